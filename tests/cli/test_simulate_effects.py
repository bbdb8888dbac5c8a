"""`simulate --effects` follows the rule of `run --effects` (complete list or signed changes); checked without
Blender: the settings are resolved before the simulator starts."""

from __future__ import annotations

import types

import pytest
from click.testing import CliRunner

from segadeform.cli.main import cli
from segadeform.errors import FileFormatError
from segadeform.settings.simulation import DEFAULT_EFFECTS, EFFECTS, parse_sim_effects

BASE = '[garment]\nmesh = "g.obj"\n[motion]\nkind = "walk"\nseconds = 0.2\n[output]\npath = "o.pc2"\n'


@pytest.fixture
def captured(monkeypatch):
    """Replace the simulator by a recorder of the settings it was given."""
    import segadeform.physics.scene_sim as scene_sim

    seen = {}

    def fake(scene, *, output=None, settings=None, sim_python=None, progress=None, guard=None, frames_from_scene=True):
        seen["settings"] = settings
        seen["body_output"] = scene.body_output
        res = types.SimpleNamespace(preroll_frames=0, seconds_per_frame=0.0, blender={"blender_version": "-"})
        return types.SimpleNamespace(frames=0, result=res, written=[])

    monkeypatch.setattr(scene_sim, "simulate_scene", fake)
    return seen


def _simulate(tmp_path, captured, table, *args):
    (tmp_path / "s.toml").write_text(BASE + table)
    captured.clear()
    r = CliRunner().invoke(cli, ["simulate", str(tmp_path / "s.toml"), *args])
    return r, captured.get("settings")


def test_complete_list_and_signed_changes(tmp_path, captured):
    table = '[simulate]\neffects = ["gravity", "pinning"]\n'
    r, st = _simulate(tmp_path, captured, table, "--effects=+wind,-pinning")
    assert r.exit_code == 0, r.output
    assert st.effects == ("gravity", "wind")
    r, st = _simulate(tmp_path, captured, table, "--effects", "body_collision,gravity")
    assert r.exit_code == 0 and st.effects == ("gravity", "body_collision")
    r, st = _simulate(tmp_path, captured, table, "--effects", "none")
    assert r.exit_code == 0 and st.effects == ()
    r, st = _simulate(tmp_path, captured, table)
    assert r.exit_code == 0 and st.effects == ("gravity", "pinning")


def test_scene_without_simulate_starts_from_the_default(tmp_path, captured):
    r, st = _simulate(tmp_path, captured, "", "--effects=-bending,+self_collision")
    assert r.exit_code == 0, r.output
    assert st.effects == tuple(e for e in EFFECTS if e in set(DEFAULT_EFFECTS) - {"bending"} | {"self_collision"})
    r, st = _simulate(tmp_path, captured, "")
    assert st.effects == DEFAULT_EFFECTS == ("gravity", "body_collision", "bending", "air_damping")


@pytest.mark.parametrize(
    "arg, message", [("gravity,-wind", "effects mix a complete list with changes"), ("+sparkles", "unknown effect")]
)
def test_bad_lists_are_errors_in_the_same_words_as_run(tmp_path, captured, arg, message):
    r, st = _simulate(tmp_path, captured, "", f"--effects={arg}")
    assert r.exit_code == 2 and message in r.output and st is None  # a command-line mistake, as run says it
    # run says the same about its own effects (before touching any file)
    r2 = CliRunner().invoke(
        cli,
        [
            "run",
            "--garment",
            "g.obj",
            "--motion",
            "m.bvh",
            "-o",
            str(tmp_path / "x.pc2"),
            f"--effects={arg.replace('gravity', 'dynamics').replace('wind', 'wrinkles')}",
        ],
    )
    assert r2.exit_code == 2 and message in r2.output


def test_parse_sim_effects():
    assert parse_sim_effects("wind,gravity") == ("gravity", "wind")
    assert parse_sim_effects("+wind") == DEFAULT_EFFECTS[:2] + ("bending", "air_damping", "wind")
    assert parse_sim_effects("-gravity", ("gravity", "pinning")) == ("pinning",)
    assert parse_sim_effects("none", ("gravity",)) == ()
    # an empty list is refused, as run's is (a scene's trial: simulate took "" as none, run kept the scene's)
    for text in ("", " , "):
        with pytest.raises(FileFormatError, match="an empty effects list"):
            parse_sim_effects(text, ("gravity",))


def test_body_out_moves_the_body_a_scene_names(tmp_path, captured):
    """A scene with [output] body that `run` had written could not be simulated: its body path was another command's
    output and `-o` moves only the garment.  `--body-out` moves the body too."""
    r, _ = _simulate(tmp_path, captured, 'body = "b.pc2"\n', "--body-out", str(tmp_path / "sim_body.usda"))
    assert r.exit_code == 0, r.output
    assert captured["body_output"] == tmp_path / "sim_body.usda"
    r, _ = _simulate(tmp_path, captured, 'body = "b.pc2"\n')
    assert r.exit_code == 0 and captured["body_output"].name == "b.pc2"
