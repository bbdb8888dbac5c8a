"""Skinning references (numpy): linear blend skinning and dual-quaternion skinning."""

from __future__ import annotations

import numpy as np

from ..errors import InputError
from .rotations import matrix_to_quaternion, quaternion_multiply, quaternion_to_matrix

__all__ = ["linear_blend_skinning", "dual_quaternion_skinning", "transforms_to_dual_quaternions"]


def _check(vertices, weights, transforms):
    v = np.asarray(vertices, np.float64)
    w = np.asarray(weights, np.float64)
    a = np.asarray(transforms, np.float64)
    if a.ndim != 4 or a.shape[-2:] != (4, 4):
        raise InputError("transforms must be (B, S, 4, 4)", got=a.shape)
    b, s = a.shape[:2]
    if v.ndim == 2:
        v = np.broadcast_to(v, (b,) + v.shape)
    if v.ndim != 3 or v.shape[-1] != 3 or v.shape[0] != b:
        raise InputError("vertices must be (N, 3) or (B, N, 3)", expected=f"(N, 3) or ({b}, N, 3)", got=v.shape)
    n = v.shape[1]
    if w.ndim == 2:
        w = np.broadcast_to(w, (b,) + w.shape)
    if w.shape != (b, n, s):
        raise InputError("weights must be (N, S) or (B, N, S)", expected=f"({n}, {s})", got=w.shape)
    return v, w, a


def linear_blend_skinning(vertices, weights, transforms) -> np.ndarray:
    """``v'_i = sum_j w_ij (A_j v_i)``: blend the transforms, then apply.

    Shapes:
        vertices: (N, 3) or (B, N, 3) rest positions
        weights: (N, S) or (B, N, S)
        transforms: (B, S, 4, 4) relative (skinning) transforms
        -> (B, N, 3)
    """
    v, w, a = _check(vertices, weights, transforms)
    m = np.einsum("bns,bsij->bnij", w, a[..., :3, :])  # (B, N, 3, 4)
    return np.einsum("bnij,bnj->bni", m[..., :3], v) + m[..., 3]


def transforms_to_dual_quaternions(transforms) -> tuple[np.ndarray, np.ndarray]:
    """Rigid transforms ``(..., 4, 4)`` to unit dual quaternions: real ``q`` and dual ``d = 0.5 (0, t) q``.

    Shapes:
        transforms: (..., 4, 4) -> (..., 4), (..., 4)
    """
    a = np.asarray(transforms, np.float64)
    q = matrix_to_quaternion(a[..., :3, :3])
    t = np.concatenate([np.zeros(a.shape[:-2] + (1,)), a[..., :3, 3]], axis=-1)
    return q, 0.5 * quaternion_multiply(t, q)


def dual_quaternion_skinning(vertices, weights, transforms, *, eps: float = 1e-8) -> np.ndarray:
    """Dual-quaternion skinning (Kavan et al. 2007).

    Each vertex blends its joints' dual quaternions after flipping every one
    into the hemisphere of the vertex's most-weighted joint (``q`` and ``-q``
    are the same rotation; blending opposite signs would cancel).  The blend
    is normalised by its real part's norm; where that norm falls below
    ``eps`` (a blend of rotations that cancel), the vertex takes its
    most-weighted joint's transform instead, so the result is always finite.

    Shapes: as :func:`linear_blend_skinning`.
    """
    v, w, a = _check(vertices, weights, transforms)
    q, d = transforms_to_dual_quaternions(a)  # (B, S, 4)
    pivot = np.argmax(w, axis=-1)  # (B, N)
    qp = np.take_along_axis(q[:, None, :, :], pivot[:, :, None, None], axis=2)[:, :, 0]  # (B, N, 4)
    sign = np.sign(np.einsum("bnk,bsk->bns", qp, q))
    sign[sign == 0] = 1.0
    ws = w * sign
    qb = np.einsum("bns,bsk->bnk", ws, q)
    db = np.einsum("bns,bsk->bnk", ws, d)
    norm = np.linalg.norm(qb, axis=-1, keepdims=True)
    bad = norm[..., 0] < eps
    if bad.any():
        dp = np.take_along_axis(d[:, None, :, :], pivot[:, :, None, None], axis=2)[:, :, 0]
        qb = np.where(bad[..., None], qp, qb)
        db = np.where(bad[..., None], dp, db)
        norm = np.where(bad[..., None], 1.0, norm)
    qb, db = qb / norm, db / norm
    R = quaternion_to_matrix(qb)
    conj = qb * np.array([1.0, -1.0, -1.0, -1.0])
    t = 2.0 * quaternion_multiply(db, conj)[..., 1:]
    return np.einsum("bnij,bnj->bni", R, v) + t
