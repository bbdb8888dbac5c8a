"""The body model: an SMPL-compatible linear blend skinned body, its file format and loaders.

One file format, ``.npz`` (read with ``allow_pickle=False``):

================  =================  ==============================================
v_template        (V, 3) float       rest-pose mesh, metres, +Y up
faces             (F, 3) int         triangles, outward-facing
shapedirs         (V, 3, B) float    linear shape space (beta ~ N(0, 1))
J_regressor       (S, V) float       joints = J_regressor @ shaped vertices, or
joint_template    (S, 3) float       ... joints = joint_template + joint_shapedirs . beta
joint_shapedirs   (S, 3, B) float
weights           (V, S) float       skinning weights, rows sum to 1
parents           (S,) int           parents[0] = -1, parents[j] < j
joint_names       (S,) str           SMPL order for S = 24
posedirs          (V, 3, P) float    optional pose blend shapes, P = 9 (S - 1)
mh_*              (see body.makehuman) optional: where MakeHuman's hm08 vertices are, to fit .mhclo garments
up_axis, units    str                "y", "m"
licence           str                optional, where the data came from
================  =================  ==============================================

:func:`load_body` also reads the official SMPL files users have: ``.npz``
(keys ``f`` and ``kintree_table``) and ``.pkl`` (through
:mod:`segadeform.body.smpl_pickle`, without chumpy and without executing
code).  Nothing is ever downloaded.
"""

from __future__ import annotations

import dataclasses
import os
import pickle
from pathlib import Path
from typing import Any, cast

import numpy as np

from ..errors import FileFormatError, InputError
from ..io.atomic import atomic_path
from .kinematics import check_parents, forward_kinematics, poses_to_rotmats, relative_transforms
from .skeleton import SMPL_JOINT_NAMES
from .skinning import dual_quaternion_skinning, linear_blend_skinning

__all__ = ["BodyModel", "BodyOutput", "load_body", "default_body_path", "BODY_SCHEMA_VERSION"]

BODY_SCHEMA_VERSION = 1
_WEIGHT_TOL = 1e-4


@dataclasses.dataclass(frozen=True)
class BodyOutput:
    """Posed body. vertices (B, V, 3), joints (B, S, 3), transforms (B, S, 4, 4) skinning transforms."""

    vertices: np.ndarray
    joints: np.ndarray
    transforms: np.ndarray


