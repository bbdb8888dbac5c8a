"""The same package, garment and motion in every runtime: parity with `segadeform run` and time per frame, in one run.

    python bench/runtimes.py [--package samples/models/default] [--scene samples/scenes/dress_dance.toml]
                             [--frames 0:60] [--batch 8] [--repeats 3] [--webgpu-frames 16] [--no-webgpu]
                             [-o docs/runtimes.md]

The scene's garment and motion are written as the files the runtimes without Python read (the garment asset
prepared for the scene's body shape, ``.sgda``, and the motion file, ``.sgdm``: ``segadeform.runtime.vectors``),
and ``segadeform run`` animates them here: its frames are the reference (the body's: ``BodyModel.forward``, numpy
in float64, the float32 body graphs' reference).  Then the Python runtime (onnxruntime), the Node runtime
(onnxruntime-node, ``runtimes/node``), the C++ runtime (the onnxruntime C library, ``runtimes/cpp``, built by
``tools/onnxruntime_cpp.sh``) and the browser runtime (``runtimes/web``'s page in headless Chromium,
onnxruntime-web on wasm and on WebGPU, the latter on SwiftShader: a software GPU, so its time says nothing of a real
GPU) animate the same files, the body posed by the package's body graph (Python too, as ``segadeform run`` does:
``segadeform.runtime.body``; the numpy body's time is printed beside it).  Every runtime times the same thing: the
garment encoder once, then the deformer over every frame in batches, sessions already made (the body graph's time
apart); ms/frame is the best of ``--repeats`` runs and ``x Python`` its ratio to the Python runtime's in the same
run.  WebGPU runs the first ``--webgpu-frames`` frames only (seconds per call on a software GPU); its errors are
against the same reference frames.  These columns run the scene's effects without collisions.

Collisions (when the scene has them): ``segadeform run`` on the same two files with the scene's effects and
collision margin is the reference; every runtime but WebGPU runs them too (Python and C++: the compiled kernel
``src/segadeform/body/_collide.c``; Node and the browser: its JavaScript port ``runtimes/node/src/collide.js``),
each pushing its own deformer's frames out of its own posed body (every one posed by the body graph); one more row
is ``segadeform run --body-backend numpy`` (the float64 body).  Collision ms/frame is the collider's build once plus
the refit and push-out of every frame, one thread, best of the repeats; the errors are against the reference's
frames, ``over`` the vertex-frames further than 1e-5 relative from them (the browser's every frame from
``tests/runtimes/web_frames.mjs``: the page reports the largest error only), and ``moved`` the vertex-frames pushed.
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
    from segadeform.geometry import GarmentAsset
    from segadeform.motion import read_motion_file
    from segadeform.motion.motion import motion_windows
    from segadeform.runtime import ModelPackage
    from segadeform.runtime.body import BodyPoser
    from segadeform.runtime.translation import at_translation

    asset = GarmentAsset.load(files["garment"])
    motion, _ = read_motion_file(files["motion"])
    _, check_meta = __import__("segadeform.io.sgdb", fromlist=["read_bundle"]).read_bundle(files["check"])
    pkg = ModelPackage(pkg_dir, threads=1)
    enc = pkg.spec("garment_encoder")
    dec_name = check_meta["graph"]
    dec = pkg.spec(dec_name)
    window = int(dec["window"])
    n, t = asset.n_vertices, motion.n_frames
    nb = int(pkg.config["n_betas"])
    betas = np.zeros(nb, np.float32)
    betas[: min(nb, len(asset.betas))] = asset.betas[:nb]
    enc_in = {
        "features": asset.features[None],
        "nbr": asset.nbr.astype(np.int32),
        "mask": asset.mask.astype(np.float32),
        "descriptor": asset.descriptor[None].astype(np.float32),
        "betas": betas[None],
    }
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
            feeds = {
                enc["outputs"][0]["name"]: code,
                "rest": rest,
                "nbr": enc_in["nbr"],
                "mask": enc_in["mask"],
                "window": motion_windows(poses, window, start=lo, stop=hi),
                "betas": np.repeat(betas[None], b, 0),
                "joints": np.repeat(joints[None], b, 0),
                "trans": np.zeros((b, 3), np.float32),  # at the root, the translation added after (as every runtime)
                "log_wbody": asset.log_wbody,
            }
            out.append(at_translation(pkg.run(dec_name, {k: feeds[k] for k in names})[0], motion.trans[lo:hi]))
        return np.concatenate(out).astype(np.float32), (time.perf_counter() - t0) / t * 1e3

    frames, _ = once()  # sessions made and warm
    ms = min(once()[1] for _ in range(repeats))
    body = load_body(default_body_path())
    skin = dec["effects"]["skinning"]
    posers = {k: BodyPoser(pkg, body, skinning=skin, backend=k) for k in ("graph", "numpy")}
    posed, body_ms = {}, {k: [] for k in posers}
    for k, poser in posers.items():  # segadeform run's body (the graph) and numpy's, one batch at a time as it poses
        poser.pose(motion.poses[:batch], asset.betas, motion.trans[:batch])  # the graph's session made
        for _ in range(repeats):
            t0 = time.perf_counter()
            posed[k] = np.concatenate(
                [
                    poser.pose(motion.poses[lo : lo + batch], asset.betas, motion.trans[lo : lo + batch])
                    for lo in range(0, t, batch)
                ]
            )
            body_ms[k].append((time.perf_counter() - t0) / t * 1e3)
    row = dict(
        runtime="Python (onnxruntime)",
        version=onnxruntime.__version__,
        frames=frames,
        body=posed["graph"],
        numpy_body=posed["numpy"],
        ms=ms,
        body_ms=min(body_ms["graph"]),
        numpy_body_ms=min(body_ms["numpy"]),
        n=n,
        t=t,
        variant=dec_name,
    )
    if margin is not None:  # the collision stage as segadeform run runs it: the compiled kernel, built once
        from segadeform.body.collision import BodyCollider

        col_ms = []
        for _ in range(repeats):
            t0 = time.perf_counter()
            col = BodyCollider(body.v_template, body.faces, threads=1)
            carry = np.zeros((frames.shape[1], 3))  # the correction carried from frame to frame, as run does
            for lo in range(0, t, batch):
                col.push_out(frames[lo : lo + batch], posed["graph"][lo : lo + batch], margin, carry=carry)
            col_ms.append((time.perf_counter() - t0) / t * 1e3)
        row.update(col_ms=min(col_ms), col_backend=col.backend)
    return row


def python_collided(pkg_dir: Path, files: dict, effects, batch: int, tmp: Path, body_backend: str = "auto"):
    """`segadeform run` (its Run) on the garment asset and motion file with collisions: frames, body, moved, and how
    the body was posed."""
    from segadeform.body import default_body_path, load_body
    from segadeform.geometry import GarmentAsset
    from segadeform.io import read_pc2
    from segadeform.motion import read_motion_file
    from segadeform.runtime import ModelPackage
    from segadeform.runtime.pipeline import Run

    motion, _ = read_motion_file(files["motion"])
    asset = GarmentAsset.load(files["garment"])
    run = Run(
        garment=files["garment"],
        motion=motion,
        package=ModelPackage(pkg_dir),
        body=load_body(default_body_path()),
        betas=asset.betas,
        effects=effects,
        output=tmp / f"collided-{body_backend}.pc2",
        body_output=tmp / f"collided-{body_backend}_body.pc2",
        batch=batch,
        cache=False,
        force=True,
        body_backend=body_backend,
    )
    s = run.execute()
    return (
        read_pc2(tmp / f"collided-{body_backend}.pc2").frames,
        read_pc2(tmp / f"collided-{body_backend}_body.pc2").frames,
        s.pushed_vertices,
        s.body_backend,
    )


def _errors(frames, expected) -> tuple[float, float]:
    d = np.abs(np.asarray(frames, np.float64).reshape(expected.shape) - expected)
    return float(d.max()), float(d.max() / np.abs(expected).max())


def _key(runtime: str) -> str:
    """A row's short name: Python, Python, (the numpy body's row), Node, C++, browser (wasm), webgpu."""
    return "webgpu" if "WebGPU" in runtime else runtime.split(" ")[0]


def _over(frames, expected, rtol: float = 1e-5) -> int:
    """Vertex-frames further than ``rtol`` relative (to the largest coordinate) from ``expected (T, N, 3)``."""
    d = np.abs(np.asarray(frames, np.float64).reshape(expected.shape) - expected).max(axis=-1)
    return int((d > rtol * np.abs(expected).max()).sum())


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
        p = subprocess.run(
            argv
            + [
                "--package",
                str(files["package"]),
                "--garment",
                str(files["garment"]),
                "--motion",
                str(files["motion"]),
                "--effects",
                eff,
                "-o",
                str(out),
                "--batch",
                str(batch),
                *extra,
            ],
            capture_output=True,
            text=True,
            timeout=900,
        )
        if p.returncode:
            raise RuntimeError(p.stderr[-2000:])
        return p.stdout

    best = None
    for _ in range(repeats):
        g, b = _ms(run(effects, tmp / "g.pc2", ["--body-out", str(tmp / "b.pc2")]))
        best = (g, b) if best is None or g < best[0] else best
    row = dict(
        runtime=name,
        version=version,
        frames=read_pc2(tmp / "g.pc2").frames,
        body=read_pc2(tmp / "b.pc2").frames,
        ms=best[0],
        body_ms=best[1],
    )
    if margin is not None:
        col = [
            _collisions(run(effects + ",collisions", tmp / "c.pc2", ["--collision-margin", repr(margin)]))
            for _ in range(repeats)
        ]
        row.update(collided=read_pc2(tmp / "c.pc2").frames, moved=col[0][0], col_ms=min(c[1] for c in col))
    return row


def node_row(files, effects, batch, repeats, tmp, margin=None) -> dict:
    node = ROOT / "runtimes" / "node"
    version = json.loads((node / "node_modules" / "onnxruntime-node" / "package.json").read_text())["version"]
    return cli_row(
        "Node (onnxruntime-node)",
        ["node", str(node / "src" / "cli.js")],
        f"{version}, node {_cmd(['node', '--version'])}",
        files,
        effects,
        batch,
        repeats,
        tmp,
        margin,
    )


def cpp_row(files, effects, batch, repeats, tmp, margin=None) -> dict:
    import onnxruntime

    b = subprocess.run(
        [str(ROOT / "tools" / "onnxruntime_cpp.sh"), str(tmp / "cpp")], capture_output=True, text=True, timeout=900
    )
    if b.returncode:
        raise RuntimeError(b.stderr[-2000:])
    return cli_row(
        "C++ (onnxruntime C API)",
        [b.stdout.strip().splitlines()[-1]],
        f"{onnxruntime.__version__} (the wheel's library), {_cmd(['g++', '--version']).splitlines()[0]}",
        files,
        effects,
        batch,
        repeats,
        tmp,
        margin,
    )


def web_row(files, effects, batch, repeats, tmp, ep, frames=None, margin=None) -> dict:
    from segadeform.io.sgdb import read_bundle, write_bundle
    from segadeform.motion import read_motion_file, write_motion_file

    site = tmp / f"site-{ep}"
    site.mkdir()
    (site / "runtimes").symlink_to(ROOT / "runtimes")
    (site / "pkg").symlink_to(Path(files["package"]).resolve())
    (site / "g.sgda").symlink_to(files["garment"])
    m, meta = read_motion_file(files["motion"])
    c, _ = read_bundle(files["check"])
    t = m.n_frames if frames is None else min(frames, m.n_frames)  # the first frames do not depend on later ones
    write_motion_file(
        site / "m.sgdm",
        dataclasses.replace(m, poses=m.poses[:t], trans=m.trans[:t]),
        body=meta.get("body"),
        betas=meta.get("betas"),
    )
    body_ref = files.get("numpy_body", c["body"])  # the body's errors against the numpy body, as the other rows'
    write_bundle(site / "c.sgdb", {"expected": c["expected"][:t], "body": body_ref[:t]})

    def page(eff, check, extra=()):
        p = subprocess.run(
            [
                "node",
                str(ROOT / "runtimes" / "web" / "test" / "page.mjs"),
                "--root",
                str(site),
                "--package",
                "pkg",
                "--garment",
                "g.sgda",
                "--motion",
                "m.sgdm",
                "--check",
                check,
                "--effects",
                eff,
                "--ep",
                ep,
                "--batch",
                str(batch),
                *extra,
            ],
            capture_output=True,
            text=True,
            timeout=3000,
        )
        if p.returncode:
            raise RuntimeError((p.stdout + p.stderr)[-2000:])
        return json.loads(next(ln for ln in p.stdout.splitlines() if ln.startswith("PAGE "))[5:])

    best = None
    for _ in range(repeats):
        r = page(effects, "c.sgdb")
        best = r if best is None or r["msPerFrame"] < best["msPerFrame"] else best
    where = "WebGPU, SwiftShader (software)" if ep == "webgpu" else "wasm, 1 thread"
    note = f", first {t} frames" if t < m.n_frames else ""
    row = dict(
        runtime=f"browser (onnxruntime-web, {where}{note})",
        version=f"{best['ort']}, {best['browser']}",
        max_abs=best["maxAbs"],
        rel=best["rel"],
        ms=best["msPerFrame"],
        body_rel=best["body"]["rel"],
        body_ms=best["body"]["msPerFrame"],
    )
    if margin is not None and "collided" in files:  # against segadeform run's frames with collisions
        write_bundle(site / "col.sgdb", {"expected": files["collided"][:t], "body": body_ref[:t]})
        col = [page(effects + ",collisions", "col.sgdb", ["--margin", repr(margin)]) for _ in range(repeats)]
        row.update(
            col_abs=col[0]["maxAbs"],
            col_rel=col[0]["rel"],
            moved=col[0]["collisions"]["moved"],
            col_ms=min(r["collisions"]["msPerFrame"] for r in col),
        )
        # every frame (the page reports the largest error only): the same runtime.js in the same browser
        p = subprocess.run(
            [
                "node",
                str(ROOT / "tests" / "runtimes" / "web_frames.mjs"),
                "--root",
                str(site),
                "--package",
                "pkg",
                "--garment",
                "g.sgda",
                "--motion",
                "m.sgdm",
                "--effects",
                effects + ",collisions",
                "--margin",
                repr(margin),
                "--batch",
                str(batch),
                "-o",
                str(tmp / f"web-{ep}.f32"),
                "--body-out",
                str(tmp / f"web-{ep}-body.f32"),
            ],
            capture_output=True,
            text=True,
            timeout=3000,
        )
        if p.returncode:
            raise RuntimeError((p.stdout + p.stderr)[-2000:])
        got = np.fromfile(tmp / f"web-{ep}.f32", "<f4").reshape(files["collided"][:t].shape)
        posed = np.fromfile(tmp / f"web-{ep}-body.f32", "<f4").reshape(c["body"][:t].shape)
        row.update(
            col_over=_over(got, files["collided"][:t].astype(np.float64)),
            run_body_abs=float(np.abs(posed.astype(np.float64) - c["body"][:t]).max()),
        )
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


def collision_note(by: dict, moved: int) -> str:
    """The Collisions paragraph, with this run's figures (``by``: the rows by :func:`_key`)."""
    import textwrap

    def fig(name, key, fmt="{:.2g}"):
        r = by.get(name)
        return "(not measured)" if r is None or key not in r else fmt.format(r[key])

    def over(name):
        r = by.get(name, {})
        if "col_over" not in r:
            return "was not measured here"
        if r["col_over"] == 0:
            return (
                f"moves none of the {moved:,} pushed vertex-frames by more than 1e-5 relative here (up to "
                f"{r['col_abs']:.2g} m)"
            )
        return (
            f"moves {r['col_over']:,} of the {moved:,} pushed vertex-frames by more than 1e-5 relative "
            f"here (up to {r['col_abs']:.2g} m)"
        )

    same = [n for n in ("Node", "C++") if n in by and by[n].get("run_body_abs") == 0]
    body = (
        f"equals {' and '.join(same)}'s bit for bit"
        if len(same) == 2
        else f"is within {fig('Node', 'run_body_abs')} m of Node's and {fig('C++', 'run_body_abs')} m of C++'s"
    )
    text = (
        "**Collisions.** Given the same deformer frames and the same posed body, the C++ runtime's push-out equals "
        "Python's `BodyCollider` exactly (both run `src/segadeform/body/_collide.c`) and the JavaScript port's equals "
        "it to the last bit of `Math.acos` in vertex pseudo-normals (`tests/runtimes/test_collisions.py`: 4,000 points "
        "near and inside the posed body, closest points, signed distances and push-out within 2.2e-16 m; on the "
        "pipeline every runtime pushes out at the root and adds the translation after, so Python's collider given a "
        "runtime's own written deformer frames and posed body reproduces its frames to that sum's rounding, a few "
        "float32 steps where the push-out turns a corner of the body: 2.5e-6 m at most).  The push-out rule is not "
        "continuous in those inputs, though: in a concave crease (under the arms, between the legs, an arm against "
        "the torso) no point is the margin away from both faces, so the "
        "passes bounce between them and which face the last pass takes, decided by the inputs' last bits, moves such "
        "a vertex by up to about the margin.  `segadeform run` therefore poses the body with the package's body "
        "graph in float32, as every other runtime does, whenever that graph poses the run's body (the body hash its "
        "manifest records; `--body-backend auto`, the default; otherwise numpy, saying why once): its body "
        f"{body}, and the browser's (onnxruntime-web's wasm kernels round in another order) is within "
        f"{fig('browser', 'run_body_abs')} m of it.  Node and C++ push out the same vertex-frames as `segadeform "
        f"run`: collisions max rel {fig('Node', 'col_rel')} and {fig('C++', 'col_rel')}, "
        f"{fig('Node', 'col_over', '{:,}')} and {fig('C++', 'col_over', '{:,}')} vertex-frames over 1e-5 relative.  "
        f"The browser's deformer rounds float32 in another order too ({fig('browser', 'max_abs')} m before "
        f"collisions), and that rounding {over('browser')}; the parity test, on a tightened dress (a third of its "
        "vertex-frames pushed), measures 1 of 18,883 pushed vertex-frames over 1e-5 relative (3.7e-5 m) "
        "and shows the cause: given the browser's own deformer frames and body, Python's collider gives its frames "
        "to that rounding, and the browser's deformer frames pushed out of Python's body differ at that "
        "vertex-frame while Python's deformer frames pushed out of the browser's body do not.  The numpy body "
        "(`--body-backend numpy`, "
        "float64; what the runtimes were compared with before) "
        f"{over('Python,')}, and on the CMU walk `02_01_walk.bvh`, whose arms brush the "
        "torso, it moved 243 of 50,677 pushed (up to 0.29 mm).  A rule that is continuous in its inputs (e.g. "
        "projecting onto both faces' offset planes at once) would be a change to `_collide.c`, `collision.py` and "
        "the port together."
    )
    return textwrap.fill(text, width=116, break_on_hyphens=False, break_long_words=False) + "\n"


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
    from segadeform.io.sgdb import read_bundle
    from segadeform.runtime.vectors import scene_vectors
    from segadeform.settings import load_scene, parse_frames

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
        expected, run_body = check["expected"].astype(np.float64), check["body"].astype(np.float64)
        margin = sc.effects.collision_margin if sc.effects.collisions else None
        moved = numpy_row = None
        if margin is not None:  # the reference with collisions: segadeform run on the same two files
            files["collided"], _, moved, how = python_collided(a.package, files, sc.effects, a.batch, tmp)
            if how != "graph":
                raise RuntimeError(f"segadeform run posed the body with {how}, not the package's body graph")
            f_np, _, moved_np, _ = python_collided(a.package, files, sc.effects, a.batch, tmp, "numpy")
            numpy_row = dict(
                runtime="Python, `--body-backend numpy` (the float64 body)", version="", collided=f_np, moved=moved_np
            )
        py = python_row(a.package, files, a.batch, a.repeats, margin)
        files["numpy_body"] = py["numpy_body"]
        body_expected = py["numpy_body"].astype(np.float64)
        if margin is not None:
            py.update(collided=files["collided"], moved=moved)
        rows = [py]
        for f in (node_row, cpp_row):
            try:
                rows.append(f(files, effects, a.batch, a.repeats, tmp, margin))
            except Exception as e:
                rows.append(dict(runtime=f.__name__, error=str(e)[-300:]))
        for ep in ("wasm",) + (() if a.no_webgpu else ("webgpu",)):
            try:  # WebGPU: the graphs only (collisions are collide.js, the same on either backend)
                rows.append(
                    web_row(
                        files,
                        effects,
                        a.batch,
                        1 if ep == "webgpu" else a.repeats,
                        tmp,
                        ep,
                        a.webgpu_frames if ep == "webgpu" else None,
                        margin if ep == "wasm" else None,
                    )
                )
            except Exception as e:
                rows.append(dict(runtime=f"browser {ep}", error=str(e)[-300:]))
        if numpy_row is not None:
            rows.append(numpy_row)
    for r in rows:
        if "frames" in r:
            r["max_abs"], r["rel"] = _errors(r.pop("frames"), expected)
            r["run_body_abs"] = _errors(r["body"], run_body)[0]  # against segadeform run --body-out's body
            r["body_rel"] = _errors(r.pop("body"), body_expected)[1]
        if "collided" in r:
            got = r.pop("collided")
            r["col_abs"], r["col_rel"] = _errors(got, files["collided"].astype(np.float64))
            r["col_over"] = _over(got, files["collided"].astype(np.float64))
    by = {_key(r["runtime"]): r for r in rows if "error" not in r}
    lines = [
        f"# Runtimes: parity and time per frame ({py['n']:,}-vertex garment, {py['t']} frames, batch {a.batch}, "
        f"graph `{py['variant']}`)",
        "",
        f"Made by `python bench/runtimes.py --package {os.path.relpath(a.package, ROOT)} --scene "
        f"{os.path.relpath(a.scene, ROOT)} --frames {a.frames} --batch {a.batch} --repeats {a.repeats} "
        f"--webgpu-frames {a.webgpu_frames}` in {time.time() - t0:.0f} s on {platform.machine()} with "
        f"{os.cpu_count()} CPU cores (load average {os.getloadavg()[0]:.2f} at the end). Every runtime animates the "
        "same garment asset (`.sgda`, prepared for the scene's body shape) and motion file (`.sgdm`) and poses the "
        "body with the package's body graph (Python: `segadeform run`'s, `segadeform.runtime.body`); errors are "
        "against `segadeform run`'s frames of the same files (max abs in metres, and relative to the largest "
        "coordinate; body: against the numpy body, `BodyModel.forward` in float64, the body graphs' reference). "
        "ms/frame is the garment encoder once plus the deformer over every frame, one thread, best of the repeats "
        "(WebGPU: one run); `x Python` is its ratio to the Python runtime's in this run; body ms/frame is the body "
        f"graph (Python's numpy body: {py['numpy_body_ms']:.2f} ms/frame in this run)."
        + (
            ""
            if margin is None
            else f" Collisions (the scene's, margin {margin * 1e3:g} mm; {moved:,} of {py['n'] * py['t']:,} "
            "vertex-frames "
            "pushed by `segadeform run`): each runtime pushes its own frames out of its own posed body; collisions "
            "ms/frame is the collider's build once plus every frame's refit and push-out, one thread, best of the "
            "repeats (Python: `BodyCollider`, " + py.get("col_backend", "?") + " backend; Node and the browser: "
            "`collide.js`; C++: `_collide.c` compiled in); max abs and max rel are against `segadeform run`'s frames "
            "with collisions, over the vertex-frames further than 1e-5 relative from them, and moved the vertex-frames "
            "each runtime pushed. The last row is `segadeform run --body-backend numpy`. WebGPU runs the graphs only."
        ),
        "",
        "| runtime | version | max abs (m) | max rel | ms/frame | x Python | body max rel | body ms/frame | "
        "collisions ms/frame | collisions max abs (m) | collisions max rel | over 1e-5 | moved |",
        "|---|---|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    for r in rows:
        if "error" in r:
            lines.append(f"| {r['runtime']} | not measured: {r['error'].splitlines()[-1][:120]} |" + " |" * 11)
            continue
        main_cols = (
            [
                f"{r['max_abs']:.2g}",
                f"{r['rel']:.2g}",
                f"{r['ms']:.2f}",
                f"{r['ms'] / py['ms']:.2f}",
                f"{r['body_rel']:.2g}",
                f"{r['body_ms']:.2f}",
            ]
            if "max_abs" in r
            else [""] * 6
        )
        col = (
            [
                f"{r['col_ms']:.2f}" if "col_ms" in r else "",
                f"{r['col_abs']:.2g}",
                f"{r['col_rel']:.2g}",
                f"{r['col_over']:,}",
                f"{r['moved']:,}",
            ]
            if "col_rel" in r
            else [""] * 5
        )
        lines.append("| " + " | ".join([r["runtime"], r["version"]] + main_cols + col) + " |")
    text = "\n".join(lines) + "\n\n" + WEBGPU_NOTE + ("" if margin is None else "\n" + collision_note(by, moved))
    print(text)
    if a.output:
        from segadeform.io.atomic import atomic_open

        with atomic_open(a.output, "w", encoding="utf-8") as fh:
            fh.write(text)
    return 0


if __name__ == "__main__":
    sys.exit(main())
