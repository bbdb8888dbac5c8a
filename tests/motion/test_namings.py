"""Every common humanoid naming loads from a BVH made here (tests/motion/namings.py), by name and -- renamed
j0 ... jN -- by the skeleton's shape; helper joints keep their rotations; six channels everywhere, zero
OFFSETs, a byte order mark, centimetres and inches; non-humanoids are refused with what is missing."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from segadeform.body.kinematics import forward_kinematics, poses_to_rotmats
from segadeform.body.retarget import min_rotation
from segadeform.body.skeleton import SMPL_JOINT_NAMES, SMPL_PARENTS, default_rest_joints
from segadeform.body.skeleton_map import REQUIRED_JOINTS, common_prefix, map_skeleton
from segadeform.errors import FileFormatError
from segadeform.motion import read_bvh
from segadeform.motion.bvh import read_bvh_skeleton

from .bvh_build import smooth_local_rotations, source_fk, write_skeleton_bvh
from .namings import NAMINGS, naming_motion, naming_skeleton, write_naming_bvh

SHARED_CMU = Path(__file__).resolve().parents[3] / "shared" / "data" / "mocap" / "cmu"
LIMBS = [
    ("left_hip", "left_knee"),
    ("left_knee", "left_ankle"),
    ("right_hip", "right_knee"),
    ("right_knee", "right_ankle"),
    ("left_shoulder", "left_elbow"),
    ("left_elbow", "left_wrist"),
    ("right_shoulder", "right_elbow"),
    ("right_elbow", "right_wrist"),
]
_I = {n: i for i, n in enumerate(SMPL_JOINT_NAMES)}


def _limbs_follow(m, names, parents, rest, loc, root, scale):
    """On the default body, every limb bone of the motion read points where the source's does, and the
    pelvis follows the source's root scaled by the leg fit."""
    _, P = source_fk(parents, rest, loc, root)
    target = default_rest_joints()
    _, posed = forward_kinematics(poses_to_rotmats(m.poses, 24), target, SMPL_PARENTS, m.trans)
    idx = {k: names.index(v) for k, v in m.meta["mapped"].items()}
    for a, b in LIMBS:
        d1 = posed[:, _I[b]] - posed[:, _I[a]]
        d2 = P[:, idx[b]] - P[:, idx[a]]
        cos = np.einsum("ti,ti->t", d1, d2) / np.linalg.norm(d1, axis=1) / np.linalg.norm(d2, axis=1)
        assert np.degrees(np.arccos(np.clip(cos, -1, 1))).max() < 1e-3, (a, b)
    np.testing.assert_allclose(posed[:, 0], P[:, idx["pelvis"]] * m.meta["scale"] * scale, atol=1e-6)


@pytest.mark.parametrize("kind", sorted(NAMINGS))
def test_naming_loads_by_name(tmp_path, kind):
    """Each naming (centimetres; Unity-style with six channels on every joint) maps as its tool means it,
    every joint found by name, and the limbs follow."""
    six = kind == "unity"
    f, names, parents, rest, expected, loc, root = write_naming_bvh(
        tmp_path / f"{kind}.bvh", kind, scale=100.0, six_channels=six
    )
    m = read_bvh(f, rest_joints=default_rest_joints())
    assert m.meta["scheme"] == NAMINGS[kind]
    assert {k: m.meta["mapped"].get(k) for k in expected} == expected
    assert set(m.meta["found_by"].values()) == {f"name ({NAMINGS[kind]})"}
    assert m.meta["units_guess"] == "cm"
    _limbs_follow(m, names, parents, rest, loc, root, 100.0)


def test_character_creator_is_a_hundred_joints_with_helpers():
    names, *_ = naming_skeleton("character-creator")
    assert len(names) >= 90 and sum("Twist" in n or "Share" in n for n in names) >= 20


