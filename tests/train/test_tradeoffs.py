"""bench/tradeoffs.py (its parts imported as modules: bench.tradeoffs_measure, bench.tradeoffs_render): the
frontier rule, the row plan, and a tiny run end to end over every knob (table,
presets, the simulator's axis with a stand-in simulator, plot, JSON)."""

from __future__ import annotations

import json

import numpy as np
import pytest

from bench import tradeoffs, tradeoffs_measure, tradeoffs_render


def test_frontier_keeps_only_undominated_points():
    f = tradeoffs_render.frontier
    pts = {"fast": (1.0, 5.0), "slow-good": (10.0, 1.0), "dominated": (10.0, 5.0), "mid": (3.0, 3.0), "tie": (3.0, 3.0)}
    assert f(pts) == ["fast", "mid", "tie", "slow-good"]


def test_every_preset_is_a_planned_row_with_its_effects_and_margin():
    from segadeform.settings.presets import QUALITY_PRESETS

    b = tradeoffs_measure
    rows, presets = b.plan_rows("PKG", "Q8", {"wide": "W"}, fp16="H")
    names = [r.name for r in rows]
    assert len(names) == len(set(names))
    by = {r.name: r for r in rows}
    for r in rows:  # a push-out row follows the row it pushes out
        if r.base is not None:
            assert names.index(r.base) < names.index(r.name) and by[r.base].spec == r.spec
    assert set(presets) == set(QUALITY_PRESETS)
    for name, rn in presets.items():
        e, r = QUALITY_PRESETS[name].effects, by[rn]
        assert r.spec == "PKG" and r.effects == b.effects_key(e)
        assert r.margin == (e.collision_margin if e.collisions or e.cloth else None)
        assert r.cloth == b.cloth_key(e)
    assert {"K=4", "N*=16", "batch 1", "garment 1/4 res", "wide + push-out 4 mm", "int8", "fp16 weights"} <= set(names)
    # the cloth stage: sweeps 1, 2, 4 (its default), 8, 16, two stiffnesses and the backstop off on all effects, its
    # defaults on every other effects row
    cloth = {r.name: r.cloth for r in rows if r.knob == "cloth"}
    assert cloth == {
        f"all effects + cloth {c}": c
        for c in (
            "iterations=1",
            "iterations=2",
            "default",
            "iterations=8",
            "iterations=16",
            "stiffness=0.5",
            "stiffness=0.2",
            "backstop=0",
        )
    } | {f"{n} + cloth default": "default" for n in ("no wrinkles", "no dynamics", "static, no wrinkles", "dqs")} | {
        f"all effects + cloth default, contact {m} mm": "default" for m in (2, 8)
    }
    assert all(by[n].base == n.split(" + cloth")[0] for n in cloth)
    assert {n: by[n].margin for n in cloth if by[n].margin != 0.004} == {
        "all effects + cloth default, contact 2 mm": 0.002,
        "all effects + cloth default, contact 8 mm": 0.008,
    }
    # every other knob of the stage (run --cloth's) at one other value: the bench's default --cloth-knobs
    from bench.tradeoffs import CLOTH_KNOBS
    from segadeform.settings.cloth import CLOTH_KNOBS as KNOBS

    more, _ = b.plan_rows("PKG", None, {}, cloth_knobs=tuple(CLOTH_KNOBS.split(";")))
    varied = {r.cloth.split("=")[0] for r in more if r.knob == "cloth" and r.cloth != "default"}
    assert varied == set(KNOBS), set(KNOBS) - varied


