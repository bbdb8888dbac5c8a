import numpy as np
import pytest

from segadeform.body import BodyProxy
from segadeform.body.collision import closest_point_on_triangles, push_out, winding_number
from segadeform.body.collision.reference import PINCH, body_size, nearest_unburied
from segadeform.errors import SegadeformError
from tests.body._shapes import crease_points, pressed_spheres, sphere, with_reach


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


# ---- the fast pass (BodyCollider, both backends) against the references -----------------------------------
from segadeform.body.collision import BodyCollider, closest_point_fast  # noqa: E402

# the compiled backend must be built here (pip install -e . compiles src/segadeform/body/_collide.c): a missing
# kernel fails these tests with the reason instead of silently testing numpy twice
BACKENDS = ["compiled", "numpy"]


def exhaustive(v, f):
    """The reference proxy with every triangle a candidate: brute force, exact."""
    return BodyProxy(v, f, k=len(f))


def brute_force_per_point(p, v, f):
    """Brute-force unsigned distance, one point at a time (for big meshes)."""
    tri = v[f]
    out = np.empty(len(p))
    for i, q in enumerate(p):
        cp, _ = closest_point_on_triangles(q[None], tri[:, 0], tri[:, 1], tri[:, 2])
        out[i] = np.linalg.norm(cp - q, axis=1).min()
    return out


def test_closest_point_fast_matches_the_reference():
    rng = np.random.default_rng(5)
    p, a, b, c = rng.normal(size=(4, 20000, 3))
    c[:50] = a[:50]  # degenerate: two corners equal
    c[50:100] = a[50:100] + 1e-9 * rng.normal(size=(50, 3))  # needle
    a[100:150] = b[100:150] = c[100:150]  # a point
    c[150:200] = 0.5 * (a[150:200] + b[150:200])  # three collinear corners
    p[200:300] = 0.3 * a[200:300] + 0.3 * b[200:300] + 0.4 * c[200:300]  # exactly on the triangle
    p[300:400] = a[300:400]  # on a corner
    ref, rb = closest_point_on_triangles(p, a, b, c)
    got, gb = closest_point_fast(p, a, b, c)
    np.testing.assert_allclose(got, ref, atol=1e-9)
    np.testing.assert_allclose(gb.sum(axis=1), 1.0, atol=1e-12)
    dref = np.linalg.norm(ref - p, axis=1)
    assert np.abs(np.linalg.norm(got - p, axis=1) - dref).max() < 1e-9
    np.testing.assert_allclose(np.einsum("ik,ikj->ij", gb, np.stack([a, b, c], 1)), got, atol=1e-9)  # weights -> point


def _degenerate_icosphere():
    """A closed icosphere with a zero-area triangle: one edge split on one side only, closed by a sliver."""
    v, f = _icosphere()
    a, b, c = f[0]
    m = len(v)
    v = np.vstack([v, 0.5 * (v[a] + v[b])])
    return v, np.vstack([f[1:], [[a, m, c], [m, b, c], [m, a, b]]])


def _cloud(v, f, n, seed):
    """Points inside, outside, on the surface (vertices, edge midpoints) and far away; none on a plane
    of symmetry, where two closest points tie."""
    rng = np.random.default_rng(seed)
    scale = np.ptp(v, axis=0) / 2
    centre = v.mean(axis=0)
    return np.concatenate(
        [
            centre + rng.normal(size=(n, 3)) * scale * rng.uniform(0.1, 1.5, (n, 1)),
            v,
            0.5 * (v[f[:, 0]] + v[f[:, 1]]),
            centre + 20 * scale * rng.normal(size=(10, 3)),
        ]
    )


@pytest.mark.parametrize("backend", BACKENDS)
@pytest.mark.parametrize("shape", ["icosphere", "degenerate", "open", "uv-sphere"])
def test_fast_query_is_the_brute_force_answer(shape, backend):
    v, f = {
        "icosphere": _icosphere,
        "degenerate": _degenerate_icosphere,
        "open": lambda: _icosphere()[:1] + (_icosphere()[1][7:],),
        "uv-sphere": lambda: sphere(24, 16),
    }[shape]()
    v = v * [0.3, 0.9, 0.2] + [0.0, 1.0, 0.0]
    p = _cloud(v, f, 2000, 3)
    col = BodyCollider(v, f, backend=backend)
    assert col.closed == (shape != "open")
    r = col.query(p, v)
    np.testing.assert_allclose(np.abs(r.signed_distance), brute_force(p, v, f), atol=1e-12)
    np.testing.assert_allclose(np.linalg.norm(r.closest - p, axis=1), np.abs(r.signed_distance), atol=1e-12)
    assert np.isfinite(r.normal).all()
    np.testing.assert_allclose(np.linalg.norm(r.normal, axis=1), 1.0, atol=1e-9)
    if col.closed:
        off = np.abs(r.signed_distance) > 1e-9
        inside = winding_number(p[off], v, f) > 0.5
        np.testing.assert_array_equal(r.signed_distance[off] < 0, inside)


