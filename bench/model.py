"""torch eager vs onnxruntime, ms per frame, one thread.

    python bench/model.py [--sizes 1000 4000 16000] [--batches 1 8] [--repeat 5]

A random-weight model with the default ModelConfig is exported once; each
row runs the per-frame deformer on a skirt-like garment of N vertices with a
batch of B frames.  "encoder cached" is what the runtime does (garment
encoder once, deformer per frame); "encoder per frame" recomputes the encoder
for every batch.  Ratios are against torch eager with the encoder cached,
measured in the same run.  Times are medians of ``--repeat`` runs.
"""

from __future__ import annotations

import argparse
import statistics
import tempfile
import time
import warnings
from pathlib import Path

import numpy as np

warnings.filterwarnings("ignore")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--sizes", type=int, nargs="+", default=[1000, 4000, 16000])
    ap.add_argument("--batches", type=int, nargs="+", default=[1, 8])
    ap.add_argument("--repeat", type=int, default=5)
    args = ap.parse_args()

    import onnxruntime as ort
    import torch

    from segadeform.body import default_rest_joints
    from segadeform.export import export_package, graph_specs
    from segadeform.geometry import precompute_garment
    from segadeform.geometry.primitives import frustum
    from segadeform.model import ModelConfig, SEGANet
    from segadeform.motion import make_motion, motion_windows

    torch.set_num_threads(1)
    torch.manual_seed(0)
    net = SEGANet(ModelConfig()).eval()
    pkg = Path(tempfile.mkdtemp()) / "pkg"
    export_package(net, pkg, check=False)
    net.freeze()
    so = ort.SessionOptions()
    so.intra_op_num_threads = 1
    so.inter_op_num_threads = 1
    enc_s = ort.InferenceSession(str(pkg / "garment_encoder.onnx"), so, providers=["CPUExecutionProvider"])
    dec_file = graph_specs(net.cfg)["deformer"]["file"]  # the model's own deformer (contracts.model_package names it)
    dec_s = ort.InferenceSession(str(pkg / dec_file), so, providers=["CPUExecutionProvider"])
    joints = default_rest_joints()
    motion = make_motion("dance", seconds=2.0)
    win_all = motion_windows(motion.poses, net.cfg.window).astype(np.float32)

    def timeit(fn):
        fn()
        ts = []
        for _ in range(args.repeat):
            t0 = time.perf_counter()
            fn()
            ts.append(time.perf_counter() - t0)
        return statistics.median(ts)

    print(
        f"{'N':>6s} {'B':>3s} {'torch ms/f':>11s} {'ort ms/f':>9s} {'ort x':>6s} "
        f"{'torch+enc ms/f':>15s} {'ort+enc ms/f':>13s} {'ort+enc x':>10s}"
    )
    for n in args.sizes:
        na = int(round(np.sqrt(2.0 * n)))
        v, f = frustum(na, max(2, n // na), 0.16, 0.34, 1.02, 0.5)
        a = precompute_garment(v, f, joints, n_star=net.cfg.n_star)
        enc = {
            "features": a.features[None],
            "nbr": a.nbr,
            "mask": a.mask,
            "descriptor": a.descriptor[None].astype(np.float32),
        }
        tenc = {k: torch.as_tensor(x) for k, x in enc.items()}
        with torch.no_grad():
            P_t = net.garment_encoder(**tenc)[0]
        P = enc_s.run(None, enc)[0][0]
        for b in args.batches:
            dec = {
                "g": P,
                "window": win_all[:b],
                "betas": np.zeros((b, 10), np.float32),
                "rest": a.vertices.astype(np.float32),
                "nbr": a.nbr,
                "mask": a.mask,
                "joints": np.repeat(joints[None], b, 0).astype(np.float32),
                "trans": motion.trans[:b].astype(np.float32),
            }
            tdec = {k: torch.as_tensor(x) for k, x in dec.items()}
            tdec["g"] = P_t

            def torch_dec():
                with torch.no_grad():
                    net.deformer(**tdec)

            def torch_both():
                with torch.no_grad():
                    p = net.garment_encoder(**tenc)[0]
                    net.deformer(**dict(tdec, g=p))

            t_t = timeit(torch_dec) / b
            t_o = timeit(lambda: dec_s.run(None, dec)) / b
            t_te = timeit(torch_both) / b
            t_oe = timeit(lambda: dec_s.run(None, dict(dec, g=enc_s.run(None, enc)[0][0]))) / b
            print(
                f"{len(v):6d} {b:3d} {1e3 * t_t:11.2f} {1e3 * t_o:9.2f} {t_t / t_o:6.2f} "
                f"{1e3 * t_te:15.2f} {1e3 * t_oe:13.2f} {t_t / t_oe:10.2f}"
            )
    print("x = torch eager (encoder cached) time / this column's time, same run, one thread.")


if __name__ == "__main__":
    main()
