"""`run --betas` refusals name the option (a new user's trial 6: `--betas 3` said "betas within about +-3" and
nothing of where the betas came from), in the flag form and over a scene, before anything is written."""

from __future__ import annotations

import pytest
from click.testing import CliRunner

from segadeform.cli.main import cli

from ..conftest import SAMPLES

DRESS = SAMPLES / "garments" / "dress.obj"
WALK = SAMPLES / "motions" / "walk.npz"


@pytest.mark.parametrize(
    ("betas", "says"),
    [
        ("3", "--betas: the body shape is not a human's height"),
        ("11", "--betas out of range"),
        ("nan", "--betas must be finite"),
        (",".join(["0"] * 17), "--betas: too many shape coefficients"),
    ],
)
@pytest.mark.parametrize("form", ["flags", "scene"])
def test_out_of_range_betas_name_the_option(tmp_path, betas, says, form):
    out = ["-o", str(tmp_path / "d.pc2"), "--frames", "0:2", "--no-cache", "--betas", betas]
    if form == "flags":
        args = ["run", "--garment", str(DRESS), "--motion", str(WALK), *out]
    else:
        args = ["run", str(SAMPLES / "scenes" / "dress_dance.toml"), *out]
    r = CliRunner().invoke(cli, args)
    lines = [ln for ln in r.output.splitlines() if ln.strip()]
    assert r.exit_code == 1 and len(lines) == 1 and lines[0].startswith(f"Error: {says}"), r.output
    assert list(tmp_path.iterdir()) == []


def test_force_still_takes_a_shape_no_human_has(tmp_path):
    r = CliRunner().invoke(
        cli,
        ["run", "--garment", str(DRESS), "--motion", str(WALK), "--frames", "0:1", "--no-cache", "--betas", "3"]
        + ["--force", "--effects", "lbs", "-o", str(tmp_path / "d.pc2")],
    )
    assert r.exit_code == 0 and "human's height" not in r.output, r.output


def test_betas_that_are_not_numbers_over_a_scene_are_a_usage_error(tmp_path):
    """(The scene form turned them to floats unguarded: a traceback.)"""
    r = CliRunner().invoke(
        cli, ["run", str(SAMPLES / "scenes" / "dress_dance.toml"), "-o", str(tmp_path / "d.pc2"), "--betas", "a,b"]
    )
    assert r.exit_code == 2 and "--betas must be comma-separated numbers, got 'a,b'" in r.output, r.output
    assert list(tmp_path.iterdir()) == []
