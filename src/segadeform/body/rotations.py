"""Rotation conversions (numpy), numerically stable at angle 0 and near pi.

Conventions: axis-angle vectors ``r = theta * axis``; quaternions ``(w, x, y, z)``;
matrices act on column vectors (``p' = R p``).  All functions broadcast over
leading axes.
"""

from __future__ import annotations

import numpy as np

from ..errors import InputError

__all__ = [
    "axis_angle_to_matrix",
    "matrix_to_axis_angle",
    "canonical_axis_angle",
    "matrix_to_quaternion",
    "quaternion_to_matrix",
    "quaternion_multiply",
    "quaternion_slerp",
    "axis_angle_to_quaternion",
    "quaternion_to_axis_angle",
    "euler_to_matrix",
    "matrix_to_euler",
]

_SMALL = 1e-4  # below this angle the series expansions are exact to float64


def axis_angle_to_matrix(r: np.ndarray) -> np.ndarray:
    """Rodrigues' formula ``R = I + A K + B K^2`` with ``A = sin t / t``, ``B = (1 - cos t) / t^2``.

    ``A`` and ``B`` use their Taylor series below ``1e-4`` rad, so ``r = 0``
    gives exactly ``I`` and tiny angles lose no precision.

    Shapes:
        r: (..., 3) -> (..., 3, 3)
    """
    r = np.asarray(r, np.float64)
    if r.ndim < 1 or r.shape[-1] != 3:  # (3, 96) gave (3, 3, 3) from its first columns (a library user's trial)
        raise InputError("axis-angle vectors must be (..., 3)", expected="(..., 3)", got=r.shape)
    t2 = np.sum(r * r, axis=-1)
    t = np.sqrt(t2)
    small = t < _SMALL
    ts = np.where(small, 1.0, t)
    a = np.where(small, 1.0 - t2 / 6.0 + t2 * t2 / 120.0, np.sin(ts) / ts)
    b = np.where(small, 0.5 - t2 / 24.0 + t2 * t2 / 720.0, (1.0 - np.cos(ts)) / (ts * ts))
    x, y, z = r[..., 0], r[..., 1], r[..., 2]
    zero = np.zeros_like(x)
    K = np.stack([zero, -z, y, z, zero, -x, -y, x, zero], axis=-1).reshape(r.shape[:-1] + (3, 3))
    eye = np.broadcast_to(np.eye(3), K.shape)
    return eye + a[..., None, None] * K + b[..., None, None] * (K @ K)


def matrix_to_quaternion(R: np.ndarray) -> np.ndarray:
    """Rotation matrix to unit quaternion ``(w, x, y, z)`` with ``w >= 0`` (Shepperd's method).

    Picks the largest of ``w, x, y, z`` to divide by, so it is stable for all
    angles including pi.

    Shapes:
        R: (..., 3, 3) -> (..., 4)
    """
    R = np.asarray(R, np.float64)
    m00, m11, m22 = R[..., 0, 0], R[..., 1, 1], R[..., 2, 2]
    tr = m00 + m11 + m22
    cand = np.stack([tr, m00, m11, m22], axis=-1)
    k = np.argmax(cand, axis=-1)
    q = np.empty(R.shape[:-2] + (4,))
    # case w largest
    s = np.sqrt(np.maximum(1.0 + cand[..., 0], 1e-300)) * 2
    qw = np.stack(
        [
            0.25 * s,
            (R[..., 2, 1] - R[..., 1, 2]) / s,
            (R[..., 0, 2] - R[..., 2, 0]) / s,
            (R[..., 1, 0] - R[..., 0, 1]) / s,
        ],
        -1,
    )
    s = np.sqrt(np.maximum(1.0 + m00 - m11 - m22, 1e-300)) * 2
    qx = np.stack(
        [
            (R[..., 2, 1] - R[..., 1, 2]) / s,
            0.25 * s,
            (R[..., 0, 1] + R[..., 1, 0]) / s,
            (R[..., 0, 2] + R[..., 2, 0]) / s,
        ],
        -1,
    )
    s = np.sqrt(np.maximum(1.0 + m11 - m00 - m22, 1e-300)) * 2
    qy = np.stack(
        [
            (R[..., 0, 2] - R[..., 2, 0]) / s,
            (R[..., 0, 1] + R[..., 1, 0]) / s,
            0.25 * s,
            (R[..., 1, 2] + R[..., 2, 1]) / s,
        ],
        -1,
    )
    s = np.sqrt(np.maximum(1.0 + m22 - m00 - m11, 1e-300)) * 2
    qz = np.stack(
        [
            (R[..., 1, 0] - R[..., 0, 1]) / s,
            (R[..., 0, 2] + R[..., 2, 0]) / s,
            (R[..., 1, 2] + R[..., 2, 1]) / s,
            0.25 * s,
        ],
        -1,
    )
    q = np.choose(k[..., None], [qw, qx, qy, qz])
    q = q / np.linalg.norm(q, axis=-1, keepdims=True)
    return np.where(q[..., :1] < 0, -q, q)


