"""FBX motion through Blender (segadeform.physics.fbx, `segadeform motion convert`): an FBX character's animation
reads as the motion it was made from; files without one are refused in one line naming them."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

from segadeform.body.rotations import axis_angle_to_matrix
from segadeform.body.skeleton import default_rest_joints
from segadeform.errors import FileFormatError, SimulationError
from segadeform.motion import load_motion, read_motion_file
from segadeform.motion.bvh import read_bvh_skeleton
from segadeform.physics.fbx import fbx_to_bvh
from tests.physics.fbx_files import make_fbx

REPO = Path(__file__).resolve().parents[2]
BVH = REPO / "samples" / "motions" / "cmu" / "02_01_walk.bvh"  # a CMU walk kept in the repository


@pytest.fixture(scope="module")
def fbx(tmp_path_factory):
    """name -> FBX file made by Blender from BVH (each 1-2 s)."""
    d = tmp_path_factory.mktemp("fbx")
    kinds = {
        "skinned": ("skinned",),
        "mixamo-cm": ("skinned", "mixamo", "cm"),
        "two-takes": ("skinned", "two-takes"),
        "unskinned": (),
        "objroot": ("skinned", "objroot"),
        "turned-biped": ("skinned", "turned", "spaces"),
        "with-prop": ("skinned", "prop"),
        "fps30": ("skinned", "fps30"),
        "still": ("still",),
        "no-armature": ("no-armature",),
    }
    return {k: make_fbx(BVH, d / f"{k}.fbx", *modes) for k, modes in kinds.items()}


def _angles(a, b) -> np.ndarray:
    """(T, 24) degrees between the joint rotations of motions a and b."""
    n = min(a.n_frames, b.n_frames)
    ra = axis_angle_to_matrix(a.poses[:n].reshape(-1, 3))
    rb = axis_angle_to_matrix(b.poses[:n].reshape(-1, 3))
    cos = (np.einsum("nij,nij->n", ra, rb) - 1.0) / 2.0
    return np.degrees(np.arccos(np.clip(cos, -1.0, 1.0))).reshape(n, 24)


@pytest.mark.parametrize("kind", ["skinned", "mixamo-cm"])
def test_an_fbx_characters_animation_reads_as_the_motion_it_was_made_from(fbx, tmp_path, kind):
    """A BVH taken to an FBX character (a mesh skinned to the armature; Mixamo's bone names and a 2x scaled armature
    for the second) and back through fbx_to_bvh: the same frames, rate and retargeted poses, within 0.5 degrees per
    joint and 3 mm of root travel (FBX stores floats; Blender resamples the keys)."""
    out = tmp_path / "back.bvh"
    got = fbx_to_bvh(fbx[kind], out)
    src_sk = read_bvh_skeleton(BVH)
    assert got.skinned and got.bones == len(src_sk.names) and got.frames == len(src_sk.positions)
    assert got.fps == pytest.approx(src_sk.fps, rel=1e-4)
    J = default_rest_joints()
    a, b = load_motion(BVH, rest_joints=J), load_motion(out, rest_joints=J)
    assert a.n_frames == b.n_frames and b.fps == pytest.approx(a.fps, rel=1e-4)
    ang = _angles(a, b)
    assert ang.max() < 1.0 and ang.mean() < 0.1, (ang.max(), ang.mean())
    assert np.abs(a.trans - b.trans).max() < 0.005
    if kind == "mixamo-cm":  # Mixamo's names read as such; the armature scaled 2x gives offsets twice as long
        assert b.meta["mapped"]["pelvis"] == "mixamorig:Hips"
        plain = tmp_path / "plain.bvh"
        fbx_to_bvh(fbx["skinned"], plain)
        r1, r2 = read_bvh_skeleton(plain).rest, read_bvh_skeleton(out).rest
        np.testing.assert_allclose(r2 - r2[0], 2.0 * (r1 - r1[0]), atol=1e-4 * np.ptp(r2))


def test_an_fbx_take_is_chosen_by_name_and_an_unknown_one_lists_the_takes(fbx, tmp_path):
    both = fbx_to_bvh(fbx["two-takes"], tmp_path / "a.bvh")
    assert len(both.animations) == 2 and both.frames > 40
    short = [a for a in both.animations if a.endswith("walk-start")][0]
    got = fbx_to_bvh(fbx["two-takes"], tmp_path / "b.bvh", animation=short)
    assert got.animation == short and got.frames == 40
    assert load_motion(tmp_path / "b.bvh").n_frames == 40
    with pytest.raises(FileFormatError) as e:
        fbx_to_bvh(fbx["two-takes"], tmp_path / "c.bvh", animation="run")
    msg = str(e.value)
    assert (
        msg.startswith(str(fbx["two-takes"]))
        and "no armature animation 'run'" in msg
        and short in msg
        and "\n" not in msg
    )
    assert not (tmp_path / "c.bvh").exists()


@pytest.mark.parametrize(
    ("kind", "says"),
    [
        ("still", "its armature has no animation"),
        ("no-armature", "no armature (skeleton)"),
        ("junk", "Blender's FBX importer could not read it (ASCII FBX files are not supported)"),
        ("binary-junk", "Blender's FBX importer could not read it"),
    ],
)
def test_a_file_without_an_animated_skeleton_is_refused_naming_it(fbx, tmp_path, kind, says):
    if kind == "junk":
        src = tmp_path / "junk.fbx"
        src.write_text("; FBX 7.4.0 project file\nFBXHeaderExtension:  {\n")
    elif kind == "binary-junk":
        src = tmp_path / "binary.fbx"
        src.write_bytes(b"Kaydara FBX Binary  \x00\x1a\x00" + bytes(range(256)) * 4)
    else:
        src = fbx[kind]
    out = tmp_path / "x.bvh"
    with pytest.raises(FileFormatError) as e:
        fbx_to_bvh(src, out)
    msg = str(e.value)
    assert msg.startswith(f"{src}: ") and says in msg and "\n" not in msg, msg
    assert not out.exists()


def test_a_missing_fbx_file_is_named_before_blender_starts(tmp_path):
    with pytest.raises(FileFormatError, match="no such file"):
        fbx_to_bvh(tmp_path / "nope.fbx", tmp_path / "x.bvh", sim_python=tmp_path / "no-python")


def _cli(args):
    from segadeform.cli.main import cli

    return CliRunner().invoke(cli, args, catch_exceptions=False)


def test_motion_convert_writes_the_bvh_and_says_what_it_read(fbx, tmp_path):
    out = tmp_path / "walk.bvh"
    r = _cli(["motion", "convert", str(fbx["two-takes"]), "-o", str(out)])
    assert r.exit_code == 0, r.output
    assert "other animations:" in r.output and "--animation NAME" in r.output and str(out) in r.output
    assert "warning" not in r.output
    assert load_motion(out).n_frames == read_bvh_skeleton(BVH).positions.shape[0]
    # an FBX without a skinned mesh: converted, with a warning that its rest pose is not a bind pose
    r = _cli(["motion", "convert", str(fbx["unskinned"]), "-o", str(tmp_path / "u.bvh")])
    assert r.exit_code == 0 and "no mesh skinned to its armature" in r.output, r.output
    # refusals: not an FBX, not a .bvh output
    r = _cli(["motion", "convert", str(out), "-o", str(tmp_path / "y.bvh")])
    assert r.exit_code == 1 and "expected .fbx" in r.output and len(r.output.strip().splitlines()) == 1
    r = _cli(["motion", "convert", str(fbx["skinned"]), "-o", str(tmp_path / "y.npz")])
    assert r.exit_code == 2 and "-o must end in .bvh" in r.output
    assert not (tmp_path / "y.bvh").exists() and not (tmp_path / "y.npz").exists()


def test_motion_info_and_export_read_an_fbx_file_as_motion_convert_does(fbx, tmp_path):
    bvh = tmp_path / "skinned.bvh"
    fbx_to_bvh(fbx["skinned"], bvh)
    r = _cli(["motion", "info", str(fbx["skinned"])])
    assert r.exit_code == 0 and "cmu-motionbuilder names" in r.output, r.output
    for src, name in ((fbx["skinned"], "a"), (bvh, "b")):
        r = _cli(["motion", "export", str(src), "-o", str(tmp_path / f"{name}.sgdm")])
        assert r.exit_code == 0, r.output
    (a, meta_a), (b, _) = read_motion_file(tmp_path / "a.sgdm"), read_motion_file(tmp_path / "b.sgdm")
    np.testing.assert_array_equal(a.poses, b.poses)
    np.testing.assert_array_equal(a.trans, b.trans)
    assert meta_a["source"] == str(fbx["skinned"])
    short = [n for n in fbx_to_bvh(fbx["two-takes"], tmp_path / "t.bvh").animations if n.endswith("walk-start")][0]
    r = _cli(["motion", "export", str(fbx["two-takes"]), "--animation", short, "-o", str(tmp_path / "s.sgdm")])
    assert r.exit_code == 0 and read_motion_file(tmp_path / "s.sgdm")[0].n_frames == 40, r.output
    # the motion readers below the command line do not read FBX: one line, with the commands that do
    with pytest.raises(FileFormatError, match="segadeform motion convert"):
        load_motion(fbx["skinned"])


def test_run_plays_an_fbx_motion_as_the_bvh_motion_convert_writes(fbx, tmp_path):
    from segadeform.io import read_pc2

    skirt = str(REPO / "samples" / "garments" / "skirt.obj")
    bvh = tmp_path / "walk.bvh"
    assert _cli(["motion", "convert", str(fbx["skinned"]), "-o", str(bvh)]).exit_code == 0
    for src, out in ((fbx["skinned"], "a.pc2"), (bvh, "b.pc2")):
        r = _cli(
            [
                "run",
                "--garment",
                skirt,
                "--motion",
                str(src),
                "--frames",
                "0:12",
                "--no-cache",
                "-o",
                str(tmp_path / out),
            ]
        )
        assert r.exit_code == 0, r.output
    np.testing.assert_array_equal(read_pc2(tmp_path / "a.pc2").frames, read_pc2(tmp_path / "b.pc2").frames)
    r = _cli(
        [
            "run",
            "--garment",
            skirt,
            "--motion",
            str(fbx["skinned"]),
            "--animation",
            "nope",
            "-o",
            str(tmp_path / "c.pc2"),
        ]
    )
    assert r.exit_code == 1 and "no armature animation 'nope'" in r.output and not (tmp_path / "c.pc2").exists()


def test_root_motion_on_the_armature_object_is_kept(fbx, tmp_path):
    """The armature object keyed 2 m along +X over the clip (the bones as they were): the BVH's root is the plain
    file's plus that travel, in world space (Blender's exporter read armature space and dropped it: a review)."""
    fbx_to_bvh(fbx["skinned"], tmp_path / "plain.bvh")
    fbx_to_bvh(fbx["objroot"], tmp_path / "moved.bvh")
    a, b = read_bvh_skeleton(tmp_path / "plain.bvh"), read_bvh_skeleton(tmp_path / "moved.bvh")
    assert a.up == b.up == "y"
    d = b.positions[:, 0] - a.positions[:, 0]
    np.testing.assert_allclose(d[0], [0.0, 0.0, 0.0], atol=1e-4)
    np.testing.assert_allclose(d[-1], [2.0, 0.0, 0.0], atol=1e-4)
    assert np.all(np.diff(d[:, 0]) >= -1e-6)  # it travels one way
    np.testing.assert_allclose(b.positions - b.positions[:, :1], a.positions - a.positions[:, :1], atol=1e-4)


def test_a_character_facing_x_with_biped_names_reads_as_the_same_motion_turned(fbx, tmp_path):
    """3ds Max Biped's names ("Bip01 LeftUpLeg": BVH names are one word, so they become "Bip01_LeftUpLeg") on a
    character that faces +X in its file: the BVH is +Y up whatever way the character faces, and every joint's
    rotation against its parent is the original's (the retargeting turned to face +Z first: a quarter-turn twist
    of the spine and knees before, a review); the root turns and travels with the file."""
    got = fbx_to_bvh(fbx["turned-biped"], tmp_path / "t.bvh")
    assert got.renamed == got.bones
    sk = read_bvh_skeleton(tmp_path / "t.bvh", up="auto")
    assert sk.up == "y" and all(" " not in n for n in sk.names) and "Bip01_LeftUpLeg" in sk.names
    J = default_rest_joints()
    a, b = load_motion(BVH, rest_joints=J), load_motion(tmp_path / "t.bvh", rest_joints=J)
    ang = _angles(a, b)[:, 1:]  # every joint but the root, against its parent
    assert ang.max() < 1.0 and ang.mean() < 0.1, (ang.max(), ang.mean())
    # the root: the original's turned a quarter about +Y (the file's turn about Blender's +Z)
    turn = axis_angle_to_matrix(np.array([0.0, np.pi / 2, 0.0]))
    ra, rb = axis_angle_to_matrix(a.poses[:, :3]), axis_angle_to_matrix(b.poses[:, :3])
    cos = (np.einsum("nij,nij->n", turn @ ra, rb) - 1.0) / 2.0
    assert np.degrees(np.arccos(np.clip(cos, -1, 1))).max() < 1.0
    travel_a, travel_b = a.trans - a.trans[0], b.trans - b.trans[0]
    np.testing.assert_allclose(travel_b, travel_a @ turn.T, atol=0.005)


def test_the_character_is_taken_before_a_prop_rig_with_more_bones(fbx, tmp_path):
    got = fbx_to_bvh(fbx["with-prop"], tmp_path / "c.bvh")
    assert got.armature == "Armature" and got.skinned and len(got.armatures) == 2
    assert read_bvh_skeleton(tmp_path / "c.bvh").names[0] == "Hips"


def test_a_take_is_also_found_by_its_own_name(fbx, tmp_path):
    got = fbx_to_bvh(fbx["two-takes"], tmp_path / "s.bvh", animation="walk-start")
    assert got.animation.endswith("|walk-start") and got.frames == 40


def test_an_empty_file_and_a_failed_worker_leave_nothing(tmp_path):
    src = tmp_path / "empty.fbx"
    src.write_bytes(b"")
    with pytest.raises(FileFormatError, match="empty file"):
        fbx_to_bvh(src, tmp_path / "x.bvh")
    src.write_bytes(b"Kaydara FBX Binary  \x00\x1a\x00" + bytes(200))
    fake = tmp_path / "python"  # a "simulator Python" that writes half a file and dies
    fake.write_text(f"#!/bin/sh\nprintf 'HIERARCHY' > '{tmp_path / 'x.bvh.part'}'\nexit 3\n")
    fake.chmod(0o755)
    with pytest.raises(SimulationError, match="exit 3"):
        fbx_to_bvh(src, tmp_path / "x.bvh", sim_python=fake)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["empty.fbx", "python"]


def test_a_30_fps_file_comes_back_at_30_fps(fbx, tmp_path):
    """The BVH's Frame Time was written to 9 decimals, 0.033333333, which reads back as 30.0000003 fps: a Node game
    loop opened at 30 fps then differed from the command line by 5.7e-6 m (a trial).  It is written to 17 digits."""
    got = fbx_to_bvh(fbx["fps30"], tmp_path / "w.bvh")
    assert got.fps == 30.0
    assert read_bvh_skeleton(tmp_path / "w.bvh").fps == pytest.approx(30.0, rel=1e-12)


def test_batch_and_bundle_read_an_fbx_motion_as_run_does(fbx, tmp_path):
    """A jobs file's motion and a scene's motion may be the .fbx itself (they took only the converted BVH): `batch`
    writes what `run` writes of it, resumes without converting the jobs' identity away, and `bundle` packs the motion
    `run` plays."""
    from segadeform.io import read_pc2
    from segadeform.io.sgdb import read_bundle

    skirt = REPO / "samples" / "garments" / "skirt.obj"
    r = _cli(
        [
            "run",
            "--garment",
            str(skirt),
            "--motion",
            str(fbx["skinned"]),
            "--frames",
            "0:12",
            "-o",
            str(tmp_path / "run.pc2"),
        ]
    )
    assert r.exit_code == 0, r.output
    jobs = tmp_path / "jobs.toml"
    jobs.write_text(
        f'[batch]\noutput = "out"\n[[garments]]\nmesh = "{skirt}"\n[[motions]]\nfile = "{fbx["skinned"]}"\n'
        'name = "walk"\nframes = "0:12"\n'
    )
    r = _cli(["batch", str(jobs)])
    assert r.exit_code == 0 and "1 made" in r.output, r.output
    np.testing.assert_allclose(
        read_pc2(tmp_path / "out" / "skirt__walk.pc2").frames, read_pc2(tmp_path / "run.pc2").frames, atol=1e-6
    )
    r = _cli(["batch", str(jobs)])  # the job's identity is the FBX file, not the temporary BVH: done
    assert r.exit_code == 0 and "1 already done" in r.output and "armature" not in r.output, r.output  # not read again
    # a file Blender cannot read fails its own jobs; the others are made (a review: it stopped the whole batch)
    bad = tmp_path / "bad.fbx"
    bad.write_bytes(np.random.default_rng(0).bytes(4096))
    walk = REPO / "samples" / "motions" / "walk.npz"
    jobs.write_text(
        f'[batch]\noutput = "out2"\n[[garments]]\nmesh = "{skirt}"\n[[motions]]\nfile = "{bad}"\n'
        f'[[motions]]\nfile = "{walk}"\nframes = "0:4"\n'
    )
    r = _cli(["batch", str(jobs)])
    assert r.exit_code == 1 and "1 made, 1 failed" in r.output and "bad.fbx" in r.output, r.output
    assert (tmp_path / "out2" / "skirt__walk.pc2").is_file() and not (tmp_path / "out2" / "skirt__bad.pc2").exists()
    # with a Ray cluster the BVH made here would not reach the workers: one line, before anything runs
    r = _cli(["batch", str(jobs), "-o", str(tmp_path / "ray"), "--executor", "ray://nowhere:1"])
    assert r.exit_code == 1 and "converted first" in r.output and not (tmp_path / "ray").exists(), r.output
    # a bundle of a scene whose motion is the FBX: the motion `run` plays (the converted BVH's), named as the file
    bvh = tmp_path / "walk.bvh"
    assert _cli(["motion", "convert", str(fbx["skinned"]), "-o", str(bvh)]).exit_code == 0
    for motion, name in ((fbx["skinned"], "a"), (bvh, "b")):
        scene = tmp_path / f"{name}.toml"
        scene.write_text(
            f'[garment]\nmesh = "{skirt}"\n[motion]\nfile = "{motion}"\nframes = "0:8"\n[output]\npath = "{name}.pc2"\n'
        )
        r = _cli(["bundle", str(scene), "--no-expected", "-o", str(tmp_path / f"{name}.sgdb")])
        assert r.exit_code == 0, r.output
    (a, ma), (b, _) = read_bundle(tmp_path / "a.sgdb"), read_bundle(tmp_path / "b.sgdb")
    np.testing.assert_array_equal(a["poses"], b["poses"])
    np.testing.assert_array_equal(a["trans"], b["trans"])
    assert ma["motion"] == fbx["skinned"].stem


def test_a_dataset_config_takes_an_fbx_motion_read_once_through_blender(fbx, tmp_path, monkeypatch):
    """A dataset's [[motions]] file may be an .fbx (it took only the converted BVH): its clips are cut from the BVH
    Blender makes of it, converted once and kept in the user cache, and named as the FBX file."""
    import segadeform.physics.fbx as fbx_mod
    from segadeform.dataset import load_dataset_config
    from segadeform.dataset.make import _capture

    monkeypatch.setenv("SEGADEFORM_CACHE_DIR", str(tmp_path / "cache"))
    bvh = tmp_path / "walk.bvh"
    assert _cli(["motion", "convert", str(fbx["skinned"]), "-o", str(bvh)]).exit_code == 0
    cfgs = []
    for name, f in (("a", fbx["skinned"]), ("b", bvh)):
        p = tmp_path / f"{name}.toml"
        p.write_text(
            '[dataset]\nfps = 30.0\nseconds = 0.5\n[[garments]]\nkind = "skirt"\n[[bodies]]\nbetas = []\n'
            f'[[motions]]\nfile = "{f}"\n'
        )
        cfgs.append(load_dataset_config(p))
    calls = []
    real = fbx_mod.fbx_to_bvh
    monkeypatch.setattr(fbx_mod, "fbx_to_bvh", lambda *a, **k: calls.append(a) or real(*a, **k))
    a = _capture(cfgs[0].motions[0], cfgs[0])
    b = _capture(cfgs[1].motions[0], cfgs[1])
    np.testing.assert_array_equal(a.poses, b.poses)
    np.testing.assert_array_equal(a.trans, b.trans)
    assert a.name == fbx["skinned"].stem and len(calls) == 1
    _capture(cfgs[0].motions[0], cfgs[0])  # the second clip of the file: from the cache, no Blender
    assert len(calls) == 1 and [p.name[:2] for p in (tmp_path / "cache").iterdir()] == ["F-"]
    # a cache too small to keep it (or cleared meanwhile): converted again, and read (a review: "walk.fbx: no such
    # file", the entry pruned before it was read)
    monkeypatch.setenv("SEGADEFORM_CACHE_MAX_MB", "0")
    for p in (tmp_path / "cache").iterdir():
        p.unlink()
    c = _capture(cfgs[0].motions[0], cfgs[0])
    np.testing.assert_array_equal(c.poses, a.poses)
    assert len(calls) == 2 and not list((tmp_path / "cache").iterdir())
