"""How a package's graph files are stored (needs ``onnx``, not torch): debug metadata stripped, and one
copy of the weights shared by every graph.

Nothing here changes what a graph computes: the nodes, their attributes and every initializer's
bytes stay as exported; only where the bytes live changes.

* :func:`strip_debug_info` drops what the exporter records for debugging: per-node metadata (the
  torch stack trace, FX node and module path of every node: about 85 % of an exported deformer's
  bytes, and local paths of the machine that exported it) and doc strings.
* :func:`pack_graphs` writes every initializer of at least ``min_bytes`` once into one
  ``weights.bin`` (ONNX external data, 64-byte aligned offsets, deduplicated by dtype, shape and
  bytes) and points each graph's initializers at it: the 8 deformer variants of a model repeat
  the same weights, which are then stored once.  onnxruntime (Python, Node, C, web with
  ``externalData``), Unity Sentis and the ``onnx`` package load such graphs from the folder;
  ``shared=False`` keeps every graph self-contained instead.
* :func:`repack_package` rewrites an existing package (schema 1, 2 or 3) in the current layout
  without re-exporting it: the same graphs, one name and one file per graph, their int64 and bool
  inputs read as int32 and float32 (a Cast inside) and their sin and cos as polynomials
  (:func:`~.portability.replace_trig`, within 2e-7 of the builtins).
"""

from __future__ import annotations

import hashlib
import json
import os
import shutil
from pathlib import Path

from segadeform.contracts import model_package as spec
from segadeform.errors import InputError
from segadeform.io.atomic import atomic_directory
from segadeform.io.hashing import file_sha256

__all__ = ["strip_debug_info", "pack_graphs", "repack_package", "finish_package", "ALIGN"]

ALIGN = 64


def strip_debug_info(model) -> None:
    """Remove per-node metadata and doc strings from ``model`` (an ``onnx.ModelProto``), in place."""
    from .portability import iter_graphs, iter_nodes

    for graph in iter_graphs(model):
        graph.doc_string = ""
    for node in iter_nodes(model):
        del node.metadata_props[:]
        node.doc_string = ""


def _raw_bytes(tensor) -> bytes:
    """The tensor's data as little-endian raw bytes (what external data stores)."""
    from onnx import numpy_helper

    a = numpy_helper.to_array(tensor)
    if a.dtype.byteorder == ">":
        a = a.astype(a.dtype.newbyteorder("<"))
    return a.tobytes()


