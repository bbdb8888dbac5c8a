"""Kept samples per hour of `dataset make` on the local process pool and on Ray, 1 and 2 workers.

    python bench/executors.py [--config CONFIG.toml] [--workers 1,2] [--keep DIR]

One small dataset (default: two coarse garments x four short motions, below) made from scratch by
each executor and worker count, in one run, interleaved (local 1, ray 1, local 2, ray 2, ...) so
that a machine shared with others loads them alike.  Each Ray row starts its own Ray instance on
this machine (``--executor ray``: a head and ``workers`` worker CPUs) and shuts it down after.

Columns: ``start s`` is Ray's start (``ray.init``; 0 for the local pool), ``wall s`` the
`make_dataset` call after it (planning, garments, every sample, the log), ``kept/h`` kept samples per
hour of that wall time, ``x local`` that rate against the local pool with as many workers, and
``kept/h incl. start`` with Ray's start counted too, ``x local, 1 worker`` the rate (without the start)
against the local pool's first worker count.  The same samples are made every time: the
last column says whether each run's arrays equal the first run's.
"""

from __future__ import annotations

import argparse
import os
import shutil
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]

BENCH = """# bench/executors.py: two coarse garments x four short motions (8 samples)
[dataset]
fps = 30.0
seconds = 0.5

[quality]
max_strain = 2.0
max_penetrating = 0.02

[simulate]
effects = ["gravity", "body_collision", "bending", "air_damping"]
material = "cotton"
quality = 5
drape_seconds = 0.2
blend_seconds = 0.1

[[garments]]
kind = "skirt"
resolution = 800

[[garments]]
kind = "shorts"
resolution = 800

[[bodies]]
betas = []

[[motions]]
name = "walk"
kind = "walk"
count = 2

[[motions]]
name = "swing"
kind = "arm_swing"
count = 2
"""


def _arrays(root: Path) -> dict:
    from segadeform.dataset import list_samples, load_sample

    return {sid: load_sample(root, sid).frames for sid in list_samples(root)}


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--config", type=Path, help="dataset config (default: the small one in this file)")
    ap.add_argument("--workers", default="1,2", help="worker counts, comma-separated")
    ap.add_argument("--keep", type=Path, help="keep the datasets in this folder (default: a temporary one)")
    a = ap.parse_args(argv)
    from segadeform.body import default_body_path
    from segadeform.dataset import load_dataset_config, make_dataset, sample_plan
    from segadeform.distributed.executors import make_executor

    work = Path(a.keep) if a.keep else Path(tempfile.mkdtemp(prefix="bench-executors-"))
    work.mkdir(parents=True, exist_ok=True)
    cfg_path = a.config
    if cfg_path is None:
        cfg_path = work / "bench.toml"
        cfg_path.write_text(BENCH)
    cfg = load_dataset_config(cfg_path)
    counts = [int(x) for x in a.workers.split(",")]
    import ray

    print(
        f"{cfg_path.name}: {len(sample_plan(cfg))} samples; {os.cpu_count()} CPUs here, load average "
        f"{os.getloadavg()[0]:.2f} at the start; ray {ray.__version__}\n"
    )
    rows, ref = [], None
    for w in counts:
        for kind in ("local", "ray"):
            out = work / f"{kind}-{w}"
            shutil.rmtree(out, ignore_errors=True)
            load = os.getloadavg()[0]
            ex = make_executor(kind, w)
            t0 = time.perf_counter()
            if kind == "ray":
                ex.connect()
            start = time.perf_counter() - t0
            t1 = time.perf_counter()
            s = make_dataset(cfg, out, body_path=default_body_path(), executor=ex)
            wall = time.perf_counter() - t1
            ex.close()
            arrays = _arrays(out)
            if ref is None:
                ref = arrays
            same = arrays.keys() == ref.keys() and all(np.array_equal(arrays[k], ref[k]) for k in ref)
            rows.append(
                dict(
                    kind=kind,
                    workers=w,
                    samples=s.kept + s.rejected,
                    kept=s.kept,
                    start=start,
                    wall=wall,
                    load=load,
                    same=same,
                )
            )
    base = {r["workers"]: r["kept"] / r["wall"] for r in rows if r["kind"] == "local"}
    one = base[min(base)]
    print(
        "| executor | workers | samples | kept | start s | wall s | kept/h | x local | kept/h incl. start "
        "| x local | x local, 1 worker | load avg | same arrays |"
    )
    print("|---|---|---|---|---|---|---|---|---|---|---|---|---|")
    for r in rows:
        rate = 3600 * r["kept"] / r["wall"]
        full = 3600 * r["kept"] / (r["wall"] + r["start"])
        b = 3600 * base[r["workers"]]
        print(
            f"| {r['kind']} | {r['workers']} | {r['samples']} | {r['kept']} | {r['start']:.1f} | {r['wall']:.1f} "
            f"| {rate:.0f} | {rate / b:.2f} | {full:.0f} | {full / b:.2f} | {rate / (3600 * one):.2f} "
            f"| {r['load']:.2f} "
            f"| {'yes' if r['same'] else 'NO'} |"
        )
    if not a.keep:
        shutil.rmtree(work, ignore_errors=True)


if __name__ == "__main__":
    main()
