"""Per-frame defects of a `segadeform run` output against its posed body: where a limb shows through the cloth.

    .venv/bin/python tools/run_defects.py GARMENT.obj OUT.pc2 BODY.pc2 [--worst 8]

``OUT.pc2`` and ``BODY.pc2`` come from one `segadeform run ... -o OUT.pc2 --body-out BODY.pc2` (metres, +Y up) on the
default body.  Per frame: vertices more than 1 mm inside the body; faces whose centre is more than 5 mm inside while
every corner is outside (a limb straddled by the cloth: what a render shows as a hole); the largest edge stretch
against the garment at rest and the edges stretched past 100 % and 20 %.  Prints the sums over the clip and the
worst frames (by straddled faces plus edges past 100 %).
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))


def defects(x: np.ndarray, faces: np.ndarray, edges: np.ndarray, rest_len: np.ndarray, posed: np.ndarray, collider):
    """Per frame: (vertices inside, straddled faces, largest stretch %, edges past 100 %, edges past 20 %).
    Shapes: x (T, N, 3), faces (F, 3), edges (E, 2), rest_len (E,), posed (T, V, 3) -> (T, 5)."""
    out = np.zeros((len(x), 5))
    for t in range(len(x)):
        sd = collider.query(x[t], posed[t]).signed_distance
        sc = collider.query(x[t][faces].mean(axis=1), posed[t]).signed_distance
        stretch = np.linalg.norm(x[t][edges[:, 0]] - x[t][edges[:, 1]], axis=1) / np.maximum(rest_len, 1e-9) - 1.0
        out[t] = (
            (sd < -0.001).sum(),
            ((sc < -0.005) & (sd[faces] >= -0.001).all(axis=1)).sum(),
            100.0 * stretch.max(),
            (stretch > 1.0).sum(),
            (stretch > 0.2).sum(),
        )
    return out


def main(argv=None) -> int:
    from segadeform.body import default_body_path, load_body
    from segadeform.body.collision.collider import BodyCollider
    from segadeform.geometry.mesh_ops import unique_edges
    from segadeform.io import read_mesh, read_pc2

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("garment")
    ap.add_argument("result")
    ap.add_argument("body")
    ap.add_argument("--worst", type=int, default=8)
    a = ap.parse_args(argv)
    g = read_mesh(a.garment)
    x = read_pc2(a.result).frames.astype(np.float64)
    posed = read_pc2(a.body).frames.astype(np.float64)
    body = load_body(default_body_path())
    faces = np.asarray(g.faces, np.int64)
    edges = unique_edges(faces)
    rest_len = np.linalg.norm(g.vertices[edges[:, 0]] - g.vertices[edges[:, 1]], axis=1)
    r = defects(x, faces, edges, rest_len, posed, BodyCollider(posed[0], body.faces))
    print(f"{a.result}: {len(r)} frames, {len(g.vertices)} vertices, {len(faces)} faces")
    print(
        f"sums: vertices inside {r[:, 0].sum():.0f}, straddled faces {r[:, 1].sum():.0f}, edges past 100 % "
        f"{r[:, 3].sum():.0f}, past 20 % {r[:, 4].sum():.0f}; largest stretch {r[:, 2].max():.0f} %"
    )
    for t in sorted(np.argsort(-(r[:, 1] + r[:, 3]))[: a.worst]):
        print(
            f"  frame {t:4d}: inside {r[t, 0]:4.0f}  straddled {r[t, 1]:4.0f}  largest {r[t, 2]:6.0f} %  "
            f"past 100 % {r[t, 3]:4.0f}  past 20 % {r[t, 4]:4.0f}"
        )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
