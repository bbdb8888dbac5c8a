"""``segadeform eval``: the paper's metrics (§5) against the simulation, for the model and its baselines.

Metrics, averaged over every frame and vertex of the evaluated samples:

* ``vertex_cm``     mean vertex distance (cm)
* ``normal_deg``    mean angle between predicted and simulated vertex normals (degrees)
* ``edge_mm``       mean |edge length - simulated edge length| (mm)
* ``low_cm`` / ``mid_cm`` / ``high_cm``  the error field ``pred - sim`` split into the
  low / mid / high spectral bands of the rest garment (§5.2, Table 2;
  :class:`~segadeform.geometry.laplacian.SpectralBasis`), mean vertex norm of each (cm)
* ``penetration_pct``  vertices deeper than 2 mm inside the posed body (%)
* ``max_strain_pct``  the largest edge stretch, length / rest length - 1 against the garment's rest mesh, over
  every edge and frame (%; over samples, the largest), and ``p99_strain_pct`` its 99th percentile (averaged)
* ``jitter_mm``     mean |second difference of pred - second difference of sim| (mm/frame^2)
* ``ms_per_frame``  the model's own time per frame (garment precompute excluded), one thread

The metrics beside the time per frame show what accuracy costs: a package can be
evaluated with effects off (``FOLDER:-wrinkles``, ``FOLDER:-dynamics``, ``FOLDER:dqs``).

Models: a model package (ONNX, run by onnxruntime, torch-free), a checkpoint
(``.pt``, run by torch), or ``lbs`` -- the body's skinning weights transferred to the
garment from the nearest body point, no blend shapes (baseline (a)).
"""

from __future__ import annotations

import abc
import dataclasses
import json
import time
from pathlib import Path
from typing import Callable, Optional

import numpy as np

from ..body.collision import BodyCollider, BodyProxy
from ..body.model import BodyModel
from ..body.transfer import WEIGHT_PRIORS, garment_weights, skin_garment
from ..dataset.roots import as_roots
from ..dataset.store import Sample
from ..errors import InputError
from ..geometry.laplacian import SpectralBasis
from ..geometry.mesh_ops import unique_edges, vertex_normals
from ..io.atomic import atomic_path
from ..motion.motion import motion_windows

__all__ = ["METRICS", "evaluate", "write_report", "Predictor", "make_predictor", "reference", "sample_metrics",
           "push_out_frames", "push_out_names"]

METRICS = ("vertex_cm", "normal_deg", "edge_mm", "low_cm", "mid_cm", "high_cm", "penetration_pct", "jitter_mm",
           "max_strain_pct", "p99_strain_pct")
#: metrics aggregated over samples by their largest value, not their mean
PEAK_METRICS = ("max_strain_pct",)
PEN_DEPTH = 0.002


class Predictor(abc.ABC):
    """``predict(sample, body, asset) -> (T, N, 3)``; see :func:`make_predictor`."""

    name: str

    @abc.abstractmethod
    def predict(self, s: Sample, body: BodyModel, asset) -> np.ndarray:
        """Shapes: -> (T, N, 3) vertices for every frame of ``s``."""


class _LBS(Predictor):
    """LBS with the body's weights carried to the garment by ``prior`` (``lbs``: the closest body point,
    baseline (a); ``lbs-<prior>`` for every other prior of :data:`segadeform.body.transfer.WEIGHT_PRIORS`:
    ``lbs-inpaint``, ``lbs-idw``, ``lbs-gaussian``, ``lbs-smooth``: the non-learned priors)."""

    def __init__(self, prior: str = "nearest"):
        self.prior = prior

    def predict(self, s, body, asset):
        betas = s.betas if s.betas.size else None
        w = garment_weights(s.rest, s.faces, body, betas, self.prior)
        return skin_garment(s.rest, w, body, s.poses, betas, s.trans)


