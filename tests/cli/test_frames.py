"""`--frames A:B` past the motion: one check (segadeform.motion.frame_range) and one message from run, simulate
and bundle, before any work (simulate: before the simulator starts, so no Blender is needed here)."""

from __future__ import annotations

import logging

import numpy as np
import pytest
from click.testing import CliRunner

from segadeform.cli.main import cli
from segadeform.errors import InputError
from segadeform.io import read_mesh
from segadeform.motion import frame_range, make_motion, select_frames

from ..conftest import SAMPLES


def test_frame_range_and_select_frames():
    assert frame_range(None, 6) == (0, 6) and frame_range((2, None), 6) == (2, 6) and frame_range((1, 4), 6) == (1, 4)
    for bad, given in (((2, 7), "2:7"), ((6, None), "6:"), ((0, 0), "0:0"), ((-1, 3), "-1:3")):
        with pytest.raises(InputError) as e:
            frame_range(bad, 6)
        assert (
            str(e.value)
            == f"frame range {given} is outside the motion's 6 frames (expected 0 <= A < B <= 6, got {given})"
        )
    m = make_motion("walk", seconds=0.2)
    part, start = select_frames(m, (2, 5))
    assert start == 2 and part.n_frames == 3 and np.array_equal(part.poses, m.poses[2:5])
    assert select_frames(m, None) == (m, 0)


@pytest.fixture
def scene(tmp_path):
    p = tmp_path / "s.toml"
    p.write_text(
        f'[garment]\nmesh = "{SAMPLES / "garments" / "skirt.obj"}"\n[motion]\nkind = "walk"\nseconds = 0.2\n'
        '[output]\npath = "out/g.pc2"\n[simulate]\neffects = ["gravity"]\n'
    )
    return p


WANT = "Error: frame range 2:50 is outside the motion's 6 frames (expected 0 <= A < B <= 6, got 2:50)"


def test_run_simulate_and_bundle_refuse_frames_past_the_motion_alike(scene, tmp_path, monkeypatch):
    import segadeform.physics.scene_sim as scene_sim

    def no_simulator(*a, **k):
        raise AssertionError("the simulator started before the frame range was checked")

    monkeypatch.setattr(scene_sim, "simulate", no_simulator)
    for args in (
        ["run", str(scene), "--frames", "2:50"],
        ["simulate", str(scene), "--frames", "2:50"],
        ["bundle", str(scene), "--frames", "2:50", "-o", str(tmp_path / "b.sgdb")],
    ):
        r = CliRunner().invoke(cli, args)
        assert r.exit_code == 1, (args, r.output, r.exception)
        assert r.output.strip().splitlines()[-1] == WANT, args
    assert not (tmp_path / "out").exists() and not (tmp_path / "b.sgdb").exists()


