"""Cost against garment size: ms per frame of each stage and peak memory at N = 1k, 4k, 16k, 64k vertices.

    python bench/scaling.py [--sizes 1000,4000,16000,64000] [--frames 30] [--batch 8] [--package DIR]
                            [--blender-max 4000]

A skirt-like frustum of N vertices on the default body, a dance of ``--frames`` frames, the shipped
model, one onnxruntime thread; each size runs in a fresh process with an empty user cache (its peak
resident memory is its own ``VmHWM``, ``bench/_peak.py``, and includes encoding the garment, as on its first
run): precompute (graph, features, descriptor; once per garment), then ``segadeform run``'s pipeline with
every effect, again without collisions, and again with the cloth stage (default settings, in place of the
push-out), each run twice and the second (warm) one timed; ``cloth ms`` is the stage's own steady time per frame
(from runs of ``--frames`` and twice as many frames: its fixed per-run cost, the body collider's build and the
cached setup, cancels), and ``cloth cpu`` the stage alone on such a run's frames by this thread's CPU time.  ``x per
vertex`` is the per-frame cost divided by N, against
the smallest size's (1.00 = linear growth).  For sizes up to ``--blender-max`` the same garment and
motion are simulated by Blender (the dataset's settings, ``segadeform simulate``'s path) and its
seconds per simulated frame (measured inside Blender, start-up excluded) are given, with the learned pipeline's
speed-up over it.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def one(n: int, frames: int, batch: int, package: str, blender: bool) -> dict:
    """Measure size ``n`` in this process; returns the row."""
    import numpy as np
    from _peak import peak_rss_bytes

    from segadeform.body import load_body
    from segadeform.geometry.precompute import precompute_garment
    from segadeform.geometry.primitives import frustum
    from segadeform.io import Mesh, write_obj
    from segadeform.motion import make_motion
    from segadeform.runtime import ModelPackage
    from segadeform.runtime.pipeline import Run
    from segadeform.settings import Effects

    tmp = Path(tempfile.mkdtemp())
    body = load_body(ROOT / "samples" / "bodies" / "default_body.npz")
    na = int(round(np.sqrt(2.0 * n)))
    v, f = frustum(na, max(2, n // na), 0.17, 0.36, 1.02, 0.5)
    garment = tmp / "skirt.obj"
    write_obj(garment, Mesh(vertices=v, faces=f))
    motion = make_motion("dance", seconds=frames / 30.0, seed=1)
    t = time.perf_counter()
    precompute_garment(v, f, body.rest_joints()[0], n_star=32)
    pre = time.perf_counter() - t
    row = {"n": int(len(v)), "precompute_s": pre}
    for key, eff in (("all", Effects()), ("nocol", Effects(collisions=False)), ("cloth", Effects(cloth=True))):
        r = Run(
            garment=garment,
            motion=motion,
            package=ModelPackage(package, threads=1),
            body=body,
            effects=eff,
            output=tmp / f"{key}.pc2",
            batch=batch,
            cache=True,
            force=True,
        )
        r.execute()  # precompute and encoder cached
        s = r.execute()
        row[key] = s.ms_per_frame
        row[key + "_stages"] = {k: 1e3 * x / s.frames for k, x in s.stage_seconds.items()}
    # the cloth stage's steady cost: the same runs at `frames` and 2 x `frames` frames of a longer dance (its
    # collider build and cached setup, fixed per run, cancel)
    longer = make_motion("dance", seconds=2 * frames / 30.0, seed=1)
    spent = {}
    for k in (frames, 2 * frames):
        r = Run(
            garment=garment,
            motion=longer,
            package=ModelPackage(package, threads=1),
            body=body,
            effects=Effects(cloth=True),
            output=tmp / "steady.pc2",
            batch=batch,
            cache=True,
            force=True,
            frames=(0, k),
        )
        spent[k] = r.execute().stage_seconds["cloth"]
    row["cloth_steady"] = 1e3 * (spent[2 * frames] - spent[frames]) / frames
    # and alone on that run's deformer frames and posed body, by this thread's CPU time (less inflated than the wall
    # clock when other work shares the machine): the collider built and the setup made before the clock starts
    from segadeform.body.cloth import ClothStage, garment_setup
    from segadeform.io import read_pc2

    Run(
        garment=garment,
        motion=longer,
        package=ModelPackage(package, threads=1),
        body=body,
        effects=Effects(collisions=False),
        output=tmp / "raw.pc2",
        body_output=tmp / "raw_body.pc2",
        batch=batch,
        cache=True,
        force=True,
        frames=(0, 2 * frames),
    ).execute()
    y, posed = np.asarray(read_pc2(tmp / "raw.pc2").frames), np.asarray(read_pc2(tmp / "raw_body.pc2").frames)
    stage = ClothStage(garment_setup(v, f, body.shaped_vertices()[0], body.faces), body.v_template, body.faces)
    c0 = time.thread_time()
    for lo in range(0, len(y), batch):
        stage.step(y[lo : lo + batch], posed[lo : lo + batch])
    row["cloth_cpu"] = 1e3 * (time.thread_time() - c0) / len(y)
    row["peak_mib"] = peak_rss_bytes() / 2**20
    if blender:
        from segadeform.physics import SimSettings, simulate

        settings = SimSettings(
            effects=("gravity", "body_collision", "bending", "air_damping", "pinning"), pin="waistband"
        )
        sim = simulate(v, f, body, motion, settings=settings)
        row["blender_s_per_frame"] = sim.seconds_per_frame  # Blender's own time per simulated frame
    return row


def _cloth_ms(row: dict) -> float:
    """The cloth stage's own steady ms per frame in a row (0 for rows of a version without it)."""
    return row.get("cloth_steady", 0.0)


