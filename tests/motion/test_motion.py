import dataclasses
import re

import numpy as np
import pytest
from click.testing import CliRunner

from segadeform.body import axis_angle_to_matrix, default_rest_joints, forward_kinematics, poses_to_rotmats
from segadeform.body.skeleton import SMPL_PARENTS
from segadeform.cli.main import cli
from segadeform.errors import FileFormatError, InputError
from segadeform.motion import (
    MOTION_KINDS,
    Motion,
    history_inputs,
    load_motion,
    make_motion,
    motion_windows,
    read_bvh,
    resample,
    write_bvh,
)
from segadeform.motion.bvh import MIXAMO_TO_SMPL, SMPL_SHORT_NAMES
from segadeform.motion.limits import limit_violation


def rot(m):
    return axis_angle_to_matrix(m.poses.reshape(-1, 24, 3))


# ---- AMASS npz -----------------------------------------------------------
@pytest.mark.parametrize("width", [72, 66, 156])
def test_amass_widths(tmp_path, width):
    rng = np.random.default_rng(0)
    poses = rng.normal(scale=0.2, size=(10, width))
    np.savez(tmp_path / "a.npz", poses=poses, trans=rng.normal(size=(10, 3)), betas=np.ones(16), mocap_framerate=120.0)
    m = load_motion(tmp_path / "a.npz")
    assert m.poses.shape == (10, 72) and m.fps == 120.0 and m.betas.shape == (16,)
    np.testing.assert_array_equal(m.poses[:, :66], poses[:, :66])
    if width != 72:
        assert (m.poses[:, 66:] == 0).all()


@pytest.mark.parametrize(
    "arrays, words",
    [
        (dict(trans=np.zeros((3, 3))), "no 'poses'"),
        (dict(poses=np.zeros((3, 70))), "unknown width"),
        (dict(poses=np.zeros((0, 72))), "no frames"),
        (dict(poses=np.zeros((3, 72)), trans=np.zeros((2, 3))), "trans"),
        (dict(poses=np.full((3, 72), np.nan)), "NaN"),
        (dict(poses=np.zeros((3, 72)), mocap_framerate=-1.0), "fps"),
        (dict(poses=np.array(["a"] * 72).reshape(1, 72)), "numeric"),
    ],
)
def test_malformed_amass(tmp_path, arrays, words):
    np.savez(tmp_path / "m.npz", **arrays)
    with pytest.raises(FileFormatError, match=words) as ei:
        load_motion(tmp_path / "m.npz")
    assert "m.npz" in str(ei.value)


def test_save_load_round_trip(tmp_path):
    m = make_motion("walk", seconds=1.0)
    m.save(tmp_path / "w.npz")
    back = load_motion(tmp_path / "w.npz")
    np.testing.assert_allclose(back.poses, m.poses, atol=1e-6)
    assert back.fps == m.fps


def test_history_inputs_are_the_pose_and_the_roots_velocity_in_its_own_frame():
    """A body facing +x (root yawed 90 degrees about y) walking along +x at 1.5 m/s moves forward (+z) in its
    own frame; the same walk turned to face +z gives the same inputs but for the root's rotation; the first
    frame is at rest."""
    t = np.arange(6) / 30.0
    poses = np.zeros((6, 72))
    poses[:, 1] = np.pi / 2  # yaw 90 degrees: the body's +z is the world's +x
    poses[:, 5] = 0.3  # some other joint, passed through
    trans = np.stack([1.5 * t, np.full(6, 0.9), np.zeros(6)], axis=1)
    x = history_inputs(poses, trans, 30.0)
    assert x.shape == (6, 75) and np.array_equal(x[:, :72], poses)
    np.testing.assert_allclose(x[0, 72:], 0.0)
    np.testing.assert_allclose(x[1:, 72:], np.tile([0.0, 0.0, 1.5], (5, 1)), atol=1e-9)
    straight = history_inputs(np.zeros((6, 72)), trans[:, [2, 1, 0]], 30.0)  # facing +z, walking +z
    np.testing.assert_allclose(straight[:, 72:], x[:, 72:], atol=1e-9)
    for bad in ((np.zeros((6, 71)), trans, 30.0), (poses, trans[:5], 30.0), (poses, trans, 0.0)):
        with pytest.raises(InputError):
            history_inputs(*bad)


