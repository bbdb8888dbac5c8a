"""The body model as ONNX graphs (``body_lbs``, ``body_dqs``), so runtimes without Python pose the body
from one source of truth: the body file, exported once, run by every runtime's onnxruntime.

A body graph takes the shape ``betas (|beta|,)``, the poses ``(B, S, 3)`` (axis-angle, SMPL order) and
the root translations ``(B, 3)`` of B frames, and returns the posed vertices ``(B, V, 3)`` and joints
``(B, S, 3)``, the rest joints of the shape ``(S, 3)`` and the body's triangles ``(F, 3)`` (constant: the
graph alone describes the mesh).  It computes what :meth:`segadeform.body.BodyModel.forward` does
(shape blend, pose blend shapes when the body has them, forward kinematics, LBS or DQS) in float32, with
the network's own exportable kinematics (:mod:`segadeform.model.kinematics`); ``tests/export`` and
``tests/runtimes`` hold every runtime to the numpy body within 1e-5 relative.

Why a graph rather than the body maths written again in JavaScript and C++: one implementation, the
one the package's deformers already use, so the body and the garment are posed by the same kernels in
every runtime, and engines that import ONNX (Unity Sentis, Unreal NNE) get the body for free.
"""

from __future__ import annotations

import os
import threading
from pathlib import Path

import numpy as np

from segadeform.contracts import model_package as contract
from segadeform.errors import InputError
from segadeform.io.atomic import atomic_directory

__all__ = ["body_module", "export_body_graphs", "add_body_to_package", "body_sample_inputs"]


def body_module(body, skinning: str):
    """A torch module posing ``body`` (a :class:`~segadeform.body.BodyModel`) with ``skinning`` (lbs | dqs):
    ``(betas (|beta|,), poses (B, S, 3), trans (B, 3)) -> vertices, joints, rest_joints, faces``."""
    import torch

    from segadeform.model.kinematics import axis_angle_to_matrix, dqs, forward_kinematics, lbs, skinning_transforms

    if skinning not in contract.SKINNING:
        raise InputError("unknown skinning", expected=" | ".join(contract.SKINNING), got=skinning)
    body.validate()
    f32 = torch.float32

    class BodyGraph(torch.nn.Module):
        def __init__(self):
            super().__init__()
            v, s, nb = body.n_vertices, body.n_joints, body.n_betas
            self.parents = [int(p) for p in body.parents]
            self.register_buffer("v_template", torch.as_tensor(body.v_template, dtype=f32))
            # (|beta|, 3 V): the shape blend as one (1, |beta|) x (|beta|, 3 V) product
            self.register_buffer("shapedirs", torch.as_tensor(body.shapedirs.reshape(v * 3, nb).T.copy(), dtype=f32))
            self.register_buffer("weights", torch.as_tensor(body.weights, dtype=f32))
            self.register_buffer("triangles", torch.as_tensor(body.faces, dtype=torch.int32))
            self.regressor = body.J_regressor is not None
            if self.regressor:
                self.register_buffer("j_regressor", torch.as_tensor(body.J_regressor, dtype=f32))
            else:
                self.register_buffer("joint_template", torch.as_tensor(body.joint_template, dtype=f32))
                self.register_buffer(
                    "joint_shapedirs", torch.as_tensor(body.joint_shapedirs.reshape(s * 3, nb).T.copy(), dtype=f32)
                )
            self.posed = body.posedirs is not None
            if self.posed:  # (9 (S - 1), 3 V)
                self.register_buffer("posedirs", torch.as_tensor(body.posedirs.reshape(v * 3, -1).T.copy(), dtype=f32))

        def forward(self, betas, poses, trans):
            v, s = self.v_template.shape[0], len(self.parents)
            b = poses.shape[0]
            shaped = self.v_template + torch.matmul(betas[None], self.shapedirs).reshape(v, 3)  # (V, 3)
            if self.regressor:
                rest = torch.matmul(self.j_regressor, shaped)  # (S, 3)
            else:
                rest = self.joint_template + torch.matmul(betas[None], self.joint_shapedirs).reshape(s, 3)
            rot = axis_angle_to_matrix(poses)  # (B, S, 3, 3)
            verts = shaped
            if self.posed:
                eye = torch.eye(3, dtype=rot.dtype)
                feat = (rot[:, 1:] - eye).reshape(b, -1)  # (B, 9 (S - 1))
                verts = shaped[None] + torch.matmul(feat, self.posedirs).reshape(b, v, 3)
            joints = rest[None].expand(b, s, 3)
            g = forward_kinematics(rot, joints, self.parents, trans)
            a = skinning_transforms(g, joints)
            if skinning == "dqs":
                posed = dqs(verts, self.weights, a)
            else:
                posed = lbs(verts, self.weights, a)
            return posed, g[..., :3, 3], rest, self.triangles

    return BodyGraph().eval()


