"""Interleaved A/B timing of one deformer graph across model packages, one onnxruntime thread.

    python bench/deformer_ab.py PKG_A PKG_B [...] [--variant deformer_lbs] [--batch 8] [--vertices 4000] [--rounds 8]

A frustum "skirt" of about ``--vertices`` vertices on the default body; each round runs every package
once, and the minimum over rounds is reported with its ratio to the first package (so load from other
processes affects all packages alike).  ``--variant`` names the graph (default: each package's default
deformer; e.g. ``deformer_lbs_nowrinkles`` for the path without blend shapes, or a body graph,
``body_lbs`` / ``body_dqs``, posing the package's body ``--batch`` times).  To compare with an
earlier commit: ``git archive COMMIT samples/models/default | tar -x -C /tmp/old`` and pass
``/tmp/old/samples/models/default``.
"""

from __future__ import annotations

import argparse
import time

import numpy as np
import onnxruntime as ort

from segadeform.body import default_body_path, load_body
from segadeform.geometry.precompute import precompute_garment
from segadeform.geometry.primitives import frustum
from segadeform.runtime import ModelPackage
from segadeform.runtime.deformer import Deformer
from segadeform.settings import Effects


def main(argv=None) -> list[tuple[str, float]]:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("packages", nargs="+")
    ap.add_argument("--variant", default=None, help="graph name (default: each package's default deformer)")
    ap.add_argument("--batch", type=int, default=8, help="frames per call")
    ap.add_argument("--vertices", type=int, default=4000)
    ap.add_argument("--rounds", type=int, default=8)
    a = ap.parse_args(argv)
    body = load_body(default_body_path())
    na = int(round(np.sqrt(2.0 * a.vertices)))
    v, f = frustum(na, max(2, a.vertices // na), 0.17, 0.36, 1.02, 0.5)
    joints = body.rest_joints(())[0]
    asset = precompute_garment(v, f, joints)
    rng = np.random.default_rng(0)
    b = a.batch
    runs = []
    for path in a.packages:
        pkg = ModelPackage(path, threads=1)
        dec = Deformer(pkg, Effects(collisions=False))
        variant = a.variant or pkg.default_deformer
        spec = pkg.spec(variant)
        shapes = {i["name"]: i["shape"] for i in spec["inputs"]}
        if spec["role"] == "body":  # a body graph: B poses of the package's body
            feeds = {
                "betas": np.zeros(shapes["betas"][0], np.float32),
                "poses": (0.3 * rng.standard_normal((b, *shapes["poses"][1:]))).astype(np.float32),
                "trans": np.zeros((b, 3), np.float32),
            }
            runs.append((path, variant, _session(pkg, spec), feeds, []))
            runs[-1][2].run(None, feeds)
            continue
        t = int(shapes["window"][1])
        code = dec.encode(asset, joints)
        feeds = {
            dec.code_name: code,
            "window": (0.3 * rng.standard_normal((b, t, 72))).astype(np.float32),
            "betas": np.zeros((b, 10), np.float32),
            "rest": asset.vertices.astype(np.float32),
            "nbr": asset.nbr,
            "mask": asset.mask,
            "joints": np.repeat(joints[None].astype(np.float32), b, 0),
            "trans": np.zeros((b, 3), np.float32),
        }
        if "log_wbody" in shapes:
            feeds["log_wbody"] = dec.body_log_weights(asset, body, np.zeros(0))
        feeds = {name: feeds[name] for name in shapes}
        sess = _session(pkg, spec)
        for w in spec["inputs"]:  # each input in its manifest's dtype (schema 3: int32 nbr, float32 mask)
            feeds[w["name"]] = np.ascontiguousarray(np.asarray(feeds[w["name"]]).astype(w["dtype"]))
        sess.run(None, feeds)
        runs.append((path, variant, sess, feeds, []))
    for _ in range(a.rounds):
        for _, _, sess, feeds, ts in runs:
            t0 = time.perf_counter()
            sess.run(None, feeds)
            ts.append(time.perf_counter() - t0)
    base = min(runs[0][4])
    out = []
    for path, variant, _, _, ts in runs:
        ms = 1e3 * min(ts) / b
        size = "body" if variant.startswith("body") else f"N={asset.n_vertices}"
        print(f"{variant} {size} B={b} {path}: {ms:.2f} ms/frame (x{min(ts) / base:.2f})")
        out.append((path, ms))
    return out


def _session(pkg, spec):
    so = ort.SessionOptions()
    so.intra_op_num_threads = 1
    return ort.InferenceSession(str(pkg.path / spec["file"]), so, providers=["CPUExecutionProvider"])


if __name__ == "__main__":
    main()
