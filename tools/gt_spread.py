"""How far apart are two equally valid simulations of the same sample?  The floor under any model's vertex
error (issue #27).

For each chosen kept sample of DATASET (made from CONFIG by ``segadeform dataset make``), Blender runs again with
the settings of the attempt the sample was kept on, changed one way per variant:

* ``repeat``: nothing changed (is the simulator repeatable?);
* ``quality+K``: K more solver steps per frame (an equally valid solver setting);
* ``jitter``: every rest vertex of the garment (and of its A-posed cloth) moved by a seeded random offset of
  0.1 mm: a garment no one could tell from the one simulated;
* ``lead=K``: only the last K frames of the capture simulated before the clip (``dataset make`` simulates 1 s
  of it and drops it, so that the cloth enters the clip in motion; the model never sees those frames): how
  much the clip's frames depend on a history no input shows;
* ``self-collision``: the cloth also collides with itself (Blender's self collision, off in the dataset
  configs): not an equally valid run but a physical effect the ground truth leaves out -- how much it moves the
  frames, against the spread of the runs above.

Per sample it prints the mean vertex distance (cm) of each rerun to the stored frames, and the vertex error of
each model (``--model NAME=SPEC`` as ``segadeform eval`` takes them) against the stored frames, against each
rerun and against the mean of the runs (the stored one and the equally valid reruns, not ``self-collision``: a
crude estimate of the expected drape).  If two runs a solver cannot tell apart are D cm apart, no deterministic
predictor is much closer than about D / 2 to either; a model's error against the mean of the runs shows how much
of its error is that spread.

    .venv/bin/python tools/gt_spread.py data/continuum samples/datasets/continuum.toml --types skirt,dress \\
        --per-type 3 -m lbs=lbs -m lbs-smooth=lbs-smooth -m shipped=samples/models/default -j 2 -o spread.md

CPU: three Blender runs per sample (10-40 s each on two cores).
"""

from __future__ import annotations

import argparse
import json
import sys
import zlib
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))
JITTER_M = 1e-4


def rerun(cfg, dataset: Path, body, sid: str, meta: dict, variant: str, sim_python=None) -> np.ndarray:
    """Blender's frames (T, N, 3) for sample ``sid`` as ``dataset make`` made it, changed by ``variant``."""
    from bench.tradeoffs_measure import resimulate

    kw: dict = {"attempt": int(meta.get("attempt", 0)), "sim_python": sim_python}
    if variant.startswith("quality+"):
        g = next(g for g in cfg.garments if g.name == meta["garment"])
        kw["quality"] = cfg.attempt_settings(g, kw["attempt"]).quality + int(variant[len("quality+") :])
    elif variant == "jitter":
        n = int(meta["vertices"])
        d = np.random.default_rng(zlib.crc32(sid.encode())).normal(size=(n, 3))
        kw["offset"] = d * (JITTER_M / np.linalg.norm(d, axis=1, keepdims=True))
    elif variant.startswith("lead="):
        kw["lead"] = int(variant[len("lead=") :])
    elif variant == "self-collision":
        kw["effects"] = ("self_collision",)
    elif variant != "repeat":
        raise ValueError(f"unknown variant {variant!r}")
    return resimulate(cfg, dataset, body, sid, **kw)[0]


