"""Property-based tests (hypothesis) over generated meshes and frames."""

import numpy as np
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from hypothesis.extra import numpy as hnp

from segadeform.geometry import (GeodesicSolver, SpectralBasis, cotangent_laplacian, neighbour_graph,
                                 unique_edges, vertex_normals)
from segadeform.io import Mesh, read_obj, read_pc2, write_obj, write_pc2

SETTINGS = dict(max_examples=int(__import__("os").environ.get("SEGADEFORM_HYPOTHESIS_EXAMPLES", "40")), deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])


@st.composite
def meshes(draw, max_vertices=12, max_faces=20):
    """Arbitrary triangle soups: duplicates, degenerate and repeated-vertex faces included."""
    n = draw(st.integers(3, max_vertices))
    coords = st.floats(-1e3, 1e3, allow_nan=False, allow_infinity=False, width=64)
    v = draw(hnp.arrays(np.float64, (n, 3), elements=coords))
    nf = draw(st.integers(1, max_faces))
    f = draw(hnp.arrays(np.int64, (nf, 3), elements=st.integers(0, n - 1)))
    return v, f


@settings(**SETTINGS)
@given(meshes())
def test_normals_are_unit_or_zero(m):
    v, f = m
    n = vertex_normals(v, f)
    ln = np.linalg.norm(n, axis=1)
    assert np.isfinite(n).all()
    assert np.all((np.abs(ln - 1) < 1e-9) | (ln == 0))


@settings(**SETTINGS)
@given(meshes())
def test_neighbour_graph_is_symmetric_and_in_range(m):
    v, f = m
    nbr, mask = neighbour_graph(f, len(v), vertices=v, k=64)
    pairs = {(i, int(j)) for i in range(len(v)) for j in nbr[i][mask[i]]}
    assert pairs == {(int(b), int(a)) for a, b in pairs}
    assert pairs == {(int(a), int(b)) for a, b in unique_edges(f)} | {(int(b), int(a)) for a, b in unique_edges(f)}


@settings(**SETTINGS)
@given(meshes())
def test_laplacian_and_geodesics_stay_finite(m):
    v, f = m
    L = cotangent_laplacian(v, f)
    assert np.isfinite(L.data).all()
    np.testing.assert_allclose(np.asarray(L.sum(axis=1)).ravel(), 0, atol=1e-6 * max(1.0, abs(L).max()))
    for method in ("heat", "dijkstra"):
        d = GeodesicSolver(v, f, method=method)(np.arange(len(v)))
        assert not np.isnan(d).any() and (d >= 0).all()


@settings(**SETTINGS)
@given(meshes(max_vertices=10), hnp.arrays(np.float64, 10, elements=st.floats(-1, 1)))
def test_band_split_reconstructs(m, sig):
    v, f = m
    low, mid, high = SpectralBasis.from_mesh(v, f).split(sig[: len(v)])
    np.testing.assert_allclose(low + mid + high, sig[: len(v)], atol=1e-9)


@settings(**SETTINGS)
@given(m=meshes())
def test_obj_round_trip(tmp_path_factory, m):
    v, f = m
    p = tmp_path_factory.mktemp("obj") / "m.obj"
    write_obj(p, Mesh(vertices=v, faces=f))
    back = read_obj(p)
    np.testing.assert_allclose(back.vertices, v, rtol=1e-8, atol=1e-9)
    np.testing.assert_array_equal(back.faces, f)


@settings(**SETTINGS)
@given(a=hnp.arrays(np.float32, hnp.array_shapes(min_dims=3, max_dims=3, min_side=1, max_side=6).map(
    lambda s: (s[0], s[1], 3)), elements=st.floats(-1e6, 1e6, width=32)))
def test_pc2_round_trip(tmp_path_factory, a):
    p = tmp_path_factory.mktemp("pc2") / "a.pc2"
    write_pc2(p, a)
    np.testing.assert_array_equal(read_pc2(p).frames, a)