def test_run_repairs_a_captures_glitches_when_asked_and_keeps_its_frames(tmp_path, caplog):
    """`run --repair-glitches` (the scene's `[motion] repair_glitches`): the same frame count, other frames where
    the capture jumped; without it the capture plays as it is."""
    import dataclasses

    from segadeform.io.pc2 import read_pc2

    m = make_motion("walk", seconds=1.0, fps=120.0, seed=0, ease_in=0.0)
    bad = m.poses.copy()
    bad[[60, 61], 3 * 1] += 1.0  # a thigh thrown forward for two frames
    dataclasses.replace(m, poses=bad).save(tmp_path / "cap.npz")
    out = {}
    for name, extra in (("as_is", []), ("repaired", ["--repair-glitches"])):
        args = ["run", "--garment", str(SAMPLES / "garments" / "skirt.obj"), "--motion", str(tmp_path / "cap.npz")]
        caplog.clear()
        with caplog.at_level(logging.WARNING):
            r = CliRunner().invoke(cli, [*args, "-o", str(tmp_path / f"{name}.pc2"), *extra])
        assert r.exit_code == 0, r.output
        said = [rec.getMessage() for rec in caplog.records if "jumps to and back from" in rec.getMessage()]
        assert len(said) == (name == "as_is"), said  # a warning naming the fix, when it is not asked for
        assert name == "repaired" or "cap.npz" in said[0] and "--repair-glitches" in said[0]
        out[name] = np.array(read_pc2(tmp_path / f"{name}.pc2").frames)
    assert out["as_is"].shape == out["repaired"].shape and out["as_is"].shape[0] == m.n_frames
    # a frame range counts the jumps inside it: none before frame 60, the two at 60-61 in 50:80
    for frames, n in (("0:50", 0), ("50:80", 2)):
        caplog.clear()
        with caplog.at_level(logging.WARNING):
            r = CliRunner().invoke(cli, [*args, "--frames", frames, "-o", str(tmp_path / "r.pc2")])
        assert r.exit_code == 0, r.output
        said = [rec.getMessage() for rec in caplog.records if "jumps to and back from" in rec.getMessage()]
        assert len(said) == (n > 0), (frames, said)
        assert not n or "cap.npz: 2 frames it jumps to and back from (joints" in said[0], said
    moved = np.abs(out["as_is"] - out["repaired"]).max(axis=(1, 2))
    assert moved[60:62].min() > 0.01 and moved[:50].max() == 0.0  # the jump is gone; the frames before are the file's
    # a garment that is not on the body is refused in one line: nothing is said of the motion first (a user's trial
    # got the glitches' warning above the garment's error)
    (tmp_path / "small.obj").write_text(
        "".join(
            f"v {0.1 * x:.5f} {0.1 * y:.5f} {0.1 * z:.5f}\n"
            for x, y, z in read_mesh(SAMPLES / "garments" / "skirt.obj").vertices
        )
        + "".join(f"f {a + 1} {b + 1} {c + 1}\n" for a, b, c in read_mesh(SAMPLES / "garments" / "skirt.obj").faces)
    )
    caplog.clear()
    with caplog.at_level(logging.WARNING):
        r = CliRunner().invoke(
            cli,
            [
                "run",
                "--garment",
                str(tmp_path / "small.obj"),
                "--motion",
                str(tmp_path / "cap.npz"),
                "-o",
                str(tmp_path / "s.pc2"),
            ],
        )
    assert r.exit_code == 1 and "small.obj" in r.output and "does not sit on the body" in r.output, r.output
    assert [rec.getMessage() for rec in caplog.records if rec.levelno >= logging.WARNING] == [], caplog.records
    assert not (tmp_path / "s.pc2").exists()


def test_a_root_too_far_is_named_at_the_frame_run_counts(tmp_path):
    """A root past 10 km named the frame of the motion as read; `run --fps` plays it resampled, and `--frames A:B`
    and run's other messages count the frames played: the refusal names the frame at the rate played (and the one as
    read beside it).  A range changes nothing: the whole motion is checked, and its frames keep their numbers."""
    m = make_motion("walk", seconds=1.0, fps=30.0)
    m.save(tmp_path / "m.npz")
    d = dict(np.load(tmp_path / "m.npz"))
    d["trans"][12:, 0] = 3e4  # 30 km away from frame 12 on
    np.savez(tmp_path / "far.npz", **d)
    skirt = str(SAMPLES / "garments" / "skirt.obj")
    for motion, extra, said in (
        ("far", [], "first at frame 12)"),
        ("far", ["--frames", "5:10"], "first at frame 12)"),
        ("far", ["--fps", "30"], "first at frame 12)"),
        ("far", ["--fps", "60"], "first at frame 23 at 60 fps (frame 12 as read, at 30 fps))"),  # 15 km at 11.5
        ("far", ["--fps", "15", "--frames", "2:4"], "first at frame 6 at 15 fps (frame 12 as read, at 30 fps))"),
        (
            "m",
            ["--fps", "60", "--frames", "0:99"],
            "outside the motion's 59 frames (expected 0 <= A < B <= 59, got 0:99)",
        ),
    ):
        args = ["run", "--garment", skirt, "--motion", str(tmp_path / f"{motion}.npz"), "-o", str(tmp_path / "o.pc2")]
        r = CliRunner().invoke(cli, [*args, *extra])
        assert r.exit_code == 1 and r.output.strip().endswith(said), (extra, r.output)
        assert motion == "m" or f"Error: {tmp_path / 'far.npz'}: the motion's root moves too far" in r.output, r.output
    assert not (tmp_path / "o.pc2").exists()


