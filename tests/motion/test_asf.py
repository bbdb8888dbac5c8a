"""CMU's ASF/AMC motion capture: parsing, the axis and Euler conventions, forward kinematics against a slow
reference, the mapping onto SMPL through the BVH path, load_motion / scenes / dataset configs / the CLI, bad
input; and on the real data in ../shared: the metre factor against the subjects' height, the cross-check with
cgspeed's BVH conversions of the same trials, and every trial of ../shared/data/mocap/cmu_asf_amc."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from segadeform.body.kinematics import forward_kinematics, poses_to_rotmats
from segadeform.body.skeleton import SMPL_JOINT_NAMES, SMPL_PARENTS, default_rest_joints
from segadeform.errors import FileFormatError
from segadeform.motion import asf, load_motion
from segadeform.motion.bvh import _own_rest

from .asf_build import amc_text, asf_text, cmu_bones, smooth_values, write_trial

SHARED = Path(__file__).resolve().parents[3] / "shared" / "data" / "mocap"
CMU_AMC = SHARED / "cmu_asf_amc"
CMU_BVH = SHARED / "cmu"
needs_shared = pytest.mark.skipif(not CMU_AMC.is_dir(), reason=f"the CMU ASF/AMC trials are not in {CMU_AMC}")


@pytest.fixture
def trial(tmp_path):
    """(asf path, amc path) of a 40-frame CMU-like trial."""
    return write_trial(tmp_path / "01")


# ---- parsing and conventions -------------------------------------------------------------------------------
def test_read_asf(trial):
    s = asf.read_asf(trial[0])
    assert s.names[:6] == ("root", "lhipjoint", "lfemur", "ltibia", "lfoot", "ltoes")  # depth first
    assert len(s.names) == 31 and all(s.parents[i] < i for i in range(1, 31))
    assert s.names[s.parents[s.names.index("lclavicle")]] == "thorax"
    assert s.dofs[0] == ("tx", "ty", "tz", "rx", "ry", "rz") and s.dofs[s.names.index("lfoot")] == ("rx", "rz")
    assert s.limits[s.names.index("lfoot")] == ((-170.0, 170.0), (-170.0, 170.0))
    assert s.lengths[s.names.index("lfemur")] == pytest.approx(7.1)
    np.testing.assert_allclose(np.linalg.norm(s.directions[1:], axis=1), 1.0)
    assert s.length_unit == 0.45 and s.angle == "deg"
    # a length L in the file is L / 0.45 inches
    assert s.metres == asf.metres_per_unit(0.45) == pytest.approx(0.0254 / 0.45)


def test_metre_factor_comes_from_the_file(tmp_path):
    """The motion on its own proportions is in metres by the ASF's ``:units length``: thigh length and root
    travel scale with it (a file saying ``length 1`` is in inches)."""
    for unit in (0.45, 1.0):
        a, m = write_trial(tmp_path / str(unit), asf=asf_text(length_unit=unit))
        mo = asf.read_amc(m)
        assert mo.meta["scale"] == pytest.approx(0.0254 / unit) and mo.meta["metres_per_unit"] == mo.meta["scale"]
        sk = asf.amc_skeleton(m)
        thigh = np.linalg.norm(sk.rest[sk.names.index("ltibia")] - sk.rest[sk.names.index("lfemur")]) * mo.meta["scale"]
        assert thigh == pytest.approx(7.1 * 0.0254 / unit)
        travel = mo.trans[-1, 2] - mo.trans[0, 2]
        assert travel == pytest.approx(8.0 * 0.0254 / unit, rel=1e-6)  # the root's AMC translation, same unit


def _tiny(tmp_path, bones, values):
    """An ASF of a root and ``bones`` and a one-frame AMC: the bones' start and end positions."""
    a = tmp_path / "t.asf"
    a.write_text(asf_text(bones, limits=False))
    m = tmp_path / "t.amc"
    m.write_text(amc_text(values))
    s = asf.read_asf(a)
    _, start, end = asf.asf_forward_kinematics(s, asf.read_amc_values(m, s))
    return s, start[0], end[0]


