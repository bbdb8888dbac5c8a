"""The garment asset: everything the model and runtime need about one garment, in one ``.npz``.

Written by ``segadeform precompute`` (or :func:`segadeform.geometry.precompute_garment` +
:meth:`GarmentAsset.save`), read with :meth:`GarmentAsset.load`, which
validates every array.  The file is a plain ``.npz`` read with
``allow_pickle=False``; ``schema_version`` changes when a field changes
meaning, and loaders refuse versions they do not know.

Fields (N vertices, F faces, K neighbour slots, S joints, m <= N* samples):

=================  ===============  =============================================
vertices           (N, 3) float64   rest positions, file vertex order
faces              (F, 3) int64     triangles (polygons fan-triangulated)
normals            (N, 3) float32   area-weighted unit normals (0 where undefined)
features           (N, 6+S) float32 ``[p, n, d]`` (§4.1)
nbr, mask          (N, K)           padded 1-ring (see ``geometry.graph``)
joints             (S, 3) float64   rest-pose joints the distances refer to
descriptor         (N*,) float64    garment type descriptor (§4.3)
fps_samples        (m,) int64       the furthest point samples
geodesic_radius    () float64       kernel width r
params             JSON string      k, max_k, n_star, geodesic method, versions
source_name        str              file name of the garment
source_sha256      str              hash of the garment file's bytes
betas              (B,) float64     optional (schema 2): the body shape ``joints`` and ``features`` are for
log_wbody          (N, S) float32   optional (schema 2): ``log(w + 1e-5)``, ``w`` the body's skinning weights
                                    at each vertex's closest point on the rest body of shape ``betas``
body               JSON string      optional (schema 2): ``{"name", "sha256", "weight_prior"}``: that body
                                    (:func:`segadeform.body.identity.body_sha256`) and how its weights
                                    reached the garment (the model's ``config.weight_prior``)
out_vertices       (P, 3) float64   optional (schema 3, all five or none): the garment as given, when the
                                    model's garment (``vertices``, ``faces``) is a decimated copy of it
                                    (``garment export --resolution R``); the runtimes write, collide and
                                    step the cloth stage on it
out_faces          (G, 3) int64     its triangles
carry_face         (P,) int64       the model garment's triangle each given vertex is carried by
carry_bary         (P, 3) float64   its barycentric weights on that triangle
carry_offset       (P,) float64     its distance along the triangle's unit normal: a posed given vertex is
                                    ``sum_k bary_k x[faces[face, k]] + offset n`` (``body.resample.SurfaceMap``)
warnings           JSON list        optional: what ``garment export`` said of the garment (a mesh split at
                                    its seams, faces wound inward ...), for the runtimes that play the asset
                                    to say again (``meta.warnings`` in the portable form)
=================  ===============  =============================================

An asset **prepared for a body shape** (:func:`segadeform.body.prepare.prepare_for_body`,
``segadeform garment export``) has the three optional fields: with them it holds every model input that only
Python computes (features for the shape, neighbours, mask, descriptor, the body's weights at the garment), so
the Node, browser and C++ runtimes animate it from a motion file alone.  Schema 1 (no optional fields) is still read.

**Portable form** (``.sgda``, for runtimes without Python; ``docs/package.md``): the same fields in
the scene-bundle container of :mod:`segadeform.io.sgdb` (little-endian, a text header, 64-byte aligned
arrays; the Node and C++ runtimes' bundle readers read it), with ``vertices``, ``joints`` and
``descriptor`` as ``f64``, ``normals`` and ``features`` as ``f32``, ``faces``, ``nbr`` and
``fps_samples`` as ``i32``, ``mask`` as ``u8``, and the rest in ``meta``: ``kind`` =
``"segadeform-garment-asset"``, ``schema_version``, ``geodesic_radius``, ``params``,
``source_name``, ``source_sha256``; prepared for a body, also the arrays ``betas`` (``f64``) and
``log_wbody`` (``f32``) and ``meta.body``.  :meth:`GarmentAsset.save` writes it for a ``.sgda`` path and
:meth:`GarmentAsset.load` reads either form; the round trip is exact.
"""

from __future__ import annotations

import dataclasses
import json
import os
from pathlib import Path
from typing import Any, cast

