"""AMASS / SMPL .npz motions: Z-up worlds, the SMPL pelvis convention, pose layouts, metadata, the floor."""

from __future__ import annotations

import numpy as np
import pytest

from segadeform.body.kinematics import forward_kinematics, poses_to_rotmats
from segadeform.body.rotations import axis_angle_to_matrix, matrix_to_axis_angle
from segadeform.body.skeleton import SMPL_PARENTS, default_rest_joints
from segadeform.errors import FileFormatError
from segadeform.motion import feet_on_floor, load_motion, make_motion
from segadeform.motion.motion import SMPL_PELVIS
from tests.conftest import SAMPLES

SAMPLES_WALK = SAMPLES / "motions" / "walk.npz"

Y_UP_TO_Z_UP = np.array([[1.0, 0, 0], [0, 0, -1.0], [0, 1.0, 0]])  # (x, y, z) -> (x, -z, y)


def _as_amass(m, J, *, width=156, layout="flat", z_up=True):
    """What AMASS stores for motion ``m`` played on a body with rest joints ``J``."""
    pelvis = J[0] + m.trans  # world pelvis, y-up
    poses = m.poses.copy()
    if z_up:
        poses[:, :3] = matrix_to_axis_angle(Y_UP_TO_Z_UP @ axis_angle_to_matrix(poses[:, :3]))
        pelvis = pelvis @ Y_UP_TO_Z_UP.T
    trans = pelvis - SMPL_PELVIS
    if width == 72:
        p = poses
    else:
        p = np.concatenate([poses[:, :66], np.random.default_rng(0).normal(size=(len(poses), width - 66)) * 0.1], 1)
    if layout == "tj3":
        p = p.reshape(len(p), -1, 3)
    return p, trans


@pytest.mark.parametrize("width, layout", [(156, "flat"), (165, "flat"), (72, "flat"), (72, "tj3"), (156, "tj3")])
def test_amass_round_trip_upright(tmp_path, width, layout):
    J = default_rest_joints()
    m = make_motion("walk", seconds=1.0, seed=1)
    poses, trans = _as_amass(m, J, width=width, layout=layout)
    np.savez(
        tmp_path / "a.npz",
        poses=poses,
        trans=trans,
        mocap_framerate=np.float64(120.00004578),
        gender=np.array(b"female"),
        betas=np.zeros(16),
        dmpls=np.zeros((len(poses), 8)),
    )
    r = load_motion(tmp_path / "a.npz", rest_joints=J)
    assert r.meta["up"] == "z" and r.meta["gender"] == "female" and r.fps == pytest.approx(120.00004578)
    body = np.asarray(m.poses)
    np.testing.assert_allclose(
        poses_to_rotmats(r.poses, 24)[:, : 22 if width != 72 else 24],
        poses_to_rotmats(body, 24)[:, : 22 if width != 72 else 24],
        atol=1e-9,
    )
    np.testing.assert_allclose(r.trans, m.trans, atol=1e-9)
    # upright: the head is above the pelvis, the feet near the floor
    _, posed = forward_kinematics(poses_to_rotmats(r.poses, 24), J, SMPL_PARENTS, r.trans)
    assert (posed[:, 15, 1] - posed[:, 0, 1]).min() > 0.4
    assert abs(posed[:, [7, 8, 10, 11], 1].min() - J[[7, 8, 10, 11], 1].min()) < 0.03


def test_amass_split_keys_and_string_gender(tmp_path):
    J = default_rest_joints()
    m = make_motion("dance", seconds=0.5, seed=2)
    poses, trans = _as_amass(m, J, width=72)
    np.savez(
        tmp_path / "x.npz",
        root_orient=poses[:, :3],
        pose_body=poses[:, 3:66],
        trans=trans,
        mocap_frame_rate=np.array(60.0),
        gender=np.array("male"),
    )
    r = load_motion(tmp_path / "x.npz", rest_joints=J)
    assert r.meta["gender"] == "male" and r.fps == 60.0 and r.meta["up"] == "z"
    np.testing.assert_allclose(r.trans, m.trans, atol=1e-9)


def test_up_override_and_y_up_data(tmp_path):
    J = default_rest_joints()
    m = make_motion("walk", seconds=0.5)
    poses, trans = _as_amass(m, J, width=72, z_up=False)
    np.savez(tmp_path / "y.npz", poses=poses, trans=trans, gender="neutral")
    r = load_motion(tmp_path / "y.npz", rest_joints=J)
    assert r.meta["up"] == "y"
    np.testing.assert_allclose(r.trans, m.trans, atol=1e-9)
    forced = load_motion(tmp_path / "y.npz", rest_joints=J, up="z")  # wrong on purpose: lies on its back
    _, posed = forward_kinematics(poses_to_rotmats(forced.poses, 24), J, SMPL_PARENTS, forced.trans)
    assert abs(posed[:, 15, 1] - posed[:, 0, 1]).max() < 0.3
    with pytest.raises(Exception, match="up must be"):
        load_motion(tmp_path / "y.npz", up="x")


def test_own_files_round_trip_unchanged(tmp_path):
    m = make_motion("jump", seconds=0.5)
    m.save(tmp_path / "m.npz")
    r = load_motion(tmp_path / "m.npz", rest_joints=default_rest_joints() * 1.1)
    np.testing.assert_allclose(r.poses, m.poses, atol=1e-6)
    np.testing.assert_allclose(r.trans, m.trans, atol=1e-6)
    assert r.meta["convention"] == "segadeform"


