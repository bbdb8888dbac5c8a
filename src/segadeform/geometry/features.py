"""Per-vertex input features of the graph encoder (§4.1)."""

from __future__ import annotations

import numpy as np

from ..errors import InputError
from ._checks import check_mesh, check_vertices
from .mesh_ops import vertex_normals

__all__ = ["vertex_features", "feature_dim"]


def feature_dim(n_joints: int) -> int:
    """The width of :func:`vertex_features`' rows for a skeleton of ``n_joints`` joints: position (3), normal (3) and
    one skinning weight per joint."""
    return 6 + int(n_joints)


def vertex_features(vertices, faces, joints, *, normals: np.ndarray | None = None) -> np.ndarray:
    """``x_i = [p_i, n_i, d_i]``: position, unit normal, distances to the S rest-pose joints.

    Shapes:
        vertices: (N, 3), faces: (F, 3), joints: (S, 3) -> (N, 6 + S) float32
    """
    v, f = check_mesh(vertices, faces)
    j = check_vertices(joints, "joints")
    n = vertex_normals(v, f) if normals is None else np.asarray(normals, np.float64)
    if n.shape != v.shape:
        raise InputError("normals must match vertices", expected=v.shape, got=n.shape)
    d = np.linalg.norm(v[:, None, :] - j[None, :, :], axis=2)
    return np.concatenate([v, n, d], axis=1).astype(np.float32)
