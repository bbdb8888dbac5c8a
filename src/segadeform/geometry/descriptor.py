"""Furthest point sampling and the garment type descriptor (§4.3, Eq. 19).

The descriptor of a garment is the vector of eigenvalues of ``A*``, the
Gaussian affinity ``A*_ij = exp(-d_ij^2 / 2 r^2)`` over ``N*`` furthest-point
samples, with ``d`` the geodesic distance and ``r`` the largest geodesic
distance on the garment.  ``nystrom_eigen`` extends the sampled affinity to
approximate the leading eigenpairs of the full ``N x N`` affinity (Fowlkes
et al. 2004) without ever forming it.

Choices (the paper leaves them open):

* ``N* = 32`` by default.  Each sample costs one geodesic solve, so cost
  grows linearly with N*.  Measured on the sample skirt (1,536 vertices,
  ``python bench/descriptor.py``): the Nyström estimate of the
  full affinity's 10 leading eigenvalues is within 0.23 / 0.14 / 0.09 % of
  lambda_1 for N* = 16 / 32 / 64, and lambda_1 / N* (0.873) matches the full
  matrix's lambda_1 / N (0.892) within 2 %; 64 samples double the solves for a
  0.05 % gain.  The geodesic Gaussian kernel is not positive semi-definite
  (3 % of the full spectrum's mass is negative on the skirt), so the tail of
  lambda does not decay to zero and carries shape information too.
* ``r`` is the largest finite distance from the FPS samples to any vertex.
  FPS starts at the vertex furthest from a central vertex and each sample is
  the furthest from the previous ones, so the diameter's endpoints are
  among the first samples; the value is a lower bound that is exact when they
  are.  Computing all pairs would cost O(N^2).
* The start vertex is the vertex geodesically furthest from the vertex nearest
  the centroid (ties by index), so samples do not depend on vertex 0.
* A garment with fewer than ``N*`` vertices samples every vertex; the missing
  eigenvalues are 0 (the eigenvalues of a smaller kernel matrix padded as if
  the extra samples added nothing).  Eq. 19 treats 0/0 terms as 0.
* Across disconnected parts ``d = inf`` and the affinity is exactly 0.
* Garments are often symmetric, so FPS meets exact ties.  Distances within
  ``TIE_TOLERANCE`` (1e-6 of the largest) are ties, broken by the lowest
  index, so rounding noise cannot pick a different sample.  Measured over
  random rigid motions and rescales of the sample skirt, a frustum and a plane,
  the descriptor was identical (``tests/geometry/test_descriptor.py``).
* Eigenvalues are sorted in descending order.  The geodesic Gaussian kernel
  need not be positive semi-definite, so small negative values can occur;
  they are kept (Eq. 19 uses ``|lambda|``).
* The descriptor depends on how the geodesic distances are computed, by more
  than garments of one kind differ: the same garment with the heat method (the
  default) and with exact Dijkstra along edges (``method="dijkstra"``,
  ``precompute --geodesic dijkstra``) is 0.026 (a tank top), 0.138 (a skirt) and
  0.164 (a dress) apart by Eq. 19, against 0.026-0.14 between a held-out
  garment and its nearest other garment and a novelty threshold of 0.058 in the
  shipped manifest (a researcher's audit, 2 Dec 2026).  Descriptors, Dissim
  values and the novelty warning are comparable only under one method: the
  shipped model's is the heat method, and so are its training garments'.
"""

from __future__ import annotations

import dataclasses
from typing import cast

import numpy as np

from ..errors import InputError
from ._checks import check_mesh
from .geodesic import DEFAULT_GEODESIC, GeodesicSolver

__all__ = [
    "DEFAULT_N_STAR",
    "furthest_point_sampling",
    "furthest_point_sampling_naive",
    "gaussian_affinity",
    "Descriptor",
    "garment_descriptor",
    "nystrom_eigen",
    "dissimilarity",
    "rescale_descriptor",
    "dissimilarities",
    "novelty_threshold",
]

DEFAULT_N_STAR = 32