def ambiguous(p, v, f, tol=1e-12):
    """Points whose nearest triangles tie (within ``tol``) on features with different pseudo-normals: on the
    degenerate icosphere, an edge of the zero-area sliver lies on an edge of a real face, so a point there
    is as near to both and either answer is right.  Exhaustive: (P, F) distances."""
    proxy = exhaustive(v, f)
    tri = v[f]
    cp, _ = closest_point_on_triangles(p[:, None, :], tri[None, :, 0], tri[None, :, 1], tri[None, :, 2])
    d = np.linalg.norm(cp - p[:, None], axis=-1)
    tied = d <= d.min(axis=1, keepdims=True) + tol
    out = np.zeros(len(p), bool)
    for i in np.flatnonzero(tied.sum(axis=1) > 1):
        faces = np.flatnonzero(tied[i])
        n = exhaustive_rows(proxy, np.repeat(p[i : i + 1], len(faces), 0), faces, normals=True)[1]
        out[i] = np.abs(n - n[0]).max() > 1e-9
    return out


@pytest.mark.parametrize("shape", ["icosphere", "degenerate", "open"])
@pytest.mark.parametrize("margin", [0.0, 0.01, 0.08])
def test_fast_push_out_is_the_exhaustive_reference(shape, margin):
    """Every point inside or within the margin moves where the reference moves it when the reference
    looks at every triangle; the others stay bit for bit.  Points whose nearest features tie with
    different normals (only on the degenerate mesh, see :func:`ambiguous`), at the start or after any
    pass, may go either way.  Both backends against one reference (its exhaustive passes are most of the time)."""
    v, f = {
        "icosphere": _icosphere,
        "degenerate": _degenerate_icosphere,
        "open": lambda: (_icosphere()[0], _icosphere()[1][7:]),
    }[shape]()
    v = v * [0.3, 0.9, 0.2]
    p = _cloud(v, f, 1500, 4)
    ref, n_ref = push_out(p, exhaustive(v, f), margin)
    skip = np.zeros(len(p), bool)
    if shape == "degenerate":
        for k in range(3):
            skip |= ambiguous(push_out(p, exhaustive(v, f), margin, iterations=k)[0] if k else p, v, f)
        assert skip.sum() < 0.01 * len(p)
    clear = np.abs(exhaustive(v, f).query(p).signed_distance - margin) > 1e-9  # not on the threshold
    untouched = np.all(ref == p, axis=1) & clear
    for backend in BACKENDS:
        got, n_got = BodyCollider(v, f, backend=backend).push_out(p, v, margin)
        np.testing.assert_allclose(got[~skip], ref[~skip], atol=1e-12, err_msg=backend)
        np.testing.assert_array_equal(got[untouched], p[untouched], err_msg=backend)
        if margin > 0:
            assert abs(n_got - n_ref) <= skip.sum() and n_ref > 100, backend
        else:  # a point pushed onto the surface can count as moved again in the next pass on either side
            assert abs(n_got - n_ref) <= 0.01 * len(p) and n_ref > 100, backend


@pytest.fixture(scope="module")
def dancing():
    """A T-shirt skinned to a dance on the default body, jittered into and out of the body."""
    from segadeform.body import default_body_path, load_body
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
    return body, posed, gv


