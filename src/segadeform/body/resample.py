"""The same garment at another resolution, and positions carried from one resolution to another.  In the body layer
(it needs the body's closest-point routine, nothing of garments) so that the runtime's ``run --resolution`` uses it.

* :func:`subdivide` -- midpoint subdivision, every triangle into four (about 4x the vertices).  The
  first ``N`` vertices are the input's; vertex ``N + i`` is the midpoint of ``unique_edges(faces)[i]``.
  :func:`subdivide_reference` (a loop over the faces) is the slow, obvious reference beside it (tests only).
* :func:`decimate` -- shortest edge first collapsed, to about ``n`` vertices.  An interior edge
  collapses to its midpoint; an edge from the boundary inwards to its boundary end (so hems,
  necklines and armholes keep their place); a boundary edge to its midpoint.  A collapse is skipped
  when it would make the mesh non-manifold (the link condition: the edge's two ends share no
  neighbour but the corners of its own faces), pinch two boundary points together through the
  interior, close a boundary loop of three, or turn any surviving triangle by more than
  ``max_turn`` degrees (folds).  Orientation is kept (a vertex index is replaced, never a triangle
  reordered).
* :class:`SurfaceMap` -- each point of one mesh as a point of another mesh's triangles (barycentric
  weights) plus its offset along that triangle's normal; :meth:`SurfaceMap.apply` carries any
  posed frames of the other mesh to the points.  A point that is a vertex of the other mesh is
  carried exactly (weights one-hot, offset 0).

``bench/tradeoffs.py`` runs a model on a decimated and a subdivided copy of each held-out garment
and carries the result to the full-resolution vertices with a :class:`SurfaceMap`.
"""

from __future__ import annotations

import dataclasses
import heapq

import numpy as np
from scipy.spatial import cKDTree

from ..errors import InputError
from ..geometry._checks import check_mesh
from ..geometry.mesh_ops import face_cross, unique_edges
from .collision import closest_point_on_triangles

__all__ = ["subdivide", "subdivide_reference", "decimate", "SurfaceMap"]


def subdivide(vertices, faces) -> tuple[np.ndarray, np.ndarray]:
    """Midpoint subdivision (see the module docstring).

    Shapes:
        vertices: (N, 3), faces: (F, 3) -> vertices (N + E, 3), faces (4 F, 3)
    """
    v, f = check_mesh(vertices, faces)
    n = np.int64(len(v))
    e = unique_edges(f, len(v))
    key = e[:, 0] * n + e[:, 1]  # ascending: the edges are sorted lexicographically

    def mid(a, b):
        return n + np.searchsorted(key, np.minimum(a, b) * n + np.maximum(a, b))

    a, b, c = f[:, 0], f[:, 1], f[:, 2]
    ab, bc, ca = mid(a, b), mid(b, c), mid(c, a)
    out = np.stack(
        [np.stack([a, ab, ca], 1), np.stack([ab, b, bc], 1), np.stack([ca, bc, c], 1), np.stack([ab, bc, ca], 1)],
        axis=1,
    ).reshape(-1, 3)
    return np.concatenate([v, 0.5 * (v[e[:, 0]] + v[e[:, 1]])]), out


def subdivide_reference(v, f):
    """The slow, obvious :func:`subdivide` (a loop over the faces and a dict of edges), for tests only.

    Shapes:
        v: (N, 3), f: (F, 3) -> (N + E, 3), (4 F, 3)
    """
    e = unique_edges(f, len(v))
    n = len(v)
    key = {(int(a), int(b)): n + i for i, (a, b) in enumerate(e)}
    mid = 0.5 * (v[e[:, 0]] + v[e[:, 1]])

    def m(a, b):
        return key[(a, b) if a < b else (b, a)]

    out = []
    for a, b, c in f.tolist():
        ab, bc, ca = m(a, b), m(b, c), m(c, a)
        out += [(a, ab, ca), (ab, b, bc), (ca, bc, c), (ab, bc, ca)]
    return np.concatenate([v, mid]), np.asarray(out, np.int64)


