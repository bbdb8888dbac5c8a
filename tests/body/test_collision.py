import numpy as np

from segadeform.body import BodyProxy
from segadeform.body.collision import closest_point_on_triangles, winding_number
from tests.body._shapes import sphere


def brute_force(p, v, f):
    tri = v[f]
    cp, _ = closest_point_on_triangles(p[:, None, :], tri[None, :, 0], tri[None, :, 1], tri[None, :, 2])
    return np.linalg.norm(cp - p[:, None], axis=-1).min(axis=1)


def test_distance_and_sign_against_references():
    v, f = sphere(24, 16)
    v = v * [0.3, 0.9, 0.2] + [0.0, 1.0, 0.0]  # an elongated, torso-like closed surface
    rng = np.random.default_rng(0)
    p = rng.normal(size=(3000, 3)) * [0.3, 0.9, 0.2] * rng.uniform(0.2, 1.6, (3000, 1)) + [0, 1, 0]
    r = BodyProxy(v, f).query(p)
    inside = winding_number(p, v, f) > 0.5
    assert np.mean((r.signed_distance < 0) == inside) == 1.0
    np.testing.assert_allclose(np.abs(r.signed_distance), brute_force(p, v, f), atol=1e-9)
    np.testing.assert_allclose(np.linalg.norm(r.normal, axis=1), 1.0, atol=1e-9)


def test_points_on_the_surface_vertices_and_edges():
    v, f = sphere(12, 8)
    on = np.concatenate([v, 0.5 * (v[f[:, 0]] + v[f[:, 1]]), v[f].mean(axis=1)])
    r = BodyProxy(v, f).query(on)
    assert np.isfinite(r.normal).all() and np.isfinite(r.signed_distance).all()
    np.testing.assert_allclose(r.signed_distance, 0.0, atol=1e-12)
    assert (np.einsum("ij,ij->i", r.normal, on) > 0).all()  # outward


def test_far_points():
    v, f = sphere(16, 10)
    p = np.array([[10.0, 0, 0], [0, -30, 0], [0, 0, 1e4]])
    r = BodyProxy(v, f).query(p)
    np.testing.assert_allclose(r.signed_distance, brute_force(p, v, f), rtol=1e-9)
