"""BVH files from many skeletons retargeted onto SMPL: name schemes, extra joints, A-poses, layouts, units,
up axes, user joint maps, unmappable files; and the real CMU captures in ../shared."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from segadeform.body.kinematics import forward_kinematics, poses_to_rotmats
from segadeform.body.retarget import kabsch, min_rotation
from segadeform.body.skeleton import SMPL_JOINT_NAMES, SMPL_PARENTS, default_rest_joints
from segadeform.body.skeleton_map import map_skeleton, normalize_name
from segadeform.errors import FileFormatError
from segadeform.motion import load_motion, read_bvh
from segadeform.motion.bvh import read_bvh_skeleton

from .bvh_build import smooth_local_rotations, source_fk, write_skeleton_bvh

SHARED_CMU = Path(__file__).resolve().parents[3] / "shared" / "data" / "mocap" / "cmu"
REPO_CMU = Path(__file__).resolve().parents[2] / "samples" / "motions" / "cmu"
LIMB_BONES = [
    ("left_hip", "left_knee"),
    ("right_hip", "right_knee"),
    ("left_knee", "left_ankle"),
    ("right_knee", "right_ankle"),
    ("left_shoulder", "left_elbow"),
    ("right_shoulder", "right_elbow"),
    ("left_elbow", "left_wrist"),
    ("right_elbow", "right_wrist"),
]


# ---- building skeletons -----------------------------------------------------------------------------------
def _a_pose(J, degrees=45.0):
    """SMPL rest joints with both arms lowered by ``degrees`` about the shoulder (an A-pose)."""
    out = J.copy()
    a = np.deg2rad(degrees)
    for sh, chain, s in ((16, (18, 20, 22), 1), (17, (19, 21, 23), -1)):
        R = min_rotation(np.array([s, 0.0, 0.0]), np.array([s * np.cos(a), -np.sin(a), 0.0]))
        for k in chain:
            out[k] = J[sh] + R @ (J[k] - J[sh])
    return out


def _skeleton(kind):
    """(names, parents, rest, expected {smpl: source name}) of a test skeleton."""
    J = default_rest_joints()
    P = list(SMPL_PARENTS)
    if kind == "mixamo":  # Mixamo names, mixamorig: prefix, eyes, fingers, toe and head ends, A-pose
        from segadeform.body.skeleton_map import MIXAMO_TO_SMPL

        inv = {v: k for k, v in MIXAMO_TO_SMPL.items()}
        names = ["mixamorig:" + inv[n] for n in SMPL_JOINT_NAMES]
        rest = _a_pose(J)
        parents = P[:]
        for nm, par, off in (
            ("LeftEye", 15, [0.03, 0.05, 0.08]),
            ("RightEye", 15, [-0.03, 0.05, 0.08]),
            ("HeadTop_End", 15, [0, 0.15, 0]),
            ("LeftToe_End", 10, [0, 0, 0.05]),
            ("LeftHandIndex1", 20, [0.08, 0, 0.03]),
            ("LeftHandIndex2", 24 + 4, [0.03, 0, 0]),
            ("RightHandThumb1", 21, [-0.03, 0, 0.05]),
        ):
            names.append("mixamorig:" + nm)
            parents.append(par)
            rest = np.vstack([rest, rest[par] + np.array(off)])
        expected = {n: "mixamorig:" + inv[n] for n in SMPL_JOINT_NAMES}
        return names, parents, rest, expected
    if kind == "game":  # 22 joints: a floor root above the hips, Unity-like names, no collars' twist
        spec = [
            ("joint_Root", -1, [0, 0, 0]),
            ("Hips", 0, J[0]),
            ("UpperLeg_L", 1, J[1]),
            ("LowerLeg_L", 2, J[4]),
            ("Foot_L", 3, J[7]),
            ("Toes_L", 4, J[10]),
            ("UpperLeg_R", 1, J[2]),
            ("LowerLeg_R", 6, J[5]),
            ("Foot_R", 7, J[8]),
            ("Toes_R", 8, J[11]),
            ("Spine", 1, J[3]),
            ("Chest", 10, J[9]),
            ("Neck", 11, J[12]),
            ("Head", 12, J[15]),
            ("Shoulder_L", 11, J[13]),
            ("UpperArm_L", 14, J[16]),
            ("LowerArm_L", 15, J[18]),
            ("Hand_L", 16, J[20]),
            ("Shoulder_R", 11, J[14]),
            ("UpperArm_R", 18, J[17]),
            ("LowerArm_R", 19, J[19]),
            ("Hand_R", 20, J[21]),
        ]
        names = [s[0] for s in spec]
        parents = [s[1] for s in spec]
        rest = np.array([s[2] for s in spec], float)
        expected = {
            "pelvis": "Hips",
            "left_hip": "UpperLeg_L",
            "left_knee": "LowerLeg_L",
            "left_ankle": "Foot_L",
            "left_foot": "Toes_L",
            "right_hip": "UpperLeg_R",
            "spine1": "Spine",
            "spine3": "Chest",
            "neck": "Neck",
            "head": "Head",
            "left_collar": "Shoulder_L",
            "left_shoulder": "UpperArm_L",
            "left_elbow": "LowerArm_L",
            "left_wrist": "Hand_L",
            "right_wrist": "Hand_R",
        }
        return names, parents, rest, expected
    if kind == "biovision":  # 19 joints, Hips/Chest/LeftCollar naming, A-pose
        Ja = _a_pose(J, 30.0)
        spec = [
            ("Hips", -1, Ja[0]),
            ("LeftHip", 0, Ja[1]),
            ("LeftKnee", 1, Ja[4]),
            ("LeftAnkle", 2, Ja[7]),
            ("RightHip", 0, Ja[2]),
            ("RightKnee", 4, Ja[5]),
            ("RightAnkle", 5, Ja[8]),
            ("Chest", 0, Ja[3]),
            ("Chest2", 7, Ja[9]),
            ("LeftCollar", 8, Ja[13]),
            ("LeftShoulder", 9, Ja[16]),
            ("LeftElbow", 10, Ja[18]),
            ("LeftWrist", 11, Ja[20]),
            ("RightCollar", 8, Ja[14]),
            ("RightShoulder", 13, Ja[17]),
            ("RightElbow", 14, Ja[19]),
            ("RightWrist", 15, Ja[21]),
            ("Neck", 8, Ja[12]),
            ("Head", 17, Ja[15]),
        ]
        names = [s[0] for s in spec]
        parents = [s[1] for s in spec]
        rest = np.array([s[2] for s in spec], float)
        expected = {
            "pelvis": "Hips",
            "left_hip": "LeftHip",
            "left_knee": "LeftKnee",
            "left_ankle": "LeftAnkle",
            "spine3": "Chest2",
            "left_collar": "LeftCollar",
            "left_shoulder": "LeftShoulder",
            "left_elbow": "LeftElbow",
            "left_wrist": "LeftWrist",
            "neck": "Neck",
            "head": "Head",
        }
        return names, parents, rest, expected
    if kind == "nonames":  # meaningless names: only the hierarchy and the geometry say which is which
        names = [f"b{i:02d}" for i in range(24)]
        expected = {
            n: f"b{i:02d}"
            for i, n in enumerate(SMPL_JOINT_NAMES)
            if n not in ("left_hand", "right_hand", "spine2", "left_foot", "right_foot", "head", "neck")
        }
        return names, P[:], J.copy(), expected
    raise KeyError(kind)


def _check_file(tmp_path, kind, *, order="zxy", six=False, scale=1.0, up="y", seed=0):
    names, parents, rest, expected = _skeleton(kind)
    parents = np.array(parents)
    T = 40
    loc = smooth_local_rotations(T, len(names), seed=seed, amplitude=0.4)
    root = rest[np.flatnonzero(parents < 0)[0]] + np.stack(
        [np.linspace(0, 0.5, T), 0.02 * np.sin(np.arange(T)), np.zeros(T)], axis=1
    )
    G, Pos = source_fk(parents, rest, loc, root)
    if up == "z":  # the same motion in a z-up world: (x, y, z)_y-up -> (x, -z, y)_z-up
        Qz = np.array([[1.0, 0, 0], [0, 0, -1.0], [0, 1.0, 0]])
        rest_w, root_w = rest @ Qz.T, root @ Qz.T
        Gw = Qz @ G @ Qz.T
        loc_w = np.empty_like(loc)
        for j in range(len(names)):
            loc_w[:, j] = Gw[:, j] if parents[j] < 0 else np.swapaxes(Gw[:, parents[j]], -1, -2) @ Gw[:, j]
        f = write_skeleton_bvh(
            tmp_path / f"{kind}.bvh", names, parents, rest_w, loc_w, root_w, order=order, six_channels=six, scale=scale
        )
    else:
        f = write_skeleton_bvh(
            tmp_path / f"{kind}.bvh", names, parents, rest, loc, root, order=order, six_channels=six, scale=scale
        )
    target = default_rest_joints()
    m = read_bvh(f, rest_joints=target)
    mapped = m.meta["mapped"]
    for smpl, src in expected.items():
        assert mapped.get(smpl) == src, (kind, smpl, mapped.get(smpl), src)
    _, posed = forward_kinematics(poses_to_rotmats(m.poses, 24), target, SMPL_PARENTS, m.trans)
    idx = {n: names.index(v) for n, v in mapped.items()}
    # every limb bone points where the source's does
    for a, b in LIMB_BONES:
        d1 = posed[:, SMPL_JOINT_NAMES.index(b)] - posed[:, SMPL_JOINT_NAMES.index(a)]
        d2 = Pos[:, idx[b]] - Pos[:, idx[a]]
        cos = np.einsum("ti,ti->t", d1, d2) / np.linalg.norm(d1, axis=1) / np.linalg.norm(d2, axis=1)
        assert np.degrees(np.arccos(np.clip(cos, -1, 1))).max() < 1e-3, (kind, a, b)
    # the pelvis follows the source root, scaled to the target's legs
    np.testing.assert_allclose(posed[:, 0], Pos[:, idx["pelvis"]] * m.meta["scale"] * scale, atol=1e-6)
    return m


@pytest.mark.parametrize("kind", ["mixamo", "game", "biovision", "nonames"])
def test_skeletons_map_and_limbs_follow(tmp_path, kind):
    m = _check_file(tmp_path, kind, six=(kind == "game"))
    assert (
        m.meta["scheme"] == {"mixamo": "mixamo", "game": "unity", "biovision": "cmu-3dsmax", "nonames": "shape"}[kind]
    )
    assert np.isfinite(m.poses).all()


def test_mixamo_extras_are_ignored_and_reported(tmp_path):
    m = _check_file(tmp_path, "mixamo")
    assert {"mixamorig:LeftEye", "mixamorig:RightEye", "mixamorig:HeadTop_End"} <= set(m.meta["ignored"])
    assert m.meta["virtual"] == []


@pytest.mark.parametrize("order", ["xyz", "yxz", "zyx"])
def test_euler_orders_and_six_channels(tmp_path, order):
    _check_file(tmp_path, "biovision", order=order, six=True, seed=3)


@pytest.mark.parametrize("scale, unit", [(100.0, "cm"), (1 / 0.0254, "inch"), (1.0, "m"), (1000.0, "mm")])
def test_units_detected(tmp_path, scale, unit):
    m = _check_file(tmp_path, "game", scale=scale)
    assert m.meta["units_guess"] == unit
    # the leg fit makes the scale independent of the unit
    assert m.meta["scale"] * scale == pytest.approx(1.0, rel=1e-6)


def test_z_up_file(tmp_path):
    m = _check_file(tmp_path, "game", up="z")
    assert m.meta["up"] == "z"


def test_given_units_are_used_as_is(tmp_path):
    names, parents, rest, _ = _skeleton("game")
    T = 5
    loc = smooth_local_rotations(T, len(names), amplitude=0.0)
    root = np.tile(rest[0], (T, 1))
    f = write_skeleton_bvh(tmp_path / "g.bvh", names, np.array(parents), rest, loc, root, scale=100.0)
    m = read_bvh(f, rest_joints=default_rest_joints() * 1.2, units="cm")
    assert m.meta["scale"] == pytest.approx(0.01)
    m2 = read_bvh(f, rest_joints=default_rest_joints() * 1.2)
    assert m2.meta["scale"] == pytest.approx(0.012)


def test_given_units_no_adult_has_are_said(tmp_path, caplog):
    """A user's trial: a CMU clip read with --units m put the body 16 m up, with no word about the units."""
    names, parents, rest, _ = _skeleton("game")
    T = 3
    loc = smooth_local_rotations(T, len(names), amplitude=0.0)
    f = write_skeleton_bvh(
        tmp_path / "g.bvh", names, np.array(parents), rest, loc, np.tile(rest[0], (T, 1)), scale=100.0
    )
    with caplog.at_level("WARNING", logger="segadeform.motion.bvh"):
        read_bvh(f, rest_joints=default_rest_joints(), units="cm")
    assert not caplog.records  # right units: nothing said
    for wrong in ("m", "mm"):
        caplog.clear()
        with caplog.at_level("WARNING", logger="segadeform.motion.bvh"):
            read_bvh(f, rest_joints=default_rest_joints(), units=wrong)
        assert len(caplog.records) == 1, wrong
        msg = caplog.records[0].getMessage()
        assert f"g.bvh: units {wrong} make the legs" in msg and "look like units cm" in msg, msg


