"""What each simulation effect and solver setting costs, and what solver quality buys.

    python bench/simulate.py [--kind dress] [--resolution 2500] [--seconds 1.0] [--motion walk]
                             [--drape t|a]

One garment on the default body playing one motion.  Section 1 turns on one
effect at a time on top of a baseline with no effects (cloth stretch only),
then all of them; section 2 varies the solver quality (steps per frame)
with the default effects and reports the mean vertex distance to a
quality-20 reference simulated in the same run.  Seconds per frame are
Blender's own (the simulated frames, pre-roll included); ratios are against
the first row of each section.  ``--drape a`` runs everything through the
datasets' drape path (garment made in the A-pose too, the cloth resting and
draping there, 2 mm collision distance, clamped collision impulses, 1 s blend;
see ``samples/datasets/kinds.toml``).
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]


def main(argv=None):
    ap = argparse.ArgumentParser()
    ap.add_argument("--kind", default="dress")
    ap.add_argument("--resolution", type=int, default=2500)
    ap.add_argument("--seconds", type=float, default=1.0)
    ap.add_argument("--motion", default="walk")
    ap.add_argument("--drape", choices=("t", "a"), default="t")
    a = ap.parse_args(argv)
    from segadeform.body import load_body
    from segadeform.garments import GarmentParams, make_garment
    from segadeform.motion import make_motion
    from segadeform.physics import A_POSE, DEFAULT_EFFECTS, EFFECTS, SimSettings, simulate

    body = load_body(ROOT / "samples" / "bodies" / "default_body.npz")
    drape_a = a.drape == "a"
    g = make_garment(
        a.kind, body, params=GarmentParams(resolution=a.resolution), cloth_pose=A_POSE if drape_a else None
    )
    path = dict(rest_pose="a", collision_distance=0.002, impulse_clamp=0.02, blend_seconds=1.0) if drape_a else {}
    extra = dict(cloth_rest=g.cloth_rest, start_pose=A_POSE) if drape_a else {}
    mo = make_motion(a.motion, seconds=a.seconds, fps=30)
    print(
        f"{a.kind}: {len(g.vertices)} vertices, {a.motion} {mo.n_frames} frames "
        f"(+{1.5 if drape_a else 1.0:g} s pre-roll), drape path {a.drape}\n"
    )

    def run(**kw):
        r = simulate(g.vertices, g.faces, body, mo, settings=SimSettings(**path, **kw), **extra)
        return r.seconds_per_frame, r.frames

    print("| effects | s/frame | x baseline |\n|---|---|---|")
    base, _ = run(effects=(), quality=10)
    print(f"| none (stretch only) | {base:.3f} | 1.00 |")
    for e in EFFECTS:
        t, _ = run(effects=(e,), quality=10)
        print(f"| + {e} | {t:.3f} | {t / base:.2f} |")
    t, _ = run(effects=EFFECTS, quality=10)
    print(f"| all | {t:.3f} | {t / base:.2f} |")
    t, _ = run(effects=DEFAULT_EFFECTS, quality=10)
    print(f"| default ({', '.join(DEFAULT_EFFECTS)}) | {t:.3f} | {t / base:.2f} |")

    print("\n| quality (steps/frame) | s/frame | x quality 3 | mean distance to quality 20 (mm) | max (mm) |")
    print("|---|---|---|---|---|")
    ref_t, ref = run(effects=DEFAULT_EFFECTS, quality=20)
    rows = []
    for q in (3, 5, 10):
        t, x = run(effects=DEFAULT_EFFECTS, quality=q)
        d = np.linalg.norm(x - ref, axis=2)
        rows.append((q, t, 1e3 * d.mean(), 1e3 * d.max()))
    rows.append((20, ref_t, 0.0, 0.0))
    for q, t, dm, dx in rows:
        print(f"| {q} | {t:.3f} | {t / rows[0][1]:.2f} | {dm:.2f} | {dx:.1f} |")


if __name__ == "__main__":
    main()
