"""One rule for effects, end to end: a scene runs the stages it names and nothing else."""

import numpy as np
import pytest
from click.testing import CliRunner

from segadeform.cli.main import cli
from tests.conftest import SAMPLES


def test_scene_runs_only_named_effects(tmp_path, random_package):
    scene = tmp_path / "s.toml"
    scene.write_text(
        f'[garment]\nmesh = "{SAMPLES / "garments" / "skirt.obj"}"\n[motion]\nkind = "walk"\n'
        f'seconds = 0.3\n[output]\npath = "{tmp_path / "o.pc2"}"\n[effects]\nskinning = "dqs"\n'
    )
    r = CliRunner().invoke(cli, ["run", str(scene), "--model", str(random_package), "--no-cache"])
    assert r.exit_code == 0, r.output
    assert "effects dqs; off: dynamics, wrinkles, collisions" in r.output
    assert "graph deformer_dqs_nowrinkles_static" in r.output and f"wrote {tmp_path / 'o.pc2'}" in r.output
    # the command line's complete list replaces the scene's set; signed items change it
    r = CliRunner().invoke(
        cli, ["run", str(scene), "--model", str(random_package), "--no-cache", "--effects", "lbs,wrinkles"]
    )
    assert r.exit_code == 0 and "effects lbs+wrinkles; off: dynamics, collisions" in r.output
    for empty in ("", " , "):  # "" kept the scene's effects and " , " turned every one off (a scene's trial)
        r = CliRunner().invoke(cli, ["run", str(scene), "--model", str(random_package), "--effects", empty])
        assert r.exit_code == 2 and "an empty effects list" in r.output, r.output
        # the same without a scene (--garment/--motion): "" ran every effect there (a test that refused the run
        # for another reason hid it)
        flags = ["run", "--garment", str(SAMPLES / "garments" / "skirt.obj"), "--motion", "walk"]
        r = CliRunner().invoke(
            cli, [*flags, "--model", str(random_package), "-o", str(tmp_path / "f.pc2"), "--effects", empty]
        )
        assert r.exit_code == 2 and "an empty effects list" in r.output, r.output
        assert not (tmp_path / "f.pc2").exists()
    r = CliRunner().invoke(
        cli, ["run", str(scene), "--model", str(random_package), "--no-cache", "--effects=+dynamics"]
    )
    assert r.exit_code == 0 and "effects dqs+dynamics; off: wrinkles, collisions" in r.output
    assert "collisions:" not in r.output  # a stage that did not run reports nothing
    # the push-out's count, as the Node and C++ runtimes report it (a user's trial: Python said nothing)
    r = CliRunner().invoke(
        cli, ["run", str(scene), "--model", str(random_package), "--no-cache", "--effects=+collisions"]
    )
    assert r.exit_code == 0 and "vertex-frames pushed out" in r.output, r.output
    n = int(r.output.split("collisions: ")[1].split()[0])
    assert n > 0  # the walk's skirt, pushed out of the body in some frames


def test_frames_past_the_motion_are_an_error(tmp_path, random_package):
    r = CliRunner().invoke(
        cli,
        [
            "run",
            "--garment",
            str(SAMPLES / "garments" / "skirt.obj"),
            "--motion",
            str(SAMPLES / "motions" / "walk.npz"),
            "-o",
            str(tmp_path / "o.pc2"),
            "--model",
            str(random_package),
            "--no-cache",
            "--frames",
            "50:100",
        ],
    )
    assert r.exit_code == 1 and "frame range" in r.output and "90" in r.output
    assert not (tmp_path / "o.pc2").exists()


def test_a_motion_far_from_the_floor_is_said(tmp_path, random_package, caplog):
    """A user's trial: walk.npz re-saved without its 'name' is read in SMPL's translation convention and the body
    ran 1.26 m below the floor, silently.  A run now says so, and --floor stands it on the floor."""
    import numpy as np

    d = dict(np.load(SAMPLES / "motions" / "walk.npz", allow_pickle=False))
    d.pop("name")
    np.savez(tmp_path / "m.npz", **d)
    base = ["run", "--garment", str(SAMPLES / "garments" / "skirt.obj"), "--model", str(random_package), "--no-cache"]
    base += ["--frames", "0:2", "--force"]

    def said(*args):
        caplog.clear()
        with caplog.at_level("WARNING", logger="segadeform.runtime.pipeline"):
            r = CliRunner().invoke(cli, base + list(args))
        assert r.exit_code == 0, r.output
        return " ".join(x.getMessage() for x in caplog.records if "the floor in most frames" in x.getMessage())

    msg = said("--motion", str(tmp_path / "m.npz"), "-o", str(tmp_path / "a.pc2"))
    assert "m.npz: its feet are 1.2" in msg and "m below the floor" in msg, msg
    assert said("--motion", str(tmp_path / "m.npz"), "--floor", "-o", str(tmp_path / "b.pc2")) == ""
    assert said("--motion", str(SAMPLES / "motions" / "walk.npz"), "-o", str(tmp_path / "c.pc2")) == ""


def test_effects_and_cloth_settings_refuse_wrong_types_with_the_projects_error():
    """A library user's trial: ``Effects(collision_margin="0.004")`` was a TypeError, ``Effects(cloth="no")`` ran the
    cloth stage, and both classes raised plain ValueError/TypeError rather than the project's error."""
    from segadeform.errors import InputError
    from segadeform.settings import Effects
    from segadeform.settings.cloth import ClothSettings

    for bad, words in (
        (dict(collision_margin="0.004"), "collision_margin must be in"),
        (dict(collision_margin=True), "collision_margin must be in"),
        (dict(collision_margin=float("nan")), "collision_margin must be in"),
        (dict(cloth="no"), "cloth must be True or False"),
        (dict(dynamics=1), "dynamics must be True or False"),
        (dict(skinning="LBS"), "skinning must be 'lbs' or 'dqs'"),
        (dict(cloth_settings={"iterations": 4}), "cloth_settings must be a ClothSettings"),
    ):
        with pytest.raises(InputError, match=words):
            Effects(**bad)
    assert Effects(collision_margin=0, cloth=np.bool_(True)).cloth is True
    with pytest.raises(InputError, match=r"cloth iterations must be an integer in \[1, 64\].*got 0"):
        ClothSettings(iterations=0)
