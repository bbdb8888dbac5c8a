"""Left-right mirror images of motions: the mirrored motion poses a symmetric skeleton into the mirror image."""

from __future__ import annotations

import numpy as np
import pytest

from segadeform.body.kinematics import forward_kinematics, poses_to_rotmats
from segadeform.body.skeleton import SMPL_JOINT_NAMES, SMPL_PARENTS
from segadeform.errors import InputError
from segadeform.motion.mirror import mirror_faces, mirror_joint_order, mirror_points, mirror_poses


def _symmetric_joints(rest_joints):
    """The test body's rest joints made exactly left-right symmetric (each twin the other's mirror image)."""
    perm = mirror_joint_order(SMPL_JOINT_NAMES)
    j = 0.5 * (rest_joints + mirror_points(rest_joints)[perm])
    return j


def test_the_twins_are_swapped_and_the_rest_kept():
    perm = mirror_joint_order(SMPL_JOINT_NAMES)
    names = list(SMPL_JOINT_NAMES)
    assert names[perm[names.index("left_knee")]] == "right_knee"
    assert names[perm[names.index("right_wrist")]] == "left_wrist"
    assert perm[names.index("spine2")] == names.index("spine2")
    assert sorted(perm) == list(range(len(names))) and (perm[perm] == np.arange(len(names))).all()


def test_a_mirrored_motion_poses_the_mirror_image(rest_joints):
    j = _symmetric_joints(rest_joints)
    rng = np.random.default_rng(3)
    poses = rng.normal(0, 0.6, (7, 72))
    trans = rng.normal(0, 1, (7, 3))
    par = np.asarray(SMPL_PARENTS)

    def posed(p, t):
        return forward_kinematics(poses_to_rotmats(p), j, par, t)[1]

    a = posed(poses, trans)
    b = posed(mirror_poses(poses, SMPL_JOINT_NAMES), mirror_points(trans))
    np.testing.assert_allclose(b, mirror_points(a)[:, mirror_joint_order(SMPL_JOINT_NAMES)], atol=1e-9)
    # and a mirror (not the identity, not a turn): the left knee's image is where the right knee went
    assert np.abs(b - a).max() > 0.1
    np.testing.assert_allclose(mirror_poses(mirror_poses(poses, SMPL_JOINT_NAMES), SMPL_JOINT_NAMES), poses)


def test_mirrored_faces_keep_normals_outward():
    v = np.array([[0.1, 0, 0], [1, 0, 0], [0.1, 1, 0]], float)
    f = np.array([[0, 1, 2]])
    n = np.cross(v[f[0, 1]] - v[f[0, 0]], v[f[0, 2]] - v[f[0, 0]])
    m, g = mirror_points(v), mirror_faces(f)
    nm = np.cross(m[g[0, 1]] - m[g[0, 0]], m[g[0, 2]] - m[g[0, 0]])
    np.testing.assert_allclose(nm, mirror_points(n))  # the mirror image of the normal, pointing the same way


def test_a_skeleton_without_twins_has_no_mirror_image():
    with pytest.raises(InputError, match="'left_toe' has no mirror twin"):
        mirror_joint_order(["pelvis", "left_toe", "right_foot"])
    with pytest.raises(InputError, match=r"expected \(\.\.\., 9\)"):
        mirror_poses(np.zeros((2, 8)), ["pelvis", "left_a", "right_a"])
