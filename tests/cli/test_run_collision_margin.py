"""`run --collision-margin M`: the push-out's margin from the command line, as Node's and C++'s option (a user's
trial: the README gave the flag for every runtime, Python's run had only the scene's collision_margin)."""

from __future__ import annotations

import numpy as np
from click.testing import CliRunner

from segadeform.cli.main import cli
from segadeform.io import read_pc2

from ..conftest import SAMPLES

DRESS = SAMPLES / "garments" / "dress.obj"
WALK = SAMPLES / "motions" / "walk.npz"


def _run(tmp_path, name, *extra):
    out = tmp_path / f"{name}.pc2"
    args = ["run", "--garment", str(DRESS), "--motion", str(WALK), "-o", str(out), "--frames", "0:6", "--no-cache"]
    r = CliRunner().invoke(cli, [*args, *extra])
    return r, out


def test_the_margin_is_the_scenes_knob(tmp_path):
    r, plain = _run(tmp_path, "plain")
    assert r.exit_code == 0, r.output
    r, wide = _run(tmp_path, "wide", "--collision-margin", "0.02")
    assert r.exit_code == 0, r.output
    scene = tmp_path / "s.toml"
    scene.write_text(
        f'[garment]\nmesh = "{DRESS}"\n[motion]\nfile = "{WALK}"\nframes = "0:6"\n'
        f'[output]\npath = "{tmp_path}/sc.pc2"\n'
        "[effects]\ndynamics = true\nwrinkles = true\ncollisions = true\ncollision_margin = 0.02\n"
    )
    r = CliRunner().invoke(cli, ["run", str(scene), "--no-cache"])
    assert r.exit_code == 0, r.output
    a, b, c = (np.asarray(read_pc2(p).frames) for p in (plain, wide, tmp_path / "sc.pc2"))
    assert np.abs(b - a).max() > 0.005  # a wider margin moved vertices
    np.testing.assert_array_equal(b, c)  # as the scene's knob
    # over a scene's own margin
    r = CliRunner().invoke(
        cli, ["run", str(scene), "--no-cache", "-o", str(tmp_path / "sc4.pc2"), "--collision-margin", "0.004"]
    )
    assert r.exit_code == 0, r.output
    np.testing.assert_array_equal(np.asarray(read_pc2(tmp_path / "sc4.pc2").frames), a)


def test_a_bad_margin_or_no_stage_to_use_it_is_refused_before_any_output(tmp_path):
    for extra, says in (
        (["--collision-margin", "-0.01"], "collision_margin must be in [0, 1)"),
        (["--collision-margin", "0.01", "--effects=-collisions"], "neither collisions nor the cloth stage is on"),
    ):
        r, out = _run(tmp_path, "x", *extra)
        assert r.exit_code == 2 and says in r.output, r.output
        assert not out.exists()