# ---- resampling and windows ----------------------------------------------
def test_resample_keeps_frames_and_interpolates_on_the_sphere():
    m = make_motion("dance", seconds=2.0, fps=30)
    up = resample(m, 60)
    assert up.n_frames == 2 * m.n_frames - 1
    np.testing.assert_allclose(rot(up)[::2], rot(m), atol=1e-9)
    # a midpoint is the slerp midpoint: equal angle to both neighbours
    r = rot(up)
    a = np.einsum("tjik,tjik->tj", r[1:-1:2], r[0:-2:2])
    b = np.einsum("tjik,tjik->tj", r[1:-1:2], r[2::2])
    np.testing.assert_allclose(a, b, atol=1e-9)
    down = resample(m, 10)
    np.testing.assert_allclose(rot(down), rot(m)[::3], atol=1e-9)


def test_a_rate_written_rounded_is_the_rate_asked_for():
    """A BVH's "Frame Time: 0.008333" is 120.005 fps; `--fps 120` resampled it and lost its last frame (343 -> 342, the
    new last frame 13.9 mm off: an engine integrator's trial).  A rate within SAME_RATE of the file's keeps its
    frames, at the rate asked; a rate really apart is resampled."""
    m = dataclasses.replace(make_motion("walk", seconds=2.0, fps=30), fps=1.0 / 0.008333)
    same = resample(m, 120.0)
    assert same.fps == 120.0 and same.n_frames == m.n_frames
    np.testing.assert_array_equal(same.poses, m.poses)
    assert resample(m, 119.0).n_frames < m.n_frames


def test_windows_pad_with_first_frame():
    p = np.arange(6, dtype=float)[:, None] * np.ones((1, 72))
    w = motion_windows(p, 4)
    assert w.shape == (6, 4, 72)
    np.testing.assert_array_equal(
        w[:, :, 0], [[0, 0, 0, 0], [1, 0, 0, 0], [2, 1, 0, 0], [3, 2, 1, 0], [4, 3, 2, 1], [5, 4, 3, 2]]
    )
    np.testing.assert_array_equal(motion_windows(p, 2, start=2, stop=4)[:, :, 0], [[2, 1], [3, 2]])
    with pytest.raises(InputError):
        motion_windows(p, 0)


# ---- procedural ----------------------------------------------------------
@pytest.mark.parametrize("kind", sorted(MOTION_KINDS))
def test_procedural_inside_limits_and_deterministic(kind):
    worst = 0.0
    for seed in range(12):
        m = make_motion(kind, seconds=3.0, seed=seed, amplitude=1.0 + 0.08 * seed, speed=0.5 + 0.2 * seed)
        worst = max(worst, limit_violation(m.poses))
        assert np.isfinite(m.poses).all() and np.isfinite(m.trans).all()
    assert worst < 1e-9
    a, b = make_motion(kind, seed=7), make_motion(kind, seed=7)
    np.testing.assert_array_equal(a.poses, b.poses)
    c = make_motion(kind, seed=8, seconds=3.0)
    assert not np.array_equal(a.poses[45:], c.poses[45:]) or kind == "jump"  # jump has no random part


@pytest.mark.parametrize("kind", sorted(MOTION_KINDS))
def test_very_short_procedural_motions(kind):
    """Regression: the dance's 0.25 s smoothing kernel was longer than motions under ~0.25 s (a broadcast error)."""
    for seconds in (1 / 30, 0.05, 0.1, 0.2, 0.3):
        m = make_motion(kind, seconds=seconds)
        assert m.poses.shape == (max(1, round(seconds * 30)), 72)
        assert np.isfinite(m.poses).all() and np.isfinite(m.trans).all()


def test_motions_ease_in_from_rest():
    m = make_motion("walk", seconds=2.0)
    assert np.abs(m.poses[0]).max() < 1e-12


def test_limit_check_can_fail():
    p = np.zeros((1, 72))
    p[0, 3 * 4] = -np.deg2rad(30)  # left knee bent backwards
    assert np.rad2deg(limit_violation(p)) == pytest.approx(30.0)


