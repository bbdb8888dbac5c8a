"""What accuracy costs in time: every runtime knob of a model package, measured in one run.

    .venv/bin/python bench/tradeoffs.py DATASET --package PKG [--model NAME=SPEC ...] -o docs/accuracy-vs-time

On the held-out ('test') split of DATASET, in one ``segadeform eval`` run (so LBS, the floor, is
measured beside every setting on the same samples and the same machine load):

* effects: all on; no wrinkles; no dynamics; neither; dual-quaternion skinning; collisions (push-out)
  at three margins;
* precision: fp32 and int8 (``segadeform quantize``);
* models: any further ``NAME=SPEC`` (other checkpoints or packages trained on the same data).

Writes ``accuracy-vs-time.md`` (the table, frontier marked) and ``accuracy-vs-time.png``/``.svg``
(vertex error against ms/frame, the Pareto frontier drawn). Times are one onnxruntime thread, this
machine, garment precompute and encoder excluded.

Not yet measured here (issue #16): threads, batch, K, N*, garment resolution, model width/depth,
fp16 and the simulator's own quality axis.
"""

from __future__ import annotations

import argparse
import json
import platform
import subprocess
import sys
import tempfile
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))


def frontier(points: dict[str, tuple[float, float]]) -> list[str]:
    """Names of the points (ms, error) no other point beats on both (ties kept), fastest first."""
    out = []
    for n, (t, e) in points.items():
        if not any((t2 <= t and e2 <= e) and (t2 < t or e2 < e) for m, (t2, e2) in points.items() if m != n):
            out.append(n)
    return sorted(out, key=lambda n: points[n][0])


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("dataset", type=Path)
    ap.add_argument("--package", type=Path, required=True)
    ap.add_argument("--model", action="append", default=[], help="NAME=SPEC, repeatable")
    ap.add_argument("--split", default="test")
    ap.add_argument("-o", "--output", type=Path, required=True)
    a = ap.parse_args(argv)

    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from segadeform.body import load_body
    from segadeform.export.precision import convert_package
    from segadeform.train.evaluate import METRICS, evaluate

    body = load_body(REPO / "samples" / "bodies" / "default_body.npz")
    pkg = str(a.package)
    t0 = time.perf_counter()
    with tempfile.TemporaryDirectory() as tmp:
        q8 = str(convert_package(pkg, Path(tmp) / "int8", "int8"))
        knobs = {  # name: (knob, setting, spec)
            "lbs": ("baseline", "body skinning only", "lbs"),
            "all effects": ("effects", "lbs + dynamics + wrinkles", pkg),
            "no wrinkles": ("effects", "-wrinkles", f"{pkg}:-wrinkles"),
            "no dynamics": ("effects", "-dynamics", f"{pkg}:-dynamics"),
            "static, no wrinkles": ("effects", "-dynamics,-wrinkles", f"{pkg}:-dynamics,-wrinkles"),
            "dqs": ("effects", "dqs skinning", f"{pkg}:dqs"),
            "int8": ("precision", "int8 dynamic", q8),
        }
        for m in a.model:
            n, _, s = m.partition("=")
            knobs[n] = ("model", n, s)
        specs = {n: s for n, (_, _, s) in knobs.items()}
        res = evaluate(a.dataset, body, specs, split=a.split, push_out_margin=0.004,
                       progress=lambda sid: print(f"  {sid}", file=sys.stderr))
        for margin in (0.002, 0.008):  # the other collision margins, on the all-effects model
            r2 = evaluate(a.dataset, body, {"all effects": pkg}, split=a.split, push_out_margin=margin)
            res["models"][f"all effects + push-out {1e3 * margin:.0f} mm"] = r2["models"]["all effects + push-out"]
    seconds = time.perf_counter() - t0
    rows = {}
    for n, m in res["models"].items():
        if n.endswith(" + push-out"):
            base = n[: -len(" + push-out")]
            label = "all effects + push-out 4 mm" if base == "all effects" else n
            rows[label] = ("collisions" if base == "all effects" else knobs[base][0], label, m)
        elif "push-out" in n:
            rows[n] = ("collisions", n, m)
        else:
            rows[n] = (knobs[n][0], knobs[n][1], m)
    pts = {n: (r[2]["ms_per_frame"], r[2]["vertex_cm"]) for n, r in rows.items()}
    front = frontier(pts)
    cols = METRICS + ("ms_per_frame",)
    head = ["knob", "setting"] + list(cols) + ["frontier"]
    lines = ["| " + " | ".join(head) + " |", "|---" * len(head) + "|"]
    for n, (knob, setting, m) in sorted(rows.items(), key=lambda kv: kv[1][2]["ms_per_frame"]):
        lines.append(f"| {knob} | {n} | " + " | ".join(f"{m[k]:.3f}" if k != "ms_per_frame" else f"{m[k]:.1f}"
                                                       for k in cols) + f" | {'yes' if n in front else ''} |")
    git = subprocess.run(["git", "rev-parse", "--short", "HEAD"], cwd=REPO, capture_output=True, text=True).stdout.strip()
    md = [f"# Accuracy against time ({a.split} split of `{a.dataset.name}`, {len(res['samples'])} samples)", "",
          f"Made by `.venv/bin/python bench/tradeoffs.py {a.dataset} --package {a.package} "
          + " ".join(f"--model {m}" for m in a.model) + f" -o {a.output}` at {git}; {seconds:.0f} s on "
          f"{platform.processor() or platform.machine()}, one onnxruntime thread, ms/frame excludes the "
          "garment precompute and encoder. Errors are against the Blender simulation; units: vertex, "
          "band errors cm, normal degrees, edge mm, penetration % of vertices deeper than 2 mm.", "",
          f"The dataset is made by `segadeform dataset make samples/datasets/generalise.toml -o {a.dataset}` "
          "(its test split: garment kinds, motion families and a body shape the training never saw); "
          "LBS is the body's skinning weights moved to the garment, no learned part; `+ push-out` adds the "
          "runtime's collision stage at the margin named (4 mm unless given). No other process ran during "
          "the measurement unless stated. Push-out here is timed with the reference collision query "
          "(BodyProxy per frame, as `segadeform eval` does), not the runtime's faster BodyCollider "
          "(bench/collisions.py), so collision rows overstate the runtime's cost.", "",
          "\n".join(lines), "", f"Pareto frontier (fastest first): {', '.join(front)}.", "",
          "![error against time](accuracy-vs-time.png)", ""]
    a.output.mkdir(parents=True, exist_ok=True)
    (a.output / "accuracy-vs-time.md").write_text("\n".join(md))
    (a.output / "accuracy-vs-time.json").write_text(json.dumps({"rows": {n: r[2] for n, r in rows.items()},
                                                                "frontier": front, "samples": res["samples"]}, indent=1))
    fig, ax = plt.subplots(figsize=(7, 4.5))
    knob_names = sorted({r[0] for r in rows.values()})
    for k in knob_names:
        xs = [pts[n] for n, r in rows.items() if r[0] == k]
        ax.scatter([x[0] for x in xs], [x[1] for x in xs], label=k)
    for n, (t, e) in pts.items():
        ax.annotate(n, (t, e), fontsize=6)
    ax.plot([pts[n][0] for n in front], [pts[n][1] for n in front], "k--", lw=0.8, label="frontier")
    ax.set_xscale("log")
    ax.set_xlabel("ms per frame (one thread)")
    ax.set_ylabel("mean vertex error (cm)")
    ax.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(a.output / "accuracy-vs-time.png", dpi=90)
    fig.savefig(a.output / "accuracy-vs-time.svg")
    print("\n".join(md))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
