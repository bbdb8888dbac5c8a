"""Input validation shared by the geometry functions (potpourri3d style)."""

from __future__ import annotations

import numpy as np

from ..errors import InputError


def check_vertices(vertices, name: str = "vertices") -> np.ndarray:
    v = np.asarray(vertices)
    if v.ndim != 2 or v.shape[1] != 3:
        raise InputError(f"{name} must be (N, 3)", expected="(N, 3)", got=v.shape)
    if v.shape[0] == 0:
        raise InputError(f"{name} is empty", expected="N >= 1", got=0)
    v = v.astype(np.float64, copy=False)
    if not np.isfinite(v).all():
        raise InputError(f"{name} contains NaN or inf")
    return v


def check_faces(faces, n_vertices: int) -> np.ndarray:
    f = np.asarray(faces)
    if f.ndim != 2 or f.shape[1] != 3:
        raise InputError("faces must be (F, 3)", expected="(F, 3)", got=f.shape)
    if f.size and not np.issubdtype(f.dtype, np.integer):
        raise InputError("faces must be integers", got=f.dtype)
    f = f.astype(np.int64, copy=False)
    if f.size and (f.min() < 0 or f.max() >= n_vertices):
        raise InputError(
            "face index out of range",
            expected=f"0..{n_vertices - 1}",
            got=int(f.min()) if f.min() < 0 else int(f.max()),
        )
    return f


def check_mesh(vertices, faces) -> tuple[np.ndarray, np.ndarray]:
    v = check_vertices(vertices)
    return v, check_faces(faces, v.shape[0])
