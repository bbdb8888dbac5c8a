import numpy as np
import pytest

from segadeform.body import (
    axis_angle_to_matrix,
    dual_quaternion_skinning,
    forward_kinematics,
    linear_blend_skinning,
    matrix_to_axis_angle,
    relative_transforms,
)
from segadeform.body.kinematics import check_parents
from segadeform.body.rotations import (
    axis_angle_to_quaternion,
    euler_to_matrix,
    matrix_to_euler,
    quaternion_slerp,
    quaternion_to_matrix,
)
from segadeform.errors import InputError


def rz(deg):
    return axis_angle_to_matrix(np.array([0, 0, np.deg2rad(deg)]))


@pytest.mark.parametrize("theta", [0.0, 1e-12, 1e-6, 0.3, np.pi / 2, np.pi - 1e-9, np.pi])
def test_axis_angle_round_trip_at_0_and_pi(theta):
    axes = np.random.default_rng(1).normal(size=(50, 3))
    r = axes / np.linalg.norm(axes, axis=1, keepdims=True) * theta
    R = axis_angle_to_matrix(r)
    np.testing.assert_allclose(R @ np.swapaxes(R, -1, -2), np.broadcast_to(np.eye(3), R.shape), atol=1e-14)
    np.testing.assert_allclose(axis_angle_to_matrix(matrix_to_axis_angle(R)), R, atol=1e-12)
    np.testing.assert_allclose(quaternion_to_matrix(axis_angle_to_quaternion(r)), R, atol=1e-12)
    assert np.all(np.linalg.norm(matrix_to_axis_angle(R), axis=1) <= np.pi + 1e-12)


@pytest.mark.parametrize("order", ["xyz", "xzy", "yxz", "yzx", "zxy", "zyx"])
def test_euler_round_trip(order):
    e = np.random.default_rng(2).uniform(-1.5, 1.5, size=(200, 3))
    np.testing.assert_allclose(matrix_to_euler(euler_to_matrix(e, order), order), e, atol=1e-12)


def test_slerp_midpoint_and_shorter_arc():
    a = axis_angle_to_quaternion(np.zeros(3))
    b = axis_angle_to_quaternion(np.array([0, 0, np.pi / 2]))
    np.testing.assert_allclose(quaternion_to_matrix(quaternion_slerp(a, b, 0.5)), rz(45), atol=1e-12)
    np.testing.assert_allclose(quaternion_to_matrix(quaternion_slerp(a, -b, 0.5)), rz(45), atol=1e-12)


def test_fk_two_joint_chain_by_hand():
    parents = np.array([-1, 0])
    J = np.array([[0.0, 0, 0], [1.0, 0, 0]])
    rot = np.stack([rz(90), rz(90)])[None]
    g, posed = forward_kinematics(rot, J, parents)
    # joint 1 sits at R0 (1,0,0) = (0,1,0); its frame is rotated 180 degrees
    np.testing.assert_allclose(posed[0, 1], [0, 1, 0], atol=1e-12)
    np.testing.assert_allclose(g[0, 1, :3, :3], rz(180), atol=1e-12)
    # a point one unit beyond joint 1 at rest, (2,0,0), skinned rigidly to joint 1
    a = relative_transforms(g, J)
    p = a[0, 1] @ np.array([2.0, 0, 0, 1])
    np.testing.assert_allclose(p[:3], [-1, 1, 0], atol=1e-12)


def test_fk_three_joint_chain_with_translation():
    parents = np.array([-1, 0, 1])
    J = np.array([[0.0, 1, 0], [0, 2, 0], [0, 3, 0]])
    rot = np.stack([np.eye(3), rz(-90), rz(-90)])[None]
    g, posed = forward_kinematics(rot, J, parents, trans=np.array([[5.0, 0, 0]]))
    # bend the chain right twice: (5,1,0) -> (5,2,0) -> (6,2,0)
    np.testing.assert_allclose(posed[0], [[5, 1, 0], [5, 2, 0], [6, 2, 0]], atol=1e-12)


def test_parents_must_form_a_tree_rooted_at_0():
    for bad in ([0, 0], [-1, 1], [-1, 0, 5], [-1, -1]):
        with pytest.raises(InputError):
            check_parents(np.array(bad))


