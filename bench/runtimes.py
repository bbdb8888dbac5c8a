"""The same package, garment and motion in every runtime: parity with `segadeform run` and time per frame, in one run.

    python bench/runtimes.py [--package samples/models/default] [--scene samples/scenes/dress_dance.toml]
                             [--frames 0:60] [--batch 8] [--repeats 3] [--webgpu-frames 16] [--no-webgpu]
                             [-o docs/runtimes.md]

The scene's garment and motion are written as the files the runtimes without Python read (the garment asset
prepared for the scene's body shape, ``.sgda``, and the motion file, ``.sgdm``: ``segadeform.runtime.vectors``),
and ``segadeform run`` animates them here: its frames (garment, and the body it poses with numpy) are the
reference.  Then the Python runtime (onnxruntime), the Node runtime (onnxruntime-node, ``runtimes/node``), the C++
runtime (the onnxruntime C library, ``runtimes/cpp``, built by ``tools/onnxruntime_cpp.sh``) and the browser
runtime (``runtimes/web``'s page in headless Chromium, onnxruntime-web on wasm and on WebGPU, the latter on
SwiftShader: a software GPU, so its time says nothing of a real GPU) animate the same files, the body posed by
the package's body graph.  Every runtime times the same thing: the garment encoder once, then the deformer over
every frame in batches, sessions already made (the body graph's time apart); ms/frame is the best of
``--repeats`` runs and ``x Python`` its ratio to the Python runtime's in the same run.  WebGPU runs the first
``--webgpu-frames`` frames only (seconds per call on a software GPU); its errors are against the same reference
frames.  These columns run the scene's effects without collisions.

Collisions (when the scene has them): ``segadeform run`` on the same two files with the scene's effects and
collision margin is the reference; every runtime but WebGPU runs them too (Python and C++: the compiled kernel
``src/segadeform/body/_collide.c``; Node and the browser: its JavaScript port ``runtimes/node/src/collide.js``),
each pushing its own deformer's frames out of its own posed body (Python: the numpy body; the others: the body
graph).  Collision ms/frame is the collider's build once plus the refit and push-out of every frame, one thread,
best of the repeats; the errors are against the reference's frames, and ``moved`` is the vertex-frames pushed.
Writes the table to ``-o`` (Markdown) and prints it.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import os
import platform
import re
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]


def python_row(pkg_dir: Path, files: dict, batch: int, repeats: int, margin=None) -> dict:
    import onnxruntime

    from segadeform.body import default_body_path, load_body
    from segadeform.bundle import read_motion_file
    from segadeform.geometry import GarmentAsset
    from segadeform.motion.motion import motion_windows
    from segadeform.runtime import ModelPackage

    asset = GarmentAsset.load(files["garment"])
    motion, _ = read_motion_file(files["motion"])
    _, check_meta = __import__("segadeform.bundle", fromlist=["read_bundle"]).read_bundle(files["check"])
    pkg = ModelPackage(pkg_dir, threads=1)
    enc = pkg.spec("garment_encoder")
    dec_name = check_meta["graph"]
    dec = pkg.spec(dec_name)
    window = int(dec["window"])
    n, t = asset.n_vertices, motion.n_frames
    nb = int(pkg.config["n_betas"])
    betas = np.zeros(nb, np.float32)
    betas[:min(nb, len(asset.betas))] = asset.betas[:nb]
    enc_in = {"features": asset.features[None], "nbr": asset.nbr.astype(np.int32),
              "mask": asset.mask.astype(np.float32), "descriptor": asset.descriptor[None].astype(np.float32),
              "betas": betas[None]}
    names = [i["name"] for i in dec["inputs"]]
    poses = motion.poses.astype(np.float32)
    rest, joints = asset.vertices.astype(np.float32), asset.joints.astype(np.float32)

    def once():
        t0 = time.perf_counter()
        code = pkg.run("garment_encoder", {i["name"]: enc_in[i["name"]] for i in enc["inputs"]})[0][0]
        out = []
        for lo in range(0, t, batch):
            hi = min(lo + batch, t)
            b = hi - lo
            feeds = {enc["outputs"][0]["name"]: code, "rest": rest, "nbr": enc_in["nbr"], "mask": enc_in["mask"],
                     "window": motion_windows(poses, window, start=lo, stop=hi), "betas": np.repeat(betas[None], b, 0),
                     "joints": np.repeat(joints[None], b, 0), "trans": motion.trans[lo:hi].astype(np.float32),
                     "log_wbody": asset.log_wbody}
            out.append(pkg.run(dec_name, {k: feeds[k] for k in names})[0])
        return np.concatenate(out), (time.perf_counter() - t0) / t * 1e3

    frames, _ = once()  # sessions made and warm
    ms = min(once()[1] for _ in range(repeats))
    body = load_body(default_body_path())
    skin = dec["effects"]["skinning"]
    body_ms = []
    for _ in range(repeats):  # the numpy body segadeform run poses (one batch at a time, as it does)
        t0 = time.perf_counter()
        posed = np.concatenate([body.forward(motion.poses[lo:lo + batch], asset.betas, motion.trans[lo:lo + batch],
                                             skinning=skin).vertices for lo in range(0, t, batch)])
        body_ms.append((time.perf_counter() - t0) / t * 1e3)
    row = dict(runtime="Python (onnxruntime; body: numpy)", version=onnxruntime.__version__, frames=frames,
               body=posed, ms=ms, body_ms=min(body_ms), n=n, t=t, variant=dec_name)
    if margin is not None:  # the collision stage as segadeform run runs it: the compiled kernel, built once
        from segadeform.body.collision import BodyCollider

        col_ms = []
        for _ in range(repeats):
            t0 = time.perf_counter()
            col = BodyCollider(body.v_template, body.faces, threads=1)
            for lo in range(0, t, batch):
                col.push_out(frames[lo:lo + batch], posed[lo:lo + batch], margin)
            col_ms.append((time.perf_counter() - t0) / t * 1e3)
        row.update(col_ms=min(col_ms), col_backend=col.backend)
    return row


def python_collided(pkg_dir: Path, files: dict, effects, batch: int, tmp: Path):
    """`segadeform run` (its Run) on the garment asset and motion file with collisions: frames, body, moved."""
    from segadeform.body import default_body_path, load_body
    from segadeform.bundle import read_motion_file
    from segadeform.geometry import GarmentAsset
    from segadeform.io import read_pc2
    from segadeform.runtime import ModelPackage
    from segadeform.runtime.pipeline import Run

    motion, _ = read_motion_file(files["motion"])
    asset = GarmentAsset.load(files["garment"])
    run = Run(garment=files["garment"], motion=motion, package=ModelPackage(pkg_dir), body=load_body(default_body_path()),
              betas=asset.betas, effects=effects, output=tmp / "collided.pc2", body_output=tmp / "collided_body.pc2",
              batch=batch, cache=False, force=True)
    s = run.execute()
    return read_pc2(tmp / "collided.pc2").frames, read_pc2(tmp / "collided_body.pc2").frames, s.pushed_vertices


def _errors(frames, expected) -> tuple[float, float]:
    d = np.abs(np.asarray(frames, np.float64).reshape(expected.shape) - expected)
    return float(d.max()), float(d.max() / np.abs(expected).max())


def _ms(text: str) -> tuple[float, float]:
    """(garment, body) ms/frame from a Node or C++ runtime's summary line."""
    g = float(re.search(r"([\d.]+) ms/frame", text).group(1))
    b = re.search(r"body \d+ vertices, ([\d.]+) ms/frame", text)
    return g, float(b.group(1)) if b else float("nan")