def test_euler_order_and_axis_by_hand(tmp_path):
    """``dof rx ry`` applies rx first (M = Ry Rx); ``axis 0 0 90 XYZ`` turns the bone's x axis onto world y."""
    bones = [("a", "root", (0, 1, 0), 2.0, (0, 0, 0), ("rx", "ry")), ("b", "root", (1, 0, 0), 3.0, (0, 0, 90), ("rx",))]
    values = {"root": np.zeros((1, 6)), "a": np.array([[90.0, 90.0]]), "b": np.array([[90.0]])}
    s, start, end = _tiny(tmp_path, bones, values)
    ia, ib = s.names.index("a"), s.names.index("b")
    np.testing.assert_allclose(end[ia], [2.0, 0, 0], atol=1e-12)  # Rx(90) y -> z, then Ry(90) z -> x
    np.testing.assert_allclose(end[ib], [0, 0, -3.0], atol=1e-12)  # 90 deg about world y: x -> -z
    # a child starts where its parent ends, and turns with it
    bones.append(("c", "a", (0, 0, 1), 1.0, (0, 0, 0), ()))
    s, start, end = _tiny(tmp_path, bones, values)
    ic = s.names.index("c")
    np.testing.assert_allclose(start[ic], end[s.names.index("a")], atol=1e-12)
    np.testing.assert_allclose(end[ic], [2.0, -1.0, 0], atol=1e-12)  # Ry(90) Rx(90) (0, 0, 1) = (0, -1, 0)


def test_root_order_orientation_position(tmp_path):
    """The root's AMC values come in its ``order``; ``orientation``/``axis`` set C_root, ``position`` offsets it."""
    bones = [("a", "root", (0, 1, 0), 1.0, (0, 0, 0), ())]
    a = tmp_path / "r.asf"
    a.write_text(asf_text(bones, root_order="RY TZ TX TY", position=(1, 2, 3), orientation=(0, 0, 0), limits=False))
    m = tmp_path / "r.amc"
    m.write_text(amc_text({"root": np.array([[90.0, 5.0, 0.5, 0.0]])}))
    s = asf.read_asf(a)
    _, start, end = asf.asf_forward_kinematics(s, asf.read_amc_values(m, s))
    np.testing.assert_allclose(start[0, 0], [1.5, 2.0, 8.0])
    a.write_text(
        asf_text([("a", "root", (1, 0, 0), 1.0, (0, 0, 0), ())], root_order="RX", orientation=(0, 0, 90), limits=False)
    )
    m.write_text(amc_text({"root": np.array([[90.0]])}))
    s = asf.read_asf(a)
    _, start, end = asf.asf_forward_kinematics(s, asf.read_amc_values(m, s))
    # C = Rz(90): the root's x axis is world y, so rx = 90 turns about world y: (1, 0, 0) -> (0, 0, -1)
    np.testing.assert_allclose(end[0, 1], [0, 0, -1.0], atol=1e-12)


def test_fast_forward_kinematics_matches_the_reference(tmp_path):
    """Random axes in every rotation order, a turned and offset root, radians: the vectorised forward kinematics
    equals the slow 4x4 bone-frame reference."""
    rng = np.random.default_rng(5)
    bones = [(n, p, d, ln, tuple(rng.uniform(-180, 180, 3)), dofs) for n, p, d, ln, _, dofs in cmu_bones()]
    text = asf_text(bones, angle="rad", root_axis="ZXY", position=(0.3, -0.2, 0.5), orientation=(10, -20, 30))
    orders = iter(["".join(rng.permutation(list("XYZ"))) for _ in bones])
    text = "\n".join(ln.replace("  XYZ", "  " + next(orders)) if "  XYZ" in ln else ln for ln in text.splitlines())
    a = tmp_path / "x.asf"
    a.write_text(text)
    values = {
        k: np.deg2rad(v) if k != "root" else np.c_[v[:, :3], np.deg2rad(v[:, 3:])]
        for k, v in smooth_values(n_frames=12, seed=2, amplitude=90).items()
    }
    m = tmp_path / "x.amc"
    m.write_text(amc_text(values, header=(":FULLY-SPECIFIED", ":RADIANS")))
    s = asf.read_asf(a)
    amc = asf.read_amc_values(m, s)
    assert amc.angle == "rad"
    G, start, end = asf.asf_forward_kinematics(s, amc)
    ref_start, ref_end = asf._fk_reference(s, amc)
    np.testing.assert_allclose(start, ref_start, atol=1e-9)
    np.testing.assert_allclose(end, ref_end, atol=1e-9)
    # and the rotations are the bones' own: each bone's end is its start plus G (direction x length)
    np.testing.assert_allclose(end - start, np.einsum("tjab,jb->tja", G, s.directions * s.lengths[:, None]), atol=1e-9)


