"""Skinning references (numpy): linear blend skinning and dual-quaternion skinning."""

from __future__ import annotations

import numpy as np

from ..errors import InputError
from .rotations import matrix_to_quaternion, quaternion_multiply

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
    b, s = a.shape[:2]
    m = _blend(w, a[..., :3, :].reshape(b, s, 12)).reshape(b, -1, 3, 4)  # (B, N, 3, 4)
    return _apply(m[..., :3], v) + m[..., 3]


def _blend(w, x):
    """``sum_s w[b, n, s] x[b, s, :]`` as BLAS products: ``w (B, N, S)``, ``x (B, S, C)`` -> ``(B, N, C)``.
    One product for every frame when the weights are shared (a broadcast ``w``)."""
    if w.strides[0] == 0:  # the same (N, S) weights for every frame
        b, s, c = x.shape
        return (w[0] @ x.transpose(1, 0, 2).reshape(s, b * c)).reshape(-1, b, c).transpose(1, 0, 2)
    return np.matmul(w, x)


def _apply(r, v):
    """``r (B, N, 3, 3)`` times ``v (B, N, 3)`` per vertex, as three multiply-adds (no einsum loop)."""
    return r[..., 0] * v[..., 0, None] + r[..., 1] * v[..., 1, None] + r[..., 2] * v[..., 2, None]


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
    b, s = q.shape[:2]
    n = w.shape[1]
    qd8 = np.concatenate([q, d], axis=-1)  # (B, S, 8)
    # the blend, component-major: c[k] (B, N) for the 8 components (contiguous rows, cheap elementwise passes)
    if w.strides[0] == 0:  # weights shared by every frame: the pivot and the flips depend on the pivot joint only
        pivot = np.broadcast_to(np.argmax(w[0], axis=-1), (b, n))
        flip = np.sign(np.matmul(q, q.transpose(0, 2, 1)))  # (B, S pivot, S): q_j's sign against pivot q_p
        flip[flip == 0] = 1.0
        c = np.empty((8, b, n))
        for jp in np.unique(pivot[0]):  # one BLAS product per pivot joint (<= S), no (B, N, S) arrays
            rows = np.flatnonzero(pivot[0] == jp)
            signed = (flip[:, jp, :, None] * qd8).transpose(1, 0, 2).reshape(s, b * 8)
            c[:, :, rows] = (w[0, rows] @ signed).reshape(-1, b, 8).transpose(2, 1, 0)
    else:
        pivot = np.argmax(w, axis=-1)  # (B, N)
        qp = np.take_along_axis(q[:, None, :, :], pivot[:, :, None, None], axis=2)[:, :, 0]  # (B, N, 4)
        sign = np.sign(np.matmul(qp, q.transpose(0, 2, 1)))  # (B, N, S)
        sign[sign == 0] = 1.0
        c = np.ascontiguousarray(np.matmul(w * sign, qd8).transpose(2, 0, 1))
    norm = np.sqrt(c[0] ** 2 + c[1] ** 2 + c[2] ** 2 + c[3] ** 2)  # (B, N)
    bad = norm < eps
    if bad.any():  # the pivot joint's own dual quaternion
        piv = qd8[np.arange(b)[:, None], pivot]  # (B, N, 8)
        c[:, bad] = piv[bad].T
        norm[bad] = 1.0
    c /= norm
    qw, ux, uy, uz, dw, dx, dy, dz = c
    vx, vy, vz = (v[..., i] for i in range(3))
    # rotate by (w, u): v + 2 w (u x v) + 2 u x (u x v); translate by t = 2 (d q*)_vec = 2 (w d - d_w u + u x d)
    cx, cy, cz = uy * vz - uz * vy, uz * vx - ux * vz, ux * vy - uy * vx
    out = np.empty((b, n, 3))
    out[..., 0] = vx + 2.0 * (qw * cx + uy * cz - uz * cy + qw * dx - dw * ux + uy * dz - uz * dy)
    out[..., 1] = vy + 2.0 * (qw * cy + uz * cx - ux * cz + qw * dy - dw * uy + uz * dx - ux * dz)
    out[..., 2] = vz + 2.0 * (qw * cz + ux * cy - uy * cx + qw * dz - dw * uz + ux * dy - uy * dx)
    return out