def _collisions(text: str) -> tuple[int, float]:
    """(vertex-frames moved, ms/frame) of the collision stage from a Node or C++ runtime's summary line."""
    m = re.search(r"collisions: (\d+) vertex-frames pushed out \(margin [\d.e-]+ m\), ([\d.]+) ms/frame", text)
    if not m:
        raise RuntimeError(f"no collision figures in {text!r}")
    return int(m.group(1)), float(m.group(2))


def cli_row(name, argv, version, files, effects, batch, repeats, tmp, margin=None) -> dict:
    from segadeform.io import read_pc2

    def run(eff, out, extra=()):
        p = subprocess.run(argv + ["--package", str(files["package"]), "--garment", str(files["garment"]), "--motion",
                                   str(files["motion"]), "--effects", eff, "-o", str(out), "--batch", str(batch),
                                   *extra], capture_output=True, text=True, timeout=900)
        if p.returncode:
            raise RuntimeError(p.stderr[-2000:])
        return p.stdout

    best = None
    for _ in range(repeats):
        g, b = _ms(run(effects, tmp / "g.pc2", ["--body-out", str(tmp / "b.pc2")]))
        best = (g, b) if best is None or g < best[0] else best
    row = dict(runtime=name, version=version, frames=read_pc2(tmp / "g.pc2").frames,
               body=read_pc2(tmp / "b.pc2").frames, ms=best[0], body_ms=best[1])
    if margin is not None:
        col = [_collisions(run(effects + ",collisions", tmp / "c.pc2", ["--collision-margin", repr(margin)]))
               for _ in range(repeats)]
        row.update(collided=read_pc2(tmp / "c.pc2").frames, moved=col[0][0], col_ms=min(c[1] for c in col))
    return row


