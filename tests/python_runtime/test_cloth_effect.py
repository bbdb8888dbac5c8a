"""The cloth effect in `segadeform run`: off unless named (a scene that does not name it builds nothing of it and calls
no kernel), on from a scene, --effects=+cloth or a preset's changes, its knobs from the scene and --cloth; the run's
frames are the stage's (contact included, no push-out after it), the same for any batch size, the per-garment setup
cached with the garment."""

from __future__ import annotations

import numpy as np
import pytest
from click.testing import CliRunner

from segadeform.body import load_body
from segadeform.cli.main import cli
from segadeform.io import read_pc2
from segadeform.motion import make_motion
from segadeform.runtime import ModelPackage
from segadeform.runtime.pipeline import Run
from segadeform.settings import DEFAULT_EFFECTS, Effects, load_scene, parse_effects
from segadeform.settings.cloth import ClothSettings
from tests.conftest import SAMPLES

BODY = SAMPLES / "bodies" / "default_body.npz"
SKIRT = SAMPLES / "garments" / "skirt.obj"


@pytest.fixture(scope="module")
def body():
    return load_body(BODY)


def _run(tmp_path, pkg, body, effects, *, batch=4, name="out.pc2", cache=False, frames=None):
    return Run(
        garment=SKIRT,
        motion=make_motion("dance", seconds=0.6, seed=3),
        package=ModelPackage(pkg),
        body=body,
        effects=effects,
        output=tmp_path / name,
        batch=batch,
        cache=cache,
        force=True,
        frames=frames,
    ).execute()


def test_off_unless_named():
    assert not DEFAULT_EFFECTS.cloth and not Effects().cloth
    assert not parse_effects("dqs,collisions").cloth and parse_effects("dqs,cloth").cloth
    assert parse_effects("+cloth", Effects(collisions=False)) == Effects(collisions=False, cloth=True)
    # the stage's contact replaces the push-out: collisions is neither named nor "off" beside it (a scene's trial:
    # `lbs+collisions+cloth` and `lbs+cloth; off: ..., collisions` ran the same frames)
    assert Effects(cloth=True).label() == "lbs+dynamics+wrinkles+cloth"
    assert Effects(cloth=True, collisions=False).label() == "lbs+dynamics+wrinkles+cloth"
    assert Effects(cloth=True, collisions=False, dynamics=False).off() == ["dynamics"]
    on = Effects(cloth=True, cloth_settings=ClothSettings(iterations=8))
    assert on.label().endswith("+cloth(iterations=8)") and "cloth" not in Effects().off()
    from segadeform.settings.presets import preset_effects

    assert not any(preset_effects(p).cloth for p in ("fast", "balanced"))
    assert preset_effects("fast", "+cloth").cloth


def test_scene_keys(tmp_path):
    base = f'[garment]\nmesh = "{SKIRT}"\n[motion]\nkind = "walk"\n[output]\npath = "{tmp_path / "o.pc2"}"\n'
    p = tmp_path / "s.toml"
    p.write_text(base + "[effects]\ncloth = true\ncloth_iterations = 8\ncloth_stretch = 0.05\ncloth_backstop = 0.0\n")
    e = load_scene(p).effects
    assert e.cloth and not e.collisions
    assert e.cloth_settings == ClothSettings(iterations=8, stretch=0.05, backstop=0.0)
    p.write_text(base + "[effects]\ncollisions = true\n")
    assert not load_scene(p).effects.cloth
    from segadeform.errors import FileFormatError

    for bad, msg in (
        ("cloth = true\ncloth_iterations = 0", "cloth iterations must be an integer"),
        ("cloth = true\ncloth_wind = 1", "unknown key effects.cloth_wind"),
        ("cloth = 1", "effects.cloth has the wrong type"),
        ('cloth = true\ncloth_stiffness = "high"', "effects.cloth_stiffness has the wrong type"),
        ("cloth = true\ncloth_backstop = -0.01", "cloth backstop must be a number in"),
    ):
        p.write_text(base + f"[effects]\n{bad}\n")
        with pytest.raises(FileFormatError, match=msg) as ei:
            load_scene(p)
        assert str(p) in str(ei.value)
        if "unknown key" not in msg and "wrong type" not in msg:  # a refused value names its line (a user's trial)
            assert ei.value.line == 8 + bad.count("\n"), (bad, ei.value.line)
    # knobs with the stage off did nothing, silently (a user's trial): refused as --cloth K=V is
    p.write_text(base + "[effects]\ncollisions = true\ncloth_iterations = 8\n")
    with pytest.raises(FileFormatError, match="sets cloth_iterations but the cloth stage is off") as ei:
        load_scene(p)
    assert ei.value.line == 9


def test_a_run_without_cloth_pays_nothing(tmp_path, random_package, body, monkeypatch):
    """No setup, no stage, no kernel call: every entry of segadeform.body.cloth a run could reach raises."""
    import segadeform.body.cloth as cloth

    def boom(*a, **k):
        raise AssertionError("the cloth stage was touched")

    for name in ("ClothStage", "garment_setup", "cloth_setup", "rest_signed_distance", "_load_kernel"):
        monkeypatch.setattr(cloth, name, boom)
    s = _run(tmp_path, random_package, body, Effects())
    assert s.cloth is None and s.stage_seconds["cloth"] == 0.0 and s.pushed_vertices > 0
    s = _run(tmp_path, random_package, body, Effects(collisions=False), name="b.pc2")
    assert s.cloth is None and s.stage_seconds["cloth"] == 0.0