@pytest.mark.parametrize("kind", sorted(NAMINGS))
def test_shape_fallback_maps_renamed_joints(tmp_path, kind):
    """The same skeletons with every joint renamed j0 ... jN: the shape rule finds every required joint where
    the names put it (the optional ones where they mean the same: a spine joint, the face's root, the
    middle finger), and the limbs follow."""
    names, parents, rest, expected, _ = naming_skeleton(kind)
    ren = [f"j{i}" for i in range(len(names))]
    f, names, parents, rest, expected, loc, root = write_naming_bvh(tmp_path / "j.bvh", kind, scale=100.0, rename=ren)
    m = read_bvh(f, rest_joints=default_rest_joints())
    assert m.meta["scheme"] == "shape"
    assert set(m.meta["found_by"].values()) == {"shape"}
    got = {k: names[int(v[1:])] for k, v in m.meta["mapped"].items()}
    for k in REQUIRED_JOINTS + ("left_collar", "right_collar", "left_foot", "right_foot", "neck"):
        if k in expected:
            assert got.get(k) == expected[k], (k, got.get(k), expected[k])
    for k in ("left_hand", "right_hand"):  # the middle finger, at its base or its metacarpal
        if k in expected:
            assert got[k] in (expected[k], names[parents[names.index(expected[k])]])
    anc = lambda j: {j} | (anc(parents[j]) if parents[j] >= 0 else set())  # noqa: E731
    if "head" in expected:  # the head or the face's root joint below it
        assert names.index(expected["head"]) in anc(names.index(got["head"]))
    mapped = {k: names.index(v) for k, v in got.items()}
    for k in ("spine1", "spine2"):  # some joint between the pelvis and the chest
        if k in expected:
            assert mapped["pelvis"] in anc(mapped[k]) and mapped[k] in anc(mapped["spine3"])
    _limbs_follow(m, ren, parents, rest, loc, root, 100.0)


@pytest.mark.parametrize("turn", [0.0, 180.0, 90.0])
def test_shape_fallback_left_right_from_the_rest_offsets(tmp_path, turn):
    """A renamed skeleton facing +Z, -Z or +X: left and right come from where the toes point, so the left leg
    is the leg on the body's left whatever the facing; an A-pose changes nothing."""
    names, parents, rest, expected, twist = naming_skeleton("unreal")
    a = np.deg2rad(30.0)
    for s, sg in (("l", 1), ("r", -1)):  # lower the arms 30 degrees: an A-pose
        top = names.index(f"upperarm_{s}")
        R = min_rotation(np.array([sg, 0.0, 0.0]), np.array([sg * np.cos(a), -np.sin(a), 0.0]))
        for j in range(len(names)):
            k = j
            while k >= 0 and k != top:
                k = parents[k]
            if k == top and j != top:
                rest[j] = rest[top] + R @ (rest[j] - rest[top])
    c, s_ = np.cos(np.deg2rad(turn)), np.sin(np.deg2rad(turn))
    Ry = np.array([[c, 0, s_], [0, 1, 0], [-s_, 0, c]])
    rest = rest @ Ry.T
    loc, root = naming_motion(parents, rest, names, twist, frames=5)
    ren = [f"j{i}" for i in range(len(names))]
    write_skeleton_bvh(tmp_path / "t.bvh", ren, parents, rest, loc, root)
    sk = read_bvh_skeleton(tmp_path / "t.bvh")
    mp = map_skeleton(sk.names, sk.parents, sk.rest, leaf_ends=sk.ends)
    got = {k: names[int(v[1:])] for k, v in mp.mapped().items()}
    for k in REQUIRED_JOINTS:
        assert got[k] == expected[k], (turn, k, got[k], expected[k])