def emit(md: list[str], rows: list[dict], output: Path | None) -> None:
    """Print the markdown lines ``md``; with ``output``, write them there and ``rows`` as JSON beside it."""
    text = "\n".join(md)
    print(text)
    if output is not None:
        output.write_text(text + "\n")
        output.with_suffix(".json").write_text(json.dumps(rows, indent=1) + "\n")


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("dataset", type=Path)
    ap.add_argument("config", type=Path)
    ap.add_argument("--split", default="test")
    ap.add_argument("--types", default="skirt,dress,sleeved-dress,top")
    ap.add_argument("--per-type", type=int, default=2)
    ap.add_argument("--sample", action="append", default=[])
    ap.add_argument("--variants", default="repeat,quality+1,jitter")
    ap.add_argument("-m", "--model", action="append", default=[], help="NAME=SPEC as segadeform eval takes it")
    ap.add_argument("-j", "--jobs", type=int, default=1)
    ap.add_argument("-o", "--output", type=Path, help="a markdown table (and .json beside it)")
    a = ap.parse_args(argv)

    from segadeform.body import default_body_path, load_body
    from segadeform.dataset.config import load_dataset_config
    from segadeform.dataset.roots import DatasetRoots
    from segadeform.physics.setup import ensure_sim_python
    from segadeform.runtime.predictor import PackagePredictor
    from segadeform.train.data import sample_asset
    from segadeform.train.predictors import make_predictor

    body = load_body(default_body_path())
    cfg = load_dataset_config(a.config)
    ds = DatasetRoots([a.dataset])
    types = [t for t in a.types.split(",") if t]
    ids = list(a.sample)
    if not ids:
        by_type: dict = {}
        for sid in sorted(ds.ids(a.split)):
            by_type.setdefault(ds.load(sid).meta.get("type"), []).append(sid)
        for t in types:
            ids += by_type.get(t, [])[: a.per_type]
    variants = [v for v in a.variants.split(",") if v]
    models = {}
    for spec in a.model:
        name, _, what = spec.partition("=")
        models[name] = make_predictor(name, what or name, package=PackagePredictor)
    sim_python = ensure_sim_python(None)

    rows = []
    for sid in ids:
        s = ds.load(sid)
        stored = s.frames.astype(np.float64)
        t = len(stored)
        with ThreadPoolExecutor(max(1, a.jobs)) as ex:
            futs = {v: ex.submit(rerun, cfg, a.dataset, body, sid, s.meta, v, sim_python) for v in variants}
            runs = {v: f.result()[:t] for v, f in futs.items()}
        valid = [x for v, x in runs.items() if v != "self-collision"]  # equally valid runs only
        mean = (stored + sum(valid)) / (1 + len(valid))
        row = {"sample": sid, "type": s.meta.get("type"), "attempt": int(s.meta.get("attempt", 0))}
        for v, x in runs.items():
            row[f"{v} vs stored"] = 100 * float(np.linalg.norm(x - stored, axis=2).mean())
        asset = sample_asset(a.dataset, s, body, 32) if models else None
        for name, pred in models.items():
            y = pred.predict(s, body, asset).astype(np.float64)[:t]
            row[f"{name} vs stored"] = 100 * float(np.linalg.norm(y - stored, axis=2).mean())
            for v, x in runs.items():
                row[f"{name} vs {v}"] = 100 * float(np.linalg.norm(y - x, axis=2).mean())
            row[f"{name} vs mean"] = 100 * float(np.linalg.norm(y - mean, axis=2).mean())
        rows.append(row)
        print(json.dumps(row), file=sys.stderr, flush=True)

    cols = [k for k in rows[0] if k not in ("sample", "type", "attempt")] if rows else []
    groups = {}
    for r in rows:
        groups.setdefault(r["type"], []).append(r)
    groups["all"] = rows
    md = ["| sample | type | attempt | " + " | ".join(cols) + " |", "|---" * (3 + len(cols)) + "|"]
    for r in rows:
        md.append(f"| {r['sample']} | {r['type']} | {r['attempt']} | " + " | ".join(f"{r[c]:.3f}" for c in cols) + " |")
    md += ["", "| type | samples | " + " | ".join(cols) + " |", "|---" * (2 + len(cols)) + "|"]
    for k, rs in groups.items():
        md.append(f"| {k} | {len(rs)} | " + " | ".join(f"{np.mean([r[c] for r in rs]):.3f}" for c in cols) + " |")
    emit(md, rows, a.output)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
