"""Forward kinematics and skinning in torch, written for portable ONNX export.

No data-dependent branches (``torch.where`` instead), no Einsum (MatMul and
broadcasting), no scatter.  The numpy references in ``segadeform.body`` are
the ground truth these are tested against.
"""

from __future__ import annotations

import torch

from ..contracts.model_package import MAX_NODE_TENSORS

__all__ = [
    "axis_angle_to_matrix",
    "heading_free_window",
    "forward_kinematics",
    "skinning_transforms",
    "lbs",
    "dqs",
    "matrix_to_quaternion",
]

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


def heading_free_window(window: torch.Tensor, eps: float = 1e-8) -> torch.Tensor:
    """The motion window with the root's rotation taken relative to the current frame's heading.

    The heading is the turn about the vertical (+Y) axis left when the current root rotation ``R_0`` is split into
    a turn about +Y and a tilt of the vertical (swing-twist); its cosine and sine are proportional to
    ``(R_00 + R_22, R_20 - R_02)``::

        a = (R_00 + R_22, R_20 - R_02) / sqrt((R_00 + R_22)^2 + (R_20 - R_02)^2 + eps),
        H = [[a_0, 0, a_1], [0, 1, 0], [-a_1, 0, a_0]],   R'_t = H R_t   for every frame t of the window.

    Turning the whole motion about +Y by ``Q`` maps ``R_t -> Q R_t`` and ``a`` by the same turn, so ``H -> H Q^T``
    and ``R'_t`` does not change: what reads the result sees the same motion whichever way it faces.  ``a`` is
    defined whether the body stands, bends, or lies on its front, back or side; it vanishes only where the body's
    vertical axis points straight down (upside down), where ``H`` degrades to a bounded, non-rotation matrix
    instead of dividing by zero.

    Shapes:
        window (B, T, 3 S) axis-angle, window[:, 0] the current frame -> (B, T, 3 S + 6): the 9 entries of
        ``R'_t`` (row-major) followed by the other ``S - 1`` joints' axis-angle as given.
    """
    b, t, _ = window.shape
    rot = axis_angle_to_matrix(window[:, :, :3])  # (B, T, 3, 3)
    r0 = rot[:, 0]  # the current root's rotation
    ca, sa = r0[:, 0, 0] + r0[:, 2, 2], r0[:, 2, 0] - r0[:, 0, 2]
    n = torch.sqrt(ca * ca + sa * sa + eps)
    c, s = ca / n, sa / n
    zero, one = torch.zeros_like(c), torch.ones_like(c)
    h = _matrix3([[c, zero, s], [zero, one, zero], [-s, zero, c]])  # (B, 3, 3)
    rel = torch.matmul(h[:, None], rot).reshape(b, t, 9)
    return torch.cat([rel, window[:, :, 3:]], dim=-1)