#: Distances within this fraction of the largest one count as ties, broken by
#: the lowest vertex index, so rounding noise (a rotation, a rescale) cannot
#: change which vertex FPS picks on a symmetric garment.
TIE_TOLERANCE = 1e-6


def _argmax_tied(x: np.ndarray, scale: float) -> int:
    """Index of the maximum of ``x``; values within ``TIE_TOLERANCE x scale`` of it tie (lowest index wins)."""
    top = x.max()
    if np.isinf(top):
        return int(np.flatnonzero(np.isinf(x))[0])
    return int(np.flatnonzero(x >= top - TIE_TOLERANCE * scale)[0])


def _start_vertex(vertices: np.ndarray, solver: GeodesicSolver, exclude: np.ndarray | None = None) -> int:
    keep = np.ones(len(vertices), bool) if exclude is None else ~exclude
    c = vertices[keep].mean(axis=0)
    dc = np.linalg.norm(vertices - c, axis=1)
    dc = np.where(keep, dc, np.inf)
    centre = _argmax_tied(-dc, float(dc[keep].max()) or 1.0)
    d = solver([centre])[0]
    # the furthest vertex in the centre's component (other parts are inf and lose)
    finite = np.where(np.isfinite(d) & keep, d, -1.0)
    return _argmax_tied(finite, float(finite.max()) or 1.0)


def furthest_point_sampling(
    distance_fn, n_vertices: int, n_samples: int, start: int = 0, exclude: np.ndarray | None = None
):
    """Greedy furthest point sampling.

    Args:
        distance_fn: ``sources (k,) -> distances (k, N)``, e.g. a :class:`GeodesicSolver`.
        n_vertices: N.
        n_samples: how many samples; clipped to N.
        start: first sample.
        exclude: (N,) bool, vertices never sampled while others remain (vertices in no face).

    Returns:
        samples ``(m,) int64`` and their distance rows ``(m, N) float64``,
        ``m = min(n_samples, N)``.  Each new sample maximises the distance to
        the nearest sample so far (``inf`` -- another component -- first;
        distances within ``TIE_TOLERANCE`` of the largest finite distance from
        the first sample tie, and the lowest index wins).
    """
    m = min(int(n_samples), int(n_vertices))
    if m < 1:
        raise InputError("n_samples must be at least 1", got=n_samples)
    if not 0 <= start < n_vertices:
        raise InputError("start vertex out of range", expected=f"0..{n_vertices - 1}", got=start)
    samples = np.empty(m, np.int64)
    rows = np.empty((m, n_vertices))
    samples[0] = start
    rows[0] = distance_fn(np.array([start]))[0]
    nearest = rows[0].copy()
    finite = rows[0][np.isfinite(rows[0])]
    scale = float(finite.max()) if finite.size and finite.max() > 0 else 1.0
    for i in range(1, m):
        nearest[samples[:i]] = -1.0  # never pick a sample twice (duplicates sit at distance 0)
        if exclude is not None:
            nearest[exclude] = -1.0
        nxt = _argmax_tied(nearest, scale)
        samples[i] = nxt
        rows[i] = distance_fn(np.array([nxt]))[0]
        np.minimum(nearest, rows[i], out=nearest)
    return samples, rows


def furthest_point_sampling_naive(dist: np.ndarray, n_samples: int, start: int = 0) -> list[int]:
    """Slow, obvious FPS over a full ``(N, N)`` distance matrix (reference for tests)."""
    n = dist.shape[0]
    chosen = [start]
    while len(chosen) < min(n_samples, n):
        best: int | None = None
        best_d = -np.inf
        for j in range(n):
            if j in chosen:
                continue
            dj = min(dist[c, j] for c in chosen)
            if dj > best_d:
                best, best_d = j, dj
        chosen.append(cast(int, best))  # every distance beats -inf
    return chosen


def gaussian_affinity(d: np.ndarray, r: float) -> np.ndarray:
    """``exp(-d^2 / 2 r^2)`` with ``inf -> 0``; ``r`` must be positive and finite."""
    if not (np.isfinite(r) and r > 0):
        raise InputError("kernel width r must be positive and finite", got=r)
    d = np.asarray(d, np.float64)
    with np.errstate(over="ignore", invalid="ignore"):
        a = np.exp(-np.square(d / r) / 2.0)
    a[~np.isfinite(d)] = 0.0
    return a