class _Package(Predictor):
    def __init__(self, path, effects: str = ""):
        from ..runtime import ModelPackage
        from ..runtime.deformer import Deformer
        from ..settings import Effects, parse_effects

        self.pkg = ModelPackage(path, threads=1)
        self.cfg = self.pkg.config
        eff = Effects(skinning=self.cfg.get("skinning", "lbs"), collisions=False)
        if effects:
            eff = parse_effects(effects, eff)
            if eff.collisions:
                raise InputError("evaluate collisions with --push-out, not as a package effect", got=effects)
            if eff.cloth:
                raise InputError("evaluate the cloth stage with --cloth, not as a package effect", got=effects)
        self.deformer = Deformer(self.pkg, eff)

    def predict(self, s, body, asset):
        betas = s.betas if s.betas.size else None
        joints = body.rest_joints(betas)[0]
        P = self.deformer.encode(asset, joints, s.betas)
        lw = self.deformer.body_log_weights(asset, body, s.betas) if self.deformer.needs_body_weights else None
        out = []
        for lo in range(0, len(s.poses), 16):
            hi = min(lo + 16, len(s.poses))
            win = motion_windows(s.poses, self.deformer.window, start=lo, stop=hi)
            out.append(self.deformer.deform(P, asset, win, joints, s.trans[lo:hi], s.betas, log_wbody=lw))
        return np.concatenate(out).astype(np.float64)


class _Checkpoint(Predictor):
    def __init__(self, path):
        from ..model.network import load_checkpoint

        self.model = load_checkpoint(path).eval()
        self.cfg = self.model.cfg

    def predict(self, s, body, asset):
        import torch

        c = self.cfg
        betas = s.betas if s.betas.size else None
        joints = body.rest_joints(betas)[0]
        b = np.zeros(c.n_betas, np.float32)
        b[: s.betas.size] = s.betas[: c.n_betas]
        t32 = lambda a: torch.as_tensor(np.asarray(a, np.float32))  # noqa: E731
        nbr, mask = torch.as_tensor(asset.nbr, dtype=torch.int64), torch.as_tensor(asset.mask, dtype=torch.bool)
        from ..geometry.features import vertex_features

        feats = vertex_features(asset.vertices, asset.faces, joints, normals=asset.normals.astype(np.float64))
        lw = None
        if self.model.residual:
            from ..body.transfer import garment_weights, residual_log_weights

            lw = t32(residual_log_weights(garment_weights(asset.vertices, asset.faces, body, betas,
                                                          self.cfg.weight_prior)))
        with torch.no_grad():
            g = self.model.garment_encoder(t32(feats)[None], nbr, mask, t32(asset.descriptor)[None])[0]
            win = motion_windows(s.poses, c.window)
            out = []
            for lo in range(0, len(s.poses), 16):
                hi = min(lo + 16, len(s.poses))
                n = hi - lo
                v, _, _ = self.model.deformer(g, t32(win[lo:hi]), t32(b)[None].expand(n, -1), t32(s.rest), nbr, mask,
                                              t32(joints)[None].expand(n, -1, -1), t32(s.trans[lo:hi]), lw)
                out.append(v.numpy())
        return np.concatenate(out).astype(np.float64)


def make_predictor(name: str, spec: str) -> Predictor:
    """``spec``: ``lbs`` (closest-point weights) or ``lbs-<prior>`` (a non-learned weight prior of
    :data:`~segadeform.body.transfer.WEIGHT_PRIORS`: ``lbs-inpaint``, ``lbs-idw`` ...), a model package
    folder (optionally ``FOLDER:EFFECTS`` with effects as for ``segadeform run --effects``, e.g.
    ``pkg:-wrinkles``), or a ``.pt`` checkpoint."""
    if spec == "lbs":
        p: Predictor = _LBS()
    elif spec.startswith("lbs-") and spec[4:] in WEIGHT_PRIORS and spec[4:] != "nearest":
        p = _LBS(spec[4:])
    elif Path(spec).is_dir():
        p = _Package(spec)
    elif ":" in spec and Path(spec.rsplit(":", 1)[0]).is_dir():
        folder, eff = spec.rsplit(":", 1)
        p = _Package(folder, eff)
    elif Path(spec).suffix == ".pt":
        p = _Checkpoint(spec)
    else:
        raise InputError("a model must be 'lbs', 'lbs-PRIOR' (" + ", ".join(f"lbs-{w}" for w in WEIGHT_PRIORS[1:])
                         + "), a model package folder or a .pt checkpoint", got=spec)
    p.name = name
    return p