def test_a_cut_motion_files_numbering_is_said_where_frames_counts_from_0(tmp_path):
    """A motion cut by `motion export --frames 10:40` numbers its frames 10-39 and the outputs keep that numbering,
    while --frames counts from 0 (a new user's trial: `--frames 10:20` wrote frames 20-29 without a word, and
    `--frames 30:40` was refused as past the motion's 30 frames with nothing saying where they start).  `motion
    info` says the numbering; `run` says the frames it wrote when they differ from --frames; the refusal says both."""
    from segadeform.io.pc2 import read_pc2_header

    cut = tmp_path / "w1040.sgdm"
    bvh = SAMPLES / "motions" / "cmu" / "02_01_walk.bvh"
    r = CliRunner()
    res = r.invoke(cli, ["motion", "export", str(bvh), "--fps", "30", "--frames", "10:40", "-o", str(cut)])
    assert res.exit_code == 0, res.output
    res = r.invoke(cli, ["motion", "info", str(cut)])
    assert res.exit_code == 0 and "30 frames (numbered 10-39: run --frames counts them from 0)" in res.output
    base = ["run", "--garment", str(SAMPLES / "garments" / "dress.obj"), "--motion", str(cut), "--no-cache"]
    res = r.invoke(cli, [*base, "--frames", "10:20", "--effects", "none", "-o", str(tmp_path / "a.pc2")])
    assert res.exit_code == 0, res.output
    assert "10 frames (written as frames 20-29)," in res.output
    assert read_pc2_header(tmp_path / "a.pc2").start_frame == 20
    res = r.invoke(cli, [*base, "--frames", "30:40", "--effects", "none", "-o", str(tmp_path / "b.pc2")])
    assert res.exit_code == 1 and not (tmp_path / "b.pc2").exists()
    assert "outside the motion's 30 frames (counted from its first frame, 0; the file numbers them 10-39)" in (
        res.output
    )
    # a motion that starts at 0 says nothing more
    res = r.invoke(cli, [*base[:4], str(bvh), "--no-cache", "--frames", "2:4", "-o", str(tmp_path / "c.pc2")])
    assert res.exit_code == 0 and res.output.startswith("2 frames, "), res.output


def test_a_root_that_teleports_is_said_once_with_its_frame(tmp_path, caplog):
    """A root moved 100 m in one frame played without a word (a QA engineer's trial; the output follows it, as it
    should).  `run` now says where, once, counting the steps inside the frames it plays; a root that jumps and comes
    straight back is a glitch (the warning above), and a walk says nothing."""
    import dataclasses

    from segadeform.motion import root_cuts

    m = make_motion("walk", seconds=1.0, fps=30.0, seed=0)
    trans = m.trans.copy()
    trans[10:, 0] += 100.0
    trans[20:, 2] += 1.0  # a second cut: 1 m in a frame is 30 m/s
    cut = dataclasses.replace(m, trans=trans)
    assert [f for f, _ in root_cuts(cut)] == [10, 20] and abs(root_cuts(cut)[0][1] - 100.0) < 0.1
    assert root_cuts(m) == [] and root_cuts(cut, (11, 20)) == [] and [f for f, _ in root_cuts(cut, (15, None))] == [20]
    back = m.trans.copy()
    back[10, 0] += 2.0  # there and straight back: a glitch, not a cut
    assert root_cuts(dataclasses.replace(m, trans=back)) == []
    cut.save(tmp_path / "cut.npz")
    m.save(tmp_path / "walk.npz")
    for name, frames, said_n in (("cut", "0:30", 1), ("cut", "11:19", 0), ("walk", "0:30", 0)):
        args = ["run", "--garment", str(SAMPLES / "garments" / "skirt.obj"), "--motion", str(tmp_path / f"{name}.npz")]
        caplog.clear()
        with caplog.at_level(logging.WARNING):
            r = CliRunner().invoke(cli, [*args, "--frames", frames, "-o", str(tmp_path / "o.pc2"), "--no-cache"])
        assert r.exit_code == 0, r.output
        said = [rec.getMessage() for rec in caplog.records if "root moves" in rec.getMessage()]
        assert len(said) == said_n, (name, frames, said)
        if said_n:
            assert "cut.npz: its root moves 100 m in one frame, into frame 10" in said[0], said
            assert "(2 steps faster than 20 m/s)" in said[0], said