# ---- BVH -----------------------------------------------------------------
def test_bvh_round_trip_smpl_and_mixamo_names(tmp_path):
    J = default_rest_joints()
    m = make_motion("dance", seconds=1.5, seed=2)
    write_bvh(tmp_path / "a.bvh", m, J, scale=100.0)
    r = read_bvh(tmp_path / "a.bvh", rest_joints=J)
    np.testing.assert_allclose(rot(r), rot(m), atol=1e-7)
    np.testing.assert_allclose(r.trans, m.trans, atol=1e-7)
    assert r.fps == pytest.approx(30.0, rel=1e-6)
    for vocab, prefix in ((MIXAMO_TO_SMPL, "mixamorig:"), (SMPL_SHORT_NAMES, "")):
        txt = (tmp_path / "a.bvh").read_text()
        inv = {v: k for k, v in vocab.items()}
        for smpl, other in inv.items():
            txt = re.sub(rf"\b(JOINT|ROOT) {smpl}\b", rf"\1 {prefix}{other}", txt)
        (tmp_path / "b.bvh").write_text(txt)
        np.testing.assert_allclose(rot(read_bvh(tmp_path / "b.bvh", rest_joints=J)), rot(m), atol=1e-7)
    # write -> read -> write gives the same file
    write_bvh(tmp_path / "c.bvh", r, J, scale=100.0)
    r2 = read_bvh(tmp_path / "c.bvh", rest_joints=J)
    np.testing.assert_allclose(rot(r2), rot(r), atol=1e-7)


def test_bvh_a_pose_rest_is_corrected(tmp_path):
    """A file whose rest pose has the arms 45 degrees down: at zero rotation the arms must hang
    45 degrees down on the T-pose target too."""
    J = default_rest_joints()
    a_pose = J.copy()
    for sh, el, wr, ha, _side in ((16, 18, 20, 22, 1), (17, 19, 21, 23, -1)):
        for k in (el, wr, ha):
            d = J[k] - J[sh]
            a_pose[k] = J[sh] + np.array([d[0] * np.cos(np.pi / 4), -abs(d[0]) * np.sin(np.pi / 4), d[2]])
    still = Motion(poses=np.zeros((2, 72)), trans=np.zeros((2, 3)), fps=30)
    write_bvh(tmp_path / "a.bvh", still, a_pose, scale=100.0)
    m = read_bvh(tmp_path / "a.bvh", rest_joints=J)
    _, posed = forward_kinematics(poses_to_rotmats(m.poses, 24), J, SMPL_PARENTS, m.trans)
    for sh, el in ((16, 18), (17, 19)):
        d = posed[0, el] - posed[0, sh]
        want = a_pose[el] - a_pose[sh]
        np.testing.assert_allclose(d / np.linalg.norm(d), want / np.linalg.norm(want), atol=1e-6)


@pytest.mark.parametrize(
    "mutate, words",
    [
        (lambda t: t.replace("HIERARCHY", "HIERARCHX"), "unexpected token"),
        (lambda t: t.rsplit("\n", 3)[0] + "\n", "does not match its declared size"),
        (lambda t: t.replace("Frames: 6", "Frames: 600000000"), "does not match its declared size"),
        (lambda t: t.replace("Frame Time: ", "Frame Time: -"), "positive"),
        (lambda t: t.replace("CHANNELS 3", "CHANNELS 9", 1), "channel count"),
        (lambda t: t.replace("Zrotation", "Wrotation", 1), "unknown channel"),
        (lambda t: "\n".join(t.splitlines()[:40]), "ends too early"),
        (lambda t: t.replace("0.000000", "nan", 1), "not finite"),
    ],
)
def test_malformed_bvh(tmp_path, mutate, words):
    write_bvh(tmp_path / "a.bvh", make_motion("idle", seconds=0.2), default_rest_joints())
    (tmp_path / "b.bvh").write_text(mutate((tmp_path / "a.bvh").read_text()))
    with pytest.raises(FileFormatError, match=words) as ei:
        read_bvh(tmp_path / "b.bvh")
    assert "b.bvh" in str(ei.value)


def test_a_frame_line_with_a_value_missing_is_named(tmp_path):
    """A user's trial: a value deleted from one frame line was reported at the Frames: line, six lines above."""
    write_bvh(tmp_path / "a.bvh", make_motion("idle", seconds=0.2), default_rest_joints())
    lines = (tmp_path / "a.bvh").read_text().splitlines()
    k = len(lines) - 3  # a frame line
    lines[k] = lines[k].rsplit(" ", 1)[0]
    (tmp_path / "b.bvh").write_text("\n".join(lines) + "\n")
    with pytest.raises(FileFormatError, match=r"this line has \d+ numbers, a frame \d+") as ei:
        read_bvh(tmp_path / "b.bvh")
    assert f"b.bvh:{k + 1}:" in str(ei.value)


