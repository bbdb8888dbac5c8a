"""The triangle mesh container every reader returns and every writer takes."""

from __future__ import annotations

import dataclasses

import numpy as np

from ..bounds import MAX_POSITION
from ..errors import InputError

__all__ = ["Mesh", "validate_mesh_arrays", "triangulate_polygon"]


@dataclasses.dataclass(frozen=True, eq=False)
class Mesh:
    """A triangle mesh whose vertex order and count are those of its file.

    Attributes:
        vertices: ``(N, 3) float64`` positions.
        faces: ``(F, 3) int64`` vertex indices, 0-based. Polygons of the
            file are fan-triangulated, in file order.
        path: the file the mesh came from (for error messages), or None.
        colors: ``(N, 3) float64`` per-vertex colours when the file had them.
        face_origin: ``(F,) int64`` index of the file polygon each triangle
            came from (so polygon structure can be recovered on write).
    """

    vertices: np.ndarray
    faces: np.ndarray
    path: str | None = None
    colors: np.ndarray | None = None
    face_origin: np.ndarray | None = None

    @property
    def n_vertices(self) -> int:
        return int(self.vertices.shape[0])

    @property
    def n_faces(self) -> int:
        return int(self.faces.shape[0])

    def __repr__(self) -> str:
        src = f", path={self.path!r}" if self.path else ""
        return f"Mesh(n_vertices={self.n_vertices}, n_faces={self.n_faces}{src})"


def triangulate_polygon(poly: np.ndarray) -> np.ndarray:
    """Fan-triangulate one polygon ``(k,)`` into ``(k-2, 3)`` triangles.

    A fan from the first corner is exact for convex polygons, which is what
    DCC tools export for quads and most n-gons.
    """
    k = len(poly)
    idx = np.arange(1, k - 1)
    return np.stack([np.full(k - 2, poly[0]), poly[idx], poly[idx + 1]], axis=1)


def validate_mesh_arrays(vertices, faces, *, path=None, allow_no_faces: bool = False, bounded: bool = False):
    """Check and convert mesh arrays; return ``(vertices float64, faces int64)``.

    ``bounded`` (the readers): every coordinate within :data:`segadeform.bounds.MAX_POSITION` (10 km) of the origin;
    the writers leave it out (a run's frames near a 10 km root translation are its own).

    Shapes:
        vertices: (N, 3), N >= 1, all finite
        faces: (F, 3), 0 <= faces < N, F >= 1 unless ``allow_no_faces``
    """
    v = np.asarray(vertices)
    f = np.asarray(faces)
    if v.ndim != 2 or v.shape[1] != 3:
        raise InputError("vertices must be an (N, 3) array", path=path, expected="(N, 3)", got=v.shape)
    if v.shape[0] == 0:
        raise InputError("mesh has no vertices", path=path)
    if not np.issubdtype(v.dtype, np.number) or np.issubdtype(v.dtype, np.complexfloating):
        raise InputError("vertices must be real numbers", path=path, got=v.dtype)
    v = v.astype(np.float64, copy=False)
    if not np.isfinite(v).all():
        bad = int(np.flatnonzero(~np.isfinite(v).all(axis=1))[0])
        raise InputError(f"vertex {bad} has a non-finite coordinate", path=path, got=v[bad].tolist())
    if bounded and v.size and np.abs(v).max() > MAX_POSITION:  # (readers: a frame written near 10 km is the run's)
        bad = int(np.flatnonzero((np.abs(v) > MAX_POSITION).any(axis=1))[0])
        raise InputError(
            f"vertex {bad} lies beyond 10 km of the origin (another unit?)",
            path=path,
            expected=f"|x| <= {MAX_POSITION:g} m",
            got=v[bad].tolist(),
        )
    if f.size == 0 and f.ndim != 2:
        f = f.reshape(0, 3)
    if f.ndim != 2 or f.shape[1] != 3:
        raise InputError("faces must be an (F, 3) array of triangles", path=path, expected="(F, 3)", got=f.shape)
    if f.shape[0] == 0 and not allow_no_faces:
        raise InputError("mesh has no faces", path=path)
    if f.size and not np.issubdtype(f.dtype, np.integer):
        if not np.issubdtype(f.dtype, np.floating) or not np.all(np.mod(f, 1) == 0):
            raise InputError("face indices must be integers", path=path, got=f.dtype)
    f = f.astype(np.int64, copy=False)
    if f.size:
        lo, hi = int(f.min()), int(f.max())
        if lo < 0 or hi >= v.shape[0]:
            raise InputError(
                "face index out of range",
                path=path,
                expected=f"0..{v.shape[0] - 1}",
                got=lo if lo < 0 else hi,
            )
    return v, f
