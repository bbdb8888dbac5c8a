"""Regenerate the small sample files in this folder (deterministic).

    python samples/make_samples.py

Paths are relative to this file, so it runs from any working directory.
The outputs are committed; this script documents how they were made.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from segadeform.body.skeleton import default_rest_joints
from segadeform.geometry.primitives import frustum

HERE = Path(__file__).resolve().parent


def write_skirt_obj(path: Path, n_around: int = 64, n_rings: int = 24) -> None:
    """A flared skirt (open tube from the waist to below the knee), written the way DCC
    tools export: quads, a UV seam (one more ``vt`` column than vertices around),
    ``vn`` normals, groups, a ``usemtl`` line, and negative (relative) indices for
    the second half of the faces.  No ``mtllib`` line: it would name a file that is
    not shipped (Blender's OBJ importer logs an error for it)."""
    v, _ = frustum(n_around, n_rings, 0.16, 0.34, 1.02, 0.50)
    lines = ["# segadeform sample: flared skirt, metres, +Y up", "o skirt", "g skirt_body"]
    lines += [f"v {x:.6f} {y:.6f} {z:.6f}" for x, y, z in v]
    for r in range(n_rings):
        for a in range(n_around + 1):  # UV seam: the first column is repeated at u = 1
            lines.append(f"vt {a / n_around:.6f} {1 - r / (n_rings - 1):.6f}")
    radial = v.copy()
    radial[:, 1] = 0.0
    radial /= np.linalg.norm(radial, axis=1, keepdims=True)
    lines += [f"vn {x:.6f} {y:.6f} {z:.6f}" for x, y, z in radial]
    lines += ["usemtl cotton", "s 1"]
    n_v = len(v)
    n_vt = n_rings * (n_around + 1)
    half = (n_rings - 1) // 2
    for r in range(n_rings - 1):
        if r == half:
            lines.append("g skirt_hem")
        for a in range(n_around):
            b = (a + 1) % n_around
            quad_v = [r * n_around + a, r * n_around + b, (r + 1) * n_around + b, (r + 1) * n_around + a]
            quad_t = [
                r * (n_around + 1) + a,
                r * (n_around + 1) + a + 1,
                (r + 1) * (n_around + 1) + a + 1,
                (r + 1) * (n_around + 1) + a,
            ]
            if r < half:
                corners = [f"{i + 1}/{t + 1}/{i + 1}" for i, t in zip(quad_v, quad_t, strict=True)]
            else:  # relative indices: -1 is the last vertex/texcoord/normal defined so far
                corners = [f"{i - n_v}/{t - n_vt}/{i - n_v}" for i, t in zip(quad_v, quad_t, strict=True)]
            lines.append("f " + " ".join(corners))
    path.write_text("\n".join(lines) + "\n", encoding="utf-8")


def main() -> None:
    (HERE / "garments").mkdir(exist_ok=True)
    (HERE / "skeletons").mkdir(exist_ok=True)
    write_skirt_obj(HERE / "garments" / "skirt.obj")
    np.save(HERE / "skeletons" / "tpose_joints_24.npy", default_rest_joints())


if __name__ == "__main__":
    main()
