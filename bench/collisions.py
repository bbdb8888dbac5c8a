"""Body collisions: the compiled kernel against the numpy BodyCollider and the reference, same garment, body
and motion, one run, passes interleaved.

    python bench/collisions.py [--sizes 4000] [--frames 60] [--batch 8] [--margin 0.004] [--noise 0.003]
                               [--repeat 5] [--threads 2]

Garments are flared skirts (``geometry.primitives.frustum``, the garment of
``bench/effects.py``; 4000 gives the 3,916-vertex skirt) skinned to a dance on
the default body (weights transferred from the body) with ``--noise`` metres of
Gaussian jitter per coordinate, so that a few percent of the vertices start
inside the body or closer than the margin, as a network's output does.  For
every size, on the same frames:

* ``reference``: :class:`BodyProxy` refitted to every frame (``moved``) and
  :func:`push_out`, as the runtime's ``collider=ReferenceCollider``;
* ``numpy``, ``numpy xB``: :class:`BodyCollider` with ``backend="numpy"`` (the
  runtime's collider before the compiled kernel), one frame per call, then
  ``--batch`` frames per call;
* ``compiled``, ``compiled xB``: ``backend="compiled"`` (``_collide.c``), one
  thread, one frame per call, then ``--batch`` frames per call (the runtime's
  collider); ``compiled xB tN``: the same on ``--threads`` threads.

Each repeat times every pass once, in turn (interleaved: the machine's load
falls on all of them alike).  Columns: wall ms/frame (median of the repeats),
process CPU ms/frame (all threads), the ratio to ``numpy xB`` and to the
reference (wall), ms/frame with the collider's build amortised over the frames,
the fraction of garment vertices inside the body after the push-out and deeper
than 2 mm inside, measured with the exact query of the numpy collider (the
brute-force answer by branch and bound; an implementation apart from the
kernel) for every output frame, the vertices moved, and the largest and mean
distance between each output and the reference's.  numpy runs on one thread.
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


def timed(fn):
    """Wall and CPU seconds of one call of ``fn``, and its result."""
    w, c = time.perf_counter(), time.process_time()
    out = fn()
    return time.perf_counter() - w, time.process_time() - c, out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--sizes", type=int, nargs="+", default=[4000])
    ap.add_argument("--frames", type=int, default=60)
    ap.add_argument("--batch", type=int, default=8)
    ap.add_argument("--margin", type=float, default=0.004)
    ap.add_argument("--noise", type=float, default=0.003)
    ap.add_argument("--repeat", type=int, default=5)
    ap.add_argument("--threads", type=int, default=2)
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

    builds = {}
    for backend in ("numpy", "compiled"):
        w = time.perf_counter()
        BodyCollider(body.v_template, body.faces, backend=backend)
        builds[backend] = time.perf_counter() - w
    colliders = {
        "numpy": BodyCollider(body.v_template, body.faces, backend="numpy"),
        "compiled": BodyCollider(body.v_template, body.faces, backend="compiled"),
        "threads": BodyCollider(body.v_template, body.faces, backend="compiled", threads=args.threads),
    }
    exact = colliders["numpy"]  # the inside check: exact, and apart from the kernel

    print(
        f"body: {body.n_vertices} vertices, {len(body.faces)} triangles; dance, {nf} frames; margin "
        f"{args.margin} m; noise {args.noise} m; numpy threads {os.environ['OMP_NUM_THREADS']}; "
        f"median of {args.repeat}, passes interleaved"
    )
    print(
        f"BodyCollider build (once per run): numpy {1e3 * builds['numpy']:.1f} ms, "
        f"compiled {1e3 * builds['compiled']:.1f} ms"
    )
    head = (
        f"{'garment':>8s} {'pass':>15s} {'ms/frame':>9s} {'cpu ms':>7s} {'x numpy xB':>10s} {'x ref':>6s} "
        f"{'amortised':>9s} {'inside %':>9s} {'>2mm %':>7s} {'moved':>7s} {'max diff':>10s} {'mean diff':>11s}"
    )
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

        def per_frame(collider):
            def run():
                out, moved = np.empty_like(garment), 0
                for i in range(nf):
                    out[i], k = collider.push_out(garment[i], posed[i], args.margin)
                    moved += k
                return out, moved

            return run

        def batched(collider):
            def run():
                out, moved = np.empty_like(garment), 0
                for lo in range(0, nf, args.batch):
                    out[lo : lo + args.batch], k = collider.push_out(
                        garment[lo : lo + args.batch], posed[lo : lo + args.batch], args.margin
                    )
                    moved += k
                return out, moved

            return run

        passes = [
            ("reference", reference, None),
            ("numpy", per_frame(colliders["numpy"]), "numpy"),
            (f"numpy x{args.batch}", batched(colliders["numpy"]), "numpy"),
            ("compiled", per_frame(colliders["compiled"]), "compiled"),
            (f"compiled x{args.batch}", batched(colliders["compiled"]), "compiled"),
            (f"compiled x{args.batch} t{args.threads}", batched(colliders["threads"]), "compiled"),
        ]
        walls = {name: [] for name, _, _ in passes}
        cpus = {name: [] for name, _, _ in passes}
        results = {}
        for _ in range(args.repeat):
            for name, fn, _ in passes:
                wall, cpu, results[name] = timed(fn)
                walls[name].append(wall)
                cpus[name].append(cpu)
        wall = {k: float(np.median(x)) for k, x in walls.items()}
        base = wall[f"numpy x{args.batch}"]
        ref_out = results["reference"][0]
        checked = []  # (output, inside, deep): outputs that are bit-identical share one check

        def inside_fractions(out):
            for o, a, b in checked:
                if np.array_equal(o, out):
                    return a, b
            sd = np.concatenate([exact.query(out[i], posed[i]).signed_distance for i in range(nf)])
            checked.append((out, float((sd < 0).mean()), float((sd < -0.002).mean())))
            return checked[-1][1:]

        for name, _, backend in passes:
            out, moved = results[name]
            inside, deep = inside_fractions(out)
            d = np.linalg.norm(out - ref_out, axis=-1)
            amort = wall[name] + (builds[backend] if backend else 0.0)
            print(
                f"{garment.shape[1]:8d} {name:>15s} {1e3 * wall[name] / nf:9.2f} "
                f"{1e3 * np.median(cpus[name]) / nf:7.2f} {wall[name] / base:10.3f} "
                f"{wall[name] / wall['reference']:6.3f} {1e3 * amort / nf:9.2f} {100 * inside:9.3f} "
                f"{100 * deep:7.3f} {moved:7d} {1e3 * d.max():8.5f}mm {1e3 * d.mean():9.6f}mm"
            )
        inside, deep = inside_fractions(garment)
        print(
            f"{garment.shape[1]:8d} {'(input)':>15s} {'':9s} {'':7s} {'':10s} {'':6s} {'':9s} "
            f"{100 * inside:9.3f} {100 * deep:7.3f}"
        )


if __name__ == "__main__":
    main()
