"""segadeform run --quality: presets are data (segadeform.settings.presets), set the effects and margin, take signed
--effects changes on top and refuse a complete --effects list."""

from __future__ import annotations

import pytest
from click.testing import CliRunner

from segadeform.cli.main import cli
from segadeform.errors import InputError
from segadeform.settings import Effects
from segadeform.settings.cloth import ClothSettings
from segadeform.settings.presets import QUALITY_PRESETS, is_change_list, preset_effects
from tests.conftest import SAMPLES


def test_preset_table_and_rules():
    assert list(QUALITY_PRESETS) == ["fast", "balanced", "best"]
    for name, p in QUALITY_PRESETS.items():
        assert isinstance(p.effects, Effects) and p.why
        assert preset_effects(name) == p.effects
    assert preset_effects("fast", "+collisions") == Effects(
        **{**QUALITY_PRESETS["fast"].effects.__dict__, "collisions": True}
    )
    assert preset_effects("best", "dqs,-wrinkles").skinning == "dqs"
    assert not preset_effects("best", "dqs,-wrinkles").wrinkles
    # best runs the cloth stage (the measured frontier's lowest error, docs/accuracy-vs-time.md) at its defaults with
    # contact at 4 mm; taking it off gives the push-out back; the cheaper presets do not name it
    best = QUALITY_PRESETS["best"].effects
    assert best.cloth and best.cloth_settings == ClothSettings() and best.collision_margin == 0.004
    assert best.dynamics and best.wrinkles
    no_cloth = preset_effects("best", "-cloth")
    assert not no_cloth.cloth and no_cloth.collisions
    assert not QUALITY_PRESETS["fast"].effects.cloth and not QUALITY_PRESETS["balanced"].effects.cloth
    assert is_change_list("-wrinkles,+collisions") and is_change_list("dqs,-dynamics")
    assert not is_change_list("dqs,collisions") and not is_change_list("dqs") and not is_change_list("")
    for bad in ("dqs,collisions", "lbs"):
        with pytest.raises(InputError, match="complete effects list"):
            preset_effects("fast", bad)
    with pytest.raises(InputError, match="unknown quality preset"):
        preset_effects("ultra")


def _flags(tmp_path, package, *extra):
    return [
        "run",
        "--garment",
        str(SAMPLES / "garments" / "skirt.obj"),
        "--motion",
        str(SAMPLES / "motions" / "walk.npz"),
        "--frames",
        "0:4",
        "-o",
        str(tmp_path / "o.pc2"),
        "--model",
        str(package),
        "--no-cache",
        *extra,
    ]


def _label(e: Effects) -> str:
    off = e.off()
    return f"effects {e.label()}" + (f"; off: {', '.join(off)}" if off else "")


def test_run_quality_presets_pick_their_effects(tmp_path, random_package):
    for name, p in QUALITY_PRESETS.items():
        r = CliRunner().invoke(cli, _flags(tmp_path, random_package, "--quality", name))
        assert r.exit_code == 0, r.output
        assert f"(quality {name}: {_label(p.effects)};" in r.output
    # signed changes apply on top of the preset
    r = CliRunner().invoke(cli, _flags(tmp_path, random_package, "--quality", "fast", "--effects=+collisions,dqs"))
    e = preset_effects("fast", "+collisions,dqs")
    assert r.exit_code == 0 and f"(quality fast: {_label(e)};" in r.output
    # a complete list conflicts: a usage error naming both, nothing written
    out = tmp_path / "x.pc2"
    args = _flags(tmp_path, random_package, "--quality", "best", "--effects", "dqs,collisions")
    args[args.index(str(tmp_path / "o.pc2"))] = str(out)
    r = CliRunner().invoke(cli, args)
    assert r.exit_code == 2 and "--quality best" in r.output and "dqs,collisions" in r.output
    assert not out.exists()
    r = CliRunner().invoke(cli, _flags(tmp_path, random_package, "--quality", "ultra"))
    assert r.exit_code == 2


def test_quality_replaces_a_scenes_effects(tmp_path, random_package):
    scene = tmp_path / "s.toml"
    scene.write_text(
        f'[garment]\nmesh = "{SAMPLES / "garments" / "skirt.obj"}"\n[motion]\nkind = "walk"\n'
        f'seconds = 0.2\n[output]\npath = "{tmp_path / "o.pc2"}"\n[effects]\nskinning = "dqs"\n'
    )
    r = CliRunner().invoke(cli, ["run", str(scene), "--model", str(random_package), "--no-cache", "--quality", "best"])
    assert r.exit_code == 0, r.output
    assert f"(quality best: {_label(QUALITY_PRESETS['best'].effects)};" in r.output
    # the scene's own cloth knobs stay when the preset runs the stage too (--quality best dropped iterations = 6)
    assert QUALITY_PRESETS["best"].effects.cloth
    scene.write_text(scene.read_text() + "cloth = true\ncloth_iterations = 6\n")
    r = CliRunner().invoke(cli, ["run", str(scene), "--model", str(random_package), "--no-cache", "--quality", "best"])
    assert r.exit_code == 0, r.output
    assert "cloth(iterations=6)" in r.output, r.output


def test_best_is_the_lowest_error_the_docs_measured():
    """docs/accuracy-vs-time.json (bench/tradeoffs.py) maps every preset to its measured row: best's row is within
    0.01 cm of the lowest vertex error of any learned row at the cloth stage's default knobs (its sweeps may vary;
    the rows that vary another knob are measured on test samples, and a default taken from them would be tuned on
    the test split), and each row's effects are the preset's."""
    import json

    from tests.conftest import REPO

    doc = json.loads((REPO / "docs" / "accuracy-vs-time.json").read_text())
    assert set(doc["presets"]) == set(QUALITY_PRESETS)
    learned = {
        k: r
        for k, r in doc["rows"].items()
        if k != "lbs"
        and r.get("knob") not in ("model", "models", "simulator")  # (the bench names a variant's knob "model")
        and (r.get("cloth") in (None, "default") or str(r.get("cloth")).startswith("iterations="))
    }
    assert len(learned) > 20 and any(str(r.get("cloth")).startswith("gravity=") for r in doc["rows"].values())
    best = learned[doc["presets"]["best"]]
    assert best["vertex_cm"] <= min(r["vertex_cm"] for r in learned.values()) + 0.01
    eff = QUALITY_PRESETS["best"].effects
    assert best["effects"] == ",".join(["lbs"] + [n for n in ("dynamics", "wrinkles") if getattr(eff, n)])
    assert best.get("cloth") == "default" and best["margin"] == eff.collision_margin
