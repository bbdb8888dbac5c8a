"""The deformer on a GPU: parity with the CPU and frames per second, batched.

    pip install onnxruntime-gpu      (instead of onnxruntime; CUDA 12 and cuDNN 9 on the machine)
    python bench/gpu.py [--package samples/models/default] [--vertices 4000] [--batches 8,64,256]
                        [--providers CUDAExecutionProvider,TensorrtExecutionProvider] [--frames 512]

A skirt-like frustum of ``--vertices`` vertices on the default body and a dance: the garment encoder
once, then the model's default deformer over ``--frames`` frames in batches, on each provider named
(those this onnxruntime lacks are reported and skipped) and on the CPU (one thread) as the baseline in
the same run.  Per provider and batch: the largest difference from the CPU's frames (m), frames per
second, the ratio to the CPU's, and the device memory in use after the run (``nvidia-smi``, when it is
there).  Exit status 2 when no GPU provider could run.
"""

from __future__ import annotations

import argparse
import shutil
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]


def _inputs(package, n: int, frames: int):
    from segadeform.body import load_body
    from segadeform.geometry.features import vertex_features
    from segadeform.geometry.precompute import precompute_garment
    from segadeform.geometry.primitives import frustum
    from segadeform.motion import make_motion
    from segadeform.motion.motion import motion_windows

    body = load_body(ROOT / "samples" / "bodies" / "default_body.npz")
    na = int(round(np.sqrt(2.0 * n)))
    v, f = frustum(na, max(2, n // na), 0.17, 0.36, 1.02, 0.5)
    joints = body.rest_joints()[0]
    a = precompute_garment(v, f, joints)
    m = make_motion("dance", seconds=frames / 30.0, seed=1)
    feats = vertex_features(a.vertices, a.faces, joints, normals=a.normals.astype(np.float64))
    enc = {
        "features": feats[None].astype(np.float32),
        "nbr": a.nbr.astype(np.int64),
        "mask": a.mask.astype(bool),
        "descriptor": a.descriptor[None].astype(np.float32),
        "betas": np.zeros((1, 10), np.float32),
    }
    window = int(package.spec(package.default_deformer)["window"])
    per_frame = {"window": motion_windows(m.poses.astype(np.float32), window), "trans": m.trans.astype(np.float32)}
    const = {
        "rest": a.vertices.astype(np.float32),
        "nbr": enc["nbr"],
        "mask": enc["mask"],
        "joints": joints.astype(np.float32),
        "betas": np.zeros(10, np.float32),
    }
    if any(i["name"] == "log_wbody" for i in package.spec(package.default_deformer)["inputs"]):
        # a residual-weights model: the body's weights at the garment by the package's prior
        from segadeform.body.transfer import garment_weights, residual_log_weights

        prior = str(package.config.get("weight_prior", "nearest"))
        const["log_wbody"] = residual_log_weights(garment_weights(a.vertices, a.faces, body, None, prior))
    return enc, per_frame, const


def run(pkg_dir, providers, enc, per_frame, const, batch) -> tuple[np.ndarray, float]:
    from segadeform.runtime import ModelPackage

    pkg = ModelPackage(pkg_dir, threads=1, providers=providers)
    e = pkg.spec("garment_encoder")
    name = pkg.default_deformer
    d = pkg.spec(name)
    code = pkg.run("garment_encoder", {i["name"]: enc[i["name"]] for i in e["inputs"]})[0][0]
    t = per_frame["window"].shape[0]

    def feeds(lo, hi):
        b = hi - lo
        f = {
            e["outputs"][0]["name"]: code,
            "window": per_frame["window"][lo:hi],
            "trans": per_frame["trans"][lo:hi],
            "rest": const["rest"],
            "nbr": const["nbr"],
            "mask": const["mask"],
            "joints": np.repeat(const["joints"][None], b, 0),
            "betas": np.repeat(const["betas"][None], b, 0),
        }
        if "log_wbody" in const:
            f["log_wbody"] = const["log_wbody"]
        return {i["name"]: f[i["name"]] for i in d["inputs"]}

    pkg.run(name, feeds(0, min(batch, t)))  # warm-up (kernels, arenas)
    out = []
    t0 = time.perf_counter()
    for lo in range(0, t, batch):
        out.append(pkg.run(name, feeds(lo, min(lo + batch, t)))[0])
    return np.concatenate(out), t / (time.perf_counter() - t0)


def _gpu_memory() -> str:
    if shutil.which("nvidia-smi") is None:
        return "-"
    p = subprocess.run(
        ["nvidia-smi", "--query-gpu=memory.used", "--format=csv,noheader"], capture_output=True, text=True
    )
    return p.stdout.strip().splitlines()[0] if p.returncode == 0 and p.stdout.strip() else "-"


def main(argv=None) -> int:
    import onnxruntime as ort

    from segadeform.runtime import ModelPackage

    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--package", type=Path, default=ROOT / "samples" / "models" / "default")
    ap.add_argument("--vertices", type=int, default=4000)
    ap.add_argument("--frames", type=int, default=512)
    ap.add_argument("--batches", default="8,64,256")
    ap.add_argument("--providers", default="CUDAExecutionProvider,TensorrtExecutionProvider")
    a = ap.parse_args(argv)
    available = ort.get_available_providers()
    print(f"onnxruntime {ort.__version__}, providers here: {', '.join(available)}")
    enc, per_frame, const = _inputs(ModelPackage(a.package), a.vertices, a.frames)
    batches = [int(x) for x in a.batches.split(",")]
    cpu = {b: run(a.package, ["CPUExecutionProvider"], enc, per_frame, const, b) for b in batches}
    print(f"{'provider':28s} {'batch':>5s} {'max |diff| m':>12s} {'frames/s':>9s} {'x CPU':>7s} {'GPU memory':>11s}")
    for b in batches:
        print(f"{'CPU (1 thread)':28s} {b:5d} {0.0:12.2e} {cpu[b][1]:9.0f} {1.0:7.2f} {'-':>11s}")
    ran = 0
    for prov in (p for p in a.providers.split(",") if p):
        if prov not in available:
            print(f"{prov}: not in this onnxruntime (pip install onnxruntime-gpu)")
            continue
        for b in batches:
            try:
                frames, fps = run(a.package, [prov, "CPUExecutionProvider"], enc, per_frame, const, b)
            except Exception as e:
                print(f"{prov}: failed ({type(e).__name__}: {str(e)[:200]})")
                break
            diff = float(np.abs(frames - cpu[b][0]).max())
            print(f"{prov:28s} {b:5d} {diff:12.2e} {fps:9.0f} {fps / cpu[b][1]:7.2f} {_gpu_memory():>11s}")
            ran += 1
    return 0 if ran else 2


if __name__ == "__main__":
    sys.exit(main())