def test_joint_map_file(tmp_path):
    """Names the rule cannot read, swapped sides: a user map fixes them (either direction of entry)."""
    names, parents, rest, _ = _skeleton("nonames")
    T = 8
    loc = smooth_local_rotations(T, 24, seed=1)
    root = np.tile(rest[0], (T, 1))
    f = write_skeleton_bvh(tmp_path / "n.bvh", names, np.array(parents), rest, loc, root)
    jm = tmp_path / "map.toml"
    jm.write_text('[joints]\nleft_hand = "b22"\nb23 = "right_hand"\nneck = "b12"\nhead = "b15"\n')
    m = read_bvh(f, rest_joints=default_rest_joints(), joint_map=jm)
    assert m.meta["mapped"]["left_hand"] == "b22" and m.meta["mapped"]["right_hand"] == "b23"
    assert m.meta["scheme"] == "shape+joint-map"
    jm.write_text('[joints]\nleft_hand = "nope"\n')
    with pytest.raises(FileFormatError, match="'nope', which is not in the file"):
        read_bvh(f, joint_map=jm)
    jm.write_text('[joints]\nb1 = "b2"\n')
    with pytest.raises(FileFormatError, match="names no SMPL joint"):
        read_bvh(f, joint_map=jm)


def test_unmappable_file_lists_what_was_found(tmp_path):
    """A four-legged chain (no arms): the error names the joints found and the SMPL joints missing."""
    names = ["root", "spine_a", "spine_b", "tail", "leg_fl", "leg_fr", "leg_bl", "leg_br"]
    parents = [-1, 0, 1, 0, 2, 2, 0, 0]
    rest = np.array(
        [[0, 1, 0], [0, 1, 0.4], [0, 1, 0.8], [0, 1, -0.5], [0.2, 0, 0.8], [-0.2, 0, 0.8], [0.2, 0, 0], [-0.2, 0, 0]],
        float,
    )
    loc = smooth_local_rotations(3, len(names), amplitude=0.0)
    f = write_skeleton_bvh(tmp_path / "dog.bvh", names, np.array(parents), rest, loc, np.tile(rest[0], (3, 1)))
    with pytest.raises(FileFormatError) as ei:
        read_bvh(f)
    msg = str(ei.value)
    assert "dog.bvh" in msg and "missing" in msg and "left_shoulder" in msg and "8 joints (root, spine_a" in msg
    assert "--joint-map" in msg