@pytest.mark.parametrize("backend", BACKENDS)
def test_fast_collider_matches_the_reference_on_a_dancing_body(dancing, backend):
    """The fast pass moves the same vertices to the same places as the reference (BodyProxy rebuilt per
    frame), frame by frame and with frames batched, with the same quality afterwards: at most 0.1 % of
    vertices inside, as many closer than the margin."""
    body, posed, gv = dancing
    margin = 0.004
    fast = BodyCollider(body.v_template, body.faces, backend=backend)
    batched, n_batched = fast.push_out(gv, posed, margin)
    exact = total = moved_ref = moved_fast = 0
    differ = 0.0
    inside, close = np.zeros(2, int), np.zeros(2, int)
    for i in range(len(gv)):
        proxy = BodyProxy(posed[i], body.faces)
        # the first pass sees the same closest points: the reference's candidates hold the nearest triangle
        # for every vertex this close to the body
        q_ref, q_fast = proxy.query(gv[i]), fast.query(gv[i], posed[i])
        near = q_ref.signed_distance < 2 * margin
        np.testing.assert_allclose(q_fast.signed_distance[near], q_ref.signed_distance[near], atol=1e-12)
        ref, n_ref = push_out(gv[i], proxy, margin)
        got, n_got = fast.push_out(gv[i], posed[i], margin)
        np.testing.assert_array_equal(batched[i], got)
        d = np.linalg.norm(ref - got, axis=1)
        exact += int((d < 1e-12).sum())
        differ = max(differ, d.max())
        total += len(d)
        moved_ref, moved_fast = moved_ref + n_ref, moved_fast + n_got
        for k, x in enumerate((ref, got)):
            sd = fast.query(x, posed[i]).signed_distance
            inside[k] += int((sd < 0).sum())
            close[k] += int((sd < margin - 1e-9).sum())
    # a vertex pushed onto an edge or a vertex of the body lies at the same distance from the triangles
    # around it; a later pass may take any of them, and the feature rule (a weight under 1e-9 is zero) can
    # then pick a face normal instead of the edge's: a few vertices differ by a sliver of the margin
    assert exact / total > 0.999, exact / total
    assert differ < 0.01 * margin, differ
    assert moved_fast == moved_ref == n_batched and moved_ref > 0.02 * total
    assert inside[1] <= inside[0] and inside[1] / total <= 0.001, (inside, total)
    assert abs(close[1] - close[0]) <= 1e-4 * total, (close, total)


@pytest.mark.parametrize("frame", ["rest", "posed"])
def test_fast_collider_finds_points_deep_inside_the_body(dancing, frame):
    """Points 1-4 cm under the skin (inside by the winding number) are at the brute-force distance, with
    the reference's sign at the same closest point, and get pushed out as the reference pushes them.  Both backends
    against one reference (the brute force is most of the time)."""
    body, posed, _ = dancing
    v = body.v_template if frame == "rest" else posed[-1]
    rng = np.random.default_rng(2)
    pick = rng.choice(len(v), 150, replace=False)
    proxy = BodyProxy(v, body.faces)
    p = v[pick] - rng.uniform(0.01, 0.04, (150, 1)) * proxy.vertex_normals[pick]
    p = p[winding_number(p, v, body.faces) > 0.5]  # where the body is thinner than that, the point left it
    assert len(p) > 100
    brute = brute_force_per_point(p, v, body.faces)
    ref_out, n_ref = push_out(p, proxy, 0.004)
    bound = PINCH * body_size(v, body.faces)
    open_d: dict[int, float] = {}  # the nearest skin that is not buried, per point nearest buried skin
    for backend in BACKENDS:
        fast = BodyCollider(body.v_template, body.faces, backend=backend)
        r = fast.query(p, v)
        np.testing.assert_allclose(np.abs(r.signed_distance), brute, atol=1e-12, err_msg=backend)
        # by the pseudo-normal: where two parts of the body overlap (an arm in the torso, at rest too), a point
        # inside both can be nearest a buried piece of skin and read as outside, with the reference alike
        assert (r.signed_distance < 0).mean() > 0.9, backend
        ref = exhaustive_rows(proxy, p, r.face)
        np.testing.assert_array_equal(np.sign(r.signed_distance), np.sign(ref), err_msg=backend)
        # every one is inside by the winding number, so every one is moved: those nearest a buried piece of skin
        # too, to the nearest skin that is not buried (the rule for buried surfaces) when it is within PINCH times
        # the body's size; one pinched deeper keeps its buried skin's side (outside), and is moved only if within
        # the margin
        out, n = fast.push_out(p, v, 0.004)
        buried = r.signed_distance >= 0
        for i in np.flatnonzero(buried):
            if i not in open_d:
                hit = nearest_unburied(p[i], v, body.faces, bound=np.inf)
                open_d[i] = np.sqrt(hit[3]) if hit is not None else np.inf
        pinched = buried & (np.array([open_d.get(i, np.inf) for i in range(len(p))]) > bound)
        assert n == n_ref == len(p) - (pinched & (r.signed_distance >= 0.004)).sum(), backend
        taken = buried & ~pinched
        if taken.any():  # moved off the buried skin, not onto it (its closest point's side said outside)
            assert (np.linalg.norm(out[taken] - p[taken], axis=1) > r.signed_distance[taken]).all(), backend
        # a point pinched deeper is lifted to the margin off the buried skin at most
        assert (np.linalg.norm(out[pinched] - p[pinched], axis=1) <= 0.004 + 1e-9).all(), backend
        assert (fast.query(out, v).signed_distance > 0).mean() >= (fast.query(ref_out, v).signed_distance > 0).mean()
        np.testing.assert_array_equal(fast.winding(out, v) > 0, fast.winding(ref_out, v) > 0, err_msg=backend)