def pack_graphs(
    folder: str | os.PathLike,
    files: list[str],
    *,
    shared: bool = True,
    min_bytes: int = 256,
    weights_file: str = spec.WEIGHTS_FILE,
) -> dict | None:
    """Rewrite the graph ``files`` in ``folder``: debug info stripped; with ``shared``, initializers of at
    least ``min_bytes`` moved into one deduplicated ``weights_file``.

    Every graph is read (with any external data it already has) before anything is written.
    Returns the manifest's ``weights`` entry (``file``, ``sha256``, ``bytes``), or None when nothing
    was shared (``shared=False`` or no initializer large enough), in which case no weights file is left.
    """
    import onnx

    folder = Path(folder)
    models = {f: onnx.load(str(folder / f), load_external_data=True) for f in files}
    blob = bytearray()
    where: dict[tuple, tuple[int, int]] = {}
    for model in models.values():
        strip_debug_info(model)
        if not shared:
            continue
        for t in model.graph.initializer:
            if t.data_type in (onnx.TensorProto.STRING, onnx.TensorProto.UNDEFINED):
                continue
            data = _raw_bytes(t)
            if len(data) < min_bytes:
                continue
            key = (t.data_type, tuple(t.dims), hashlib.sha256(data).digest())
            if key not in where:
                off = -(-len(blob) // ALIGN) * ALIGN
                blob.extend(b"\0" * (off - len(blob)))
                blob.extend(data)
                where[key] = (off, len(data))
            off, length = where[key]
            for field in ("float_data", "int32_data", "int64_data", "double_data", "uint64_data", "raw_data"):
                t.ClearField(field)
            del t.external_data[:]
            for key, value in (("location", weights_file), ("offset", str(off)), ("length", str(length))):
                entry = t.external_data.add()
                entry.key, entry.value = key, value
            t.data_location = onnx.TensorProto.EXTERNAL
    wpath = folder / weights_file
    if blob:
        wpath.write_bytes(bytes(blob))
    elif wpath.exists():
        wpath.unlink()
    for f, model in models.items():
        (folder / f).write_bytes(model.SerializeToString())
        onnx.checker.check_model(str(folder / f))
    if not blob:
        return None
    return {"file": weights_file, "sha256": file_sha256(wpath), "bytes": len(blob)}


def convert_opset(model, opset: int):
    """``model`` (an ``onnx.ModelProto``) at another default-domain opset, by onnx's version converter.

    The graphs convert to opset 15 and up; below 15 onnx has no adapter for their ``Shape`` nodes.
    ``tests/export/test_package_spec.py`` checks that a converted package computes the same outputs."""
    import onnx
    from onnx import version_converter

    if not spec.SUPPORTED_OPSETS.start <= int(opset) < spec.SUPPORTED_OPSETS.stop:
        raise InputError(
            "unsupported ONNX opset",
            expected=f"{spec.SUPPORTED_OPSETS.start}..{spec.SUPPORTED_OPSETS.stop - 1}",
            got=opset,
        )
    now = next(o.version for o in model.opset_import if o.domain in ("", "ai.onnx"))
    if now == opset:
        return model
    out = version_converter.convert_version(model, int(opset))
    if opset < 18:  # the converter keeps opset 18's noop_with_empty_axes on reductions that had none before
        from .portability import iter_nodes

        for node in iter_nodes(out):
            if node.op_type.startswith("Reduce") and (node.op_type != "ReduceSum" or opset < 13):
                keep = [a for a in node.attribute if a.name != "noop_with_empty_axes"]
                if any(a.name == "noop_with_empty_axes" and a.i for a in node.attribute):
                    raise InputError(f"{node.op_type} with noop_with_empty_axes=1 has no opset-{opset} form")
                del node.attribute[:]
                node.attribute.extend(keep)
    onnx.checker.check_model(out)
    return out


def repack_package(
    src: str | os.PathLike,
    dst: str | os.PathLike,
    *,
    shared: bool = True,
    training_garments: dict | None = None,
    training_motions: dict | None = None,
    opset: int | None = None,
) -> dict:
    """Write package ``src`` (schema 1, 2 or 3) to ``dst`` in the current layout; returns the new manifest.

    The graphs are the same (what they compute is unchanged but for sin and cos, now polynomials within 2e-7
    of the builtins; only their storage, their int64/bool inputs, which become int32/float32 read through a
    Cast, and, for schema-1 packages, the file name of the model's own deformer change): debug info stripped,
    weights shared unless ``shared=False``.  The model card and other ``.md``/``.txt`` files are copied; checkpoints and
    reports are not (they live beside a package, not in it).  ``training_garments`` (a manifest entry,
    :func:`export.training_set.training_garments_entry`) replaces the package's list, ``training_motions``
    (:func:`segadeform.motion.fingerprint.motions_record`) its record of motions; ``opset`` converts
    every graph (:func:`convert_opset`, e.g. 15 for Unity Sentis).  Written atomically."""
    import onnx

    from .portability import make_inputs_portable, op_counts, replace_trig

    src, dst = Path(src), Path(dst)
    mpath = src / spec.MANIFEST_FILE
    if not mpath.is_file():
        raise InputError("not a model package (no manifest.json)", path=src)
    if src.resolve() == dst.resolve():
        raise InputError("repack writes a new folder", expected="an output other than the package", got=dst)
    m = spec.read_manifest_text(mpath.read_text(encoding="utf-8"), path=mpath)
    with atomic_directory(dst) as tmp:
        tmp = Path(tmp)
        graphs, ops = {}, {}
        for name, g in m["graphs"].items():
            new = spec.graph_file(name)
            model = onnx.load(str(src / g["file"]), load_external_data=True)
            retyped = make_inputs_portable(model)  # schema 3: int32 / float32 inputs (older packages: int64 / bool)
            replace_trig(model)  # sin and cos float32-accurate on WebGPU (graphs exported before it)
            onnx.save(model if opset is None else convert_opset(model, opset), str(tmp / new))
            graphs[name] = dict(
                g, file=new, inputs=[dict(i, dtype=retyped.get(i["name"], i["dtype"])) for i in g["inputs"]]
            )
        weights = pack_graphs(tmp, [g["file"] for g in graphs.values()], shared=shared)
        for name, g in graphs.items():
            g["sha256"] = file_sha256(tmp / g["file"])
            ops[name] = dict(sorted(op_counts(onnx.load(str(tmp / g["file"]), load_external_data=False)).items()))
        out = {k: v for k, v in m.items() if k not in ("graphs", "ops", "weights", "upgraded_from")}
        out.update(schema_version=spec.SCHEMA_VERSION, graphs=graphs, ops=ops)
        if opset is not None:
            out["opset"] = int(opset)
        if training_garments is not None:
            out[spec.TRAINING_GARMENTS] = training_garments
        if training_motions is not None:
            out[spec.TRAINING_MOTIONS] = training_motions
        if weights is not None:
            out["weights"] = weights
        finish_package(src, tmp, out, dst)
    return out


def finish_package(src: Path, tmp: Path, manifest: dict, dst: Path) -> None:
    """The last step of rewriting a package ``src`` into ``tmp`` (the folder that becomes ``dst``): validate
    ``manifest``, carry the package's documents (``.md``, ``.txt``: the model card) over, write ``manifest.json``."""
    spec.validate_manifest(manifest, path=Path(dst) / spec.MANIFEST_FILE)
    for extra in Path(src).iterdir():
        if extra.is_file() and extra.suffix in (".md", ".txt"):
            shutil.copyfile(extra, Path(tmp) / extra.name)
    (Path(tmp) / spec.MANIFEST_FILE).write_text(json.dumps(manifest, indent=2, sort_keys=True) + "\n", encoding="utf-8")