def _unit_normal(p0, p1, p2):
    n = np.cross(p1 - p0, p2 - p0)
    return n / max(float(np.linalg.norm(n)), 1e-300)


def decimate(vertices, faces, n_vertices: int, *, max_turn: float = 60.0) -> tuple[np.ndarray, np.ndarray]:
    """Shortest-edge collapse to about ``n_vertices`` vertices (see the module docstring).

    Fewer collapses happen when every remaining one would break a rule above; the result then has more
    than ``n_vertices`` vertices.  Vertices no face uses are dropped.

    Shapes:
        vertices: (N, 3), faces: (F, 3) -> vertices (M, 3), faces (F', 3) with M >= n_vertices
    """
    v, f = check_mesh(vertices, faces)
    if isinstance(n_vertices, bool) or not isinstance(n_vertices, (int, np.integer)) or n_vertices < 3:
        raise InputError("decimate needs a target of at least 3 vertices", expected=">= 3", got=n_vertices)
    if not 0 < max_turn <= 180:
        raise InputError("max_turn must be in (0, 180] degrees", got=max_turn)
    cos_turn = float(np.cos(np.radians(max_turn)))
    pos = v.copy()
    tri = f.copy()
    alive = np.ones(len(tri), bool)
    fan: list[set] = [set() for _ in range(len(v))]
    for i, t in enumerate(tri.tolist()):
        for x in t:
            fan[x].add(i)
    used = np.zeros(len(v), bool)
    used[f.ravel()] = True
    count = int(used.sum())
    version = np.zeros(len(v), np.int64)

    def nbrs(a):
        return {x for i in fan[a] for x in tri[i]} - {a}

    def shared(a, b):
        return fan[a] & fan[b]

    boundary = np.zeros(len(v), bool)
    e_all = unique_edges(f, len(v))
    for a, b in e_all.tolist():
        if len(shared(a, b)) == 1:
            boundary[a] = boundary[b] = True

    heap: list[tuple[float, int, int, int, int]] = []

    def push(a, b):
        a, b = min(a, b), max(a, b)
        heapq.heappush(heap, (float(np.linalg.norm(pos[a] - pos[b])), a, b, int(version[a]), int(version[b])))

    for a, b in e_all.tolist():
        push(a, b)
    while count > n_vertices and heap:
        _, a, b, va, vb = heapq.heappop(heap)
        if va != version[a] or vb != version[b] or not fan[a] or not fan[b]:
            continue  # stale: an end moved or went
        both = shared(a, b)
        if not both:
            continue
        thirds = {x for i in both for x in tri[i]} - {a, b}
        if nbrs(a) & nbrs(b) != thirds:
            continue  # the link condition
        ba, bb = bool(boundary[a]), bool(boundary[b])
        if ba and bb:
            if len(both) != 1:
                continue  # two boundary points joined through the interior
            (c,) = thirds
            if boundary[c] and len(shared(a, c)) == 1 and len(shared(b, c)) == 1:
                continue  # a boundary loop of three would close
            new = 0.5 * (pos[a] + pos[b])
        elif ba:
            new = pos[a]
        elif bb:
            new = pos[b]
        else:
            new = 0.5 * (pos[a] + pos[b])
        ok = True
        for i in (fan[a] | fan[b]) - both:
            p = pos[tri[i]]
            q = p.copy()
            q[(tri[i] == a) | (tri[i] == b)] = new
            n_old, n_new = _unit_normal(*p), _unit_normal(*q)
            if float(n_old @ n_new) < cos_turn or not np.linalg.norm(np.cross(q[1] - q[0], q[2] - q[0])) > 0:
                ok = False
                break
        if not ok:
            continue
        # collapse b into a
        for i in both:
            alive[i] = False
            for x in tri[i]:
                fan[x].discard(i)
        for i in fan[b]:
            tri[i][tri[i] == b] = a
            fan[a].add(i)
        fan[b] = set()
        pos[a] = new
        boundary[a] = ba or bb
        version[a] += 1
        version[b] += 1
        count -= 1
        for x in thirds:
            if not fan[x]:  # cannot happen with the link condition, kept as a guard
                count -= 1
        for c in nbrs(a):
            push(a, c)
    keep = np.zeros(len(v), bool)
    keep[tri[alive].ravel()] = True
    index = np.cumsum(keep) - 1
    return pos[keep], index[tri[alive]]