def exhaustive_rows(proxy, p, face, normals=False):
    """The reference's signed distance for each point at the given closest face (its own feature rule);
    with ``normals``, the pseudo-normals too."""
    tri = proxy.vertices[proxy.faces[face]]
    cp, b = closest_point_on_triangles(p, tri[:, 0], tri[:, 1], tri[:, 2])
    count = (b > 1e-9).sum(axis=1)
    n = proxy.face_normals[face].copy()
    edge = count == 2
    n[edge] = proxy.edge_normals[face[edge], np.argmin(b[edge], axis=1)]
    vert = count <= 1
    n[vert] = proxy.vertex_normals[proxy.faces[face[vert], np.argmax(b[vert], axis=1)]]
    diff = p - cp
    sd = np.where(np.einsum("ij,ij->i", diff, n) < 0, -1.0, 1.0) * np.linalg.norm(diff, axis=1)
    return (sd, n) if normals else sd


@pytest.mark.parametrize("backend", BACKENDS)
def test_fast_collider_edge_cases(backend):
    """Points on the surface, deep inside, far away; a margin of 0; bad input refused."""
    v, f = _icosphere()
    col = BodyCollider(v, f, backend=backend)
    on = v[:10].copy()
    deep = 0.1 * v[10:20]
    far = 5.0 * v[20:30]
    pts = np.concatenate([on, deep, far])
    out, n = col.push_out(pts, v, 0.01)
    assert np.isfinite(out).all()
    np.testing.assert_array_equal(out[20:], far)  # far points are untouched
    ref, n_ref = push_out(pts, BodyProxy(v, f), 0.01)
    np.testing.assert_allclose(out[:10], ref[:10], atol=1e-12)  # on-surface points go where the reference puts them
    assert n == n_ref == 20  # deep points are pushed too
    assert (col.query(out[:20], v).signed_distance > 0.0099).all()
    zero, _ = col.push_out(pts, v, 0.0)
    np.testing.assert_array_equal(zero[:10], on)  # on the surface is not inside
    assert (np.abs(col.query(zero[10:20], v).signed_distance) < 1e-12).all()  # deep points to the surface
    with pytest.raises(SegadeformError, match="NaN"):
        col.push_out(np.full((2, 3), np.nan), v, 0.01)
    with pytest.raises(SegadeformError, match="expected"):
        col.push_out(pts, v[:-1], 0.01)
    with pytest.raises(SegadeformError, match="expected"):
        col.push_out(pts[None], v, 0.01)  # a batch of points needs a batch of bodies
    with pytest.raises(SegadeformError, match="margin"):
        col.push_out(pts, v, -0.01)
    with pytest.raises(SegadeformError, match="leaf_size"):
        BodyCollider(v, f, leaf_size=0)
    with pytest.raises(SegadeformError, match="face index"):
        BodyCollider(v, f + len(v))


def _icosphere():
    """A unit icosahedron subdivided twice and projected onto the sphere (closed, outward faces)."""
    t = (1 + 5**0.5) / 2
    v = np.array(
        [
            [-1, t, 0],
            [1, t, 0],
            [-1, -t, 0],
            [1, -t, 0],
            [0, -1, t],
            [0, 1, t],
            [0, -1, -t],
            [0, 1, -t],
            [t, 0, -1],
            [t, 0, 1],
            [-t, 0, -1],
            [-t, 0, 1],
        ],
        float,
    )
    f = np.array(
        [
            [0, 11, 5],
            [0, 5, 1],
            [0, 1, 7],
            [0, 7, 10],
            [0, 10, 11],
            [1, 5, 9],
            [5, 11, 4],
            [11, 10, 2],
            [10, 7, 6],
            [7, 1, 8],
            [3, 9, 4],
            [3, 4, 2],
            [3, 2, 6],
            [3, 6, 8],
            [3, 8, 9],
            [4, 9, 5],
            [2, 4, 11],
            [6, 2, 10],
            [8, 6, 7],
            [9, 8, 1],
        ]
    )
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


