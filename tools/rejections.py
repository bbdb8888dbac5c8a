"""Take rejected simulations apart: where the gate's penetrating vertices are, and how fast the body moves.

    .venv/bin/python tools/rejections.py DATASET [ID ...]        (default: every rejected sample)

For each sample in ``DATASET/rejected`` (or each ``ID``): the worst frame's share of vertices deeper than the
config's ``penetration_depth`` inside the posed body that are not pinched (as the gate counts them,
:func:`segadeform.dataset.quality.quality_check`), the mean over frames, the first frame over 1 %, the depth
(median and 90th percentile), how many vertices are inside in more than half of the frames (stuck) against
any frame, the body part nearest to them (torso, arms, legs: the gate's parts), the fastest body vertex's
motion per frame (cm) over the clip and at that first frame, and the same share measured against the body one
frame earlier and later (a time offset between garment and body would make those smaller).  Used for
``docs/simulator-gate.md``.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

PARTS = ("torso", "left arm", "right arm", "left leg", "right leg")


def inside_share(frames, posed, faces, depth, parts, lag: int = 0):
    """Per frame t: the share of vertices deeper than ``depth`` in the body at frame ``t + lag`` that are not
    pinched, and (lag 0) their indices and depths.  Shapes: frames (T, N, 3), posed (T, V, 3)."""
    from segadeform.body.collision import BodyProxy
    from segadeform.dataset.quality import pinched

    share, found, proxy = [], [], None
    for t in range(max(0, -lag), len(frames) - max(0, lag)):
        proxy = BodyProxy(posed[t + lag], faces) if proxy is None else proxy.moved(posed[t + lag])
        q = proxy.query(frames[t])
        idx = np.flatnonzero(q.signed_distance < -depth)
        if len(idx):
            idx = idx[~pinched(frames[t][idx], -q.signed_distance[idx], posed[t + lag], parts)]
        share.append(len(idx) / frames.shape[1])
        found.append((t, idx, -q.signed_distance[idx], q.closest[idx]))
    return np.array(share), found


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("dataset", type=Path)
    ap.add_argument("ids", nargs="*")
    a = ap.parse_args(argv)
    from scipy.spatial import cKDTree

    from segadeform.body import default_body_path, load_body
    from segadeform.dataset.quality import BodyParts
    from segadeform.dataset.store import load_sample
    from segadeform.io.toml import read_toml

    body = load_body(default_body_path())
    table = read_toml(a.dataset / "config.toml", "dataset config")[0]  # the dataset's own copy of its config
    depth = float(table.get("quality", {}).get("penetration_depth", 0.005))
    ids = a.ids or sorted(p.stem for p in (a.dataset / "rejected").glob("*.json"))
    for sid in ids:
        s = load_sample(a.dataset, sid, "rejected")
        betas = s.betas if s.betas.size else None
        posed = body.forward(s.poses, betas, s.trans).vertices
        parts = BodyParts.of(body, betas)
        x = s.frames.astype(np.float64)
        share, found = inside_share(x, posed, body.faces, depth, parts)
        count = np.zeros(x.shape[1])
        near = np.zeros(len(PARTS))
        depths = []
        for t, idx, d, closest in found:
            count[idx] += 1
            depths.extend(d)
            if len(idx):
                np.add.at(near, parts.part[cKDTree(posed[t]).query(closest)[1]], 1)
        speed = np.r_[0.0, np.linalg.norm(np.diff(posed, axis=0), axis=2).max(axis=1)]
        onset = int(np.argmax(share > 0.01)) if (share > 0.01).any() else -1
        d = np.array(depths) if depths else np.zeros(1)
        lags = {lag: inside_share(x, posed, body.faces, depth, parts, lag)[0].max() for lag in (-1, 1)}
        print(
            f"{sid}: inside {100 * share.max():.2f} % worst frame, {100 * share.mean():.2f} % mean, first over 1 % "
            f"at frame {onset}; depth {1000 * np.median(d):.0f} / {1000 * np.percentile(d, 90):.0f} mm (median / "
            f"p90); {int((count > 0.5 * len(x)).sum())} of {int((count > 0).sum())} vertices stuck; near "
            + ", ".join(f"{PARTS[i]} {100 * near[i] / max(near.sum(), 1):.0f} %" for i in range(5) if near[i])
            + f"; body {100 * speed.max():.1f} cm/frame at most, {100 * speed[max(onset, 0)]:.1f} at that frame; "
            f"against the body one frame earlier / later: {100 * lags[-1]:.1f} / {100 * lags[1]:.1f} %",
            file=sys.stdout,
        )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
