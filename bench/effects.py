"""What each effect costs: ms per frame of every effect combination, one thread (``--threads``).

    python bench/effects.py [--vertices 4000] [--frames 60] [--steady 300] [--batch 8] [--threads 1] [--package DIR]

A ~4k-vertex skirt on the default body, a dance; the model package is a random-weight export unless
``--package`` is given (the cost does not depend on the weights).  Each row is a full ``Run`` (the
garment asset, its encoding and the body's weights at the garment cached beforehand, as on any second
run of a garment), writing PC2 to a temporary folder, done twice: with ``--frames`` and with
``--steady`` frames of the same motion.  From the two:

* ``ms/frame @F``: the whole run of ``--frames`` frames divided by them (what a short clip costs);
* ``steady``: the cost of one more frame, ``(t_steady - t_F) / (steady - F)`` (what a long motion costs
  per frame; the frames per second a stream sustains), with the deform / pose / collide stages the same way;
* ``fixed ms``: what a run costs before its frames, ``t_F - F x steady`` (creating the sessions and
  onnxruntime's first calls, which grow its memory arena).

Rows with the cloth stage (``cloth``: :mod:`segadeform.body.cloth` at its default settings, which replaces the
push-out) follow the 16 combinations; a section then times the stage alone, steady, median of 3 (``--cloth K=V,..``
for other knobs).  Ratios are against "all effects on" measured in the same run.  The collision stage is then timed for
the reference (BodyProxy per frame), the numpy BodyCollider and the compiled one (the runtime's), runs
interleaved.  A final section streams ``--long`` frames (default 10,000) with LBS and dynamics (no
wrinkles, no collisions) in a fresh process and reports its peak resident memory (its own ``VmHWM``, not
the parent's: ``bench/_peak.py``) against a 100-frame run in another fresh process: flat memory means the ratio stays
near 1 while the output grows 100x.
"""

from __future__ import annotations

import argparse
import itertools
import os
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]


def _hwm_reset():
    try:
        with open("/proc/self/clear_refs", "w") as fh:
            fh.write("5")
        return True
    except OSError:
        return False


