"""A garment file's own surface -- its faces as modelled (quads and polygons) and its texture coordinates -- for the
sequence writers that can keep them (OBJ frames, USD, Alembic).  The model works on triangles; a textured garment
should still come back textured, with the polygons its artist made.

:func:`obj_surface` reads it from an OBJ (``f v/vt/vn`` corners, ``vt`` lines); :func:`fan_triangles` turns any
polygon list into triangles (for readers and for writers that only take triangles).
"""

from __future__ import annotations

import dataclasses
import os

import numpy as np

from ..errors import FileFormatError, InputError, file_error
from .numbers import number

__all__ = ["Surface", "obj_surface", "fan_triangles"]


@dataclasses.dataclass(frozen=True)
class Surface:
    """Polygons and (optionally) per-corner texture coordinates over a mesh's vertices.

    Attributes:
        counts: (F,) corners per face (>= 3).
        indices: (C,) vertex index of every corner, face after face (C = counts.sum()).
        uvs: (U, 2) texture coordinates, or None.
        uv_indices: (C,) the texture coordinate of every corner, or None (then ``uvs`` is None).
    """

    counts: np.ndarray
    indices: np.ndarray
    uvs: np.ndarray | None = None
    uv_indices: np.ndarray | None = None

    def __post_init__(self):
        c, i = np.asarray(self.counts), np.asarray(self.indices)
        if c.ndim != 1 or not c.size or (c < 3).any() or i.ndim != 1 or i.size != int(c.sum()):
            raise InputError("a surface needs faces of >= 3 corners and one index per corner", got=(c.shape, i.shape))
        if (self.uvs is None) != (self.uv_indices is None):
            raise InputError("texture coordinates need both uvs and uv_indices")
        if self.uvs is not None:
            u, ui = np.asarray(self.uvs), np.asarray(self.uv_indices)
            if (
                u.ndim != 2
                or u.shape[1] != 2
                or ui.shape != i.shape
                or (ui.size and not 0 <= ui.min() <= ui.max() < len(u))
            ):
                raise InputError("uv_indices must index uvs (U, 2), one per corner", got=(u.shape, ui.shape))

    @property
    def n_vertices_used(self) -> int:
        return int(np.asarray(self.indices).max()) + 1

    def triangles(self) -> np.ndarray:
        """(T, 3) the polygons split as fans from their first corner."""
        return fan_triangles(self.counts, self.indices)


def fan_triangles(counts, indices) -> np.ndarray:
    """Polygons (``counts`` corners each, ``indices`` face after face) as triangles, a fan from each first corner.

    Shapes:
        counts: (F,); indices: (C,) -> (sum(counts - 2), 3)
    """
    c = np.asarray(counts, np.int64)
    idx = np.asarray(indices, np.int64)
    if (c == 3).all():
        return idx.reshape(-1, 3)
    start = np.concatenate([[0], np.cumsum(c)[:-1]])
    face = np.repeat(np.arange(len(c)), c - 2)
    k = np.arange(len(face)) - np.repeat(np.cumsum(c - 2) - (c - 2), c - 2)  # 0 .. counts-3 within each face
    s = start[face]
    return np.stack([idx[s], idx[s + k + 1], idx[s + k + 2]], axis=1)


def obj_surface(path: str | os.PathLike) -> Surface:
    """The faces and texture coordinates of an OBJ file as written (``f`` corners ``v``, ``v/vt``, ``v//vn``,
    ``v/vt/vn``; negative indices count back).  Texture coordinates are kept only when every corner has one.

    Raises:
        FileFormatError: a face index out of range, or a face of fewer than 3 corners.
    """
    from .obj import _obj_index, obj_logical_lines

    try:
        lines = obj_logical_lines(path)
    except OSError as e:
        raise file_error(e, path) from None
    nv = nt = 0
    uvs: list = []
    counts: list = []
    vi: list = []
    ti: list = []
    all_uv = True
    for lineno, ln in lines:
        parts = ln.split()
        if not parts:
            continue
        if parts[0] == "v":
            nv += 1
        elif parts[0] == "vt":
            nt += 1
            try:
                uv = (number(parts[1]), number(parts[2]) if len(parts) > 2 else 0.0)
            except (IndexError, ValueError):
                raise FileFormatError("bad vt line", path=path, line=lineno, got=ln) from None
            if not np.isfinite(uv).all():  # (a NaN texture coordinate went into every format's UVs: a review)
                raise FileFormatError("vt line is not finite", path=path, line=lineno, got=ln)
            uvs.append(uv)
        elif parts[0] == "f":
            corners = parts[1:]
            if len(corners) < 3:
                raise FileFormatError("a face needs 3 corners or more", path=path, line=lineno, got=len(corners))
            counts.append(len(corners))
            for tok in corners:
                sub = tok.split("/")
                vi.append(_obj_index(sub[0], nv, path, lineno))
                if len(sub) > 1 and sub[1]:
                    ti.append(_obj_index(sub[1], nt, path, lineno))
                else:
                    all_uv = False
    if not counts:
        raise FileFormatError("OBJ has no faces", path=path)
    keep_uv = all_uv and bool(uvs) and len(ti) == len(vi)
    return Surface(
        counts=np.asarray(counts, np.int64),
        indices=np.asarray(vi, np.int64),
        uvs=np.asarray(uvs, np.float64) if keep_uv else None,
        uv_indices=np.asarray(ti, np.int64) if keep_uv else None,
    )