import numpy as np

from ..errors import FileFormatError, InputError
from .atomic import atomic_path
from .sgdb import BUNDLE_MAGIC, read_bundle, write_bundle

__all__ = [
    "ASSET_SCHEMA_VERSION",
    "READABLE_ASSET_SCHEMAS",
    "ASSET_KIND",
    "PORTABLE_SUFFIX",
    "GarmentAsset",
    "check_asset_path",
]

#: 2: optional ``betas``, ``log_wbody`` and ``body`` (an asset prepared for a body shape); 3: also the optional
#: ``out_*`` and ``carry_*`` fields (a model garment decimated from the garment as given).  An asset is written with
#: the lowest version that holds its fields (runtimes that cannot carry frames refuse a schema-3 asset)
ASSET_SCHEMA_VERSION = 2
CARRY_SCHEMA_VERSION = 3
READABLE_ASSET_SCHEMAS = (1, 2, 3)
#: ``meta.kind`` of the portable form, and its file suffix
ASSET_KIND = "segadeform-garment-asset"
PORTABLE_SUFFIX = ".sgda"


def check_asset_path(path: str | os.PathLike) -> Path:
    """``path`` as a garment asset's file name: ``.npz`` or ``.sgda`` (the portable form), else InputError.  Any
    other name was written as an ``.npz`` under it (``-o skirt.obj`` replaced nothing of the user's, but left an
    archive named as a mesh)."""
    p = Path(path)
    if p.suffix.lower() not in (".npz", PORTABLE_SUFFIX):
        raise InputError(
            "a garment asset is written as .npz or .sgda (portable)",
            path=p,
            expected=f".npz or {PORTABLE_SUFFIX}",
            got=p.suffix or "no suffix",
        )
    return p


#: the portable form's array dtypes (bundle dtype names)
_PORTABLE = {
    "vertices": "f64",
    "faces": "i32",
    "normals": "f32",
    "features": "f32",
    "nbr": "i32",
    "mask": "u8",
    "joints": "f64",
    "descriptor": "f64",
    "fps_samples": "i32",
}
_NP_OF = {"f64": np.float64, "f32": np.float32, "i32": np.int32, "u8": np.uint8}
#: the optional fields of an asset prepared for a body shape (portable dtypes); ``body`` is in ``meta``
_BODY_PORTABLE = {"betas": "f64", "log_wbody": "f32"}
_BODY_ARRAYS = {"betas": (np.float64, 1), "log_wbody": (np.float32, 2)}
#: the optional fields of a decimated model garment (schema 3): the garment as given and the map to it
_CARRY_PORTABLE = {
    "out_vertices": "f64",
    "out_faces": "i32",
    "carry_face": "i32",
    "carry_bary": "f64",
    "carry_offset": "f64",
}
_CARRY_ARRAYS = {
    "out_vertices": (np.float64, 2),
    "out_faces": (np.int64, 2),
    "carry_face": (np.int64, 1),
    "carry_bary": (np.float64, 2),
    "carry_offset": (np.float64, 1),
}

_ARRAYS = {
    "vertices": (np.float64, 2),
    "faces": (np.int64, 2),
    "normals": (np.float32, 2),
    "features": (np.float32, 2),
    "nbr": (np.int64, 2),
    "mask": (np.bool_, 2),
    "joints": (np.float64, 2),
    "descriptor": (np.float64, 1),
    "fps_samples": (np.int64, 1),
}


#: how far from 1 a row of carry_bary may sum (barycentric weights of a point on a face)
CARRY_BARY_TOLERANCE = 1e-6


