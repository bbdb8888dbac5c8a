"""`--frames A:B` past the motion: one check (segadeform.motion.frame_range) and one message from run, simulate
and bundle, before any work (simulate: before the simulator starts, so no Blender is needed here)."""

from __future__ import annotations

import numpy as np
import pytest
from click.testing import CliRunner

from segadeform.cli.main import cli
from segadeform.errors import InputError
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
