"""Holes a render shows: triangles and edges whose corners are outside the body and whose middle is inside it.

    .venv/bin/python bench/cloth_holes.py DATASET [--split test] [--types skirt,dress,top] [--sample ID ...]
        [--package samples/models/default] [--cloth default|K=V,..] [--push-out 0.004] [-o NEW.md]

Every vertex can be outside the body while the faces between them cross it (a chord of length L across a limb of
radius R sinks about L^2 / 8R below its ends): the "speckles" of a render.  Per sample (of ``--split`` whose
garment type is one of ``--types``, or each ``--sample``), for the Blender frames, the package's frames, those
pushed out (``--push-out``, the collision stage) and the cloth stage on them (``--cloth``, contact at 4 mm, as
``segadeform eval --cloth``), the mean per frame of: vertices inside the posed body; edge middles more than 1 mm
inside with both ends outside; face centres more than 1 mm inside with every corner outside (the body's exact
closest point, :class:`~segadeform.body.collision.BodyCollider`).  The last rows sum the samples by garment type.
``-o`` writes the table to a new file (an existing one is refused).
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from bench._heldout import add_sample_args, emit, open_samples, refuse_existing_output

#: metres: a middle counts as inside when it is deeper than this (a hole one can see, not a graze)
DEEP = 0.001
COLUMNS = ("vertices inside", "edge middles inside, ends out", "face centres inside, corners out")


def holes(x: np.ndarray, faces: np.ndarray, edges: np.ndarray, posed: np.ndarray, collider) -> np.ndarray:
    """Per frame: vertices inside, edge middles deeper than :data:`DEEP` with both ends outside, face centres deeper
    than :data:`DEEP` with every corner outside.  Shapes: x (T, N, 3), faces (F, 3), edges (E, 2), posed (T, V, 3)
    -> (T, 3)."""
    out = np.zeros((len(x), 3))
    for t in range(len(x)):
        sd = collider.query(x[t], posed[t]).signed_distance
        mid = 0.5 * (x[t][edges[:, 0]] + x[t][edges[:, 1]])
        sm = collider.query(mid, posed[t]).signed_distance
        sc = collider.query(x[t][faces].mean(axis=1), posed[t]).signed_distance
        out[t] = (
            (sd < 0).sum(),
            ((sm < -DEEP) & (sd[edges] >= 0).all(axis=1)).sum(),
            ((sc < -DEEP) & (sd[faces] >= 0).all(axis=1)).sum(),
        )
    return out


def sample_rows(dataset, sid: str, body, predictor, settings, margin: float) -> tuple[str, dict]:
    """``(type, {frames name: per-frame means (3,)})`` of one sample."""
    from segadeform.body.collision import BodyCollider
    from segadeform.geometry.mesh_ops import unique_edges
    from segadeform.train.data import sample_asset
    from segadeform.train.evaluate import cloth_frames
    from segadeform.train.metrics import reference

    s = dataset.load(sid)
    ref = reference(s, body)
    y = predictor.predict(s, body, sample_asset(dataset, s, body, 32))
    col = BodyCollider(body.v_template, body.faces)
    carry = np.zeros((y.shape[1], 3))  # the correction carried from frame to frame, as run does
    pushed = np.concatenate(
        [col.push_out(y[lo : lo + 8], ref.posed[lo : lo + 8], margin, carry=carry)[0] for lo in range(0, len(y), 8)]
    )
    frames = {
        "Blender": s.frames.astype(np.float64),
        "shipped": y,
        f"+ push-out {1e3 * margin:g} mm": pushed,
        "+ cloth": cloth_frames(y, s, ref, body, settings),
    }
    faces = np.asarray(s.faces, np.int64)
    edges = unique_edges(faces)
    return s.meta.get("type", "?"), {k: holes(v, faces, edges, ref.posed, col).mean(axis=0) for k, v in frames.items()}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    add_sample_args(ap, "skirt,dress,top")
    ap.add_argument("--push-out", type=float, default=0.004)
    a = ap.parse_args(argv)
    refuse_existing_output(a)
    body, ds, settings, ids, pred = open_samples(a)
    md = [
        f"Mean per frame; cloth settings `{a.cloth}`, push-out {1e3 * a.push_out:g} mm; inside = deeper than "
        f"{1e3 * DEEP:g} mm for middles and centres, any depth for vertices.",
        "",
        "| sample | type | frames | " + " | ".join(COLUMNS) + " |",
        "|---|---|---|---|---|---|",
    ]
    by_type: dict = {}
    for sid in ids:
        print(f"  {sid}", file=sys.stderr)
        typ, rows = sample_rows(ds, sid, body, pred, settings, a.push_out)
        for name, v in rows.items():
            md.append(f"| {sid} | {typ} | {name} | " + " | ".join(f"{x:.1f}" for x in v) + " |")
            by_type.setdefault((typ, name), []).append(v)
    md += ["", "| type | samples | frames | " + " | ".join(COLUMNS) + " |", "|---|---|---|---|---|---|"]
    for (typ, name), vs in sorted(by_type.items(), key=lambda kv: kv[0][0]):
        md.append(f"| {typ} | {len(vs)} | {name} | " + " | ".join(f"{x:.1f}" for x in np.mean(vs, axis=0)) + " |")
    text = "\n".join(md) + "\n"
    emit(text, a.output)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