@pytest.mark.parametrize("backend", BACKENDS)
@pytest.mark.parametrize("scale", [1.0, 1e-3, 1e3])
def test_push_out_leaves_buried_skin_for_the_skin_outside(backend, scale):
    """A body that intersects itself (an arm pressed into the torso: two spheres, one mesh): points inside the
    torso whose closest surface is the arm's buried skin -- its side says outside -- are inside by the winding
    number.  The push-out takes those with skin that is not buried within PINCH times the body's size (2.6 cm here)
    to that skin, as the reference does, so none of them is left inside (the closest-surface rule alone left every
    one where it was); those pinched deeper stay pinched, lifted at most to the margin off the arm's skin."""
    v, f = pressed_spheres(16, 12)  # coarse: every point finds open skin within the faces it may test
    rng = np.random.default_rng(0)
    # deep in the torso (pinched) and near the crease (taken out)
    p0 = np.concatenate([rng.uniform([0.3, -0.4, -0.4], [1.3, 0.4, 0.4], (200, 3)), crease_points(rng, 300)])
    bound = PINCH * body_size(v, f)
    v, p = v * scale, p0 * scale
    col = BodyCollider(v, f, backend=backend)
    inside = col.winding(p, v) > 0
    q = col.query(p, v)
    conflict = inside & (q.signed_distance > 0)
    open_d = np.full(len(p), np.inf)
    for i in np.flatnonzero(conflict):
        open_d[i] = np.sqrt(nearest_unburied(p0[i], v / scale, f, bound=np.inf)[3])  # unbounded: every one has some
    taken, pinched = conflict & (open_d < 0.99 * bound), conflict & (open_d > 1.01 * bound)
    assert taken.sum() > 20 and pinched.sum() > 50 and (inside & ~conflict).sum() > 25  # every kind is there
    margin = 0.002 * scale
    out, n = col.push_out(p, v, margin, iterations=3)
    ref, n_ref = push_out(p, BodyProxy(v, f, k=len(f)), margin, iterations=3)
    assert n == n_ref
    np.testing.assert_allclose(out, ref, rtol=0, atol=1e-9 * scale)
    after = col.winding(out, v) > 0
    assert not after[taken].any()
    # every point left in the torso is pinched: nearest the arm's skin, at least the margin outside it (a point in both
    # spheres goes out of the arm onto its buried skin, and is then one pinched)
    assert after[pinched].all() and (col.query(out[after], v).signed_distance >= margin * (1 - 1e-6)).all()
    # each one taken went past the buried skin it was nearest to, not onto it
    moved = np.linalg.norm(out - p, axis=1)
    assert (moved[taken] > q.signed_distance[taken] + margin).all()
    # each one pinched deeper stays where it was, at most lifted to the margin off the arm's skin
    assert (moved[pinched] <= margin * (1 + 1e-9)).all()
    # points outside both spheres are left alone or only lifted to the margin
    far = ~inside & (q.signed_distance >= margin)
    np.testing.assert_array_equal(out[far], p[far])


def test_numpy_backend_with_every_ray_missing_the_body():
    """A cluster of points beside the body, many enough that the numpy walk casts its rays run by run: every run's
    rays miss the body (an empty walk once crashed with an IndexError); nothing is inside or moved."""
    v, f = sphere(16, 12)
    col = BodyCollider(v, f, backend="numpy")
    p = np.random.default_rng(1).uniform(-0.2, 0.2, (200, 3)) + [3.0, 0.0, 0.0]
    out, n = col.push_out(p, v, 0.01)
    assert n == 0 and np.array_equal(out, p)
    fr = col._impl._frames(v[None])
    wind, graze = col._impl._winding_retry(fr, np.ascontiguousarray(p.T), np.zeros(len(p), int))
    assert not wind.any() and not graze.any()