def _normals(x, faces):
    return np.stack([vertex_normals(f, faces) for f in x])


@dataclasses.dataclass
class _Acc:
    sums: dict
    counts: dict

    @classmethod
    def new(cls):
        return cls({}, {})

    def add(self, key, value, n=1):
        if key in PEAK_METRICS:  # the largest, kept in sums with a count of 1
            self.sums[key] = max(self.sums.get(key, -np.inf), float(value))
            self.counts[key] = 1
            return
        self.sums[key] = self.sums.get(key, 0.0) + float(value) * n
        self.counts[key] = self.counts.get(key, 0) + n

    def mean(self, key):
        return self.sums[key] / max(self.counts[key], 1)


@dataclasses.dataclass
class Reference:
    """What every prediction of one sample is compared with, computed once per sample.

    Shapes: gt (T, N, 3); n_gt (T, N, 3) vertex normals; l_gt (T, E) edge lengths; acc_gt (T-2, N, 3)
    second differences; proxies: one posed-body proxy per frame (the penetration metric's reference
    query); posed (T, V, 3): the posed body (what the runtime's collider pushes out of)."""

    gt: np.ndarray
    faces: np.ndarray
    edges: np.ndarray
    basis: SpectralBasis
    n_gt: np.ndarray
    l_gt: np.ndarray
    acc_gt: np.ndarray
    proxies: list
    posed: Optional[np.ndarray] = None
    #: (E,) the edges' lengths on the garment's rest mesh (the strain metrics' reference)
    l_rest: Optional[np.ndarray] = None


def reference(s: Sample, body: BodyModel, basis: Optional[SpectralBasis] = None) -> Reference:
    """The simulated frames of sample ``s`` and what the metrics derive from them (``basis``: the rest
    garment's spectral basis, made here when not given)."""
    gt = s.frames.astype(np.float64)
    edges = unique_edges(s.faces, len(s.rest))
    basis = basis if basis is not None else SpectralBasis.from_mesh(s.rest, s.faces)
    posed = body.forward(s.poses, s.betas if s.betas.size else None, s.trans).vertices
    proxies, proxy = [], None
    for t in range(len(posed)):
        proxy = BodyProxy(posed[t], body.faces) if proxy is None else proxy.moved(posed[t])
        proxies.append(proxy)
    return Reference(gt=gt, faces=s.faces, edges=edges, basis=basis, n_gt=_normals(gt, s.faces),
                     l_gt=np.linalg.norm(gt[:, edges[:, 0]] - gt[:, edges[:, 1]], axis=2),
                     acc_gt=gt[2:] - 2 * gt[1:-1] + gt[:-2], proxies=proxies, posed=posed,
                     l_rest=np.linalg.norm(s.rest[edges[:, 0]] - s.rest[edges[:, 1]], axis=1))


