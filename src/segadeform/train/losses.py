"""Training losses: supervised terms against the simulation and the paper's physics terms (torch).

All functions are batched over frames: ``x (B, N, 3)`` predicted vertices.
"""

from __future__ import annotations

import torch

from ..errors import InputError

__all__ = [
    "vertex_normals",
    "vertex_loss",
    "normal_loss",
    "edge_loss",
    "stretch_loss",
    "shear_loss",
    "gravity_loss",
    "collision_loss",
    "corner_angles",
]


def vertex_normals(x: torch.Tensor, faces: torch.Tensor) -> torch.Tensor:
    """Area-weighted vertex normals. x (B, N, 3), faces (F, 3) -> (B, N, 3)."""
    a, b, c = x[:, faces[:, 0]], x[:, faces[:, 1]], x[:, faces[:, 2]]
    fn = torch.cross(b - a, c - a, dim=-1)
    n = torch.zeros_like(x)
    for k in range(3):
        n = n.index_add(1, faces[:, k], fn)
    return n / n.norm(dim=-1, keepdim=True).clamp_min(1e-12)


def vertex_loss(x, y):
    """Mean Euclidean vertex distance (m)."""
    return (x - y).norm(dim=-1).mean()


def normal_loss(x, y, faces):
    """Mean ``1 - cos`` between predicted and simulated vertex normals."""
    return (1 - (vertex_normals(x, faces) * vertex_normals(y, faces)).sum(-1)).mean()


def _lengths(x, edges):
    return (x[:, edges[:, 0]] - x[:, edges[:, 1]]).norm(dim=-1)


def edge_loss(x, y, edges):
    """Mean |edge length - simulated edge length| (m)."""
    return (_lengths(x, edges) - _lengths(y, edges)).abs().mean()


def stretch_loss(x, rest, edges):
    """Mean squared edge strain against the rest garment (membrane stretch energy, per unit stiffness)."""
    l0 = _lengths(rest[None], edges).clamp_min(1e-9)
    return ((_lengths(x, edges) / l0 - 1) ** 2).mean()


def corner_angles(x, faces):
    """Cosines of the three corner angles of every triangle: (B, F, 3)."""
    out = []
    for i in range(3):
        p, q, r = x[:, faces[:, i]], x[:, faces[:, (i + 1) % 3]], x[:, faces[:, (i + 2) % 3]]
        u, v = q - p, r - p
        out.append((u * v).sum(-1) / (u.norm(dim=-1) * v.norm(dim=-1)).clamp_min(1e-12))
    return torch.stack(out, -1)


def shear_loss(x, rest, faces):
    """Mean squared change of the corner-angle cosines against the rest garment (in-plane shear)."""
    return ((corner_angles(x, faces) - corner_angles(rest[None], faces)) ** 2).mean()


def gravity_loss(x, rest, g: float = 9.81):
    """Mean gravitational potential per unit mass relative to the rest garment, ``g (y - y_rest)``."""
    return (g * (x[..., 1] - rest[None, :, 1])).mean()


def collision_loss(x, body_p, body_n, margin: float = 0.002, power: int = 2, near: float = 0.0, y=None):
    """Mean depth below ``margin`` above the body surface (closest point and normal given), squared
    (``power`` 2) or not (1: metres, the unit of :func:`vertex_loss`).

    ``body_p``, ``body_n`` are the closest body point to each *simulated* vertex ``y`` and the normal there: the
    body is replaced by that tangent plane, which stands for it only near the contact.  ``near`` > 0 counts only
    the vertices whose simulated position is within ``near`` of the plane (``y`` required); the mean is still
    over every vertex, so the term's scale does not depend on how many are near.

    Shapes: x, body_p, body_n, y (..., N, 3) -> ()"""
    d = ((x - body_p) * body_n).sum(-1)
    depth = torch.relu(margin - d).pow(power)
    if near > 0:
        if y is None:
            raise InputError("collision_loss with near > 0 needs the simulated vertices y")
        depth = depth * (((y - body_p) * body_n).sum(-1) < near)
    return depth.mean()
