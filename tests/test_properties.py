"""Property-based tests (hypothesis) over generated meshes and frames."""

import numpy as np
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from hypothesis.extra import numpy as hnp

from segadeform.geometry import (
    GeodesicSolver,
    SpectralBasis,
    cotangent_laplacian,
    neighbour_graph,
    unique_edges,
    vertex_normals,
)
from segadeform.io import Mesh, read_obj, read_pc2, write_obj, write_pc2

SETTINGS = dict(
    max_examples=int(__import__("os").environ.get("SEGADEFORM_HYPOTHESIS_EXAMPLES", "40")),
    deadline=None,
    suppress_health_check=[HealthCheck.function_scoped_fixture],
)


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
@given(
    a=hnp.arrays(
        np.float32,
        hnp.array_shapes(min_dims=3, max_dims=3, min_side=1, max_side=6).map(lambda s: (s[0], s[1], 3)),
        elements=st.floats(-1e6, 1e6, width=32),
    )
)
def test_pc2_round_trip(tmp_path_factory, a):
    p = tmp_path_factory.mktemp("pc2") / "a.pc2"
    write_pc2(p, a)
    np.testing.assert_array_equal(read_pc2(p).frames, a)


# ---- motions and skinning ------------------------------------------------------------------------
from segadeform.body import (  # noqa: E402
    SMPL_PARENTS,
    default_rest_joints,
    dual_quaternion_skinning,
    forward_kinematics,
    linear_blend_skinning,
    relative_transforms,
)
from segadeform.body.rotations import axis_angle_to_matrix, matrix_to_axis_angle  # noqa: E402
from segadeform.motion import MOTION_KINDS, Motion, make_motion, motion_windows, resample  # noqa: E402
from segadeform.motion.limits import limit_violation  # noqa: E402

angles = st.floats(-4 * np.pi, 4 * np.pi, allow_nan=False)


@settings(**SETTINGS)
@given(hnp.arrays(np.float64, (5, 3), elements=angles))
def test_axis_angle_round_trip_any_angle(r):
    R = axis_angle_to_matrix(r)
    np.testing.assert_allclose(axis_angle_to_matrix(matrix_to_axis_angle(R)), R, atol=1e-9)


@settings(**SETTINGS)
@given(
    hnp.arrays(np.float64, (2, 72), elements=st.floats(-np.pi, np.pi)),
    hnp.arrays(np.float64, (6, 24), elements=st.floats(0, 1)),
    hnp.arrays(np.float64, (6, 3), elements=st.floats(-2, 2)),
)
def test_skinning_is_finite_and_lbs_stays_in_the_hull(poses, w, verts):
    w = w + 1e-9
    w = w / w.sum(1, keepdims=True)
    joints = default_rest_joints()
    g, _ = forward_kinematics(axis_angle_to_matrix(poses.reshape(2, 24, 3)), joints, SMPL_PARENTS)
    a = relative_transforms(g, joints)
    lbs = linear_blend_skinning(verts, w, a)
    dqs = dual_quaternion_skinning(verts, w, a)
    assert np.isfinite(lbs).all() and np.isfinite(dqs).all()
    moved = np.einsum("bsij,nj->bnsi", a[..., :3, :3], verts) + a[:, None, :, :3, 3]
    assert (lbs >= moved.min(2) - 1e-9).all() and (lbs <= moved.max(2) + 1e-9).all()
    # DQS applies a rigid transform per vertex: distances to the blended origin are kept up to scale 1
    onehot = np.eye(24)[np.argmax(w, 1)]
    np.testing.assert_allclose(
        dual_quaternion_skinning(verts, onehot, a), linear_blend_skinning(verts, onehot, a), atol=1e-9
    )


@settings(**SETTINGS)
@given(
    st.sampled_from(sorted(MOTION_KINDS)),
    st.integers(0, 10_000),
    st.floats(0.2, 2.0),
    st.floats(0.05, 1.5),
    st.floats(10, 120),
)
def test_procedural_motions_any_parameters(kind, seed, speed, amplitude, fps):
    m = make_motion(kind, seconds=1.0, seed=seed, speed=speed, amplitude=amplitude, fps=fps)
    assert np.isfinite(m.poses).all() and np.isfinite(m.trans).all()
    assert limit_violation(m.poses) < 1e-9


@settings(**SETTINGS)
@given(
    hnp.arrays(np.float64, st.tuples(st.integers(1, 12), st.just(72)), elements=st.floats(-3, 3)),
    st.floats(5, 200),
    st.floats(5, 200),
    st.integers(1, 6),
)
def test_resample_and_windows(poses, fps_in, fps_out, window):
    m = Motion(poses=poses, trans=np.zeros((len(poses), 3)), fps=fps_in)
    r = resample(m, fps_out)
    assert np.isfinite(r.poses).all() and r.n_frames >= 1
    np.testing.assert_allclose(
        axis_angle_to_matrix(r.poses[0].reshape(24, 3)), axis_angle_to_matrix(poses[0].reshape(24, 3)), atol=1e-9
    )
    w = motion_windows(r.poses, window)
    assert w.shape == (r.n_frames, window, 72)
    np.testing.assert_array_equal(w[:, 0], r.poses)
