"""Export a SEGANet to a model package directory (see ``export/__init__.py``)."""

from __future__ import annotations

import json
import os
import warnings
from pathlib import Path

import numpy as np

from segadeform import UNITS, UP_AXIS, __version__
from segadeform.body.skeleton import SMPL_JOINT_NAMES, SMPL_PARENTS
from segadeform.contracts import model_package as contract
from segadeform.contracts.model_package import OPSET, graph_specs
from segadeform.errors import InputError
from segadeform.io.atomic import atomic_directory

from ..io.hashing import file_sha256
from .packing import pack_graphs
from .portability import check_portability, replace_trig

__all__ = ["MANIFEST_SCHEMA_VERSION", "OPSET", "graph_specs", "deformer_variants", "export_package", "sample_inputs"]

#: the manifest layout written (``segadeform.contracts.model_package`` holds the contract: I/O, names, manifest keys)
MANIFEST_SCHEMA_VERSION = contract.SCHEMA_VERSION


_NP = {"float32": np.float32, "int32": np.int32, "int64": np.int64, "bool": np.bool_}


def sample_inputs(cfg, graph: str, *, n: int, k: int, b: int, seed: int = 0) -> dict[str, np.ndarray]:
    """Random, valid inputs for ``graph`` with N = n, K = k, B = b (a symmetric ring-like graph)."""
    rng = np.random.default_rng(seed)
    role = contract.ENCODER if graph == contract.ENCODER else contract.DEFORMER  # a deformer graph's name or its role
    gspec = graph_specs(cfg)[role]
    dims = {"N": n, "K": k, "B": b}
    out = {}
    nbr = (np.arange(n)[:, None] + np.arange(1, k + 1)[None, :] * (1 - 2 * (np.arange(k) % 2))[None, :]) % n
    mask = rng.random((n, k)) > 0.15
    mask[:, 0] = True
    for inp in gspec["inputs"]:
        shape = [dims[d] if isinstance(d, str) else d for d in inp["shape"]]
        if inp["name"] == "nbr":
            out["nbr"] = nbr.astype(_NP[inp["dtype"]])
        elif inp["name"] == "mask":
            out["mask"] = mask.astype(_NP[inp["dtype"]])
        elif inp["name"] == "window":
            out["window"] = (0.4 * rng.standard_normal(shape)).astype(np.float32)
        elif inp["name"] == "joints":
            out["joints"] = (
                (np.random.default_rng(1).normal(size=(cfg.n_joints, 3)) * 0.3)[None].repeat(b, 0).astype(np.float32)
            )
        elif inp["name"] == "log_wbody":  # sparse body weights: a few joints per vertex, as on a real body
            w = rng.dirichlet(np.full(cfg.n_joints, 0.3), size=n)
            w[w < 0.05] = 0.0
            w /= w.sum(axis=1, keepdims=True)
            out["log_wbody"] = np.log(w + 1e-5).astype(np.float32)
        else:
            out[inp["name"]] = rng.standard_normal(shape).astype(_NP[inp["dtype"]])
    return out


def _wrappers(model):
    """The graphs' modules.  ``nbr`` arrives as int32 (Gather takes int32 indices as they are) and ``mask`` as
    float32 1/0 (the attention multiplies by it as a float anyway): schema 3's inputs, with no Cast added."""
    import torch

    class Encoder(torch.nn.Module):
        def __init__(self, net):
            super().__init__()
            self.net = net

        def forward(self, features, nbr, mask, descriptor):
            return self.net.garment_encoder(features, nbr, mask, descriptor)

    class Deformer(torch.nn.Module):
        def __init__(self, net):
            super().__init__()
            self.net = net

        def forward(self, g, window, betas, rest, nbr, mask, joints, trans):
            return self.net.deformer(g, window, betas, rest, nbr, mask, joints, trans)

    class ResidualDeformer(torch.nn.Module):
        def __init__(self, net):
            super().__init__()
            self.net = net

        def forward(self, g, window, betas, rest, nbr, mask, joints, trans, log_wbody):
            return self.net.deformer(g, window, betas, rest, nbr, mask, joints, trans, log_wbody)

    dec = ResidualDeformer(model) if getattr(model, "residual", False) else Deformer(model)
    return {"garment_encoder": Encoder(model), "deformer": dec}


def _export_one(module, spec, inputs, path: Path, *, dynamo: bool) -> None:
    import torch

    args = tuple(torch.as_tensor(inputs[i["name"]]) for i in spec["inputs"])
    in_names = [i["name"] for i in spec["inputs"]]
    out_names = [o["name"] for o in spec["outputs"]]
    import logging

    onnx_log = logging.getLogger("torch.onnx")
    level = onnx_log.level
    onnx_log.setLevel(logging.ERROR)  # torch logs one line per missing torchvision op
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        try:
            _run_export(module, args, spec, in_names, out_names, path, dynamo)
        finally:
            onnx_log.setLevel(level)


