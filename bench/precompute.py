"""Time and peak memory of each precompute step for garments of 1k, 4k, 16k and 64k vertices.

    python bench/precompute.py [--sizes 1000 4000 16000 64000] [--repeat 1]

Garments are flared-skirt tubes (``geometry.primitives.frustum``).  Each row
gives the step's wall time and its peak memory (the larger of the resident
high-water mark above the memory held before it -- Linux VmHWM, reset with
/proc/self/clear_refs -- and tracemalloc's peak, measured in a second, untimed
run), and the growth ratios against the
previous size (4x vertices): linear cost shows ~4x, O(N^2) would show ~16x.
``spectral bands`` is for evaluation only (dense, O(N^2) memory) and is not in
the path ``segadeform precompute`` takes; it is run up to 4k vertices.
"""

from __future__ import annotations

import argparse
import gc
import os
import tempfile
import time
import tracemalloc
from pathlib import Path

import numpy as np

from segadeform.geometry import (
    GeodesicSolver,
    SpectralBasis,
    garment_descriptor,
    neighbour_graph,
    precompute_garment,
    vertex_features,
    vertex_normals,
)
from segadeform.geometry.primitives import frustum
from segadeform.io import Mesh, read_obj, write_obj

ROOT = Path(__file__).resolve().parents[1]
_PROC = Path("/proc/self/status").exists() and os.access("/proc/self/clear_refs", os.W_OK)


def _status(key: str) -> int:
    for line in open("/proc/self/status"):
        if line.startswith(key):
            return int(line.split()[1]) * 1024
    return 0


def measure(fn):
    """Run ``fn`` twice: once timed, once for memory.

    Returns (seconds, peak bytes): the peak is the larger of the resident
    high-water mark above the starting RSS (catches C allocations such as
    SuperLU's, misses memory reused from the allocator's free lists) and
    tracemalloc's peak (catches numpy arrays wherever they come from).
    """
    gc.collect()
    t0 = time.perf_counter()
    fn()
    dt = time.perf_counter() - t0
    gc.collect()
    hwm = 0
    if _PROC:
        with open("/proc/self/clear_refs", "w") as fh:
            fh.write("5")
        base = _status("VmRSS")
    tracemalloc.start()
    fn()
    traced = tracemalloc.get_traced_memory()[1]
    tracemalloc.stop()
    if _PROC:
        hwm = max(0, _status("VmHWM") - base)
    return dt, max(hwm, traced)


def garment(n: int):
    na = int(round(np.sqrt(2.0 * n)))
    nh = max(2, int(round(n / na)))
    return frustum(na, nh, 0.16, 0.34, 1.02, 0.5)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--sizes", type=int, nargs="+", default=[1000, 4000, 16000, 64000])
    args = ap.parse_args()
    joints = np.load(ROOT / "samples" / "skeletons" / "tpose_joints_24.npy")
    rows: dict[str, list[tuple[int, float, int]]] = {}
    tmp = Path(tempfile.mkdtemp())
    for n in args.sizes:
        v, f = garment(n)
        n_real = len(v)
        write_obj(tmp / "g.obj", Mesh(vertices=v, faces=f))
        steps = [
            ("read OBJ", lambda: read_obj(tmp / "g.obj")),
            ("vertex normals", lambda: vertex_normals(v, f)),
            ("neighbour graph", lambda: neighbour_graph(f, n_real, vertices=v)),
            ("geodesic setup (LU)", lambda: GeodesicSolver(v, f)),
            ("descriptor (FPS+eig)", lambda: garment_descriptor(v, f)),
            ("vertex features", lambda: vertex_features(v, f, joints)),
            ("precompute (all)", lambda: precompute_garment(v, f, joints)),
        ]
        if n_real <= 5000:
            steps.append(("spectral bands*", lambda: SpectralBasis.from_mesh(v, f)))
        for name, fn in steps:
            dt, peak = measure(fn)
            rows.setdefault(name, []).append((n_real, dt, peak))
    print(f"{'step':22s} {'N':>7s} {'ms':>10s} {'peak MB':>9s} {'time x':>7s} {'mem x':>7s}")
    for name, rs in rows.items():
        prev = None
        for n_real, dt, peak in rs:
            tx = f"{dt / prev[1]:7.1f}" if prev and prev[1] > 0 else f"{'-':>7s}"
            mx = f"{peak / prev[2]:7.1f}" if prev and prev[2] > 0 else f"{'-':>7s}"
            print(f"{name:22s} {n_real:7d} {1e3 * dt:10.1f} {peak / 2**20:9.1f} {tx} {mx}")
            prev = (n_real, dt, peak)
    print("growth ratios are against the previous size (4x vertices). * evaluation only, not in `precompute`.")


if __name__ == "__main__":
    main()