@dataclasses.dataclass(frozen=True, eq=False)
class BodyModel:
    """An SMPL-compatible body (see the module docstring for the fields)."""

    v_template: np.ndarray
    faces: np.ndarray
    shapedirs: np.ndarray
    weights: np.ndarray
    parents: np.ndarray
    joint_names: tuple
    J_regressor: np.ndarray | None = None
    joint_template: np.ndarray | None = None
    joint_shapedirs: np.ndarray | None = None
    posedirs: np.ndarray | None = None
    up_axis: str = "y"
    units: str = "m"
    licence: str = ""
    path: str | None = None
    makehuman: dict | None = None  # see segadeform.body.makehuman

    # ---- sizes --------------------------------------------------------
    @property
    def n_vertices(self) -> int:
        return int(self.v_template.shape[0])

    @property
    def n_joints(self) -> int:
        return int(self.parents.shape[0])

    @property
    def n_betas(self) -> int:
        return int(self.shapedirs.shape[2])

    def __repr__(self) -> str:
        src = f", path={self.path!r}" if self.path else ""
        return (
            f"BodyModel(V={self.n_vertices}, F={len(self.faces)}, S={self.n_joints}, betas={self.n_betas}, "
            f"posedirs={'yes' if self.posedirs is not None else 'no'}{src})"
        )

    # ---- validation ---------------------------------------------------
    def validate(self) -> BodyModel:
        """Check every array; raises :class:`InputError` naming the field."""
        v = self.v_template
        if v.ndim != 2 or v.shape[1] != 3 or v.shape[0] < 3:
            raise InputError("v_template must be (V, 3)", got=v.shape)
        nv = v.shape[0]
        p = check_parents(self.parents)
        s = p.size
        if len(self.joint_names) != s or len(set(self.joint_names)) != s:
            raise InputError("joint_names must name each joint once", expected=s, got=len(self.joint_names))
        f = self.faces
        if f.ndim != 2 or f.shape[1] != 3 or len(f) < 1 or f.min() < 0 or f.max() >= nv:
            raise InputError(
                "faces must be (F, 3) indices into v_template",
                expected=f"0..{nv - 1}",
                got=f"{f.shape}, range {f.min() if f.size else '-'}..{f.max() if f.size else '-'}",
            )
        if self.shapedirs.ndim != 3 or self.shapedirs.shape[:2] != (nv, 3):
            raise InputError("shapedirs must be (V, 3, B)", expected=f"({nv}, 3, B)", got=self.shapedirs.shape)
        if self.weights.shape != (nv, s):
            raise InputError("weights must be (V, S)", expected=(nv, s), got=self.weights.shape)
        if (self.weights < -_WEIGHT_TOL).any():
            raise InputError("weights must be non-negative", got=float(self.weights.min()))
        sums = self.weights.sum(axis=1)
        if np.abs(sums - 1).max() > _WEIGHT_TOL:
            i = int(np.argmax(np.abs(sums - 1)))
            raise InputError(f"weights of vertex {i} do not sum to 1", expected=1.0, got=float(sums[i]))
        if self.J_regressor is not None:
            if self.J_regressor.shape != (s, nv):
                raise InputError("J_regressor must be (S, V)", expected=(s, nv), got=self.J_regressor.shape)
        elif self.joint_template is not None and self.joint_shapedirs is not None:
            if self.joint_template.shape != (s, 3):
                raise InputError("joint_template must be (S, 3)", expected=(s, 3), got=self.joint_template.shape)
            if self.joint_shapedirs.shape != (s, 3, self.n_betas):
                raise InputError(
                    "joint_shapedirs must be (S, 3, B)", expected=(s, 3, self.n_betas), got=self.joint_shapedirs.shape
                )
        else:
            raise InputError("body needs J_regressor, or joint_template with joint_shapedirs")
        if self.posedirs is not None and self.posedirs.shape != (nv, 3, 9 * (s - 1)):
            raise InputError(
                "posedirs must be (V, 3, 9 (S - 1))", expected=(nv, 3, 9 * (s - 1)), got=self.posedirs.shape
            )
        for name in (
            "v_template",
            "shapedirs",
            "weights",
            "J_regressor",
            "joint_template",
            "joint_shapedirs",
            "posedirs",
        ):
            a = getattr(self, name)
            if a is not None and not np.isfinite(a).all():
                raise InputError(f"{name} contains NaN or inf")
        if self.up_axis not in ("y", "z"):
            raise InputError("up_axis must be 'y' or 'z'", got=self.up_axis)
        return self

    def with_makehuman(self, binding: dict) -> BodyModel:
        """This body with a MakeHuman binding (:mod:`segadeform.body.makehuman`), validated."""
        from .makehuman import check_makehuman_binding

        return dataclasses.replace(self, makehuman=check_makehuman_binding(binding, self.n_vertices, len(self.faces)))

    # ---- evaluation ---------------------------------------------------
    def _betas(self, betas) -> np.ndarray:
        b = np.atleast_2d(np.asarray(0.0 if betas is None else betas, np.float64))
        if b.ndim != 2:
            raise InputError("betas must be (B,) or (batch, B)", got=b.shape)
        if b.shape[1] > self.n_betas:
            raise InputError("too many shape coefficients", expected=f"<= {self.n_betas}", got=b.shape[1])
        if not np.isfinite(b).all():
            raise InputError("betas contain NaN or inf")
        from ..bounds import check_betas

        check_betas(b)  # within the shape space: past it the body folds through itself
        out = np.zeros((b.shape[0], self.n_betas))
        out[:, : b.shape[1]] = b
        return out

    def shaped_vertices(self, betas=None) -> np.ndarray:
        """Rest-pose vertices for shapes ``betas (batch, B')``, ``B' <= B``: ``(batch, V, 3)``."""
        b = self._betas(betas)
        return self.v_template[None] + np.einsum("vcb,nb->nvc", self.shapedirs, b)

    def rest_joints(self, betas=None) -> np.ndarray:
        """Rest-pose joint positions ``(batch, S, 3)``."""
        b = self._betas(betas)
        if self.J_regressor is not None:
            return np.einsum("sv,nvc->nsc", self.J_regressor, self.shaped_vertices(b))
        # validate(): without J_regressor, joint_template and joint_shapedirs are both given
        template, dirs = cast(np.ndarray, self.joint_template), cast(np.ndarray, self.joint_shapedirs)
        return template[None] + np.einsum("scb,nb->nsc", dirs, b)

    def forward(self, poses, betas=None, trans=None, *, skinning: str = "lbs") -> BodyOutput:
        """Pose the body.

        Shapes:
            poses: (batch, 3 S) axis-angle, root first
            betas: (B',) or (batch, B')
            trans: (batch, 3)
            -> BodyOutput(vertices (batch, V, 3), joints (batch, S, 3), transforms (batch, S, 4, 4))
        """
        poses = np.atleast_2d(np.asarray(poses, np.float64))
        if poses.shape[-1] != 3 * self.n_joints or not np.isfinite(poses).all():
            raise InputError(
                "poses must be finite (batch, 3 S)", expected=f"(batch, {3 * self.n_joints})", got=poses.shape
            )
        n = poses.shape[0]
        b = self._betas(betas)
        if b.shape[0] == 1 and n > 1:
            b = np.repeat(b, n, axis=0)
        if b.shape[0] != n:
            raise InputError("betas batch does not match poses", expected=n, got=b.shape[0])
        rot = poses_to_rotmats(poses, self.n_joints)
        if n > 1 and (b == b[:1]).all():  # one shape for every frame: shape the body once
            verts = np.broadcast_to(self.shaped_vertices(b[:1]), (n, self.n_vertices, 3))
            joints = np.broadcast_to(self.rest_joints(b[:1]), (n, self.n_joints, 3))
        else:
            verts = self.shaped_vertices(b)
            joints = self.rest_joints(b)
        if self.posedirs is not None:
            feat = (rot[:, 1:] - np.eye(3)).reshape(n, -1)
            verts = verts + np.einsum("vcp,np->nvc", self.posedirs, feat)
        g, posed_joints = forward_kinematics(rot, joints, self.parents, trans)
        a = relative_transforms(g, joints)
        skin = {"lbs": linear_blend_skinning, "dqs": dual_quaternion_skinning}.get(skinning)
        if skin is None:
            raise InputError("unknown skinning", expected="lbs | dqs", got=skinning)
        return BodyOutput(vertices=skin(verts, self.weights, a), joints=posed_joints, transforms=a)

    # ---- files --------------------------------------------------------
    def save(self, path: str | os.PathLike, *, compressed: bool = True) -> Path:
        """Write the body ``.npz`` atomically (float32 arrays, int32 faces)."""
        self.validate()
        arrays: dict[str, Any] = dict(
            schema_version=np.int64(BODY_SCHEMA_VERSION),
            v_template=self.v_template.astype(np.float32),
            faces=self.faces.astype(np.int32),
            shapedirs=self.shapedirs.astype(np.float32),
            weights=self.weights.astype(np.float32),
            parents=self.parents.astype(np.int64),
            joint_names=np.array(self.joint_names, dtype=np.str_),
            up_axis=np.str_(self.up_axis),
            units=np.str_(self.units),
            licence=np.str_(self.licence),
        )
        for name in ("J_regressor", "joint_template", "joint_shapedirs", "posedirs"):
            a = getattr(self, name)
            if a is not None:
                arrays[name] = a.astype(np.float32)
        if self.makehuman is not None:
            for k, a in self.makehuman.items():
                a = np.asarray(a)
                arrays["mh_" + k] = a.astype(np.int32 if np.issubdtype(a.dtype, np.integer) else np.float32)
        p = Path(path)
        with atomic_path(p) as tmp:
            with open(tmp, "wb") as fh:
                (np.savez_compressed if compressed else np.savez)(fh, **arrays)
        return p