def test_not_fully_specified_amc_keeps_values(tmp_path, trial):
    """Without :FULLY-SPECIFIED a bone left out of a frame keeps its previous values (zero before its first)."""
    v = smooth_values(n_frames=4)
    full = amc_text(v)
    lines = full.splitlines()
    drop = {i for i, ln in enumerate(lines) if ln.startswith("lfemur ") and i > lines.index("3")}  # frames 3, 4
    drop |= {i for i, ln in enumerate(lines) if ln.startswith("head ") and i < lines.index("2")}  # frame 1
    text = "\n".join(ln for i, ln in enumerate(lines) if i not in drop and ln != ":FULLY-SPECIFIED")
    p = trial[1].with_name("01_02.amc")
    p.write_text(text)
    s = asf.read_asf(trial[0])
    amc = asf.read_amc_values(p, s)
    assert not amc.fully_specified and amc.n_frames == 4
    np.testing.assert_allclose(amc.values["lfemur"][2:], np.repeat(np.round(v["lfemur"][1:2], 6), 2, axis=0))
    np.testing.assert_allclose(amc.values["head"][0], 0.0)
    np.testing.assert_allclose(amc.values["head"][1:], np.round(v["head"][1:], 6))
    with pytest.raises(FileFormatError, match=r"01_03.amc:4: frame 1 lacks bone 'head'"):  # fully specified
        p.with_name("01_03.amc").write_text(text.replace(":DEGREES", ":FULLY-SPECIFIED\n:DEGREES"))
        asf.read_amc_values(p.with_name("01_03.amc"), s)


# ---- onto SMPL ---------------------------------------------------------------------------------------------
def test_own_proportions_follow_the_skeleton(trial):
    """On the capture's own proportions the mapped SMPL joints follow the ASF's forward kinematics (< 1 mm; the
    head < 1 cm: the folded upperneck bends the neck, which changes the lowerneck-to-head distance a rigid SMPL
    neck keeps; 8 mm at this test's 25-degree neck swings, 0.8 mm over CMU's 16_15): folded bones lose nothing
    else, and the chest, whose three children (neck, clavicles) start at one point, gets no arbitrary turn."""
    mo = asf.read_amc(trial[1])
    sk = asf.amc_skeleton(trial[1])
    assert mo.meta["format"] == "amc" and mo.meta["scheme"] == "cmu-asf" and mo.fps == 120.0
    assert mo.meta["mapped"]["left_wrist"] == "lhand" and mo.meta["mapped"]["left_elbow"] == "lradius"
    assert {"lwrist", "rwrist", "lhipjoint", "upperneck"} <= set(mo.meta["ignored"])
    src = np.array([sk.names.index(mo.meta["mapped"][n]) if n in mo.meta["mapped"] else -1 for n in SMPL_JOINT_NAMES])
    Jo = _own_rest(sk.rest, src) * mo.meta["scale"]
    _, posed = forward_kinematics(poses_to_rotmats(mo.poses, 24), Jo, SMPL_PARENTS, mo.trans)
    sel = np.flatnonzero(src >= 0)
    err = np.linalg.norm(posed[:, sel] - sk.positions[:, src[sel]] * mo.meta["scale"], axis=-1)
    head = list(sel).index(SMPL_JOINT_NAMES.index("head"))
    assert np.delete(err, head, axis=1).max() < 1e-3 and err[:, head].max() < 0.01, err.max(axis=0)


