"""Interleaved A/B timing of one deformer graph across model packages, one onnxruntime thread.

    python bench/deformer_ab.py PKG_A PKG_B [...]   (env: V=variant name, B=frames per call, NV=vertices, R=rounds)

A frustum "skirt" of ~NV vertices on the default body; each round runs every package once, and the
minimum over rounds is reported with its ratio to the first package (so load from other processes
affects all packages alike).  To compare with an earlier commit: `git archive COMMIT
 samples/models/default | tar -x -C /tmp/old` and pass /tmp/old/samples/models/default.
"""
import sys, time, os, numpy as np, onnxruntime as ort
from pathlib import Path
from segadeform.body import load_body
from segadeform.geometry.primitives import frustum
from segadeform.geometry.asset import precompute_garment
from segadeform.runtime import ModelPackage
from segadeform.runtime.deformer import Deformer
from segadeform.scene import Effects
variant = os.environ.get("V", "deformer")  # the default deformer in old and new manifests; B = int(os.environ.get("B", 8)); NV = int(os.environ.get("NV", 4000))
body = load_body(str(Path(__file__).resolve().parents[1] / "samples" / "bodies" / "default_body.npz"))
na = int(round(np.sqrt(2.0 * NV))); v, f = frustum(na, max(2, NV // na), 0.17, 0.36, 1.02, 0.5)
j = body.rest_joints(())[0]; asset = precompute_garment(v, f, j)
rng = np.random.default_rng(0)
runs = []
for path in sys.argv[1:]:
    pkg = ModelPackage(path, threads=1); d = Deformer(pkg, Effects()); P = d.encode(asset, j)
    spec = pkg.spec(variant); T = int(dict((i["name"], i["shape"]) for i in spec["inputs"])["window"][1])
    feeds = {d.code_name: P, "window": (0.3 * rng.standard_normal((B, T, 72))).astype(np.float32), "betas": np.zeros((B, 10), np.float32),
             "rest": asset.vertices.astype(np.float32), "nbr": asset.nbr, "mask": asset.mask,
             "joints": np.repeat(j[None].astype(np.float32), B, 0), "trans": np.zeros((B, 3), np.float32)}
    feeds = {i["name"]: feeds[i["name"]] for i in spec["inputs"]}
    so = ort.SessionOptions(); so.intra_op_num_threads = 1
    s = ort.InferenceSession(str(Path(path) / spec["file"]), so, providers=["CPUExecutionProvider"])
    s.run(None, feeds); runs.append((path, s, feeds, []))
for _ in range(int(os.environ.get("R", 8))):
    for path, s, feeds, ts in runs:
        t0 = time.perf_counter(); s.run(None, feeds); ts.append(time.perf_counter() - t0)
base = min(runs[0][3])
for path, s, feeds, ts in runs:
    print(f"{variant} N={asset.n_vertices} B={B} {path}: {1e3 * min(ts) / B:.2f} ms/frame (x{min(ts) / base:.2f})")