def node_row(files, effects, batch, repeats, tmp, margin=None) -> dict:
    node = ROOT / "runtimes" / "node"
    version = json.loads((node / "node_modules" / "onnxruntime-node" / "package.json").read_text())["version"]
    return cli_row("Node (onnxruntime-node)", ["node", str(node / "src" / "cli.js")],
                   f"{version}, node {_cmd(['node', '--version'])}", files, effects, batch, repeats, tmp, margin)


def cpp_row(files, effects, batch, repeats, tmp, margin=None) -> dict:
    import onnxruntime

    b = subprocess.run([str(ROOT / "tools" / "onnxruntime_cpp.sh"), str(tmp / "cpp")], capture_output=True,
                       text=True, timeout=900)
    if b.returncode:
        raise RuntimeError(b.stderr[-2000:])
    return cli_row("C++ (onnxruntime C API)", [b.stdout.strip().splitlines()[-1]],
                   f"{onnxruntime.__version__} (the wheel's library), {_cmd(['g++', '--version']).splitlines()[0]}",
                   files, effects, batch, repeats, tmp, margin)


def web_row(files, effects, batch, repeats, tmp, ep, frames=None, margin=None) -> dict:
    from segadeform.bundle import read_bundle, read_motion_file, write_bundle, write_motion_file

    site = tmp / f"site-{ep}"
    site.mkdir()
    (site / "runtimes").symlink_to(ROOT / "runtimes")
    (site / "pkg").symlink_to(Path(files["package"]).resolve())
    (site / "g.sgda").symlink_to(files["garment"])
    m, meta = read_motion_file(files["motion"])
    c, _ = read_bundle(files["check"])
    t = m.n_frames if frames is None else min(frames, m.n_frames)  # the first frames do not depend on later ones
    write_motion_file(site / "m.sgdm", dataclasses.replace(m, poses=m.poses[:t], trans=m.trans[:t]),
                      body=meta.get("body"), betas=meta.get("betas"))
    write_bundle(site / "c.sgdb", {"expected": c["expected"][:t], "body": c["body"][:t]})

    def page(eff, check, extra=()):
        p = subprocess.run(["node", str(ROOT / "runtimes" / "web" / "test" / "page.mjs"), "--root", str(site),
                            "--package", "pkg", "--garment", "g.sgda", "--motion", "m.sgdm", "--check", check,
                            "--effects", eff, "--ep", ep, "--batch", str(batch), *extra],
                           capture_output=True, text=True, timeout=3000)
        if p.returncode:
            raise RuntimeError((p.stdout + p.stderr)[-2000:])
        return json.loads(next(ln for ln in p.stdout.splitlines() if ln.startswith("PAGE "))[5:])

    best = None
    for _ in range(repeats):
        r = page(effects, "c.sgdb")
        best = r if best is None or r["msPerFrame"] < best["msPerFrame"] else best
    where = "WebGPU, SwiftShader (software)" if ep == "webgpu" else "wasm, 1 thread"
    note = f", first {t} frames" if t < m.n_frames else ""
    row = dict(runtime=f"browser (onnxruntime-web, {where}{note})", version=f"{best['ort']}, {best['browser']}",
               max_abs=best["maxAbs"], rel=best["rel"], ms=best["msPerFrame"], body_rel=best["body"]["rel"],
               body_ms=best["body"]["msPerFrame"])
    if margin is not None and "collided" in files:  # against segadeform run's frames with collisions
        write_bundle(site / "col.sgdb", {"expected": files["collided"][:t], "body": c["body"][:t]})
        col = [page(effects + ",collisions", "col.sgdb", ["--margin", repr(margin)]) for _ in range(repeats)]
        row.update(col_abs=col[0]["maxAbs"], col_rel=col[0]["rel"], moved=col[0]["collisions"]["moved"],
                   col_ms=min(r["collisions"]["msPerFrame"] for r in col))
    return row


