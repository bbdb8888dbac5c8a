"""Posing the run's body per batch: with the package's body graph (float32, as the Node, browser and C++ runtimes
pose it) or with numpy (:meth:`segadeform.body.BodyModel.forward`, float64).

The collision push-out is not continuous in the body at concave creases (docs/package.md, Collisions), so the
last bits of the posed body decide where a few pushed vertices go.  ``segadeform run`` therefore poses the body
with the package's body graph whenever it can -- the package has a body graph for the run's skinning and the
run's body is the one that graph poses (the body hash its manifest entry records) -- so that every runtime pushes
out of the same float32 body.  Otherwise (a package without body graphs, another body file) it poses the body with
numpy and says why, once.  The body the graphs pose is the one the model was trained on (``segadeform export``
gives a package its checkpoint's body: :func:`package_body`), so ``segadeform run`` refuses another body file
before it gets here, unless ``--force`` (:func:`segadeform.runtime.pipeline.check_package_body`).

==========  =====================================================================================
``auto``    the body graph when it poses the run's body, else numpy (the reason logged once)
``graph``   the body graph; an error saying why when it cannot pose the run's body
``numpy``   :meth:`BodyModel.forward` in float64 (the reference the body graphs are tested against)
==========  =====================================================================================
"""

from __future__ import annotations

import logging
from typing import cast

import numpy as np

from segadeform.body import BodyModel
from segadeform.contracts import model_package as contract
from segadeform.errors import InputError

from .package import ModelPackage, PackageError
from .translation import at_translation

__all__ = ["BODY_BACKENDS", "BodyPoser", "graph_body_status", "package_body"]

log = logging.getLogger(__name__)

#: the ways a run can pose its body (``Run(body_backend=...)``, ``segadeform run --body-backend``)
BODY_BACKENDS = ("auto", "graph", "numpy")


def _short(label: dict) -> str:
    return f"{label.get('name') or 'unnamed body'} {str(label.get('sha256', ''))[:12]}".strip()


def package_body(package: ModelPackage) -> dict | None:
    """``{"name", "sha256"}`` of the body ``package``'s model was trained on: the manifest's ``training_body``
    (``segadeform export`` writes it from the checkpoint; ``export-body --force`` gives the package another body's
    graphs and leaves it), else the body its body graphs pose (their entries'
    :func:`segadeform.body.identity.body_label`: ``export`` makes them the training body's); None for a package that
    records neither."""
    return manifest_body(package.manifest)


def manifest_body(manifest: dict) -> dict | None:
    """:func:`package_body` of a package's ``manifest.json`` as read (no graph loaded)."""
    t = manifest.get("training_body")
    if isinstance(t, dict) and t.get("sha256"):
        return {"name": str(t.get("name") or ""), "sha256": str(t["sha256"])}
    for g in contract.body_graphs(manifest).values():
        b = g.get("body")
        if isinstance(b, dict) and b.get("sha256"):
            return {"name": str(b.get("name") or ""), "sha256": str(b["sha256"])}
    return None


def graph_body_status(package: ModelPackage, body: BodyModel, skinning: str) -> tuple[str | None, str | None]:
    """Whether ``package`` has a body graph that poses ``body`` with ``skinning``: ``(graph name, None)`` when it
    does, ``(None, why not)`` when it does not (no body graph, none for that skinning, no body hash recorded, or
    the recorded hash is not ``body``'s: :func:`segadeform.body.identity.body_sha256`)."""
    from segadeform.body.identity import body_label

    try:
        name = contract.select_body(package.manifest, skinning, path=package.path)
    except PackageError as e:
        return None, f"the package has no body graph for skinning '{skinning}' ({e})"
    if name is None:
        return None, "the package has no body graph (segadeform export-body [BODY] -o PACKAGE adds one)"
    recorded = package.spec(name).get("body")
    if not recorded or not recorded.get("sha256"):
        return None, f"the package's body graph '{name}' does not record which body it poses"
    mine = body_label(body)
    if mine["sha256"] != recorded["sha256"]:
        return None, (
            f"the run's body ({_short(mine)}) is not the one the package's body graph '{name}' poses "
            f"({_short(recorded)})"
        )
    if body.n_joints != int(package.spec(name)["inputs"][1]["shape"][1]):  # the hash covers it; a clear error anyway
        return None, f"the package's body graph '{name}' poses another skeleton than the run's body"
    return name, None