# ---- CLI -----------------------------------------------------------------
def test_motion_cli(tmp_path):
    r = CliRunner().invoke(
        cli, ["motion", "make", "run", "--seconds", "1", "--fps", "24", "--seed", "3", "-o", str(tmp_path / "r.npz")]
    )
    assert r.exit_code == 0, r.output
    m = load_motion(tmp_path / "r.npz")
    assert m.n_frames == 24 and m.fps == 24
    r = CliRunner().invoke(cli, ["motion", "info", str(tmp_path / "r.npz")])
    assert r.exit_code == 0 and "24 frames" in r.output and "outside joint limits by: 0.00 deg" in r.output
    r = CliRunner().invoke(cli, ["motion", "make", "fly", "-o", str(tmp_path / "x.npz")])
    assert r.exit_code == 1 and "unknown motion kind" in r.output and not (tmp_path / "x.npz").exists()
    r = CliRunner().invoke(cli, ["motion", "info", str(tmp_path / "missing.bvh")])
    assert r.exit_code == 1 and "missing.bvh" in r.output


def test_drop_leading_jumps_removes_a_tpose_put_in_front():
    from segadeform.motion import make_motion
    from segadeform.motion.motion import drop_leading_jumps

    m = make_motion("walk", seconds=1.0, fps=30.0, seed=0)
    assert drop_leading_jumps(m)[1] == 0  # a motion that flows is left alone
    poses = np.concatenate([np.zeros((1, 72)), m.poses])
    poses[1:, 3 * 16 + 2] -= 1.3  # the capture has the arms down; the T-pose in front has them up
    trans = np.concatenate([m.trans[:1], m.trans])
    tp = dataclasses.replace(m, poses=poses, trans=trans)
    out, k = drop_leading_jumps(tp)
    assert k == 1 and out.n_frames == m.n_frames and np.allclose(out.poses, poses[1:])
    assert out.meta["dropped_leading_frames"] == 1


def _joint_speeds_by_hand(m, joints):
    """The obvious reference: every frame posed on its own, the fastest joint's step times the frame rate."""
    posed = []
    for t in range(m.n_frames):
        rot = axis_angle_to_matrix(m.poses[t].reshape(1, 24, 3))
        posed.append(forward_kinematics(rot, joints, SMPL_PARENTS, m.trans[t : t + 1])[1][0])
    return np.array([np.linalg.norm(posed[t + 1] - posed[t], axis=1).max() * m.fps for t in range(m.n_frames - 1)])


def test_joint_speeds_are_the_fastest_joints_step_per_second():
    from segadeform.motion import make_motion
    from segadeform.motion.motion import joint_speeds

    j = default_rest_joints()
    m = make_motion("dance", seconds=0.5, fps=30.0, seed=1)
    np.testing.assert_allclose(joint_speeds(m, j), _joint_speeds_by_hand(m, j), rtol=1e-10, atol=1e-12)
    still = dataclasses.replace(m, poses=np.zeros_like(m.poses), trans=np.outer(np.arange(m.n_frames), [0.1, 0, 0]))
    np.testing.assert_allclose(joint_speeds(still, j), 3.0)  # 0.1 m a frame at 30 fps: every joint at 3 m/s
    with pytest.raises(InputError, match="rest joints"):
        joint_speeds(m, j[:10])


def test_drop_leading_glitches_drops_the_frames_a_capture_settles_from():
    from segadeform.motion import make_motion
    from segadeform.motion.motion import drop_leading_glitches

    j = default_rest_joints()
    m = make_motion("walk", seconds=2.0, fps=120.0, seed=0)
    assert drop_leading_glitches(m, j)[1] == 0  # a motion that flows is left alone
    bad = m.poses.copy()
    bad[[0, 2], 3 * 1 + 0] += 1.2  # the first frames of the solve: a thigh thrown forward and back
    g = dataclasses.replace(m, poses=bad)
    out, k = drop_leading_glitches(g, j)
    assert k == 3 and out.n_frames == m.n_frames - 3 and np.array_equal(out.poses, m.poses[3:])
    assert out.meta["dropped_leading_glitch_frames"] == 3
    late = m.poses.copy()
    late[100, 3 * 1 + 0] += 1.2  # a jump after the first tenth of a second is no settling: left here
    assert drop_leading_glitches(dataclasses.replace(m, poses=late), j)[1] == 0