def test_load_motion_reads_amc_as_bvh(trial, tmp_path):
    J = default_rest_joints()
    m = load_motion(trial[1], rest_joints=J, floor=True)  # as the dataset maker calls it
    assert m.n_frames == 40 and m.fps == 120.0 and m.name == "01_01" and m.meta["skeleton"] == str(trial[0])
    _, posed = forward_kinematics(poses_to_rotmats(m.poses, 24), J, SMPL_PARENTS, m.trans)
    assert posed[:, [7, 8, 10, 11], 1].min() == pytest.approx(J[[7, 8, 10, 11], 1].min(), abs=1e-9)
    # the skeleton elsewhere, named
    other = tmp_path / "elsewhere"
    other.mkdir()
    (other / "subject.asf").write_bytes(trial[0].read_bytes())
    lone = tmp_path / "lone" / "01_01.amc"
    lone.parent.mkdir()
    lone.write_bytes(trial[1].read_bytes())
    with pytest.raises(FileFormatError, match="cannot tell which skeleton.*no .asf there"):
        load_motion(lone)
    m2 = load_motion(lone, rest_joints=J, floor=True, skeleton=other / "subject.asf")
    np.testing.assert_allclose(m2.poses, m.poses)
    with pytest.raises(FileFormatError, match="units apply to BVH files only"):
        load_motion(trial[1], units="cm")
    with pytest.raises(FileFormatError, match="applies to AMC motions only"):
        load_motion(tmp_path / "x.bvh", skeleton=trial[0])
    # several .asf beside it: SUBJECT.asf for SUBJECT_TRIAL.amc, else an error listing them
    (trial[0].parent / "02.asf").write_bytes(trial[0].read_bytes())
    assert asf.find_asf(trial[1]) == trial[0]
    trial[0].rename(trial[0].with_name("03.asf"))
    with pytest.raises(FileFormatError, match="cannot tell which skeleton.*02.asf, 03.asf"):
        load_motion(trial[1])
    # a missing AMC is a missing file, not a missing skeleton (a user's trial), with or without an .asf beside it
    for folder in (trial[1].parent, tmp_path / "empty"):
        folder.mkdir(exist_ok=True)
        with pytest.raises(FileFormatError, match="nope.amc: no such file"):
            load_motion(folder / "nope.amc")


def test_scene_and_dataset_config_take_amc(trial, tmp_path):
    from segadeform.dataset.config import load_dataset_config
    from segadeform.dataset.make import _motion
    from segadeform.motion import build_motion
    from segadeform.settings import load_scene

    skel = tmp_path / "skeletons" / "s.asf"
    skel.parent.mkdir()
    trial[0].rename(skel)
    scene = tmp_path / "scene.toml"
    scene.write_text(
        f'[garment]\nmesh = "g.obj"\n[motion]\nfile = "{trial[1]}"\nskeleton = "skeletons/s.asf"\n'
        f'fps = 30\n[output]\npath = "o.pc2"\n'
    )
    sc = load_scene(scene)
    assert sc.motion.skeleton == skel
    m = build_motion(sc.motion, default_rest_joints())
    assert m.fps == 30.0 and m.n_frames == 10  # 40 frames at 120 fps, resampled
    skel.rename(trial[0])  # datasets find the .asf beside the .amc
    cfg_path = tmp_path / "ds.toml"
    cfg_path.write_text(
        '[dataset]\nfps = 30.0\nseconds = 0.2\n[[garments]]\nkind = "skirt"\nsplit = "train"\n'
        f'[[motions]]\nfile = "{trial[1]}"\nsplit = "train"\n'
    )
    cfg = load_dataset_config(cfg_path)
    clip = _motion(cfg.motions[0], cfg, default_rest_joints())
    # no capture before the clip for a lead: it starts RAMP_MIN_SECONDS in (at most 2 frames before the end)
    from segadeform.dataset.make import RAMP_MIN_SECONDS

    a = max(1, min(round(RAMP_MIN_SECONDS * 30), 10 - 2))
    assert clip.n_frames == min(10 - a, 6) and clip.meta["format"] == "amc"


# ---- bad input ---------------------------------------------------------------------------------------------
def _edit_amc(text, old, new, count=1):
    assert old in text, old
    return text.replace(old, new, count)


def _first_value(text, bone, value):
    """``text`` with the first value of ``bone``'s first line replaced by ``value``."""
    lines = text.splitlines()
    i = next(k for k, ln in enumerate(lines) if ln.startswith(bone + " "))
    parts = lines[i].split()
    lines[i] = " ".join([bone, value] + parts[2:])
    return "\n".join(lines) + "\n"


