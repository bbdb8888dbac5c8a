"""How strongly should the ``smooth`` prior smooth?  LBS error and penetration per smoothing strength (issue #27)

For every kept sample of SPLIT of DATASET (every K-th with ``--every K``): skin the garment with the ``smooth``
prior's weights (:func:`segadeform.body.transfer.smooth_transfer_weights`) at 1, 1/2.25, 1/4, 1/9 and 1/16 of its
strength (``smooth`` is 1; ``smooth-light`` 1/4), and with the closest point's weights (``nearest``, strength 0).
Prints the vertex error (cm, mean over frames and vertices, then over samples, as ``segadeform eval``) and the
share of vertices deeper than 2 mm inside the posed body (%, every 3rd frame), over the split and per garment type.

    .venv/bin/python tools/prior_strength.py data/continuum --split val
    .venv/bin/python tools/prior_strength.py data/continuum --split train --every 8

CPU only; a few seconds per sample.  Used for ``docs/gpu-training.md`` ("A lighter prior").  Choose on the
training and validation splits, never on the test split.
"""

from __future__ import annotations

import argparse
from collections import defaultdict

import numpy as np

#: fractions of SMOOTH_STRENGTH tried (1/2.25, 1/4, 1/9, 1/16: the distance scale 1.5, 2, 3, 4 times longer)
FRACTIONS = (0.0, 1.0, 1 / 2.25, 1 / 4, 1 / 9, 1 / 16)
PEN_DEPTH = 0.002


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("dataset")
    ap.add_argument("--split", default="train")
    ap.add_argument("--every", type=int, default=1, help="every K-th sample of the split (default: all)")
    a = ap.parse_args(argv)
    if a.every < 1:
        print(f"--every: expected an integer >= 1, got {a.every}")
        return 1

    from segadeform.body import default_body_path, load_body
    from segadeform.body.collision import BodyProxy
    from segadeform.body.transfer import SMOOTH_STRENGTH, skin_garment, smooth_transfer_weights, transfer_weights
    from segadeform.dataset.roots import as_roots

    body = load_body(default_body_path())
    roots = as_roots(a.dataset)
    per: dict = defaultdict(list)  # type -> [(err (K,), pen (K,))]
    for sid in list(roots.ids(a.split))[:: a.every]:
        s = roots.load(sid)
        betas = s.betas if s.betas.size else None
        bv = body.shaped_vertices(betas)[0]
        posed = body.forward(s.poses, betas, s.trans).vertices
        gt = s.frames.astype(np.float64)
        errs, pens = [], []
        for k in FRACTIONS:
            if k == 0:
                w = transfer_weights(s.rest, bv, body.faces, body.weights)
            else:
                w = smooth_transfer_weights(s.rest, s.faces, bv, body.faces, body.weights, strength=k * SMOOTH_STRENGTH)
            x = skin_garment(s.rest, w, body, s.poses, betas, s.trans)
            errs.append(100 * np.linalg.norm(x - gt, axis=-1).mean())
            proxy, pen = None, []
            for t in range(0, len(x), 3):
                proxy = BodyProxy(posed[t], body.faces) if proxy is None else proxy.moved(posed[t])
                pen.append((proxy.query(x[t]).signed_distance < -PEN_DEPTH).mean())
            pens.append(100 * float(np.mean(pen)))
        typ = s.meta.get("type", s.meta.get("kind", "?"))
        per[typ].append((errs, pens))
        per["all"].append((errs, pens))
    if not per:
        print(f"no '{a.split}' samples in {a.dataset}")
        return 1
    head = " ".join(f"{'nearest' if k == 0 else f'1/{1 / k:g}':>15s}" for k in FRACTIONS)
    print(f"{a.split}: {len(per['all'])} samples; vertex error cm / penetrating % by smoothing strength:")
    print(f"{'':10s} {'n':>4s} {head}")
    for typ in ["all"] + sorted(k for k in per if k != "all"):
        e = np.mean([r[0] for r in per[typ]], axis=0)
        p = np.mean([r[1] for r in per[typ]], axis=0)
        print(f"{typ:10s} {len(per[typ]):4d} " + " ".join(f"{x:7.3f} /{y:6.2f}" for x, y in zip(e, p, strict=True)))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
