"""Look before you trust a number: held-out samples of a dataset rendered beside their ground truth.

    python bench/render_heldout.py DATASET --sample ID [--sample ID ...] [--model NAME=SPEC ...] \
        [--frames 15,30,45] [--push-out 0.004] [--cloth default|K=V,..] -o heldout.png

One row per (sample, frame): the Blender simulation, then each model (``NAME=SPEC`` as in
``segadeform eval``: a package folder, a checkpoint, ``lbs`` or ``lbs-inpaint``), with the mean vertex
error of that frame in each title.  ``--push-out`` adds the first learned model with the runtime's
collision stage at that margin (what ``segadeform run`` gives with collisions on); ``--cloth`` adds it with the
cloth stage at those settings (``default``: its defaults; what ``segadeform run --effects=+cloth --cloth ...``
gives; contact at the ``--push-out`` margin, else 4 mm).  The default models are ``lbs`` and the shipped package.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

from segadeform.body import default_body_path, load_body
from segadeform.body.collision import BodyCollider
from segadeform.dataset.store import load_sample
from segadeform.geometry import precompute_garment
from segadeform.preview.render import MeshLayer, fit_bounds, render, save_image
from segadeform.runtime.pipeline import default_model_path
from segadeform.runtime.predictor import PackagePredictor
from segadeform.train.evaluate import cloth_frames, cloth_names, push_out_frames
from segadeform.train.metrics import reference
from segadeform.train.predictors import make_predictor

SKIN, CLOTH = (0.85, 0.7, 0.6), (0.25, 0.4, 0.85)


def main(argv=None) -> Path:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("dataset", type=Path)
    ap.add_argument("--sample", action="append", required=True, help="sample id (repeatable)")
    ap.add_argument("--model", action="append", help="NAME=SPEC (repeatable; default lbs and the shipped package)")
    ap.add_argument("--frames", default="15,30,45")
    ap.add_argument("--push-out", type=float, default=None)
    ap.add_argument("--cloth", action="append", help="the cloth stage's settings (repeatable; 'default')")
    ap.add_argument("--size", default="200x260")
    ap.add_argument("-o", "--output", type=Path, required=True)
    a = ap.parse_args(argv)
    w, h = (int(x) for x in a.size.split("x"))
    frames = [int(x) for x in a.frames.split(",")]
    specs = [m.split("=", 1) for m in (a.model or ["lbs=lbs", f"shipped={default_model_path()}"])]
    body = load_body(default_body_path())
    predictors = [(name, make_predictor(name, spec, package=PackagePredictor)) for name, spec in specs]
    rows = []
    for sid in a.sample:
        s = load_sample(a.dataset, sid)
        betas = s.betas if s.betas.size else None
        n_star = next(
            (
                int(p.cfg["n_star"] if isinstance(p.cfg, dict) else p.cfg.n_star)
                for _, p in predictors
                if hasattr(p, "cfg")
            ),
            32,
        )
        asset = precompute_garment(s.rest, s.faces, body.rest_joints(betas)[0], n_star=n_star)
        shown = {"Blender": s.frames}
        learned = None
        for name, p in predictors:
            shown[name] = p.predict(s, body, asset)
            if learned is None and hasattr(p, "cfg"):
                learned = name
        if a.push_out is not None and learned is not None:
            shown[f"{learned}+push-out"] = push_out_frames(
                shown[learned], reference(s, body), BodyCollider(body.v_template, body.faces), a.push_out
            )
        for sfx, settings in cloth_names(a.cloth).items():
            if learned is not None:
                shown[f"{learned}{sfx.replace(' + ', '+')}"] = cloth_frames(
                    shown[learned],
                    s,
                    reference(s, body),
                    body,
                    settings,
                    margin=a.push_out if a.push_out is not None else 0.004,
                )
        label = sid.split("__")[0]
        for fi in frames:
            if not 0 <= fi < len(s.frames):
                raise SystemExit(f"{sid}: frame {fi} outside 0..{len(s.frames) - 1}")
            bv = body.forward(s.poses[fi : fi + 1], betas, s.trans[fi : fi + 1]).vertices[0]
            bounds = fit_bounds(np.concatenate([bv, s.frames[fi]]), size=(w, h))
            row = []
            for name, x in shown.items():
                err = np.linalg.norm(x[fi] - s.frames[fi], axis=-1).mean() * 100
                row.append(
                    render(
                        [MeshLayer(bv, body.faces, SKIN), MeshLayer(x[fi], s.faces, CLOTH, depth_bias=0.003)],
                        size=(w, h),
                        bounds=bounds,
                        title=f"{label[:14]} f{fi}" if name == "Blender" else f"{name} {err:.1f} cm",
                    )
                )
            rows.append(np.concatenate(row, axis=1))
    out = save_image(a.output, np.concatenate(rows, axis=0))
    print(f"-> {out}")
    return out


if __name__ == "__main__":
    main()