BAD_AMC = [  # (name, edit of the AMC text, message fragment: FILE:LINE: problem)
    (
        "bone_not_in_asf",
        lambda t: _edit_amc(t, "\nlhumerus", "\ntail 1 2 3\nlhumerus"),
        ":22: bone 'tail' is not in the skeleton",
    ),
    (
        "wrong_value_count",
        lambda t: _edit_amc(t, "\nltibia ", "\nltibia 5 "),
        "wrong number of values for bone 'ltibia' (expected 1 (dof rx in",
    ),
    (
        "frames_not_consecutive",
        lambda t: _edit_amc(t, "\n3\n", "\n4\n"),
        "frame numbers are not consecutive (expected frame 3, got frame 4)",
    ),
    ("nan", lambda t: _first_value(t, "lfemur", "nan"), ":6: bone 'lfemur' has a value that is not finite"),
    ("inf", lambda t: _first_value(t, "ltibia", "-inf"), ":8: bone 'ltibia' has a value that is not finite"),
    ("not_a_number", lambda t: _first_value(t, "lfemur", "x1"), ":6: bone 'lfemur' has a value that is not a number"),
    # past the BVH reader's bound: 1e20 played (a new user's trial), 1e300 overflowed and blamed the bone lengths
    ("huge", lambda t: _first_value(t, "lfemur", "1e20"), ":6: bone 'lfemur' has a value no capture holds (expected"),
    ("overflow", lambda t: _first_value(t, "ltibia", "1e300"), ":8: bone 'ltibia' has a value no capture holds"),
    ("empty", lambda t: "", "AMC has no frames (expected frame numbers followed by bone values, got an empty file)"),
    ("only_header", lambda t: "#!OML:ASF x\n:FULLY-SPECIFIED\n:DEGREES\n", "no frame numbers"),
    ("unknown_keyword", lambda t: _edit_amc(t, ":DEGREES", ":GRADIANS"), ":3: unknown AMC keyword ':GRADIANS'"),
    ("bone_twice", lambda t: _edit_amc(t, "\nltibia ", "\nltibia 1\nltibia "), "bone 'ltibia' given twice in frame 1"),
    (
        "missing_bone",
        lambda t: "\n".join(ln for ln in t.splitlines() if not ln.startswith("rtoes")),
        "frame 1 lacks bone 'rtoes'",
    ),
    (
        "data_before_frames",
        lambda t: _edit_amc(t, ":DEGREES", ":DEGREES\nroot 0 0 0 0 0 0"),
        ":4: AMC data before the first frame",
    ),
]


@pytest.mark.parametrize("name, edit, words", BAD_AMC, ids=[c[0] for c in BAD_AMC])
def test_bad_amc(trial, name, edit, words):
    bad = trial[1].with_name("01_09.amc")
    bad.write_text(edit(trial[1].read_text()))
    with pytest.raises(FileFormatError) as e:
        load_motion(bad, rest_joints=default_rest_joints())
    assert str(bad) in str(e.value) and words in str(e.value), str(e.value)


BAD_ASF = [  # (name, edit of the ASF text, message fragment)
    (
        "two_parents",
        lambda t: t.replace("    lfemur ltibia\n", "    lfemur ltibia\n    ltoes lhipjoint\n"),
        "bone 'lhipjoint' has two parents in the hierarchy",
    ),
    (
        "hierarchy_loop",
        lambda t: t.replace("    root lhipjoint rhipjoint lowerback\n", "    root rhipjoint lowerback\n").replace(
            "    lfemur ltibia\n", "    lfemur ltibia\n    ltoes lhipjoint\n"
        ),
        "the hierarchy has a cycle (expected a tree under root, got lhipjoint -> lfemur -> ltibia -> lfoot -> ltoes -> "
        "lhipjoint)",
    ),
    (
        "hierarchy_unknown_bone",
        lambda t: t.replace("    lfemur ltibia", "    lfemur ltibia tail"),
        "unknown bone 'tail' in the hierarchy (expected a bone of :bonedata, got tail)",
    ),
    ("hierarchy_unknown_parent", lambda t: t.replace("    lfemur ltibia", "    femur ltibia"), "unknown bone 'femur'"),
    ("bone_not_connected", lambda t: t.replace("    ltibia lfoot\n", ""), "bone 'lfoot' is not connected to the root"),
    ("no_hierarchy", lambda t: t.split(":hierarchy")[0], "ASF has no :hierarchy"),
    ("empty", lambda t: "", "ASF is empty"),
    ("bad_dof", lambda t: t.replace("dof rx rz", "dof rx rw", 1), "dof must list rotations rx, ry, rz"),
    ("bad_axis_order", lambda t: t.replace("  XYZ", "  XXY", 1), "axis order must be a permutation of XYZ"),
    (
        "limits_count",
        lambda t: t.replace(
            "dof rx rz\n    limits (-170.0 170.0)\n           (-170.0 170.0)", "dof rx rz\n    limits (-170.0 170.0)", 1
        ),
        "bone 'lfoot' has 2 dofs and 1 limits",
    ),
    ("nan_length", lambda t: t.replace("length 7.1", "length nan", 1), "length is not finite"),
    ("negative_unit", lambda t: t.replace("length 0.45", "length -0.45"), "units length must be positive"),
    ("unknown_section", lambda t: t.replace(":documentation", ":colour"), "unknown ASF keyword ':colour'"),
    ("duplicate_bone", lambda t: t.replace("name rtoes", "name ltoes"), "bone 'ltoes' is defined twice"),
    ("unclosed_bone", lambda t: t.replace("  end\n:hierarchy", ":hierarchy"), "bone block not closed"),
]