def twist_setup(deg=90.0, n=40):
    """A bar along X from joint 0 (x=0) to joint 1 (x=1), joint 1 twisted about X."""
    parents = np.array([-1, 0])
    J = np.array([[0.0, 0, 0], [1.0, 0, 0]])
    x = np.linspace(0, 2, n)
    ring = np.stack([np.zeros(8), np.cos(np.arange(8) * np.pi / 4), np.sin(np.arange(8) * np.pi / 4)], 1) * 0.1
    v = (x[:, None, None] * np.array([1.0, 0, 0]) + ring[None]).reshape(-1, 3)
    w1 = np.clip((v[:, 0] - 0.5) / 1.0, 0, 1)  # blend from joint 0 to joint 1 across x in [0.5, 1.5]
    w = np.stack([1 - w1, w1], 1)
    rot = np.stack([np.eye(3), axis_angle_to_matrix(np.array([np.deg2rad(deg), 0, 0]))])[None]
    g, _ = forward_kinematics(rot, J, parents)
    return v, w, relative_transforms(g, J)


def test_lbs_equals_dqs_at_identity_and_for_rigid_weights():
    v, w, _ = twist_setup()
    a = np.broadcast_to(np.eye(4), (1, 2, 4, 4))
    np.testing.assert_allclose(linear_blend_skinning(v, w, a), v[None], atol=1e-14)
    np.testing.assert_allclose(dual_quaternion_skinning(v, w, a), v[None], atol=1e-12)
    _, _, a = twist_setup(70)
    onehot = np.eye(2)[(w[:, 1] > 0.5).astype(int)]
    np.testing.assert_allclose(linear_blend_skinning(v, onehot, a), dual_quaternion_skinning(v, onehot, a), atol=1e-12)


def test_dqs_keeps_more_volume_than_lbs_on_a_twist():
    v, w, a = twist_setup(90)

    def radius(p):  # distance from the bar's axis
        return np.linalg.norm(p[..., 1:], axis=-1)

    mid = np.abs(v[:, 0] - 1.0) < 0.03  # the most blended cross-section
    r_rest = radius(v[mid]).mean()
    r_lbs = radius(linear_blend_skinning(v, w, a)[0, mid]).mean()
    r_dqs = radius(dual_quaternion_skinning(v, w, a)[0, mid]).mean()
    # LBS collapses the half-blended section by cos(45 deg); DQS keeps it
    assert r_lbs < 0.75 * r_rest
    assert abs(r_dqs - r_rest) < 1e-6
    assert r_dqs > r_lbs


def test_dqs_antipodal_quaternions_and_cancelling_blend():
    # joint 1 rotated by 360 deg - eps is the same rotation as -eps; its quaternion is antipodal
    parents = np.array([-1, 0])
    J = np.zeros((2, 3))
    v = np.array([[0.0, 1.0, 0.0]])
    w = np.array([[0.5, 0.5]])
    for ang in (2 * np.pi - 1e-3, np.pi):
        rot = np.stack([np.eye(3), axis_angle_to_matrix(np.array([0, 0, ang]))])[None]
        g, _ = forward_kinematics(rot, J, parents)
        a = relative_transforms(g, J)
        out = dual_quaternion_skinning(v, w, a)
        assert np.isfinite(out).all()
        np.testing.assert_allclose(np.linalg.norm(out), 1.0, atol=1e-9)  # rigid: stays on the unit circle
    # a 360-degree-equivalent pose is exactly the rest pose for both
    rot = np.stack([np.eye(3), axis_angle_to_matrix(np.array([0, 0, 2 * np.pi]))])[None]
    g, _ = forward_kinematics(rot, J, parents)
    a = relative_transforms(g, J)
    np.testing.assert_allclose(dual_quaternion_skinning(v, w, a)[0], v, atol=1e-12)
    np.testing.assert_allclose(linear_blend_skinning(v, w, a)[0], v, atol=1e-12)


def test_skinning_shape_errors():
    with pytest.raises(InputError, match="weights"):
        linear_blend_skinning(np.zeros((3, 3)), np.ones((3, 5)), np.broadcast_to(np.eye(4), (1, 2, 4, 4)))


