"""Does the ground truth's hem ride up and stay up, and how much of each model's error is there?  (issue #27)

For every skirt and dress of a split, each frame of Blender's cloth is pulled back to the rest pose through the
``smooth`` prior's skinning (the blended joint rotation of each vertex inverted, as ``tools/drape_oracle.py``
does), and the hem -- the lowest tenth of the rest vertices -- is measured for how far it rose above its rest
height.  A frame whose hem rose more than ``--threshold`` cm (default 10) is a *hem-up* frame: the skirt or dress
bunched up on the thighs or hips.  Every model (``-m NAME=SPEC`` as ``segadeform eval`` takes them) is then
reported on the hem-up frames, on the others, and on the samples with no hem-up frame at all, beside its share of
the error.  Vertex error in cm, averaged over frames (``segadeform eval`` averages samples first, so its totals
differ in the second decimal).

    .venv/bin/python tools/hem_rise.py data/continuum --split test -m lbs=lbs -m lbs-smooth=lbs-smooth \\
        -m shipped=samples/models/default -o hem_rise_test.md

CPU: a few seconds per sample and model.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np

LOOSE = ("skirt", "dress")


def hem_rise(s, body, prior: str = "smooth") -> np.ndarray:
    """The hem's rise (cm) above its rest height in each of ``s``'s frames, in the rest pose (the prior's skinning
    undone per vertex).  Shapes: -> (T,)"""
    from segadeform.body.transfer import garment_weights, skin_garment

    betas = s.betas if s.betas.size else None
    w = garment_weights(s.rest, s.faces, body, betas, prior)
    lin = body.forward(s.poses, betas, s.trans).transforms[:, :, :3, :3]
    m = np.einsum("ns,tsij->tnij", w, lin)
    x = skin_garment(s.rest, w, body, s.poses, betas, s.trans)
    r = np.linalg.solve(m, (s.frames.astype(np.float64) - x)[..., None])[..., 0]
    y = s.rest[:, 1]
    return 100 * r[:, y < np.quantile(y, 0.1), 1].mean(1)


def summarise(rows: list[dict], threshold: float) -> list[str]:
    """Markdown lines: every model on all / hem-up / other frames (all samples and the loose ones), and on the
    samples whose hem never rises."""
    names = list(rows[0]["err"]) if rows else []
    ref = "lbs-smooth" if "lbs-smooth" in names else (names[0] if names else None)

    def line(label, rs, pick):
        errs = {n: np.concatenate([np.asarray(r["err"][n])[pick(r)] for r in rs]) for n in names}
        total = {n: np.concatenate([np.asarray(r["err"][n]) for r in rs]).sum() for n in names}
        nf = len(next(iter(errs.values()))) if errs else 0
        cells = []
        for n in names:
            e = errs[n]
            mean = e.mean() if e.size else float("nan")
            rel = f" ({100 * (mean / errs[ref].mean() - 1):+.1f} %)" if ref and n != ref and e.size else ""
            cells.append(f"{mean:.3f}{rel}, {100 * e.sum() / total[n]:.0f} % of its error")
        return f"| {label} | {len(rs)} | {nf} | " + " | ".join(cells) + " |"

    loose = [r for r in rows if r["type"] in LOOSE]
    up = lambda r: np.asarray(r["rise"]) > threshold  # noqa: E731
    every = lambda r: np.ones(len(r["rise"]), bool)  # noqa: E731
    clean = [r for r in rows if not up(r).any()]
    md = [
        f"Hem-up: the hem more than {threshold:g} cm above its rest height (rest pose).  Each cell: vertex error (cm),"
        f" against `{ref}` in brackets, and the share of the model's error over the rows' samples in those frames.",
        "",
        "| frames | samples | frames | " + " | ".join(names) + " |",
        "|---" * (3 + len(names)) + "|",
        line("all", rows, every),
        line("all, hem up", rows, up),
        line("all, hem not up", rows, lambda r: ~up(r)),
        line("skirts and dresses", loose, every),
        line("skirts and dresses, hem up", loose, up),
        line("skirts and dresses, hem not up", loose, lambda r: ~up(r)),
        line("samples whose hem never rises", clean, every),
    ]
    return md


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("dataset", type=Path)
    ap.add_argument("--split", default="test")
    ap.add_argument("--threshold", type=float, default=10.0, help="cm above the rest height")
    ap.add_argument("-m", "--model", action="append", default=[], help="NAME=SPEC as segadeform eval takes it")
    ap.add_argument("-o", "--output", type=Path, help="a markdown file (and .json beside it: cm per frame, to 0.01 mm)")
    a = ap.parse_args(argv)
    if a.output is not None and (a.output.exists() or a.output.with_suffix(".json").exists()):
        print(f"{a.output}: exists; not overwritten", file=sys.stderr)
        return 1

    from segadeform.body import default_body_path, load_body
    from segadeform.dataset.roots import as_roots
    from segadeform.runtime.predictor import PackagePredictor
    from segadeform.train.data import sample_asset
    from segadeform.train.predictors import make_predictor

    body = load_body(default_body_path())
    ds = as_roots(a.dataset)
    models = {}
    for spec in a.model:
        name, _, what = spec.partition("=")
        models[name] = make_predictor(name, what or name, package=PackagePredictor)
    rows = []
    for sid in ds.ids(a.split):
        s = ds.load(sid)
        typ = s.meta.get("type")
        gt = s.frames.astype(np.float64)
        rise = hem_rise(s, body) if typ in LOOSE else np.zeros(len(gt))
        asset = sample_asset(ds, s, body, 32) if models else None
        err = {
            n: (100 * np.linalg.norm(p.predict(s, body, asset).astype(np.float64) - gt, axis=-1).mean(1))
            .round(3)
            .tolist()
            for n, p in models.items()
        }
        rows.append({"sample": sid, "type": typ, "rise": rise.round(3).tolist(), "err": err})
        print(
            f"{sid} {typ}: hem up in {100 * np.mean(rise > a.threshold):.0f} % of frames, median rise "
            f"{np.median(rise):+.1f} cm; " + " ".join(f"{n} {np.mean(e):.2f}" for n, e in err.items()),
            file=sys.stderr,
            flush=True,
        )
    md = summarise(rows, a.threshold)
    print("\n".join(md))
    if a.output is not None:
        a.output.write_text("\n".join(md) + "\n")
        a.output.with_suffix(".json").write_text(json.dumps(rows) + "\n")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