def test_a_run_with_cloth(tmp_path, random_package, body, monkeypatch):
    cache = tmp_path / "cache"
    monkeypatch.setenv("SEGADEFORM_CACHE_DIR", str(cache))
    on = Effects(cloth=True)
    a = _run(tmp_path, random_package, body, on, batch=4, name="a.pc2", cache=True)
    assert a.cloth is not None and a.cloth["contacts"] > 0 and a.cloth["resets"] == 0
    assert a.pushed_vertices == 0 and a.stage_seconds["collisions"] == 0.0 and a.stage_seconds["cloth"] > 0
    assert len(list(cache.glob("C-*.npz"))) == 1  # the per-garment setup, cached with the garment
    _run(tmp_path, random_package, body, on, batch=1, name="b.pc2")
    fa, fb = read_pc2(tmp_path / "a.pc2").frames, read_pc2(tmp_path / "b.pc2").frames
    # any batch size: the frames of one long call (the deformer's float32 may differ in its last bit between batch
    # sizes: the stage's own batch invariance is exact, tests/body/test_cloth.py)
    np.testing.assert_allclose(fa, fb, rtol=0, atol=1e-6)
    pushed = _run(tmp_path, random_package, body, Effects(), name="p.pc2")
    fp = read_pc2(tmp_path / "p.pc2").frames
    assert pushed.pushed_vertices > 0 and np.abs(np.asarray(fa, np.float64) - fp).max() > 1e-3
    # a run that starts later (frames A:B, a render in chunks) steps the stage over the frames before A, writing
    # nothing: its frames are the whole run's (a user's trial: they differed by up to 7 mm at a chunk's start), and
    # it reports its own frames' counts
    late = _run(tmp_path, random_package, body, on, name="l.pc2", frames=(5, 18))
    assert late.frames == 13 and 0 < late.cloth["contacts"] < a.cloth["contacts"]
    fl = read_pc2(tmp_path / "l.pc2").frames
    assert fl.shape[0] == 13
    np.testing.assert_allclose(fl, fa[5:18], rtol=0, atol=1e-6)


def test_command_line(tmp_path, random_package):
    base = [
        "run",
        "--garment",
        str(SKIRT),
        "--motion",
        str(SAMPLES / "motions" / "walk.npz"),
        "--model",
        str(random_package),
        "--no-cache",
        "--frames",
        "0:6",
    ]
    r = CliRunner().invoke(
        cli, base + ["-o", str(tmp_path / "a.pc2"), "--effects=+cloth", "--cloth", "iterations=2,stiffness=0.5"]
    )
    assert r.exit_code == 0, r.output
    assert (
        "+cloth(iterations=2,stiffness=0.5)" in r.output
        and "cloth: " in r.output
        and "vertex-frames in contact" in r.output
        and "traced out by the backstop" in r.output
    )
    r = CliRunner().invoke(cli, base + ["-o", str(tmp_path / "b.pc2"), "--cloth", "iterations=2"])
    assert r.exit_code == 2 and "the stage is off" in r.output and not (tmp_path / "b.pc2").exists()
    r = CliRunner().invoke(cli, base + ["-o", str(tmp_path / "c.pc2"), "--effects=+cloth", "--cloth", "iterations=0"])
    assert r.exit_code == 2 and "cloth iterations must be an integer" in r.output and not (tmp_path / "c.pc2").exists()
    r = CliRunner().invoke(cli, base + ["-o", str(tmp_path / "d.pc2"), "--quality", "fast", "--effects=+cloth"])
    assert r.exit_code == 0 and "+cloth" in r.output, r.output
    # --quality replaces the scene's [effects], but a scene's own cloth knobs stay when both run the stage (as
    # documented in segadeform.settings.presets; tests/python_runtime/test_presets.py); --cloth applies on top
    scene = tmp_path / "s.toml"
    scene.write_text(
        f'[garment]\nmesh = "{SKIRT}"\n[motion]\nfile = "{SAMPLES / "motions" / "walk.npz"}"\nframes = "0:4"\n'
        f'[output]\npath = "{tmp_path / "e.pc2"}"\n[model]\npackage = "{random_package}"\n'
        "[effects]\ncloth = true\ncloth_iterations = 2\ncloth_stiffness = 0.5\n"
    )
    r = CliRunner().invoke(cli, ["run", str(scene), "--no-cache", "--quality", "best"])
    assert r.exit_code == 0 and "+cloth(iterations=2,stiffness=0.5)" in r.output, r.output
    r = CliRunner().invoke(
        cli,
        [
            "run",
            str(scene),
            "--no-cache",
            "--quality",
            "best",
            "--cloth",
            "iterations=3",
            "-o",
            str(tmp_path / "f.pc2"),
        ],
    )
    assert r.exit_code == 0 and "+cloth(iterations=3,stiffness=0.5)" in r.output, r.output