def test_repair_glitches_rebuilds_a_frame_the_capture_jumps_to_and_back_from():
    from segadeform.motion import make_motion
    from segadeform.motion.motion import joint_speeds, repair_glitches

    j = default_rest_joints()
    m = make_motion("walk", seconds=2.0, fps=120.0, seed=0)
    assert repair_glitches(m, j)[1] == 0
    bad = m.poses.copy()
    bad[[100, 101], 3 * 18 + 1] += 2.5  # two frames of a forearm swung 143 degrees away (swapped markers)
    out, k = repair_glitches(dataclasses.replace(m, poses=bad), j)
    assert k == 2 and out.meta["repaired_glitch_frames"] == 2
    assert joint_speeds(out, j).max() < 20.0
    np.testing.assert_allclose(out.poses[:100], m.poses[:100])  # nothing else moves
    np.testing.assert_allclose(out.poses[102:], m.poses[102:])
    # the rebuilt frames lie where the walk was (it is smooth at 120 fps): millimetres, not the 0.4 m jump
    _, was = forward_kinematics(axis_angle_to_matrix(m.poses[100:102].reshape(2, 24, 3)), j, SMPL_PARENTS)
    _, now = forward_kinematics(axis_angle_to_matrix(out.poses[100:102].reshape(2, 24, 3)), j, SMPL_PARENTS)
    assert np.linalg.norm(now - was, axis=2).max() < 0.005
    cut = m.poses.copy()
    cut[100:, 3 * 18 + 1] += 2.5  # one step over the bound and no way back: a cut, nothing to rebuild
    assert repair_glitches(dataclasses.replace(m, poses=cut), j)[1] == 0
    with pytest.raises(InputError, match="max_speed"):
        repair_glitches(m, j, max_speed=0.0)


def test_a_scene_can_repair_a_captures_glitches_keeping_its_frames(tmp_path):
    """``[motion] repair_glitches``: the settling frames hold the first settled pose and a two-frame jump is
    rebuilt; the frame count and every other frame are the file's (a user's timeline does not move)."""
    from segadeform.motion import make_motion
    from segadeform.motion.motion import joint_speeds
    from segadeform.motion.spec import build_motion
    from segadeform.settings.scene import MotionSpec

    j = default_rest_joints()
    m = make_motion("walk", seconds=2.0, fps=120.0, seed=0, ease_in=0.0)
    bad = m.poses.copy()
    bad[[0, 2], 3 * 1] += 0.9
    bad[[100, 101], 3 * 18 + 1] += 2.5
    dataclasses.replace(m, poses=bad).save(tmp_path / "cap.npz")
    as_is = build_motion(MotionSpec(file=tmp_path / "cap.npz"), j)
    assert joint_speeds(as_is, j).max() > 80
    fixed = build_motion(MotionSpec(file=tmp_path / "cap.npz", repair_glitches=True), j)
    assert fixed.n_frames == m.n_frames and joint_speeds(fixed, j).max() < 20.0
    np.testing.assert_allclose(fixed.poses[:3], np.repeat(m.poses[3:4], 3, axis=0), atol=1e-6)  # held
    np.testing.assert_allclose(fixed.poses[3:100], m.poses[3:100], atol=1e-6)
    np.testing.assert_allclose(fixed.poses[102:], m.poses[102:], atol=1e-6)
    assert fixed.meta["held_leading_glitch_frames"] == 3 and fixed.meta["repaired_glitch_frames"] == 2
    assert "dropped_leading_glitch_frames" not in fixed.meta
    r = CliRunner().invoke(cli, ["motion", "info", str(tmp_path / "cap.npz")])
    assert r.exit_code == 0 and "3 leading frames the capture settles from, 2 frames it jumps to" in r.output
    # `motion export` (the other runtimes' motion files) warns of them in its range, and repairs them when asked
    from segadeform.io.sgdm import read_motion_arrays

    def export(name, *extra):
        out = tmp_path / name
        args = ["motion", "export", str(tmp_path / "cap.npz"), "--fps", "120", "-o", str(out), *extra]
        res = CliRunner().invoke(cli, args)
        assert res.exit_code == 0, res.output
        return read_motion_arrays(out)[0], res.output

    raw, said = export("raw.sgdm")
    assert "3 leading frames it settles from and 2 frames it jumps to" in said and "--repair-glitches" in said
    # kept in the file, for Node and C++ to say again (tests/runtimes/test_command_lines.py)
    kept = read_motion_arrays(tmp_path / "raw.sgdm")[3]["warnings"]
    assert len(kept) == 1 and "3 leading frames it settles from" in kept[0] and kept[0] in said
    _, said = export("late.sgdm", "--frames", "110:200")  # none inside this range: nothing to say
    assert "warning" not in said
    rep, said = export("rep.sgdm", "--repair-glitches")
    assert "warning" not in said and rep.shape == raw.shape
    np.testing.assert_allclose(rep.reshape(m.n_frames, -1), fixed.poses, atol=1e-5)