def forward_kinematics(
    rot: torch.Tensor, joints: torch.Tensor, parents: list[int], trans: torch.Tensor | None = None
) -> torch.Tensor:
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
    return torch.cat([torch.stack(ts[i : i + width], dim=dim) for i in range(0, len(ts), width)], dim=dim)


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

    Laid out for onnxruntime's fast paths: the blended 3x4 matrices are formed component-major,
    ``(B, 12, N)`` (one MatMul against the transposed weights), so every later operation is an
    element-wise one on contiguous ``(B, N)`` rows; the vertex-major ``(B, N, 4, 3)`` layout spent most
    of its time in strided slices and ``(B, N, 1)`` broadcasts.

    Shapes:
        verts: (B, N, 3) or (N, 3), weights: (B, N, S) or (N, S), a: (B, S, 3, 4) -> (B, N, 3)
    """
    b, s = a.shape[:2]
    at = a.reshape(b, s, 12).transpose(1, 2)  # (B, 12, S): row 4 r + c holds A[r, c]
    m = torch.matmul(at, weights.transpose(-1, -2))  # (B, 12, N)
    vx, vy, vz = _planar(verts)
    rows = [m[:, 4 * r] * vx + m[:, 4 * r + 1] * vy + m[:, 4 * r + 2] * vz + m[:, 4 * r + 3] for r in range(3)]
    return torch.stack(rows, dim=-1)


def _planar(verts: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
    """The x, y, z rows of ``verts (..., N, 3)``, each ``(..., N)``."""
    return verts[..., 0], verts[..., 1], verts[..., 2]


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
    q0 = torch.stack(
        [
            0.25 * s0,
            (R[..., 2, 1] - R[..., 1, 2]) / s0,
            (R[..., 0, 2] - R[..., 2, 0]) / s0,
            (R[..., 1, 0] - R[..., 0, 1]) / s0,
        ],
        -1,
    )
    q1 = torch.stack(
        [
            (R[..., 2, 1] - R[..., 1, 2]) / s1,
            0.25 * s1,
            (R[..., 0, 1] + R[..., 1, 0]) / s1,
            (R[..., 0, 2] + R[..., 2, 0]) / s1,
        ],
        -1,
    )
    q2 = torch.stack(
        [
            (R[..., 0, 2] - R[..., 2, 0]) / s2,
            (R[..., 0, 1] + R[..., 1, 0]) / s2,
            0.25 * s2,
            (R[..., 1, 2] + R[..., 2, 1]) / s2,
        ],
        -1,
    )
    q3 = torch.stack(
        [
            (R[..., 1, 0] - R[..., 0, 1]) / s3,
            (R[..., 0, 2] + R[..., 2, 0]) / s3,
            (R[..., 1, 2] + R[..., 2, 1]) / s3,
            0.25 * s3,
        ],
        -1,
    )
    bb = best[..., None]
    q = torch.where(bb == 0, q0, torch.where(bb == 1, q1, torch.where(bb == 2, q2, q3)))
    return q / torch.linalg.vector_norm(q, dim=-1, keepdim=True)


def _qmul(a: torch.Tensor, b: torch.Tensor) -> torch.Tensor:
    aw, ax, ay, az = a.unbind(-1)
    bw, bx, by, bz = b.unbind(-1)
    return torch.stack(
        [
            aw * bw - ax * bx - ay * by - az * bz,
            aw * bx + ax * bw + ay * bz - az * by,
            aw * by - ax * bz + ay * bw + az * bx,
            aw * bz + ax * by - ay * bx + az * bw,
        ],
        -1,
    )


def dqs(verts: torch.Tensor, weights: torch.Tensor, a: torch.Tensor, eps: float = 1e-8) -> torch.Tensor:
    """Dual-quaternion skinning (see :func:`segadeform.body.skinning.dual_quaternion_skinning`).

    Quaternions are flipped into the hemisphere of each vertex's most-weighted
    joint; a blend whose real part has norm below ``eps`` falls back to that
    joint's transform.

    Laid out as :func:`lbs`: which joints flip depends only on the pair (pivot joint, joint), so an
    ``(S, S)`` sign table per frame is gathered by pivot, and so is the pivot's own dual quaternion
    (row Gathers, no ``(B, N, S)`` comparison or Where); the blend is one MatMul into component-major
    ``(B, 8, N)`` and everything after it is element-wise on contiguous ``(B, N)`` rows.

    Shapes: as :func:`lbs`.
    """
    b, s = a.shape[:2]
    n = weights.shape[-2]
    q = matrix_to_quaternion(a[..., :3])  # (B, S, 4)
    t = torch.cat([torch.zeros_like(a[..., :1, 3]), a[..., :3, 3]], dim=-1)  # (B, S, 4) pure quaternion
    d = 0.5 * _qmul(t, q)
    qd = torch.cat([q, d], dim=-1)  # (B, S, 8)
    # sign[j, k] = +1 when joint k's quaternion lies in joint j's hemisphere (q_j . q_k >= 0), else -1;
    # sign(sign(x) + 0.5) maps x >= 0 to +1 and x < 0 to -1
    sign = torch.sign(torch.sign(torch.matmul(q, q.transpose(1, 2))) + 0.5)  # (B, S, S)
    # weights shared by every frame (N, S) are only read transposed (see below)
    wt = weights.transpose(0, 1) if weights.dim() == 2 else None
    pivot = torch.argmax(wt, dim=0) if wt is not None else torch.argmax(weights, dim=-1)  # (N,) or (B, N)
    rows = (pivot + (torch.arange(b, device=a.device) * s)[:, None]).reshape(-1)  # (B N): row of (frame, pivot)
    signs = torch.index_select(sign.reshape(b * s, s), 0, rows).reshape(b, n, s)
    # each joint's weight, signed into the pivot's hemisphere, joint-major (B, S, N) for the blend's MatMul
    if wt is not None:  # shared by every frame: only the transposed weights are read (an exported body
        # graph then stores the one (S, N) copy its LBS sibling stores too)
        wst = wt * signs.transpose(1, 2)
    else:
        wst = (weights * signs).transpose(1, 2)
    qdb = torch.matmul(qd.transpose(1, 2), wst)  # (B, 8, N)
    # the pivot's dual quaternion, component-major (8, B, N)
    qdp = torch.index_select(qd.reshape(b * s, 8), 0, rows).transpose(0, 1).reshape(8, b, n)
    c = [qdb[:, i] for i in range(8)]
    norm = torch.sqrt(c[0] * c[0] + c[1] * c[1] + c[2] * c[2] + c[3] * c[3])
    bad = (norm < eps).to(norm.dtype)  # 1 where the blend falls back to the pivot
    c = [ci + bad * (qdp[i] - ci) for i, ci in enumerate(c)]
    inv = 1.0 / (norm + bad * (1.0 - norm))  # the pivot is a unit quaternion
    w, x, y, z, dw, dx, dy, dz = [ci * inv for ci in c]
    # translation: 2 (db * conj(qb)), its vector part
    tx = 2.0 * (-dw * x + dx * w - dy * z + dz * y)
    ty = 2.0 * (-dw * y + dx * z + dy * w - dz * x)
    tz = 2.0 * (-dw * z - dx * y + dy * x + dz * w)
    vx, vy, vz = _planar(verts)
    xx, yy, zz, xy, xz, yz, wx, wy, wz = x * x, y * y, z * z, x * y, x * z, y * z, w * x, w * y, w * z
    px = (1 - 2 * (yy + zz)) * vx + 2 * (xy - wz) * vy + 2 * (xz + wy) * vz + tx
    py = 2 * (xy + wz) * vx + (1 - 2 * (xx + zz)) * vy + 2 * (yz - wx) * vz + ty
    pz = 2 * (xz - wy) * vx + 2 * (yz + wx) * vy + (1 - 2 * (xx + yy)) * vz + tz
    return torch.stack([px, py, pz], dim=-1)