def _run_export(module, args, spec, in_names, out_names, path, dynamo) -> None:
    import torch

    if dynamo:
        from torch.export import Dim

        dims = {"B": Dim("B", min=1, max=1 << 20), "N": Dim("N", min=3, max=1 << 24), "K": Dim("K", min=1, max=256)}
        dyn = {
            i["name"]: {ax: dims[d] for ax, d in enumerate(i["shape"]) if isinstance(d, str)} for i in spec["inputs"]
        }
        prog = torch.onnx.export(
            module,
            args,
            dynamo=True,
            opset_version=OPSET,
            dynamic_shapes=dyn,
            input_names=in_names,
            output_names=out_names,
            verbose=False,
        )
        prog.save(str(path), external_data=False)
    else:
        dyn = {
            x["name"]: {ax: d for ax, d in enumerate(x["shape"]) if isinstance(d, str)}
            for x in spec["inputs"] + spec["outputs"]
        }
        torch.onnx.export(
            module,
            args,
            str(path),
            dynamo=False,
            opset_version=OPSET,
            input_names=in_names,
            output_names=out_names,
            dynamic_axes=dyn,
        )


def deformer_variants(cfg) -> dict:
    """The per-effect deformer graphs: skinning x wrinkles (blend-shape decoder) x dynamics (window).

    ``dynamics=False`` sees only the current pose (window 1); ``wrinkles=False`` drops the decoder
    (B = 0).  Names and files follow :func:`segadeform.contracts.model_package.deformer_name`; ``default`` marks
    the one matching ``cfg`` (exported from the model itself).  ``config`` is the network each variant
    is exported from; ``spec`` its manifest entry (without the hash).
    """
    out = {}
    dflt = contract.default_effects(cfg)
    for eff in contract.effect_sets(cfg):
        name = contract.deformer_name(eff)
        vcfg = cfg.replace(
            skinning=eff["skinning"], use_blend_shapes=eff["wrinkles"], window=cfg.window if eff["dynamics"] else 1
        )
        vspec = contract.deformer_spec(cfg, eff)
        out[name] = {"config": vcfg, "file": vspec["file"], "effects": eff, "default": eff == dflt, "spec": vspec}
    return out


def _variant_model(net, vcfg):
    """A network for ``vcfg`` carrying ``net``'s (frozen) weights; the dropped parts are left out."""
    from segadeform.model.ensemble import build_model

    v = build_model(vcfg).eval()
    missing, unexpected = v.load_state_dict(net.state_dict(), strict=False)
    if missing:
        raise RuntimeError(f"variant is missing weights: {missing[:5]}")
    for m in v.modules():
        if hasattr(m, "frozen"):
            m.frozen = True  # the weights are already scaled
    return v


def _load_body(body):
    """``body`` for :func:`export_package`: ``"default"`` (the shipped body), a path, a BodyModel, or None."""
    if body is None:
        return None
    from segadeform.body import BodyModel, default_body_path, load_body

    if isinstance(body, BodyModel):
        return body
    return load_body(default_body_path() if isinstance(body, str) and body == "default" else body)


def body_parity(body, path, skinning: str, sizes=(1, 4)) -> dict:
    """Worst abs/rel error of body graph ``path`` against :meth:`BodyModel.forward` (float64) on random inputs."""
    import onnxruntime as ort

    from .body import body_sample_inputs
    from .verify import compare

    sess = ort.InferenceSession(str(path), providers=["CPUExecutionProvider"])
    worst = {"vertices": [0.0, 0.0], "joints": [0.0, 0.0], "rest_joints": [0.0, 0.0]}
    for b in sizes:
        x = body_sample_inputs(body, b=b, seed=b)
        got = dict(zip(("vertices", "joints", "rest_joints", "faces"), sess.run(None, x), strict=False))
        ref = body.forward(
            x["poses"].reshape(b, -1).astype(np.float64),
            x["betas"].astype(np.float64),
            x["trans"].astype(np.float64),
            skinning=skinning,
        )
        for k, r in (
            ("vertices", ref.vertices),
            ("joints", ref.joints),
            ("rest_joints", body.rest_joints(x["betas"].astype(np.float64))[0]),
        ):
            a, rel = compare(r, got[k])
            worst[k] = [max(worst[k][0], a), max(worst[k][1], rel)]
        if not np.array_equal(got["faces"], body.faces):
            raise RuntimeError(f"{path}: the body graph's faces are not the body's")
    return {k: {"max_abs": v[0], "max_rel": v[1]} for k, v in worst.items()}