def _cmd(argv) -> str:
    try:
        return subprocess.run(argv, capture_output=True, text=True).stdout.strip()
    except OSError:
        return "?"


WEBGPU_NOTE = """\
**WebGPU.** With the previous graphs (schema 2, before issue #15's re-export) WebGPU on SwiftShader was 1.0e-4
relative from Python (1.6e-4 m) while wasm was 5e-7.  `bench/webgpu_nodes.py` compares every node's output of one
graph between onnxruntime on the CPU and onnxruntime-web on WebGPU (graph optimisations off, so the same nodes run)
and prints the error each node adds to its inputs'.  On the body graph (`--graph body_lbs`) and on the shipped
`deformer_lbs` (the dress, frame 30 of the dance) the error started in two nodes: `Sin` and `Cos` of Rodrigues'
formula (axis-angle to rotation matrix, in every deformer and body graph) were off by 4.6e-5 and 1.9e-4 absolute
with inputs exact to 1e-7.  WGSL's `sin` and `cos`, which onnxruntime-web's kernels call, only promise an absolute
error of 2^-11 on [-pi, pi]; SwiftShader uses that latitude.  Downstream, `(1 - cos t) / t^2` amplified it for small
angles (1.9e-2 relative at that node) and 23 levels of forward kinematics carried it into every vertex (2.3e-5
relative at frame 30, 1e-4 over the dance).  The exported graphs now compute sine and cosine from Mul, Add, Sub and
Floor (`export.portability.replace_trig`: x = k pi + r with a two-part pi, Taylor polynomials of degree 11 and 12
on |r| <= pi/2, within 2e-7 of float64 sin/cos; the shipped model's frames moved by at most 2.4e-7 m), which every
backend computes to an ulp.  After it, the same comparison gives the body graph's vertices 2.7e-7 relative (no node
adding more than 1.4e-7) and the deformer's 3.9e-7 (was 2.3e-5); what the deformer still shows is float32 rounding
in another order (fused multiply-adds, GPU reduction order) in the attention's subtractions of near-equal numbers
and its `Exp` (up to 1e-5 relative on those nodes' small outputs, 1e-5 on the blend shapes, which are millimetres,
and the same before and after), inherent to float32 on that backend and far below the vertices' 1e-5.  The table's
WebGPU row is the whole pipeline with graph optimisations on; `tests/runtimes/test_web.py` holds WebGPU to 1e-5
relative, like every other runtime.
"""