@dataclasses.dataclass(frozen=True, eq=False)
class GarmentAsset:
    """A precomputed garment (see the module table for shapes)."""

    vertices: np.ndarray
    faces: np.ndarray
    normals: np.ndarray
    features: np.ndarray
    nbr: np.ndarray
    mask: np.ndarray
    joints: np.ndarray
    descriptor: np.ndarray
    fps_samples: np.ndarray
    geodesic_radius: float
    params: dict
    source_name: str = ""
    source_sha256: str = ""
    betas: np.ndarray | None = None
    log_wbody: np.ndarray | None = None
    body: dict | None = None
    out_vertices: np.ndarray | None = None
    out_faces: np.ndarray | None = None
    carry_face: np.ndarray | None = None
    carry_bary: np.ndarray | None = None
    carry_offset: np.ndarray | None = None
    warnings: tuple = ()  # what `garment export` said of the garment (strings)

    @property
    def n_vertices(self) -> int:
        """The model garment's vertices (with :attr:`carried`, the decimated copy's)."""
        return int(self.vertices.shape[0])

    @property
    def carried(self) -> bool:
        """Whether the model garment is a decimated copy whose frames are carried to the garment as given
        (``out_vertices``, ``out_faces`` and the ``carry_*`` map)."""
        return self.out_vertices is not None

    @property
    def schema_version(self) -> int:
        """The version this asset is written with: the lowest that holds its fields."""
        return CARRY_SCHEMA_VERSION if self.carried else ASSET_SCHEMA_VERSION

    @property
    def for_a_body(self) -> bool:
        """Whether the asset was prepared for a body shape (``betas``, ``log_wbody`` and ``body``)."""
        return self.betas is not None

    def __repr__(self) -> str:
        shape = f", betas={np.round(self.betas, 3).tolist()}" if self.betas is not None else ""  # for_a_body
        if self.carried:  # the model's garment, decimated; the outputs have the garment as given
            shape += f", carried to the garment's {len(cast(np.ndarray, self.out_vertices))} vertices"
        return (
            f"GarmentAsset(N={self.n_vertices}, F={len(self.faces)}, K={self.nbr.shape[1]}, "
            f"S={len(self.joints)}, N*={len(self.descriptor)}, source={self.source_name!r}{shape})"
        )

    def save(self, path: str | os.PathLike) -> Path:
        """Write the asset atomically: an uncompressed ``.npz``, or the portable form for a ``.sgda`` path."""
        p = check_asset_path(path)
        self.validate()
        if p.suffix.lower() == PORTABLE_SUFFIX:
            return self._save_portable(p)
        extra: dict[str, Any] = {"warnings": np.str_(json.dumps(list(self.warnings)))} if self.warnings else {}
        with atomic_path(p) as tmp:
            with open(tmp, "wb") as fh:
                np.savez(
                    fh,
                    schema_version=np.int64(self.schema_version),
                    geodesic_radius=np.float64(self.geodesic_radius),
                    params=np.str_(json.dumps(self.params, sort_keys=True)),
                    source_name=np.str_(self.source_name),
                    source_sha256=np.str_(self.source_sha256),
                    **{k: getattr(self, k) for k in _ARRAYS},
                    **(
                        {k: getattr(self, k) for k in _BODY_ARRAYS} | {"body": np.str_(json.dumps(self.body))}
                        if self.for_a_body
                        else {}
                    ),
                    **({k: getattr(self, k) for k in _CARRY_ARRAYS} if self.carried else {}),
                    **extra,
                )
        return p

    def _save_portable(self, p: Path) -> Path:
        if self.n_vertices >= 2**31 - 1:
            raise InputError(
                "garment too large for the portable asset's int32 indices", expected="N < 2^31 - 1", got=self.n_vertices
            )
        arrays = {k: getattr(self, k).astype(_NP_OF[dt]) for k, dt in _PORTABLE.items()}
        meta = {
            "kind": ASSET_KIND,
            "schema_version": self.schema_version,
            "geodesic_radius": float(self.geodesic_radius),
            "params": self.params,
            "source_name": self.source_name,
            "source_sha256": self.source_sha256,
        }
        if self.for_a_body:
            arrays.update({k: getattr(self, k).astype(_NP_OF[dt]) for k, dt in _BODY_PORTABLE.items()})
            meta["body"] = self.body
        if self.carried:
            arrays.update({k: getattr(self, k).astype(_NP_OF[dt]) for k, dt in _CARRY_PORTABLE.items()})
        if self.warnings:
            meta["warnings"] = list(self.warnings)
        return write_bundle(p, arrays, meta)

    @classmethod
    def _load_portable(cls, p: Path) -> GarmentAsset:
        arrays, meta = read_bundle(p)
        if meta.get("kind") != ASSET_KIND:
            raise FileFormatError(
                "not a garment asset", path=p, expected=f"meta.kind {ASSET_KIND!r}", got=meta.get("kind")
            )
        if meta.get("schema_version") not in READABLE_ASSET_SCHEMAS:
            raise FileFormatError(
                "unsupported garment asset schema version",
                path=p,
                expected=" or ".join(map(str, READABLE_ASSET_SCHEMAS)),
                got=meta.get("schema_version"),
            )
        fields = {}
        optional = {k: dt for k, dt in _BODY_PORTABLE.items() if k in arrays or "body" in meta}
        if meta.get("schema_version") == CARRY_SCHEMA_VERSION or any(k in arrays for k in _CARRY_PORTABLE):
            optional |= _CARRY_PORTABLE
        for k, dt in (_PORTABLE | optional).items():
            a = arrays.get(k)
            if a is None or a.dtype != np.dtype(_NP_OF[dt]).newbyteorder("<"):
                raise FileFormatError(
                    f"garment asset field {k!r} is missing or has the wrong dtype",
                    path=p,
                    expected=dt,
                    got=None if a is None else a.dtype,
                )
            fields[k] = a.astype((_ARRAYS | _BODY_ARRAYS | _CARRY_ARRAYS)[k][0])
        try:
            radius = float(meta["geodesic_radius"])
            params = dict(meta["params"])
        except (KeyError, TypeError, ValueError):
            raise FileFormatError("garment asset meta lacks geodesic_radius or params", path=p) from None
        if any(k in optional for k in _BODY_PORTABLE):
            fields["body"] = meta.get("body")
        said = meta.get("warnings", [])
        fields["warnings"] = tuple(said) if isinstance(said, list) else said  # checked by validate
        return cls(
            geodesic_radius=radius,
            params=params,
            source_name=str(meta.get("source_name", "")),
            source_sha256=str(meta.get("source_sha256", "")),
            **fields,
        )

    @classmethod
    def load(cls, path: str | os.PathLike) -> GarmentAsset:
        """Read and validate an asset (``.npz`` or the portable form); errors name the file and the field."""
        p = Path(path)
        from .npz import load_npz

        try:
            with open(p, "rb") as fh:
                portable = fh.read(len(BUNDLE_MAGIC)) == BUNDLE_MAGIC
        except OSError:
            portable = False  # load_npz reports the file error
        if portable:
            asset = cls._load_portable(p)
            try:
                asset.validate()
            except InputError as e:
                raise FileFormatError(e.problem, path=p, expected=e.expected, got=e.got) from None
            return asset

        if p.suffix.lower() == PORTABLE_SUFFIX and p.is_file():  # a .sgda that is not one (an empty file, a web page)
            with open(p, "rb") as fh:
                head = fh.read(64)
            raise FileFormatError(
                "not a garment asset",
                path=p,
                expected="a file `segadeform garment export` writes (it starts with 'SEGADEFORM-BUNDLE')",
                got="an empty file" if not head else repr(head[:16]) + "...",
            )
        z = load_npz(p, what="garment asset .npz")
        names = set(z)
        required = set(_ARRAYS) | {"schema_version", "geodesic_radius", "params"}
        missing = sorted(required - names)
        if missing:
            raise FileFormatError(
                "garment asset is missing fields",
                path=p,
                expected=", ".join(sorted(required)),
                got="missing " + ", ".join(missing),
            )
        try:
            version = int(z["schema_version"])
            if version not in READABLE_ASSET_SCHEMAS:
                raise FileFormatError(
                    "unsupported garment asset schema version",
                    path=p,
                    expected=" or ".join(map(str, READABLE_ASSET_SCHEMAS)),
                    got=version,
                )
            fields: dict[str, Any] = {k: z[k] for k in _ARRAYS}
            if version >= 2 and ({"betas", "log_wbody", "body"} & names):
                fields.update({k: z[k] for k in _BODY_ARRAYS if k in names})
                fields["body"] = json.loads(str(z["body"])) if "body" in names else None
            if version >= CARRY_SCHEMA_VERSION or (set(_CARRY_ARRAYS) & names):
                if not set(_CARRY_ARRAYS) <= names:
                    raise FileFormatError(
                        "garment asset of a decimated model garment lacks fields",
                        path=p,
                        expected=", ".join(_CARRY_ARRAYS),
                        got="missing " + ", ".join(sorted(set(_CARRY_ARRAYS) - names)),
                    )
                fields.update({k: z[k] for k in _CARRY_ARRAYS})
            if "warnings" in names:
                said = json.loads(str(z["warnings"]))
                fields["warnings"] = tuple(said) if isinstance(said, list) else said
            params = json.loads(str(z["params"]))
            radius = float(z["geodesic_radius"])
            src = str(z["source_name"]) if "source_name" in names else ""
            sha = str(z["source_sha256"]) if "source_sha256" in names else ""
        except FileFormatError:
            raise
        except Exception as e:
            raise FileFormatError(f"garment asset field cannot be read ({e})", path=p) from None
        asset = cls(geodesic_radius=radius, params=params, source_name=src, source_sha256=sha, **fields)
        try:
            asset.validate()
        except InputError as e:
            raise FileFormatError(e.problem, path=p, expected=e.expected, got=e.got) from None
        return asset

    def validate(self) -> None:
        """Check dtypes, shapes, consistency and finiteness of every field."""
        self._check_types(_ARRAYS)
        n = self.vertices.shape[0]
        s = self.joints.shape[0]
        checks = [
            ("vertices", self.vertices.shape == (n, 3) and n >= 1, "(N, 3), N >= 1"),
            ("faces", self.faces.shape[1:] == (3,) and len(self.faces) >= 1, "(F, 3), F >= 1"),
            ("normals", self.normals.shape == (n, 3), f"({n}, 3)"),
            ("joints", self.joints.shape == (s, 3) and s >= 1, "(S, 3)"),
            ("features", self.features.shape == (n, 6 + s), f"({n}, {6 + s})"),
            ("nbr", self.nbr.shape[0] == n and self.nbr.shape[1] >= 1, f"({n}, K)"),
            ("mask", self.mask.shape == self.nbr.shape, f"{self.nbr.shape}"),
            ("descriptor", self.descriptor.shape[0] >= 1, "(N*,)"),
            ("fps_samples", 1 <= len(self.fps_samples) <= len(self.descriptor), "(m,), 1 <= m <= N*"),
        ]
        for name, ok, exp in checks:
            if not ok:
                raise InputError(
                    f"asset field {name!r} has the wrong shape", expected=exp, got=getattr(self, name).shape
                )
        for name, arr in (("faces", self.faces), ("nbr", self.nbr), ("fps_samples", self.fps_samples)):
            if arr.size and (arr.min() < 0 or arr.max() >= n):
                raise InputError(
                    f"asset field {name!r} has an index out of range",
                    expected=f"0..{n - 1}",
                    got=int(arr.max()) if arr.max() >= n else int(arr.min()),
                )
        for name in ("vertices", "normals", "features", "joints", "descriptor"):
            if not np.isfinite(getattr(self, name)).all():
                raise InputError(f"asset field {name!r} contains NaN or inf")
        for name in ("vertices", "joints"):  # positions, within the bounds of segadeform.bounds (10 km): 1e30 came
            far = float(np.abs(getattr(self, name)).max())  # out of the encoder as NaN, the file unnamed
            if far > 1.0e4:
                raise InputError(f"asset field {name!r} lies beyond 10 km", expected="|x| <= 10000 m", got=far)
        given = [k for k in ("betas", "log_wbody", "body") if getattr(self, k) is not None]
        if given and len(given) != 3:
            raise InputError(
                "an asset prepared for a body needs betas, log_wbody and body together",
                expected="all three or none",
                got=", ".join(given),
            )
        if given:
            for k, (dt, nd) in _BODY_ARRAYS.items():
                a = getattr(self, k)
                if not isinstance(a, np.ndarray) or a.dtype != dt or a.ndim != nd or not np.isfinite(a).all():
                    raise InputError(
                        f"asset field {k!r} has the wrong type or is not finite",
                        expected=f"finite {np.dtype(dt).name} array with {nd} dims",
                        got=f"{getattr(a, 'dtype', type(a).__name__)} {getattr(a, 'shape', '')}",
                    )
            log_wbody = cast(np.ndarray, self.log_wbody)  # given: checked above
            if log_wbody.shape != (n, s):
                raise InputError("asset field 'log_wbody' has the wrong shape", expected=(n, s), got=log_wbody.shape)
            if not isinstance(self.body, dict) or not isinstance(self.body.get("sha256"), str):
                raise InputError(
                    "asset field 'body' must name the body", expected='{"name": str, "sha256": str}', got=self.body
                )
        self._validate_carry(n)
        w = self.warnings
        if not (isinstance(w, tuple) and all(isinstance(x, str) and x and "\n" not in x for x in w)):
            raise InputError(
                "asset field 'warnings' is not a list of one-line texts", expected="strings without line breaks", got=w
            )
        if not (np.isfinite(self.geodesic_radius) and self.geodesic_radius > 0):
            raise InputError("asset geodesic_radius must be positive", got=self.geodesic_radius)

    def _check_types(self, fields: dict) -> None:
        """Each of ``fields`` (name -> (dtype, ndim)) an array of its dtype and number of dimensions."""
        for k, (dt, nd) in fields.items():
            a = getattr(self, k)
            if not isinstance(a, np.ndarray) or a.dtype != dt or a.ndim != nd:
                raise InputError(
                    f"asset field {k!r} has the wrong type",
                    expected=f"{np.dtype(dt).name} array with {nd} dims",
                    got=f"{getattr(a, 'dtype', type(a).__name__)} with shape {getattr(a, 'shape', '?')}",
                )

    def _validate_carry(self, n: int) -> None:
        """The ``out_*`` and ``carry_*`` fields: all or none; shapes, index ranges, finite values."""
        given = [k for k in _CARRY_ARRAYS if getattr(self, k) is not None]
        if not given:
            return
        if len(given) != len(_CARRY_ARRAYS):
            raise InputError(
                "a decimated model garment needs out_vertices, out_faces, carry_face, carry_bary and carry_offset",
                expected="all five or none",
                got=", ".join(given),
            )
        self._check_types(_CARRY_ARRAYS)
        ov, of = cast(np.ndarray, self.out_vertices), cast(np.ndarray, self.out_faces)
        face, bary, off = (cast(np.ndarray, getattr(self, k)) for k in ("carry_face", "carry_bary", "carry_offset"))
        p = len(ov)
        checks = [
            ("out_vertices", ov.shape == (p, 3) and p >= 1, "(P, 3), P >= 1"),
            ("out_faces", of.shape[1:] == (3,) and len(of) >= 1, "(G, 3), G >= 1"),
            ("carry_face", face.shape == (p,), f"({p},)"),
            ("carry_bary", bary.shape == (p, 3), f"({p}, 3)"),
            ("carry_offset", off.shape == (p,), f"({p},)"),
        ]
        for name, ok, exp in checks:
            if not ok:
                raise InputError(
                    f"asset field {name!r} has the wrong shape", expected=exp, got=getattr(self, name).shape
                )
        for name, arr, hi in (("out_faces", of, p), ("carry_face", face, len(self.faces))):
            if arr.min() < 0 or arr.max() >= hi:
                raise InputError(
                    f"asset field {name!r} has an index out of range",
                    expected=f"0..{hi - 1}",
                    got=int(arr.max()) if arr.max() >= hi else int(arr.min()),
                )
        for name in ("out_vertices", "carry_bary", "carry_offset"):
            if not np.isfinite(getattr(self, name)).all():
                raise InputError(f"asset field {name!r} contains NaN or inf")
        off = np.abs(bary.sum(axis=1) - 1.0)
        if float(off.max()) > CARRY_BARY_TOLERANCE:  # weights (1, 1, 0) on a face (A, A, B) wrote a vertex twice as far
            raise InputError(
                "asset field 'carry_bary' has weights that do not sum to 1 (an asset exported by a release that put a "
                "vertex on a face with a repeated corner twice: export it again)",
                expected=f"each row summing to 1 within {CARRY_BARY_TOLERANCE:g}",
                got=f"row {int(off.argmax())} sums to {float(bary[int(off.argmax())].sum()):.9g}",
            )
        if float(np.abs(ov).max()) > 1.0e4:
            raise InputError("asset field 'out_vertices' lies beyond 10 km", expected="|x| <= 10000 m")