@pytest.mark.parametrize("name, edit, words", BAD_ASF, ids=[c[0] for c in BAD_ASF])
def test_bad_asf(trial, name, edit, words):
    trial[0].write_text(edit(trial[0].read_text()))
    with pytest.raises(FileFormatError) as e:
        load_motion(trial[1], rest_joints=default_rest_joints())
    assert str(trial[0]) in str(e.value) and words in str(e.value), str(e.value)


def test_bad_asf_errors_carry_the_line(trial):
    text = trial[0].read_text()
    trial[0].write_text(text.replace("    lfemur ltibia", "    lfemur ltibia tail"))
    line = next(i for i, ln in enumerate(text.splitlines(), 1) if ln == "    lfemur ltibia")
    with pytest.raises(FileFormatError, match=rf"01.asf:{line}: unknown bone 'tail'"):
        asf.read_asf(trial[0])


def test_mismatched_skeleton(trial, tmp_path):
    """A skeleton whose bones differ from the AMC's: the AMC line that does not fit is named."""
    bones = [b if b[0] != "ltibia" else b[:5] + (("rx", "rz"),) for b in cmu_bones()]
    other = tmp_path / "other.asf"
    other.write_text(asf_text(bones))
    with pytest.raises(
        FileFormatError,
        match=r"01_01.amc:8: wrong number of values for bone 'ltibia' "
        r"\(expected 2 \(dof rx rz in other.asf\), got 1\)",
    ):
        load_motion(trial[1], skeleton=other)
    with pytest.raises(FileFormatError, match="no such file"):
        load_motion(trial[1], skeleton=tmp_path / "nowhere.asf")


# ---- the command line --------------------------------------------------------------------------------------
def test_cli_info_export_run(trial, tmp_path):
    from click.testing import CliRunner

    from segadeform.cli.main import cli
    from segadeform.motion import read_motion_file

    r = CliRunner().invoke(cli, ["motion", "info", str(trial[1])])
    assert r.exit_code == 0, r.output
    assert "40 frames, 120 fps" in r.output and "length unit 0.45 = 0.056444 m" in r.output
    assert "left_wrist=lhand" in r.output
    out = tmp_path / "t.sgdm"
    r = CliRunner().invoke(cli, ["motion", "export", str(trial[1]), "--fps", "30", "-o", str(out)])
    assert r.exit_code == 0, r.output
    m, _ = read_motion_file(out)
    assert m.n_frames == 10 and m.fps == 30.0
    skel = tmp_path / "s.asf"
    trial[0].rename(skel)
    samples = Path(__file__).resolve().parents[2] / "samples"
    pc2 = tmp_path / "o.pc2"
    r = CliRunner().invoke(
        cli,
        [
            "run",
            "--garment",
            str(samples / "garments" / "skirt.obj"),
            "--motion",
            str(trial[1]),
            "--skeleton",
            str(skel),
            "--frames",
            "0:4",
            "-o",
            str(pc2),
            "--no-cache",
        ],
    )
    assert r.exit_code == 0, r.output
    from segadeform.io import read_pc2

    assert read_pc2(pc2).frames.shape[0] == 4
    r = CliRunner().invoke(cli, ["motion", "info", str(trial[1])])  # the skeleton is no longer beside it
    assert r.exit_code == 1 and "Error: " in r.output and "01_01.amc: cannot tell which skeleton" in r.output


# ---- the real CMU data (../shared) -------------------------------------------------------------------------
CMU_ASF = sorted(CMU_AMC.glob("*/*.asf")) if CMU_AMC.is_dir() else []
CMU_TRIALS = sorted(CMU_AMC.glob("*/*.amc")) if CMU_AMC.is_dir() else []


