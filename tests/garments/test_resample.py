"""Resampling a garment: midpoint subdivision (against the garment maker's loop), decimation that keeps
a clean garment, and the surface map that carries positions between resolutions."""

from __future__ import annotations

import numpy as np
import pytest

from segadeform.body.resample import SurfaceMap, decimate, subdivide, subdivide_reference
from segadeform.body.transfer import skin_garment, transfer_weights
from segadeform.errors import InputError
from segadeform.garments import check_garment
from segadeform.geometry.mesh_ops import boundary_loops, mean_edge_length
from segadeform.io import read_mesh
from segadeform.motion import make_motion

from ..conftest import SAMPLES


@pytest.fixture(scope="module")
def skirt():
    m = read_mesh(SAMPLES / "garments" / "skirt.obj")
    return m.vertices.astype(np.float64), m.faces


def test_subdivide_matches_the_garment_makers_loop(skirt):
    v, f = skirt
    v2, f2 = subdivide(v, f)
    r2, rf2 = subdivide_reference(v, f)
    np.testing.assert_array_equal(f2, rf2)
    np.testing.assert_array_equal(v2, r2)
    np.testing.assert_array_equal(v2[: len(v)], v)  # the input's vertices come first
    assert len(f2) == 4 * len(f)
    check_garment(v2, f2)


def test_decimate_keeps_a_clean_garment_near_the_original(skirt):
    v, f = skirt
    for frac in (0.5, 0.25):
        vc, fc = decimate(v, f, int(frac * len(v)))
        assert int(frac * len(v)) <= len(vc) <= int(frac * len(v)) + 0.05 * len(v)
        check_garment(vc, fc)  # one piece, edge-manifold, consistently oriented, open
        assert len(boundary_loops(fc, len(vc))) == len(boundary_loops(f, len(v)))
        # every original vertex stays close to the coarse surface
        m = SurfaceMap.build(v, vc, fc)
        assert np.abs(m.offset).max() < mean_edge_length(vc, fc)
        normal = np.mean(np.cross(v[f[:, 1]] - v[f[:, 0]], v[f[:, 2]] - v[f[:, 0]]), 0)
        normal_c = np.mean(np.cross(vc[fc[:, 1]] - vc[fc[:, 0]], vc[fc[:, 2]] - vc[fc[:, 0]]), 0)
        assert normal @ normal_c >= 0  # orientation kept
    with pytest.raises(InputError):
        decimate(v, f, 2)
    vn, fn = decimate(v, f, len(v))  # nothing to do
    np.testing.assert_allclose(vn, v)
    np.testing.assert_array_equal(fn, f)


def test_surface_map_carries_posed_frames_between_resolutions(skirt):
    from segadeform.body import load_body

    v, f = skirt
    body = load_body(SAMPLES / "bodies" / "default_body.npz")
    mo = make_motion("walk", seconds=0.2, fps=30)
    w = transfer_weights(v, body.shaped_vertices()[0], body.faces, body.weights)
    posed = skin_garment(v, w, body, mo.poses, None, mo.trans)  # (T, N, 3)
    # onto a finer copy and back: exact (each vertex is a vertex there)
    v2, f2 = subdivide(v, f)
    fine = SurfaceMap.build(v, v2, f2)
    assert (fine.offset == 0).all()
    fine_posed = skin_garment(
        v2, transfer_weights(v2, body.shaped_vertices()[0], body.faces, body.weights), body, mo.poses, None, mo.trans
    )
    np.testing.assert_allclose(fine.apply(fine_posed), fine_posed[:, : len(v)], atol=1e-12)
    # from a coarse copy: the rest shape comes back within a fraction of an edge, and so does a posed one
    vc, fc = decimate(v, f, len(v) // 4)
    coarse = SurfaceMap.build(v, vc, fc)
    rest_err = np.linalg.norm(coarse.apply(vc) - v, axis=1)
    assert rest_err.mean() < 0.05 * mean_edge_length(v, f)
    wc = transfer_weights(vc, body.shaped_vertices()[0], body.faces, body.weights)
    carried = coarse.apply(skin_garment(vc, wc, body, mo.poses, None, mo.trans))
    assert carried.shape == posed.shape
    assert np.linalg.norm(carried - posed, axis=2).mean() < mean_edge_length(v, f)
    with pytest.raises(InputError):
        coarse.apply(np.zeros((2, 3, 3)))
    with pytest.raises(InputError):
        SurfaceMap.build(np.full((2, 3), np.nan), vc, fc)


def test_a_point_on_a_vertex_of_a_face_with_a_repeated_corner_maps_to_it_once(skirt):
    """A vertex of the mesh maps to itself with weight 1 on one corner, of a face with three corners when one holds it:
    a face (A, A, B) listed first gave A the weights (1, 1, 0), and `run --resolution` wrote it 1.55 m off (a
    review)."""
    v, f = skirt[0], skirt[1]
    a, b = int(f[0, 0]), int(f[0, 1])
    faces = np.concatenate([[[a, a, b]], f])
    m = SurfaceMap.build(v, v, faces)
    np.testing.assert_allclose(m.bary.sum(axis=1), 1.0, atol=1e-12)
    assert (faces[m.face[a]] != faces[m.face[a]][[1, 2, 0]]).all()  # a face with three corners
    np.testing.assert_allclose(m.apply(v[None])[0], v, atol=1e-12)
    only = np.array([[a, a, b]])  # no other face holds them: the one there is, once
    m = SurfaceMap.build(v[[a, b]], v, only)
    np.testing.assert_allclose(m.bary.sum(axis=1), 1.0, atol=1e-12)
