"""Garment encoding (cached) and batched per-frame deformation on onnxruntime."""

from __future__ import annotations

import hashlib
import json
import logging
import os
from pathlib import Path

import numpy as np

from segadeform.errors import InputError
from segadeform.geometry import GarmentAsset
from segadeform.geometry.features import vertex_features
from segadeform.settings import Effects

from .package import ModelPackage
from .translation import at_translation

__all__ = ["Deformer", "unfamiliar_warning"]

log = logging.getLogger(__name__)


def _digest(*arrays, extra: str = "") -> str:
    h = hashlib.sha256(extra.encode())
    for a in arrays:
        a = np.ascontiguousarray(a)
        h.update(str(a.dtype).encode() + str(a.shape).encode())
        h.update(a.tobytes())
    return h.hexdigest()[:32]


class Deformer:
    """Runs a model package for one set of effects.

    Only the graphs the effects need get a session: the garment encoder (when
    a garment is encoded) and the one deformer variant for ``effects``.

    Args:
        package: a :class:`ModelPackage`.
        effects: which stages run (skinning kind, dynamics, wrinkles; collisions are the pipeline's).
    """

    def __init__(self, package: ModelPackage, effects: Effects = Effects()):
        self.package = package
        self.effects = effects
        self.variant = package.variant_for(effects)
        spec = package.spec(self.variant)
        self.window = int(dict((i["name"], i["shape"]) for i in spec["inputs"])["window"][1])
        self.n_betas = int(package.config["n_betas"])
        self.n_joints = int(package.config["n_joints"])
        self._memory: dict[str, np.ndarray] = {}
        self._bodies: dict[int, tuple[object, str]] = {}  # id(body) -> (body, digest of its rest arrays)
        self.encoder_runs = 0
        #: residual-weights models take the body's weights at the garment (``log_wbody``)
        self.needs_body_weights = any(i["name"] == "log_wbody" for i in spec["inputs"])
        enc = package.spec("garment_encoder")
        #: the encoder's output, fed to every deformer call under the same name without its batch axis:
        #: ``g (N, K S)``, K = config.ensemble (older packages: ``P (N, S, F_enc)``, from an encoder that also
        #: took betas)
        self.code_name = enc["outputs"][0]["name"]
        self._encoder_inputs = [i["name"] for i in enc["inputs"]]

    # ---- encoder -------------------------------------------------------
    def _betas(self, betas) -> np.ndarray:
        b = np.zeros(self.n_betas, np.float32)
        given = np.asarray(betas if betas is not None else [], np.float64).ravel()
        if given.size > self.n_betas:
            raise InputError(
                "too many shape coefficients for this model", expected=f"<= {self.n_betas}", got=given.size
            )
        if not np.isfinite(given).all():
            raise InputError("betas contain NaN or inf")
        b[: given.size] = given
        return b

    def encode(
        self,
        asset: GarmentAsset,
        joints: np.ndarray,
        betas=None,
        *,
        cache_dir: str | os.PathLike | None = None,
        surface: np.ndarray | None = None,
    ) -> np.ndarray:
        """The garment code the deformer takes, ``g (N, K S)`` (``P (N, S, F_enc)`` for older packages).

        Vertex features are recomputed for ``joints`` (the body's rest joints
        for ``betas``).  Results are cached in memory and, when ``cache_dir``
        is given and writable, on disk as ``P-<hash>.npy``, keyed by a hash of
        every encoder input and the encoder graph.  ``surface``: the garment's
        :func:`~segadeform.geometry.mesh_ops.surface_faces` for the check of its openings, when the caller has
        them (a run shares them between its checks); None: computed when needed.
        """
        asset.validate()
        j = np.asarray(joints, np.float64)
        if j.shape != (self.n_joints, 3) or not np.isfinite(j).all():
            raise InputError("joints must be a finite (S, 3) array", expected=(self.n_joints, 3), got=j.shape)
        b = self._betas(betas)
        feats = vertex_features(asset.vertices, asset.faces, j, normals=asset.normals.astype(np.float64))
        desc = asset.descriptor.astype(np.float32)
        n_star = int(self.package.config["n_star"])
        if desc.shape != (n_star,):
            raise InputError("garment descriptor length does not match the model", expected=n_star, got=desc.shape[0])
        # the key covers the encoder file and its manifest entry: a package whose manifest no
        # longer matches its graph must not be served from an old cache
        spec = self.package.spec("garment_encoder")
        key = _digest(
            feats,
            asset.nbr,
            asset.mask,
            desc,
            b,
            extra=json.dumps(spec, sort_keys=True) + str(spec.get("sha256", self.package.path)),
        )
        if key in self._memory:
            return self._memory[key]
        self._warn_if_unfamiliar(asset, surface)
        path = Path(cache_dir) / f"P-{key}.npy" if cache_dir is not None else None
        if path is not None and path.is_file():
            try:
                P = np.load(path, allow_pickle=False)
                if P.shape[0] == asset.n_vertices and np.isfinite(P).all():
                    self._memory[key] = P
                    return P
            except (OSError, ValueError):
                log.warning("ignoring unreadable encoder cache %s", path)
        avail = {
            "features": feats[None],
            "nbr": asset.nbr,
            "mask": asset.mask,
            "descriptor": desc[None],
            "betas": b[None],
        }
        P = self.package.run("garment_encoder", {k: avail[k] for k in self._encoder_inputs if k in avail})[0][0]
        self.encoder_runs += 1
        if not np.isfinite(P).all():
            raise InputError("the garment encoder produced NaN or inf")
        self._memory[key] = P
        if path is not None:
            self._save(path, P)
        return P

    def _warn_if_unfamiliar(self, asset: GarmentAsset, surface: np.ndarray | None = None) -> None:
        said = unfamiliar_warning(self.package, asset, surface)
        if said is not None:
            log.warning("%s", said)

    # ---- deformer ------------------------------------------------------
    def body_log_weights(
        self, asset: GarmentAsset, body, betas=None, *, cache_dir: str | os.PathLike | None = None
    ) -> np.ndarray:
        """``log_wbody (N, S)``: the body's skinning weights carried to the garment on the rest body of shape
        ``betas`` by the model's ``weight_prior`` (closest point, or inpainted:
        :func:`segadeform.body.transfer.garment_weights`): what residual-weights models start from.

        Cached in memory and, when ``cache_dir`` is given and writable, on disk as ``W-<hash>.npy``, keyed by
        the garment's vertices and faces, ``betas``, the prior (name, version, settings) and the body's rest
        arrays (the inpainted prior takes about 0.2 s at 4k vertices: every run of the same garment would pay
        it again).
        """
        from segadeform.body import transfer
        from segadeform.body.transfer import garment_weights, residual_log_weights

        b = self._betas(betas)
        prior = self.weight_prior
        # the prior's version and settings are part of the key: a release that changes them reads no old entry
        settings = (
            f"v{transfer.WEIGHT_PRIOR_VERSION}-{transfer.INPAINT_MAX_DISTANCE}-{transfer.INPAINT_MAX_ANGLE}-"
            f"{transfer.RESIDUAL_EPS}"
        )
        key = _digest(asset.vertices, asset.faces, b, extra=f"wbody-{prior}-{settings}-{self._body_key(body)}")
        if key in self._memory:
            return self._memory[key]
        path = Path(cache_dir) / f"W-{key}.npy" if cache_dir is not None else None
        if path is not None and path.is_file():
            try:
                lw = np.load(path, allow_pickle=False)
                if lw.shape == (asset.n_vertices, self.n_joints) and lw.dtype == np.float32 and np.isfinite(lw).all():
                    self._memory[key] = lw
                    return lw
            except (OSError, ValueError):
                log.warning("ignoring unreadable body-weights cache %s", path)
        w = garment_weights(asset.vertices, asset.faces, body, b[: body.n_betas], prior)
        lw = self._memory[key] = residual_log_weights(w)
        if path is not None:
            self._save(path, lw)
        return lw

    def _body_key(self, body) -> str:
        """A digest of the body's rest arrays that decide its weights at a garment, once per body object (the
        object is kept, so its ``id`` is not reused while the entry lives)."""
        held = self._bodies.get(id(body))
        if held is None or held[0] is not body:
            held = self._bodies[id(body)] = (body, _digest(body.v_template, body.faces, body.shapedirs, body.weights))
        return held[1]

    @staticmethod
    def _save(path: Path, array: np.ndarray) -> None:
        """Write a cache entry atomically; a read-only cache folder only costs the cache."""
        try:
            from segadeform.io.atomic import atomic_path

            with atomic_path(path) as tmp:
                with open(tmp, "wb") as fh:
                    np.save(fh, array)
        except OSError as e:
            log.warning("cannot write the cache entry %s (%s)", path, e.strerror or e)

    @property
    def weight_prior(self) -> str:
        """How residual models get the body's weights (``weight_prior`` of the package's config)."""
        return str(self.package.config.get("weight_prior", "nearest"))

    def deform(
        self,
        P: np.ndarray,
        asset: GarmentAsset,
        windows: np.ndarray,
        joints: np.ndarray,
        trans: np.ndarray,
        betas=None,
        *,
        outputs: bool = False,
        log_wbody: np.ndarray | None = None,
    ):
        """Deform a batch of frames.

        Shapes:
            P: the output of :meth:`encode`, (N, K S) (or (N, S, F_enc)), windows: (B, T, 3 S) (T = the variant's
            window; window[:, 0] is the current pose), joints: (S, 3) rest joints, trans: (B, 3),
            log_wbody: (N, S) for residual-weights models (:meth:`body_log_weights`)
            -> vertices (B, N, 3) float64; with ``outputs=True`` also weights (B, N, S) and blend shapes (B, N, 3)

        The graph runs at the root (``trans`` zero) and the translation, rounded to float32 as motion files hold it,
        is added after it in float64: the network's float32 arithmetic is then the same wherever the character
        stands (1 km from the origin it rounded the garment by up to 0.1 mm, and a vertex deep in the body left it
        on the other side: a garment 5.9 cm off at 100 m, a new user's trial), and every runtime adds it so.
        """
        w = np.asarray(windows, np.float32)
        if w.ndim != 3 or w.shape[1] != self.window or w.shape[2] != 3 * self.n_joints:
            raise InputError(
                "motion windows have the wrong shape", expected=f"(B, {self.window}, {3 * self.n_joints})", got=w.shape
            )
        bsz = w.shape[0]
        if np.shape(trans) != (bsz, 3):
            raise InputError("trans must be (batch, 3), one row per window", expected=(bsz, 3), got=np.shape(trans))
        if not np.isfinite(np.asarray(trans, np.float64)).all():  # every frame came out NaN (a library user's trial)
            raise InputError("trans must be finite", expected="finite (batch, 3)", got="NaN or inf")
        code = np.asarray(P, np.float32)
        if code.ndim < 2 or code.shape[0] != asset.n_vertices or not np.isfinite(code).all():
            # one row per garment vertex: another garment's code reached onnxruntime's own error (a library user's
            # trial)
            raise InputError(
                "the garment code P is not this garment's (Deformer.encode of this asset)",
                expected=f"finite ({asset.n_vertices}, ...)",
                got=code.shape,
            )
        b = np.repeat(self._betas(betas)[None], bsz, axis=0)
        j = np.repeat(np.asarray(joints, np.float32)[None], bsz, axis=0)
        feeds = {
            self.code_name: code,
            "window": w,
            "betas": b,
            "rest": asset.vertices.astype(np.float32),
            "nbr": asset.nbr,
            "mask": asset.mask,
            "joints": j,
            "trans": np.zeros((bsz, 3), np.float32),
        }
        if self.needs_body_weights:
            lw = None if log_wbody is None else np.asarray(log_wbody, np.float32)
            if lw is None or lw.shape != (asset.n_vertices, self.n_joints) or not np.isfinite(lw).all():
                raise InputError(
                    "this model needs the body's weights at the garment (log_wbody)",
                    expected=f"finite ({asset.n_vertices}, {self.n_joints}): Deformer.body_log_weights",
                    got=None if lw is None else lw.shape,
                )
            feeds["log_wbody"] = lw
        out = list(self.package.run(self.variant, feeds))
        out[0] = at_translation(out[0], trans)
        return out if outputs else out[0]


def unfamiliar_warning(package, asset: GarmentAsset, surface: np.ndarray | None = None) -> str | None:
    """What a run says of a garment that lies outside the garments ``package``'s model was trained on
    (:meth:`~segadeform.runtime.package.ModelPackage.familiarity`), or None.  ``surface``: the asset's
    :func:`~segadeform.geometry.mesh_ops.surface_faces` (None: computed here)."""
    from segadeform.geometry.mesh_ops import boundary_loops, surface_faces

    if surface is None:
        surface = surface_faces(asset.vertices, asset.faces)
    fam = package.familiarity(asset.descriptor, len(boundary_loops(surface, asset.n_vertices)))
    if fam is None or not fam.outside:
        return None
    return (
        f"garment {asset.source_name or '(unnamed)'} lies outside the garments model {package.path.name} was trained "
        f"on ({fam}); results may be less accurate than on those (for the shipped model: its MODEL_CARD.md)"
    )