COLLISION_NOTE = """\
**Collisions.** Given the same deformer frames and the same posed body, the C++ runtime's push-out equals Python's
`BodyCollider` exactly (both run `src/segadeform/body/_collide.c`) and the JavaScript port's equals it to the last
bit of `Math.acos` in vertex pseudo-normals (`tests/runtimes/test_collisions.py`: 4,000 points near and inside the
posed body, closest points, signed distances and push-out within 2.2e-16 m; on the pipeline, Python's collider given
a runtime's own posed body reproduces its frames bit for bit).  What the collision errors above measure is the
inputs: the runtimes pose the body with the package's body graph in float32 (within 4e-7 m of the numpy body
`segadeform run` poses; the browser's deformer adds its own float32 rounding, 8e-7 m), and the push-out rule is not
continuous in them.  In a concave crease (under the arms, between the legs, an arm against the torso) no point is
the margin away from both faces, so the passes bounce between them and which face the last pass takes, decided by
the body's last bits, moves such a vertex by up to about the margin.  Measured: the parity test's tightened dress on
a dance, 1 vertex-frame of 18,900 pushed over 1e-5 relative (3.7e-5 m); the dress on the CMU walk `02_01_walk.bvh`,
whose arms brush the torso, 243 of 50,677 (up to 0.29 mm), and there Python's own push-out given its float64 body
rounded to float32 moves vertices by up to 2.2 mm.  A rule that is continuous in the body (e.g. projecting onto both
faces' offset planes at once) would be a change to `_collide.c`, `collision.py` and the port together.
"""


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--package", type=Path, default=ROOT / "samples" / "models" / "default")
    ap.add_argument("--scene", type=Path, default=ROOT / "samples" / "scenes" / "dress_dance.toml")
    ap.add_argument("--frames", default="0:60")
    ap.add_argument("--batch", type=int, default=8)
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--webgpu-frames", type=int, default=16)
    ap.add_argument("--no-webgpu", action="store_true")
    ap.add_argument("-o", "--output", type=Path)
    a = ap.parse_args(argv)
    from segadeform.bundle import read_bundle
    from segadeform.runtime.vectors import scene_vectors
    from segadeform.scene import load_scene, parse_frames

    t0 = time.time()
    sc = load_scene(a.scene)
    sc = dataclasses.replace(sc, motion=dataclasses.replace(sc.motion, frames=parse_frames(a.frames)))
    e = dataclasses.replace(sc.effects, collisions=False)
    effects = ",".join([e.skinning] + (["dynamics"] if e.dynamics else []) + (["wrinkles"] if e.wrinkles else []))
    with tempfile.TemporaryDirectory() as d:
        tmp = Path(d)
        files = scene_vectors(sc, tmp / "v", model=a.package, batch=a.batch)
        files["package"] = a.package
        check, _ = read_bundle(files["check"])
        expected, body_expected = check["expected"].astype(np.float64), check["body"].astype(np.float64)
        margin = sc.effects.collision_margin if sc.effects.collisions else None
        moved = None
        if margin is not None:  # the reference with collisions: segadeform run on the same two files
            files["collided"], _, moved = python_collided(a.package, files, sc.effects, a.batch, tmp)
        py = python_row(a.package, files, a.batch, a.repeats, margin)
        if margin is not None:
            py.update(collided=files["collided"], moved=moved)
        rows = [py]
        for f in (node_row, cpp_row):
            try:
                rows.append(f(files, effects, a.batch, a.repeats, tmp, margin))
            except Exception as e:  # noqa: BLE001 -- a runtime that cannot run here is reported, not fatal
                rows.append(dict(runtime=f.__name__, error=str(e)[-300:]))
        for ep in ("wasm",) + (() if a.no_webgpu else ("webgpu",)):
            try:  # WebGPU: the graphs only (collisions are collide.js, the same on either backend)
                rows.append(web_row(files, effects, a.batch, 1 if ep == "webgpu" else a.repeats, tmp, ep,
                                    a.webgpu_frames if ep == "webgpu" else None, margin if ep == "wasm" else None))
            except Exception as e:  # noqa: BLE001
                rows.append(dict(runtime=f"browser {ep}", error=str(e)[-300:]))
    for r in rows:
        if "frames" in r:
            r["max_abs"], r["rel"] = _errors(r.pop("frames"), expected)
            r["body_rel"] = _errors(r.pop("body"), body_expected)[1]
        if "collided" in r:
            r["col_abs"], r["col_rel"] = _errors(r.pop("collided"), files["collided"].astype(np.float64))
    lines = [
        f"# Runtimes: parity and time per frame ({py['n']:,}-vertex garment, {py['t']} frames, batch {a.batch}, "
        f"graph `{py['variant']}`)",
        "",
        f"Made by `python bench/runtimes.py --package {os.path.relpath(a.package, ROOT)} --scene "
        f"{os.path.relpath(a.scene, ROOT)} --frames {a.frames} --batch {a.batch} --repeats {a.repeats} "
        f"--webgpu-frames {a.webgpu_frames}` in {time.time() - t0:.0f} s on {platform.machine()} with "
        f"{os.cpu_count()} CPU cores (load average {os.getloadavg()[0]:.2f} at the end). Every runtime animates the "
        "same garment asset (`.sgda`, prepared for the scene's body shape) and motion file (`.sgdm`) and poses the "
        "body with the package's body graph; errors are against `segadeform run`'s frames of the same files (max "
        "abs in metres, and relative to the largest coordinate; body: the numpy body `run --body-out` writes). "
        "ms/frame is the garment encoder once plus the deformer over every frame, one thread, best of the repeats "
        "(WebGPU: one run); `x Python` is its ratio to the Python runtime's in this run; body ms/frame is the body "
        "graph (Python: numpy `BodyModel.forward`)."
        + ("" if margin is None else
           f" Collisions (the scene's, margin {margin * 1e3:g} mm; {moved:,} of {py['n'] * py['t']:,} vertex-frames "
           "pushed by `segadeform run`): each runtime pushes its own frames out of its own posed body; collisions "
           "ms/frame is the collider's build once plus every frame's refit and push-out, one thread, best of the "
           "repeats (Python: `BodyCollider`, " + py.get("col_backend", "?") + " backend; Node and the browser: "
           "`collide.js`; C++: `_collide.c` compiled in); max rel is against `segadeform run`'s frames with "
           "collisions, and moved the vertex-frames each runtime pushed. WebGPU runs the graphs only."),
        "",
        "| runtime | version | max abs (m) | max rel | ms/frame | x Python | body max rel | body ms/frame | "
        "collisions ms/frame | collisions max rel | moved |",
        "|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    for r in rows:
        if "error" in r:
            lines.append(f"| {r['runtime']} | not measured: {r['error'].splitlines()[-1][:120]} | | | | | | | | | |")
        else:
            col = " | ".join([f"{r['col_ms']:.2f}", f"{r.get('col_rel', 0):.2g}", f"{r['moved']:,}"]
                             if "col_ms" in r else ["", "", ""])
            lines.append(f"| {r['runtime']} | {r['version']} | {r['max_abs']:.2g} | {r['rel']:.2g} | {r['ms']:.2f} | "
                         f"{r['ms'] / py['ms']:.2f} | {r['body_rel']:.2g} | {r['body_ms']:.2f} | {col} |")
    text = "\n".join(lines) + "\n\n" + WEBGPU_NOTE + ("" if margin is None else "\n" + COLLISION_NOTE)
    print(text)
    if a.output:
        from segadeform.io.atomic import atomic_open

        with atomic_open(a.output, "w", encoding="utf-8") as fh:
            fh.write(text)
    return 0


if __name__ == "__main__":
    sys.exit(main())