def body_sample_inputs(body, *, b: int = 3, seed: int = 0) -> dict[str, np.ndarray]:
    """Random valid body-graph inputs for B = ``b`` frames (poses within a quarter turn per axis)."""
    rng = np.random.default_rng(seed)
    return {
        "betas": rng.normal(0.0, 1.0, body.n_betas).astype(np.float32),
        "poses": rng.uniform(-0.8, 0.8, (b, body.n_joints, 3)).astype(np.float32),
        "trans": rng.normal(0.0, 0.3, (b, 3)).astype(np.float32),
    }


def _export(module, inputs: dict, spec: dict, path: Path) -> None:
    import logging
    import warnings

    import torch
    from torch.export import Dim

    args = tuple(torch.as_tensor(inputs[i["name"]]) for i in spec["inputs"])
    dyn = {
        i["name"]: {ax: Dim("B", min=1, max=1 << 20) for ax, d in enumerate(i["shape"]) if d == "B"}
        for i in spec["inputs"]
    }
    # the exporter's chatter, and its report that it keeps the constant output `triangles` as it is (printed on every
    # export, about nothing to act on: a researcher's trial), quiet for this export only
    quiet = [logging.getLogger(n) for n in ("torch.onnx", "onnx_ir.passes.common.initializer_deduplication")]
    levels = [q.level for q in quiet]
    for q in quiet:
        q.setLevel(logging.ERROR)
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            prog = torch.onnx.export(
                module,
                args,
                dynamo=True,
                opset_version=contract.OPSET,
                dynamic_shapes=dyn,
                input_names=[i["name"] for i in spec["inputs"]],
                output_names=[o["name"] for o in spec["outputs"]],
                verbose=False,
            )
            prog.save(str(path), external_data=False)
    finally:
        for q, lv in zip(quiet, levels, strict=True):
            q.setLevel(lv)


def _constant_outputs(proto) -> None:
    """The exporter hands a constant output (``faces``) through an ``Identity`` of an initializer; the output
    is made the initializer itself (valid ONNX, and onnx's opset converter has no Identity adapter below 16)."""
    outs = {o.name for o in proto.graph.output}
    inits = {t.name: t for t in proto.graph.initializer}
    keep = []
    for n in proto.graph.node:
        if (
            n.op_type == "Identity"
            and n.input[0] in inits
            and n.output[0] in outs
            and sum(n.input[0] in m.input for m in proto.graph.node) == 1
        ):
            inits[n.input[0]].name = n.output[0]
            continue
        keep.append(n)
    del proto.graph.node[:]
    proto.graph.node.extend(keep)


class _Exported:
    """The body graphs this process has exported, by the body's arrays (:func:`~segadeform.body.identity.body_sha256`),
    the skinning, the opset and the exporter's version: a graph depends on nothing else, and every package exported
    in one process for one body (an ensemble's members, a training run's checkpoints, the test suite's packages)
    carried the same two graphs, at 5-12 s each on two cores.  Holds at most ``size`` graphs (about 2 MB each for
    the shipped body); thread-safe."""

    def __init__(self, size: int = 4) -> None:
        self.size, self._graphs, self._lock = size, {}, threading.Lock()

    def get(self, key: tuple) -> tuple[bytes, dict] | None:
        with self._lock:
            hit = self._graphs.pop(key, None)
            if hit is not None:
                self._graphs[key] = hit  # most recently used last
            return hit

    def put(self, key: tuple, graph: bytes, ops: dict) -> None:
        with self._lock:
            self._graphs.pop(key, None)
            self._graphs[key] = (graph, dict(ops))
            while len(self._graphs) > self.size:
                self._graphs.pop(next(iter(self._graphs)))


_EXPORTED = _Exported()