def sample_metrics(x: np.ndarray, ref: Reference, frame_step: int = 1) -> dict:
    """The :data:`METRICS` of one prediction ``x`` (T, N, 3) against ``ref`` (bands and penetration on
    every ``frame_step``-th frame)."""
    gt, faces, edges = ref.gt, ref.faces, ref.edges
    d = np.linalg.norm(x - gt, axis=2)
    cosang = np.clip((_normals(x, faces) * ref.n_gt).sum(-1), -1, 1)
    l_x = np.linalg.norm(x[:, edges[:, 0]] - x[:, edges[:, 1]], axis=2)
    frames = range(0, len(gt), frame_step)
    bands = np.zeros(3)
    for t in frames:
        lo, mid, hi = ref.basis.split(x[t] - gt[t])
        bands += [np.linalg.norm(lo, axis=1).mean(), np.linalg.norm(mid, axis=1).mean(),
                  np.linalg.norm(hi, axis=1).mean()]
    bands /= len(frames)
    pen = np.mean([(ref.proxies[t].query(x[t]).signed_distance < -PEN_DEPTH).mean() for t in frames])
    jit = np.linalg.norm((x[2:] - 2 * x[1:-1] + x[:-2]) - ref.acc_gt, axis=2).mean() if len(gt) > 2 else 0.0
    # stretch (compression counts as 0): what a stretch limit bounds
    strain = (np.maximum(l_x / np.maximum(ref.l_rest, 1e-12) - 1, 0) if ref.l_rest is not None and len(edges)
              else np.zeros((1, 1)))
    return {"vertex_cm": 100 * d.mean(), "normal_deg": np.degrees(np.arccos(cosang)).mean(),
            "edge_mm": 1000 * np.abs(l_x - ref.l_gt).mean(), "low_cm": 100 * bands[0], "mid_cm": 100 * bands[1],
            "high_cm": 100 * bands[2], "penetration_pct": 100 * pen, "jitter_mm": 1000 * jit,
            "max_strain_pct": 100 * float(strain.max()), "p99_strain_pct": 100 * float(np.percentile(strain, 99))}


def push_out_frames(x: np.ndarray, ref: Reference, collider: BodyCollider, margin: float, *,
                    batch: int = 8) -> np.ndarray:
    """The runtime's collision stage on a prediction: ``collider`` (:class:`BodyCollider`, built once)
    pushes ``batch`` frames at a time out of the posed body, as ``segadeform run`` does.
    Shapes: x (T, N, 3) -> (T, N, 3)."""
    if ref.posed is None:
        raise InputError("this reference has no posed body", expected="reference(...) of this module")
    out = np.empty(x.shape, np.float64)
    for lo in range(0, len(x), batch):
        out[lo:lo + batch] = collider.push_out(x[lo:lo + batch], ref.posed[lo:lo + batch], margin)[0]
    return out


def push_out_names(margins) -> dict:
    """``{suffix: margin}`` for :func:`evaluate`'s ``push_out_margin``: one margin (a number) gives the
    suffix ``" + push-out"``, a sequence one ``" + push-out N mm"`` per margin."""
    if margins is None:
        return {}
    if np.ndim(margins) == 0:
        ms, one = [float(margins)], True
    else:
        ms, one = [float(m) for m in margins], False
    for m in ms:
        if not (np.isfinite(m) and 0 <= m < 1):
            raise InputError("a push-out margin must be in [0, 1) metres", got=m)
    return {" + push-out": ms[0]} if one else {f" + push-out {1e3 * m:g} mm": m for m in ms}


def cloth_frames(x: np.ndarray, s: Sample, ref: Reference, body: BodyModel, settings, *, margin: float = 0.004,
                 batch: int = 8) -> np.ndarray:
    """The runtime's cloth stage (:class:`segadeform.body.cloth.ClothStage`, as ``segadeform run --effects=+cloth``)
    on a prediction of sample ``s``: the garment's setup on the body at rest of the sample's shape, then ``batch``
    frames at a time against the posed body, one stage (its state) over the whole sample.
    Shapes: x (T, N, 3) -> (T, N, 3)."""
    from ..body.cloth import ClothStage, garment_setup

    if ref.posed is None:
        raise InputError("this reference has no posed body", expected="reference(...) of this module")
    rest_body = body.shaped_vertices(s.betas if s.betas.size else None)[0]
    stage = ClothStage(garment_setup(s.rest, s.faces, rest_body, body.faces, settings), body.v_template, body.faces,
                       settings, margin=margin, dt=1.0 / float(s.meta.get("fps", 30.0)))
    return np.concatenate([stage.step(x[lo:lo + batch], ref.posed[lo:lo + batch]) for lo in range(0, len(x), batch)])