def test_shape_fallback_on_real_cmu_files_renamed():
    """Every CMU capture in ../shared (MotionBuilder-style names) renamed j0 ... jN maps by shape onto the
    very joints its names map to, all 24."""
    files = sorted(SHARED_CMU.glob("*.bvh"))
    assert len(files) >= 20
    for f in files:
        sk = read_bvh_skeleton(f)
        by_name = map_skeleton(sk.names, sk.parents, sk.rest, leaf_ends=sk.ends)
        by_shape = map_skeleton([f"j{i}" for i in range(len(sk.names))], sk.parents, sk.rest, leaf_ends=sk.ends)
        assert by_shape.scheme == "shape" and by_name.scheme != "shape"
        assert by_shape.source.tolist() == by_name.source.tolist(), f.name


@pytest.mark.parametrize("kind", ["character-creator", "rigify"])
def test_helper_joints_keep_their_rotations(tmp_path, kind):
    """Twist, share, finger and face helpers turn in every frame (Rigify's .001 segments inside the limbs,
    about their bone).  On the file's own proportions the SMPL joints read back land where the source's
    mapped joints are, and turn as they do: a helper's rotation is carried by the joints below it, not lost
    (the wrist turns with the forearm's twist segment)."""
    f, names, parents, rest, expected, loc, root = write_naming_bvh(tmp_path / "h.bvh", kind, scale=100.0)
    m = read_bvh(f)  # no target body: the file's own skeleton, in metres
    assert m.meta["scale"] == pytest.approx(0.01)
    G, P = source_fk(parents, rest, loc, root)
    from segadeform.motion.bvh import _own_rest

    sk = read_bvh_skeleton(f)  # joints in the file's (depth-first) order
    mapped = m.meta["mapped"]
    J = (
        _own_rest(sk.rest, np.array([sk.names.index(mapped[n]) if n in mapped else -1 for n in SMPL_JOINT_NAMES]))
        * 0.01
    )
    src = np.array([names.index(mapped[n]) if n in mapped else -1 for n in SMPL_JOINT_NAMES])
    Gs, posed = forward_kinematics(poses_to_rotmats(m.poses, 24), J, SMPL_PARENTS, m.trans)
    sel = np.array([j for j in np.flatnonzero(src >= 0) if SMPL_JOINT_NAMES[j] not in ("left_collar", "right_collar")])
    assert np.abs(posed[:, sel] - P[:, src[sel]]).max() < 1e-6  # metres
    assert np.abs(Gs[:, sel, :3, :3] - G[:, src[sel]]).max() < 1e-5  # the collars keep only their swing
    if kind == "rigify":  # the twist segment really turns the hand: without it the wrist would be off
        i_tw, i_fa = names.index("DEF-forearm.L.001"), names.index("DEF-forearm.L")
        assert np.abs(loc[:, i_tw] - np.eye(3)).max() > 0.1
        no_twist = G[:, i_fa] @ loc[:, names.index("DEF-hand.L")]
        assert np.abs(Gs[:, _I["left_wrist"], :3, :3] - no_twist).max() > 0.1


def test_six_channels_with_zero_offsets_bom_and_inches(tmp_path):
    """A game export with six channels on every joint and every OFFSET zero (the bones only in the position
    channels), a UTF-8 byte order mark, in inches: the same motion as the plain file."""
    f, names, parents, rest, expected, loc, root = write_naming_bvh(
        tmp_path / "plain.bvh", "unity", scale=1 / 0.0254, six_channels=True
    )
    text = f.read_text()
    lines = [
        ("OFFSET 0.000000 0.000000 0.000000" if ln.strip().startswith("OFFSET") and k > 3 else ln)
        for k, ln in enumerate(text.splitlines())
    ]
    odd = tmp_path / "odd.bvh"
    odd.write_bytes(b"\xef\xbb\xbf" + ("\r\n".join(lines) + "\r\n").encode())
    a = read_bvh(f, rest_joints=default_rest_joints())
    b = read_bvh(odd, rest_joints=default_rest_joints())
    assert a.meta["units_guess"] == b.meta["units_guess"] == "inch"
    assert b.meta["mapped"] == a.meta["mapped"]
    np.testing.assert_allclose(b.poses, a.poses, atol=1e-6)
    np.testing.assert_allclose(b.trans, a.trans, atol=1e-6)


