"""The compiled collision kernel (``src/segadeform/body/_collide.c`` through :class:`BodyCollider`,
``backend="compiled"``) against brute force and the references, its threads, hard inputs, and the numpy
fallback.  ``tests/body/test_collision.py`` runs the shared cases on both backends."""

import pickle
import shutil
import subprocess

import numpy as np
import pytest

import segadeform.body.collision as collision
from segadeform.body import BodyProxy
from segadeform.body.collision import BodyCollider, closest_point_on_triangles, push_out, winding_number
from segadeform.errors import InputError, SegadeformError
from tests.body._shapes import sphere
from tests.body.test_collision import _cloud, _degenerate_icosphere, _icosphere, exhaustive, exhaustive_rows
from tests.conftest import REPO


def compiled(v, f, **kw):
    return BodyCollider(v, f, backend="compiled", **kw)


def brute(p, v, f):
    """Exact unsigned distance and the nearest face (lowest index among exact ties) of each point, one point
    at a time over every triangle (the reference's closest-point routine)."""
    tri = v[f]
    d, face = np.empty(len(p)), np.empty(len(p), np.int64)
    for i, q in enumerate(p):
        cp, _ = closest_point_on_triangles(q[None], tri[:, 0], tri[:, 1], tri[:, 2])
        dist = np.linalg.norm(cp - q, axis=1)
        face[i] = int(np.argmin(dist))
        d[i] = dist[face[i]]
    return d, face


@pytest.fixture(scope="module")
def posed_body():
    """The default body in a dance pose (its arms and legs away from the rest pose the tree was built in)."""
    from segadeform.body import default_body_path, load_body
    from segadeform.motion import make_motion

    body = load_body(default_body_path())
    m = make_motion("dance", seconds=0.5, seed=1)
    return body, body.forward(m.poses, None, m.trans).vertices


def test_the_kernel_is_built():
    """CI and `pip install -e .` build it; without it every other test here fails with this reason."""
    assert collision.compiled_available(), collision.compiled.load_kernel()[1]
    assert BodyCollider(*_icosphere()).backend == "compiled"


def test_closest_point_and_sign_on_the_posed_body_are_brute_force(posed_body):
    """Points near the skin (either side), deeper inside and far away: the distance is the brute-force one
    (every triangle), the closest point lies at that distance, and the sign is the reference's feature rule
    at that face."""
    body, posed = posed_body
    v, f = posed[-1], body.faces
    rng = np.random.default_rng(7)
    proxy = BodyProxy(v, f)
    pick = rng.choice(len(v), 120, replace=False)
    near = v[pick] + rng.uniform(-0.01, 0.01, (120, 1)) * proxy.vertex_normals[pick]
    deep = v[pick[:40]] - rng.uniform(0.01, 0.05, (40, 1)) * proxy.vertex_normals[pick[:40]]
    far = v.mean(axis=0) + rng.normal(size=(30, 3)) * [0.5, 1.0, 0.5] * 2
    p = np.concatenate([near, deep, far])
    r = compiled(body.v_template, f).query(p, v)
    d, face = brute(p, v, f)
    np.testing.assert_allclose(np.abs(r.signed_distance), d, rtol=0, atol=1e-12)
    np.testing.assert_allclose(np.linalg.norm(r.closest - p, axis=1), d, atol=1e-12)
    np.testing.assert_array_equal(np.sign(r.signed_distance), np.sign(exhaustive_rows(proxy, p, r.face)))
    np.testing.assert_allclose(np.linalg.norm(r.normal, axis=1), 1.0, atol=1e-9)
    deep = deep[np.concatenate([winding_number(deep[i : i + 8], v, f) for i in range(0, len(deep), 8)]) > 0.5]
    assert len(deep) > 20  # the others left a thin limb on its other side
    # inside by the pseudo-normal too (bar where parts of the body overlap: a point in both can read outside)
    assert (compiled(body.v_template, f).query(deep, v).signed_distance < 0).mean() > 0.9


