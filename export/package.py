"""Export a SEGANet to a model package directory (see ``export/__init__.py``)."""

from __future__ import annotations

import hashlib
import json
import os
import warnings
from pathlib import Path

import numpy as np

from segadeform import UNITS, UP_AXIS, __version__
from segadeform.body.skeleton import SMPL_JOINT_NAMES, SMPL_PARENTS
from segadeform.io.atomic import atomic_directory

from .portability import check_portability

__all__ = ["MANIFEST_SCHEMA_VERSION", "OPSET", "graph_specs", "export_package", "sample_inputs"]

MANIFEST_SCHEMA_VERSION = 1
OPSET = 18


def graph_specs(cfg) -> dict:
    """Input/output names, dtypes and symbolic shapes of both graphs for ``cfg``."""
    s, f, t = cfg.n_joints, cfg.f_enc, cfg.window
    return {
        "garment_encoder": {
            "file": "garment_encoder.onnx",
            "inputs": [
                {"name": "features", "dtype": "float32", "shape": ["B", "N", cfg.feat_dim]},
                {"name": "nbr", "dtype": "int64", "shape": ["N", "K"]},
                {"name": "mask", "dtype": "bool", "shape": ["N", "K"]},
                {"name": "descriptor", "dtype": "float32", "shape": ["B", cfg.n_star]},
                {"name": "betas", "dtype": "float32", "shape": ["B", cfg.n_betas]},
            ],
            "outputs": [{"name": "P", "dtype": "float32", "shape": ["B", "N", s, f]}],
        },
        "deformer": {
            "file": "deformer.onnx",
            "inputs": [
                {"name": "P", "dtype": "float32", "shape": ["N", s, f]},
                {"name": "window", "dtype": "float32", "shape": ["B", t, 3 * s]},
                {"name": "betas", "dtype": "float32", "shape": ["B", cfg.n_betas]},
                {"name": "rest", "dtype": "float32", "shape": ["N", 3]},
                {"name": "nbr", "dtype": "int64", "shape": ["N", "K"]},
                {"name": "mask", "dtype": "bool", "shape": ["N", "K"]},
                {"name": "joints", "dtype": "float32", "shape": ["B", s, 3]},
                {"name": "trans", "dtype": "float32", "shape": ["B", 3]},
            ] + ([{"name": "log_wbody", "dtype": "float32", "shape": ["N", s]}]
                 if getattr(cfg, "weights", "free") == "residual" else []),
            "outputs": [
                {"name": "vertices", "dtype": "float32", "shape": ["B", "N", 3]},
                {"name": "weights", "dtype": "float32", "shape": ["B", "N", s]},
                {"name": "blend_shapes", "dtype": "float32", "shape": ["B", "N", 3]},
            ],
        },
    }


_NP = {"float32": np.float32, "int64": np.int64, "bool": np.bool_}


def sample_inputs(cfg, graph: str, *, n: int, k: int, b: int, seed: int = 0) -> dict[str, np.ndarray]:
    """Random, valid inputs for ``graph`` with N = n, K = k, B = b (a symmetric ring-like graph)."""
    rng = np.random.default_rng(seed)
    spec = graph_specs(cfg)[graph]
    dims = {"N": n, "K": k, "B": b}
    out = {}
    nbr = (np.arange(n)[:, None] + np.arange(1, k + 1)[None, :] * (1 - 2 * (np.arange(k) % 2))[None, :]) % n
    mask = rng.random((n, k)) > 0.15
    mask[:, 0] = True
    for inp in spec["inputs"]:
        shape = [dims[d] if isinstance(d, str) else d for d in inp["shape"]]
        if inp["name"] == "nbr":
            out["nbr"] = nbr.astype(np.int64)
        elif inp["name"] == "mask":
            out["mask"] = mask
        elif inp["name"] == "window":
            out["window"] = (0.4 * rng.standard_normal(shape)).astype(np.float32)
        elif inp["name"] == "joints":
            out["joints"] = (np.random.default_rng(1).normal(size=(cfg.n_joints, 3)) * 0.3)[None].repeat(b, 0).astype(np.float32)
        elif inp["name"] == "log_wbody":  # sparse body weights: a few joints per vertex, as on a real body
            w = rng.dirichlet(np.full(cfg.n_joints, 0.3), size=n)
            w[w < 0.05] = 0.0
            w /= w.sum(axis=1, keepdims=True)
            out["log_wbody"] = np.log(w + 1e-5).astype(np.float32)
        else:
            out[inp["name"]] = rng.standard_normal(shape).astype(_NP[inp["dtype"]])
    return out


def _wrappers(model):
    import torch

    class Encoder(torch.nn.Module):
        def __init__(self, net):
            super().__init__()
            self.net = net

        def forward(self, features, nbr, mask, descriptor, betas):
            return self.net.garment_encoder(features, nbr, mask, descriptor, betas)

    class Deformer(torch.nn.Module):
        def __init__(self, net):
            super().__init__()
            self.net = net

        def forward(self, P, window, betas, rest, nbr, mask, joints, trans):
            return self.net.deformer(P, window, betas, rest, nbr, mask, joints, trans)

    class ResidualDeformer(torch.nn.Module):
        def __init__(self, net):
            super().__init__()
            self.net = net

        def forward(self, P, window, betas, rest, nbr, mask, joints, trans, log_wbody):
            return self.net.deformer(P, window, betas, rest, nbr, mask, joints, trans, log_wbody)

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

        dims = {"B": Dim("B", min=1, max=1 << 20), "N": Dim("N", min=3, max=1 << 24),
                "K": Dim("K", min=1, max=256)}
        dyn = {i["name"]: {ax: dims[d] for ax, d in enumerate(i["shape"]) if isinstance(d, str)}
               for i in spec["inputs"]}
        prog = torch.onnx.export(module, args, dynamo=True, opset_version=OPSET, dynamic_shapes=dyn,
                                 input_names=in_names, output_names=out_names, verbose=False)
        prog.save(str(path), external_data=False)
    else:
        dyn = {x["name"]: {ax: d for ax, d in enumerate(x["shape"]) if isinstance(d, str)}
               for x in spec["inputs"] + spec["outputs"]}
        torch.onnx.export(module, args, str(path), dynamo=False, opset_version=OPSET, input_names=in_names,
                          output_names=out_names, dynamic_axes=dyn)


