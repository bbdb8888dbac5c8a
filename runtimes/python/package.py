"""Model packages: ``manifest.json`` plus ONNX graphs, validated before any session runs."""

from __future__ import annotations

import hashlib
import json
import os
from pathlib import Path

import numpy as np

from segadeform.errors import FileFormatError, InputError

__all__ = ["ModelPackage", "PackageError", "SUPPORTED_SCHEMA", "SUPPORTED_OPSETS"]

SUPPORTED_SCHEMA = (1,)
SUPPORTED_OPSETS = range(17, 22)
_ORT_TYPES = {"tensor(float)": "float32", "tensor(int64)": "int64", "tensor(bool)": "bool"}


class PackageError(FileFormatError):
    """A model package is malformed or its manifest and ONNX files disagree."""


class ModelPackage:
    """A loaded (not yet run) model package.

    Sessions are created lazily by :meth:`session` and recorded in
    :attr:`created`, so a stage a scene does not need never gets one.

    Args:
        path: the package directory.
        threads: intra-op threads per session (1 is often fastest on small CPUs).
        providers: execution providers, e.g. ``["CUDAExecutionProvider", "CPUExecutionProvider"]``;
            ``None`` means CPU; ``"auto"`` means CUDA when onnxruntime offers it.
        verify_hashes: check each graph file's SHA-256 against the manifest.
    """

    def __init__(self, path: str | os.PathLike, *, threads: int = 1, providers=None, verify_hashes: bool = True):
        self.path = Path(path)
        self.threads = int(threads)
        if self.threads < 1:
            raise InputError("threads must be at least 1", got=threads)
        self.manifest = self._read_manifest(verify_hashes)
        self.config = self.manifest["config"]
        self.providers = self._providers(providers)
        self.created: dict[str, object] = {}

    # ---- manifest -----------------------------------------------------
    def _read_manifest(self, verify_hashes: bool) -> dict:
        mpath = self.path / "manifest.json"
        if not self.path.is_dir():
            raise PackageError("model package must be a folder", path=self.path)
        try:
            m = json.loads(mpath.read_text(encoding="utf-8"))
        except FileNotFoundError:
            raise PackageError("model package has no manifest.json", path=self.path) from None
        except (OSError, UnicodeDecodeError, json.JSONDecodeError) as e:
            raise PackageError(f"manifest is not valid JSON ({e})", path=mpath) from None
        if not isinstance(m, dict):
            raise PackageError("manifest must be a JSON object", path=mpath)
        for key in ("schema_version", "opset", "config", "graphs", "joint_names"):
            if key not in m:
                raise PackageError(f"manifest has no '{key}'", path=mpath)
        if m["schema_version"] not in SUPPORTED_SCHEMA:
            raise PackageError("unsupported manifest schema version", path=mpath,
                               expected=" or ".join(map(str, SUPPORTED_SCHEMA)), got=m["schema_version"])
        if m["opset"] not in SUPPORTED_OPSETS:
            raise PackageError("unsupported ONNX opset", path=mpath,
                               expected=f"{SUPPORTED_OPSETS.start}..{SUPPORTED_OPSETS.stop - 1}", got=m["opset"])
        if "garment_encoder" not in m["graphs"] or "deformer" not in m["graphs"]:
            raise PackageError("manifest must describe 'garment_encoder' and 'deformer'", path=mpath,
                               got=", ".join(m["graphs"]))
        if len(m["joint_names"]) != m["config"].get("n_joints"):
            raise PackageError("manifest joint_names do not match config.n_joints", path=mpath,
                               expected=m["config"].get("n_joints"), got=len(m["joint_names"]))
        specs = dict(m["graphs"], **m.get("variants", {}))
        for name, spec in specs.items():
            f = self.path / spec.get("file", "")
            if not spec.get("file") or not f.is_file():
                raise PackageError(f"graph '{name}' file is missing", path=f)
            if verify_hashes and "sha256" in spec:
                h = hashlib.sha256(f.read_bytes()).hexdigest()
                if h != spec["sha256"]:
                    raise PackageError(f"graph '{name}' does not match its manifest hash", path=f,
                                       expected=spec["sha256"][:16] + "...", got=h[:16] + "...")
        return m

    def _providers(self, providers):
        import onnxruntime as ort

        available = ort.get_available_providers()
        if providers is None:
            return ["CPUExecutionProvider"]
        if providers == "auto":
            return [p for p in ("CUDAExecutionProvider", "CPUExecutionProvider") if p in available]
        providers = list(providers)
        bad = [p for p in providers if p not in available]
        if bad:
            raise InputError("execution provider not available in this onnxruntime", expected=", ".join(available),
                             got=", ".join(bad))
        return providers

    # ---- graphs --------------------------------------------------------
    def spec(self, name: str) -> dict:
        specs = dict(self.manifest["graphs"], **self.manifest.get("variants", {}))
        if name not in specs:
            raise PackageError(f"package has no graph '{name}'", path=self.path, expected=", ".join(sorted(specs)))
        return specs[name]

    def variant_for(self, effects) -> str:
        """The deformer graph for ``effects`` (skinning, wrinkles, dynamics)."""
        want = {"skinning": effects.skinning, "wrinkles": effects.wrinkles, "dynamics": effects.dynamics}
        variants = self.manifest.get("variants", {})
        for name, v in variants.items():
            if v.get("effects") == want:
                return name
        cfg = self.config
        default = {"skinning": cfg["skinning"], "wrinkles": cfg["use_blend_shapes"], "dynamics": True}
        if default == want:
            return "deformer"
        have = [v.get("effects") for v in variants.values()] or [default]
        raise PackageError("package has no deformer for these effects", path=self.path, expected=str(have), got=str(want))

    def session(self, name: str):
        """The onnxruntime session for graph ``name``, created (and checked against the manifest) on first use."""
        if name in self.created:
            return self.created[name]
        import onnxruntime as ort

        spec = self.spec(name)
        so = ort.SessionOptions()
        so.intra_op_num_threads = self.threads
        so.inter_op_num_threads = 1
        so.log_severity_level = 3
        path = self.path / spec["file"]
        try:
            sess = ort.InferenceSession(str(path), so, providers=self.providers)
        except Exception as e:
            raise PackageError(f"onnxruntime cannot load graph '{name}' ({str(e).splitlines()[0][:200]})", path=path) from None
        self._check_io(name, spec, sess, path)
        self.created[name] = sess
        return sess

    @staticmethod
    def _check_io(name, spec, sess, path) -> None:
        for kind, got, want in (("inputs", sess.get_inputs(), spec["inputs"]), ("outputs", sess.get_outputs(), spec["outputs"])):
            gn = [g.name for g in got]
            wn = [w["name"] for w in want]
            if gn != wn:
                raise PackageError(f"graph '{name}' {kind} disagree with the manifest", path=path,
                                   expected=", ".join(wn), got=", ".join(gn))
            for g, w in zip(got, want):
                if len(g.shape) != len(w["shape"]) or _ORT_TYPES.get(g.type) != w["dtype"]:
                    raise PackageError(f"graph '{name}' {kind[:-1]} '{g.name}' disagrees with the manifest", path=path,
                                       expected=f"{w['dtype']} {w['shape']}", got=f"{g.type} {g.shape}")
                for gd, wd in zip(g.shape, w["shape"]):
                    if isinstance(wd, int) and isinstance(gd, int) and gd != wd:
                        raise PackageError(f"graph '{name}' {kind[:-1]} '{g.name}' has a different size", path=path,
                                           expected=w["shape"], got=g.shape)

    def run(self, name: str, feeds: dict[str, np.ndarray]) -> list[np.ndarray]:
        """Validate ``feeds`` against the manifest (names, dtypes, ranks, fixed sizes, finiteness), then run.

        The session is created first, so a manifest that disagrees with its ONNX file is reported as
        such (naming the file) rather than as a caller's missing input; nothing runs before the feeds
        pass."""
        sess = self.session(name)
        spec = self.spec(name)
        checked = {}
        for w in spec["inputs"]:
            if w["name"] not in feeds:
                raise InputError(f"missing input '{w['name']}' for graph '{name}'")
            a = np.asarray(feeds[w["name"]])
            want_dt = np.dtype(w["dtype"])
            if a.dtype != want_dt:
                if want_dt == np.bool_ or (np.issubdtype(want_dt, np.integer) and not np.issubdtype(a.dtype, np.integer)):
                    raise InputError(f"input '{w['name']}' has the wrong dtype", expected=w["dtype"], got=a.dtype)
                a = a.astype(want_dt)
            if a.ndim != len(w["shape"]) or any(isinstance(d, int) and d != s for d, s in zip(w["shape"], a.shape)):
                raise InputError(f"input '{w['name']}' has the wrong shape", expected=w["shape"], got=a.shape)
            if a.dtype.kind == "f" and not np.isfinite(a).all():
                raise InputError(f"input '{w['name']}' contains NaN or inf")
            checked[w["name"]] = np.ascontiguousarray(a)
        return sess.run(None, checked)
