"""Geodesic distances on a triangle mesh.

Two methods, both single-source at a time and O(N) memory per source:

* ``"heat"`` -- the heat method (Crane, Weischedel, Wardetzky 2013): one
  heat step ``(M + t L) u = delta_s``, the normalised gradient field
  ``X = -grad u / |grad u|``, then the Poisson equation ``L phi = div X``.
  Both matrices are factored once per mesh (sparse LU), so each source costs
  two triangular solves.  For meshes with boundary (garments) the heat step of
  an interior source is the average of the Neumann and Dirichlet solutions,
  as the paper suggests; a source on the boundary uses the Neumann solution
  (a Dirichlet condition would pin the source itself to zero).
* ``"dijkstra"`` -- shortest paths along mesh edges (scipy).  Robust on any
  input; over-estimates true distances (paths zig-zag along edges).

Disconnected parts: a vertex in another component than the source is at
distance ``inf`` (both methods).  Downstream code (sampling, affinity) maps
``inf`` to zero affinity explicitly; nothing turns into NaN.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla
from scipy.sparse import csgraph

from ..errors import InputError
from ._checks import check_mesh
from .laplacian import cotangent_laplacian, lumped_mass, nondegenerate_faces
from .mesh_ops import boundary_vertices, connected_components, edge_lengths, face_cross, mean_edge_length, unique_edges

__all__ = ["GEODESIC_METHODS", "DEFAULT_GEODESIC", "GeodesicSolver", "geodesic_distances"]

GEODESIC_METHODS = ("heat", "dijkstra")
DEFAULT_GEODESIC = "heat"


def _factor(a: sp.csc_matrix):
    """Sparse LU with SuperLU's default COLAMD ordering.

    Minimum degree on A^T + A (``MMD_AT_PLUS_A``) gives 25-30 % less fill on these symmetric matrices and a faster
    precompute on a regular grid (the 64k-vertex frustum of ``bench/scaling.py``: 2.9 s against 4.0 s, 16k: 0.51
    against 0.69 s), but its ordering time can explode: on a user's 38,866-vertex subdivided dress it took 83.6 s
    against COLAMD's 0.18 s (and solved 8 right-hand sides in 0.51 s against 0.019 s), and a 154,790-vertex one did
    not finish in 12 minutes, uninterruptible inside SuperLU.  COLAMD's cost is bounded; the precompute runs once per
    garment (cached).
    """
    return spla.splu(a, permc_spec="COLAMD")


class GeodesicSolver:
    """Precomputed per-mesh state; ``solver(sources)`` gives ``(len(sources), N)`` distances.

    Args:
        vertices: (N, 3)
        faces: (F, 3)
        method: ``"heat"`` or ``"dijkstra"``
        t_factor: heat method time step as a multiple of h^2 (h = mean edge length)
    """

    def __init__(self, vertices, faces, *, method: str = DEFAULT_GEODESIC, t_factor: float = 1.0) -> None:
        v, f = check_mesh(vertices, faces)
        if method not in GEODESIC_METHODS:
            raise InputError("unknown geodesic method", expected=" | ".join(GEODESIC_METHODS), got=method)
        self.method = method
        self.n = v.shape[0]
        self.n_components, self.labels = connected_components(f, self.n)
        e = unique_edges(f)
        # csgraph treats explicit zeros as missing edges: keep duplicate vertices connected.
        w = np.maximum(edge_lengths(v, e), np.finfo(float).tiny)
        g = sp.coo_matrix((w, (e[:, 0], e[:, 1])), shape=(self.n, self.n))
        self._graph = (g + g.T).tocsr()
        if method == "heat":
            self._setup_heat(v, f, t_factor)

    def _setup_heat(self, v, f, t_factor: float) -> None:
        n = self.n
        good = nondegenerate_faces(v, f)
        fg = f[good]
        covered = np.zeros(n, bool)
        covered[fg.ravel()] = True
        self._orphans = np.flatnonzero(~covered)
        if len(fg) == 0:  # no surface at all: every vertex uses graph distances
            self._heat_ready = False
            return
        self._heat_ready = True
        h = mean_edge_length(v, f) or 1.0
        L = cotangent_laplacian(v, f).tocsc()
        m = lumped_mass(v, f)
        M = sp.diags(m).tocsc()
        t = t_factor * h * h
        # Neumann heat step; Dirichlet variant pins boundary vertices to u = 0.
        heat = (M + t * L).tocsc()
        self._heat_n = _factor(heat)
        bd = boundary_vertices(fg)
        self._has_boundary = bd.size > 0
        if self._has_boundary:
            interior = np.ones(n, bool)
            interior[bd] = False
            # Dirichlet rows: identity at the boundary, the heat equation elsewhere.
            keep = sp.diags(interior.astype(np.float64))
            self._heat_d = _factor((keep @ heat + sp.diags((~interior).astype(np.float64))).tocsc())
            self._bd = bd
        # Per-face gradient operator of a piecewise-linear function:
        # grad u = sum_i u_i (n_f x e_i) / (2 A_f), e_i the edge opposite corner i (ccw).
        cr = face_cross(v, fg)
        area2 = np.linalg.norm(cr, axis=1)
        nrm = cr / area2[:, None]
        rows, cols, vals = [], [], []
        F = len(fg)
        for c in range(3):
            e_opp = v[fg[:, (c + 2) % 3]] - v[fg[:, (c + 1) % 3]]
            g = np.cross(nrm, e_opp) / area2[:, None]
            for k in range(3):
                rows.append(np.arange(F) * 3 + k)
                cols.append(fg[:, c])
                vals.append(g[:, k])
        self._grad = sp.csr_matrix(
            (np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))), shape=(3 * F, n)
        )
        self._area = np.repeat(0.5 * area2, 3)
        self._div = (self._grad.T @ sp.diags(self._area)).tocsr()  # integrated divergence (N x 3F)
        # Poisson solve: L is singular per component; a tiny mass shift pins the constant.
        eps = 1e-8 * max(float(L.diagonal().mean()) / float(m.mean()), 1.0 / (h * h))
        self._poisson = _factor((L + eps * M).tocsc())

    def __call__(self, sources) -> np.ndarray:
        s = np.atleast_1d(np.asarray(sources))
        if s.ndim != 1 or not np.issubdtype(s.dtype, np.integer):
            raise InputError("sources must be a 1-D array of vertex indices", got=s)
        if s.size and (s.min() < 0 or s.max() >= self.n):
            raise InputError("source vertex out of range", expected=f"0..{self.n - 1}", got=int(s.max()))
        if self.method == "dijkstra":
            return csgraph.dijkstra(self._graph, directed=False, indices=s)
        return self._heat(s)

    def _heat(self, s: np.ndarray) -> np.ndarray:
        n, k = self.n, len(s)
        if not self._heat_ready:
            d = csgraph.dijkstra(self._graph, directed=False, indices=s)
            return d
        delta = np.zeros((n, k))
        delta[s, np.arange(k)] = 1.0
        u = self._heat_n.solve(delta)
        if self._has_boundary:
            # Average with the Dirichlet solution (u = 0 on the boundary) for
            # interior sources.  Both solve (M + tL) u = delta at interior rows,
            # so they have the same magnitude.  A source on the boundary would
            # be pinned to 0 itself: it keeps the Neumann solution alone.
            interior = ~np.isin(s, self._bd)
            if interior.any():
                rhs = delta[:, interior].copy()
                rhs[self._bd] = 0.0
                u[:, interior] = 0.5 * (u[:, interior] + self._heat_d.solve(rhs))
        gu = (self._grad @ u).reshape(-1, 3, k)
        norm = np.linalg.norm(gu, axis=1, keepdims=True)
        tiny = np.finfo(float).tiny
        X = np.where(norm > tiny, -gu / np.maximum(norm, tiny), 0.0).reshape(-1, k)
        phi = self._poisson.solve(self._div @ X)
        phi -= phi[s, np.arange(k)][None, :]
        d = phi.T
        # The solve leaves a small negative undershoot near the source; distances are >= 0.
        np.maximum(d, 0.0, out=d)
        d[np.arange(k), s] = 0.0
        if self._orphans.size:
            # Vertices in no non-degenerate face (isolated, duplicates joined
            # only by zero-area faces) have no surface for the heat method:
            # they get edge-graph distances from the source.
            d[:, self._orphans] = csgraph.dijkstra(self._graph, directed=False, indices=s)[:, self._orphans]
        other = self.labels[None, :] != self.labels[s][:, None]
        d[other] = np.inf
        return d


def geodesic_distances(vertices, faces, sources, *, method: str = DEFAULT_GEODESIC) -> np.ndarray:
    """Distances from each source to every vertex: ``(len(sources), N)`` float64 (inf across components)."""
    return GeodesicSolver(vertices, faces, method=method)(sources)