def test_generic_rule_reads_unknown_names(tmp_path):
    """The old reader refused an SMPL file with one renamed joint; the generic rule reads it."""
    from segadeform.motion import make_motion, write_bvh

    J = default_rest_joints()
    mo = make_motion("dance", seconds=0.5, seed=1)
    write_bvh(tmp_path / "a.bvh", mo, J)
    txt = (tmp_path / "a.bvh").read_text().replace("JOINT left_knee", "JOINT LKneeThing")
    (tmp_path / "b.bvh").write_text(txt)
    m = read_bvh(tmp_path / "b.bvh", rest_joints=J)
    assert m.meta["mapped"]["left_knee"] == "LKneeThing"
    np.testing.assert_allclose(poses_to_rotmats(m.poses, 24), poses_to_rotmats(mo.poses, 24), atol=1e-6)


def test_normalize_and_kabsch_min_rotation():
    assert normalize_name("mixamorig1:LeftUpLeg") == "leftupleg" == normalize_name("Left_Up-Leg")
    rng = np.random.default_rng(0)
    a, b = rng.normal(size=(50, 3)), rng.normal(size=(50, 3))
    R = min_rotation(a, b)
    np.testing.assert_allclose(
        np.einsum("nij,nj->ni", R, a / np.linalg.norm(a, axis=1, keepdims=True)),
        b / np.linalg.norm(b, axis=1, keepdims=True),
        atol=1e-12,
    )
    np.testing.assert_allclose(np.linalg.det(R), 1.0, atol=1e-12)
    opp = min_rotation(np.array([1.0, 0, 0]), np.array([-2.0, 0, 0]))
    np.testing.assert_allclose(opp @ [1.0, 0, 0], [-1.0, 0, 0], atol=1e-12)
    Rt = min_rotation(np.array([0.3, 1, 0.2]), np.array([-0.5, 0.1, 1.0]))
    u = rng.normal(size=(6, 3))
    np.testing.assert_allclose(kabsch(u, u @ Rt.T), Rt, atol=1e-10)