def test_ramp_in_starts_from_rest_and_joins_the_motion_at_full_speed():
    from segadeform.motion import make_motion
    from segadeform.motion.motion import ramp_in

    m = make_motion("run", seconds=2.0, fps=30.0, seed=0, ease_in=0.0)
    r = ramp_in(m, 0.5)
    k = 15
    assert r.n_frames == 2 * k + (m.n_frames - k)
    np.testing.assert_allclose(r.poses[2 * k :], m.poses[k:])  # the rest as it is
    np.testing.assert_allclose(r.poses[0], m.poses[0])  # starts in the first pose ...
    step = np.linalg.norm(np.diff(r.trans, axis=0), axis=1)
    assert step[0] < 0.1 * step[2 * k + 5]  # ... at rest, and speeds up ...
    assert np.all(np.diff(step[: 2 * k - 1]) > -1e-3 * step.max())  # ... without slowing down on the way
    assert abs(step[2 * k - 1] - step[2 * k]) < 0.2 * step[2 * k]  # its speed where the motion takes over
    with pytest.raises(InputError):
        ramp_in(m, 100.0)


def test_drop_leading_tpose_removes_a_calibration_pose_and_the_move_out_of_it():
    from segadeform.motion import make_motion
    from segadeform.motion.motion import drop_leading_tpose

    m = make_motion("walk_arms_down", seconds=2.0, fps=30.0, seed=0, ease_in=0.0)
    assert drop_leading_tpose(m)[1] == 0  # arms down from the start: left alone
    poses = m.poses.copy()
    poses[:10, 3 * 16 : 3 * 18] = 0.0  # the first 10 frames: both upper arms at the T-pose
    out, k = drop_leading_tpose(dataclasses.replace(m, poses=poses))
    assert k == 10 + 15 and out.n_frames == m.n_frames - k and np.allclose(out.poses, poses[k:])
    still = dataclasses.replace(m, poses=np.zeros_like(m.poses))  # a T-pose throughout: nothing to tell apart
    assert drop_leading_tpose(still)[1] == 0


def test_a_motion_file_cut_twice_counts_frames_from_its_source(tmp_path):
    """`motion export a.sgdm --frames 5:10` of a file cut at 10 recorded 5 (its source's frame is 15)."""
    from segadeform.cli.main import main
    from segadeform.io.sgdm import read_motion_arrays

    assert (
        main(["motion", "export", "dance", "--seconds", "2", "--frames", "10:40", "-o", str(tmp_path / "a.sgdm")]) == 0
    )
    assert main(["motion", "export", str(tmp_path / "a.sgdm"), "--frames", "5:10", "-o", str(tmp_path / "b.sgdm")]) == 0
    assert read_motion_arrays(tmp_path / "a.sgdm")[3]["start_frame"] == 10
    assert read_motion_arrays(tmp_path / "b.sgdm")[3]["start_frame"] == 15
    # resampled, its first frame keeps its time: frame 10 at 30 fps is frame 20 at 60
    assert main(["motion", "export", str(tmp_path / "a.sgdm"), "--fps", "60", "-o", str(tmp_path / "c.sgdm")]) == 0
    assert read_motion_arrays(tmp_path / "c.sgdm")[3]["start_frame"] == 20