@needs_shared
def test_cmu_metre_factor_against_the_subjects_height():
    """0.0254 / 0.45 m per unit makes every subject an adult standing 1.54-1.60 m from the lowest foot point to
    the head bone's end (joint centres: stature is a few cm more), legs (femur + tibia) 0.83-0.87 m; reading the
    unit as inches (ignoring 0.45) would make them 0.69-0.72 m tall."""
    assert len(CMU_ASF) == 7
    for f in CMU_ASF:
        s = asf.read_asf(f)
        start, end = s.rest()
        pts = np.concatenate([start, end])[:, 1]
        height = (pts.max() - pts.min()) * s.metres
        legs = sum(s.lengths[s.names.index(b)] for b in ("lfemur", "ltibia")) * s.metres
        assert 1.50 < height < 1.65 and 0.80 < legs < 0.90, (f.name, height, legs)
        assert (pts.max() - pts.min()) * 0.0254 < 0.75


@needs_shared
def test_cmu_root_translation_is_in_the_length_unit():
    """The AMC root translation and the bone lengths share the unit: in a walk the foot on the ground stays put
    (median horizontal speed of the lower foot joints < 10 % of the root's)."""
    sk = asf.amc_skeleton(CMU_AMC / "16" / "16_15.amc")
    root = np.median(np.linalg.norm(np.diff(sk.positions[:, 0, [0, 2]], axis=0), axis=1))
    for toe in ("ltoes", "rtoes"):
        p = sk.positions[:, sk.names.index(toe)]
        low = p[1:, 1] < np.percentile(p[:, 1], 20)
        speed = np.median(np.linalg.norm(np.diff(p[:, [0, 2]], axis=0), axis=1)[low])
        assert speed < 0.1 * root, (toe, speed, root)


@needs_shared
def test_cmu_fast_forward_kinematics_matches_the_reference():
    s = asf.read_asf(CMU_AMC / "49" / "49.asf")
    amc = asf.read_amc_values(CMU_AMC / "49" / "49_06.amc", s)  # a cartwheel
    amc = asf.AMCValues(
        amc.path, {k: v[::40] for k, v in amc.values.items()}, 1, len(amc.values["root"][::40]), amc.angle, True
    )
    _, start, end = asf.asf_forward_kinematics(s, amc)
    ref_start, ref_end = asf._fk_reference(s, amc)
    np.testing.assert_allclose(start, ref_start, atol=1e-9)
    np.testing.assert_allclose(end, ref_end, atol=1e-9)


def _globals(m):
    R = poses_to_rotmats(m.poses, 24)
    G = np.empty_like(R)
    for j in range(24):
        G[:, j] = R[:, j] if SMPL_PARENTS[j] < 0 else G[:, SMPL_PARENTS[j]] @ R[:, j]
    return G


def _pelvis_relative(G, J):
    P = np.zeros(G.shape[:2] + (3,))
    for j in range(1, 24):
        p = SMPL_PARENTS[j]
        P[:, j] = P[:, p] + G[:, p] @ (J[j] - J[p])
    return P


def _cross_check(J):
    """Joint distances (T, 23) between 02_01 read from its AMC and from cgspeed's BVH, both on the body ``J``,
    pelvis-relative, the start aligned: each SMPL joint's global rotation in the BVH's motion is turned by
    its frame-0 difference to the AMC's (the BVH's subject-02 skeleton is calibrated differently)."""
    a = load_motion(CMU_AMC / "02" / "02_01.amc", rest_joints=J)
    b = load_motion(CMU_BVH / "02_01_walk.bvh", rest_joints=J)
    Ga, Gb = _globals(a), _globals(b)
    assert len(Ga) == len(Gb) == 343
    Gb = Gb @ (np.swapaxes(Gb[0], -1, -2) @ Ga[0])
    return np.linalg.norm(_pelvis_relative(Ga, J) - _pelvis_relative(Gb, J), axis=-1)[:, 1:]