@pytest.mark.parametrize("shape", ["icosphere", "uv-sphere", "torus"])
def test_small_closed_meshes_brute_force_and_winding_number(shape):
    v, f = {"icosphere": _icosphere, "uv-sphere": lambda: sphere(16, 12), "torus": _torus}[shape]()
    v = v * [0.3, 0.9, 0.2] + [0.1, 1.0, -0.05]
    p = _cloud(v, f, 600, 11)
    col = compiled(v, f)
    assert col.closed
    r = col.query(p, v)
    d, _ = brute(p, v, f)
    np.testing.assert_allclose(np.abs(r.signed_distance), d, atol=1e-12)
    off = d > 1e-9
    np.testing.assert_array_equal(r.signed_distance[off] < 0, winding_number(p[off], v, f) > 0.5)
    # push-out: where the sign comes from a ray instead of the closest point, the same points move
    for margin in (0.0, 0.01):
        assert_push_out_matches(col, p, v, f, margin)


def assert_push_out_matches(col, p, v, f, margin, iterations=3, exact=0.95, sliver=0.05):
    """The first pass is the exhaustive reference's (every triangle a candidate) to 1e-9.  Later passes
    start from points pushed to the margin off an edge or a vertex, where two faces are equally near (the
    point lies on the bisector of a concave edge) or a barycentric weight sits at the 1e-9 feature threshold:
    either answer is right, so only ``exact`` of the points must match, the others by ``sliver`` of the
    margin (None: any amount, for sharp concave corners), with as many points left closer than the
    margin."""
    every = exhaustive(v, f)
    ref1, n1 = push_out(p, every, margin, iterations=1)
    got1, g1 = col.push_out(p, v, margin, iterations=1)
    np.testing.assert_allclose(got1, ref1, atol=1e-9)
    if margin > 0:  # (with margin 0, a point on the surface is inside or not by the rounding of a 0 distance)
        assert g1 == n1
    ref, n_ref = push_out(p, every, margin, iterations=iterations)
    got, n_got = col.push_out(p, v, margin, iterations=iterations)
    d = np.linalg.norm(got - ref, axis=1)
    assert (d < 1e-9).mean() >= exact, (d < 1e-9).mean()
    assert sliver is None or d.max() <= sliver * max(margin, 1e-12), d.max()
    if margin > 0:
        assert n_got == n_ref
    else:  # a point pushed onto the surface can count as moved again in the next pass on either side
        assert abs(n_got - n_ref) <= 0.01 * len(p)
    left = [int((every.query(x).signed_distance < margin - 1e-9).sum()) for x in (got, ref)]
    assert abs(left[0] - left[1]) <= 0.01 * len(p), left


@pytest.mark.parametrize("iterations", [2, 5])
def test_passes_are_the_reference_passes(iterations):
    """A point moved in one pass is queried again in the next, up to ``iterations`` passes, as in push_out:
    the passes are the single pass repeated on the points it moved (bit for bit) and the first is the
    exhaustive reference's.  A narrow, lumpy waist (two surfaces closer than twice the margin) keeps moving
    points back and forth; its sharp concave rims make later passes tie between faces at right angles,
    so there only the number of points left too close is compared."""
    v, f = sphere(20, 14)
    v = v * np.where(np.abs(v[:, 1:2]) < 0.3, [0.05, 1.0, 0.08], [0.3, 1.0, 0.3])  # an hourglass
    v = v * np.random.default_rng(0).uniform(0.97, 1.03, (len(v), 1))  # no two faces equally near by symmetry
    p = _cloud(v, f, 500, 12)
    col = compiled(v, f)
    for margin in (0.02, 0.06):
        got, n_got = col.push_out(p, v, margin, iterations=iterations)
        x, idx, moved = p.copy(), np.arange(len(p)), np.zeros(len(p), bool)
        for _ in range(iterations):
            y, _ = col.push_out(x[idx], v, margin, iterations=1)
            hit = np.any(y != x[idx], axis=1) | (col.query(x[idx], v).signed_distance < margin)
            x[idx[hit]] = y[hit]
            moved[idx[hit]] = True
            idx = idx[hit]
        np.testing.assert_array_equal(got, x)
        assert n_got == moved.sum()
        assert_push_out_matches(col, p, v, f, margin, iterations=iterations, exact=0.9, sliver=None)


