"""Does the learned part move the prior by the right amount?  The shipped package's frames ``p + a (m - p)`` for a
prior ``p`` (``lbs-smooth-light``, the one its residual weights start from, or ``lbs-smooth``) and scales ``a``
around 1, on one split, with both priors in the same run (issue #27; docs/gpu-training.md, "Is the residual too
timid?").  Each model's frames are computed once per sample and mixed.

    .venv/bin/python tools/residual_scale.py data/continuum --split val -o runs/residual_scale_val.json
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

from segadeform.body import default_body_path, load_body
from segadeform.runtime.predictor import PackagePredictor
from segadeform.train.evaluate import evaluate
from segadeform.train.predictors import Predictor, make_predictor


class _Frames:
    """Each base model's frames of the sample being evaluated, computed once."""

    def __init__(self, body, specs: dict):
        self.body = body
        self.base = {n: make_predictor(n, s, package=PackagePredictor) for n, s in specs.items()}
        self.sample, self.frames = None, {}

    def __call__(self, name, s, asset):
        if self.sample is not s:
            self.sample, self.frames = s, {}
        if name not in self.frames:
            self.frames[name] = self.base[name].predict(s, self.body, asset)
        return self.frames[name]


class _Mix(Predictor):
    """``prior + a (model - prior)``: a = 0 is the prior, 1 the model."""

    def __init__(self, name, frames: _Frames, a: float, prior: str):
        self.name, self.spec, self.frames, self.a, self.prior = name, name, frames, a, prior

    def predict(self, s, body, asset):
        m, p = self.frames("model", s, asset), self.frames(self.prior, s, asset)
        return p + self.a * (m - p)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("dataset", type=Path)
    ap.add_argument("--split", default="val")
    ap.add_argument("--model", default="samples/models/default")
    ap.add_argument("-o", "--output", type=Path, required=True, help="JSON report (metrics per model and type)")
    args = ap.parse_args()
    body = load_body(default_body_path())
    frames = _Frames(body, {"model": args.model, "lbs-smooth": "lbs-smooth", "lbs-smooth-light": "lbs-smooth-light"})
    preds = {p: _Mix(p, frames, 0.0, p) for p in ("lbs-smooth", "lbs-smooth-light")}
    for a in (0.8, 1.0, 1.2, 1.4):
        preds[f"light a={a}"] = _Mix(f"light a={a}", frames, a, "lbs-smooth-light")
    for a in (0.8, 1.2, 1.4):
        preds[f"smooth a={a}"] = _Mix(f"smooth a={a}", frames, a, "lbs-smooth")
    res = evaluate(args.dataset, body, preds, split=args.split)
    args.output.parent.mkdir(parents=True, exist_ok=True)
    args.output.write_text(json.dumps({"models": res["models"], "by_type": res["by_type"]}, indent=1))
    types = sorted({t for d in res["by_type"].values() for t in d})
    print("| model | vertex (cm) | " + " | ".join(types) + " | penetrating (%) |")
    print("|---" * (len(types) + 3) + "|")
    for n, m in res["models"].items():
        per = " | ".join(f"{res['by_type'][n][t]['vertex_cm']:.3f}" for t in types)
        print(f"| {n} | {m['vertex_cm']:.3f} | {per} | {m['penetration_pct']:.2f} |")


if __name__ == "__main__":
    main()
