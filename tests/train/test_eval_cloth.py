"""`segadeform eval` with the cloth stage: LBS, lbs-inpaint, a model, the model + push-out and the model + the cloth
stage at two settings in one run, with per-type vertex, normal, edge, penetration and stretch."""

from __future__ import annotations

import json

import numpy as np
import pytest

pytest.importorskip("torch")

from segadeform.cli.main import main
from segadeform.runtime.predictor import PackagePredictor
from segadeform.train.evaluate import cloth_names, evaluate
from segadeform.train.metrics import METRICS
from segadeform.train.predictors import make_predictors
from segadeform.train.report import markdown_table


def test_cloth_names():
    from segadeform.errors import InputError
    from segadeform.settings.cloth import ClothSettings

    assert cloth_names(None) == {}
    assert cloth_names("default") == {" + cloth": ClothSettings()}
    assert cloth_names(["default", "iterations=8,stiffness=0.5"]) == {
        " + cloth": ClothSettings(),
        " + cloth iterations=8,stiffness=0.5": ClothSettings(iterations=8, stiffness=0.5),
    }
    with pytest.raises(InputError, match="bad cloth settings"):
        cloth_names(["iterations=0"])


def test_evaluate_with_the_cloth_stage(synthetic_dataset, random_package, body):
    pkg = str(random_package)
    res = evaluate(
        synthetic_dataset,
        body,
        make_predictors({"lbs": "lbs", "lbs-inpaint": "lbs-inpaint", "model": pkg}, package=PackagePredictor),
        push_out_margin=0.004,
        cloth=["default", "iterations=1,stiffness=0.2"],
    )
    m = res["models"]
    want = {
        "lbs",
        "lbs-inpaint",
        "model",
        "lbs-inpaint + push-out",
        "model + push-out",
        "model + cloth",
        "model + cloth iterations=1,stiffness=0.2",
    }
    assert set(m) == want
    assert all(np.isfinite(m[n][k]) for n in m for k in METRICS)
    for n in ("model + cloth", "model + cloth iterations=1,stiffness=0.2"):
        assert m[n]["penetration_pct"] <= m["model"]["penetration_pct"] + 1e-9
        assert m[n]["ms_per_frame"] > m["model"]["ms_per_frame"]
        assert m[n]["vertex_cm"] != m["model"]["vertex_cm"]  # the stage changed the frames
    # per type: every metric, the largest stretch the largest over the samples
    bt = res["by_type"]["model + cloth"]
    assert set(bt) == {"skirt"} and {"edge_mm", "normal_deg", "max_strain_pct", "p99_strain_pct"} <= set(bt["skirt"])
    assert bt["skirt"]["max_strain_pct"] == m["model + cloth"]["max_strain_pct"] >= bt["skirt"]["p99_strain_pct"]
    md = markdown_table(res)
    assert "| skirt | model + cloth |" in md and "max stretch (%)" in md
    with pytest.raises(Exception, match="--cloth"):
        evaluate(synthetic_dataset, body, make_predictors({"x": f"{pkg}:+cloth"}, package=PackagePredictor))


def test_cli_eval_cloth(synthetic_dataset, random_package, tmp_path, capsys):
    out = tmp_path / "eval"
    assert (
        main(
            [
                "eval",
                str(synthetic_dataset),
                "-m",
                "lbs=lbs",
                "-m",
                f"model={random_package}",
                "--push-out",
                "0.004",
                "--cloth",
                "default",
                "--cloth",
                "iterations=2",
                "-o",
                str(out),
            ]
        )
        == 0
    )
    text = capsys.readouterr().out
    assert (
        "| model + cloth |" in text
        and "| model + cloth iterations=2 |" in text
        and "Per garment type, every metric" in text
    )
    res = json.loads((out / "eval.json").read_text())
    assert "model + cloth iterations=2" in res["models"]
    assert (
        main(["eval", str(synthetic_dataset), "-m", "lbs=lbs", "--cloth", "wind=1", "-o", str(tmp_path / "bad")]) == 1
    )
