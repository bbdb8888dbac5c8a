"""bench/tradeoffs.py: the frontier rule, and a tiny run end to end (table, plot, JSON)."""

from __future__ import annotations

import importlib.util
import json

import numpy as np
import pytest

from ..conftest import REPO


def _bench():
    spec = importlib.util.spec_from_file_location("tradeoffs_bench", REPO / "bench" / "tradeoffs.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def test_frontier_keeps_only_undominated_points():
    f = _bench().frontier
    pts = {"fast": (1.0, 5.0), "slow-good": (10.0, 1.0), "dominated": (10.0, 5.0), "mid": (3.0, 3.0),
           "tie": (3.0, 3.0)}
    assert f(pts) == ["fast", "mid", "tie", "slow-good"]


def test_tradeoffs_runs_on_a_tiny_dataset(synthetic_dataset, random_package, tmp_path):
    pytest.importorskip("matplotlib")
    out = tmp_path / "docs"
    assert _bench().main([str(synthetic_dataset), "--package", str(random_package), "-o", str(out)]) == 0
    md = (out / "accuracy-vs-time.md").read_text()
    for row in ("lbs", "all effects", "no wrinkles", "int8", "push-out 2 mm", "push-out 8 mm"):
        assert f"| {row}" in md or row in md, row
    data = json.loads((out / "accuracy-vs-time.json").read_text())
    assert data["frontier"] and set(data["frontier"]) <= set(data["rows"])
    assert all(np.isfinite(v["vertex_cm"]) and v["ms_per_frame"] > 0 for v in data["rows"].values())
    assert data["rows"]["lbs"]["vertex_cm"] < 1e-3  # the synthetic test sample is exactly LBS
    assert (out / "accuracy-vs-time.png").stat().st_size > 0 and (out / "accuracy-vs-time.svg").is_file()