def test_threads_give_bit_identical_results(posed_body):
    body, posed = posed_body
    rng = np.random.default_rng(3)
    pts = posed[:, rng.choice(posed.shape[1], 3000, replace=False)] + rng.normal(scale=0.01, size=(len(posed), 3000, 3))
    one = compiled(body.v_template, body.faces, threads=1)
    out1, n1 = one.push_out(pts, posed, 0.004)
    for threads in (2, 3):
        many = compiled(body.v_template, body.faces, threads=threads)
        out, n = many.push_out(pts, posed, 0.004)
        np.testing.assert_array_equal(out, out1)
        assert n == n1
        a, b = one.query(pts[0], posed[0]), many.query(pts[0], posed[0])
        for x, y in zip(
            (a.signed_distance, a.closest, a.normal, a.face),
            (b.signed_distance, b.closest, b.normal, b.face),
            strict=True,
        ):
            np.testing.assert_array_equal(x, y)
    # frame by frame or batched: the same
    for i in range(0, len(posed), 4):
        np.testing.assert_array_equal(one.push_out(pts[i], posed[i], 0.004)[0], out1[i])


def test_points_on_vertices_edges_and_faces(posed_body):
    """On the surface: distance 0, a finite unit normal; push-out puts them where the reference does (its
    candidates hold the right face for points on the surface) and margin 0 leaves them where they are."""
    body, posed = posed_body
    v, f = posed[0], body.faces
    rng = np.random.default_rng(4)
    tri = f[rng.choice(len(f), 300, replace=False)]
    on = np.concatenate([v[tri[:100, 0]], 0.5 * (v[tri[100:200, 0]] + v[tri[100:200, 1]]), v[tri[200:]].mean(axis=1)])
    col = compiled(body.v_template, f)
    r = col.query(on, v)
    np.testing.assert_allclose(r.signed_distance, 0.0, atol=1e-12)
    assert np.isfinite(r.normal).all()
    np.testing.assert_allclose(np.linalg.norm(r.normal, axis=1), 1.0, atol=1e-9)
    out, n = col.push_out(on, v, 0.004, iterations=1)
    ref, n_ref = push_out(on, BodyProxy(v, f), 0.004, iterations=1)
    np.testing.assert_allclose(out, ref, atol=1e-9)
    assert n == n_ref >= len(on) - 5
    # later passes start from the margin above an edge or a vertex: ties (see assert_push_out_matches)
    out, n = col.push_out(on, v, 0.004)
    ref, n_ref = push_out(on, BodyProxy(v, f), 0.004)
    d = np.linalg.norm(out - ref, axis=1)
    assert n == n_ref and (d < 1e-9).mean() > 0.95 and d.max() < 0.05 * 0.004
    same, n0 = col.push_out(on, v, 0.0)
    np.testing.assert_array_equal(same[np.abs(r.signed_distance) == 0], on[np.abs(r.signed_distance) == 0])


def _needles():
    """A closed icosphere with a needle (one vertex 1e-9 from another) and a zero-area sliver."""
    v, f = _degenerate_icosphere()
    v = v.copy()
    a, b = f[5, 0], f[5, 1]
    v[b] = v[a] + 1e-9 * (v[b] - v[a])  # every face at b becomes a needle
    return v, f