@dataclasses.dataclass(frozen=True, eq=False)
class Descriptor:
    """A garment type descriptor and what it was computed from.

    Attributes:
        eigenvalues: (N*,) descending, zero-padded when the garment has < N* vertices
        samples: (m,) FPS vertex indices, m = min(N*, N)
        distances: (m, N) geodesic distances from the samples
        radius: the kernel width r
    """

    eigenvalues: np.ndarray
    samples: np.ndarray
    distances: np.ndarray
    radius: float

    @property
    def sampled_affinity(self) -> np.ndarray:
        """``A* (m, m)``, symmetrised."""
        d = self.distances[:, self.samples]
        return gaussian_affinity(0.5 * (d + d.T), self.radius)


def garment_descriptor(
    vertices,
    faces,
    *,
    n_star: int = DEFAULT_N_STAR,
    method: str = DEFAULT_GEODESIC,
    solver: GeodesicSolver | None = None,
) -> Descriptor:
    """The garment type descriptor lambda of §4.3 (see the module notes for the choices)."""
    v, f = check_mesh(vertices, faces)
    if int(n_star) < 1:
        raise InputError("n_star must be at least 1", got=n_star)
    solver = solver or GeodesicSolver(v, f, method=method)
    # vertices in no face are not of the garment's surface: never sampled (100 stray copies of a skirt's waistband
    # vertices were each sampled as a part of their own, taking the descriptor 150x the model's threshold away)
    used = np.zeros(v.shape[0], bool)
    used[f.ravel()] = True
    exclude = None if used.all() or not used.any() else ~used
    start = _start_vertex(v, solver, exclude)
    samples, rows = furthest_point_sampling(
        solver, v.shape[0], min(int(n_star), int(used.sum()) or v.shape[0]), start, exclude
    )
    finite = rows[np.isfinite(rows)]
    r = float(finite.max()) if finite.size else 0.0
    if not (r > 0 and np.isfinite(r)):
        r = 1.0  # a single point, or all samples coincide: every affinity is 1
    d = rows[:, samples]
    a = gaussian_affinity(0.5 * (d + d.T), r)
    lam = np.linalg.eigvalsh(a)[::-1]
    out = np.zeros(int(n_star))
    out[: lam.size] = lam
    return Descriptor(eigenvalues=out, samples=samples, distances=rows, radius=r)


def rescale_descriptor(eigenvalues, n_star: int) -> np.ndarray:
    """A descriptor made from ``m = len(eigenvalues)`` samples, as the ``n_star``-long one a model
    trained at ``N* = n_star`` takes: the eigenvalues of the ``m x m`` sampled affinity approximate
    ``m / N`` times the full affinity's (Nystrom; the module notes measure lambda_1 / N* against
    lambda_1 / N), so they are scaled by ``n_star / m`` and the leading ``n_star`` kept, zero-padded
    when ``m < n_star`` (as for a garment with fewer vertices than samples).  ``bench/tradeoffs.py``
    runs a model at other N* this way.

    Shapes: (m,) -> (n_star,)
    """
    lam = np.asarray(eigenvalues, np.float64)
    if lam.ndim != 1 or lam.size == 0 or not np.isfinite(lam).all():
        raise InputError("eigenvalues must be a finite, non-empty 1-D array", got=lam.shape)
    if isinstance(n_star, bool) or not isinstance(n_star, (int, np.integer)) or n_star < 1:
        raise InputError("n_star must be a positive integer", got=n_star)
    out = np.zeros(int(n_star))
    k = min(int(n_star), lam.size)
    out[:k] = lam[:k] * (int(n_star) / lam.size)
    return out


