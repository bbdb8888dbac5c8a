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
        make_predictors(
            {"blender": "simulation", "lbs": "lbs", "lbs-inpaint": "lbs-inpaint", "model": pkg},
            package=PackagePredictor,
        ),
        push_out_margin=0.004,
        cloth=["default", "iterations=1,stiffness=0.2"],
    )
    m = res["models"]
    want = {
        "blender",  # the simulator's own frames: no push-out or cloth rows
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
    assert m["blender"]["vertex_cm"] == m["blender"]["edge_mm"] == m["blender"]["jitter_mm"] == 0
    assert all(m[n]["pinched_pct"] <= m[n]["penetration_pct"] for n in m)
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


def test_pinched_cloth_is_penetrating_and_told_apart():
    """Where the body intersects itself (an arm pressed into the torso: two spheres, one mesh), a point in the torso
    whose nearest surface is the arm's buried skin is penetrating and pinched; a point in the torso nearer its own
    skin, or in the arm outside the torso, is penetrating and not pinched; a point outside is neither."""
    from types import SimpleNamespace

    from segadeform.body.collision import BodyCollider
    from segadeform.train.metrics import penetrating, penetrating_and_pinched
    from tests.body._shapes import pressed_spheres

    v, f = pressed_spheres(24, 16)
    ref = SimpleNamespace(collider=BodyCollider(v, f), posed=v[None])
    pts = np.array([[0.55, 0.0, 0.0], [-0.5, 0.0, 0.0], [1.1, 0.0, 0.0], [2.0, 0.0, 0.0], [0.0, 0.999, 0.0]])
    pen, pinched = penetrating_and_pinched(ref, pts, 0)
    assert pen.tolist() == [True, True, True, False, False]  # the last: within 2 mm of the skin
    assert pinched.tolist() == [True, False, False, False, False]
    assert penetrating(ref, pts, 0).tolist() == pen.tolist()


def test_a_face_across_a_limb_is_told_from_one_that_lies_on_it():
    """``through_faces``: a face whose corners are all outside a unit sphere on opposite sides of it (its centre deep
    inside) spans the limb; one outside, one with a corner inside (that is penetration, counted there) and one
    hugging the surface with its centre 2 mm inside (a coarse face wrapped round a limb) do not."""
    from types import SimpleNamespace

    from segadeform.body.collision import BodyCollider
    from segadeform.train.metrics import THROUGH_DEPTH, through_faces
    from tests.body._shapes import sphere

    v, f = sphere(48, 32)
    r = np.linalg.norm(v, axis=1).min()  # the mesh's inscribed radius, about 1
    pts = np.array(
        [
            [-1.2, -0.5, 0.0],
            [1.2, -0.5, 0.0],
            [0.0, 1.1, 0.0],  # across: centre at the sphere's middle
            [3.0, 0.0, 0.0],
            [4.0, 0.0, 0.0],
            [3.0, 1.0, 0.0],  # outside
            [0.0, 0.0, 0.0],
            [2.0, 0.0, 0.0],
            [2.0, 1.0, 0.0],  # a corner inside
        ]
    )
    c = r - 0.004  # the fourth: corners just outside, centre 2-3 mm inside the faceted sphere
    h = np.sqrt(1.03**2 - c**2)
    pts = np.vstack([pts, [[c, h, 0.0], [c, -h / 2, h * 0.866], [c, -h / 2, -h * 0.866]]])
    faces = np.arange(12).reshape(4, 3)
    ref = SimpleNamespace(collider=BodyCollider(v, f), posed=v[None], faces=faces)
    assert through_faces(ref, pts, 0).tolist() == [True, False, False, False]
    sd = ref.collider.query(pts[faces].mean(axis=1), v).signed_distance
    assert sd[0] < -0.5 and -THROUGH_DEPTH < sd[3] < -0.001  # the fourth's centre: inside, shallower than the depth
    assert (ref.collider.query(pts[[0, 1, 2, 9, 10, 11]], v).signed_distance > 0).all()  # their corners: outside


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