@pytest.mark.parametrize("mesh", ["degenerate", "needles", "collapsed"])
def test_degenerate_and_needle_triangles_stay_finite(mesh):
    if mesh == "collapsed":  # every vertex at one point: every triangle has zero area, every normal is zero
        v, f = np.zeros((12, 3)) + [0.1, 0.2, 0.3], _icosphere()[1][:20] % 12
    else:
        v, f = {"degenerate": _degenerate_icosphere, "needles": _needles}[mesh]()
    p = _cloud(v if mesh != "collapsed" else _icosphere()[0], f, 500, 5)
    col = compiled(v, f)
    r = col.query(p, v)
    for x in (r.signed_distance, r.closest, r.normal):
        assert np.isfinite(x).all()
    d, _ = brute(p, v, f)
    np.testing.assert_allclose(np.abs(r.signed_distance), d, atol=1e-12)
    out, _ = col.push_out(p, v, 0.01, iterations=5)
    assert np.isfinite(out).all()
    if mesh != "collapsed":
        off = d > 1e-6
        np.testing.assert_array_equal(r.signed_distance[off] < 0, winding_number(p[off], v, f) > 0.5)


@pytest.mark.parametrize("scale", [1e4, 1e-4])
def test_huge_and_tiny_scales(scale):
    """Everything scales: distances, closest points and push-outs at 1e4 m and 1e-4 m are the unit ones
    times the scale (to rounding), and finite."""
    v, f = _icosphere()
    v = v * [0.3, 0.9, 0.2]
    p = _cloud(v, f, 800, 6)
    unit = compiled(v, f)
    big = compiled(v * scale, f)
    a, b = unit.query(p, v), big.query(p * scale, v * scale)
    np.testing.assert_allclose(b.signed_distance, a.signed_distance * scale, rtol=1e-9, atol=1e-12 * scale)
    np.testing.assert_allclose(b.closest, a.closest * scale, rtol=0, atol=1e-9 * scale)
    d, _ = brute(p * scale, v * scale, f)
    np.testing.assert_allclose(np.abs(b.signed_distance), d, rtol=1e-12, atol=1e-15 * scale)
    for margin in (0.0, 0.01):
        x, nx = unit.push_out(p, v, margin)
        y, ny = big.push_out(p * scale, v * scale, margin * scale)
        assert np.isfinite(y).all()
        np.testing.assert_allclose(y, x * scale, rtol=0, atol=1e-9 * scale)
        if margin:
            assert nx == ny


def test_far_points_and_far_bodies():
    """Points a million body sizes away, and a body a thousand metres from the origin: exact and finite."""
    v, f = _icosphere()
    p = np.array([[1e6, 0, 0], [0, -3e6, 1], [1e8, 1e8, -1e8], [0.0, 0.0, 0.0]])
    r = compiled(v, f).query(p, v)
    np.testing.assert_allclose(np.abs(r.signed_distance), brute(p, v, f)[0], rtol=1e-12)
    assert r.signed_distance[-1] < 0 and (r.signed_distance[:3] > 0).all()
    shifted = v + 1000.0
    q = _cloud(shifted, f, 300, 8)
    got, _ = compiled(shifted, f).push_out(q, shifted, 0.01)
    ref, _ = push_out(q, exhaustive(shifted, f), 0.01)
    np.testing.assert_allclose(got, ref, atol=1e-9)


def test_an_open_mesh():
    """Not closed (an edge with one face): no ray can tell inside from outside, so every point farther than
    the margin gets the exact unbounded query (slower, same rule): the sign is the pseudo-normal's, a
    boundary edge's normal is its one face's.  The result is the exhaustive reference's."""
    v, f = _icosphere()
    f = f[f[:, :].min(axis=1) != 0]  # a hole around vertex 0
    col = compiled(v, f)
    assert not col.closed
    p = _cloud(v, f, 800, 9)
    r = col.query(p, v)
    ref = exhaustive(v, f).query(p)
    np.testing.assert_allclose(r.signed_distance, ref.signed_distance, atol=1e-12)
    for margin in (0.0, 0.05):
        got, n = col.push_out(p, v, margin)
        want, n_ref = push_out(p, exhaustive(v, f), margin)
        np.testing.assert_allclose(got, want, atol=1e-9)


