"""The torch model on CUDA against the CPU: the largest difference of the garment's frames and frames per second
(the shipped checkpoint, a 4,000-vertex skirt-like garment, a dance), both measured in the same run.

    python tools/gpu/torch_parity.py [--checkpoint samples/models/default.train/model.pt] [--frames 256]
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np
import torch

ROOT = Path(__file__).resolve().parents[2]


def main() -> int:
    from segadeform.body import load_body
    from segadeform.body.transfer import RESIDUAL_EPS, garment_weights
    from segadeform.geometry.features import vertex_features
    from segadeform.geometry.precompute import precompute_garment
    from segadeform.geometry.primitives import frustum
    from segadeform.model.network import load_checkpoint
    from segadeform.motion import make_motion
    from segadeform.motion.motion import motion_windows

    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--checkpoint", type=Path, default=ROOT / "samples" / "models" / "default.train" / "model.pt")
    ap.add_argument("--frames", type=int, default=256)
    ap.add_argument("--vertices", type=int, default=4000)
    ap.add_argument("--batch", type=int, default=64)
    ap.add_argument("--device", default="cuda", help="the device compared with the CPU (cpu: rehearse it)")
    a = ap.parse_args()
    if a.device == "cuda" and not torch.cuda.is_available():
        print("no CUDA device")
        return 2
    model = load_checkpoint(a.checkpoint).eval()
    cfg = model.cfg
    body = load_body(ROOT / "samples" / "bodies" / "default_body.npz")
    na = int(round(np.sqrt(2.0 * a.vertices)))
    v, f = frustum(na, max(2, a.vertices // na), 0.17, 0.36, 1.02, 0.5)
    joints = body.rest_joints()[0]
    g = precompute_garment(v, f, joints, n_star=cfg.n_star)
    feats = vertex_features(g.vertices, g.faces, joints, normals=g.normals.astype(np.float64))
    w = garment_weights(g.vertices, g.faces, body, None, cfg.weight_prior)
    m = make_motion("dance", seconds=a.frames / 30.0, seed=1)
    t = lambda x, dt=torch.float32: torch.as_tensor(np.ascontiguousarray(x), dtype=dt)  # noqa: E731
    inp = {
        "features": t(feats[None]),
        "nbr": t(g.nbr, torch.int64),
        "mask": t(g.mask, torch.bool),
        "descriptor": t(g.descriptor[None]),
        "window": t(motion_windows(m.poses.astype(np.float32), cfg.window)),
        "trans": t(m.trans),
        "rest": t(g.vertices),
        "joints": t(joints),
        "lw": t(np.log(w + RESIDUAL_EPS)),
    }

    def frames(device: str) -> tuple[np.ndarray, float]:
        mm = model.to(device)
        x = {k: v.to(device) for k, v in inp.items()}
        n = x["window"].shape[0]
        with torch.no_grad():
            code = mm.garment_encoder(x["features"], x["nbr"], x["mask"], x["descriptor"])[0]

            def run(lo, hi):
                b = hi - lo
                return mm.deformer(
                    code,
                    x["window"][lo:hi],
                    torch.zeros(b, cfg.n_betas, device=device),
                    x["rest"],
                    x["nbr"],
                    x["mask"],
                    x["joints"][None].expand(b, -1, -1),
                    x["trans"][lo:hi],
                    x["lw"] if mm.residual else None,
                )[0]

            run(0, min(a.batch, n))  # warm-up
            if device.startswith("cuda"):
                torch.cuda.synchronize()
            t0 = time.perf_counter()
            out = [run(lo, min(lo + a.batch, n)) for lo in range(0, n, a.batch)]
            if device.startswith("cuda"):
                torch.cuda.synchronize()
            fps = n / (time.perf_counter() - t0)
        return torch.cat(out).cpu().numpy(), fps

    torch.set_num_threads(1)
    cpu, cpu_fps = frames("cpu")
    gpu, gpu_fps = frames(a.device)
    name = torch.cuda.get_device_name() if a.device.startswith("cuda") else a.device
    print(f"torch {torch.__version__} on {name}: {a.vertices} vertices, {a.frames} frames")
    print(f"max |{a.device} - CPU| = {float(np.abs(gpu - cpu).max()):.2e} m (float32)")
    print(
        f"frames/s: CPU (1 thread) {cpu_fps:.0f}, {a.device} {gpu_fps:.0f} ({gpu_fps / cpu_fps:.1f}x), batch {a.batch}"
    )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
