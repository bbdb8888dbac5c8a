"""The drape at rest as a skinning prior: how far toward it should the skinned rest go?  (issue #27)

For every kept sample of SPLIT of DATASET (a folder, pack or several roots): the vertex error (cm, mean over frames
and vertices) of ``lbs-smooth`` skinning the garment's rest moved 0, 0.25, 0.5, 0.75 and 1 of the way toward its
drape on the body at rest (:func:`segadeform.body.drape.drape_rest`, :func:`~segadeform.body.drape.partial_drape`;
amount 0 is ``lbs-smooth``, 1 is ``lbs-drape``).  Prints the means over the split, per garment kind and per design
(with its flare where the design has one).

    .venv/bin/python tools/drape_prior.py data/continuum --split train

CPU only; about a second per sample.  Used for ``docs/gpu-training.md``.  Choose on the training and validation
splits, never on the test split.
"""

from __future__ import annotations

import argparse

import numpy as np

AMOUNTS = (0.0, 0.25, 0.5, 0.75, 1.0)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("dataset")
    ap.add_argument("--split", default="train")
    a = ap.parse_args(argv)

    from segadeform.body import default_body_path, load_body
    from segadeform.body.drape import partial_drape, skinned_rest
    from segadeform.body.transfer import garment_weights, skin_garment
    from segadeform.dataset.roots import as_roots

    body = load_body(default_body_path())
    roots = as_roots(a.dataset)
    memo: dict = {}
    rows = []
    for sid in roots.ids(a.split):
        s = roots.load(sid)
        betas = s.betas if s.betas.size else None
        w = garment_weights(s.rest, s.faces, body, betas, "smooth")
        draped = skinned_rest(s.rest, s.faces, body, betas, 1.0, memo)
        gt = s.frames.astype(np.float64)
        err = [
            100
            * np.linalg.norm(
                skin_garment(partial_drape(s.rest, draped, k), w, body, s.poses, betas, s.trans) - gt, axis=-1
            ).mean()
            for k in AMOUNTS
        ]
        flare = (s.meta.get("garment_params") or {}).get("flare")
        rows.append((s.meta.get("kind", s.meta.get("type", "?")), s.meta.get("garment", sid), flare, err))
    if not rows:
        print(f"no '{a.split}' samples in {a.dataset}")
        return 1
    e = np.array([r[3] for r in rows])
    head = " ".join(f"{k:>6g}" for k in AMOUNTS)
    print(f"{a.split}: {len(rows)} samples; vertex error (cm) with the rest moved this far toward its drape:")
    print(f"{'':32s} {'n':>4s} {head}")
    print(f"{'all':32s} {len(rows):4d} " + " ".join(f"{x:6.3f}" for x in e.mean(0)))
    for group, col in (("kind", 0), ("design", 1)):
        for g in sorted({r[col] for r in rows}):
            i = [j for j, r in enumerate(rows) if r[col] == g]
            flare = rows[i[0]][2]
            name = f"  {g}" + (f" (flare {flare:.2f})" if group == "design" and isinstance(flare, float) else "")
            print(f"{name:32s} {len(i):4d} " + " ".join(f"{x:6.3f}" for x in e[i].mean(0)))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