def _from_arrays(z: dict, path: Path) -> BodyModel:
    """Build a BodyModel from our keys or SMPL's (``f``, ``kintree_table``)."""

    def get(name, *alts):
        for k in (name,) + alts:
            if k in z:
                return np.asarray(z[k])
        return None

    v = get("v_template")
    f = get("faces", "f")
    shapedirs = get("shapedirs")
    weights = get("weights")
    missing = [
        n for n, a in (("v_template", v), ("faces", f), ("shapedirs", shapedirs), ("weights", weights)) if a is None
    ]
    if missing:
        raise FileFormatError(
            "body file is missing arrays",
            path=path,
            expected="v_template, faces (or f), shapedirs, weights",
            got="missing " + ", ".join(missing),
        )
    parents = get("parents")
    if parents is None and get("kintree_table") is not None:
        kt = get("kintree_table").astype(np.int64)
        if kt.ndim != 2 or kt.shape[0] != 2:
            raise FileFormatError("kintree_table must be (2, S)", path=path, got=kt.shape)
        order = np.argsort(kt[1])
        parents = kt[0][order].copy()
        ids = {int(j): i for i, j in enumerate(kt[1][order])}
        parents = np.array([-1 if i == 0 else ids.get(int(p), -2) for i, p in enumerate(parents)], np.int64)
    if parents is None:
        raise FileFormatError("body file has no joint hierarchy", path=path, expected="'parents' or 'kintree_table'")
    s = int(np.asarray(parents).size)
    names = get("joint_names")
    if names is None:
        if s == len(SMPL_JOINT_NAMES):
            names = np.array(SMPL_JOINT_NAMES)
        else:
            names = np.array([f"joint_{i}" for i in range(s)])
    for name, a in (("v_template", v), ("shapedirs", shapedirs), ("weights", weights)):
        if not np.issubdtype(a.dtype, np.number):
            raise FileFormatError(f"{name} must be numeric", path=path, got=a.dtype)
    if not np.issubdtype(f.dtype, np.integer):
        raise FileFormatError("faces must be integers", path=path, got=f.dtype)
    if not np.issubdtype(np.asarray(parents).dtype, np.integer):
        raise FileFormatError("parents must be integers", path=path, got=np.asarray(parents).dtype)
    if shapedirs.ndim == 2 and shapedirs.shape[0] == 3 * v.shape[0]:  # flattened (3V, B)
        shapedirs = shapedirs.reshape(v.shape[0], 3, -1)
    opt = {
        k: (None if get(k) is None else get(k).astype(np.float64))
        for k in ("J_regressor", "joint_template", "joint_shapedirs", "posedirs")
    }

    def text(k, default):
        a = get(k)
        return default if a is None else str(a)

    body = BodyModel(
        v_template=v.astype(np.float64),
        faces=f.astype(np.int64),
        shapedirs=shapedirs.astype(np.float64),
        weights=weights.astype(np.float64),
        parents=np.asarray(parents).astype(np.int64),
        joint_names=tuple(str(x) for x in np.asarray(names).tolist()),
        up_axis=text("up_axis", "y"),
        units=text("units", "m"),
        licence=text("licence", ""),
        path=str(path),
        **opt,
    )
    try:
        body = body.validate()
        mh = {k[3:]: z[k] for k in z if k.startswith("mh_")}
        return body.with_makehuman(mh) if mh else body
    except InputError as e:
        raise FileFormatError(e.problem, path=path, expected=e.expected, got=e.got) from None


