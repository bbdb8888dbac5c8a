"""Descriptor choices measured: Nyström accuracy and stability against N*.

    python bench/descriptor.py

For each shape, the full N x N geodesic Gaussian affinity is formed densely
(small meshes only) and its eigenvalues compared with the Nyström estimate
from N* furthest-point samples.  Columns: N* | time of the descriptor (ms) |
ratio of that time to N* = 16 | max |lambda_k - est_k| / lambda_1 over the top 10
| lambda_1 / N* of the descriptor | lambda_1 / N of the full affinity | share of
the full spectrum's absolute mass that is negative.
"""

from __future__ import annotations

import time
from pathlib import Path

import numpy as np

from segadeform.geometry import GeodesicSolver, garment_descriptor, nystrom_eigen
from segadeform.geometry.descriptor import gaussian_affinity
from segadeform.geometry.primitives import frustum, grid_plane
from segadeform.io import read_mesh

ROOT = Path(__file__).resolve().parents[1]


def main() -> None:
    skirt = read_mesh(ROOT / "samples" / "garments" / "skirt.obj")
    shapes = {
        "skirt": (skirt.vertices, skirt.faces),
        "plane 25x25": grid_plane(25, 25),
        "long tube": frustum(30, 40, 0.1, 0.1, 1.0, 0.0),
    }
    print(
        f"{'shape':12s} {'N':>5s} {'N*':>4s} {'ms':>7s} {'x(16)':>6s} {'nys err/l1':>10s} "
        f"{'l1/N*':>6s} {'l1/N':>6s} {'neg':>6s}"
    )
    for name, (v, f) in shapes.items():
        solver = GeodesicSolver(v, f)
        dist = solver(np.arange(len(v)))
        base = None
        for ns in (16, 32, 64):
            t0 = time.perf_counter()
            d = garment_descriptor(v, f, n_star=ns, solver=solver)
            ms = 1e3 * (time.perf_counter() - t0)
            base = base or ms
            full = np.linalg.eigvalsh(gaussian_affinity(0.5 * (dist + dist.T), d.radius))[::-1]
            lam, _ = nystrom_eigen(d, 10)
            err = np.max(np.abs(lam - full[: len(lam)])) / full[0]
            neg = -full[full < 0].sum() / np.abs(full).sum()
            print(
                f"{name:12s} {len(v):5d} {ns:4d} {ms:7.1f} {ms / base:6.2f} {100 * err:9.3f}% "
                f"{d.eigenvalues[0] / ns:6.3f} {full[0] / len(v):6.3f} {100 * neg:5.1f}%"
            )


if __name__ == "__main__":
    main()