def test_bad_input_is_refused():
    v, f = _icosphere()
    col = compiled(v, f)
    for bad in (np.nan, np.inf):
        p = np.zeros((4, 3))
        p[2, 1] = bad
        with pytest.raises(InputError, match="points contain NaN or inf"):
            col.push_out(p, v, 0.01)
        with pytest.raises(InputError, match="points contain NaN or inf"):
            col.query(p, v)
        w = v.copy()
        w[3, 0] = bad
        with pytest.raises(InputError, match="posed body contains NaN or inf"):
            col.push_out(np.zeros((4, 3)), w, 0.01)
    with pytest.raises(InputError, match="expected 'auto', 'compiled' or 'numpy', got 'gpu'"):
        BodyCollider(v, f, backend="gpu")
    with pytest.raises(InputError, match="threads must be a positive integer"):
        BodyCollider(v, f, threads=0)
    with pytest.raises(InputError, match="margin"):
        col.push_out(np.zeros((4, 3)), v, np.nan)


def test_fallback_to_numpy_when_the_kernel_is_missing(monkeypatch, caplog):
    """No compiler at install: "auto" runs numpy with one logged warning per process, "compiled" says why."""
    monkeypatch.setattr(collision.compiled, "_KERNEL", {"lib": None, "why": "not built (test)"})
    v, f = _icosphere()
    with caplog.at_level("WARNING", logger="segadeform.body.collision"):
        a = BodyCollider(v, f)
        b = BodyCollider(v, f, backend="auto")
    assert a.backend == b.backend == "numpy"
    warnings = [r for r in caplog.records if "compiled collision kernel is not available" in r.getMessage()]
    assert len(warnings) == 1 and "not built (test)" in warnings[0].getMessage()
    with pytest.raises(SegadeformError, match="not available.*got not built \\(test\\)"):
        BodyCollider(v, f, backend="compiled")
    p = _cloud(v, f, 300, 10)
    np.testing.assert_allclose(a.push_out(p, v, 0.01)[0], push_out(p, exhaustive(v, f), 0.01)[0], atol=1e-12)


def test_pickles():
    v, f = _icosphere()
    col = compiled(v, f, threads=2)
    again = pickle.loads(pickle.dumps(col))
    assert again.backend == "compiled" and again.threads == 2
    p = _cloud(v, f, 200, 13)
    np.testing.assert_array_equal(again.push_out(p, v, 0.01)[0], col.push_out(p, v, 0.01)[0])


@pytest.mark.skipif(shutil.which("cc") is None, reason="no C compiler")
def test_the_kernel_is_plain_c99_without_python(tmp_path):
    """The C++ runtime compiles the same file: C99, no Python, no warnings."""
    src = REPO / "src" / "segadeform" / "body" / "_collide.c"
    r = subprocess.run(
        [
            "cc",
            "-std=c99",
            "-pedantic",
            "-Wall",
            "-Wextra",
            "-Werror",
            "-O2",
            "-c",
            str(src),
            "-o",
            str(tmp_path / "collide.o"),
        ],
        capture_output=True,
        text=True,
    )
    assert r.returncode == 0, r.stderr
    assert "Python.h" not in subprocess.run(["cc", "-std=c99", "-E", str(src)], capture_output=True, text=True).stdout


def _torus(n=24, m=12, big=1.0, small=0.35):
    """A closed torus (genus 1: a ray from the hole crosses the surface twice)."""
    u, w = np.meshgrid(np.arange(n) * 2 * np.pi / n, np.arange(m) * 2 * np.pi / m, indexing="ij")
    v = np.stack(
        [(big + small * np.cos(w)) * np.cos(u), small * np.sin(w), (big + small * np.cos(w)) * np.sin(u)], -1
    ).reshape(-1, 3)
    i, j = np.meshgrid(np.arange(n), np.arange(m), indexing="ij")
    a, b, c, d = i * m + j, ((i + 1) % n) * m + j, ((i + 1) % n) * m + (j + 1) % m, i * m + (j + 1) % m
    f = np.concatenate([np.stack([a, c, b], -1).reshape(-1, 3), np.stack([a, d, c], -1).reshape(-1, 3)])
    # outward: flip if the signed volume is negative
    t = v[f]
    if np.einsum("ij,ij->i", t[:, 0], np.cross(t[:, 1], t[:, 2])).sum() < 0:
        f = f[:, ::-1]
    return v, f


