import numpy as np
import pytest
import scipy.linalg

from segadeform.errors import InputError
from segadeform.geometry import SpectralBasis, cotangent_laplacian, lumped_mass, spectral_bands
from segadeform.geometry.laplacian import cotangents
from segadeform.geometry.primitives import cylinder, grid_plane


def slow_cot_laplacian(v, f):
    n = len(v)
    L = np.zeros((n, n))
    for t in f:
        for c in range(3):
            o, i, j = t[c], t[(c + 1) % 3], t[(c + 2) % 3]
            a, b = v[i] - v[o], v[j] - v[o]
            ang = np.arccos(np.clip(a @ b / np.linalg.norm(a) / np.linalg.norm(b), -1, 1))
            w = 0.5 / np.tan(ang)
            L[i, j] -= w
            L[j, i] -= w
            L[i, i] += w
            L[j, j] += w
    return L


def bumpy():
    v, f = cylinder(14, 7)
    return v + np.random.default_rng(2).normal(scale=0.03, size=v.shape), f


def test_matches_slow_reference_and_is_symmetric_psd():
    v, f = bumpy()
    L = cotangent_laplacian(v, f)
    np.testing.assert_allclose(L.toarray(), slow_cot_laplacian(v, f), atol=1e-10)
    d = L.toarray()
    np.testing.assert_allclose(d, d.T, atol=1e-12)
    np.testing.assert_allclose(d.sum(axis=1), 0, atol=1e-10)
    assert np.linalg.eigvalsh(d).min() > -1e-9


def test_linear_precision_on_flat_interior():
    v, f = grid_plane(7, 6, jitter=0.3)
    L = cotangent_laplacian(v, f)
    interior = (v[:, 0] > 1e-9) & (v[:, 0] < 1 - 1e-9) & (v[:, 2] > 1e-9) & (v[:, 2] < 1 - 1e-9)
    for k in (0, 2):
        np.testing.assert_allclose((L @ v[:, k])[interior], 0, atol=1e-10)


def test_mass_sums_to_area_and_is_positive():
    v, f = grid_plane(5, 5, size=(2.0, 3.0))
    assert lumped_mass(v, f).sum() == pytest.approx(6.0)
    m = lumped_mass(np.vstack([v, [[9, 9, 9]]]), f)
    assert m[-1] > 0 and m[-1] < 1e-6


def test_degenerate_faces_stay_finite():
    v = np.array([[0, 0, 0], [1, 0, 0], [2, 0, 0], [1, 1, 0], [1, 1e-14, 0]], float)
    f = np.array([[0, 1, 3], [1, 2, 3], [0, 2, 1], [0, 4, 1]])
    L = cotangent_laplacian(v, f).toarray()
    assert np.isfinite(L).all()
    assert np.isfinite(cotangents(v, f)).all()


def test_band_split_is_exact_and_matches_full_projection():
    v, f = bumpy()
    sig = np.random.default_rng(3).normal(size=(len(v), 3))
    basis = SpectralBasis.from_mesh(v, f)
    low, mid, high = basis.split(sig)
    np.testing.assert_allclose(low + mid + high, sig, atol=1e-12)
    # reference: the full generalised eigendecomposition
    L = cotangent_laplacian(v, f).toarray()
    M = np.diag(lumped_mass(v, f))
    w, phi = scipy.linalg.eigh(L, M)
    c = phi.T @ M @ sig
    n_low, n_mid = basis.n_low, basis.n_mid
    np.testing.assert_allclose(low, phi[:, :n_low] @ c[:n_low], atol=1e-8)
    np.testing.assert_allclose(mid, phi[:, n_low:n_mid] @ c[n_low:n_mid], atol=1e-8)
    np.testing.assert_allclose(high, phi[:, n_mid:] @ c[n_mid:], atol=1e-8)
    assert n_low == round(0.03 * len(v)) and n_mid == round(0.30 * len(v))


def test_smooth_signal_lives_in_the_low_band():
    v, f = grid_plane(20, 20)
    sig = np.cos(np.pi * v[:, 0])  # the first non-constant mode of a square
    low, mid, high = spectral_bands(v, f, sig)
    assert np.linalg.norm(low) > 0.99 * np.linalg.norm(sig)


def test_band_split_validates():
    v, f = grid_plane(4, 4)
    with pytest.raises(InputError, match="signal must be"):
        SpectralBasis.from_mesh(v, f).split(np.zeros(5))
    with pytest.raises(InputError, match="too large"):
        SpectralBasis.from_mesh(*grid_plane(120, 120))