def test_the_rule_for_buried_skin_tests_a_bounded_number_of_faces():
    """A fine arm buried deep in the torso: a point in the torso next to it has more buried faces nearer than any
    open one than the rule may test (``BURY_TRIES``), so it keeps its closest surface (the arm's: outside), as before
    the rule -- in bounded time, kernel and reference alike; a coarse arm, the same point goes out of the torso.  (A
    small sphere 30 units away, a hand at the end of a long reach, makes the body large enough that the torso's open
    skin, 19 cm from the point, is within PINCH times its size: the cap, not the bound, decides.)"""
    from segadeform.body.collision.reference import BURY_TRIES

    for (n, m), kept in (((96, 72), True), ((16, 12), False)):
        v, f = with_reach(*pressed_spheres(n, m), 30.0)
        p = np.array([[0.75, 0.3, 0.0]])  # 3.5-3.8 cm from the arm's buried skin, 19 cm from the torso's
        assert 1 - np.linalg.norm(p) < PINCH * body_size(v, f)
        col = BodyCollider(v, f)
        assert col.winding(p, v)[0] == 1 and col.query(p, v).signed_distance[0] > 0
        out, moved = col.push_out(p, v, 0.01)
        ref, ref_moved = push_out(p, BodyProxy(v, f, k=len(f)), 0.01)
        assert moved == ref_moved == (0 if kept else 1), (n, m, moved, ref_moved)
        np.testing.assert_allclose(out, ref, atol=1e-9)
        assert len(f) // 2 > BURY_TRIES or not kept
        if not kept:
            assert col.winding(out, v)[0] == 0


def test_a_zero_area_face_in_buried_skin_is_never_taken():
    """A face of zero area in the arm's buried skin (a buried triangle split at the middle of an edge, the mesh still
    closed): its normal is zero, so whether it is buried cannot be told; it is never taken as open skin (once, every
    point nearest it was pushed onto it and left inside the torso).  Same result as without it, as the reference."""
    v, f = pressed_spheres(24, 16)
    half = len(v) // 2
    arm = np.flatnonzero(f.min(axis=1) >= half)
    fi = arm[np.argmin(np.linalg.norm(v[f[arm]].mean(axis=1), axis=1))]  # the buried face deepest in the torso
    a, b, c = f[fi]
    m = len(v)
    v2 = np.vstack([v, v[b] + 0.5 * (v[c] - v[b])])
    f2 = np.vstack([np.delete(f, fi, 0), [[a, b, m], [a, m, c], [m, b, c]]])
    # a long reach: the torso's open skin, 30-60 cm from these points, within PINCH times the body's size (73 cm)
    v2, f2 = with_reach(v2, f2, 60.0)
    cr = np.cross(v2[f2[:, 1]] - v2[f2[:, 0]], v2[f2[:, 2]] - v2[f2[:, 0]])
    zero = np.flatnonzero((cr == 0).all(axis=1))
    assert len(zero) == 1 and (np.abs(np.delete(cr, zero, 0)).max(axis=1) > 0).all()  # one face of zero area, exactly
    p = v[[a, b, c]].mean(axis=0) + np.random.default_rng(0).normal(scale=0.05, size=(200, 3))
    ref, n_ref = push_out(p, BodyProxy(v2, f2, k=len(f2)), 0.01)  # one reference for both backends
    for backend in BACKENDS:
        col = BodyCollider(v2, f2, backend=backend)
        assert col.closed and (col.winding(p, v2) > 0).all() and (col.query(p, v2).signed_distance > 0).sum() > 50
        out, n = col.push_out(p, v2, 0.01)
        assert n == n_ref == len(p), backend
        np.testing.assert_allclose(out, ref, atol=1e-9, err_msg=backend)
        assert not (col.winding(out, v2) > 0).any(), backend


@pytest.mark.parametrize("backend", BACKENDS)
def test_no_rule_for_buried_skin_on_a_body_that_is_not_closed(backend):
    """Without a closed mesh there is no winding number: the pressed spheres with one face gone get the closest
    surface's answer alone, in both backends and the reference alike (the reference once cast its rays anyway)."""
    v, f = pressed_spheres(16, 12)
    f = f[1:]  # a face at the torso's pole, far from the arm
    p = np.random.default_rng(0).uniform([0.3, -0.4, -0.4], [1.3, 0.4, 0.4], (200, 3))
    col = BodyCollider(v, f, backend=backend)
    assert not col.closed
    out, n = col.push_out(p, v, 0.01)
    ref, n_ref = push_out(p, BodyProxy(v, f, k=len(f)), 0.01)
    old, n_old = push_out(p, BodyProxy(v, f, k=len(f)), 0.01, buried=False)
    assert n == n_ref == n_old
    np.testing.assert_allclose(out, ref, atol=1e-9)
    np.testing.assert_array_equal(ref, old)