@dataclasses.dataclass(frozen=True)
class SurfaceMap:
    """Points as places on a mesh's triangles.

    Attributes:
        face: (P,) the triangle each point maps to; bary: (P, 3) its barycentric weights there;
        offset: (P,) distance along the triangle's unit normal; faces: (F, 3) the mesh's triangles.
    """

    face: np.ndarray
    bary: np.ndarray
    offset: np.ndarray
    faces: np.ndarray

    @classmethod
    def build(cls, points, vertices, faces, *, candidates: int = 16) -> SurfaceMap:
        """Map ``points`` (P, 3) onto the mesh ``vertices`` (N, 3), ``faces`` (F, 3): the closest point
        among the triangles with the ``candidates`` nearest centroids (exact for points near a mesh of
        fairly even triangles, which is what it is for: the same garment at another resolution)."""
        v, f = check_mesh(vertices, faces)
        p = np.asarray(points, np.float64)
        if p.ndim != 2 or p.shape[1] != 3 or not np.isfinite(p).all():
            raise InputError("points must be a finite (P, 3) array", expected="(P, 3)", got=p.shape)
        if len(f) == 0:
            raise InputError("the mesh has no faces", expected="F >= 1", got=0)
        k = int(min(max(1, candidates), len(f)))
        cand = cKDTree(v[f].mean(1)).query(p, k=k)[1].reshape(len(p), k)
        a, b, c = (v[f[cand, i]] for i in range(3))
        closest, bary = closest_point_on_triangles(p[:, None], a, b, c)
        best = np.argmin(np.linalg.norm(closest - p[:, None], axis=2), axis=1)
        rows = np.arange(len(p))
        face = cand[rows, best]
        bary = bary[rows, best]
        # a vertex of the mesh maps to itself exactly
        hit = cKDTree(v).query(p, k=1)
        exact = hit[0] == 0.0
        if exact.any():
            # on a face holding it with three distinct corners when one does (weights (1, 1, 0) on a face (A, A, B)
            # put the point twice as far: 1.55 m off under --resolution, a review), its weight on one corner
            proper = (f[:, 0] != f[:, 1]) & (f[:, 1] != f[:, 2]) & (f[:, 2] != f[:, 0])
            for r in np.flatnonzero(exact):
                vi = hit[1][r]
                holding = np.flatnonzero((f == vi).any(1))
                good = holding[proper[holding]]
                fi = int(good[0] if len(good) else holding[0])
                bary[r] = 0.0
                bary[r, int(np.argmax(f[fi] == vi))] = 1.0
                face[r] = fi
        n = face_cross(v, f[face])
        n /= np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-300)
        on = np.einsum("pk,pkd->pd", bary, v[f[face]])
        offset = np.where(exact, 0.0, np.einsum("pd,pd->p", p - on, n))
        return cls(face=face.astype(np.int64), bary=bary, offset=offset, faces=f)

    def apply(self, frames) -> np.ndarray:
        """The points on posed copies of the mesh.  Shapes: frames (..., N, 3) -> (..., P, 3)."""
        x = np.asarray(frames, np.float64)
        if x.ndim < 2 or x.shape[-1] != 3 or x.shape[-2] <= int(self.faces.max()):
            raise InputError(
                "frames must be (..., N, 3) for the mapped mesh",
                expected=f"(..., >{int(self.faces.max())}, 3)",
                got=x.shape,
            )
        tri = x[..., self.faces[self.face], :]  # (..., P, 3, 3)
        on = np.einsum("pk,...pkd->...pd", self.bary, tri)
        n = np.cross(tri[..., 1, :] - tri[..., 0, :], tri[..., 2, :] - tri[..., 0, :])
        n /= np.maximum(np.linalg.norm(n, axis=-1, keepdims=True), 1e-300)
        return on + self.offset[:, None] * n