def test_mapping_refuses_out_of_order_limbs():
    names = [n for n in SMPL_JOINT_NAMES]
    rest = default_rest_joints()
    with pytest.raises(Exception, match="does not descend"):
        map_skeleton(names, SMPL_PARENTS, rest, joint_map={"left_knee": "left_ankle", "left_ankle": "left_knee"})


# ---- the real CMU captures --------------------------------------------------------------------------------
CMU_FILES = sorted(SHARED_CMU.glob("*.bvh"))


@pytest.fixture(scope="module")
def default_joints():
    from segadeform.body import default_body_path, load_body

    return load_body(default_body_path()).rest_joints()[0]


def test_shared_cmu_data_present():
    assert len(CMU_FILES) >= 20, f"expected the CMU captures in {SHARED_CMU}"


@pytest.mark.parametrize("path", CMU_FILES, ids=[p.stem for p in CMU_FILES])
def test_real_cmu_file(path, default_joints):
    """Every CMU capture loads.  On the file's own proportions the mapped joints follow its forward
    kinematics (mean < 1 cm, max < 4 cm: folded helper joints like a rotating LHipJoint cost a few
    mm-cm); on the default body every limb bone points where the file's does; with ``floor`` the
    feet touch the floor."""
    own = read_bvh(path)
    sk = read_bvh_skeleton(path)
    from segadeform.motion.bvh import _own_rest

    src = np.full(24, -1)
    for k, v in own.meta["mapped"].items():
        src[SMPL_JOINT_NAMES.index(k)] = sk.names.index(v)
    Jo = _own_rest(sk.rest, src) * own.meta["scale"]
    _, posed = forward_kinematics(poses_to_rotmats(own.poses, 24), Jo, SMPL_PARENTS, own.trans)
    sel = np.flatnonzero(src >= 0)
    err = np.linalg.norm(posed[:, sel] - sk.positions[:, src[sel]] * own.meta["scale"], axis=-1)
    assert err.mean() < 0.01 and err.max() < 0.04, (err.mean(), err.max())
    m = load_motion(path, rest_joints=default_joints, floor=True)
    _, posed = forward_kinematics(poses_to_rotmats(m.poses, 24), default_joints, SMPL_PARENTS, m.trans)
    for a, b in LIMB_BONES:
        ia, ib = SMPL_JOINT_NAMES.index(a), SMPL_JOINT_NAMES.index(b)
        d1 = posed[:, ib] - posed[:, ia]
        d2 = sk.positions[:, src[ib]] - sk.positions[:, src[ia]]
        cos = np.einsum("ti,ti->t", d1, d2) / np.linalg.norm(d1, axis=1) / np.linalg.norm(d2, axis=1)
        assert np.degrees(np.arccos(np.clip(cos, -1, 1))).max() < 0.01
    feet = posed[:, [7, 8, 10, 11], 1]
    assert feet.min() == pytest.approx(default_joints[[7, 8, 10, 11], 1].min(), abs=1e-6)
    assert np.isfinite(m.poses).all() and m.fps == pytest.approx(120.0, rel=1e-3)