def quaternion_to_matrix(q: np.ndarray) -> np.ndarray:
    """Unit quaternion ``(w, x, y, z)`` to rotation matrix (normalises first).

    Shapes:
        q: (..., 4) -> (..., 3, 3)
    """
    q = np.asarray(q, np.float64)
    q = q / np.linalg.norm(q, axis=-1, keepdims=True)
    w, x, y, z = q[..., 0], q[..., 1], q[..., 2], q[..., 3]
    return np.stack(
        [
            1 - 2 * (y * y + z * z),
            2 * (x * y - z * w),
            2 * (x * z + y * w),
            2 * (x * y + z * w),
            1 - 2 * (x * x + z * z),
            2 * (y * z - x * w),
            2 * (x * z - y * w),
            2 * (y * z + x * w),
            1 - 2 * (x * x + y * y),
        ],
        axis=-1,
    ).reshape(q.shape[:-1] + (3, 3))


def quaternion_to_axis_angle(q: np.ndarray) -> np.ndarray:
    """Quaternion to axis-angle with angle in ``[0, pi]``; stable at 0 (series) and pi (atan2).

    Shapes:
        q: (..., 4) -> (..., 3)
    """
    q = np.asarray(q, np.float64)
    q = q / np.linalg.norm(q, axis=-1, keepdims=True)
    q = np.where(q[..., :1] < 0, -q, q)
    v = q[..., 1:]
    s = np.linalg.norm(v, axis=-1)
    theta = 2.0 * np.arctan2(s, q[..., 0])
    small = s < _SMALL
    ss = np.where(small, 1.0, s)
    # theta / s -> 2 / w (1 + s^2 / (3 w^2) ...) for small s; w ~ 1 there
    w = q[..., 0]
    factor = np.where(
        small, 2.0 / np.maximum(w, 1e-300) * (1.0 - s * s / (3.0 * np.maximum(w * w, 1e-300))), theta / ss
    )
    return v * factor[..., None]


def canonical_axis_angle(r: np.ndarray) -> np.ndarray:
    """The same rotations with every angle in ``[0, pi]``: an angle above pi is taken modulo 2 pi, and one still
    above pi becomes 2 pi minus it about the opposite axis.  Vectors already in range are returned bit for bit
    (the network reads axis-angle, so equal rotations must be written alike: a user's hip turned by 720 degrees
    more moved the garment by centimetres).

    Shapes:
        r: (..., 3) -> (..., 3)
    """
    r = np.asarray(r, np.float64)
    t = np.linalg.norm(r, axis=-1)
    over = t > np.pi
    if not over.any():
        return r
    out = r.copy()
    ro, to = r[over], t[over]
    axis = ro / to[:, None]
    a = np.mod(to, 2.0 * np.pi)
    flip = a > np.pi
    a = np.where(flip, 2.0 * np.pi - a, a)
    out[over] = np.where(flip[:, None], -axis, axis) * a[:, None]
    return out


def matrix_to_axis_angle(R: np.ndarray) -> np.ndarray:
    """Rotation matrix to axis-angle (angle in ``[0, pi]``), via a stable quaternion."""
    return quaternion_to_axis_angle(matrix_to_quaternion(R))


