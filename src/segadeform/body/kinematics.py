"""Forward kinematics reference (numpy), smplx ``lbs.py`` style: arrays in, arrays out."""

from __future__ import annotations

import numpy as np

from ..errors import InputError
from .rotations import axis_angle_to_matrix

__all__ = ["check_parents", "forward_kinematics", "relative_transforms", "poses_to_rotmats"]


def check_parents(parents) -> np.ndarray:
    """Validate a joint hierarchy: ``parents[0] == -1`` and ``parents[j] < j`` for j > 0 (a tree rooted at 0)."""
    p = np.asarray(parents)
    if p.ndim != 1 or p.size < 1 or not np.issubdtype(p.dtype, np.integer):
        raise InputError("parents must be a 1-D integer array", got=f"{p.dtype} {p.shape}")
    p = p.astype(np.int64)
    if p[0] != -1:
        raise InputError("joint 0 must be the root (parent -1)", got=int(p[0]))
    bad = np.flatnonzero((p[1:] < 0) | (p[1:] >= np.arange(1, p.size)))
    if bad.size:
        j = int(bad[0]) + 1
        raise InputError(
            f"joint {j} has an invalid parent (each parent must come before its child)",
            expected=f"0..{j - 1}",
            got=int(p[j]),
        )
    return p


def poses_to_rotmats(poses: np.ndarray, n_joints: int | None = None) -> np.ndarray:
    """Axis-angle poses ``(..., 3S)`` to rotation matrices ``(..., S, 3, 3)``."""
    poses = np.asarray(poses, np.float64)
    if poses.shape[-1] % 3 or (n_joints is not None and poses.shape[-1] != 3 * n_joints):
        raise InputError(
            "poses must have 3 values per joint", expected=f"(..., {3 * (n_joints or 24)})", got=poses.shape
        )
    return axis_angle_to_matrix(poses.reshape(poses.shape[:-1] + (-1, 3)))


def forward_kinematics(rot: np.ndarray, joints: np.ndarray, parents, trans: np.ndarray | None = None):
    """Global joint transforms from local rotations.

    ``G_0 = [R_0 | J_0 + t]``, ``G_j = G_parent(j) [R_j | J_j - J_parent(j)]``.

    Shapes:
        rot: (B, S, 3, 3) local rotations
        joints: (B, S, 3) or (S, 3) rest-pose joint positions
        trans: (B, 3) root translation, optional
        -> global transforms (B, S, 4, 4), posed joints (B, S, 3)
    """
    p = check_parents(parents)
    rot = np.asarray(rot, np.float64)
    if rot.ndim != 4 or rot.shape[-2:] != (3, 3) or rot.shape[1] != p.size:
        raise InputError("rot must be (B, S, 3, 3)", expected=f"(B, {p.size}, 3, 3)", got=rot.shape)
    b = rot.shape[0]
    j = np.asarray(joints, np.float64)
    if j.shape not in ((p.size, 3), (b, p.size, 3)):
        raise InputError(
            "joints must be (S, 3) or (B, S, 3)", expected=f"({p.size}, 3) or ({b}, {p.size}, 3)", got=j.shape
        )
    j = np.broadcast_to(j, (b, p.size, 3))
    rel = j.copy()
    rel[:, 1:] -= j[:, p[1:]]
    local = np.zeros((b, p.size, 4, 4))
    local[..., :3, :3] = rot
    local[..., :3, 3] = rel
    local[..., 3, 3] = 1.0
    if trans is not None:
        t = np.asarray(trans, np.float64)
        if t.shape not in ((b, 3), (3,) if b == 1 else (b, 3)):
            # a transposed (3, B) was reshaped into the wrong frames' translations (a library user's trial)
            raise InputError("trans must be (B, 3)", expected=f"({b}, 3)", got=t.shape)
        if not np.isfinite(t).all():
            raise InputError("trans must be finite", expected="finite translations", got="NaN or inf")
        local[:, 0, :3, 3] += t.reshape(b, 3)
    g = np.empty_like(local)
    g[:, 0] = local[:, 0]
    for k in range(1, p.size):
        g[:, k] = g[:, p[k]] @ local[:, k]
    return g, g[..., :3, 3].copy()


def relative_transforms(global_tf: np.ndarray, joints: np.ndarray) -> np.ndarray:
    """Skinning transforms ``A_j = G_j [I | -J_j]``: map rest-pose points to posed points.

    Shapes:
        global_tf: (B, S, 4, 4), joints: (B, S, 3) or (S, 3) -> (B, S, 4, 4)
    """
    g = np.asarray(global_tf, np.float64)
    j = np.broadcast_to(np.asarray(joints, np.float64), g.shape[:-2] + (3,))
    a = g.copy()
    a[..., :3, 3] = g[..., :3, 3] - np.einsum("...ij,...j->...i", g[..., :3, :3], j)
    return a