def test_bad_motion_data_names_its_line(tmp_path):
    """A user's trial: a NaN row and a cut-short file named the BVH but not where."""
    names, parents, rest, _ = _skeleton("game")
    T = 4
    loc = smooth_local_rotations(T, len(names), amplitude=0.0)
    f = write_skeleton_bvh(tmp_path / "g.bvh", names, np.array(parents), rest, loc, np.tile(rest[0], (T, 1)))
    lines = f.read_text().splitlines()
    first = next(i for i, s in enumerate(lines) if s.startswith("Frame Time")) + 1  # 0-based index of frame 0's row
    frame2 = lines[first + 2].split()
    frame2[4] = "nan"
    bad = lines[: first + 2] + [" ".join(frame2)] + lines[first + 3 :]
    (tmp_path / "n.bvh").write_text("\n".join(bad) + "\n")
    with pytest.raises(FileFormatError, match=r"NaN or inf \(got nan \(frame 2\)\)") as e:
        read_bvh(tmp_path / "n.bvh")
    assert e.value.line == first + 3  # 1-based
    frame2[4] = "1e308"  # overflowed into inf later: named without a line, after numpy's warnings (a user's trial)
    (tmp_path / "h.bvh").write_text("\n".join(lines[: first + 2] + [" ".join(frame2)] + lines[first + 3 :]) + "\n")
    with pytest.raises(FileFormatError, match=r"a value no capture holds.*got 1e308 \(frame 2\)") as e:
        read_bvh(tmp_path / "h.bvh")
    assert e.value.line == first + 3
    (tmp_path / "t.bvh").write_text("\n".join(lines[:-1]) + "\n")  # the last frame cut off
    frames_line = next(i for i, s in enumerate(lines) if s.startswith("Frames:")) + 1
    with pytest.raises(FileFormatError, match=r"got \d+ numbers, 3 frames \(cut short\?\)") as e:
        read_bvh(tmp_path / "t.bvh")
    assert e.value.line == frames_line


