"""Does a model give the same cloth when the motion faces another way?  Physics does: gravity is vertical, so a
motion turned about the vertical axis moves the garment the same way, turned.  A model whose motion input reads the
root's rotation in the world (``ModelConfig.motion_input = "pose"``, the paper's window) need not.

For each chosen sample of DATASET and each ``--model NAME=SPEC`` (as ``segadeform eval`` takes them), the motion is
turned by each ``--angle`` about +Y through the world origin (every root rotation R -> Q R, the root joint's
position p -> Q p), the model's frames are turned back by Q^T and compared with its frames on the motion as stored:
``moved`` is the mean vertex distance (cm), ``error`` the vertex error against the stored frames (cm) with the motion
as stored and turned.

    .venv/bin/python tools/heading_check.py data/continuum --split test --samples 8 \\
        -m shipped=samples/models/default.train/model.pt -m lbs=lbs-smooth-light -o heading.md
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import sys
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))


def turn_y(deg: float) -> np.ndarray:
    a = np.radians(deg)
    return np.array([[np.cos(a), 0.0, np.sin(a)], [0.0, 1.0, 0.0], [-np.sin(a), 0.0, np.cos(a)]])


def turned(s, body, q: np.ndarray):
    """Sample ``s`` with its motion turned by ``q`` about +Y through the origin (the stored frames are not turned)."""
    from segadeform.body.rotations import axis_angle_to_matrix, matrix_to_axis_angle

    poses = np.array(s.poses, np.float64)
    poses[:, :3] = matrix_to_axis_angle(q @ axis_angle_to_matrix(poses[:, :3]))
    j0 = body.rest_joints(s.betas if s.betas.size else None)[0][0]
    trans = (np.asarray(s.trans, np.float64) + j0) @ q.T - j0
    return dataclasses.replace(s, poses=poses, trans=trans)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("dataset", type=Path)
    ap.add_argument("--split", default="test")
    ap.add_argument("--samples", type=int, default=8, help="this many samples, evenly spaced over the split")
    ap.add_argument("--angle", type=float, action="append", default=[], help="degrees (default 90 and 180)")
    ap.add_argument("-m", "--model", action="append", default=[], help="NAME=SPEC as segadeform eval takes it")
    ap.add_argument("-o", "--output", type=Path, help="a markdown table (and .json beside it); never overwritten")
    a = ap.parse_args(argv)
    if a.output is not None and (a.output.exists() or a.output.with_suffix(".json").exists()):
        ap.error(f"{a.output}: exists; choose another name")
    from gt_spread import emit  # this folder (the script's own) is on the path

    from segadeform.body import default_body_path, load_body
    from segadeform.dataset.roots import as_roots
    from segadeform.runtime.predictor import PackagePredictor
    from segadeform.train.data import sample_asset
    from segadeform.train.predictors import make_predictor

    body = load_body(default_body_path())
    ds = as_roots(a.dataset)
    ids = sorted(ds.ids(a.split))
    if not ids:
        ap.error(f"{a.dataset}: no '{a.split}' samples")
    ids = ids[:: max(1, len(ids) // max(1, a.samples))][: a.samples]
    angles = a.angle or [90.0, 180.0]
    models = {}
    for spec in a.model:
        name, _, what = spec.partition("=")
        models[name] = make_predictor(name, what or name, package=PackagePredictor)
    rows = []
    for sid in ids:
        s = ds.load(sid)
        asset = sample_asset(ds, s, body, 32)
        gt = s.frames.astype(np.float64)
        for name, pred in models.items():
            base = pred.predict(s, body, asset).astype(np.float64)
            row = {"sample": sid, "model": name, "error": 100 * float(np.linalg.norm(base - gt, axis=-1).mean())}
            for deg in angles:
                q = turn_y(deg)
                back = pred.predict(turned(s, body, q), body, asset).astype(np.float64) @ q
                row[f"moved {deg:g}°"] = 100 * float(np.linalg.norm(back - base, axis=-1).mean())
                row[f"error {deg:g}°"] = 100 * float(np.linalg.norm(back - gt, axis=-1).mean())
            rows.append(row)
            print(json.dumps(row), file=sys.stderr, flush=True)
    cols = [k for k in rows[0] if k not in ("sample", "model")]
    md = ["| model | samples | " + " | ".join(f"{c} (cm)" for c in cols) + " |", "|---" * (2 + len(cols)) + "|"]
    for name in models:
        rs = [r for r in rows if r["model"] == name]
        md.append(f"| {name} | {len(rs)} | " + " | ".join(f"{np.mean([r[c] for r in rs]):.3f}" for c in cols) + " |")
    emit(md, rows, a.output)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