def export_package(
    model,
    out_dir: str | os.PathLike,
    *,
    dynamo: bool = True,
    check: bool = True,
    variants: bool = True,
    extra_manifest: dict | None = None,
    shared_weights: bool = True,
    body="default",
    progress=None,
) -> dict:
    """Export ``model`` (a SEGANet) to ``out_dir``; returns the manifest (and parity figures when ``check``).

    Writes the garment encoder and one deformer per effect combination (only the model's own with
    ``variants=False``), named and described by :mod:`segadeform.contracts.model_package`, and the body graphs
    ``body_lbs`` and ``body_dqs`` of ``body`` (``"default"``: the shipped body; a body file or
    :class:`~segadeform.body.BodyModel`; None: no body graphs; :mod:`.body`), then packs them
    (:func:`~segadeform.export.packing.pack_graphs`: debug info stripped; with ``shared_weights`` one
    ``weights.bin`` holds the weights every graph shares).  The parity check runs on the packed files.

    The model is copied and frozen (tau scalings folded into constants).
    Sample sizes are >= 2 and distinct (N = 37, K = 7, B = 3): the dynamo
    exporter freezes size-1 axes without warning.  Every graph passes
    :func:`check_portability`; the package appears atomically.  ``progress``: called with a line of text as each
    graph is exported and checked (an export of eight deformers takes minutes on two cores, silent before: an ML
    user's trial).
    """
    import copy

    import onnx
    import torch

    from .verify import parity

    if model.cfg.rest_drape:
        raise InputError(
            "the model package format has no garment drape yet: a model trained with rest_drape does not export",
            expected="ModelConfig.rest_drape = 0",
            got=model.cfg.rest_drape,
        )
    if model.cfg.history:
        raise InputError(
            "the model package format has no motion-history graph yet: a model trained with a history does not export",
            expected="ModelConfig.history = 0",
            got=model.cfg.history,
        )
    net = copy.deepcopy(model).eval().float().freeze()
    cfg = net.cfg
    body_model = _load_body(body)
    wrappers = _wrappers(net)
    todo = {contract.ENCODER: (wrappers[contract.ENCODER], graph_specs(cfg)[contract.ENCODER], cfg, True)}
    for vname, var in deformer_variants(cfg).items():
        if var["default"]:
            todo[vname] = (wrappers[contract.DEFORMER], var["spec"], cfg, True)
        elif variants:
            todo[vname] = (
                _wrappers(_variant_model(net, var["config"]))[contract.DEFORMER],
                var["spec"],
                var["config"],
                False,
            )
    default = contract.deformer_name(contract.default_effects(cfg))
    graphs, ops, report = {}, {}, {}
    with atomic_directory(out_dir) as tmp:
        for k, (name, (module, gspec, gcfg, _)) in enumerate(todo.items(), 1):
            if progress is not None:
                progress(f"exporting {name} ({k} of {len(todo)})")
            path = tmp / gspec["file"]
            _export_one(module, gspec, sample_inputs(gcfg, name, n=37, k=7, b=3), path, dynamo=dynamo)
            proto = onnx.load(str(path))
            if replace_trig(proto):  # WebGPU's sin/cos are not float32-accurate (portability.replace_trig)
                onnx.save(proto, str(path))
            onnx.checker.check_model(proto)
            ops[name] = dict(sorted(check_portability(proto, name).items()))
            got_in = [i.name for i in proto.graph.input]
            want_in = [i["name"] for i in gspec["inputs"]]
            if got_in != want_in:
                raise RuntimeError(f"{name}: exported inputs {got_in} differ from the spec {want_in}")
            graphs[name] = dict(gspec)
        if body_model is not None:
            from .body import export_body_graphs

            if list(body_model.joint_names) != list(SMPL_JOINT_NAMES):
                raise RuntimeError("the body's skeleton is not the model's (SMPL's 24 joints)")
            if progress is not None:
                progress("exporting the body graphs")
            body_graphs, body_ops = export_body_graphs(body_model, tmp)
            graphs.update(body_graphs)
            ops.update(body_ops)
        weights = pack_graphs(tmp, [g["file"] for g in graphs.values()], shared=shared_weights)
        for name, g in graphs.items():
            g["sha256"] = file_sha256(tmp / g["file"])
            if check and progress is not None:
                progress(f"checking {name} against torch")
            if check and g["role"] == contract.ROLES[contract.BODY]:
                report[name] = body_parity(body_model, tmp / g["file"], g["skinning"])
            elif check:
                module, gspec, gcfg, full = todo[name]
                sizes = {} if full else {"sizes": ((37, 7, 2),)}
                report[name] = parity(module, tmp / g["file"], gspec, gcfg, graph=name, **sizes)
        manifest = contract.make_manifest(
            config=json.loads(cfg.to_json()),
            graphs=graphs,
            default_deformer=default,
            producer=f"segadeform {__version__}",
            joint_names=SMPL_JOINT_NAMES,
            parents=SMPL_PARENTS,
            units=UNITS,
            up_axis=UP_AXIS,
            ops=ops,
            weights=weights,
            torch=torch.__version__,
            exporter="dynamo" if dynamo else "legacy",
            **(extra_manifest or {}),
        )
        contract.validate_manifest(manifest, path=tmp / contract.MANIFEST_FILE)
        (tmp / contract.MANIFEST_FILE).write_text(json.dumps(manifest, indent=2, sort_keys=True) + "\n")
    if check:
        manifest = dict(manifest, parity=report)
    return manifest
