import numpy as np
import pytest

from segadeform.body import BodyProxy
from segadeform.body.collision import closest_point_on_triangles, push_out, winding_number
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


# ---- the fast pass against the reference -----------------------------------------------------------------
def test_closest_point_fast_matches_the_reference():
    from segadeform.body.collision import closest_point_fast

    rng = np.random.default_rng(5)
    p, a, b, c = rng.normal(size=(4, 20000, 3))
    c[:50] = a[:50]  # degenerate: two corners equal
    c[50:100] = a[50:100] + 1e-9 * rng.normal(size=(50, 3))  # needle
    p[100:200] = 0.3 * a[100:200] + 0.3 * b[100:200] + 0.4 * c[100:200]  # exactly on the triangle
    ref, rb = closest_point_on_triangles(p, a, b, c)
    got, gb = closest_point_fast(p, a, b, c)
    np.testing.assert_allclose(got, ref, atol=1e-9)
    dref = np.linalg.norm(ref - p, axis=1)
    assert np.abs(np.linalg.norm(got - p, axis=1) - dref).max() < 1e-9


def test_fast_collider_matches_the_reference_on_a_dancing_body():
    """A T-shirt skinned to a dance, jittered into and out of the body: the fast pass pushes the same
    vertices to the same places as the reference (BodyProxy rebuilt per frame), and leaves at most 0.1 %
    of vertices inside."""
    from segadeform.body import default_body_path, load_body
    from segadeform.body.collision import BodyCollider
    from segadeform.body.transfer import skin_garment, transfer_weights
    from segadeform.garments import make_garment
    from segadeform.motion import make_motion

    body = load_body(default_body_path())
    g = make_garment("tshirt", body)
    m = make_motion("dance", seconds=0.5, seed=1)
    posed = body.forward(m.poses, None, m.trans).vertices
    w = transfer_weights(g.vertices, body.shaped_vertices()[0], body.faces, body.weights)
    gv = skin_garment(g.vertices, w, body, m.poses, None, m.trans)
    gv = gv + np.random.default_rng(0).normal(scale=0.005, size=gv.shape)
    fast = BodyCollider(body.v_template, body.faces)
    same, total, inside = 0, 0, 0
    for i in range(0, len(gv), 3):
        ref, n_ref = push_out(gv[i], BodyProxy(posed[i], body.faces), 0.004)
        got, n_got = fast.push_out(gv[i], posed[i], 0.004)
        d = np.linalg.norm(ref - got, axis=1)
        same += int((d < 1e-6).sum())
        total += len(d)
        assert abs(n_ref - n_got) <= 0.01 * len(d)
        inside += int((BodyProxy(posed[i], body.faces).query(got).signed_distance < 0).sum())
    assert same / total > 0.995, same / total
    assert inside / total <= 0.001, inside / total


def test_fast_collider_edge_cases():
    """Points on the surface, deep inside, far away; a margin of 0; NaN refused."""
    from segadeform.body.collision import BodyCollider

    v, f = _icosphere()
    col = BodyCollider(v, f)
    on = v[:10].copy()
    deep = 0.1 * v[10:20]
    far = 5.0 * v[20:30]
    pts = np.concatenate([on, deep, far])
    out, n = col.push_out(pts, v, 0.01)
    assert np.isfinite(out).all()
    np.testing.assert_array_equal(out[20:], far)  # far points are untouched
    ref, n_ref = push_out(pts, BodyProxy(v, f), 0.01)
    np.testing.assert_allclose(out[:10], ref[:10], atol=1e-9)  # on-surface points go where the reference puts them
    assert n == n_ref == 20  # deep points are pushed too (near the centre the closest point is ambiguous)
    assert (BodyProxy(v, f).query(out[:20]).signed_distance > 0.0099).all()
    with pytest.raises(Exception, match="NaN"):
        col.push_out(np.full((2, 3), np.nan), v, 0.01)


def _icosphere():
    """A unit icosahedron subdivided twice and projected onto the sphere (closed, outward faces)."""
    t = (1 + 5 ** 0.5) / 2
    v = np.array([[-1, t, 0], [1, t, 0], [-1, -t, 0], [1, -t, 0], [0, -1, t], [0, 1, t], [0, -1, -t], [0, 1, -t],
                  [t, 0, -1], [t, 0, 1], [-t, 0, -1], [-t, 0, 1]], float)
    f = np.array([[0, 11, 5], [0, 5, 1], [0, 1, 7], [0, 7, 10], [0, 10, 11], [1, 5, 9], [5, 11, 4], [11, 10, 2],
                  [10, 7, 6], [7, 1, 8], [3, 9, 4], [3, 4, 2], [3, 2, 6], [3, 6, 8], [3, 8, 9], [4, 9, 5],
                  [2, 4, 11], [6, 2, 10], [8, 6, 7], [9, 8, 1]])
    for _ in range(2):
        mids = {}
        nv = list(v)
        nf = []
        for a, b, c in f:
            ids = []
            for x, y in ((a, b), (b, c), (c, a)):
                k = (min(x, y), max(x, y))
                if k not in mids:
                    mids[k] = len(nv)
                    nv.append((v[x] + v[y]) / 2)
                ids.append(mids[k])
            ab, bc, ca = ids
            nf += [[a, ab, ca], [b, bc, ab], [c, ca, bc], [ab, bc, ca]]
        v, f = np.array(nv), np.array(nf)
    return v / np.linalg.norm(v, axis=1, keepdims=True), f