def cloth_names(settings) -> dict:
    """``{suffix: ClothSettings}`` for :func:`evaluate`'s ``cloth``: each item a :class:`ClothSettings` or its
    text form (``iterations=8,stiffness=0.5``; ``default`` or ``""``: the defaults), named ``" + cloth"`` for
    the defaults and ``" + cloth iterations=8,..."`` otherwise."""
    from ..settings.cloth import ClothSettings

    out = {}
    for item in ([] if settings is None else [settings] if isinstance(settings, (str, ClothSettings)) else settings):
        if isinstance(item, str):
            try:
                item = ClothSettings.parse("" if item.strip() == "default" else item)
            except ValueError as e:
                raise InputError(f"bad cloth settings: {e}", got=item) from None
        label = item.label()
        out[f" + cloth {label}" if label else " + cloth"] = item
    return out


def evaluate(dataset: Path, body: BodyModel, models: dict, *, split: str = "test", n_star: int = 32,
             frame_step: int = 1, progress: Optional[Callable[[str], None]] = None, push_out_margin=None,
             cloth=None, cloth_margin: float = 0.004) -> dict:
    """Evaluate ``models`` ({name: spec}) on ``split`` of ``dataset``.

    Returns ``{"models": {name: {metric: value}}, "by_type": {name: {type: {metric: value}}},
    "per_frame": {name: [vertex_cm per frame index]}, "samples": [...]}``.
    ``push_out_margin``: also report every learned model with the runtime's collision post-process
    (:class:`BodyCollider`, as ``segadeform run``): one margin in metres (``name + push-out``) or a list
    (``name + push-out 2 mm``, ... ; :func:`push_out_names`).  Its time is the model's plus the push-out's.
    ``cloth``: also report every learned model (a package or checkpoint) with the runtime's cloth stage at each
    of these settings (:func:`cloth_names`, :func:`cloth_frames`; contact at ``cloth_margin``), timed the same way.
    """
    from .data import sample_asset

    dataset = as_roots(dataset)  # a folder, a pack, or several roots
    ids = dataset.ids(split)
    if not ids:
        raise InputError(f"no '{split}' samples in the dataset", got=str(dataset))
    preds = {n: make_predictor(n, s) for n, s in models.items()}
    pushes = push_out_names(push_out_margin)
    cloths = cloth_names(cloth)
    learned = [n for n, s in models.items() if s not in ("lbs", "lbs-inpaint")]
    names = list(preds) + [f"{n}{sfx}" for sfx in pushes for n, s in models.items() if s != "lbs"] + \
        [f"{n}{sfx}" for sfx in cloths for n in learned]
    collider = BodyCollider(body.v_template, body.faces) if pushes else None
    acc = {n: _Acc.new() for n in names}
    by_type = {n: {} for n in names}
    per_frame = {n: _Acc.new() for n in names}
    bases = {}
    for sid in ids:
        s = dataset.load(sid)
        if progress:
            progress(sid)
        asset = sample_asset(dataset, s, body, n_star)
        key = s.meta.get("garment", sid) + f"-b{s.meta.get('body', 0)}"
        if key not in bases:
            bases[key] = SpectralBasis.from_mesh(s.rest, s.faces)
        ref = reference(s, body, bases[key])
        gt = ref.gt
        outs = {}
        for n, p in preds.items():
            t0 = time.perf_counter()
            outs[n] = p.predict(s, body, asset)
            ms = 1e3 * (time.perf_counter() - t0) / len(gt)
            acc[n].add("ms_per_frame", ms)
            for sfx, margin in pushes.items():
                if models[n] == "lbs":
                    continue
                t0 = time.perf_counter()
                outs[f"{n}{sfx}"] = push_out_frames(outs[n], ref, collider, margin)
                acc[f"{n}{sfx}"].add("ms_per_frame", ms + 1e3 * (time.perf_counter() - t0) / len(gt))
            for sfx, settings in cloths.items():
                if n not in learned:
                    continue
                t0 = time.perf_counter()
                outs[f"{n}{sfx}"] = cloth_frames(outs[n], s, ref, body, settings, margin=cloth_margin)
                acc[f"{n}{sfx}"].add("ms_per_frame", ms + 1e3 * (time.perf_counter() - t0) / len(gt))
        typ = s.meta.get("type", "?")
        for n, x in outs.items():
            if x.shape != gt.shape or not np.isfinite(x).all():
                raise InputError(f"model {n} produced a bad prediction for {sid}", expected=gt.shape, got=x.shape)
            vals = sample_metrics(x, ref, frame_step)
            d = np.linalg.norm(x - gt, axis=2)
            for k, v in vals.items():
                acc[n].add(k, v)
                by_type[n].setdefault(typ, _Acc.new()).add(k, v)
            for t, v in enumerate(100 * d.mean(axis=1)):
                per_frame[n].add(t, v)
    res = {"split": split, "samples": ids, "metrics": list(METRICS),
           "models": {n: {k: acc[n].mean(k) for k in METRICS + ("ms_per_frame",)} for n in names},
           "by_type": {n: {t: {k: a.mean(k) for k in METRICS} for t, a in sorted(by_type[n].items())} for n in names},
           "per_frame": {n: [per_frame[n].mean(t) for t in sorted(per_frame[n].sums)] for n in names},
           "specs": dict(models), "n_star": n_star}
    return res


