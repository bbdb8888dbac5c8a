"""torch FK / skinning against the numpy references in segadeform.body."""

import numpy as np
import pytest
import torch

from segadeform.body import SMPL_PARENTS, default_rest_joints, relative_transforms
from segadeform.body import dual_quaternion_skinning as np_dqs
from segadeform.body import forward_kinematics as np_fk
from segadeform.body import linear_blend_skinning as np_lbs
from segadeform.body.rotations import axis_angle_to_matrix as np_aa
from segadeform.body.rotations import matrix_to_quaternion as np_m2q
from segadeform.model import kinematics as K


def setup(b=3, n=50, seed=0, scale=1.0, twist=True):
    rng = np.random.default_rng(seed)
    poses = rng.normal(scale=scale, size=(b, 24, 3))
    if twist:
        poses[0, 5] = [np.pi, 0, 0]  # a 180-degree twist
    poses[1, 7] = [0, 0, 1e-9]  # a near-zero rotation
    joints = default_rest_joints()[None].repeat(b, 0)
    trans = rng.normal(size=(b, 3))
    verts = rng.normal(size=(n, 3))
    w = rng.dirichlet(np.ones(24) * 0.3, size=(b, n))
    return poses, joints, trans, verts, w


@pytest.mark.parametrize("scale", [0.3, 1.5, 3.0])
def test_axis_angle_and_quaternion_match_numpy(scale):
    r = np.random.default_rng(1).normal(scale=scale, size=(200, 3))
    r[0] = 0
    r[1] = [np.pi, 0, 0]
    R = K.axis_angle_to_matrix(torch.as_tensor(r)).numpy()
    np.testing.assert_allclose(R, np_aa(r), atol=1e-12)
    q = K.matrix_to_quaternion(torch.as_tensor(R)).numpy()
    qn = np_m2q(R)
    np.testing.assert_allclose(np.abs(np.sum(q * qn, -1)), 1.0, atol=1e-9)  # same up to sign


@pytest.mark.parametrize("skin", ["lbs", "dqs"])
def test_skinning_matches_numpy(skin):
    # DQS flips each quaternion into the pivot joint's hemisphere by the sign of a dot
    # product; when two joints' rotations differ by exactly 180 degrees that dot product is
    # 0 and rounding decides the flip (both answers are valid DQS).  The exact comparison
    # therefore avoids the tie for DQS; the tie itself is tested below.
    poses, joints, trans, verts, w = setup(twist=skin == "lbs", scale=1.0 if skin == "lbs" else 0.5)
    g_np, _ = np_fk(np_aa(poses), joints, SMPL_PARENTS, trans)
    a_np = relative_transforms(g_np, joints)
    ref = (np_lbs if skin == "lbs" else np_dqs)(verts, w, a_np)
    t = lambda x: torch.as_tensor(np.asarray(x))  # noqa: E731
    g = K.forward_kinematics(K.axis_angle_to_matrix(t(poses)), t(joints), [int(p) for p in SMPL_PARENTS], t(trans))
    np.testing.assert_allclose(g.numpy(), g_np, atol=1e-12)
    a = K.skinning_transforms(g, t(joints))
    out = (K.lbs if skin == "lbs" else K.dqs)(t(verts)[None], t(w), a).numpy()
    np.testing.assert_allclose(out, ref, atol=1e-10)


def test_dqs_at_the_180_degree_tie_is_finite_and_rigid_where_unblended():
    poses, joints, trans, verts, w = setup(twist=True)
    t = lambda x: torch.as_tensor(np.asarray(x))  # noqa: E731
    g = K.forward_kinematics(K.axis_angle_to_matrix(t(poses)), t(joints), [int(p) for p in SMPL_PARENTS], t(trans))
    a = K.skinning_transforms(g, t(joints))
    out = K.dqs(t(verts)[None], t(w), a)
    assert torch.isfinite(out).all()
    onehot = torch.nn.functional.one_hot(torch.full((3, 50), 5), 24).double()  # all weight on the twisted joint
    torch.testing.assert_close(K.dqs(t(verts)[None], onehot, a), K.lbs(t(verts)[None], onehot, a))


def test_dqs_falls_back_to_the_pivot_joint_where_the_blend_vanishes():
    # after the hemisphere flip the blend's real part has norm >= the pivot's weight, so only a vertex
    # with no weight at all reaches the fallback: it takes the pivot's (joint 0's) rigid transform
    poses, joints, trans, verts, w = setup(twist=False, scale=0.5)
    w = np.array(w, copy=True)
    w[..., :7, :] = 0.0
    g_np, _ = np_fk(np_aa(poses), joints, SMPL_PARENTS, trans)
    ref = np_dqs(verts, w, relative_transforms(g_np, joints))
    t = lambda x: torch.as_tensor(np.asarray(x))  # noqa: E731
    g = K.forward_kinematics(K.axis_angle_to_matrix(t(poses)), t(joints), [int(p) for p in SMPL_PARENTS], t(trans))
    a = K.skinning_transforms(g, t(joints))
    out = K.dqs(t(verts)[None], t(w), a).numpy()
    np.testing.assert_allclose(out, ref, atol=1e-10)
    onehot = torch.nn.functional.one_hot(torch.zeros(w.shape[:-1], dtype=torch.long), 24).double()
    np.testing.assert_allclose(out[..., :7, :], K.lbs(t(verts)[None], onehot, a).numpy()[..., :7, :], atol=1e-10)


@pytest.mark.parametrize("skin", ["lbs", "dqs"])
def test_weights_shared_by_every_frame_give_the_per_frame_result(skin):
    # (N, S) weights (the body graphs' path, read transposed) against the same weights given per frame
    poses, joints, trans, verts, w = setup(twist=False, scale=0.5)
    t = lambda x: torch.as_tensor(np.asarray(x))  # noqa: E731
    g = K.forward_kinematics(K.axis_angle_to_matrix(t(poses)), t(joints), [int(p) for p in SMPL_PARENTS], t(trans))
    a = K.skinning_transforms(g, t(joints))
    f = K.lbs if skin == "lbs" else K.dqs
    shared = t(w[0])
    torch.testing.assert_close(
        f(t(verts), shared, a), f(t(verts), shared[None].expand(len(poses), -1, -1), a), rtol=0, atol=1e-12
    )
