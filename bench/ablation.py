"""Ablation table: trained runs against LBS on a dataset's held-out split, each row with its training time.

    .venv/bin/python bench/ablation.py DATASET --run full=runs/full --run no_physics=runs/no_physics ... \
        [--reference full] [--push-out 0.004] -o docs/ablation

Every run is a ``segadeform train`` folder (``model.pt`` and ``train.json``).  One
:func:`segadeform.train.evaluate.evaluate` call measures them all with the baselines ``lbs`` (the body's
closest-point weights, the floor) and ``lbs-inpaint`` (inpainted weights, no learning) in the same run.
Writes ``ablation.md`` and ``ablation.json`` into the output folder and prints the table:
vertex error and its change against LBS, mid-band error (the SEGA vs PlainGAT comparison of the
paper's Table 2), penetration before any push-out, vertex error per garment type, training seconds,
steps and training samples.
"""

from __future__ import annotations

import argparse
import json
import platform
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]


def _commit() -> str:
    try:
        out = subprocess.run(["git", "-C", str(REPO), "rev-parse", "--short", "HEAD"], capture_output=True, text=True)
        dirty = subprocess.run(
            ["git", "-C", str(REPO), "status", "--porcelain", "--untracked-files=no"], capture_output=True, text=True
        ).stdout.strip()
        return out.stdout.strip() + (" (with uncommitted changes)" if dirty else "")
    except OSError:
        return "?"


def table(res: dict, runs: dict, floor: str = "lbs") -> str:
    models = res["models"]
    types = sorted({t for n in res["by_type"] for t in res["by_type"][n]})
    base = models[floor]["vertex_cm"]
    head = ["model", "vertex cm", "vs LBS", "mid band cm", "penetrating %", *types, "train s", "steps", "samples"]
    lines = ["| " + " | ".join(head) + " |", "|---" * len(head) + "|"]
    for n, m in models.items():
        info = runs.get(n.split(" + ")[0], {})
        row = [
            n,
            f"{m['vertex_cm']:.3f}",
            f"{100 * (m['vertex_cm'] / base - 1):+.1f} %",
            f"{m['mid_cm']:.3f}",
            f"{m['penetration_pct']:.2f}",
        ]
        row += [f"{res['by_type'][n][t]['vertex_cm']:.3f}" if t in res["by_type"][n] else "" for t in types]
        row += [
            f"{info['train_seconds']:.0f}" if "train_seconds" in info else "",
            str(info.get("steps", "")),
            str(info.get("samples", "")),
        ]
        lines.append("| " + " | ".join(row) + " |")
    return "\n".join(lines)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("dataset", type=Path)
    ap.add_argument("--run", action="append", default=[], metavar="NAME=RUN_DIR")
    ap.add_argument(
        "--package",
        action="append",
        default=[],
        metavar="NAME=PACKAGE",
        help="a model package (or PACKAGE:EFFECTS) evaluated beside the runs",
    )
    ap.add_argument("--split", default="test")
    ap.add_argument("--push-out", type=float, action="append", default=[])
    ap.add_argument("-o", "--output", type=Path, required=True)
    a = ap.parse_args(argv)

    from segadeform.body.model import default_body_path, load_body
    from segadeform.runtime.predictor import PackagePredictor
    from segadeform.train.evaluate import evaluate
    from segadeform.train.predictors import make_predictors

    body = load_body(default_body_path())
    models = {"lbs": "lbs", "lbs-inpaint": "lbs-inpaint"}
    runs = {}
    for spec in a.run:
        name, _, d = spec.partition("=")
        d = Path(d)
        info = json.loads((d / "train.json").read_text())
        runs[name] = {
            "train_seconds": info.get("train_seconds"),
            "steps": info.get("steps"),
            "samples": len(info.get("samples", [])),
            "config": info.get("config"),
            "run": str(d),
        }
        models[name] = str(d / "model.pt")
    for spec in a.package:
        name, _, p = spec.partition("=")
        models[name] = p
    t0 = time.perf_counter()
    res = evaluate(
        a.dataset,
        body,
        make_predictors(models, package=PackagePredictor),
        split=a.split,
        push_out_margin=a.push_out or None,
        progress=lambda sid: print("  " + sid, file=sys.stderr, flush=True),
    )
    took = time.perf_counter() - t0
    md = table(res, runs)
    cmd = " ".join(["python bench/ablation.py", *[str(x) for x in (argv if argv is not None else sys.argv[1:])]])
    doc = (
        f"# Ablation ({a.split} split of `{a.dataset.name}`, {len(res['samples'])} samples)\n\n"
        f"Made by `{cmd}` at {_commit()}; {took:.0f} s on {platform.machine()}.\n\n"
        "Vertex and band errors in cm against the Blender simulation; `vs LBS`: change of the vertex error "
        "against `lbs` (the body's closest-point weights) in the same run; penetrating: % of vertices deeper "
        "than 2 mm inside the body, before any push-out; per-type columns: vertex error; `train s`: the "
        "run's training time (train.json), `samples`: simulated training samples it saw.\n\n" + md + "\n\n"
        "Samples: " + ", ".join(res["samples"]) + "\n"
    )
    a.output.mkdir(parents=True, exist_ok=True)
    (a.output / "ablation.md").write_text(doc)
    (a.output / "ablation.json").write_text(
        json.dumps(
            {"eval": res, "runs": runs, "seconds": took},
            indent=1,
            default=lambda x: float(x) if isinstance(x, np.floating) else str(x),
        )
    )
    print(md)
    return 0


if __name__ == "__main__":
    sys.exit(main())
