"""The same package and scene in every runtime: parity with Python and time per frame, in one run.

    python bench/runtimes.py [--package samples/models/default] [--scene samples/scenes/dress_dance.toml]
                             [--frames 0:60] [--batch 8] [--repeats 3] [--no-webgpu] [-o docs/runtimes.md]

One scene bundle (``segadeform bundle``: the garment asset, body shape and motion, with the Python
runtime's frames as the test vector) is run by the Python runtime (onnxruntime), the Node runtime
(onnxruntime-node, ``runtimes/node``), the C++ runtime (the onnxruntime C library, ``runtimes/cpp``,
built by ``tools/onnxruntime_cpp.sh``) and the browser runtime (``runtimes/web``'s page in headless
Chromium, onnxruntime-web on wasm and on WebGPU, the latter on SwiftShader: a software GPU, so its time
says nothing of a real GPU).  Every runtime times the same thing: the garment encoder once, then the
deformer over every frame in batches, sessions already made; ms/frame is the best of ``--repeats`` runs
and ``x Python`` its ratio to the Python runtime's in the same run.  Deformer only: collisions are the
Python runtime's (not in the others yet).  Writes the table to ``-o`` (Markdown) and prints it.
"""

from __future__ import annotations

import argparse
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


def python_row(pkg_dir: Path, bundle: Path, batch: int, repeats: int) -> dict:
    import onnxruntime

    from segadeform.bundle import read_bundle
    from segadeform.motion.motion import motion_windows
    from segadeform.runtime import ModelPackage

    A, meta = read_bundle(bundle)
    pkg = ModelPackage(pkg_dir, threads=1)
    enc = pkg.spec("garment_encoder")
    dec_name = meta["graph"]
    dec = pkg.spec(dec_name)
    window = int(meta["window"])
    n, t = A["rest"].shape[0], A["poses"].shape[0]
    enc_in = {"features": A["features"][None], "nbr": A["nbr"].astype(np.int64), "mask": A["mask"].astype(bool),
              "descriptor": A["descriptor"][None], "betas": A["betas"][None]}
    names = [i["name"] for i in dec["inputs"]]

    def once():
        t0 = time.perf_counter()
        code = pkg.run("garment_encoder", {i["name"]: enc_in[i["name"]] for i in enc["inputs"]})[0][0]
        out = []
        for lo in range(0, t, batch):
            hi = min(lo + batch, t)
            b = hi - lo
            feeds = {enc["outputs"][0]["name"]: code, "rest": A["rest"], "nbr": enc_in["nbr"], "mask": enc_in["mask"],
                     "window": motion_windows(A["poses"].astype(np.float32), window, start=lo, stop=hi),
                     "betas": np.repeat(A["betas"][None], b, 0), "joints": np.repeat(A["joints"][None], b, 0),
                     "trans": A["trans"][lo:hi]}
            if "log_wbody" in names:
                feeds["log_wbody"] = A["log_wbody"]
            out.append(pkg.run(dec_name, {k: feeds[k] for k in names})[0])
        return np.concatenate(out), (time.perf_counter() - t0) / t * 1e3

    frames, _ = once()  # sessions made and warm
    ms = min(once()[1] for _ in range(repeats))
    return dict(runtime="Python (onnxruntime)", version=onnxruntime.__version__, frames=frames, ms=ms,
                n=n, t=t, variant=dec_name)


def _errors(frames, expected) -> tuple[float, float]:
    d = np.abs(np.asarray(frames, np.float64).reshape(expected.shape) - expected)
    return float(d.max()), float(d.max() / np.abs(expected).max())


def node_row(pkg_dir, bundle, batch, repeats, tmp) -> dict:
    from segadeform.io import read_pc2

    node = ROOT / "runtimes" / "node"
    ms = []
    for _ in range(repeats):
        p = subprocess.run(["node", str(node / "src" / "cli.js"), str(pkg_dir), str(bundle), "-o", str(tmp / "n.pc2"),
                            "--batch", str(batch)], capture_output=True, text=True, timeout=600)
        if p.returncode:
            raise RuntimeError(p.stderr[-2000:])
        ms.append(float(re.search(r"([\d.]+) ms/frame", p.stdout).group(1)))
    version = json.loads((node / "node_modules" / "onnxruntime-node" / "package.json").read_text())["version"]
    return dict(runtime="Node (onnxruntime-node)", version=f"{version}, node {_cmd(['node', '--version'])}",
                frames=read_pc2(tmp / "n.pc2").frames, ms=min(ms))


def cpp_row(pkg_dir, bundle, batch, repeats, tmp) -> dict:
    b = subprocess.run([str(ROOT / "tools" / "onnxruntime_cpp.sh"), str(tmp / "cpp")], capture_output=True,
                       text=True, timeout=900)
    if b.returncode:
        raise RuntimeError(b.stderr[-2000:])
    exe = b.stdout.strip().splitlines()[-1]
    best = None
    for _ in range(repeats):
        p = subprocess.run([exe, str(pkg_dir), str(bundle), "-o", str(tmp / "c.pc2"), "--check", "--batch", str(batch)],
                           capture_output=True, text=True, timeout=600)
        if p.returncode:
            raise RuntimeError(p.stderr[-2000:])
        r = json.loads(p.stdout.split("PARITY", 1)[1].strip().splitlines()[0])
        best = r if best is None or r["ms_per_frame"] < best["ms_per_frame"] else best
    from segadeform.io import read_pc2

    import onnxruntime

    return dict(runtime="C++ (onnxruntime C API)", version=f"{onnxruntime.__version__} (the wheel's library), "
                f"{_cmd(['g++', '--version']).splitlines()[0]}", frames=read_pc2(tmp / "c.pc2").frames,
                ms=best["ms_per_frame"])