_HEAD = {"vertex_cm": "vertex (cm)", "normal_deg": "normal (°)", "edge_mm": "edge (mm)", "low_cm": "low band (cm)",
         "mid_cm": "mid band (cm)", "high_cm": "high band (cm)", "penetration_pct": "penetrating (%)",
         "jitter_mm": "jitter (mm/f²)", "ms_per_frame": "ms/frame", "max_strain_pct": "max stretch (%)",
         "p99_strain_pct": "p99 stretch (%)"}
#: the per-type table's columns
_TYPE_COLS = ("vertex_cm", "normal_deg", "edge_mm", "penetration_pct", "max_strain_pct", "p99_strain_pct")


def markdown_table(res: dict) -> str:
    cols = METRICS + ("ms_per_frame",)
    lines = ["| model | " + " | ".join(_HEAD[k] for k in cols) + " |", "|---" * (len(cols) + 1) + "|"]
    for n, m in res["models"].items():
        lines.append(f"| {n} | " + " | ".join(f"{m[k]:.3f}" if k != "ms_per_frame" else f"{m[k]:.1f}"
                                             for k in cols) + " |")
    out = ["\n".join(lines), "", "Per garment type (vertex error, cm):", ""]
    types = sorted({t for n in res["by_type"] for t in res["by_type"][n]})
    out.append("| model | " + " | ".join(types) + " |")
    out.append("|---" * (len(types) + 1) + "|")
    for n, bt in res["by_type"].items():
        out.append(f"| {n} | " + " | ".join(f"{bt[t]['vertex_cm']:.3f}" if t in bt else "-" for t in types) + " |")
    out += ["", "Per garment type, every metric:", "",
            "| type | model | " + " | ".join(_HEAD[k] for k in _TYPE_COLS) + " |", "|---" * (len(_TYPE_COLS) + 2) + "|"]
    for t in types:
        for n, bt in res["by_type"].items():
            if t in bt:
                out.append(f"| {t} | {n} | " + " | ".join(f"{bt[t][k]:.3f}" if k in bt[t] else "-"
                                                        for k in _TYPE_COLS) + " |")
    return "\n".join(out)