def nystrom_eigen(descriptor: Descriptor, k: int | None = None, *, rcond: float = 1e-10):
    """Nyström approximation of the leading eigenpairs of the full ``N x N`` affinity.

    One-shot orthogonalised Nyström (Fowlkes et al. 2004, §3): with the
    sampled block ``A (m, m)`` and the sample-to-rest block ``B (m, N-m)``,
    ``Q = A + A^-1/2 B B^T A^-1/2 = R S R^T`` and
    ``V = [A; B^T] A^-1/2 R S^-1/2``; then ``W ~ V S V^T`` with orthonormal
    ``V``.  ``A^-1/2`` uses the eigenvalues of A above ``rcond x max``.

    Returns:
        eigenvalues ``(k,)`` descending and eigenvectors ``(N, k)`` in vertex order.
    """
    s = descriptor.samples
    m, n = descriptor.distances.shape
    rest = np.setdiff1d(np.arange(n), s)
    d = descriptor.distances
    A = gaussian_affinity(0.5 * (d[:, s] + d[:, s].T), descriptor.radius)
    B = gaussian_affinity(d[:, rest], descriptor.radius)
    w, U = np.linalg.eigh(A)
    keep = w > rcond * max(w.max(), np.finfo(float).tiny)
    A_isqrt = (U[:, keep] / np.sqrt(w[keep])) @ U[:, keep].T
    Q = A + A_isqrt @ (B @ B.T) @ A_isqrt
    sig, R = np.linalg.eigh(0.5 * (Q + Q.T))
    order = np.argsort(sig)[::-1]
    sig, R = sig[order], R[:, order]
    pos = sig > rcond * max(sig[0], np.finfo(float).tiny)
    sig, R = sig[pos], R[:, pos]
    k = len(sig) if k is None else min(int(k), len(sig))
    V_s = A @ A_isqrt @ R[:, :k] / np.sqrt(sig[:k])
    V_r = B.T @ A_isqrt @ R[:, :k] / np.sqrt(sig[:k])
    V = np.empty((n, k))
    V[s] = V_s
    V[rest] = V_r
    return sig[:k], V


def dissimilarity(lam_p, lam_q) -> float:
    """Chi-square dissimilarity of two descriptors (Eq. 19); 0/0 terms count 0."""
    a, b = np.sqrt(np.abs(np.asarray(lam_p, np.float64))), np.sqrt(np.abs(np.asarray(lam_q, np.float64)))
    if a.shape != b.shape or a.ndim != 1:
        raise InputError("descriptors must be 1-D and of equal length", got=(a.shape, b.shape))
    num, den = (a - b) ** 2, a + b
    terms = np.divide(num, den, out=np.zeros_like(num), where=den > 0)
    return float(0.5 * terms.sum())


def dissimilarities(lam, refs) -> np.ndarray:
    """Eq. 19 between one descriptor ``lam (N*,)`` and each row of ``refs (R, N*)``; ``(R,)``.

    The vectorised form of :func:`dissimilarity` (``tests/geometry/test_descriptor.py`` compares them)."""
    a = np.sqrt(np.abs(np.asarray(lam, np.float64)))
    b = np.sqrt(np.abs(np.asarray(refs, np.float64)))
    if a.ndim != 1 or b.ndim != 2 or b.shape[1] != a.shape[0]:
        raise InputError("expected a (N*,) descriptor and (R, N*) references", got=(a.shape, b.shape))
    num, den = (a - b) ** 2, a + b
    return 0.5 * np.divide(num, den, out=np.zeros_like(num), where=den > 0).sum(axis=1)


def novelty_threshold(refs, groups) -> float | None:
    """How far a garment may lie from its nearest reference and still count as familiar.

    The largest distance (Eq. 19) from a reference to its nearest reference of *another* group
    (leave one garment out, every body it was made on at once): a garment further from every
    reference than any training garment is from the rest of the training set is outside it.
    ``refs (R, N*)``, ``groups`` R labels; None with fewer than two groups.
    """
    refs = np.asarray(refs, np.float64)
    groups = np.asarray(groups)
    if refs.ndim != 2 or groups.shape != (refs.shape[0],):
        raise InputError("expected (R, N*) references and R group labels", got=(refs.shape, groups.shape))
    if len(set(groups.tolist())) < 2:
        return None
    worst = 0.0
    for i in range(len(refs)):
        other = groups != groups[i]
        worst = max(worst, float(dissimilarities(refs[i], refs[other]).min()))
    return worst
