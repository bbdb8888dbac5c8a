"""Model packages: ``manifest.json`` plus ONNX graphs, validated before any session runs.

The package format is :mod:`segadeform.contracts.model_package` (``docs/package.md``): the manifest is read and
checked through it (schema-1 manifests are upgraded on reading), and the deformer for a set of
effects is chosen by its rule."""

from __future__ import annotations

import dataclasses
import os
from pathlib import Path

import numpy as np

from segadeform.contracts import model_package as contract
from segadeform.contracts.model_package import PackageError
from segadeform.errors import InputError, file_error
from segadeform.io.hashing import file_sha256

__all__ = ["ModelPackage", "PackageError", "Familiarity", "SUPPORTED_SCHEMA", "SUPPORTED_OPSETS"]

SUPPORTED_SCHEMA = contract.READABLE_SCHEMAS
SUPPORTED_OPSETS = contract.SUPPORTED_OPSETS
_ORT_TYPES = {"tensor(float)": "float32", "tensor(int32)": "int32", "tensor(int64)": "int64", "tensor(bool)": "bool"}


@dataclasses.dataclass(frozen=True)
class Familiarity:
    """How close a garment is to the model's training garments (Eq. 19 between descriptors).

    ``outside`` when the nearest training garment is further than the package's threshold (the
    largest distance from a training garment to its nearest other one), or when no training garment
    has as many openings (boundary loops); accuracy there is unknown."""

    nearest: str
    distance: float
    threshold: float | None
    openings: int | None = None
    training_openings: tuple[int, ...] = ()

    @property
    def new_openings(self) -> bool:
        return (
            bool(self.training_openings) and self.openings is not None and self.openings not in self.training_openings
        )

    @property
    def outside(self) -> bool:
        return (self.threshold is not None and self.distance > self.threshold) or self.new_openings

    def __str__(self) -> str:
        thr = "no threshold" if self.threshold is None else f"threshold {self.threshold:.4g}"
        s = f"descriptor distance {self.distance:.4g} to the nearest training garment '{self.nearest}' ({thr})"
        if self.new_openings:
            s += f"; {self.openings} openings, training garments have {' or '.join(map(str, self.training_openings))}"
        return s


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
        mpath = self.path / contract.MANIFEST_FILE
        try:
            self.path.stat()
        except OSError as e:
            raise file_error(e, self.path, "model package", cls=PackageError) from None
        if not self.path.is_dir():
            raise PackageError("model package must be a folder", path=self.path)
        try:
            raw = mpath.read_bytes()
        except FileNotFoundError:  # the folder is there but is not a package
            run = next((n for n in ("model.pt", "last.pt") if (self.path / n).is_file()), None)
            if run is not None:  # a training run's folder (a user's trial: no hint what to do)
                raise PackageError(
                    "is a training run's folder, not a model package (it has no manifest.json)",
                    path=self.path,
                    expected=f"a package: `segadeform export {self.path / run} -o PACKAGE_DIR`, then --model it",
                ) from None
            raise PackageError("model package has no manifest.json", path=self.path) from None
        except OSError as e:
            raise file_error(e, mpath, "manifest", cls=PackageError) from None
        try:
            text = raw.decode("utf-8-sig")  # a byte-order mark (an editor's) is dropped
        except UnicodeDecodeError:
            raise PackageError("manifest is not UTF-8 text", path=mpath) from None
        m = contract.read_manifest_text(text, path=mpath)
        wfile = self.path / contract.WEIGHTS_FILE
        if "weights" not in m and wfile.is_file():  # the graphs read it: its hash must be checked too
            raise PackageError(
                "the package holds weights.bin but its manifest has no 'weights' entry, so the "
                "weights would be used unchecked",
                path=mpath,
                expected='"weights": {"file", "sha256", "bytes"} (segadeform repack writes it)',
                got="no weights entry",
            )
        files = [
            (f"graph '{name}'", f"graph '{name}' file", spec["file"], spec.get("sha256"))
            for name, spec in m["graphs"].items()
        ]
        if "weights" in m:
            files.append(("the weights file", "the weights file", m["weights"]["file"], m["weights"].get("sha256")))
        for what, what_file, name, sha in files:
            f = self.path / name
            if not f.is_file():
                raise PackageError(f"{what_file} is missing", path=f)
            if verify_hashes and sha:
                h = file_sha256(f)
                if h != sha:
                    raise PackageError(
                        f"{what} does not match its manifest hash",
                        path=f,
                        expected=sha[:16] + "...",
                        got=h[:16] + "...",
                    )
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
            raise InputError(
                "execution provider not available in this onnxruntime",
                expected=", ".join(available),
                got=", ".join(bad),
            )
        return providers

    # ---- graphs --------------------------------------------------------
    @property
    def default_deformer(self) -> str:
        """The deformer for the model's own effects (its skinning and blend shapes, with dynamics)."""
        return self.manifest["default_deformer"]

    def spec(self, name: str) -> dict:
        """The manifest entry of graph ``name`` (``"deformer"``: the :attr:`default_deformer`)."""
        graphs = self.manifest["graphs"]
        if name == contract.DEFORMER:
            name = self.default_deformer
        if name not in graphs:
            raise PackageError(f"package has no graph '{name}'", path=self.path, expected=", ".join(sorted(graphs)))
        return graphs[name]

    def familiarity(self, descriptor, openings: int | None = None) -> Familiarity | None:
        """Where a garment (descriptor ``(N*,)``, number of boundary loops) lies against the training
        garments the manifest lists (:data:`segadeform.contracts.model_package.TRAINING_GARMENTS`); None when the
        package lists none."""
        from segadeform.geometry.descriptor import dissimilarities

        t = self.manifest.get(contract.TRAINING_GARMENTS)
        if t is None:
            return None
        d = dissimilarities(descriptor, np.array([g["descriptor"] for g in t["garments"]], np.float64))
        i = int(np.argmin(d))
        known = tuple(sorted({g["openings"] for g in t["garments"] if "openings" in g}))
        return Familiarity(
            nearest=t["garments"][i]["name"],
            distance=float(d[i]),
            threshold=t["threshold"],
            openings=openings,
            training_openings=known,
        )

    def variant_for(self, effects) -> str:
        """The deformer graph for ``effects`` (skinning, wrinkles, dynamics), by the contract's rule
        (:func:`segadeform.contracts.model_package.select_deformer`: an exact match, or an error listing the graphs)."""
        return contract.select_deformer(self.manifest, effects, path=self.path)

    def session(self, name: str):
        """The onnxruntime session for graph ``name``, created (and checked against the manifest) on first use."""
        if name == contract.DEFORMER:
            name = self.default_deformer
        if name in self.created:
            return self.created[name]
        import onnxruntime as ort

        spec = self.spec(name)
        so = ort.SessionOptions()
        so.intra_op_num_threads = self.threads
        so.inter_op_num_threads = 1
        so.log_severity_level = 3
        # the encoder runs once per garment: onnxruntime's memory arena would keep its peak (about 300 MB at
        # 16k vertices) for the rest of the run, so it allocates without one.  The deformer and body graphs
        # keep the arena (without it the deformer graph measured about 2x slower at 4k vertices, issue #14)
        so.enable_cpu_mem_arena = spec["role"] != contract.ROLES[contract.ENCODER]
        if self.threads > 1:  # idle pool threads sleep instead of spinning: the run's other stages (posing,
            # the collision kernel's threads, writing) get the cores between deformer calls
            so.add_session_config_entry("session.intra_op.allow_spinning", "0")
        path = self.path / spec["file"]
        try:
            sess = ort.InferenceSession(str(path), so, providers=self.providers)
        except Exception as e:
            raise PackageError(
                f"onnxruntime cannot load graph '{name}' ({str(e).splitlines()[0][:200]})", path=path
            ) from None
        self._check_io(name, spec, sess, path)
        feedable = set(contract.FEEDS[spec["role"]])
        if spec["role"] == "deformer":
            feedable.add(contract.code_name(self.manifest))
        unknown = [i["name"] for i in spec["inputs"] if i["name"] not in feedable]
        if unknown:
            raise PackageError(
                f"graph '{name}' takes inputs this runtime cannot feed",
                path=path,
                expected=", ".join(sorted(feedable)),
                got=", ".join(unknown),
            )
        self.created[name] = sess
        return sess

    @staticmethod
    def _check_io(name, spec, sess, path) -> None:
        for kind, got, want in (
            ("inputs", sess.get_inputs(), spec["inputs"]),
            ("outputs", sess.get_outputs(), spec["outputs"]),
        ):
            gn = [g.name for g in got]
            wn = [w["name"] for w in want]
            if gn != wn:
                raise PackageError(
                    f"graph '{name}' {kind} disagree with the manifest",
                    path=path,
                    expected=", ".join(wn),
                    got=", ".join(gn),
                )
            for g, w in zip(got, want, strict=True):
                if len(g.shape) != len(w["shape"]) or _ORT_TYPES.get(g.type) != w["dtype"]:
                    raise PackageError(
                        f"graph '{name}' {kind[:-1]} '{g.name}' disagrees with the manifest",
                        path=path,
                        expected=f"{w['dtype']} {w['shape']}",
                        got=f"{g.type} {g.shape}",
                    )
                for gd, wd in zip(g.shape, w["shape"], strict=True):
                    if isinstance(wd, int) and isinstance(gd, int) and gd != wd:
                        raise PackageError(
                            f"graph '{name}' {kind[:-1]} '{g.name}' has a different size",
                            path=path,
                            expected=w["shape"],
                            got=g.shape,
                        )

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
            if (
                a.dtype != want_dt
            ):  # each input in its manifest's dtype: schema 3 int32 / float32, schema 2 int64 / bool
                if np.issubdtype(want_dt, np.integer) and not np.issubdtype(a.dtype, np.integer):
                    raise InputError(f"input '{w['name']}' has the wrong dtype", expected=w["dtype"], got=a.dtype)
                if (
                    np.issubdtype(want_dt, np.integer)
                    and a.size
                    and (a.min() < np.iinfo(want_dt).min or a.max() > np.iinfo(want_dt).max)
                ):
                    raise InputError(
                        f"input '{w['name']}' does not fit {w['dtype']}",
                        expected=w["dtype"],
                        got=f"values {a.min()}..{a.max()}",
                    )
                if want_dt == np.bool_ and a.dtype.kind not in "biuf":
                    raise InputError(f"input '{w['name']}' has the wrong dtype", expected=w["dtype"], got=a.dtype)
                a = a != 0 if want_dt == np.bool_ else a.astype(want_dt)
            if a.ndim != len(w["shape"]) or any(
                isinstance(d, int) and d != s for d, s in zip(w["shape"], a.shape, strict=True)
            ):
                raise InputError(f"input '{w['name']}' has the wrong shape", expected=w["shape"], got=a.shape)
            if a.dtype.kind == "f" and not np.isfinite(a).all():
                raise InputError(f"input '{w['name']}' contains NaN or inf")
            checked[w["name"]] = np.ascontiguousarray(a)
        return sess.run(None, checked)