def write_report(res: dict, out_dir: Path, *, dataset: Optional[Path] = None, body: Optional[BodyModel] = None,
                 heatmap_model: Optional[str] = None) -> None:
    """Write ``eval.json``, ``eval.md`` and the PNG plots into ``out_dir``."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    with atomic_path(out / "eval.json") as tmp:
        Path(tmp).write_text(json.dumps(res, indent=1))
    md = [f"# Evaluation on the '{res['split']}' split ({len(res['samples'])} samples)", "", markdown_table(res), ""]
    with atomic_path(out / "eval.md") as tmp:
        Path(tmp).write_text("\n".join(md))
    fig, ax = plt.subplots(figsize=(7, 4))
    for n, v in res["per_frame"].items():
        ax.plot(v, label=n)
    ax.set_xlabel("frame")
    ax.set_ylabel("mean vertex error (cm)")
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(out / "error_per_frame.png", dpi=80)
    plt.close(fig)
    fig, ax = plt.subplots(figsize=(7, 4))
    names = list(res["models"])
    w = 0.8 / len(names)
    for i, n in enumerate(names):
        ax.bar(np.arange(3) + i * w, [res["models"][n][k] for k in ("low_cm", "mid_cm", "high_cm")], w, label=n)
    ax.set_xticks(np.arange(3) + 0.4 - w / 2, ["low", "mid", "high"])
    ax.set_ylabel("band error (cm)")
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(out / "error_per_band.png", dpi=80)
    plt.close(fig)
    fig, ax = plt.subplots(figsize=(6, 4))
    for n, m in res["models"].items():
        ax.scatter(m["ms_per_frame"], m["vertex_cm"])
        ax.annotate(n, (m["ms_per_frame"], m["vertex_cm"]), fontsize=7)
    ax.set_xlabel("ms per frame (one thread, this machine)")
    ax.set_ylabel("mean vertex error (cm)")
    ax.set_title("what accuracy costs")
    fig.tight_layout()
    fig.savefig(out / "error_vs_cost.png", dpi=80)
    plt.close(fig)
    if dataset is not None and body is not None and heatmap_model:
        _heatmap(res, dataset, body, heatmap_model, out / "error_map.png", res.get("n_star", 32))


def _heatmap(res, dataset, body, name, path, n_star: int = 32):
    """Per-vertex error of one held-out frame, coloured on the simulated garment."""
    import matplotlib.pyplot as plt
    from mpl_toolkits.mplot3d.art3d import Poly3DCollection

    from .data import sample_asset

    sid = res["samples"][0]
    dataset = as_roots(dataset)
    s = dataset.load(sid)
    p = make_predictor(name, res["specs"][name])
    x = p.predict(s, body, sample_asset(dataset, s, body, n_star))
    t = len(x) // 2
    err = 100 * np.linalg.norm(x[t] - s.frames[t], axis=1)
    v = s.frames[t].astype(np.float64)
    fe = err[s.faces].mean(1)
    fig = plt.figure(figsize=(5, 6))
    ax = fig.add_subplot(projection="3d")
    cmap = plt.get_cmap("viridis")
    vmax = max(float(np.percentile(err, 99)), 1e-6)
    tri = v[s.faces][:, :, [0, 2, 1]]
    ax.add_collection3d(Poly3DCollection(tri, facecolors=cmap(np.clip(fe / vmax, 0, 1)), linewidth=0))
    c = v.mean(0)
    r = np.abs(v - c).max()
    ax.set_xlim(c[0] - r, c[0] + r)
    ax.set_ylim(c[2] - r, c[2] + r)
    ax.set_zlim(c[1] - r, c[1] + r)
    ax.view_init(10, -70)
    ax.axis("off")
    sm = plt.cm.ScalarMappable(cmap=cmap, norm=plt.Normalize(0, vmax))
    fig.colorbar(sm, ax=ax, shrink=0.6, label="vertex error (cm)")
    ax.set_title(f"{name}: {sid}, frame {t}", fontsize=8)
    fig.savefig(path, dpi=80)
    plt.close(fig)
