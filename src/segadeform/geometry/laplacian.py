"""Cotangent Laplacian, lumped mass, and the low / middle / high frequency split (§4.2, Fig. 2)."""

from __future__ import annotations

import dataclasses

import numpy as np
import scipy.linalg
import scipy.sparse as sp

from ..errors import InputError
from ._checks import check_mesh
from .mesh_ops import face_cross, mean_edge_length

__all__ = [
    "COT_CLAMP",
    "cotangents",
    "cotangent_laplacian",
    "lumped_mass",
    "nondegenerate_faces",
    "SpectralBasis",
    "spectral_bands",
    "BAND_LOW",
    "BAND_MID",
    "MAX_DENSE_VERTICES",
]

#: |cot| is clamped here (an angle of ~0.057 deg).  Needle triangles below it
#: are numerically degenerate and would otherwise give weights of 1e12+.
COT_CLAMP = 1e3
#: A face whose area is below this fraction of (mean edge length)^2 is treated
#: as zero-area and left out of the operators (it has no surface to weight).
DEGENERATE_AREA = 1e-12
BAND_LOW = 0.03
BAND_MID = 0.30
#: The band split needs a dense eigendecomposition: O(N^2) memory, O(N^3) time.
MAX_DENSE_VERTICES = 12000


def nondegenerate_faces(vertices, faces) -> np.ndarray:
    """Boolean ``(F,)``: faces that carry a well-defined surface.

    A face is degenerate when it repeats a vertex, when its area is below
    ``DEGENERATE_AREA * h^2``, or when it is a needle: an angle whose
    cotangent reaches ``COT_CLAMP`` (below ~0.06 deg or above ~179.94 deg).  A
    needle kept with clamped cotangents gives Laplacian rows that sum to zero
    with zero diagonal -- an exactly singular factorisation (found by the
    hard-case catalogue).
    """
    f = faces
    v = vertices
    area2 = np.linalg.norm(face_cross(v, f), axis=1)
    h = mean_edge_length(v, f)
    distinct = (f[:, 0] != f[:, 1]) & (f[:, 1] != f[:, 2]) & (f[:, 0] != f[:, 2])
    ok = distinct & (area2 > 2 * DEGENERATE_AREA * max(h * h, np.finfo(float).tiny))
    for c in range(3):
        a = v[f[:, (c + 1) % 3]] - v[f[:, c]]
        b = v[f[:, (c + 2) % 3]] - v[f[:, c]]
        dot = np.einsum("ij,ij->i", a, b)
        ok &= np.abs(dot) < COT_CLAMP * np.maximum(area2, np.finfo(float).tiny)
    return ok


def cotangents(vertices: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """Cotangent of each corner angle, ``(F, 3)``: column c is the angle at ``faces[:, c]``.

    Computed as ``(a . b) / |a x b|``, clamped to ``+-COT_CLAMP``.
    """
    v, f = vertices, faces
    out = np.empty(f.shape, np.float64)
    for c in range(3):
        o = v[f[:, c]]
        a = v[f[:, (c + 1) % 3]] - o
        b = v[f[:, (c + 2) % 3]] - o
        cr = np.linalg.norm(np.cross(a, b), axis=1)
        dot = np.einsum("ij,ij->i", a, b)
        with np.errstate(divide="ignore", invalid="ignore"):
            cot = dot / cr
        cot = np.where(cr > 0, cot, np.sign(dot) * COT_CLAMP)
        out[:, c] = np.clip(cot, -COT_CLAMP, COT_CLAMP)
    return out


def cotangent_laplacian(vertices, faces) -> sp.csr_matrix:
    """Positive semi-definite cotangent Laplacian ``L = D - W`` (sparse ``(N, N)``).

    ``W_ij = (cot a_ij + cot b_ij) / 2`` over the (one or two) angles opposite
    edge ij; ``D = diag(sum_j W_ij)``, so every row sums to 0.  Zero-area
    faces are left out (see :func:`nondegenerate_faces`); a vertex they
    isolate gets an empty row.
    """
    v, f = check_mesh(vertices, faces)
    n = v.shape[0]
    f = f[nondegenerate_faces(v, f)]
    cot = cotangents(v, f)
    rows, cols, vals = [], [], []
    for c in range(3):
        i, j = f[:, (c + 1) % 3], f[:, (c + 2) % 3]  # edge opposite corner c
        rows += [i, j]
        cols += [j, i]
        vals += [0.5 * cot[:, c], 0.5 * cot[:, c]]
    w = sp.coo_matrix((np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))), shape=(n, n)).tocsr()
    w.sum_duplicates()
    d = np.asarray(w.sum(axis=1)).ravel()
    return (sp.diags(d) - w).tocsr()


