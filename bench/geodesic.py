"""Geodesic distance error against analytic distances, heat method vs edge Dijkstra.

    python bench/geodesic.py

Sources at the centre of a flat grid (and a jittered one) and on a cylinder
of unit radius; exact distances are Euclidean on the plane and
``sqrt((r dphi)^2 + dy^2)`` on the cylinder.  Columns: mean |d - exact| and
max |d - exact| as a fraction of the largest exact distance, the median
relative error, and the time of one solver setup plus one source.
"""

from __future__ import annotations

import time

import numpy as np

from segadeform.geometry.geodesic import GeodesicSolver
from segadeform.geometry.primitives import cylinder, grid_plane


def cylinder_exact(v, p):
    a = np.arctan2(v[:, 2], v[:, 0]) - np.arctan2(p[2], p[0])
    return np.hypot(np.abs((a + np.pi) % (2 * np.pi) - np.pi), v[:, 1] - p[1])


def main() -> None:
    cases = []
    for n in (21, 61):
        for jit in (0.0, 0.4):
            v, f = grid_plane(n, n, jitter=jit)
            cases.append(
                (
                    f"plane {n}x{n}" + (" jittered" if jit else ""),
                    v,
                    f,
                    (n // 2) * n + n // 2,
                    lambda v, p: np.linalg.norm(v - p, axis=1),
                )
            )
    for na, nh in ((40, 13), (120, 39)):
        v, f = cylinder(na, nh, 1.0, 2 * np.pi / na * (nh - 1))
        cases.append((f"cylinder {na}x{nh}", v, f, (nh // 2) * na, cylinder_exact))
    print(f"{'mesh':22s} {'method':9s} {'N':>6s} {'mean/diam':>10s} {'max/diam':>9s} {'median rel':>11s} {'ms':>7s}")
    for name, v, f, src, exact_fn in cases:
        exact = exact_fn(v, v[src])
        for method in ("heat", "dijkstra"):
            t0 = time.perf_counter()
            d = GeodesicSolver(v, f, method=method)([src])[0]
            ms = 1e3 * (time.perf_counter() - t0)
            m = exact > 1e-9
            print(
                f"{name:22s} {method:9s} {len(v):6d} {np.abs(d - exact).mean() / exact.max():10.4f} "
                f"{np.abs(d - exact).max() / exact.max():9.4f} {np.median(np.abs(d[m] - exact[m]) / exact[m]):11.4f} "
                f"{ms:7.1f}"
            )


if __name__ == "__main__":
    main()
