"""``segadeform eval``: the paper's metrics (§5) against the simulation, for the model and its baselines.

Metrics, each sample's averaged over its frames and vertices, then averaged over the samples with equal weight (a
short clip of a small garment counts as much as a long clip of a large one; per garment type, the mean of that
type's samples):

* ``vertex_cm``     mean vertex distance (cm)
* ``normal_deg``    mean angle between predicted and simulated vertex normals (degrees; each vertex's normal the
  area-weighted mean of its faces' -- the paper's tables say vertex normals, its §5.3 text "facet": face normals
  give larger angles, 30.4 against 25.9 degrees for the shipped model on one held-out dress)
* ``edge_mm``       mean over edges of |edge length - simulated edge length| (mm; not the difference of the two mean
  lengths, which the paper's "average edge length" could also be read as)
* ``low_cm`` / ``mid_cm`` / ``high_cm``  the error field ``pred - sim`` split into the
  low / mid / high spectral bands of the rest garment (§5.2, Table 2;
  :class:`~segadeform.geometry.laplacian.SpectralBasis`: the cotangent Laplacian's eigenvectors, orthonormal in
  the lumped mass matrix, split at 3 % and 30 % of them -- the paper names no Laplacian; a graph Laplacian with
  Euclidean projection gives a mid band 18-29 % larger), mean vertex norm of each (cm; the three do not add up to
  ``vertex_cm``: each is a mean of norms)
* ``penetration_pct``  vertices deeper than 2 mm inside the posed body (%): inside by the body's winding number,
  more than 2 mm from every surface of it (:func:`~segadeform.train.metrics.penetrating`); ``pinched_pct`` those of
  them in a pinch where the body intersects itself (an arm pressed into the torso: the surface nearest them, the
  arm's skin buried in the torso, says outside; :func:`~segadeform.train.metrics.penetrating_and_pinched`)
* ``through_pct``  faces across a limb (% of faces): the centre more than 5 mm inside the body while no corner
  penetrates -- a limb through the cloth between vertices taken out on opposite sides of it, which a render shows
  as a hole and the vertex count does not (:func:`~segadeform.train.metrics.through_faces`)
* ``max_strain_pct``  the largest edge stretch, length / rest length - 1 against the garment's rest mesh, over
  every edge and frame (%; over samples, the largest), and ``p99_strain_pct`` its 99th percentile (averaged).
  The simulation's frames are measured against the same rest mesh, though Blender took its rest lengths from the
  garment made in an A-pose where the dataset says so (``cloth_rest``): part of the simulation's stretch is that
  other rest shape (a researcher's audit: a held-out dress on CMU 49_02, 115.5 % largest and 22.4 % p99 against
  the rest mesh, 88.2 % and 15.2 % against its ``cloth_rest``)
* ``jitter_mm``     mean |second difference of pred - second difference of sim| (mm/frame^2)
* ``ms_per_frame``  the model's own time per frame (garment precompute excluded), one thread

The metrics beside the time per frame show what accuracy costs: a package can be
evaluated with effects off (``FOLDER:-wrinkles``, ``FOLDER:-dynamics``, ``FOLDER:dqs``).

Models are predictors (:mod:`.predictors`): a model package (ONNX, run by onnxruntime, torch-free:
:class:`segadeform.runtime.predictor.PackagePredictor`), a checkpoint (``.pt``, run by torch), or ``lbs`` -- the
body's skinning weights transferred to the garment from the nearest body point, no blend shapes (baseline (a)).
This module is the loop; the metrics are :mod:`.metrics`', the report (``eval.md``, ``eval.json``, plots)
:mod:`.report`'s.
"""

from __future__ import annotations

import dataclasses
import time
from collections.abc import Callable, Sequence
from pathlib import Path

import numpy as np

from ..body.cloth import ClothStage, garment_setup
from ..body.collision import BodyCollider
from ..body.model import BodyModel
from ..dataset.roots import as_roots
from ..dataset.store import Sample
from ..errors import InputError
from ..geometry.laplacian import SpectralBasis
from ..settings.cloth import ClothSettings
from .data import sample_asset
from .metrics import METRICS, PEAK_METRICS, Reference, reference, sample_metrics
from .predictors import Predictor