@pytest.mark.parametrize("degrees", [90.0, 180.0, -35.0])
def test_a_skeleton_that_faces_another_way_at_rest_gets_the_same_joint_rotations(degrees):
    """A CMU walk with its rest and motion turned rigidly about +Y (a character that faces +X, -Z ... in its file):
    every joint's rotation against its parent is the original's, the root and its travel turn with the file.  The
    retargeting matches bone directions, which leaves a vertical bone's turn about itself free: without turning the
    source to face +Z first (motion.bvh.facing_turn) the spine and knees took the file's turn as a twist of their
    own (90 degrees at 90: an FBX review)."""
    import dataclasses

    from segadeform.body.rotations import axis_angle_to_matrix
    from segadeform.motion.bvh import facing_turn, skeleton_motion

    path = REPO_CMU / "02_01_walk.bvh"
    sk = read_bvh_skeleton(path)
    m = map_skeleton(sk.names, sk.parents, sk.rest, leaf_ends=sk.ends)
    assert facing_turn(sk.rest, m.source) is None  # CMU's skeletons face +Z: read as before
    R = axis_angle_to_matrix(np.array([0.0, np.radians(degrees), 0.0]))
    turned = dataclasses.replace(
        sk, rest=sk.rest @ R.T, ends=sk.ends @ R.T, rotations=R @ sk.rotations @ R.T, positions=sk.positions @ R.T
    )
    J = default_rest_joints()
    a, b = skeleton_motion(sk, path, rest_joints=J), skeleton_motion(turned, path, rest_joints=J)
    ra = axis_angle_to_matrix(a.poses.reshape(-1, 24, 3))
    rb = axis_angle_to_matrix(b.poses.reshape(-1, 24, 3))
    np.testing.assert_allclose(rb[:, 1:], ra[:, 1:], atol=1e-6)
    np.testing.assert_allclose(rb[:, 0], R @ ra[:, 0], atol=1e-6)
    np.testing.assert_allclose(J[0] + b.trans, (J[0] + a.trans) @ R.T, atol=1e-6)


def test_joints_nested_thousands_deep_are_one_line(tmp_path):
    """A fuzzer's trial: a chain of 2,000 joints gave a RecursionError traceback from `run`, `inspect` and `motion
    info`; past MAX_DEPTH levels the file is refused at the joint's line."""
    from segadeform.motion.bvh import MAX_DEPTH, read_bvh_skeleton

    def chain(n: int) -> str:
        six = "CHANNELS 6 Xposition Yposition Zposition Zrotation Xrotation Yrotation\n"
        head = "HIERARCHY\nROOT Hips\n{\nOFFSET 0 0 0\n" + six
        body = "".join(f"JOINT j{k}\n{{\nOFFSET 0 1 0\nCHANNELS 3 Zrotation Xrotation Yrotation\n" for k in range(n))
        tail = "End Site\n{\nOFFSET 0 1 0\n}\n" + "}\n" * (n + 1)
        row = " ".join(["0"] * (6 + 3 * n))
        return head + body + tail + f"MOTION\nFrames: 2\nFrame Time: 0.0333333\n{row}\n{row}\n"

    (tmp_path / "ok.bvh").write_text(chain(MAX_DEPTH - 1))  # the root and MAX_DEPTH - 1 joints below it
    assert len(read_bvh_skeleton(tmp_path / "ok.bvh").names) == MAX_DEPTH
    (tmp_path / "one.bvh").write_text(chain(MAX_DEPTH))
    with pytest.raises(FileFormatError, match="joints nest too deeply"):
        read_bvh_skeleton(tmp_path / "one.bvh")
    (tmp_path / "deep.bvh").write_text(chain(2000))
    with pytest.raises(FileFormatError, match=r"deep\.bvh:\d+: joints nest too deeply \(expected at most 256 levels"):
        read_bvh_skeleton(tmp_path / "deep.bvh")
