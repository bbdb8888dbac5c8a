"""How far apart does a run take the two copies of a vertex split at a seam?  The sample dress is split along its
centre line as a game engine's export splits vertices at UV seams (``tests.conftest.split_at_a_seam``), run with
``segadeform run --quality balanced`` and ``--quality best`` over frames 0:60, and each copy's distance from its twin
is printed per preset (largest, median, frames with a gap over 1 mm)::

    .venv/bin/python tools/seam_twins.py [MOTION] -o runs/seam

MOTION defaults to ``samples/motions/walk.npz``.  ``docs/hard-cases.md`` ("a garment split at its seams") quotes it.
"""

from __future__ import annotations

import argparse
import subprocess
import sys
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))


def main(argv=None) -> int:
    from scipy.spatial import cKDTree

    from segadeform.io import Mesh, read_mesh, read_pc2, write_obj
    from tests.conftest import SAMPLES, split_at_a_seam

    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("motion", nargs="?", default=str(SAMPLES / "motions" / "walk.npz"))
    ap.add_argument("-o", "--out", required=True, help="a new folder for the split garment and the runs' caches")
    a = ap.parse_args(argv)
    out = Path(a.out)
    out.mkdir(parents=True, exist_ok=False)  # never over a folder it did not make
    m = read_mesh(SAMPLES / "garments" / "dress.obj")
    v, f, n = split_at_a_seam(m)
    garment = out / "split.obj"
    write_obj(garment, Mesh(v, f))
    twin = cKDTree(m.vertices).query(v[len(m.vertices) :])[1]
    exe = Path(sys.executable).with_name("segadeform")
    for q in ("balanced", "best"):
        pc2 = out / f"{q}.pc2"
        cmd = [str(exe), "run", "--garment", str(garment), "--motion", a.motion, "--quality", q, "-o", str(pc2)]
        subprocess.run([*cmd, "--no-cache", "--frames", "0:60"], check=True, capture_output=True)
        fr = read_pc2(pc2).frames
        gap = np.linalg.norm(fr[:, len(m.vertices) :] - fr[:, twin], axis=-1)
        print(
            f"{q}: {n} copies, gap max {gap.max():.4f} m, median {np.median(gap):.6f} m, "
            f"frames with a gap over 1 mm {(gap.max(1) > 1e-3).sum()}"
        )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