def web_row(pkg_dir, bundle, batch, repeats, tmp, ep) -> dict:
    site = tmp / f"site-{ep}"
    site.mkdir()
    (site / "runtimes").symlink_to(ROOT / "runtimes")
    (site / "pkg").symlink_to(Path(pkg_dir).resolve())
    (site / "s.sgdb").symlink_to(Path(bundle).resolve())
    best = None
    for _ in range(repeats):
        p = subprocess.run(["node", str(ROOT / "runtimes" / "web" / "test" / "page.mjs"), "--root", str(site),
                            "--package", "pkg", "--bundle", "s.sgdb", "--ep", ep, "--batch", str(batch)],
                           capture_output=True, text=True, timeout=900)
        if p.returncode:
            raise RuntimeError((p.stdout + p.stderr)[-2000:])
        r = json.loads(next(ln for ln in p.stdout.splitlines() if ln.startswith("PAGE "))[5:])
        best = r if best is None or r["msPerFrame"] < best["msPerFrame"] else best
    where = "WebGPU, SwiftShader (software)" if ep == "webgpu" else "wasm, 1 thread"
    return dict(runtime=f"browser (onnxruntime-web, {where})", version=f"{best['ort']}, {best['browser']}",
                max_abs=best["maxAbs"], rel=best["rel"], ms=best["msPerFrame"])


def _cmd(argv) -> str:
    try:
        return subprocess.run(argv, capture_output=True, text=True).stdout.strip()
    except OSError:
        return "?"


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--package", type=Path, default=ROOT / "samples" / "models" / "default")
    ap.add_argument("--scene", type=Path, default=ROOT / "samples" / "scenes" / "dress_dance.toml")
    ap.add_argument("--frames", default="0:60")
    ap.add_argument("--batch", type=int, default=8)
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--no-webgpu", action="store_true")
    ap.add_argument("-o", "--output", type=Path)
    a = ap.parse_args(argv)
    from segadeform.bundle import read_bundle
    from segadeform.runtime.bundles import scene_bundle
    import dataclasses

    from segadeform.scene import load_scene, parse_frames

    t0 = time.time()
    sc = load_scene(a.scene)
    sc = dataclasses.replace(sc, motion=dataclasses.replace(sc.motion, frames=parse_frames(a.frames)))
    with tempfile.TemporaryDirectory() as d:
        tmp = Path(d)
        bundle = scene_bundle(sc, tmp / "s.sgdb", model=a.package, batch=a.batch)
        expected = read_bundle(bundle)[0]["expected"].astype(np.float64)
        py = python_row(a.package, bundle, a.batch, a.repeats)
        rows = [py]
        for f in (node_row, cpp_row):
            try:
                rows.append(f(a.package, bundle, a.batch, a.repeats, tmp))
            except Exception as e:  # noqa: BLE001 -- a runtime that cannot run here is reported, not fatal
                rows.append(dict(runtime=f.__name__, error=str(e)[-300:]))
        for ep in ("wasm",) + (() if a.no_webgpu else ("webgpu",)):
            try:
                rows.append(web_row(a.package, bundle, a.batch, a.repeats, tmp, ep))
            except Exception as e:  # noqa: BLE001
                rows.append(dict(runtime=f"browser {ep}", error=str(e)[-300:]))
    for r in rows:
        if "frames" in r:
            r["max_abs"], r["rel"] = _errors(r.pop("frames"), expected)
    lines = [
        f"# Runtimes: parity and time per frame ({py['n']:,}-vertex garment, {py['t']} frames, batch {a.batch}, "
        f"graph `{py['variant']}`)",
        "",
        f"Made by `python bench/runtimes.py --package {os.path.relpath(a.package, ROOT)} --scene "
        f"{os.path.relpath(a.scene, ROOT)} --frames {a.frames} --batch {a.batch} --repeats {a.repeats}` in "
        f"{time.time() - t0:.0f} s on {platform.machine()} with {os.cpu_count()} CPU cores (load average "
        f"{os.getloadavg()[0]:.2f} at the end). Errors are against the Python runtime's frames stored in the "
        "bundle (max abs in metres, and relative to the largest coordinate); ms/frame is the garment encoder "
        "once plus the deformer over every frame, one thread, best of the repeats; `x Python` is the ratio to the "
        "Python runtime's time in this run.",
        "",
        "| runtime | version | max abs (m) | max rel | ms/frame | x Python |",
        "|---|---|---|---|---|---|",
    ]
    for r in rows:
        if "error" in r:
            lines.append(f"| {r['runtime']} | not measured: {r['error'].splitlines()[-1][:120]} | | | | |")
        else:
            lines.append(f"| {r['runtime']} | {r['version']} | {r['max_abs']:.2g} | {r['rel']:.2g} | {r['ms']:.2f} | "
                         f"{r['ms'] / py['ms']:.2f} |")
    text = "\n".join(lines) + "\n"
    print(text)
    if a.output:
        a.output.write_text(text)
    return 0


if __name__ == "__main__":
    sys.exit(main())