def deformer_variants(cfg) -> dict:
    """The per-effect deformer graphs: skinning x wrinkles (blend-shape decoder) x dynamics (window).

    ``dynamics=False`` sees only the current pose (window 1); ``wrinkles=False``
    drops the decoder (B = 0).  The variant matching ``cfg`` is ``deformer.onnx``.
    """
    out = {}
    for skin in ("lbs", "dqs"):
        for wrinkles in (True, False):
            if wrinkles and not cfg.use_blend_shapes:
                continue
            for dynamics in (True, False):
                name = f"deformer_{skin}" + ("" if wrinkles else "_nowrinkles") + ("" if dynamics else "_static")
                vcfg = cfg.replace(skinning=skin, use_blend_shapes=wrinkles, window=cfg.window if dynamics else 1)
                default = skin == cfg.skinning and wrinkles == cfg.use_blend_shapes and dynamics
                out[name] = {"config": vcfg, "file": "deformer.onnx" if default else f"{name}.onnx",
                             "effects": {"skinning": skin, "wrinkles": wrinkles, "dynamics": dynamics},
                             "default": default}
    return out


def _variant_model(net, vcfg):
    """A network for ``vcfg`` carrying ``net``'s (frozen) weights; the dropped parts are left out."""
    from segadeform.model import SEGANet

    v = SEGANet(vcfg).eval()
    missing, unexpected = v.load_state_dict(net.state_dict(), strict=False)
    if missing:
        raise RuntimeError(f"variant is missing weights: {missing[:5]}")
    for m in v.modules():
        if hasattr(m, "frozen"):
            m.frozen = True  # the weights are already scaled
    return v


def _sha256(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


def export_package(model, out_dir: str | os.PathLike, *, dynamo: bool = True, check: bool = True,
                   variants: bool = True, extra_manifest: dict | None = None) -> dict:
    """Export ``model`` (a SEGANet) to ``out_dir``; returns the manifest (and parity figures when ``check``).

    The model is copied and frozen (tau scalings folded into constants).
    Sample sizes are >= 2 and distinct (N = 37, K = 7, B = 3): the dynamo
    exporter freezes size-1 axes without warning.  Every graph passes
    :func:`check_portability`; the package appears atomically.
    """
    import copy

    import onnx
    import torch

    from .verify import parity

    net = copy.deepcopy(model).eval().float().freeze()
    cfg = net.cfg
    specs = graph_specs(cfg)
    wrappers = _wrappers(net)
    manifest = {
        "schema_version": MANIFEST_SCHEMA_VERSION, "format": "segadeform-model-package", "opset": OPSET,
        "producer": f"segadeform {__version__}", "torch": torch.__version__, "exporter": "dynamo" if dynamo else "legacy",
        "config": json.loads(cfg.to_json()), "joint_names": list(SMPL_JOINT_NAMES),
        "parents": [int(p) for p in SMPL_PARENTS], "units": UNITS, "up_axis": UP_AXIS,
        "graphs": {}, "ops": {},
    }
    if extra_manifest:
        manifest.update(extra_manifest)
    report = {}
    with atomic_directory(out_dir) as tmp:
        for name, spec in specs.items():
            inputs = sample_inputs(cfg, name, n=37, k=7, b=3)
            path = tmp / spec["file"]
            _export_one(wrappers[name], spec, inputs, path, dynamo=dynamo)
            proto = onnx.load(str(path))
            onnx.checker.check_model(proto)
            counts = check_portability(proto, name)
            got_in = [i.name for i in proto.graph.input]
            want_in = [i["name"] for i in spec["inputs"]]
            if got_in != want_in:
                raise RuntimeError(f"{name}: exported inputs {got_in} differ from the spec {want_in}")
            manifest["graphs"][name] = dict(spec, sha256=_sha256(path))
            manifest["ops"][name] = dict(sorted(counts.items()))
            if check:
                report[name] = parity(wrappers[name], path, spec, cfg)
        manifest["variants"] = {}
        if variants:
            for vname, var in deformer_variants(cfg).items():
                vspec = dict(graph_specs(var["config"])["deformer"], file=var["file"])
                if not var["default"]:
                    vnet = _variant_model(net, var["config"])
                    vmod = _wrappers(vnet)["deformer"]
                    path = tmp / var["file"]
                    _export_one(vmod, vspec, sample_inputs(var["config"], "deformer", n=37, k=7, b=3), path,
                                dynamo=dynamo)
                    counts = check_portability(onnx.load(str(path)), vname)
                    manifest["ops"][vname] = dict(sorted(counts.items()))
                    if check:
                        report[vname] = parity(vmod, path, vspec, var["config"], sizes=((37, 7, 2),), graph="deformer")
                manifest["variants"][vname] = dict(vspec, effects=var["effects"], window=var["config"].window,
                                                   sha256=_sha256(tmp / var["file"]))
        (tmp / "manifest.json").write_text(json.dumps(manifest, indent=2, sort_keys=True) + "\n")
    if check:
        manifest = dict(manifest, parity=report)
    return manifest