def _dqs_per_vertex(v, w, a):
    """The obvious DQS: vertex by vertex, quaternions flipped to the pivot's side, blended, normalised,
    turned into a matrix and a translation (the fast code never forms the matrix)."""
    from segadeform.body.rotations import quaternion_multiply
    from segadeform.body.skinning import transforms_to_dual_quaternions

    q, d = transforms_to_dual_quaternions(a)
    out = np.zeros((a.shape[0], len(v), 3))
    for b in range(a.shape[0]):
        for i in range(len(v)):
            p = int(np.argmax(w[i]))
            sg = np.where(q[b] @ q[b, p] < 0, -1.0, 1.0)
            qb, db = (w[i] * sg) @ q[b], (w[i] * sg) @ d[b]
            nrm = np.linalg.norm(qb)
            if nrm < 1e-8:
                qb, db, nrm = q[b, p], d[b, p], 1.0
            qb, db = qb / nrm, db / nrm
            t = 2 * quaternion_multiply(db, qb * np.array([1, -1, -1, -1]))[1:]
            out[b, i] = quaternion_to_matrix(qb) @ v[i] + t
    return out


def test_skinning_fast_paths_match_the_per_vertex_reference():
    """Shared weights (N, S) take one BLAS product per pivot joint, per-frame weights (B, N, S) another
    path; both match the vertex-by-vertex formula, including a vertex whose blend vanishes."""
    rng = np.random.default_rng(4)
    s, n, b = 6, 40, 3
    parents = np.array([-1, 0, 1, 1, 2, 3])
    J = rng.normal(size=(s, 3))
    rot = axis_angle_to_matrix(rng.normal(size=(b, s, 3)) * 1.5)
    g, _ = forward_kinematics(rot, J, parents)
    a = relative_transforms(g, J)
    v = rng.normal(size=(n, 3))
    w = rng.random((n, s)) ** 3
    w /= w.sum(1, keepdims=True)
    w[0] = [0.5, 0.5, 0, 0, 0, 0]  # joints 0 and 1 rotated by pi against each other: a quaternion dot of 0
    w[1] = 0.0  # no weights: the blend is zero and the vertex takes its pivot joint's transform
    a[:, 1] = a[:, 0] @ np.block(
        [[axis_angle_to_matrix(np.array([0, 0, np.pi])), np.zeros((3, 1))], [np.zeros((1, 3)), np.ones((1, 1))]]
    )
    ref = _dqs_per_vertex(v, w, a)
    np.testing.assert_allclose(dual_quaternion_skinning(v, w, a), ref, atol=1e-12)
    np.testing.assert_allclose(
        dual_quaternion_skinning(np.repeat(v[None], b, 0), np.repeat(w[None], b, 0), a), ref, atol=1e-12
    )
    lbs_ref = np.stack(
        [
            [(w[i] @ a[k, :, :3, :].reshape(s, 12)).reshape(3, 4) @ np.append(v[i], 1) for i in range(n)]
            for k in range(b)
        ]
    )
    np.testing.assert_allclose(linear_blend_skinning(v, w, a), lbs_ref, atol=1e-12)
    np.testing.assert_allclose(linear_blend_skinning(v, np.repeat(w[None], b, 0), a), lbs_ref, atol=1e-12)


def test_wrong_shapes_are_refused_not_reshaped():
    """A library user's trial: a transposed (3, B) translation was reshaped into the wrong frames' translations (the
    body 2.17 m off), and (3, 96) axis-angle vectors gave matrices from their first three columns."""
    from segadeform.body import default_body_path, load_body
    from segadeform.body.rotations import axis_angle_to_matrix

    body = load_body(default_body_path())
    poses = np.zeros((4, 72))
    with pytest.raises(InputError, match=r"trans must be \(B, 3\).*expected \(4, 3\), got \(3, 4\)"):
        body.forward(poses, trans=np.zeros((3, 4)))
    with pytest.raises(InputError, match="trans must be finite"):
        body.forward(poses, trans=np.full((4, 3), np.nan))
    assert body.forward(poses[:1], trans=np.zeros(3)).vertices.shape == (1, body.n_vertices, 3)
    with pytest.raises(InputError, match=r"must be \(\.\.\., 3\).*got \(3, 96\)"):
        axis_angle_to_matrix(np.zeros((3, 96)))
    with pytest.raises(InputError, match=r"got \(96, 2\)"):
        axis_angle_to_matrix(np.zeros((96, 2)))