def _status(key):
    for line in open("/proc/self/status"):
        if line.startswith(key):
            return int(line.split()[1]) * 1024
    return 0


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--vertices", type=int, default=4000)
    ap.add_argument("--frames", type=int, default=60)
    ap.add_argument("--steady", type=int, default=300, help="frames of the second run of each row (> --frames)")
    ap.add_argument("--batch", type=int, default=8)
    ap.add_argument("--threads", type=int, default=1, help="onnxruntime and collision threads per run")
    ap.add_argument("--package", type=Path)
    ap.add_argument("--long", type=int, default=10000)
    ap.add_argument("--cloth", default="", help="the cloth stage's knobs for its rows (default: its defaults)")
    ap.add_argument(
        "--repeats",
        type=int,
        default=3,
        help="runs of each length per row; the fastest is kept (a busy machine gave negative differences of one)",
    )
    ap.add_argument("--child-long", type=int, help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.child_long:
        child_long(args.child_long, args.package, args.vertices, args.batch)
        return

    from segadeform.body import load_body
    from segadeform.body.collision import BodyCollider, ReferenceCollider
    from segadeform.geometry.primitives import frustum
    from segadeform.io import Mesh, write_obj
    from segadeform.motion import make_motion
    from segadeform.runtime import ModelPackage
    from segadeform.runtime.pipeline import Run
    from segadeform.settings import Effects

    tmp = Path(tempfile.mkdtemp())
    pkg = args.package
    if pkg is None:
        import torch

        from segadeform.export import export_package
        from segadeform.model import ModelConfig, SEGANet

        torch.manual_seed(0)
        pkg = tmp / "pkg"
        export_package(SEGANet(ModelConfig()), pkg, check=False)
    body = load_body(ROOT / "samples" / "bodies" / "default_body.npz")
    na = int(round(np.sqrt(2.0 * args.vertices)))
    v, f = frustum(na, max(2, args.vertices // na), 0.17, 0.36, 1.02, 0.5)
    garment = tmp / "skirt.obj"
    write_obj(garment, Mesh(vertices=v, faces=f))
    if args.steady <= args.frames:
        raise SystemExit(f"--steady must be more than --frames, got {args.steady} <= {args.frames}")
    motion = make_motion("dance", seconds=args.steady / 30.0, seed=1)

    def run(effects, frames=args.frames, out="o.pc2", cache=True, collider=BodyCollider):
        r = Run(
            garment=garment,
            motion=motion,
            package=ModelPackage(pkg, threads=args.threads),
            body=body,
            effects=effects,
            output=tmp / out,
            batch=args.batch,
            cache=cache,
            force=True,
            collider=collider,
            frames=(0, frames),
        )
        return r.execute()

    run(Effects())  # warm the precompute, encoder and body-weights caches
    from segadeform.settings.cloth import ClothSettings

    knobs = ClothSettings.parse(args.cloth)
    stages = ("deform", "pose body", "collisions", "cloth")

    def measure(e):
        # the fastest of --repeats runs of each length: what other work on the machine adds is never negative, so the
        # minimum is the least disturbed run (the difference of single runs went negative under load)
        short = min((run(e) for _ in range(max(1, args.repeats))), key=lambda r: r.seconds)
        long = min((run(e, frames=motion.n_frames) for _ in range(max(1, args.repeats))), key=lambda r: r.seconds)
        df = long.frames - short.frames
        steady = 1e3 * (long.seconds - short.seconds) / df
        st = {k: 1e3 * (long.stage_seconds[k] - short.stage_seconds[k]) / df for k in stages}
        return e, short.ms_per_frame, steady, 1e3 * short.seconds - short.frames * steady, st

    rows = [
        measure(Effects(skinning=skin, dynamics=dyn, wrinkles=wr, collisions=col))
        for skin, dyn, wr, col in itertools.product(("lbs", "dqs"), (True, False), (True, False), (True, False))
    ]
    rows += [
        measure(Effects(cloth=True, cloth_settings=knobs)),
        measure(Effects(dynamics=False, wrinkles=False, cloth=True, cloth_settings=knobs)),
    ]
    noisy = [r for r in rows if r[2] <= 0 or r[3] < 0]
    if noisy:  # said before the table, not read off it
        print(
            f"warning: {len(noisy)} row(s) have a steady cost <= 0 or a negative fixed cost: the machine was too busy "
            f"to time them (load average {os.getloadavg()[0]:.2f}); run again with more --repeats on an idle machine"
        )
    base = next(r for r in rows if r[0] == Effects())
    print(
        f"garment: {len(v)} vertices; body: {body.n_vertices} vertices; {args.frames} and {args.steady} frames; "
        f"batch {args.batch}; {args.threads} thread(s)"
    )
    print(
        f"{'skinning':8s} {'dynamics':>8s} {'wrinkles':>8s} {'collisions':>10s} {'cloth':>6s} "
        f"{'ms/frame@' + str(args.frames):>12s} {'steady':>7s} {'x all-on':>8s} {'fps':>6s} {'fixed ms':>8s} "
        f"{'deform':>7s} {'pose':>6s} {'collide':>8s} {'cloth':>6s}"
    )
    for e, ms, steady, fixed, st in rows:
        print(
            f"{e.skinning:8s} {str(e.dynamics):>8s} {str(e.wrinkles):>8s} "
            f"{str(e.collisions and not e.cloth):>10s} {str(e.cloth):>6s} {ms:12.2f} "
            f"{steady:7.2f} {steady / base[2]:8.2f} {1e3 / steady:6.0f} {fixed:8.1f} {st['deform']:7.2f} "
            f"{st['pose body']:6.2f} {st['collisions']:8.2f} {st['cloth']:6.2f}"
        )
    # the cloth stage alone, steady (its setup and the collider's build excluded by the two run lengths), at its
    # settings, median of 3, against the push-out of the same runs (all effects on)
    cl, po = [], []
    for _ in range(3):
        cl.append(measure(Effects(cloth=True, cloth_settings=knobs))[4]["cloth"])
        po.append(measure(Effects())[4]["collisions"])
    print(
        f"cloth stage ({knobs.label() or 'default settings'}; all effects on; {len(v)} vertices; one thread), "
        f"steady, median of 3: {np.median(cl):.2f} ms/frame (runs {', '.join(f'{x:.2f}' for x in cl)}); the "
        f"push-out it replaces {np.median(po):.2f} ms/frame; x push-out {np.median(cl) / np.median(po):.2f}; "
        f"load average {os.getloadavg()[0]:.2f}"
    )
    # the stage alone on one run's deformer frames and posed body (as the pipeline gives them: float32), timed by the
    # wall clock and by this thread's CPU time (which other work on the machine inflates far less), median of 3
    from segadeform.body.cloth import ClothStage, garment_setup
    from segadeform.io import read_pc2 as _read

    Run(
        garment=garment,
        motion=motion,
        package=ModelPackage(pkg, threads=args.threads),
        body=body,
        effects=Effects(collisions=False),
        output=tmp / "raw.pc2",
        body_output=tmp / "raw_body.pc2",
        batch=args.batch,
        cache=True,
        force=True,
    ).execute()
    y, posed = np.asarray(_read(tmp / "raw.pc2").frames), np.asarray(_read(tmp / "raw_body.pc2").frames)
    setup = garment_setup(v, f, body.shaped_vertices()[0], body.faces, knobs)
    wall, cpu = [], []
    for _ in range(3):
        stage = ClothStage(setup, body.v_template, body.faces, knobs, dt=1 / motion.fps)
        w0, c0 = time.perf_counter(), time.thread_time()
        for lo in range(0, len(y), args.batch):
            stage.step(y[lo : lo + args.batch], posed[lo : lo + args.batch])
        wall.append(1e3 * (time.perf_counter() - w0) / len(y))
        cpu.append(1e3 * (time.thread_time() - c0) / len(y))
    print(
        f"cloth stage alone on {len(y)} frames of that run (collider built, setup cached): "
        f"{np.median(wall):.2f} ms/frame wall, {np.median(cpu):.2f} ms/frame CPU (this thread), median of 3; "
        f"{stage.contacts / len(y):.0f} vertices in contact per frame; load average {os.getloadavg()[0]:.2f}"
    )
    # the collision pass, all effects on: the reference (BodyProxy rebuilt per frame), the numpy BodyCollider
    # and the compiled one (the runtime's), interleaved, median of 3; outputs compared with the reference's
    import functools

    import segadeform.runtime.pipeline as pipeline
    from segadeform.body.collision import BodyCollider
    from segadeform.io import read_pc2

    def collide(kind):
        if kind == "reference":
            return run(Effects(), collider=ReferenceCollider, out=f"{kind}.pc2")
        pipeline.BodyCollider = functools.partial(BodyCollider, backend=kind)
        try:
            return run(Effects(), out=f"{kind}.pc2")
        finally:
            pipeline.BodyCollider = BodyCollider

    kinds = ("reference", "numpy", "compiled")
    times = {k: [] for k in kinds}
    summary = {}
    for _ in range(3):
        for k in kinds:
            summary[k] = collide(k)
            times[k].append(summary[k].stage_seconds["collisions"] / summary[k].frames)
    ms = {k: 1e3 * float(np.median(t)) for k, t in times.items()}
    frames = {k: np.asarray(read_pc2(tmp / f"{k}.pc2").frames) for k in kinds}
    print(f"collisions (all effects on, {args.threads} thread(s), median of 3 interleaved runs):")
    for k in kinds:
        print(
            f"  {k:9s} {ms[k]:7.2f} ms/frame  x numpy {ms[k] / ms['numpy']:6.3f}  whole frame "
            f"{summary[k].ms_per_frame:7.2f} ms  pushed {summary[k].pushed_vertices:6d}  max diff from the "
            f"reference {1e3 * np.abs(frames[k] - frames['reference']).max():.4f} mm"
        )
    if args.long:
        import subprocess
        import sys

        peaks = {}
        for n in (100, args.long):
            p = subprocess.run(
                [
                    sys.executable,
                    __file__,
                    "--child-long",
                    str(n),
                    "--package",
                    str(pkg),
                    "--vertices",
                    str(args.vertices),
                    "--batch",
                    str(args.batch),
                ],
                capture_output=True,
                text=True,
                check=True,
            )
            rss, ms, size = (float(x) for x in p.stdout.split())
            peaks[n] = rss
            print(
                f"{n:6d} frames (lbs + dynamics, fresh process): {ms:.2f} ms/frame, peak RSS {rss / 2**20:.1f} MiB, "
                f"output {size / 2**20:.1f} MiB"
            )
        print(
            f"peak memory ratio {args.long} vs 100 frames: {peaks[args.long] / peaks[100]:.3f} "
            f"(the output file grows {args.long / 100:.0f}x)"
        )


def child_long(n: int, pkg: Path, vertices: int, batch: int) -> None:
    """Stream n frames in this (fresh) process; print peak RSS bytes, ms/frame, output bytes."""
    from _peak import peak_rss_bytes

    from segadeform.body import load_body
    from segadeform.geometry.primitives import frustum
    from segadeform.io import Mesh, write_obj
    from segadeform.motion import make_motion
    from segadeform.runtime import ModelPackage
    from segadeform.runtime.pipeline import Run
    from segadeform.settings import Effects

    tmp = Path(tempfile.mkdtemp())
    na = int(round(np.sqrt(2.0 * vertices)))
    v, f = frustum(na, max(2, vertices // na), 0.17, 0.36, 1.02, 0.5)
    write_obj(tmp / "g.obj", Mesh(vertices=v, faces=f))
    m = make_motion("walk", seconds=n / 30.0, seed=0)
    run = Run(
        garment=tmp / "g.obj",
        motion=m,
        package=ModelPackage(pkg),
        effects=Effects(wrinkles=False, collisions=False),
        body=load_body(ROOT / "samples" / "bodies" / "default_body.npz"),
        output=tmp / "o.pc2",
        batch=batch,
        cache=False,
        force=True,
    )
    t0 = time.perf_counter()
    run.execute()
    dt = time.perf_counter() - t0
    rss = peak_rss_bytes()
    print(rss, 1e3 * dt / n, os.path.getsize(tmp / "o.pc2"))


if __name__ == "__main__":
    main()