def export_body_graphs(body, folder: str | os.PathLike, *, skinnings=contract.SKINNING) -> tuple[dict, dict]:
    """Write ``body_<skinning>.onnx`` for each skinning into ``folder`` (self-contained graphs: the package's
    packing shares their weights); returns ``(graphs, ops)``: the manifest entries (without hashes) and each
    graph's op counts, after the portability check.  A graph this process has exported already for the same body
    arrays, skinning and exporter is written again from memory (the same bytes), not exported again."""
    import onnx
    import torch

    from segadeform.body.identity import body_label

    from .portability import check_portability, replace_trig

    folder = Path(folder)
    graphs, ops = {}, {}
    label = body_label(body)
    for skin in skinnings:
        name = contract.body_name(skin)
        spec = contract.body_spec(
            n_vertices=body.n_vertices,
            n_faces=len(body.faces),
            n_betas=body.n_betas,
            n_joints=body.n_joints,
            skinning=skin,
            body=label,
        )
        path = folder / spec["file"]
        key = (label["sha256"], skin, contract.OPSET, torch.__version__)
        hit = _EXPORTED.get(key)
        if hit is not None:
            path.write_bytes(hit[0])
            ops[name] = dict(hit[1])
            graphs[name] = spec
            continue
        _export(body_module(body, skin), body_sample_inputs(body), spec, path)
        proto = onnx.load(str(path))
        replace_trig(proto)  # Rodrigues' sin and cos, float32-accurate on WebGPU too
        _constant_outputs(proto)
        onnx.save(proto, str(path))
        onnx.checker.check_model(proto)
        ops[name] = dict(sorted(check_portability(proto, name).items()))
        got = [i.name for i in proto.graph.input]
        if got != [i["name"] for i in spec["inputs"]]:
            raise RuntimeError(f"{name}: exported inputs {got} differ from the spec")
        graphs[name] = spec
        _EXPORTED.put(key, path.read_bytes(), ops[name])
    return graphs, ops


def add_body_to_package(package: str | os.PathLike, body, out: str | os.PathLike | None = None) -> dict:
    """Give model package ``package`` the body graphs of ``body`` (replacing any it has), written to ``out``
    (default: the package itself, replaced atomically); returns the new manifest.

    The package must be schema 3 (``segadeform repack`` brings older ones there); the body must have the
    model's skeleton.  Its graphs' weights join the package's ``weights.bin`` (when it has one)."""
    import onnx

    from ..io.hashing import file_sha256
    from .packing import finish_package, pack_graphs

    src = Path(package)
    dst = Path(out) if out is not None else src
    mpath = src / contract.MANIFEST_FILE
    if not mpath.is_file():
        raise InputError("not a model package (no manifest.json)", path=src, expected="a model package folder")
    m = contract.read_manifest_text(mpath.read_text(encoding="utf-8"), path=mpath)
    if m.get("upgraded_from"):
        raise InputError(
            "the package is an older schema: repack it first",
            path=src,
            expected=f"schema {contract.SCHEMA_VERSION} (segadeform repack PKG -o NEW)",
            got=f"schema {m['upgraded_from']}",
        )
    if list(body.joint_names) != list(m["joint_names"]):
        raise InputError(
            "the body's skeleton is not the model's",
            expected=", ".join(m["joint_names"][:4]) + ", ...",
            got=", ".join(list(body.joint_names)[:4]) + ", ...",
        )
    with atomic_directory(dst) as tmp:
        tmp = Path(tmp)
        graphs = {k: dict(g) for k, g in m["graphs"].items() if g["role"] != contract.ROLES[contract.BODY]}
        for g in graphs.values():  # self-contained copies, shared again below
            onnx.save(onnx.load(str(src / g["file"]), load_external_data=True), str(tmp / g["file"]))
        new, body_ops = export_body_graphs(body, tmp)
        graphs.update(new)
        weights = pack_graphs(tmp, [g["file"] for g in graphs.values()], shared="weights" in m)
        for g in graphs.values():
            g["sha256"] = file_sha256(tmp / g["file"])
        ops = {k: v for k, v in m.get("ops", {}).items() if k in graphs}
        ops.update(body_ops)
        out_m = {k: v for k, v in m.items() if k not in ("graphs", "ops", "weights")}
        out_m.update(graphs=graphs, ops=ops)
        if weights is not None:
            out_m["weights"] = weights
        finish_package(src, tmp, out_m, dst)
    return out_m
