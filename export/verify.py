"""torch vs onnxruntime parity for an exported graph."""

from __future__ import annotations

import numpy as np

__all__ = ["parity", "compare"]


def compare(ref: np.ndarray, got: np.ndarray) -> tuple[float, float]:
    """(max absolute error, max error relative to the reference's largest magnitude)."""
    ref = np.asarray(ref, np.float64)
    got = np.asarray(got, np.float64)
    err = float(np.abs(ref - got).max()) if ref.size else 0.0
    scale = float(np.abs(ref).max()) if ref.size else 0.0
    return err, err / max(scale, 1e-30)


def parity(module, onnx_path, spec, cfg, sizes=((3, 4, 1), (37, 7, 2), (300, 9, 5)), graph: str | None = None) -> dict:
    """Run torch and onnxruntime on random inputs of several (N, K, B); worst abs/rel error per output.

    ``graph`` is "garment_encoder" or "deformer" (default: from the file name)."""
    import onnxruntime as ort
    import torch

    from .package import sample_inputs

    name = graph or spec["file"].replace(".onnx", "")
    sess = ort.InferenceSession(str(onnx_path), providers=["CPUExecutionProvider"])
    worst = {o["name"]: [0.0, 0.0] for o in spec["outputs"]}
    for n, k, b in sizes:
        feeds = sample_inputs(cfg, name, n=n, k=k, b=b, seed=n + k + b)
        with torch.no_grad():
            ref = module(*(torch.as_tensor(feeds[i["name"]]) for i in spec["inputs"]))
        ref = ref if isinstance(ref, tuple) else (ref,)
        got = sess.run(None, feeds)
        for o, r, g in zip(spec["outputs"], ref, got, strict=False):
            a, rel = compare(r.numpy(), g)
            worst[o["name"]][0] = max(worst[o["name"]][0], a)
            worst[o["name"]][1] = max(worst[o["name"]][1], rel)
    return {k: {"max_abs": v[0], "max_rel": v[1]} for k, v in worst.items()}
