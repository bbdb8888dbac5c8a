"""Body collisions: the reference pass against the fast one, same garment, body and motion, one run.

    python bench/collisions.py [--sizes 1000 4000 16000] [--frames 60] [--batch 8] [--margin 0.004]
                               [--noise 0.003]

Garments are flared skirts (``geometry.primitives.frustum``, the garment of
``bench/effects.py``) at each size, skinned to a dance on the default body
(weights transferred from the body) with ``--noise`` metres of Gaussian jitter
per coordinate, so that a few percent of the vertices start inside the body or
closer than the margin, as a network's output does.  For every size, on the
same frames:

* ``reference``: :class:`BodyProxy` refitted to every frame (``moved``) and
  :func:`push_out`, as the runtime's ``collider="reference"``;
* ``fast``: one :class:`BodyCollider` (its build time is shown apart and
  included in the amortised column), one frame per call;
* ``fast xB``: the same, ``--batch`` frames per call, as the runtime calls it.

Columns: wall ms/frame (median of three passes over the frames), process CPU
ms/frame (same passes), the ratio to the reference, the fraction of garment
vertices inside the body after the push-out (measured with the exact query,
:meth:`BodyCollider.query`, for every output), the vertices moved, and the
largest and mean distance between each output and the reference's.  numpy
runs on one thread.
"""

from __future__ import annotations

import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")  # before numpy loads: one thread, as the runtime's default

import argparse  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]


def skirt(body, n: int):
    """A ~n-vertex flared skirt around the default body's hips, in its rest pose."""
    from segadeform.geometry.primitives import frustum

    na = int(round(np.sqrt(2.0 * n)))
    return frustum(na, max(2, n // na), 0.17, 0.36, 1.02, 0.5)[0]


def timed(fn, repeat: int):
    """Median wall and CPU seconds of ``repeat`` calls of ``fn``, and its last result."""
    walls, cpus = [], []
    for _ in range(repeat):
        w, c = time.perf_counter(), time.process_time()
        out = fn()
        walls.append(time.perf_counter() - w)
        cpus.append(time.process_time() - c)
    return float(np.median(walls)), float(np.median(cpus)), out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--sizes", type=int, nargs="+", default=[1000, 4000, 16000])
    ap.add_argument("--frames", type=int, default=60)
    ap.add_argument("--batch", type=int, default=8)
    ap.add_argument("--margin", type=float, default=0.004)
    ap.add_argument("--noise", type=float, default=0.003)
    ap.add_argument("--repeat", type=int, default=3)
    args = ap.parse_args()

    from segadeform.body import BodyProxy, load_body
    from segadeform.body.collision import BodyCollider, push_out
    from segadeform.body.transfer import skin_garment, transfer_weights
    from segadeform.motion import make_motion

    body = load_body(ROOT / "samples" / "bodies" / "default_body.npz")
    motion = make_motion("dance", seconds=args.frames / 30.0, seed=1)
    posed = body.forward(motion.poses, None, motion.trans).vertices
    nf = len(posed)
    rest_body = body.shaped_vertices()[0]

    w, c = time.perf_counter(), time.process_time()
    collider = BodyCollider(body.v_template, body.faces)
    build_wall, build_cpu = time.perf_counter() - w, time.process_time() - c

    print(f"body: {body.n_vertices} vertices, {len(body.faces)} triangles; dance, {nf} frames; margin "
          f"{args.margin} m; noise {args.noise} m; numpy threads {os.environ['OMP_NUM_THREADS']}; "
          f"median of {args.repeat}")
    print(f"BodyCollider build (once per run): {1e3 * build_wall:.1f} ms wall, {1e3 * build_cpu:.1f} ms CPU")
    head = (f"{'garment':>8s} {'pass':>10s} {'ms/frame':>9s} {'cpu ms':>8s} {'x ref':>7s} {'amortised':>9s} "
            f"{'inside %':>9s} {'moved':>7s} {'max diff':>10s} {'mean diff':>10s}")
    print(head)
    for n in args.sizes:
        rest = skirt(body, n)
        weights = transfer_weights(rest, rest_body, body.faces, body.weights)
        garment = skin_garment(rest, weights, body, motion.poses, None, motion.trans)
        garment = garment + np.random.default_rng(0).normal(scale=args.noise, size=garment.shape)

        def reference():
            out, moved, proxy = np.empty_like(garment), 0, None
            for i in range(nf):
                proxy = BodyProxy(posed[i], body.faces) if proxy is None else proxy.moved(posed[i])
                out[i], k = push_out(garment[i], proxy, args.margin)
                moved += k
            return out, moved

        def fast():
            out, moved = np.empty_like(garment), 0
            for i in range(nf):
                out[i], k = collider.push_out(garment[i], posed[i], args.margin)
                moved += k
            return out, moved

        def fast_batched():
            out, moved = np.empty_like(garment), 0
            for lo in range(0, nf, args.batch):
                out[lo:lo + args.batch], k = collider.push_out(garment[lo:lo + args.batch],
                                                               posed[lo:lo + args.batch], args.margin)
                moved += k
            return out, moved

        rows = [(name, *timed(fn, args.repeat)) for name, fn in
                (("reference", reference), ("fast", fast), (f"fast x{args.batch}", fast_batched))]
        ref_wall, ref_out = rows[0][1], rows[0][3][0]
        for name, wall, cpu, (out, moved) in rows:
            inside = sum(int((collider.query(out[i], posed[i]).signed_distance < 0).sum()) for i in range(nf))
            d = np.linalg.norm(out - ref_out, axis=-1)
            amort = wall + (0.0 if name == "reference" else build_wall)
            print(f"{garment.shape[1]:8d} {name:>10s} {1e3 * wall / nf:9.2f} {1e3 * cpu / nf:8.2f} "
                  f"{wall / ref_wall:7.3f} {1e3 * amort / nf:9.2f} {100 * inside / out[..., 0].size:9.3f} "
                  f"{moved:7d} {1e3 * d.max():8.5f}mm {1e3 * d.mean():8.6f}mm")
        start = garment
        before = sum(int((collider.query(start[i], posed[i]).signed_distance < 0).sum()) for i in range(nf))
        print(f"{garment.shape[1]:8d} {'(input)':>10s} {'':9s} {'':8s} {'':7s} {'':9s} "
              f"{100 * before / start[..., 0].size:9.3f}")


if __name__ == "__main__":
    main()
