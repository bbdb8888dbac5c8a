"""What accuracy costs in time: every knob of the learned runtime, and the simulator's own quality, in one run.

    .venv/bin/python bench/tradeoffs.py DATASET --package PKG [--model NAME=SPEC ...] -o docs
        [--split test] [--threads-all N] [--repeats 3] [--sim SAMPLE_ID | --no-sim]
        [--sim-config DATASET_PLAN.toml] [--sim-qualities 2,5,10,20] [--sim-reference 40]
    .venv/bin/python bench/tradeoffs.py DATASET --package PKG -o docs --redraw   # docs again from the JSON

On the held-out (``--split``) samples of DATASET, every row is measured on the same samples, in the same
process, one after another (errors against the Blender simulation stored in the dataset):

* effects: all on; no wrinkles; no dynamics; neither; dual-quaternion skinning (all effects);
* collisions: the runtime's push-out (:class:`BodyCollider`, built once, frames in batches as
  ``segadeform run`` does) at 2, 4 and 8 mm on "all effects" and "no wrinkles", at 4 mm on every other
  effects, precision and model row;
* precision: fp16 weights (float32 arithmetic) and int8 dynamic quantisation (``segadeform quantize``);
* batch: frames per deformer call (8 elsewhere, the runtime's default);
* K: neighbours per vertex in the garment graph, made at precompute (``neighbour_graph(k=K)``; the
  models were trained at K = the garment's largest valence, capped at 16);
* N*: furthest-point samples of the garment descriptor, its eigenvalues rescaled to the model's length
  (:func:`segadeform.geometry.descriptor.rescale_descriptor`);
* garment resolution: the model run on a decimated and a subdivided copy of each garment
  (:mod:`segadeform.body.resample`), the result carried to the full-resolution vertices by a
  :class:`SurfaceMap` and compared there;
* models: each ``NAME=SPEC`` (e.g. width/depth variants trained on the same data);
* cloth: the runtime's cloth stage (:mod:`segadeform.body.cloth`, as ``segadeform run --effects=+cloth``) on
  "all effects" at 1, 2, 4, 8 and 16 sweeps per frame (the other knobs at their defaults), at two other
  stiffnesses, with the backstop off, at one other value of every other knob and at contact margins of 2 and 8 mm,
  and at its defaults on every other effects row, contact at 4 mm (``--cloth-iterations``, ``--cloth-stiffness``,
  ``--cloth-backstop``, ``--cloth-knobs``, ``--cloth-margins``);
* presets: ``segadeform run --quality`` (:mod:`segadeform.settings.presets`), each the row with its effects and margin
  (and cloth settings).

Every row: ms/frame at one onnxruntime thread and at ``--threads-all`` threads (best of ``--repeats``),
deformer calls and push-out only (plus carrying results back to full resolution for the resolution rows);
"setup" is the once-per-garment cost (precompute and encoder).  The simulator's axis: one sample
(``--sim``) re-simulated by Blender at several cloth qualities and at a reference quality, each
quality's seconds per frame and its distance to the reference, the learned presets' distance to the
same reference and how many times faster they run, all in this run.

Writes ``accuracy-vs-time.md`` (tables, frontier, presets), ``.json`` and ``.png``/``.svg`` (error
against ms/frame for both thread counts, the Pareto frontier, and the simulator's quality axis).
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import tempfile
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
#: the cloth stage's knobs beyond iterations, stiffness and backstop: one other value each (the defaults'
#: neighbourhood; `segadeform run --cloth` takes them)
CLOTH_KNOBS = (
    "stretch=0.1;compress=0.1;bending=0.5;damping=0.3;follow=0.8;gravity=0;attachment=0.01;max_distance=0.1;reset=0.1"
)
sys.path.insert(0, str(REPO))

# the measuring and the rendering live in importable modules beside this command (issue #30); their names are
# re-exported here for the callers of this file
from bench.tradeoffs_measure import (  # noqa: E402,F401
    DEFAULT_BATCH,
    EFFECTS_ROWS,
    Row,
    blender_resimulate,
    cloth_key,
    effects_key,
    match_presets,
    measure,
    peak_metrics,
    plan_rows,
    preset_key,
    simulator_axis,
)
from bench.tradeoffs_render import frontier, write_docs  # noqa: E402,F401


def main(argv=None, *, _simulate: Callable | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("dataset", type=Path)
    ap.add_argument("--package", type=Path, required=True)
    ap.add_argument("--model", action="append", default=[], help="NAME=SPEC, repeatable")
    ap.add_argument("--split", default="test")
    ap.add_argument("--threads-all", type=int, default=os.cpu_count() or 1)
    ap.add_argument("--repeats", type=int, default=3, help="timed runs per row and sample (the best counts)")
    ap.add_argument("--ks", default="4,6,12")
    ap.add_argument("--n-stars", default="8,16,64")
    ap.add_argument("--batches", default="1,32")
    ap.add_argument("--resolutions", default="1/4,1/2,4x")
    ap.add_argument("--cloth-iterations", default="1,2,4,8,16", help="the cloth stage's sweeps per frame, one row each")
    ap.add_argument("--cloth-stiffness", default="0.5,0.2", help="its other stiffnesses, one row each")
    ap.add_argument("--cloth-backstop", default="0", help="its other backstop depths (m; 0: off), one row each")
    ap.add_argument(
        "--cloth-knobs",
        default=CLOTH_KNOBS,
        help="its other knobs, one row per ';'-separated setting (NAME=VALUE[,NAME=VALUE]: run --cloth's form)",
    )
    ap.add_argument("--cloth-margins", default="0.002,0.008", help="its other contact margins (m), one row each")
    ap.add_argument("--no-int8", action="store_true")
    ap.add_argument("--no-fp16", action="store_true")
    ap.add_argument("--samples", default="", help="comma-separated sample ids (default: the whole split)")
    ap.add_argument(
        "--sim",
        help="sample id for the simulator's quality axis (default: the test sample with the fewest vertices x frames)",
    )
    ap.add_argument("--no-sim", action="store_true")
    ap.add_argument("--sim-config", type=Path, default=REPO / "samples" / "datasets" / "continuum.toml")
    ap.add_argument("--sim-qualities", default="2,5,10,20")
    ap.add_argument("--sim-reference", type=int, default=40)
    ap.add_argument(
        "--redraw",
        action="store_true",
        help="write the docs again from OUTPUT/accuracy-vs-time.json (e.g. after the preset table "
        "changed) without measuring; the recorded command and duration stay",
    )
    ap.add_argument("-o", "--output", type=Path, required=True)
    a = ap.parse_args(argv)
    if a.redraw:
        d = json.loads((a.output / "accuracy-vs-time.json").read_text())
        # the largest stretch is the largest over the samples (runs before 2 Dec 2026 stored the mean of each
        # sample's largest under the same name): taken again from the per-sample numbers
        for name, row in d["rows"].items():
            row.update(peak_metrics(d["per_sample"][name]))
        res = {"rows": d["rows"], "samples": d["samples"], "per_sample": d["per_sample"], "metrics": d["metrics"]}
        sim = d.get("simulator")
        md = write_docs(
            res,
            a.output,
            command=d["command"],
            seconds=d["seconds"],
            threads_all=d["threads_all"],
            load=tuple(d["load_average"]),
            presets=match_presets(d["rows"], str(a.package)),
            sim=sim,
            sim_error=d.get("simulator_error", ""),
            split=a.split,
            dataset=a.dataset,
            git=d.get("git"),
        )
        print("\n".join(md))
        return 0

    from segadeform.body import load_body
    from segadeform.dataset.store import list_samples, load_sample
    from segadeform.export.precision import convert_package

    ints = lambda t: tuple(int(x) for x in t.split(",") if x.strip())  # noqa: E731
    body = load_body(REPO / "samples" / "bodies" / "default_body.npz")
    pkg = str(a.package)
    models = {}
    for m in a.model:
        n, eq, s = m.partition("=")
        if not eq:
            raise SystemExit(f"--model must be NAME=SPEC, got {m!r}")
        models[n] = s
    load0 = os.getloadavg()[0]
    t0 = time.perf_counter()
    sim_sid = None
    if not a.no_sim:
        ids = [i for i in list_samples(a.dataset, a.split) if not a.samples or i in a.samples.split(",")]
        if a.sim:
            sim_sid = a.sim
        else:
            sizes = {i: load_sample(a.dataset, i) for i in ids}
            # the smallest sample kept on its first simulation attempt (the config's own settings)
            first = [i for i in ids if not sizes[i].meta.get("attempt", 0)] or ids
            sim_sid = min(first, key=lambda i: (sizes[i].frames.shape[0] * sizes[i].frames.shape[1], i))
    with tempfile.TemporaryDirectory() as tmp:
        q8 = None if a.no_int8 else str(convert_package(pkg, Path(tmp) / "int8", "int8"))
        h16 = None if a.no_fp16 else str(convert_package(pkg, Path(tmp) / "fp16", "fp16-weights"))
        rows, presets = plan_rows(
            pkg,
            q8,
            models,
            fp16=h16,
            ks=ints(a.ks),
            n_stars=ints(a.n_stars),
            batches=ints(a.batches),
            resolutions=tuple(x for x in a.resolutions.split(",") if x.strip()),
            cloth_iterations=ints(a.cloth_iterations),
            cloth_stiffness=tuple(float(x) for x in a.cloth_stiffness.split(",") if x.strip()),
            cloth_backstop=tuple(float(x) for x in a.cloth_backstop.split(",") if x.strip()),
            cloth_knobs=tuple(x.strip() for x in a.cloth_knobs.split(";") if x.strip()),
            cloth_margins=tuple(float(x) for x in a.cloth_margins.split(",") if x.strip()),
        )
        res = measure(
            a.dataset,
            body,
            rows,
            split=a.split,
            threads_all=a.threads_all,
            repeats=a.repeats,
            keep=(sim_sid,) if sim_sid else (),
            only=tuple(x for x in a.samples.split(",") if x),
            progress=lambda sid: print(f"  {sid}", file=sys.stderr),
        )
    sim, sim_error = None, "" if not a.no_sim else "--no-sim"
    if sim_sid:
        try:
            run = _simulate or blender_resimulate(a.sim_config, a.dataset, body)
            s = load_sample(a.dataset, sim_sid)
            if getattr(run, "digest", None) and s.meta.get("config_digest") not in (None, run.digest):
                print(f"note: {sim_sid} was made from another version of {a.sim_config}", file=sys.stderr)
            kept = res["kept"][sim_sid]
            learned = {n: (x, *tm[:2]) for n, (x, tm) in kept.items()}  # every row: presets may change later
            sim = simulator_axis(
                run, sim_sid, s.frames.astype(np.float64), ints(a.sim_qualities), a.sim_reference, learned
            )
            quality_of = getattr(run, "quality_of", None)  # the attempt the sample was kept on
            sim["dataset_quality"] = (
                quality_of(sim_sid)
                if quality_of
                else getattr(run, "quality", s.meta.get("settings", {}).get("segadeform", {}).get("quality", ""))
            )
        except Exception as e:  # the simulator is optional: a machine without it still gets the rest
            sim_error = f"{type(e).__name__}: {e}"
            print(f"simulator axis not measured: {sim_error}", file=sys.stderr)
    seconds = time.perf_counter() - t0
    res.pop("kept")
    shown = [str(a.dataset), "--package", pkg] + [x for m in a.model for x in ("--model", m)] + ["-o", str(a.output)]
    for flag, val, default in (
        ("--split", a.split, "test"),
        ("--repeats", a.repeats, 3),
        ("--samples", a.samples, ""),
        ("--threads-all", a.threads_all, os.cpu_count() or 1),
        ("--ks", a.ks, "4,6,12"),
        ("--n-stars", a.n_stars, "8,16,64"),
        ("--batches", a.batches, "1,32"),
        ("--resolutions", a.resolutions, "1/4,1/2,4x"),
        ("--cloth-iterations", a.cloth_iterations, "1,2,4,8,16"),
        ("--cloth-stiffness", a.cloth_stiffness, "0.5,0.2"),
        ("--cloth-backstop", a.cloth_backstop, "0"),
        ("--cloth-knobs", a.cloth_knobs, CLOTH_KNOBS),
        ("--cloth-margins", a.cloth_margins, "0.002,0.008"),
        ("--sim", a.sim, None),
        ("--sim-qualities", a.sim_qualities, "2,5,10,20"),
        ("--sim-reference", a.sim_reference, 40),
    ):
        if val != default:
            shown += [flag, str(val)]
    shown += [flag for flag, on in (("--no-int8", a.no_int8), ("--no-fp16", a.no_fp16), ("--no-sim", a.no_sim)) if on]
    md = write_docs(
        res,
        a.output,
        command=".venv/bin/python bench/tradeoffs.py " + " ".join(shown),
        seconds=seconds,
        threads_all=a.threads_all,
        load=(load0, os.getloadavg()[0]),
        presets=presets,
        sim=sim,
        sim_error=sim_error,
        split=a.split,
        dataset=a.dataset,
    )
    print("\n".join(md))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
