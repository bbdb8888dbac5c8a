"""Forward kinematics and skinning in torch, written for portable ONNX export.

No data-dependent branches (``torch.where`` instead), no Einsum (MatMul and
broadcasting), no scatter.  The numpy references in ``segadeform.body`` are
the ground truth these are tested against.
"""

from __future__ import annotations

import torch

from ..package_spec import MAX_NODE_TENSORS

__all__ = ["axis_angle_to_matrix", "forward_kinematics", "skinning_transforms", "lbs", "dqs",
           "matrix_to_quaternion"]

_SMALL = 1e-4


def axis_angle_to_matrix(r: torch.Tensor) -> torch.Tensor:
    """Rodrigues with series below 1e-4 rad (stable at 0). Shapes: (..., 3) -> (..., 3, 3)."""
    t2 = (r * r).sum(-1)
    small = t2 < _SMALL * _SMALL
    t2s = torch.where(small, torch.ones_like(t2), t2)
    t = torch.sqrt(t2s)
    a = torch.where(small, 1.0 - t2 / 6.0, torch.sin(t) / t)
    b = torch.where(small, 0.5 - t2 / 24.0, (1.0 - torch.cos(t)) / t2s)
    x, y, z = r[..., 0], r[..., 1], r[..., 2]
    zero = torch.zeros_like(x)
    K = _matrix3([[zero, -z, y], [z, zero, -x], [-y, x, zero]])
    eye = torch.eye(3, dtype=r.dtype, device=r.device).expand(K.shape)
    return eye + a[..., None, None] * K + b[..., None, None] * torch.matmul(K, K)


def forward_kinematics(rot: torch.Tensor, joints: torch.Tensor, parents: list[int],
                       trans: torch.Tensor | None = None) -> torch.Tensor:
    """Global transforms ``(B, S, 4, 4)`` from local rotations ``(B, S, 3, 3)`` and rest joints ``(B, S, 3)``."""
    b, s = rot.shape[:2]
    par = torch.tensor(list(parents[1:s]), dtype=torch.long, device=joints.device)
    rel = torch.cat([joints[:, :1], joints[:, 1:] - torch.index_select(joints, 1, par)], dim=1)  # (B, S, 3): offsets
    if trans is not None:
        rel = torch.cat([rel[:, :1] + trans[:, None], rel[:, 1:]], dim=1)
    bottom = torch.tensor([0.0, 0.0, 0.0, 1.0], dtype=rot.dtype, device=rot.device).expand(b, s, 1, 4)
    local = torch.cat([torch.cat([rot, rel[..., None]], dim=-1), bottom], dim=-2)
    g = [local[:, 0]]
    for k in range(1, s):
        g.append(torch.matmul(g[parents[k]], local[:, k]))
    return stack_narrow(g, dim=1)


def stack_narrow(ts: list, dim: int) -> torch.Tensor:
    """``torch.stack(ts, dim)`` exported as Concats of at most ``MAX_NODE_TENSORS - 1`` inputs (same values)."""
    width = MAX_NODE_TENSORS - 1
    if len(ts) <= width:
        return torch.stack(ts, dim=dim)
    return torch.cat([torch.stack(ts[i:i + width], dim=dim) for i in range(0, len(ts), width)], dim=dim)


def _matrix3(rows) -> torch.Tensor:
    """A ``(..., 3, 3)`` matrix from 3 rows of 3 ``(...)`` tensors, as 4 three-input Concats (not one of 9)."""
    return torch.stack([torch.stack(r, dim=-1) for r in rows], dim=-2)


def skinning_transforms(g: torch.Tensor, joints: torch.Tensor) -> torch.Tensor:
    """``A_j = G_j [I | -J_j]`` as ``(B, S, 3, 4)`` (the last row is constant)."""
    r = g[..., :3, :3]
    t = g[..., :3, 3] - torch.matmul(r, joints[..., None])[..., 0]
    return torch.cat([r, t[..., None]], dim=-1)


def lbs(verts: torch.Tensor, weights: torch.Tensor, a: torch.Tensor) -> torch.Tensor:
    """Linear blend skinning.

    Shapes:
        verts: (B, N, 3) or (N, 3), weights: (B, N, S), a: (B, S, 3, 4) -> (B, N, 3)
    """
    b, s = a.shape[:2]
    # blended transforms stored column-major, (B, N, 4, 3): column c of every vertex's 3x4 matrix
    m = torch.matmul(weights, a.transpose(2, 3).reshape(b, s, 12)).reshape(b, -1, 4, 3)
    return _affine(m[:, :, 0], m[:, :, 1], m[:, :, 2], m[:, :, 3], verts)


def _affine(c0: torch.Tensor, c1: torch.Tensor, c2: torch.Tensor, t: torch.Tensor, verts: torch.Tensor) -> torch.Tensor:
    """``[c0 c1 c2] @ v + t`` per vertex as multiply-adds of the matrix columns (a batch of 3x3
    MatMuls is slow in onnxruntime).

    Shapes:
        c0, c1, c2, t: (B, N, 3), verts: (B, N, 3) or (N, 3) -> (B, N, 3)
    """
    return c0 * verts[..., 0:1] + c1 * verts[..., 1:2] + c2 * verts[..., 2:3] + t