__all__ = ["evaluate", "pick_samples", "push_out_frames", "push_out_names", "cloth_frames", "cloth_names"]


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


def push_out_frames(
    x: np.ndarray, ref: Reference, collider: BodyCollider, margin: float, *, batch: int = 8
) -> np.ndarray:
    """The runtime's collision stage on a prediction: ``collider`` (:class:`BodyCollider`, built once)
    pushes ``batch`` frames at a time out of the posed body, the correction carried from frame to frame from the
    sample's first, as ``segadeform run`` does.
    Shapes: x (T, N, 3) -> (T, N, 3)."""
    if ref.posed is None:
        raise InputError("this reference has no posed body", expected="reference(...) of this module")
    out = np.empty(x.shape, np.float64)
    carry = np.zeros((x.shape[1], 3))
    for lo in range(0, len(x), batch):
        out[lo : lo + batch] = collider.push_out(x[lo : lo + batch], ref.posed[lo : lo + batch], margin, carry=carry)[0]
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


def cloth_frames(
    x: np.ndarray, s: Sample, ref: Reference, body: BodyModel, settings, *, margin: float = 0.004, batch: int = 8
) -> np.ndarray:
    """The runtime's cloth stage (:class:`segadeform.body.cloth.ClothStage`, as ``segadeform run --effects=+cloth``)
    on a prediction of sample ``s``: the garment's setup on the body at rest of the sample's shape, then ``batch``
    frames at a time against the posed body, one stage (its state) over the whole sample.
    Shapes: x (T, N, 3) -> (T, N, 3)."""
    if ref.posed is None:
        raise InputError("this reference has no posed body", expected="reference(...) of this module")
    rest_body = body.shaped_vertices(s.betas if s.betas.size else None)[0]
    stage = ClothStage(
        garment_setup(s.rest, s.faces, rest_body, body.faces, settings),
        body.v_template,
        body.faces,
        settings,
        margin=margin,
        dt=1.0 / float(s.meta.get("fps", 30.0)),
    )
    return np.concatenate(
        [stage.step(x[lo : lo + batch], ref.posed[lo : lo + batch]) for lo in range(0, len(x), batch)]
    )


def cloth_names(settings) -> dict:
    """``{suffix: ClothSettings}`` for :func:`evaluate`'s ``cloth``: each item a :class:`ClothSettings` or its
    text form (``iterations=8,stiffness=0.5``; ``default`` or ``""``: the defaults), named ``" + cloth"`` for
    the defaults and ``" + cloth iterations=8,..."`` otherwise."""
    out = {}
    for item in [] if settings is None else [settings] if isinstance(settings, (str, ClothSettings)) else settings:
        if isinstance(item, str):
            try:
                item = ClothSettings.parse("" if item.strip() == "default" else item)
            except ValueError as e:
                raise InputError(f"bad cloth settings: {e}", got=item) from None
        label = item.label()
        out[f" + cloth {label}" if label else " + cloth"] = item
    return out


def pick_samples(ids: list, samples: Sequence[str], split: str, dataset) -> list:
    """``ids`` (the split's) restricted to ``samples``, in the split's order; a name that is not one of them, or one
    named twice, is an error naming it."""
    want = [str(x) for x in samples]
    if not want:
        raise InputError("no samples named", expected="at least one sample id of the split", got="none")
    twice = sorted({x for x in want if want.count(x) > 1})
    if twice:
        raise InputError("a sample is named twice", expected="each sample once", got=", ".join(twice))
    have = set(ids)
    missing = [x for x in want if x not in have]
    if missing:
        raise InputError(
            f"not a sample of the '{split}' split",
            path=str(dataset),
            expected=f"one of its {len(ids)} kept samples (first: {ids[0]})" if ids else "a kept sample",
            got=", ".join(missing),
        )
    keep = set(want)
    return [x for x in ids if x in keep]