def test_feet_on_floor_shift_is_one_constant(tmp_path):
    J = default_rest_joints()
    m = make_motion("jump", seconds=1.0)
    lifted = feet_on_floor(m, J, floor=0.5)
    d = lifted.trans - m.trans
    assert np.ptp(d[:, 1]) < 1e-12 and np.abs(d[:, [0, 2]]).max() == 0
    _, posed = forward_kinematics(poses_to_rotmats(lifted.poses, 24), J, SMPL_PARENTS, lifted.trans)
    assert posed[:, [7, 8, 10, 11], 1].min() == pytest.approx(J[[7, 8, 10, 11], 1].min() + 0.5)


@pytest.mark.parametrize(
    "arrays, words",
    [
        (dict(poses=np.zeros((3, 24, 2))), "unknown layout"),
        (dict(poses=np.zeros((3, 23, 3))), "unknown layout"),
        (dict(root_orient=np.zeros((3, 3)), pose_body=np.zeros((3, 60))), "do not fit"),
        (dict(poses=np.zeros((3, 72)), mocap_framerate=np.float64(np.nan)), "positive"),
        (dict(poses=np.full((3, 72), np.nan)), "NaN"),
        (dict(poses=np.zeros((3, 72)), trans=np.full((3, 3), np.inf)), "NaN or inf"),
        # finite but past any capture: 1e300 overflowed the angle's norm into NaN, said of the network's input with
        # numpy's warnings, and `motion export` wrote it (a fuzzer's trial)
        (dict(poses=np.full((3, 72), 1e300)), r"an angle no capture holds.*got 1e\+300 \(frame 0, joint 0\)"),
        (dict(poses=np.pad(np.full((1, 1), -2e6), ((2, 0), (5, 66)))), r"got -2e\+06 \(frame 2, joint 1\)"),
    ],
)
def test_malformed_amass_layouts(tmp_path, arrays, words):
    np.savez(tmp_path / "m.npz", **arrays)
    with pytest.raises(FileFormatError, match=words) as ei:
        load_motion(tmp_path / "m.npz")
    assert "m.npz" in str(ei.value)


def test_equal_rotations_written_otherwise_are_the_same_motion(tmp_path):
    """A user's trial: walk.npz with the left hip's axis-angle turned 720 degrees further (or about the opposite axis
    by 2 pi minus its angle) posed the same body but moved the garment by 4.7 mm to 7 cm, since the network reads
    axis-angle.  Every motion now holds its rotations with angles in [0, pi]; those already there are kept bit for
    bit."""
    from segadeform.body.rotations import canonical_axis_angle

    rng = np.random.default_rng(0)
    r = rng.normal(0.0, 1.0, (200, 3))
    r *= (rng.uniform(0.0, np.pi, 200) / np.linalg.norm(r, axis=1))[:, None]  # angles in [0, pi)
    assert canonical_axis_angle(r) is r or np.array_equal(canonical_axis_angle(r), r)
    u = r / np.linalg.norm(r, axis=1, keepdims=True)
    t = np.linalg.norm(r, axis=1, keepdims=True)
    for other in (r + 4 * np.pi * u, -u * (2 * np.pi - t), r + 1000 * 2 * np.pi * u):
        np.testing.assert_allclose(axis_angle_to_matrix(other), axis_angle_to_matrix(r), atol=1e-9)
        np.testing.assert_allclose(canonical_axis_angle(other), r, atol=1e-9 * (1 + np.abs(other).max()))
    m = load_motion(SAMPLES_WALK)
    d = dict(np.load(SAMPLES_WALK, allow_pickle=False))
    hip = d["poses"][:, 3:6].astype(np.float64)
    th = np.maximum(np.linalg.norm(hip, axis=1, keepdims=True), 1e-12)
    for name, new in (("720", hip + 4 * np.pi * hip / th), ("flip", -hip / th * (2 * np.pi - th))):
        d2 = dict(d, poses=np.concatenate([d["poses"][:, :3], new, d["poses"][:, 6:]], axis=1))
        np.savez(tmp_path / f"{name}.npz", **d2)
        m2 = load_motion(tmp_path / f"{name}.npz")
        np.testing.assert_allclose(m2.poses, m.poses, atol=1e-9)
        assert np.array_equal(m2.poses[:, 6:], m.poses[:, 6:])  # the other joints: untouched


def test_a_motion_made_in_python_with_angles_past_any_capture_is_refused():
    """The same bound on a Motion built by hand: it was built, holding NaN after its angles were made canonical."""
    from segadeform.errors import InputError
    from segadeform.motion import Motion

    with pytest.raises(InputError, match="an angle no capture holds"):
        Motion(poses=np.full((2, 72), 1e300), trans=np.zeros((2, 3)), fps=30.0)
    m = Motion(poses=np.full((2, 72), 1e5), trans=np.zeros((2, 3)), fps=30.0)  # within it: finite, canonical
    assert np.isfinite(m.poses).all() and np.linalg.norm(m.poses.reshape(-1, 3), axis=1).max() <= np.pi + 1e-9
