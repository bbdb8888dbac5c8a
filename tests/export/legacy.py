"""Packages as older exporters wrote them, made from a current one, for the tests that check they still run:
schema 2 (int64 ``nbr`` and bool ``mask`` graph inputs, no body graphs) and schema 1 (the model's own deformer
listed twice as ``deformer.onnx``)."""

from __future__ import annotations

import json
from pathlib import Path

import onnx
from onnx import TensorProto, helper

from segadeform.io.hashing import file_sha256


def legacy_inputs(model) -> None:
    """``model``'s int32 inputs as int64 and its float32 ``mask`` as bool, each read through a Cast back (in place):
    the graph as schema-2 exports took them."""
    casts = []
    for inp in model.graph.input:
        tt = inp.type.tensor_type
        if tt.elem_type == TensorProto.INT32 or (inp.name == "mask" and tt.elem_type == TensorProto.FLOAT):
            old, new = tt.elem_type, (TensorProto.INT64 if tt.elem_type == TensorProto.INT32 else TensorProto.BOOL)
            inner = f"{inp.name}__current"
            for node in model.graph.node:
                for k, x in enumerate(node.input):
                    if x == inp.name:
                        node.input[k] = inner
            casts.append(helper.make_node("Cast", [inp.name], [inner], to=old))
            tt.elem_type = new
    nodes = list(model.graph.node)
    del model.graph.node[:]
    model.graph.node.extend(casts + nodes)


def as_schema(src: Path, dst: Path, version: int) -> Path:
    """``src`` (a current package) rewritten as a schema-``version`` (1 or 2) package in ``dst``."""
    m = json.loads((src / "manifest.json").read_text())
    dst.mkdir()
    dtype = {"int32": "int64", "float32": "float32"}
    graphs = {}
    for name, g in m["graphs"].items():
        if g["role"] == "body":
            continue
        f = "deformer.onnx" if version == 1 and name == m["default_deformer"] else g["file"]
        model = onnx.load(str(src / g["file"]), load_external_data=True)
        legacy_inputs(model)
        onnx.save(model, str(dst / f))
        inputs = [dict(i, dtype="bool" if i["name"] == "mask" else dtype[i["dtype"]]) for i in g["inputs"]]
        graphs[name] = dict(g, file=f, inputs=inputs, sha256=file_sha256(dst / f))
    old = {k: v for k, v in m.items() if k not in ("graphs", "weights", "ops")}
    if version == 1:
        for g in graphs.values():
            g.pop("role", None)
        enc = graphs.pop("garment_encoder")
        dflt = {k: v for k, v in graphs[m["default_deformer"]].items() if k not in ("effects", "window")}
        old.pop("default_deformer")
        old.update(schema_version=1, graphs={"garment_encoder": enc, "deformer": dflt}, variants=graphs)
    else:
        old.update(schema_version=2, graphs=graphs)
    (dst / "manifest.json").write_text(json.dumps(old))
    return dst