def evaluate(
    dataset: Path,
    body: BodyModel,
    predictors: dict[str, Predictor],
    *,
    split: str = "test",
    n_star: int = 32,
    frame_step: int = 1,
    progress: Callable[[str], None] | None = None,
    push_out_margin=None,
    cloth=None,
    cloth_margin: float = 0.004,
    samples: Sequence[str] | None = None,
) -> dict:
    """Evaluate ``predictors`` ({name: :class:`~segadeform.train.predictors.Predictor`}) on ``split`` of ``dataset``.

    Returns ``{"models": {name: {metric: value}}, "by_type": {name: {type: {metric: value}}},
    "per_frame": {name: [vertex_cm per frame index]}, "by_sample": {id: {"type", "vertex_cm": {name: cm},
    "metrics": {name: {metric: value}}}}, "samples": [...]}`` (``by_sample``'s ``metrics``: every metric of each
    model on that sample, from which any subset's table can be made again).
    ``samples``: only these samples of the split (each must be one of it), in the split's order; None: all.
    ``push_out_margin``: also report every model but plain ``lbs`` and ``simulation`` with the runtime's collision
    post-process (:class:`BodyCollider`, as ``segadeform run``): one margin in metres (``name + push-out``) or a list
    (``name + push-out 2 mm``, ... ; :func:`push_out_names`).  Its time is the model's plus the push-out's.
    ``cloth``: also report every model but ``lbs``, ``lbs-inpaint`` and ``simulation`` with the runtime's cloth stage at
    each of these settings (:func:`cloth_names`, :func:`cloth_frames`; contact at ``cloth_margin``), timed the same way.
    """
    dataset = as_roots(dataset)  # a folder, a pack, or several roots
    dataset.check_body(body)
    from ..body.identity import body_text, other_body

    for n, p in predictors.items():  # a model trained on another body gave numbers as if it fitted this one
        here = other_body(getattr(p, "body", None), body)
        if here is not None:
            raise InputError(
                f"model {n} was trained on another body than the dataset's (eval --body)",
                path=p.spec,
                expected=body_text(here),
                got=body_text(p.body),
            )
    ids = dataset.ids(split)
    if not ids:
        have = sorted({str(dataset.meta(s).get("split")) for s in dataset.ids()})
        raise InputError(
            f"no '{split}' samples in the dataset",
            path=str(dataset),
            expected="--split " + (" | ".join(have) if have else "of a dataset with samples (it has none kept)"),
            got=f"the splits {', '.join(have)}" if have else "no kept samples",
        )
    if samples is not None:
        ids = pick_samples(ids, samples, split, dataset)
    preds = dict(predictors)
    models = {n: p.spec for n, p in preds.items()}
    pushes = push_out_names(push_out_margin)
    cloths = cloth_names(cloth)
    learned = [n for n, s in models.items() if s not in ("lbs", "lbs-inpaint", "simulation")]
    names = (
        list(preds)
        + [f"{n}{sfx}" for sfx in pushes for n, s in models.items() if s not in ("lbs", "simulation")]
        + [f"{n}{sfx}" for sfx in cloths for n in learned]
    )
    collider = BodyCollider(body.v_template, body.faces) if pushes else None
    acc = {n: _Acc.new() for n in names}
    by_type = {n: {} for n in names}
    per_frame = {n: _Acc.new() for n in names}
    by_sample: dict = {}
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
                if models[n] in ("lbs", "simulation"):
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
            row = by_sample.setdefault(sid, {"type": typ, "vertex_cm": {}, "metrics": {}})
            row["vertex_cm"][n] = float(vals["vertex_cm"])
            row["metrics"][n] = {k: float(v) for k, v in vals.items()}
            for t, v in enumerate(100 * d.mean(axis=1)):
                per_frame[n].add(t, v)
    res = {
        "split": split,
        "samples": ids,
        "metrics": list(METRICS),
        "models": {n: {k: acc[n].mean(k) for k in METRICS + ("ms_per_frame",)} for n in names},
        "by_type": {n: {t: {k: a.mean(k) for k in METRICS} for t, a in sorted(by_type[n].items())} for n in names},
        "per_frame": {n: [per_frame[n].mean(t) for t in sorted(per_frame[n].sums)] for n in names},
        "by_sample": by_sample,
        "specs": dict(models),
        "n_star": n_star,
    }
    return res