def axis_angle_to_quaternion(r: np.ndarray) -> np.ndarray:
    """Axis-angle to unit quaternion ``(w, x, y, z)`` (series below 1e-4 rad)."""
    r = np.asarray(r, np.float64)
    t = np.linalg.norm(r, axis=-1)
    small = t < _SMALL
    ts = np.where(small, 1.0, t)
    k = np.where(small, 0.5 - t * t / 48.0, np.sin(ts / 2) / ts)
    return np.concatenate([np.cos(t / 2)[..., None], r * k[..., None]], axis=-1)


def quaternion_multiply(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Hamilton product ``a * b`` (rotation b first, then a)."""
    a, b = np.asarray(a, np.float64), np.asarray(b, np.float64)
    aw, ax, ay, az = np.moveaxis(a, -1, 0)
    bw, bx, by, bz = np.moveaxis(b, -1, 0)
    return np.stack(
        [
            aw * bw - ax * bx - ay * by - az * bz,
            aw * bx + ax * bw + ay * bz - az * by,
            aw * by - ax * bz + ay * bw + az * bx,
            aw * bz + ax * by - ay * bx + az * bw,
        ],
        axis=-1,
    )


def quaternion_slerp(a: np.ndarray, b: np.ndarray, t) -> np.ndarray:
    """Spherical interpolation along the shorter arc; falls back to nlerp for nearly equal inputs."""
    a = np.asarray(a, np.float64)
    b = np.asarray(b, np.float64)
    t = np.asarray(t, np.float64)[..., None]
    dot = np.sum(a * b, axis=-1, keepdims=True)
    b = np.where(dot < 0, -b, b)
    dot = np.abs(dot)
    close = dot > 0.9995
    om = np.arccos(np.clip(dot, -1.0, 1.0))
    so = np.where(close, 1.0, np.sin(om))
    wa = np.where(close, 1.0 - t, np.sin((1.0 - t) * om) / so)
    wb = np.where(close, t, np.sin(t * om) / so)
    q = wa * a + wb * b
    return q / np.linalg.norm(q, axis=-1, keepdims=True)


_AXES = {"x": 0, "y": 1, "z": 2}


def _axis_matrix(axis: str, ang: np.ndarray) -> np.ndarray:
    r = np.zeros(np.shape(ang) + (3,))
    r[..., _AXES[axis]] = ang
    return axis_angle_to_matrix(r)


def euler_to_matrix(angles: np.ndarray, order: str) -> np.ndarray:
    """Intrinsic Euler angles (radians) to matrix: ``R = R_order[0] @ R_order[1] @ R_order[2]``.

    This is BVH's convention: channels listed as ``Zrotation Xrotation
    Yrotation`` mean ``R = Rz Rx Ry``.

    Shapes:
        angles: (..., 3) in the order given -> (..., 3, 3)
    """
    order = order.lower()
    angles = np.asarray(angles, np.float64)
    R = _axis_matrix(order[0], angles[..., 0])
    for i in (1, 2):
        R = R @ _axis_matrix(order[i], angles[..., i])
    return R


def matrix_to_euler(R: np.ndarray, order: str) -> np.ndarray:
    """Inverse of :func:`euler_to_matrix` for any of the six orders (gimbal lock: third angle 0).

    Shapes:
        R: (..., 3, 3) -> (..., 3) radians, in ``order``
    """
    order = order.lower()
    i, j, k = (_AXES[c] for c in order)
    R = np.asarray(R, np.float64)
    # sign of the permutation (i, j, k)
    sign = 1.0 if (j - i) % 3 == 1 else -1.0
    # For R = Ri(a) Rj(b) Rk(c): R[i, k] = sign * sin(b)
    sb = np.clip(sign * R[..., i, k], -1.0, 1.0)
    b = np.arcsin(sb)
    cb = np.sqrt(np.maximum(0.0, 1.0 - sb * sb))
    lock = cb < 1e-9
    a = np.arctan2(-sign * R[..., j, k], R[..., k, k])
    c = np.arctan2(-sign * R[..., i, j], R[..., i, i])
    # gimbal lock: c = 0, a from the remaining block
    a_lock = np.arctan2(sign * R[..., k, j], R[..., j, j])
    a = np.where(lock, a_lock, a)
    c = np.where(lock, 0.0, c)
    return np.stack([a, b, c], axis=-1)
