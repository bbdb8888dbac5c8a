import numpy as np
import pytest

from segadeform.errors import InputError
from segadeform.geometry import neighbour_graph, valence
from segadeform.geometry.primitives import fan, grid_plane


def ring_sets(f, n):
    s = [set() for _ in range(n)]
    for t in f:
        for a in t:
            for b in t:
                if a != b:
                    s[a].add(int(b))
    return s


def test_matches_one_ring_and_pads_with_self():
    v, f = grid_plane(6, 5, jitter=0.3)
    nbr, mask = neighbour_graph(f, len(v), vertices=v)
    rings = ring_sets(f, len(v))
    assert nbr.dtype == np.int64 and mask.dtype == bool
    assert nbr.shape[1] == max(len(r) for r in rings)
    for i, r in enumerate(rings):
        assert set(nbr[i][mask[i]].tolist()) == r
        assert (nbr[i][~mask[i]] == i).all()
        d = np.linalg.norm(v[nbr[i][mask[i]]] - v[i], axis=1)
        assert (np.diff(d) >= 0).all()  # nearest first


def test_cap_keeps_nearest_neighbours():
    v, f = fan(64)
    v[1:] *= 1 + np.arange(64)[:, None] / 64.0  # spoke lengths grow with index
    nbr, mask = neighbour_graph(f, len(v), vertices=v, max_k=16)
    assert nbr.shape[1] == 16 and mask[0].all()
    np.testing.assert_array_equal(np.sort(nbr[0]), np.arange(1, 17))
    assert valence(f, len(v))[0] == 64
    nbr, mask = neighbour_graph(f, len(v), vertices=v, k=64)
    assert set(nbr[0].tolist()) == set(range(1, 65))


def test_isolated_vertex_row_is_all_padding():
    v, f = grid_plane(3, 3)
    nbr, mask = neighbour_graph(f, 10)
    assert not mask[9].any() and (nbr[9] == 9).all()


def test_self_loops_put_the_vertex_first():
    v, f = grid_plane(3, 3)
    nbr, mask = neighbour_graph(f, 10, self_loops=True)
    np.testing.assert_array_equal(nbr[:, 0], np.arange(10))
    assert mask[:, 0].all()
    assert mask[9].sum() == 1


def test_bad_arguments():
    with pytest.raises(InputError):
        neighbour_graph(np.array([[0, 1, 2]]), 0)
    with pytest.raises(InputError, match="too small"):
        neighbour_graph(np.array([[0, 1, 2]]), 3, k=0)