class BodyPoser:
    """Poses ``body`` for a run, with the package's body graph or numpy (module docstring).

    Args:
        package: the run's :class:`ModelPackage` (its threads and providers run the graph).
        body: the run's :class:`BodyModel`.
        skinning: ``"lbs"`` | ``"dqs"``, the garment's (so body and garment are skinned alike).
        backend: one of :data:`BODY_BACKENDS`.

    Attributes:
        backend: ``"graph"`` or ``"numpy"``, what :meth:`pose` uses.
        graph: the body graph's name (``body_lbs`` / ``body_dqs``) when ``backend == "graph"``.
        reason: why the body graph is not used (None when it is, or when numpy was asked for).
    """

    def __init__(self, package: ModelPackage, body: BodyModel, *, skinning: str = "lbs", backend: str = "auto"):
        if backend not in BODY_BACKENDS:
            raise InputError("unknown body backend", expected=" | ".join(BODY_BACKENDS), got=backend)
        if skinning not in contract.SKINNING:
            raise InputError("unknown skinning", expected=" | ".join(contract.SKINNING), got=skinning)
        self.package, self.body, self.skinning = package, body, skinning
        self.graph: str | None = None
        self.reason: str | None = None
        self._betas: tuple | None = None
        self._betas_row: np.ndarray | None = None
        if backend == "numpy":
            self.backend = "numpy"
            return
        self.graph, self.reason = graph_body_status(package, body, skinning)
        if self.graph is None:
            if backend == "graph":
                raise InputError(
                    f"cannot pose the body with the package's body graph: {self.reason}",
                    expected="a package whose body graph poses the run's body, or body backend 'numpy' or 'auto'",
                )
            log.info("posing the body with numpy (float64), not the package's body graph: %s", self.reason)
            self.backend = "numpy"
        else:
            self.backend = "graph"

    def _graph_betas(self, betas) -> np.ndarray:
        """The body graph's ``betas (|beta_body|,)`` float32 row: ``betas`` zero-padded (as BodyModel does)."""
        key = tuple(np.asarray(betas if betas is not None else (), np.float64).ravel().tolist())
        if key != self._betas:
            nb = int(self.package.spec(cast(str, self.graph))["inputs"][0]["shape"][0])  # backend "graph"
            b = np.asarray(key, np.float64)
            if b.size > nb:
                raise InputError("too many shape coefficients for the body", expected=f"<= {nb}", got=b.size)
            if not np.isfinite(b).all():
                raise InputError("betas contain NaN or inf")
            row = np.zeros(nb, np.float32)
            row[: b.size] = b
            self._betas, self._betas_row = key, row
        return cast(np.ndarray, self._betas_row)

    def pose(self, poses, betas, trans) -> np.ndarray:
        """The posed body's vertices for a batch of frames.

        Shapes:
            poses: (B, 3 S) axis-angle, root first; betas: (B',) one shape for every frame; trans: (B, 3)
            -> vertices (B, V, 3) float64 (the body graph runs at the root and the translation is added after it,
            as :mod:`segadeform.runtime.translation` says)
        """
        if self.backend == "numpy":
            return self.body.forward(poses, betas, trans, skinning=self.skinning).vertices
        p = np.atleast_2d(np.asarray(poses, np.float64))
        s = self.body.n_joints
        if p.ndim != 2 or p.shape[-1] != 3 * s:
            raise InputError("poses must be (batch, 3 S)", expected=f"(batch, {3 * s})", got=p.shape)
        t = np.zeros((len(p), 3)) if trans is None else np.asarray(trans, np.float64)
        if t.shape != (len(p), 3):
            raise InputError("trans must be (batch, 3), one row per pose", expected=(len(p), 3), got=t.shape)
        out = self.package.run(
            cast(str, self.graph),
            {
                "betas": self._graph_betas(betas),
                "poses": p.reshape(len(p), s, 3).astype(np.float32),
                "trans": np.zeros((len(p), 3), np.float32),
            },
        )
        return at_translation(out[0], t)
