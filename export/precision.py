"""A model package at another precision: fp16 weights or int8 dynamic quantisation.

``convert_package(src, dst, precision)`` copies a package and rewrites every graph file:

* ``fp16-weights``: every float32 weight tensor stored as float16, followed by a Cast back to float32;
  onnxruntime folds the Casts when it loads the graph, so the arithmetic stays float32: the file is
  about half the size, the speed that of fp32, and the error that of rounding the weights to fp16.
* ``int8``: onnxruntime's dynamic quantisation (``quantize_dynamic``): MatMul/Gemm weights stored as
  int8, activations quantised per call; inputs and outputs stay float32.

The body graphs (``body_lbs``, ``body_dqs``: the body's own skinning, which collisions and ``--body-out`` use)
stay float32 at every precision: rounding the body's blend shapes and weights moves the posed body by centimetres
(int8) and millimetres (fp16) for no gain in the model.

The manifest gets the new files' SHA-256, ``"precision"`` and the current layout (schema 3: one file per
graph, the weights shared in ``weights.bin``, int32/float32 inputs); nothing else changes. Error and speed
of each precision are measured by ``bench/tradeoffs.py`` (docs/accuracy-vs-time.md).

Not here: fp16 *arithmetic*.  onnxruntime's CPU provider has float16 kernels for few of the graphs' ops
(it would insert a Cast around every other node), and onnxconverter-common's float16 conversion of the
exported graphs gave a garment encoder onnxruntime refuses to load (a Cast whose declared output type
disagrees with its node); with Cast kept in fp32 it did not finish in 90 minutes on this machine.
fp16 arithmetic is a GPU matter (the CUDA provider), measured when a GPU is at hand.
"""

from __future__ import annotations

import json
import os
import shutil
import tempfile
from pathlib import Path

from segadeform.contracts import model_package as contract
from segadeform.errors import InputError
from segadeform.io.atomic import atomic_directory

from ..io.hashing import file_sha256
from .packing import pack_graphs

__all__ = ["PRECISIONS", "convert_package", "convert_graph"]

PRECISIONS = ("fp32", "fp16-weights", "int8")

#: float32 weights with fewer elements stay as they are (scalars and tiny vectors: nothing to save)
FP16_MIN_ELEMENTS = 16


def convert_graph(src: Path, dst: Path, precision: str) -> None:
    """Write graph ``src`` (.onnx) at ``precision`` to ``dst``."""
    if precision not in PRECISIONS:
        raise InputError("unknown precision", expected=" | ".join(PRECISIONS), got=precision)
    if precision == "fp32":  # self-contained (any external weights read in); the packing shares them again
        import onnx

        onnx.save(onnx.load(str(src), load_external_data=True), str(dst))
    elif precision == "fp16-weights":
        import onnx

        m = onnx.load(str(src), load_external_data=True)
        _fp16_weights(m.graph)
        onnx.save(m, str(dst))
    else:
        import onnx
        from onnxruntime.quantization import QuantType, quantize_dynamic

        with tempfile.TemporaryDirectory() as tmp:  # quantize_dynamic writes side files beside its output
            # the exporter's intermediate value_info can carry the example's sizes, which the
            # quantiser's shape inference then contradicts: let it infer them afresh
            m = onnx.load(str(src))
            del m.graph.value_info[:]
            plain, out = Path(tmp) / "plain.onnx", Path(tmp) / "q.onnx"
            onnx.save(m, str(plain))
            import logging

            root = logging.getLogger()
            level = root.level
            root.setLevel(logging.ERROR)  # the quantiser's advice goes to the root logger
            try:
                quantize_dynamic(str(plain), str(out), weight_type=QuantType.QInt8)
            finally:
                root.setLevel(level)
            shutil.copyfile(out, dst)


def _fp16_weights(graph) -> None:
    """Store ``graph``'s float32 initializers (with >= FP16_MIN_ELEMENTS elements) as float16, each read
    through a Cast to float32 under its old name, so every consumer is unchanged."""
    import numpy as np
    from onnx import TensorProto, helper, numpy_helper

    casts, keep = [], []
    for init in graph.initializer:
        n = int(np.prod(init.dims)) if len(init.dims) else 1
        if init.data_type != TensorProto.FLOAT or n < FP16_MIN_ELEMENTS:
            keep.append(init)
            continue
        half = numpy_helper.from_array(numpy_helper.to_array(init).astype(np.float16), init.name + "__fp16")
        keep.append(half)
        casts.append(
            helper.make_node("Cast", [half.name], [init.name], to=TensorProto.FLOAT, name=init.name + "__to_fp32")
        )
    del graph.initializer[:]
    graph.initializer.extend(keep)
    nodes = list(graph.node)
    del graph.node[:]
    graph.node.extend(casts + nodes)


def _portable_inputs(path: Path) -> dict:
    """An older package's int64/bool graph inputs as int32/float32 (schema 3), in place; the inputs changed."""
    import onnx

    from .portability import make_inputs_portable

    m = onnx.load(str(path), load_external_data=True)
    changed = make_inputs_portable(m)
    if changed:
        onnx.save(m, str(path))
    return changed


def convert_package(src: str | os.PathLike, dst: str | os.PathLike, precision: str) -> Path:
    """Copy package ``src`` to ``dst`` with every graph at ``precision``; returns ``dst``.

    Written to a temporary folder and renamed, so a failed conversion leaves no ``dst``."""
    src, dst = Path(src), Path(dst)
    if precision not in PRECISIONS:
        raise InputError("unknown precision", expected=" | ".join(PRECISIONS), got=precision)
    mpath = src / contract.MANIFEST_FILE
    if not mpath.is_file():
        raise InputError("not a model package (no manifest.json)", path=src)
    m = contract.read_manifest_text(mpath.read_text(encoding="utf-8"), path=mpath)
    if m.get("precision", "fp32") != "fp32":  # its weights are rounded already: again would round the rounding
        raise InputError(
            f"the package is at precision {m['precision']} already: convert the float32 package it was made from",
            expected="precision fp32 (or none)",
            got=m["precision"],
            path=src,
        )
    with atomic_directory(dst) as tmp:
        tmp = Path(tmp)
        graphs = {}
        for name, spec in m["graphs"].items():
            f = contract.graph_file(name)
            # the body graphs pose the body, not the learned model: kept float32 (int8 moved the posed body by up
            # to 5 cm, and the collisions with it; a user's trial)
            convert_graph(src / spec["file"], tmp / f, "fp32" if "body" in spec else precision)
            retyped = _portable_inputs(tmp / f)
            graphs[name] = dict(
                spec, file=f, inputs=[dict(i, dtype=retyped.get(i["name"], i["dtype"])) for i in spec["inputs"]]
            )
        weights = pack_graphs(tmp, [g["file"] for g in graphs.values()])
        for g in graphs.values():
            g["sha256"] = file_sha256(tmp / g["file"])
        for extra in src.iterdir():  # the model card and the like, not the checkpoint or reports
            if extra.is_file() and extra.suffix in (".md", ".txt") and not (tmp / extra.name).exists():
                shutil.copyfile(extra, tmp / extra.name)
        out = {k: v for k, v in m.items() if k not in ("graphs", "weights", "upgraded_from")}
        out.update(schema_version=contract.SCHEMA_VERSION, graphs=graphs, precision=precision)
        if weights is not None:
            out["weights"] = weights
        contract.validate_manifest(out, path=dst / contract.MANIFEST_FILE)
        (tmp / contract.MANIFEST_FILE).write_text(json.dumps(out, indent=2, sort_keys=True) + "\n")
    return dst
