"""Small analytic meshes for tests, benchmarks and samples (all Y-up, metres)."""

from __future__ import annotations

import numpy as np

__all__ = ["grid_plane", "cylinder", "frustum", "fan"]


def grid_plane(
    nx: int, ny: int, size: tuple[float, float] = (1.0, 1.0), *, jitter: float = 0.0, seed: int = 0
) -> tuple[np.ndarray, np.ndarray]:
    """A flat ``nx x ny``-vertex grid in the XZ plane, triangulated with alternating diagonals.

    Returns ``vertices (nx*ny, 3)``, ``faces (2 (nx-1)(ny-1), 3)``.  ``jitter``
    moves interior vertices in-plane by up to that fraction of a cell.
    """
    xs = np.linspace(0.0, size[0], nx)
    zs = np.linspace(0.0, size[1], ny)
    X, Z = np.meshgrid(xs, zs, indexing="ij")
    v = np.stack([X.ravel(), np.zeros(X.size), Z.ravel()], axis=1)
    if jitter:
        rng = np.random.default_rng(seed)
        interior = (X.ravel() > 0) & (X.ravel() < size[0]) & (Z.ravel() > 0) & (Z.ravel() < size[1])
        cell = np.array([size[0] / (nx - 1), 0.0, size[1] / (ny - 1)])
        v[interior] += jitter * cell * rng.uniform(-0.5, 0.5, (interior.sum(), 3))
    idx = np.arange(nx * ny).reshape(nx, ny)
    a, b = idx[:-1, :-1].ravel(), idx[1:, :-1].ravel()
    c, d = idx[1:, 1:].ravel(), idx[:-1, 1:].ravel()
    alt = ((np.arange(nx - 1)[:, None] + np.arange(ny - 1)[None, :]) % 2).ravel().astype(bool)
    t1 = np.where(alt[:, None], np.stack([a, b, c], 1), np.stack([a, b, d], 1))
    t2 = np.where(alt[:, None], np.stack([a, c, d], 1), np.stack([b, c, d], 1))
    return v, np.concatenate([t1, t2]).astype(np.int64)


def frustum(
    n_around: int, n_height: int, r_top: float, r_bottom: float, y_top: float, y_bottom: float, *, center=(0.0, 0.0)
) -> tuple[np.ndarray, np.ndarray]:
    """An open tube (truncated cone) around +Y, open at both ends, outward-facing.

    ``n_around`` vertices per ring, ``n_height`` rings from ``y_top`` down to
    ``y_bottom``; ring radius interpolates ``r_top`` -> ``r_bottom``.
    """
    th = np.linspace(0.0, 2 * np.pi, n_around, endpoint=False)
    ys = np.linspace(y_top, y_bottom, n_height)
    rs = np.linspace(r_top, r_bottom, n_height)
    v = np.stack(
        [
            (center[0] + rs[:, None] * np.cos(th)[None, :]).ravel(),
            np.repeat(ys, n_around),
            (center[1] + rs[:, None] * np.sin(th)[None, :]).ravel(),
        ],
        axis=1,
    )
    idx = np.arange(n_around * n_height).reshape(n_height, n_around)
    nxt = np.roll(idx, -1, axis=1)
    a, b, c, d = idx[:-1], nxt[:-1], nxt[1:], idx[1:]
    # Rings run top to bottom and counter-clockwise seen from above; this
    # winding makes face normals point away from the axis.
    t1 = np.stack([a, b, c], -1).reshape(-1, 3)
    t2 = np.stack([a, c, d], -1).reshape(-1, 3)
    return v, np.concatenate([t1, t2]).astype(np.int64)


def cylinder(n_around: int, n_height: int, radius: float = 1.0, height: float = 1.0):
    """An open cylinder of the given radius and height (see :func:`frustum`)."""
    return frustum(n_around, n_height, radius, radius, height, 0.0)


def fan(n_triangles: int, radius: float = 1.0) -> tuple[np.ndarray, np.ndarray]:
    """A disc fan of ``n_triangles`` around vertex 0 (valence ``n_triangles``)."""
    th = np.linspace(0.0, 2 * np.pi, n_triangles, endpoint=False)
    v = np.concatenate([[[0.0, 0.0, 0.0]], np.stack([radius * np.cos(th), np.zeros_like(th), radius * np.sin(th)], 1)])
    i = np.arange(1, n_triangles + 1)
    j = np.roll(i, -1)
    return v, np.stack([np.zeros_like(i), j, i], 1).astype(np.int64)
