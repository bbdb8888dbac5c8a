"""Where WebGPU's numbers part from the CPU's: one graph of a package, every node's output compared.

    python bench/webgpu_nodes.py --package samples/models/default --graph body_lbs [--ep webgpu] [--top 25]
    python bench/webgpu_nodes.py --package PKG --graph deformer_lbs --garment G.sgda --motion M.sgdm [--frames 2]

The graph is rewritten with every float node output as a graph output, run here by onnxruntime (CPU, the
reference) and in headless Chromium by onnxruntime-web on ``--ep`` (WebGPU on SwiftShader; ``runtimes/web/test/
nodes.mjs``), both with graph optimisations off so the same nodes run; each node's output is compared.  Printed
in graph order: the node, its op, the max abs difference, that relative to the output's largest magnitude, and
the relative difference its inputs already carried (``in``), so the nodes that *add* error stand out
(``added`` = rel - in).  Used to find why docs/runtimes.md's WebGPU row differs (docs/runtimes.md says what was found).
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]


def debug_model(path: Path):
    """The graph with every node output whose type is known as a graph output, and its output names."""
    import onnx

    m = onnx.load(str(path), load_external_data=True)
    m = onnx.shape_inference.infer_shapes(m)
    known = {v.name: v for v in list(m.graph.value_info) + list(m.graph.output)}
    have = {o.name for o in m.graph.output}
    for node in m.graph.node:
        for o in node.output:
            v = known.get(o)
            if o and o not in have and v is not None and v.type.tensor_type.elem_type == onnx.TensorProto.FLOAT:
                m.graph.output.append(v)
                have.add(o)
    return m, [o.name for o in m.graph.output]


def inputs_for(pkg, name: str, a):
    from segadeform.body import default_body_path, load_body
    from segadeform.export.body import body_sample_inputs
    from segadeform.runtime import ModelPackage

    spec = ModelPackage(pkg).spec(name)
    if spec["role"] == "body":
        return body_sample_inputs(load_body(default_body_path()), b=a.frames, seed=1)
    from segadeform.io.sgdb import read_bundle
    from segadeform.motion.motion import motion_windows

    g, gm = read_bundle(a.garment)
    mo, _ = read_bundle(a.motion)
    dt = {"float32": np.float32, "int32": np.int32, "int64": np.int64, "bool": np.bool_}
    want = {i["name"]: dt[i["dtype"]] for i in spec["inputs"]}
    from segadeform.geometry.features import vertex_features  # noqa: F401

    enc = {"features": g["features"][None], "nbr": g["nbr"], "mask": g["mask"], "descriptor": g["descriptor"][None]}
    if spec["role"] == "encoder":
        return {k: v.astype(want[k]) for k, v in enc.items() if k in want}
    import onnxruntime as ort

    es = ModelPackage(pkg).spec("garment_encoder")
    sess = ort.InferenceSession(str(Path(pkg) / es["file"]))
    ein = {i["name"]: enc[i["name"]].astype(dt[i["dtype"]]) for i in es["inputs"]}
    code = sess.run(None, ein)[0][0]
    b = a.frames
    poses = mo["poses"].reshape(len(mo["poses"]), -1)
    win = motion_windows(poses.astype(np.float32), spec["inputs"][1]["shape"][1], start=0, stop=b)
    nb = spec["inputs"][2]["shape"][1]
    betas = np.zeros(nb, np.float32)
    betas[: min(nb, len(g["betas"]))] = g["betas"][:nb]
    feeds = {
        "g": code,
        "window": win,
        "betas": np.repeat(betas[None], b, 0),
        "rest": g["vertices"].astype(np.float32),
        "nbr": g["nbr"],
        "mask": g["mask"],
        "joints": np.repeat(g["joints"][None].astype(np.float32), b, 0),
        "trans": mo["trans"][:b],
        "log_wbody": g["log_wbody"],
    }
    return {k: np.asarray(feeds[k]).astype(want[k]) for k in want}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--package", type=Path, default=ROOT / "samples" / "models" / "default")
    ap.add_argument("--graph", default="body_lbs")
    ap.add_argument("--garment", type=Path)
    ap.add_argument("--motion", type=Path)
    ap.add_argument("--frames", type=int, default=1)
    ap.add_argument("--ep", default="webgpu")
    ap.add_argument("--opt", default="disabled", help="onnxruntime-web graphOptimizationLevel (disabled | all)")
    ap.add_argument("--top", type=int, default=25)
    a = ap.parse_args(argv)
    import onnx
    import onnxruntime as ort

    from segadeform.io.sgdb import write_bundle
    from segadeform.runtime import ModelPackage

    spec = ModelPackage(a.package).spec(a.graph)
    feeds = inputs_for(a.package, a.graph, a)
    with tempfile.TemporaryDirectory() as d:
        d = Path(d)
        m, outs = debug_model(a.package / spec["file"])
        onnx.save(m, str(d / "debug.onnx"))
        so = ort.SessionOptions()
        so.graph_optimization_level = ort.GraphOptimizationLevel.ORT_DISABLE_ALL
        ref = ort.InferenceSession(str(d / "debug.onnx"), so, providers=["CPUExecutionProvider"]).run(None, feeds)
        keys = {o: f"o{i}" for i, o in enumerate(outs)}
        arrays = {f"in__{k}": (v.astype(np.uint8) if v.dtype == np.bool_ else v) for k, v in feeds.items()}
        arrays.update({f"out__{keys[o]}": np.asarray(r, np.float32) for o, r in zip(outs, ref, strict=True)})
        write_bundle(d / "data.sgdb", arrays, {"inputs": list(feeds), "outputs": outs, "keys": keys})
        (d / "runtimes").symlink_to(ROOT / "runtimes")
        p = subprocess.run(
            [
                "node",
                str(ROOT / "runtimes" / "web" / "test" / "nodes.mjs"),
                "--root",
                str(d),
                "--model",
                "debug.onnx",
                "--data",
                "data.sgdb",
                "--ep",
                a.ep,
                "--opt",
                a.opt,
            ],
            capture_output=True,
            text=True,
            timeout=3000,
        )
        if p.returncode:
            print(p.stdout[-2000:], p.stderr[-3000:])
            return 1
        res = json.loads(next(ln for ln in p.stdout.splitlines() if ln.startswith("NODES "))[6:])
    rel = {k: v[0] / max(v[1], 1e-30) for k, v in res.items()}
    rows = []
    producer = {}
    for node in m.graph.node:
        for o in node.output:
            producer[o] = node
    for node in m.graph.node:
        for o in node.output:
            if o not in rel:
                continue
            inn = max([rel.get(i, 0.0) for i in node.input] or [0.0])
            rows.append((node.name or o, node.op_type, res[o][0], rel[o], inn, rel[o] - inn, o))
    final = [o["name"] for o in spec["outputs"] if o["name"] in rel]
    print(
        f"{a.graph} on {a.ep} (graph optimisations {a.opt}): final outputs "
        + ", ".join(f"{o} rel {rel[o]:.2e}" for o in final)
    )
    print(f"\nthe {a.top} nodes adding the most relative error (node, op, max abs, rel, rel of inputs, added):")
    for r in sorted(rows, key=lambda r: -r[5])[: a.top]:
        print(f"  {r[0][:60]:60s} {r[1]:10s} {r[2]:.2e} {r[3]:.2e} {r[4]:.2e} {r[5]:+.2e}")
    ops = {}
    for r in rows:
        ops[r[1]] = max(ops.get(r[1], 0.0), r[5])
    print(
        "\nlargest added relative error by op: "
        + ", ".join(f"{k} {v:.1e}" for k, v in sorted(ops.items(), key=lambda kv: -kv[1]))
    )
    return 0


if __name__ == "__main__":
    sys.exit(main())
