"""How often does ``garment fit --from-body`` find a posed source body?  A garment made on the default body at
``--betas`` (another shape than the one it is fitted to) is skinned into frames of real motion capture (the root's
rotation removed: the body faces +z, as a modelling package has it), the posed body becomes the source mesh, and
the garment is carried back onto the same shape with :func:`segadeform.garments.registration.fit_to_body_mesh`.
Per frame and garment kind: the mean error of the registered body's joints (cm), the carried garment's mean and
largest distance from where it was made (cm), the share of its edges that changed length more than 2x (``torn``:
``garment fit`` refuses a fit above 5 %), and whether it passed.

    OMP_NUM_THREADS=1 .venv/bin/python tools/registration_check.py samples/motions/cmu/02_01_walk.bvh \\
        samples/motions/cmu/07_03_walk.bvh --every 20 --kinds tshirt,trousers -o registration.md

(An LBS-posed garment is itself a little crushed in the armpits and between the legs, so ``torn`` is not zero with
the exact pose either; a real garment modelled on a posed body is not.)
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))


def main(argv=None) -> int:
    from segadeform.body import default_body_path, load_body
    from segadeform.body.skinning import linear_blend_skinning
    from segadeform.body.transfer import transfer_weights
    from segadeform.garments import GarmentParams, make_garment
    from segadeform.garments.registration import edge_distortion, fit_to_body_mesh
    from segadeform.motion import load_motion
    from tools.gt_spread import emit

    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("motions", nargs="+", help="motion files (BVH, AMC, npz)")
    ap.add_argument("--every", type=int, default=20, help="every k-th frame")
    ap.add_argument("--max-frames", type=int, default=8, help="at most this many frames per motion")
    ap.add_argument("--kinds", default="tshirt,trousers", help="garment kinds, comma-separated")
    ap.add_argument("--betas", default="1.5,-1.0", help="the source body's shape")
    ap.add_argument("-o", "--output", type=Path, help="also write the table (markdown) here")
    a = ap.parse_args(argv)
    body = load_body(default_body_path())
    betas = np.array([float(x) for x in a.betas.split(",")])
    rest = body.shaped_vertices(betas)[0]
    joints = body.rest_joints(betas)[0]
    garments = {}
    for kind in a.kinds.split(","):
        g = make_garment(kind, body, betas, GarmentParams())
        garments[kind] = (g, transfer_weights(g.vertices, rest, body.faces, body.weights))
    rows = []
    for path in a.motions:
        m = load_motion(path, rest_joints=joints)
        for fr in list(range(0, len(m.poses), a.every))[: a.max_frames]:
            pose = np.asarray(m.poses[fr], np.float64).copy()
            pose[:3] = 0.0
            out = body.forward(pose[None], betas)
            for kind, (g, w) in garments.items():
                posed = linear_blend_skinning(g.vertices, w, out.transforms)[0]
                t0 = time.perf_counter()
                fit = fit_to_body_mesh(posed, out.vertices[0], body.faces, body, betas, garment_faces=g.faces)
                sec = time.perf_counter() - t0
                fo = body.forward(fit.pose[None], fit.betas)
                je = np.linalg.norm(fo.joints[0] * fit.scale + fit.trans - out.joints[0], axis=1).mean()
                err = np.linalg.norm(fit.vertices - g.vertices, axis=1)
                torn, _ = edge_distortion(g.vertices, fit.vertices, g.faces)
                row = {
                    "motion": Path(path).stem,
                    "frame": fr,
                    "kind": kind,
                    "joints_cm": round(100 * je, 1),
                    "mean_cm": round(100 * err.mean(), 2),
                    "max_cm": round(100 * err.max(), 1),
                    "torn_pct": round(100 * torn, 2),
                    "passes": bool(torn <= 0.05),
                    "seconds": round(sec, 1),
                }
                rows.append(row)
    cols = list(rows[0])
    md = ["| " + " | ".join(cols) + " |", "|" + "---|" * len(cols)]
    md += ["| " + " | ".join(str(x[c]) for c in cols) + " |" for x in rows]
    md.append("")
    for kind in garments:
        r = [x for x in rows if x["kind"] == kind]
        md.append(f"* {kind}: {sum(x['passes'] for x in r)} of {len(r)} frames pass")
    emit(md, rows, a.output)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