def test_tradeoffs_runs_on_a_tiny_dataset(synthetic_dataset, random_package, tmp_path):
    pytest.importorskip("matplotlib")
    out = tmp_path / "docs"
    calls = []

    def fake_simulator(sid, quality):  # a simulator whose error falls as 1/quality and whose cost grows with it
        from segadeform.dataset.store import load_sample

        calls.append((sid, quality))
        x = load_sample(synthetic_dataset, sid).frames.astype(np.float64)
        return x + 0.01 / quality, 0.01 * quality

    b = tradeoffs
    argv = [
        str(synthetic_dataset),
        "--package",
        str(random_package),
        "--model",
        f"again={random_package}",
        "-o",
        str(out),
        "--repeats",
        "1",
        "--threads-all",
        "2",
        "--ks",
        "4",
        "--n-stars",
        "16",
        "--batches",
        "3",
        "--resolutions",
        "1/2,4x",
        "--sim-qualities",
        "2,5",
        "--sim-reference",
        "20",
    ]
    assert b.main(argv, _simulate=fake_simulator) == 0
    md = (out / "accuracy-vs-time.md").read_text()
    data = json.loads((out / "accuracy-vs-time.json").read_text())
    rows = data["rows"]
    for row in (
        "lbs",
        "all effects",
        "no wrinkles",
        "dqs",
        "int8",
        "again",
        "all effects + push-out 2 mm",
        "all effects + push-out 8 mm",
        "again + push-out 4 mm",
        "batch 3",
        "K=4",
        "N*=16",
        "garment 1/2 res",
        "garment 4x res",
        "all effects + cloth default",
        "all effects + cloth iterations=1",
        "all effects + cloth stiffness=0.2",
    ):
        assert row in rows and f"| {row} |" in md, row
    assert data["frontier"] and set(data["frontier"]) <= set(rows) and set(data["frontier_2t"]) <= set(rows)
    for v in rows.values():
        assert all(np.isfinite(v[k]) for k in data["metrics"] + ["setup_ms"])
        assert v["ms_per_frame"] > 0 and v["ms_per_frame_all"] > 0
    assert rows["lbs"]["vertex_cm"] < 1e-3  # the synthetic test sample is exactly LBS
    # the same package under another name predicts the same; a batch changes only the time
    assert rows["again"]["vertex_cm"] == pytest.approx(rows["all effects"]["vertex_cm"], rel=1e-5)
    assert data["per_sample"]["batch 3"]["skirt__b0__swing"].get("same_as") == "all effects"
    # push-out leaves nothing deeper than 2 mm
    assert rows["all effects + push-out 4 mm"]["penetration_pct"] <= rows["all effects"]["penetration_pct"]
    assert rows["all effects + push-out 4 mm"]["penetration_pct"] < 1.0
    for n in (n for n in rows if "+ cloth" in n):  # the cloth stage's rows: its own contact, timed on top
        base = n.split(" + cloth")[0]  # the row it runs on: timed on top of that row's
        assert rows[n]["penetration_pct"] < 1.0 and rows[n]["ms_per_frame"] > rows[base]["ms_per_frame"]
        assert rows[n]["cloth"] and rows[n]["max_strain_pct"] >= 0
    # the subdivided garment carries back exactly the vertices it was made from: a close prediction
    assert abs(rows["garment 4x res"]["vertex_cm"] - rows["all effects"]["vertex_cm"]) < 0.5
    assert (
        data["per_sample"]["garment 1/2 res"]["skirt__b0__swing"]["vertices"]
        < data["per_sample"]["all effects"]["skirt__b0__swing"]["vertices"]
    )
    # presets: each names a row, with its error and frames per second in the docs
    assert set(data["presets"]) == {"fast", "balanced", "best"} and set(data["presets"].values()) <= set(rows)
    assert "## Presets" in md and "| fast |" in md and "fps" in md
    # the simulator's axis: reference first, then each quality; errors fall with quality, speed-ups measured
    sim = data["simulator"]
    assert [q for _, q in calls] == [20, 2, 5] and sim["sample"] == "skirt__b0__swing"
    assert sim["qualities"]["2"]["vertex_cm"] > sim["qualities"]["5"]["vertex_cm"] > 0
    assert sim["qualities"]["20"]["vertex_cm"] == 0.0
    lrn = sim["learned"]
    assert "lbs" in lrn and set(data["presets"].values()) <= set(lrn)  # every row against the reference
    r = lrn[data["presets"]["fast"]]
    assert r["speedup"]["20"] == pytest.approx(1e3 * 0.2 / r["ms_per_frame"])
    assert "simulator's quality axis" in md and "Blender quality 2" in md
    assert f"| fast ({data['presets']['fast']}) |" in md
    assert (out / "accuracy-vs-time.png").stat().st_size > 0 and (out / "accuracy-vs-time.svg").is_file()
    # the docs come back the same from the JSON alone (no measuring)
    (out / "accuracy-vs-time.md").unlink()
    assert b.main([str(synthetic_dataset), "--package", str(random_package), "-o", str(out), "--redraw"]) == 0
    assert (out / "accuracy-vs-time.md").read_text() == md