def load_body(path: str | os.PathLike) -> BodyModel:
    """Read a body ``.npz`` (ours or SMPL's) or an official SMPL ``.pkl``; validate everything."""
    p = Path(path)
    if not p.is_file():
        raise FileFormatError(
            "is a folder, not a body file" if p.is_dir() else "no such file",
            path=p,
            expected="a body .npz or SMPL .pkl" if p.is_dir() else None,
        )
    ext = p.suffix.lower()
    if ext == ".pkl":
        from .smpl_pickle import load_smpl_pickle

        try:
            z = load_smpl_pickle(p.read_bytes())
        except pickle.UnpicklingError as e:
            raise FileFormatError(f"refused or malformed pickle: {e}", path=p) from None
        except Exception as e:  # truncated data, bad opcodes ...
            raise FileFormatError(f"malformed pickle ({type(e).__name__}: {e})", path=p) from None
        return _from_arrays(z, p)
    if ext == ".npz":
        from ..io.npz import load_npz

        z = load_npz(p, what="body .npz")
        if "schema_version" in z and int(z["schema_version"]) != BODY_SCHEMA_VERSION:
            raise FileFormatError(
                "unsupported body schema version", path=p, expected=BODY_SCHEMA_VERSION, got=int(z["schema_version"])
            )
        return _from_arrays(z, p)
    raise FileFormatError("unknown body file type", path=p, expected=".npz or .pkl", got=ext or "none")


def default_body_path() -> Path:
    """The shipped default body (package data; ``samples/bodies/default_body.npz`` in the source tree)."""
    from ..io.resources import data_path

    p = data_path("default_body.npz")
    if not p.is_file():
        raise InputError("the default body is not available in this installation; pass a body file", expected=str(p))
    return p