@needs_shared
@pytest.mark.skipif(not CMU_BVH.is_dir(), reason=f"cgspeed's BVH conversions are not in {CMU_BVH}")
def test_cmu_cross_check_with_cgspeed_bvh(monkeypatch):
    """The same trials through cgspeed's BVH conversions.

    02_01 (MotionBuilder-style BVH, the ASF's bone layout) on the shipped body, pelvis-relative, start aligned,
    all 23 joints x 343 frames: mean 0.74 cm, 95th percentile 2.46 cm, max 6.25 cm (a toe); 91.5 % of the
    joint-frames within 2 cm; without toes and hands: 95th percentile 1.84 cm, max 2.97 cm.  The 2 cm the
    issue asks for holds for the bulk, not every joint-frame: this BVH is not a conversion of these AMC values.
    Its root translation is the AMC's times 1.06312 on every axis in every frame, its skeleton is another
    calibration of subject 02 (femur 7.16 vs 7.59 units, hip joints 2-4 mm elsewhere), and its joint
    rotations differ from the AMC's by 2-6 degrees that change over the trial (the head's are identical).
    Read with the Euler order reversed (axes and dofs), the same comparison gives mean 6.9 cm, max 66 cm.

    16_15, 16_31, 16_36 (DAZ-style BVH, retargeted by cgspeed onto a figure of other proportions; a T-pose
    first frame): the root's global rotation equals the AMC's in every frame to 1e-4 degrees.
    """
    from segadeform.body import default_body_path, load_body
    from segadeform.motion.bvh import read_bvh_skeleton

    J = load_body(default_body_path()).rest_joints()[0]
    e = _cross_check(J)
    assert e.mean() < 0.01 and np.percentile(e, 95) < 0.026 and e.max() < 0.065, (e.mean(), e.max())
    assert (e < 0.02).mean() > 0.9
    body = [j - 1 for j in range(1, 24) if j not in (10, 11, 22, 23)]  # not toes, not hands
    assert np.percentile(e[:, body], 95) < 0.02 and e[:, body].max() < 0.031
    for t in ("16_15", "16_31", "16_36"):
        sa = asf.amc_skeleton(CMU_AMC / "16" / f"{t}.amc")
        sb = read_bvh_skeleton(next(CMU_BVH.glob(f"{t}_*.bvh")))
        k = len(sa.rotations)
        assert len(sb.rotations) == k + 1
        Ra, Rb = sa.rotations[:, 0], sb.rotations[1:, 0]
        cos = (np.trace(np.swapaxes(Ra, -1, -2) @ Rb, axis1=-2, axis2=-1) - 1) / 2
        assert np.degrees(np.arccos(np.clip(cos, -1, 1))).max() < 1e-3, t
    # the comparison can fail: the dofs' Euler order reversed
    euler = asf._euler
    monkeypatch.setattr(asf, "_euler", lambda angles, axes: euler(angles[..., ::-1], axes[::-1]))
    assert _cross_check(J).mean() > 0.05


@needs_shared
def test_every_cmu_trial_animates_an_upright_body():
    """All 157 trials load as the dataset maker loads them (retargeted onto the shipped body, feet on the
    floor) and animate an upright body: on the first frame the spine points up (within 60 degrees), the head
    is at least 0.9 m above every foot joint and above the neck, the neck above the pelvis, the pelvis above
    both knees and the standing leg's ankle below its knee (a runner's other foot may be up behind); on at
    least 40 % of nine frames spread over the trial the spine points up too (cartwheels and dive rolls turn
    over in between: 49_08 has the fewest, 4 of 9)."""
    from segadeform.body import default_body_path, load_body

    assert len(CMU_TRIALS) == 157
    J = load_body(default_body_path()).rest_joints()[0]
    skeletons = {f.parent: asf.read_asf(f) for f in CMU_ASF}
    bad = []
    for f in CMU_TRIALS:
        m = load_motion(f, rest_joints=J, floor=True, skeleton=None)
        assert m.fps == 120.0 and np.isfinite(m.poses).all() and m.meta["skeleton"] == str(skeletons[f.parent].path)
        idx = np.linspace(0, m.n_frames - 1, 9).round().astype(int)
        _, P = forward_kinematics(poses_to_rotmats(m.poses[idx], 24), J, SMPL_PARENTS, m.trans[idx])
        spine = P[:, 12] - P[:, 0]
        up = spine[:, 1] / np.linalg.norm(spine, axis=1)
        y = P[0, :, 1]
        first_ok = (
            up[0] > 0.5
            and y[15] - y[[7, 8, 10, 11]].max() > 0.9
            and y[15] > y[12] > y[0] > max(y[4], y[5])
            and min(y[4], y[5]) > min(y[7], y[8])
        )
        if not first_ok or (up > 0.5).mean() < 0.4:
            bad.append(f"{f.name}: first-frame up {up[0]:.2f}, upright frames {(up > 0.5).mean():.2f}")
    assert not bad, bad