def matrix_to_quaternion(R: torch.Tensor) -> torch.Tensor:
    """Rotation matrices ``(..., 3, 3)`` to unit quaternions ``(w, x, y, z)`` (Shepperd, branch-free)."""
    m00, m11, m22 = R[..., 0, 0], R[..., 1, 1], R[..., 2, 2]
    tr = m00 + m11 + m22
    cands = torch.stack([tr, m00, m11, m22], dim=-1)
    best = torch.argmax(cands, dim=-1)

    def safe_s(x):
        return torch.sqrt(torch.clamp(1.0 + x, min=1e-12)) * 2.0

    s0, s1 = safe_s(tr), safe_s(m00 - m11 - m22)
    s2, s3 = safe_s(m11 - m00 - m22), safe_s(m22 - m00 - m11)
    q0 = torch.stack([0.25 * s0, (R[..., 2, 1] - R[..., 1, 2]) / s0, (R[..., 0, 2] - R[..., 2, 0]) / s0,
                      (R[..., 1, 0] - R[..., 0, 1]) / s0], -1)
    q1 = torch.stack([(R[..., 2, 1] - R[..., 1, 2]) / s1, 0.25 * s1, (R[..., 0, 1] + R[..., 1, 0]) / s1,
                      (R[..., 0, 2] + R[..., 2, 0]) / s1], -1)
    q2 = torch.stack([(R[..., 0, 2] - R[..., 2, 0]) / s2, (R[..., 0, 1] + R[..., 1, 0]) / s2, 0.25 * s2,
                      (R[..., 1, 2] + R[..., 2, 1]) / s2], -1)
    q3 = torch.stack([(R[..., 1, 0] - R[..., 0, 1]) / s3, (R[..., 0, 2] + R[..., 2, 0]) / s3,
                      (R[..., 1, 2] + R[..., 2, 1]) / s3, 0.25 * s3], -1)
    bb = best[..., None]
    q = torch.where(bb == 0, q0, torch.where(bb == 1, q1, torch.where(bb == 2, q2, q3)))
    return q / torch.linalg.vector_norm(q, dim=-1, keepdim=True)


def _qmul(a: torch.Tensor, b: torch.Tensor) -> torch.Tensor:
    aw, ax, ay, az = a.unbind(-1)
    bw, bx, by, bz = b.unbind(-1)
    return torch.stack([aw * bw - ax * bx - ay * by - az * bz, aw * bx + ax * bw + ay * bz - az * by,
                        aw * by - ax * bz + ay * bw + az * bx, aw * bz + ax * by - ay * bx + az * bw], -1)


def dqs(verts: torch.Tensor, weights: torch.Tensor, a: torch.Tensor, eps: float = 1e-8) -> torch.Tensor:
    """Dual-quaternion skinning (see :func:`segadeform.body.skinning.dual_quaternion_skinning`).

    Quaternions are flipped into the hemisphere of each vertex's most-weighted
    joint; a blend whose real part has norm below ``eps`` falls back to that
    joint's transform.

    Shapes: as :func:`lbs`.
    """
    b, s = a.shape[:2]
    q = matrix_to_quaternion(a[..., :3])  # (B, S, 4)
    t = torch.cat([torch.zeros_like(a[..., :1, 3]), a[..., :3, 3]], dim=-1)  # (B, S, 4) pure quaternion
    d = 0.5 * _qmul(t, q)
    pivot = torch.argmax(weights, dim=-1)  # (B, N)
    onehot = torch.nn.functional.one_hot(pivot, s).to(weights.dtype)  # (B, N, S)
    qp = torch.matmul(onehot, q)  # (B, N, 4)
    dp = torch.matmul(onehot, d)
    sign = torch.matmul(qp, q.transpose(1, 2))  # (B, N, S)
    sign = torch.where(sign < 0, -torch.ones_like(sign), torch.ones_like(sign))
    ws = weights * sign
    qb = torch.matmul(ws, q)
    db = torch.matmul(ws, d)
    norm = torch.linalg.vector_norm(qb, dim=-1, keepdim=True)
    bad = norm < eps
    qb = torch.where(bad, qp, qb)
    db = torch.where(bad, dp, db)
    norm = torch.where(bad, torch.ones_like(norm), norm)
    qb, db = qb / norm, db / norm
    w, x, y, z = qb.unbind(-1)
    R = _matrix3([[1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
                  [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
                  [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]])
    conj = qb * torch.tensor([1.0, -1.0, -1.0, -1.0], dtype=qb.dtype, device=qb.device)
    tr = 2.0 * _qmul(db, conj)[..., 1:]
    return _affine(R[..., 0], R[..., 1], R[..., 2], tr, verts)
