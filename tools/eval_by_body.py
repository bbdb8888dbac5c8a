"""The vertex error of models per body shape of a dataset split (issue #27: does the held-out body shape lose more?).

    .venv/bin/python tools/eval_by_body.py data/continuum --split test -m lbs=lbs -m lbs-smooth=lbs-smooth \
        -m shipped=samples/models/default -o by_body.json

Runs ``segadeform.train.evaluate.evaluate`` once per body (``__bN__`` in the sample ids) and prints and writes
``{body: {"n": samples, model: vertex_cm}}``.
"""

from __future__ import annotations

import argparse
import json
import re
import sys


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("dataset", nargs="+")
    ap.add_argument("--split", default="test")
    ap.add_argument("-m", "--model", action="append", required=True, help="NAME=SPEC, as segadeform eval takes")
    ap.add_argument("-o", "--output", required=True)
    a = ap.parse_args(argv)

    from segadeform.body import default_body_path, load_body
    from segadeform.dataset.roots import DatasetRoots
    from segadeform.runtime.predictor import PackagePredictor
    from segadeform.train.evaluate import evaluate
    from segadeform.train.predictors import make_predictors

    spec = dict(m.split("=", 1) for m in a.model)
    body = load_body(default_body_path())
    ids = DatasetRoots(a.dataset).ids(a.split)
    bodies = sorted({m.group(1) for i in ids if (m := re.search(r"__(b\d+)__", i))})
    out = {}
    for b in bodies:
        ds = DatasetRoots(a.dataset)
        mine = [i for i in ids if f"__{b}__" in i]
        every = ds.ids
        ds.ids = lambda split=None, _m=mine, _e=every: _m if split == a.split else _e(split)  # this body's samples
        res = evaluate(ds, body, make_predictors(spec, package=PackagePredictor), split=a.split)
        out[b] = {"n": len(mine), **{n: res["models"][n]["vertex_cm"] for n in spec}}
        print(b, json.dumps(out[b]), flush=True)
    with open(a.output, "w") as fh:
        json.dump(out, fh, indent=1)
    return 0


if __name__ == "__main__":
    sys.exit(main())