def lumped_mass(vertices, faces, *, floor: float = 1e-8) -> np.ndarray:
    """Barycentric lumped mass ``(N,)``: a third of the area of each incident face.

    Vertices with no area (isolated, or only in zero-area faces) get
    ``floor x mean mass`` so the mass matrix stays positive definite; their
    modes then sit at the top of the spectrum.
    """
    v, f = check_mesh(vertices, faces)
    n = v.shape[0]
    a = 0.5 * np.linalg.norm(face_cross(v, f), axis=1) if len(f) else np.zeros(0)
    m = np.zeros(n)
    for c in range(3):
        m += np.bincount(f[:, c], weights=a / 3.0, minlength=n)
    pos = m[m > 0]
    ref = pos.mean() if pos.size else 1.0
    return np.maximum(m, floor * ref)


@dataclasses.dataclass(frozen=True, eq=False)
class SpectralBasis:
    """The first eigenpairs of ``L phi = lambda M phi`` for splitting signals into bands.

    Only the first ``n_mid`` (30 %) eigenvectors are computed: the high band
    is the residual ``f - low - mid``, so ``low + mid + high == f`` holds
    exactly (to rounding) by construction.  Since the eigenvectors are
    M-orthonormal, that residual equals the projection on the remaining
    eigenvectors (tests check this against a full decomposition).

    Cost: a dense ``(N, N)`` eigenproblem; memory ``8 N^2`` bytes (1.1 GB at
    12k vertices), time O(N^3).  It is for evaluation, never the runtime;
    above :data:`MAX_DENSE_VERTICES` it refuses unless ``allow_large=True``.

    Attributes:
        eigenvalues: (n_mid,) ascending
        eigenvectors: (N, n_mid), M-orthonormal columns
        mass: (N,)
        n_low, n_mid: band boundaries as eigenvector counts
    """

    eigenvalues: np.ndarray
    eigenvectors: np.ndarray
    mass: np.ndarray
    n_low: int
    n_mid: int

    @classmethod
    def from_mesh(
        cls, vertices, faces, *, low: float = BAND_LOW, mid: float = BAND_MID, allow_large: bool = False
    ) -> SpectralBasis:
        """The basis of a mesh: the cotangent Laplacian's first ``mid`` share of eigenvectors (M-orthonormal in the
        lumped mass matrix), the low band their first ``low`` share.  ``allow_large``: past
        :data:`MAX_DENSE_VERTICES` vertices (a dense eigenproblem) compute it anyway.

        Shapes:
            vertices: (N, 3) metres; faces: (F, 3) int -> a basis with eigenvectors (N, ceil(mid N))
        """
        v, f = check_mesh(vertices, faces)
        n = v.shape[0]
        if not (0 < low <= mid <= 1):
            raise InputError("band fractions must satisfy 0 < low <= mid <= 1", got=(low, mid))
        if n > MAX_DENSE_VERTICES and not allow_large:
            raise InputError(
                "mesh too large for the dense band split",
                expected=f"<= {MAX_DENSE_VERTICES} vertices (or allow_large=True)",
                got=n,
            )
        n_low = min(n, max(1, int(round(low * n))))
        n_mid = min(n, max(n_low, int(round(mid * n))))
        L = cotangent_laplacian(v, f).toarray()
        m = lumped_mass(v, f)
        s = 1.0 / np.sqrt(m)
        A = (s[:, None] * L) * s[None, :]
        A = 0.5 * (A + A.T)
        w, U = scipy.linalg.eigh(A, subset_by_index=[0, n_mid - 1], driver="evr")
        return cls(eigenvalues=w, eigenvectors=s[:, None] * U, mass=m, n_low=n_low, n_mid=n_mid)

    def split(self, signal: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Split ``signal (N,)`` or ``(N, C)`` into ``(low, mid, high)`` of the same shape."""
        f = np.asarray(signal, np.float64)
        n = self.mass.shape[0]
        if f.shape[0] != n or f.ndim not in (1, 2):
            raise InputError("signal must be (N,) or (N, C) for this mesh", expected=f"({n},) or ({n}, C)", got=f.shape)
        if not np.isfinite(f).all():
            raise InputError("signal contains NaN or inf")
        phi = self.eigenvectors
        coef = phi.T @ (self.mass.reshape((-1,) + (1,) * (f.ndim - 1)) * f)
        low = phi[:, : self.n_low] @ coef[: self.n_low]
        mid = phi[:, self.n_low :] @ coef[self.n_low :]
        return low, mid, f - low - mid


def spectral_bands(vertices, faces, signal, *, low: float = BAND_LOW, mid: float = BAND_MID, allow_large: bool = False):
    """One-shot :meth:`SpectralBasis.split`; build the basis once when splitting many signals."""
    return SpectralBasis.from_mesh(vertices, faces, low=low, mid=mid, allow_large=allow_large).split(signal)