def acos_inputs(rng, n: int) -> np.ndarray:
    """``n`` float64 inputs for an acos: nine tenths uniform on [-1, 1], the rest within 1e-6 of +-1 and 1e-8 of 0,
    then the branch points +-1/2 (and their neighbours), +-1 and +-0."""
    k = n // 20
    return np.concatenate(
        [
            rng.uniform(-1, 1, n - 2 * k - k // 2),
            1 - rng.uniform(0, 1e-6, k),
            -1 + rng.uniform(0, 1e-6, k),
            rng.uniform(-1e-8, 1e-8, k // 2),
            [0.5, -0.5, np.nextafter(0.5, 1), np.nextafter(-0.5, -1), 1.0, -1.0, 0.0, -0.0],
        ]
    )


def test_the_kernels_acos_is_within_two_ulp_of_acos_and_needs_no_c_library():
    """``sdc_acos`` (vertex pseudo-normals' angles: + - * / and sqrt only, so that the JavaScript port gives its
    bits) against numpy's long double acos: within 2 ulp everywhere on [-1, 1], endpoints and the branch points
    +-1/2 exact or within 1 ulp; out-of-range inputs clamp, NaN stays NaN."""
    from segadeform.body.collision.compiled import load_kernel

    lib, why = load_kernel()
    if lib is None:
        pytest.fail(f"the compiled kernel is not built: {why}")
    xs = acos_inputs(np.random.default_rng(7), 62_000)
    got = np.array([lib.sdc_acos(float(x)) for x in xs])
    ref = np.arccos(xs.astype(np.longdouble))
    ulps = np.abs(got.astype(np.longdouble) - ref) / np.spacing(np.abs(ref.astype(np.float64)))
    assert float(ulps.max()) <= 2.0, float(ulps.max())
    assert lib.sdc_acos(1.0) == 0.0 and lib.sdc_acos(-1.0) == np.pi and lib.sdc_acos(0.0) == np.pi / 2
    assert lib.sdc_acos(1.5) == 0.0 and lib.sdc_acos(-7.0) == np.pi and np.isnan(lib.sdc_acos(float("nan")))


def test_winding_is_inside_where_a_buried_surface_is_the_closest_and_matches_the_reference():
    """One mesh of two overlapping spheres (a posed body whose arm is pressed into the torso): a point inside the
    first sphere whose closest surface is the second sphere's skin buried in the first is outside by the closest
    surface's side (query's sign) and inside by the winding number (1; 2 where both overlap).  The kernel's ray
    count equals the reference's generalised winding number, rounded, on random points, in both backends."""
    from segadeform.body.collision import winding_number

    v1, f1 = sphere()
    v2 = v1 * 0.5 + [0.9, 0.0, 0.0]  # a smaller sphere pushed half into the first
    v, f = np.concatenate([v1, v2]), np.concatenate([f1, f1 + len(v1)])
    p = np.array([[0.3, 0.0, 0.0], [0.85, 0.0, 0.0], [1.3, 0.0, 0.0], [2.0, 0.0, 0.0], [0.0, 0.0, 0.0]])
    for backend in ("compiled", "numpy"):
        c = BodyCollider(v, f, backend=backend)
        q = c.query(p[:1], v)
        assert q.signed_distance[0] > 0  # the closest surface (the buried sphere's, 0.1 away) says outside
        assert c.winding(p, v).tolist() == [1, 2, 1, 0, 1], backend
    rng = np.random.default_rng(1)
    pts = rng.uniform(-1.3, 1.6, (1500, 3))
    ref = np.rint(np.abs(winding_number(pts, v, f))).astype(int)
    got = BodyCollider(v, f, backend="compiled").winding(pts, v)
    assert np.array_equal(got, ref), int((got != ref).sum())
    assert {0, 1, 2} <= set(ref.tolist())