def _opt(x, fmt: str) -> str:
    width = int(fmt.split(".")[0])
    return format(x, fmt) if x else "-".rjust(width)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--sizes", default="1000,4000,16000,64000")
    ap.add_argument("--frames", type=int, default=30)
    ap.add_argument("--batch", type=int, default=8)
    ap.add_argument("--package", default=str(ROOT / "samples" / "models" / "default"))
    ap.add_argument("--blender-max", type=int, default=4000)
    ap.add_argument("--one", type=int, help=argparse.SUPPRESS)
    a = ap.parse_args(argv)
    if a.one:
        print("ROW " + json.dumps(one(a.one, a.frames, a.batch, a.package, a.one <= a.blender_max)))
        return 0
    rows = []
    for n in (int(x) for x in a.sizes.split(",")):
        with tempfile.TemporaryDirectory() as cache:  # an empty user cache: the first run encodes the garment
            p = subprocess.run(
                [
                    sys.executable,
                    __file__,
                    "--one",
                    str(n),
                    "--frames",
                    str(a.frames),
                    "--batch",
                    str(a.batch),
                    "--package",
                    a.package,
                    "--blender-max",
                    str(a.blender_max),
                ],
                capture_output=True,
                text=True,
                env={**os.environ, "SEGADEFORM_CACHE_DIR": cache},
            )
        if p.returncode:
            print(f"N={n}: failed\n{p.stderr[-2000:]}", file=sys.stderr)
            continue
        rows.append(json.loads(next(ln for ln in p.stdout.splitlines() if ln.startswith("ROW "))[4:]))
        print(f"  N={rows[-1]['n']} done", file=sys.stderr)
    base = rows[0]
    print(
        f"{'N':>7s} {'precomp s':>9s} {'all ms':>8s} {'x/vert':>6s} {'deform':>7s} {'pose':>6s} {'collide':>7s} "
        f"{'no-col ms':>9s} {'x/vert':>6s} {'cloth ms':>8s} {'x/vert':>6s} {'cloth cpu':>9s} {'x/vert':>6s} "
        f"{'peak MiB':>8s} {'Blender s/f':>11s} {'x faster':>8s}"
    )
    for r in rows:
        st = r["all_stages"]
        scale = base["n"] / r["n"]
        bl = r.get("blender_s_per_frame")
        print(
            f"{r['n']:7d} {r['precompute_s']:9.2f} {r['all']:8.2f} {r['all'] / base['all'] * scale:6.2f} "
            f"{st.get('deform', 0):7.2f} {st.get('pose body', 0):6.2f} {st.get('collisions', 0):7.2f} "
            f"{r['nocol']:9.2f} {r['nocol'] / base['nocol'] * scale:6.2f} {_cloth_ms(r):8.2f} "
            f"{_cloth_ms(r) / _cloth_ms(base) * scale:6.2f} {r.get('cloth_cpu', 0.0):9.2f} "
            f"{r.get('cloth_cpu', 0.0) / max(base.get('cloth_cpu', 0.0), 1e-9) * scale:6.2f} {r['peak_mib']:8.0f} "
            f"{_opt(bl, '11.3f')} {_opt(bl and bl * 1e3 / r['all'], '8.0f')}"
        )
    return 0


if __name__ == "__main__":
    sys.exit(main())
