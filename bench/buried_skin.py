"""The push-out's rule for buried skin, measured on a dataset's frames: the collision kernel against an earlier
build of it, same frames, passes interleaved.

    python bench/buried_skin.py DATASET [--split test] [--prefix dress top] [--samples 4] [--margin 0.004]
                                [--repeat 3] [--old-kernel OLD.so]

Where the posed body intersects itself (an arm pressed into the torso), a vertex inside the torso can be nearest
the arm's buried skin, whose side says outside: the push-out used to leave it there.  The kernel now takes such a
vertex (inside by the body's winding number, outside by its closest surface) to the nearest skin that is not buried
(``src/segadeform/body/_collide.c``, "buried").  For each sample (the first ``--samples`` of the split whose ids
start with a ``--prefix``) the Blender frames are pushed out of the posed body at ``--margin``, and this prints
per kernel: CPU ms/frame (the best of ``--repeat``), the vertex-frames moved, and those still inside the body by
its winding number afterwards; with the ratios of the current kernel to the old one.

``--old-kernel``: a shared library built from an earlier ``_collide.c`` with the same flags, e.g. the one before
the rule (commit bcc8f7b)::

    git show bcc8f7b:src/segadeform/body/_collide.c > /tmp/old_collide.c
    gcc -O2 -fPIC -shared -ffp-contract=off -std=c99 -o /tmp/old_collide.so /tmp/old_collide.c -lm

Without it only the current kernel is measured.
"""

from __future__ import annotations

import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import argparse  # noqa: E402
import ctypes  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402


def _load(path: str | None):
    """The ctypes library of the kernel at ``path`` (None: the installed one), signatures set."""
    from segadeform.body.collision import compiled

    if path is None:
        compiled._KERNEL.clear()
        lib, why = compiled.load_kernel()
        if lib is None:
            raise SystemExit(f"the compiled kernel is not available: {why}")
        return lib
    lib = ctypes.CDLL(path)
    installed, _ = compiled.load_kernel()
    for name in (
        "sdc_create",
        "sdc_free",
        "sdc_n_nodes",
        "sdc_depth",
        "sdc_closed",
        "sdc_refit",
        "sdc_query",
        "sdc_push_out",
        "sdc_winding",
    ):
        fn, ref = getattr(lib, name), getattr(installed, name)
        fn.restype, fn.argtypes = ref.restype, ref.argtypes
    return lib


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("dataset", type=Path)
    ap.add_argument("--split", default="test")
    ap.add_argument("--prefix", nargs="+", default=["dress", "top"])
    ap.add_argument("--samples", type=int, default=4)
    ap.add_argument("--margin", type=float, default=0.004)
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--old-kernel")
    args = ap.parse_args()

    from segadeform.body import default_body_path, load_body
    from segadeform.body.collision import BodyCollider, compiled
    from segadeform.dataset.store import list_samples, load_sample

    kernels = {"current": _load(None)}
    if args.old_kernel:
        kernels["old"] = _load(args.old_kernel)
    winding = BodyCollider  # the winding number is always the current kernel's (the old one may lack it)
    body = load_body(default_body_path())
    ids = [i for i in list_samples(args.dataset, args.split) if i.startswith(tuple(args.prefix))][: args.samples]
    if not ids:
        raise SystemExit(f"{args.dataset}: no {args.split} sample starts with {args.prefix}")
    rows = {}
    for sid in ids:
        s = load_sample(args.dataset, sid)
        posed = body.forward(s.poses, s.betas if s.betas.size else None, s.trans).vertices
        pts = s.frames.astype(np.float64)
        for _ in range(args.repeat):
            for tag, lib in kernels.items():  # interleaved: the machine's load falls on both alike
                compiled._KERNEL.update(lib=lib, why="")
                col = BodyCollider(body.v_template, body.faces, backend="compiled")
                t = time.process_time()
                out, moved = col.push_out(pts, posed, args.margin)
                t = (time.process_time() - t) / len(pts) * 1e3
                rows.setdefault((sid, tag), []).append((t, moved, out))
        compiled._KERNEL.update(lib=kernels["current"], why="")
        judge = winding(body.v_template, body.faces, backend="compiled")
        print(f"{sid}: {pts.shape[1]} vertices, {len(pts)} frames")
        for tag in kernels:
            runs = rows[(sid, tag)]
            out = runs[0][2]
            inside = int(sum((judge.winding(out[k], posed[k]) > 0).sum() for k in range(len(pts))))
            before = int(sum((judge.winding(pts[k], posed[k]) > 0).sum() for k in range(len(pts))))
            rows[(sid, tag)] = (min(r[0] for r in runs), runs[0][1], inside, before)
            ms, moved, inside, before = rows[(sid, tag)]
            print(f"  {tag:8s} {ms:6.2f} ms/frame  moved {moved:6d}  inside after {inside:6d}  (before {before})")
        if "old" in kernels:
            new, old = rows[(sid, "current")], rows[(sid, "old")]
            print(f"  current / old: time {new[0] / old[0]:.2f}, inside after {new[2] / max(old[2], 1):.2f}")


if __name__ == "__main__":
    main()