def test_common_prefix():
    assert common_prefix(["Character1_Hips", "Character1_Spine", "Character1_Head", "Reference"]) == "Character1_"
    assert common_prefix(["CC_Base_Hip", "CC_Base_L_Thigh", "CC_Base_R_Thigh", "RL_BoneRoot"]) == "CC_Base_"
    assert common_prefix(["pelvis", "spine_01", "spine_02", "thigh_l", "thigh_r", "calf_l"]) == ""


def _write_tree(tmp_path, name, names, parents, rest):
    loc = smooth_local_rotations(3, len(names), amplitude=0.0)
    root = np.tile(rest[0], (3, 1))
    return write_skeleton_bvh(tmp_path / name, names, np.array(parents), rest, loc, root)


def test_non_humanoids_are_refused_saying_what_is_missing(tmp_path):
    """Legs without arms, arms without legs, a snake: one error naming the file, the SMPL joints missing and
    what the shape rule did not find."""
    J = default_rest_joints()
    keep_legs = [0, 1, 2, 4, 5, 7, 8, 10, 11, 3, 6, 9, 12, 15]  # no arms
    names = [f"j{k}" for k in range(len(keep_legs))]
    parents = [keep_legs.index(SMPL_PARENTS[j]) if SMPL_PARENTS[j] >= 0 else -1 for j in keep_legs]
    f = _write_tree(tmp_path, "legs.bvh", names, parents, J[keep_legs])
    with pytest.raises(
        FileFormatError, match=r"legs\.bvh.*missing .*left_shoulder.*by shape: no arms.*found two legs hanging from j0"
    ):
        read_bvh(f)
    keep_arms = [0, 3, 6, 9, 12, 15, 13, 14, 16, 17, 18, 19, 20, 21, 22, 23]  # no legs
    names = [f"j{k}" for k in range(len(keep_arms))]
    parents = [keep_arms.index(SMPL_PARENTS[j]) if SMPL_PARENTS[j] >= 0 else -1 for j in keep_arms]
    f = _write_tree(tmp_path, "torso.bvh", names, parents, J[keep_arms])
    with pytest.raises(FileFormatError, match=r"torso\.bvh.*missing .*left_hip.*by shape: no two legs"):
        read_bvh(f)
    n = 12
    snake = np.stack([np.linspace(0, 2, n), np.full(n, 0.1), np.zeros(n)], axis=1)
    f = _write_tree(tmp_path, "snake.bvh", [f"s{k}" for k in range(n)], [-1] + list(range(n - 1)), snake)
    with pytest.raises(FileFormatError, match=r"snake\.bvh.*missing pelvis.*by shape"):
        read_bvh(f)


def test_motion_info_says_how_each_joint_was_found(tmp_path):
    from click.testing import CliRunner

    from segadeform.cli.main import cli

    names, *_ = naming_skeleton("unity")
    write_naming_bvh(tmp_path / "named.bvh", "unity", scale=100.0)
    write_naming_bvh(tmp_path / "j.bvh", "unity", scale=100.0, rename=[f"j{i}" for i in range(len(names))])
    named = CliRunner().invoke(cli, ["motion", "info", str(tmp_path / "named.bvh")])
    shape = CliRunner().invoke(cli, ["motion", "info", str(tmp_path / "j.bvh")])
    assert named.exit_code == 0 and shape.exit_code == 0, named.output + shape.output
    assert "  skeleton: unity names, up y, units look like cm" in named.output
    assert "  mapped by name (unity): pelvis=Hips, left_hip=UpperLeg_L," in named.output
    assert "  skeleton: read by its shape, up y" in shape.output
    line = next(ln for ln in shape.output.splitlines() if ln.startswith("  mapped by shape: "))
    assert "left_hip=j" in line and "left_wrist=j" in line and "mapped by name" not in shape.output
