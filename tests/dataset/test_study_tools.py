"""The simulator-study tools: the study config is what its writer writes, and the paired count is right."""

from __future__ import annotations

import json
import subprocess
import sys

import pytest

from ..conftest import SAMPLES

TOOLS = SAMPLES.parent / "tools"


@pytest.mark.parametrize(
    "tool, args, config",
    [
        ("mh_shirt_study.py", [], "mh_shirts.toml"),
        ("kind_study.py", [], "kinds.toml"),
        ("kind_study.py", ["--fallback", "quality=20,collision_quality=4"], "kinds_fallback.toml"),
        (
            "kind_study.py",
            ["--fallback", "quality=20,collision_quality=4", "--fallback", "quality=40,collision_quality=4"],
            "kinds_fallback2.toml",
        ),
    ],
)
def test_a_study_config_is_what_its_tool_writes(tool, args, config):
    cmd = [sys.executable, str(TOOLS / tool), *args]
    out = subprocess.run(cmd, check=True, capture_output=True, text=True).stdout
    assert out == (SAMPLES / "datasets" / "studies" / config).read_text()


def test_the_fallback_study_is_the_kind_study_with_its_fallbacks():
    """Same samples, same attempt-0 specs (a copy of data/kinds is continued, only its rejections simulated again)."""
    from segadeform.dataset import sample_plan
    from segadeform.dataset.config import load_dataset_config
    from segadeform.dataset.make import sample_spec

    base = load_dataset_config(SAMPLES / "datasets" / "studies" / "kinds.toml")
    fb = load_dataset_config(SAMPLES / "datasets" / "studies" / "kinds_fallback.toml")
    assert fb.fallbacks == ((("collision_quality", 4), ("quality", 20)),) and fb.simulate == base.simulate
    plan = sample_plan(fb)
    assert [p.id for p in plan] == [p.id for p in sample_plan(base)]
    assert all(sample_spec(fb, p) == sample_spec(base, p) for p in plan)


def test_the_kind_study_has_every_kind_once_on_the_same_training_captures():
    from segadeform.dataset.config import load_dataset_config

    cfg = load_dataset_config(SAMPLES / "datasets" / "studies" / "kinds.toml")
    kinds = [g.kind for g in cfg.garments]
    assert {"dress", "sleeved-dress", "skirt", "tshirt", "tank", "trousers", "shorts", "jumpsuit"} <= set(kinds)
    assert all(g.split == "train" for g in cfg.garments) and all(m.split == "train" for m in cfg.motions)
    assert all(m.file for m in cfg.motions) and cfg.order == "body-major"


def test_study_pairs_counts_pairs_and_tests_the_discordant_ones(tmp_path):
    """Two garments in two arms on four motions; one sample made twice counts as last finished; a garment made in
    one arm only has no pair."""
    rows = []
    kept = {  # (garment, motion) -> kept
        **{("a", m): m in ("m0", "m1") for m in ("m0", "m1", "m2", "m3")},
        **{("a-coarse", m): m != "m3" for m in ("m0", "m1", "m2", "m3")},
        **{("b", m): False for m in ("m0", "m1", "m2", "m3")},
        **{("b-coarse", m): True for m in ("m0", "m1", "m2", "m3")},
        ("c", "m0"): True,
    }
    for (g, m), k in kept.items():
        rows.append(
            {"id": f"{g}__b0__{m}", "garment": g, "body": 0, "motion": m, "status": "kept" if k else "rejected"}
            | ({} if k else {"reasons": ["strain 2.1 > 1.0 on 0.3% of edges > 0.1%"]})
        )
    rows.insert(0, {**rows[8], "status": "kept"})  # b__m0 first kept, then rejected: rejected counts
    (tmp_path / "log.jsonl").write_text("\n".join(json.dumps(r) for r in rows) + "\n")
    out = subprocess.run(
        [sys.executable, str(TOOLS / "study_pairs.py"), str(tmp_path)], check=True, capture_output=True, text=True
    ).stdout
    lines = {ln.split()[0]: ln.split()[1:] for ln in out.splitlines() if ln and not ln.startswith(("garment", "rej"))}
    assert lines["a"] == ["4", "2", "3", "0", "1", "1.000"]
    assert lines["b"] == ["4", "0", "4", "0", "4", "0.125"]  # 4 of 4 discordant one way: p = 2 / 2^4
    assert lines["(all)"] == ["8", "2", "7", "0", "5", "0.062"]
    assert "c" not in lines
    assert "rejections (plain): strain 6" in out and "rejections (changed): strain 1" in out


def test_kind_study_report_counts_only_clips_every_garment_finished(tmp_path):
    """Two clips made for all ten garments, a third for one only (left out); a procedural entry's draw
    (``dress-0``) counts as its entry; kinds sum their garments."""
    sys.path.insert(0, str(TOOLS))
    try:
        from kind_study import GARMENTS
    finally:
        sys.path.remove(str(TOOLS))
    procedural = {"dress", "skirt", "tshirt", "jacket", "trousers-fit", "shorts-fit"}
    rows = []
    for m in ("m0", "m1"):
        for name, _ in GARMENTS:
            g = f"{name}-0" if name in procedural else name
            kept = not (m == "m1" and name in ("tank", "trousers-fit"))
            rows.append(
                {"id": f"{g}__b0__{m}", "garment": g, "body": 0, "motion": m, "status": "kept" if kept else "rejected"}
                | ({} if kept else {"reasons": ["penetration 2.1% of vertices > 1.00%"]})
            )
    rows.append({"id": "tank__b0__m2", "garment": "tank", "body": 0, "motion": "m2", "status": "rejected"})
    (tmp_path / "log.jsonl").write_text("\n".join(json.dumps(r) for r in rows) + "\n")
    out = subprocess.run(
        [sys.executable, str(TOOLS / "kind_study.py"), "--report", str(tmp_path)],
        check=True,
        capture_output=True,
        text=True,
    ).stdout
    assert out.startswith("2 clips finished by all 10 garments")
    lines = {ln[:22].strip(): ln[22:].split() for ln in out.splitlines()[1:] if "kept / made" not in ln}
    assert lines["dress"][:3] == ["2", "/", "2"]
    assert lines["tank"][:4] == ["1", "/", "2", "50"] and lines["tank"][4:] == ["penetration", "1"]
    assert lines["tops"][:3] == ["7", "/", "8"] and lines["trousers"][:3] == ["3", "/", "4"]
