"""Every MakeHuman garment fitted to the default body at three shapes: how well it sits.

    python bench/garment_fit.py [FOLDER ...]     (default: ../shared/data/garments)

Per garment and body shape: median and 90th-percentile distance of the fitted vertices from the body
surface, the share inside the body (and deeper than 1 cm) straight from the binding, then after the
3 mm push-out `segadeform garment fit` applies by default, and the fit time.
"""

from __future__ import annotations

import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
SHAPES = {"mean": [], "beta1=+2": [2.0], "beta=(-1.5,+1.5)": [-1.5, 1.5]}


def main(argv=None) -> None:
    from segadeform.body import default_body_path, load_body
    from segadeform.body.placement import placement_report, push_off_body
    from segadeform.garments.registration import fit_mhclo
    from segadeform.io.mhclo import read_mhclo

    folders = [Path(a) for a in (argv or sys.argv[1:])] or [ROOT.parent / "shared" / "data" / "garments"]
    files = sorted(f for d in folders for f in d.rglob("*.mhclo"))
    body = load_body(default_body_path())
    print(
        "| garment | vertices | shape | median cm | p90 cm | inside % | >1 cm inside % | after push-out inside % | s |"
    )
    print("|---|---|---|---|---|---|---|---|---|")
    for f in files:
        b = read_mhclo(f)
        for label, betas in SHAPES.items():
            t0 = time.perf_counter()
            v = fit_mhclo(b, body, betas)
            dt = time.perf_counter() - t0
            rest = body.shaped_vertices(betas)[0]
            r = placement_report(v, rest, body.faces)
            pushed, _ = push_off_body(v, rest, body.faces, 0.003)
            r2 = placement_report(pushed, rest, body.faces)
            print(
                f"| {f.parent.name}/{f.stem} | {b.n_vertices} | {label} | {100 * r.median_distance:.1f} | "
                f"{100 * r.p90_distance:.1f} | {100 * r.inside_fraction:.1f} | {100 * r.deep_inside_fraction:.1f} | "
                f"{100 * r2.inside_fraction:.2f} | {dt:.2f} |"
            )


if __name__ == "__main__":
    main()
