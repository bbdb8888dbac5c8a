"""Where the cloth stage's edge stretch comes from: the shipped model, then the stage, on held-out samples.

    .venv/bin/python bench/cloth_strain.py DATASET [--split test] [--types skirt,dress,sleeved-dress]
        [--sample ID ...] [--package samples/models/default] [--cloth default|K=V,..] [-o NEW.md]

For every sample (of ``--split`` whose garment type is one of ``--types``, or each ``--sample``): the package's
frames (the target), the cloth stage on them (as ``segadeform eval --cloth``, contact at 4 mm) and the Blender
frames.  Stretch is length / rest length - 1 of every edge in every frame (compression counts as 0), as
``segadeform eval``'s ``max_strain_pct``.  Per sample: the largest stretch of the simulation, the target and the
stage's output; the stage's largest stretch over ``max(rest length, the target's length)`` (what it adds to the
network's own stretch); the 99th percentile of stretch over edge-frames of each; the share of edge-frames over the
stretch limit (the simulation's, the target's, the stage's); and where the edge-frames over twice
the limit are: by how deep the target puts the deeper end inside the posed body (the body's exact closest
point), and how many have both ends attached (radius 0: they follow the target and only contact moves them).
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from bench._heldout import add_sample_args, emit, open_samples, refuse_existing_output

#: bins of the deeper end's signed distance from the posed body in the target (m; negative inside)
DEPTHS = (
    (-np.inf, -0.03, "deeper than 3 cm"),
    (-0.03, -0.01, "1-3 cm inside"),
    (-0.01, 0.0, "0-1 cm inside"),
    (0.0, np.inf, "outside"),
)


def stretch(x: np.ndarray, edges: np.ndarray, ref_len: np.ndarray) -> np.ndarray:
    """Stretch of every edge per frame: max(length / ref_len - 1, 0).  Shapes: x (T, N, 3), edges (E, 2),
    ref_len (E,) or (T, E) -> (T, E)."""
    length = np.linalg.norm(x[:, edges[:, 0]] - x[:, edges[:, 1]], axis=2)
    return np.maximum(length / np.maximum(ref_len, 1e-12) - 1, 0)


def sample_rows(dataset, sid: str, body, predictor, settings) -> dict:
    """The numbers of one sample (see the module docstring)."""
    from segadeform.body.cloth import garment_setup
    from segadeform.body.collision import BodyCollider
    from segadeform.train.data import sample_asset
    from segadeform.train.evaluate import cloth_frames
    from segadeform.train.metrics import reference

    s = dataset.load(sid)
    ref = reference(s, body)
    y = predictor.predict(s, body, sample_asset(dataset, s, body, 32))
    out = cloth_frames(y, s, ref, body, settings)
    rest_body = body.shaped_vertices(s.betas if s.betas.size else None)[0]
    setup = garment_setup(s.rest, s.faces, rest_body, body.faces, settings)
    e, rest = setup.edges, setup.rest_len
    s_gt, s_y, s_out = (stretch(v, e, rest) for v in (s.frames.astype(np.float64), y, out))
    l_y = np.linalg.norm(y[:, e[:, 0]] - y[:, e[:, 1]], axis=2)
    added = stretch(out, e, np.maximum(rest, l_y))
    col = BodyCollider(body.v_template, body.faces)
    sd = np.stack([col.query(y[t], ref.posed[t]).signed_distance for t in range(len(y))])
    deep = np.minimum(sd[:, e[:, 0]], sd[:, e[:, 1]])
    bad = s_out > 2 * settings.stretch
    attached = (setup.radius[e[:, 0]] == 0) & (setup.radius[e[:, 1]] == 0)
    moved = np.linalg.norm(out - y, axis=2)
    row = {
        "sample": sid,
        "type": s.meta.get("type", "?"),
        "vertices": len(s.rest),
        "edges": len(e),
        "gt_max": 100 * s_gt.max(),
        "target_max": 100 * s_y.max(),
        "cloth_max": 100 * s_out.max(),
        "cloth_added_max": 100 * added.max(),
        "gt_p99": 100 * np.percentile(s_gt, 99),
        "target_p99": 100 * np.percentile(s_y, 99),
        "cloth_p99": 100 * np.percentile(s_out, 99),
        "gt_over_limit_pct": 100 * (s_gt > settings.stretch + 1e-9).mean(),
        "over_limit_pct": 100 * (s_out > settings.stretch + 1e-9).mean(),
        "target_over_limit_pct": 100 * (s_y > settings.stretch + 1e-9).mean(),
        "bad": int(bad.sum()),
        "bad_attached_pct": 100 * attached[None].repeat(len(y), 0)[bad].mean() if bad.any() else 0.0,
        "target_inside_pct": 100 * (sd < 0).mean(),
    }
    for lo, hi, name in DEPTHS:
        m = (deep >= lo) & (deep < hi)
        row[f"bad in {name} %"] = 100 * (bad & m).sum() / max(int(bad.sum()), 1)
        row[f"max in {name}"] = 100 * s_out[m].max() if m.any() else 0.0
    t, k = np.unravel_index(np.argmax(s_out), s_out.shape)
    a, b = e[k]
    row["worst"] = (
        f"frame {t}, rest {1e3 * rest[k]:.1f} mm, target stretch {100 * s_y[t, k]:.0f} %, ends moved "
        f"{1e3 * moved[t, a]:.0f}/{1e3 * moved[t, b]:.0f} mm from the target (radius "
        f"{1e3 * setup.radius[a]:.0f}/{1e3 * setup.radius[b]:.0f} mm), deeper end "
        f"{1e3 * deep[t, k]:.0f} mm from the body"
    )
    return row


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    add_sample_args(ap, "skirt,dress,sleeved-dress")
    a = ap.parse_args(argv)
    refuse_existing_output(a)
    body, ds, settings, ids, pred = open_samples(a)
    rows = []
    for sid in ids:
        print(f"  {sid}", file=sys.stderr)
        rows.append(sample_rows(ds, sid, body, pred, settings))
    cols = (
        ["gt_max", "target_max", "cloth_max", "cloth_added_max", "gt_p99", "target_p99", "cloth_p99"]
        + ["gt_over_limit_pct", "target_over_limit_pct", "over_limit_pct"]
        + [f"bad in {n} %" for _, _, n in DEPTHS]
        + ["bad_attached_pct"]
    )
    head = ["sample", "type"] + cols
    md = [
        f"Stretch limit {100 * settings.stretch:g} %; cloth settings `{a.cloth}`; "
        f"`bad` = edge-frames over twice the limit after the stage.",
        "",
        "| " + " | ".join(head) + " |",
        "|---" * len(head) + "|",
    ]
    for r in rows:
        md.append(f"| {r['sample']} | {r['type']} | " + " | ".join(f"{r[c]:.1f}" for c in cols) + " |")
    md += [""] + [f"* {r['sample']}: worst edge at {r['worst']}" for r in rows] + [""]
    text = "\n".join(md)
    emit(text, a.output)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
