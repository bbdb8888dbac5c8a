"""What ``bench/tradeoffs.py`` measures: the rows (every knob's settings, :func:`plan_rows`), the presets they
match (:func:`match_presets`), each row's errors and times on a dataset's split (:func:`measure`) and the
simulator's quality axis (:func:`simulator_axis`, :func:`blender_resimulate`, :func:`resimulate`).  Nothing here
writes a file; :mod:`bench.tradeoffs_render` turns the results into the docs, ``bench/tradeoffs.py`` is the command.

Importable (``from bench import tradeoffs_measure`` from the repository root).
"""

from __future__ import annotations

import dataclasses
import json
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np

__all__ = [
    "EFFECTS_ROWS",
    "DEFAULT_BATCH",
    "Row",
    "cloth_key",
    "preset_key",
    "effects_key",
    "match_presets",
    "plan_rows",
    "measure",
    "resimulate",
    "blender_resimulate",
    "simulator_axis",
]

#: effects rows: name -> (complete effects list for the package, what it is)
EFFECTS_ROWS = {
    "all effects": ("lbs,dynamics,wrinkles", "lbs + dynamics + wrinkles"),
    "no wrinkles": ("lbs,dynamics", "-wrinkles"),
    "no dynamics": ("lbs,wrinkles", "-dynamics"),
    "static, no wrinkles": ("lbs", "-dynamics,-wrinkles"),
    "dqs": ("dqs,dynamics,wrinkles", "dqs skinning, all effects"),
}
DEFAULT_BATCH = 8


@dataclasses.dataclass(frozen=True)
class Row:
    """One measured setting.  ``spec``: a package folder, ``lbs`` or another ``make_predictor`` spec;
    ``effects``: the package's effects as a complete list; ``base``: the row whose prediction this one
    pushes out (``margin``)."""

    name: str
    knob: str
    setting: str
    spec: str
    effects: str = "lbs,dynamics,wrinkles"
    margin: float | None = None
    batch: int = DEFAULT_BATCH
    k: int | None = None
    n_star: int | None = None
    res: str | None = None
    base: str | None = None
    #: the cloth stage's settings (their text form, "default" for the defaults) on ``base``'s prediction
    cloth: str | None = None


def cloth_key(e) -> str | None:
    """An Effects' cloth stage as the rows name it: None when off, ``"default"`` or its knobs' text form."""
    return (e.cloth_settings.label() or "default") if e.cloth else None


def preset_key(e) -> tuple:
    """What a row must match to be a preset's: (effects list, margin of the push-out or the cloth's contact, cloth)."""
    return (effects_key(e), e.collision_margin if e.collisions or e.cloth else None, cloth_key(e))


def effects_key(e) -> str:
    """An Effects as the complete list the rows use (collisions are the margin, not part of it)."""
    return ",".join([e.skinning] + [n for n in ("dynamics", "wrinkles") if getattr(e, n)])


def _mm(m: float) -> str:
    return f"{1e3 * m:g} mm"


def _model_setting(spec: str) -> str:
    """A model row's setting: its width and depth (and ensemble size) when the spec is a package."""
    mpath = Path(spec) / "manifest.json"
    if not mpath.is_file():
        return spec
    c = json.loads(mpath.read_text())["config"]
    return (
        f"hidden {c['hidden']}, {c['enc_layers']}+{c['dec_layers']} graph blocks, {c.get('heads', '?')} heads, "
        f"window T = {c.get('window', '?')}"
        + (f", {c['ensemble']} networks averaged" if c.get("ensemble", 1) > 1 else "")
        + f" ({spec})"
    )


def match_presets(rows: dict, pkg: str) -> dict:
    """``{preset: row name}``: the row of package ``pkg`` with each preset's effects and margin."""
    from segadeform.settings.presets import QUALITY_PRESETS

    out = {}
    for name, p in QUALITY_PRESETS.items():
        key = preset_key(p.effects)
        hit = [
            n
            for n, r in rows.items()
            if r["spec"] == pkg
            and r["knob"] in ("effects", "collisions", "cloth", "preset")
            and (r["effects"], r["margin"], r.get("cloth")) == key
        ]
        if not hit:
            raise SystemExit(f"preset {name} ({key}) was not measured in this run")
        out[name] = hit[0]
    return out


def plan_rows(
    pkg: str,
    int8: str | None,
    models: dict,
    *,
    fp16: str | None = None,
    margins=(0.002, 0.004, 0.008),
    ks=(4, 6, 12),
    n_stars=(8, 16, 64),
    batches=(1, 32),
    resolutions=("1/4", "1/2", "4x"),
    cloth_iterations=(1, 2, 4, 8, 16),
    cloth_stiffness=(0.5, 0.2),
    cloth_backstop=(0.0,),
    cloth_knobs=(),
    cloth_margins=(0.002, 0.008),
) -> tuple[list[Row], dict]:
    """Every row, bases before what is derived from them, and ``{preset: row name}``."""
    from segadeform.settings.presets import QUALITY_PRESETS

    rows = [Row("lbs", "baseline", "body skinning only", "lbs", effects="")]
    for n, (eff, what) in EFFECTS_ROWS.items():
        rows.append(Row(n, "effects", what, pkg, eff))
    if fp16:
        rows.append(Row("fp16 weights", "precision", "weights stored as float16, float32 arithmetic", fp16))
    if int8:
        rows.append(Row("int8", "precision", "int8 dynamic quantisation", int8))
    for n, s in models.items():
        rows.append(Row(n, "model", _model_setting(s), s))
    for b in batches:
        rows.append(Row(f"batch {b}", "batch", f"{b} frames per deformer call", pkg, batch=b))
    for k in ks:
        rows.append(Row(f"K={k}", "K", f"{k} neighbours per vertex", pkg, k=k))
    for n in n_stars:
        rows.append(Row(f"N*={n}", "N*", f"{n} descriptor samples", pkg, n_star=n))
    for r in resolutions:
        what = "subdivided" if r.endswith("x") else "decimated"
        rows.append(Row(f"garment {r} res", "resolution", f"{what} to {r} of the vertices", pkg, res=r))
    learned = [r for r in rows if r.knob in ("effects", "precision", "model")]
    for r in learned:
        ms = margins if r.name in ("all effects", "no wrinkles") else (0.004,)
        for m in ms:
            rows.append(
                dataclasses.replace(
                    r,
                    name=f"{r.name} + push-out {_mm(m)}",
                    knob="collisions",
                    setting=f"{r.name}, push-out at {_mm(m)}",
                    margin=m,
                    base=r.name,
                )
            )
    from segadeform.settings.cloth import ClothSettings

    cloths = (
        [f"iterations={k}" if k != ClothSettings().iterations else "default" for k in cloth_iterations]
        + [f"stiffness={k:g}" for k in cloth_stiffness]
        + [f"backstop={k:g}" for k in cloth_backstop if k != ClothSettings().backstop]
        + [ClothSettings.parse(k).label() for k in cloth_knobs]
    )

    def cloth_row(r: Row, c: str, m: float = 0.004, suffix: str = "") -> Row:
        return dataclasses.replace(
            r,
            name=f"{r.name} + cloth {c}{suffix}",
            knob="cloth",
            setting=f"{r.name}, the cloth stage ({c}), contact at {_mm(m)}",
            margin=m,
            base=r.name,
            cloth=c,
        )

    # every setting on "all effects"; the defaults on every other effects row (as the push-out at 4 mm), so that
    # the stage can be compared with the push-out on the rows the presets use
    for r in [r for r in rows if r.knob == "effects"]:
        rows += [cloth_row(r, c) for c in (cloths if r.name == "all effects" else ["default"])]
    all_effects = next(r for r in rows if r.name == "all effects")
    # the contact margin (run --collision-margin with the stage), at the defaults
    rows += [cloth_row(all_effects, "default", m, f", contact {_mm(m)}") for m in cloth_margins]
    presets = {}
    for name, p in QUALITY_PRESETS.items():
        key = preset_key(p.effects)
        hit = [
            r.name
            for r in rows
            if r.spec == pkg and r.knob in ("effects", "collisions", "cloth") and (r.effects, r.margin, r.cloth) == key
        ]
        if hit:
            presets[name] = hit[0]
        else:
            base = [r.name for r in rows if r.spec == pkg and r.knob == "effects" and r.effects == key[0]]
            rows.append(
                Row(
                    f"preset {name}",
                    "preset",
                    f"--quality {name}",
                    pkg,
                    key[0],
                    margin=key[1],
                    base=base[0] if base and key[1] is not None else None,
                    cloth=key[2],
                )
            )
            presets[name] = f"preset {name}"
    return rows, presets


class _Runner:
    """A model package for one set of effects, at one thread and at ``threads_all``; times the deformer."""

    def __init__(self, path: str, effects: str, threads_all: int):
        from segadeform.runtime import ModelPackage
        from segadeform.runtime.deformer import Deformer
        from segadeform.settings import parse_effects

        eff = dataclasses.replace(parse_effects(effects), collisions=False)
        self.deformers = {t: Deformer(ModelPackage(path, threads=t), eff) for t in sorted({1, threads_all})}
        self.n_star = int(self.deformers[1].package.config["n_star"])

    def encode(self, s, body, asset):
        """(P, log_wbody, ms) at one thread; P is cached per asset by the deformers themselves."""
        d = self.deformers[1]
        joints = body.rest_joints(s.betas if s.betas.size else None)[0]
        t0 = time.perf_counter()
        P = d.encode(asset, joints, s.betas)
        lw = d.body_log_weights(asset, body, s.betas) if d.needs_body_weights else None
        return P, lw, 1e3 * (time.perf_counter() - t0)

    def deform(self, s, body, asset, P, lw, threads: int, batch: int, repeats: int):
        """(T, N, 3) frames and the best ms/frame of ``repeats`` runs, as the runtime's deform stage."""
        from segadeform.motion.motion import motion_windows

        d = self.deformers[threads]
        joints = body.rest_joints(s.betas if s.betas.size else None)[0]
        best, out = np.inf, None
        for _ in range(repeats):
            t0 = time.perf_counter()
            parts = []
            for lo in range(0, len(s.poses), batch):
                hi = min(lo + batch, len(s.poses))
                win = motion_windows(s.poses, d.window, start=lo, stop=hi)
                parts.append(d.deform(P, asset, win, joints, s.trans[lo:hi], s.betas, log_wbody=lw))
            best = min(best, time.perf_counter() - t0)
            out = parts
        return np.concatenate(out).astype(np.float64), 1e3 * best / len(s.poses)


def _resampled(v, f, res: str):
    from segadeform.body.resample import decimate, subdivide

    if res.endswith("x"):
        vv, ff = v, f
        for _ in range(int(round(np.log(float(res[:-1])) / np.log(4.0)))):
            vv, ff = subdivide(vv, ff)
        return vv, ff
    num, den = (int(x) for x in res.split("/"))
    return decimate(v, f, max(4, int(round(len(v) * num / den))))


class _Assets:
    """The garment assets of one sample for every (K, N*, resolution), each with its setup time."""

    def __init__(self, s, body, n_star_model: int):
        self.s, self.n_star = s, n_star_model
        self.joints = body.rest_joints(s.betas if s.betas.size else None)[0]
        self.cache = {}

    def get(self, k=None, n_star=None, res=None):
        """(asset, precompute ms, SurfaceMap or None)."""
        from segadeform.body.resample import SurfaceMap
        from segadeform.geometry import precompute_garment
        from segadeform.geometry.descriptor import garment_descriptor, rescale_descriptor
        from segadeform.geometry.graph import neighbour_graph

        key = (k, n_star, res)
        if key in self.cache:
            return self.cache[key]
        v, f = self.s.rest.astype(np.float64), self.s.faces
        t0 = time.perf_counter()
        smap = None
        if res is not None:
            v, f = _resampled(v, f, res)
            smap = SurfaceMap.build(self.s.rest, v, f)
        a = precompute_garment(v, f, self.joints, n_star=self.n_star)
        if k is not None:
            nbr, mask = neighbour_graph(a.faces, a.n_vertices, k=k, vertices=a.vertices)
            a = dataclasses.replace(a, nbr=nbr, mask=mask, params=dict(a.params, k=int(k)))
        if n_star is not None:
            lam = rescale_descriptor(garment_descriptor(v, f, n_star=n_star).eigenvalues, self.n_star)
            a = dataclasses.replace(a, descriptor=lam, params=dict(a.params, n_star_sampled=int(n_star)))
        ms = 1e3 * (time.perf_counter() - t0)
        if n_star is not None:  # the descriptor at N* replaces the one at the model's N*: time only that one
            t1 = time.perf_counter()
            garment_descriptor(v, f, n_star=self.n_star)
            ms -= 1e3 * (time.perf_counter() - t1)
        self.cache[key] = (a, ms, smap)
        return self.cache[key]


def peak_metrics(per_sample: dict) -> dict:
    """The metrics that are a largest value (``segadeform eval``'s PEAK_METRICS: the largest edge stretch) over a
    row's samples: the largest of the samples', as ``eval`` reports them, not their mean.  ``per_sample``: sample
    id -> {"metrics": {...}}."""
    from segadeform.train.metrics import PEAK_METRICS

    return {k: max(v["metrics"][k] for v in per_sample.values()) for k in PEAK_METRICS}


def measure(
    dataset: Path,
    body,
    rows: list[Row],
    *,
    split: str,
    threads_all: int,
    repeats: int,
    keep: tuple = (),
    only: tuple = (),
    progress: Callable[[str], None] = lambda s: None,
) -> dict:
    """Every row on every sample of ``split`` (or those of them in ``only``): mean metrics and times, and the
    predictions of the samples in ``keep`` (for the simulator's axis)."""
    from segadeform.body.collision import BodyCollider
    from segadeform.dataset.store import list_samples, load_sample
    from segadeform.geometry.laplacian import SpectralBasis
    from segadeform.runtime.predictor import PackagePredictor
    from segadeform.settings.cloth import ClothSettings
    from segadeform.train.evaluate import cloth_frames, push_out_frames
    from segadeform.train.metrics import METRICS, reference, sample_metrics
    from segadeform.train.predictors import make_predictor

    ids = [i for i in list_samples(dataset, split) if not only or i in only]
    if not ids:
        raise SystemExit(f"no '{split}' samples in {dataset}" + (f" among {only}" if only else ""))
    collider = BodyCollider(body.v_template, body.faces)
    runners: dict = {}
    others: dict = {}
    sums = {r.name: {} for r in rows}
    bases, kept, per_sample = {}, {}, {r.name: {} for r in rows}

    def add(name, key, value):
        sums[name][key] = sums[name].get(key, 0.0) + float(value)

    for sid in ids:
        progress(sid)
        s = load_sample(dataset, sid)
        key = s.meta.get("garment", sid) + f"-b{s.meta.get('body', 0)}"
        if key not in bases:
            bases[key] = SpectralBasis.from_mesh(s.rest, s.faces)
        ref = reference(s, body, bases[key])
        T = len(s.frames)
        preds, times, encoded = {}, {}, {}
        assets = None
        for r in rows:
            info = {}
            if r.base is not None:  # a push-out (or the cloth stage) of another row's prediction
                t0 = time.perf_counter()
                if r.cloth is not None:
                    x = cloth_frames(
                        preds[r.base],
                        s,
                        ref,
                        body,
                        ClothSettings.parse("" if r.cloth == "default" else r.cloth),
                        margin=r.margin,
                        batch=r.batch,
                    )
                else:
                    x = push_out_frames(preds[r.base], ref, collider, r.margin, batch=r.batch)
                push = 1e3 * (time.perf_counter() - t0) / T
                ms1, msn, setup = times[r.base][0] + push, times[r.base][1] + push, times[r.base][2]
            elif Path(r.spec).is_dir():
                rk = (r.spec, r.effects)
                if rk not in runners:
                    runners[rk] = _Runner(r.spec, r.effects, threads_all)
                run = runners[rk]
                if assets is None or assets.n_star != run.n_star:
                    assets = _Assets(s, body, run.n_star)
                asset, pre_ms, smap = assets.get(r.k, r.n_star, r.res)
                P, lw, enc_ms = run.encode(s, body, asset)
                # the encoder runs once per garment: a row reusing another's (batch) reports that run's time
                enc_ms = encoded.setdefault((rk, r.k, r.n_star, r.res), enc_ms)
                x, ms1 = run.deform(s, body, asset, P, lw, 1, r.batch, repeats)
                xn, msn = run.deform(s, body, asset, P, lw, threads_all, r.batch, repeats)
                info["threads_max_diff_mm"] = 1e3 * float(np.abs(xn - x).max())
                info["vertices"] = asset.n_vertices
                if smap is not None:  # carry to the full-resolution vertices
                    t0 = time.perf_counter()
                    x = smap.apply(x)
                    carry = 1e3 * (time.perf_counter() - t0) / T
                    ms1, msn = ms1 + carry, msn + carry
                setup = pre_ms + enc_ms
            else:  # lbs or a checkpoint: one timing (numpy / torch eager), both columns
                if r.spec not in others:
                    others[r.spec] = make_predictor(r.name, r.spec, package=PackagePredictor)
                asset = None
                if r.spec != "lbs":
                    from segadeform.train.data import sample_asset

                    asset = sample_asset(dataset, s, body, 32)
                t0 = time.perf_counter()
                x = others[r.spec].predict(s, body, asset)
                ms1 = msn = 1e3 * (time.perf_counter() - t0) / T
                setup = 0.0
            if x.shape != ref.gt.shape or not np.isfinite(x).all():
                raise SystemExit(f"row {r.name} produced a bad prediction for {sid}: {x.shape}")
            preds[r.name], times[r.name] = x, (ms1, msn, setup)
            same = next((o for o in ("all effects",) if r.knob == "batch" and o in preds), None)
            if same is not None and np.abs(x - preds[same]).max() < 1e-5:
                m = per_sample[same][sid]["metrics"]  # the same prediction: its metrics
                info["same_as"] = same
            else:
                m = sample_metrics(x, ref)
            for k_, v_ in m.items():
                add(r.name, k_, v_)
            add(r.name, "ms_per_frame", ms1)
            add(r.name, "ms_per_frame_all", msn)
            add(r.name, "setup_ms", setup)
            per_sample[r.name][sid] = {"metrics": m, "ms_per_frame": ms1, "ms_per_frame_all": msn, **info}
        if sid in keep:
            kept[sid] = {n: (preds[n], times[n]) for n in preds}
    out = {}
    for r in rows:
        out[r.name] = {k_: v_ / len(ids) for k_, v_ in sums[r.name].items()}
        out[r.name].update(peak_metrics(per_sample[r.name]))
        out[r.name].update(
            knob=r.knob,
            setting=r.setting,
            spec=r.spec,
            effects=r.effects,
            margin=r.margin,
            batch=r.batch,
            k=r.k,
            n_star=r.n_star,
            res=r.res,
            cloth=r.cloth,
        )
    return {"rows": out, "samples": ids, "per_sample": per_sample, "kept": kept, "metrics": list(METRICS)}


def resimulate(
    cfg,
    dataset: Path,
    body,
    sid: str,
    *,
    attempt: int = 0,
    quality=None,
    offset=None,
    lead=None,
    effects=(),
    sim_python=None,
):
    """Sample ``sid`` of ``dataset`` made again by Blender as ``segadeform dataset make`` made it from ``cfg``
    (its garment files, the motion with its simulated lead, the settings of simulation ``attempt``: 0, or the
    [[fallback]] the sample was kept on), changed where asked: ``quality`` replaces the solver's steps per frame,
    ``offset`` (N, 3, metres) moves the garment's rest vertices (and its A-posed cloth's), ``lead`` keeps only the
    last ``lead`` frames of the simulated lead (the capture before the clip, which no model input shows),
    ``effects`` names simulation effects to turn on as well (e.g. ``("self_collision",)``).

    Shapes: -> frames (T, N, 3) of the clip (float64), Blender's seconds per simulated frame."""
    from segadeform.dataset.make import _cloth_rel, _garment_rel, _motion, sample_plan
    from segadeform.io import read_mesh
    from segadeform.physics.blender import A_POSE, simulate

    ps = next((p for p in sample_plan(cfg) if p.id == sid), None)
    if ps is None:
        raise SystemExit(f"{sid} is not a sample of the dataset config")
    g, m, betas = cfg.garments[ps.garment], cfg.motions[ps.motion], cfg.bodies[ps.body]
    st = cfg.attempt_settings(g, int(attempt))
    if quality is not None:
        st = st.replace(quality=int(quality))
    extra = tuple(e for e in effects if e not in st.effects)
    if extra:
        st = st.replace(effects=tuple(st.effects) + extra)
    rel = _garment_rel(cfg, ps.garment, ps.body)
    mesh = read_mesh(Path(dataset) / rel)
    cpath = Path(dataset) / _cloth_rel(rel)
    verts = mesh.vertices.astype(np.float64)
    cloth = read_mesh(cpath).vertices.astype(np.float64) if cpath.is_file() else None
    if offset is not None:
        verts = verts + offset
        cloth = None if cloth is None else cloth + offset
    kw = {} if cloth is None else {"cloth_rest": cloth, "start_pose": A_POSE}
    motion, n_lead = _motion(m, cfg, body.rest_joints(betas or None)[0], with_lead=True)
    if lead is not None:
        cut = max(0, n_lead - int(lead))
        motion = dataclasses.replace(motion, poses=motion.poses[cut:], trans=motion.trans[cut:])
        n_lead -= cut
    res = simulate(verts, mesh.faces, body, motion, betas=betas or None, settings=st, sim_python=sim_python, **kw)
    return res.frames[n_lead:].astype(np.float64), res.seconds_per_frame


def blender_resimulate(config: Path, dataset: Path, body, sim_python=None):
    """A function ``(sample_id, quality) -> (frames (T, N, 3), Blender seconds per simulated frame)`` that
    makes a dataset sample again as ``segadeform dataset make`` did (:func:`resimulate`: the settings of the
    attempt the sample was kept on) at another cloth quality.  ``run.quality_of(sample_id)``: the quality the
    dataset made it at."""
    from segadeform.dataset.config import load_dataset_config
    from segadeform.dataset.make import sample_plan
    from segadeform.dataset.store import load_sample

    cfg = load_dataset_config(config)

    def attempt(sid: str) -> int:
        return int(load_sample(dataset, sid).meta.get("attempt", 0))

    def run(sid: str, quality: int):
        return resimulate(cfg, dataset, body, sid, attempt=attempt(sid), quality=quality, sim_python=sim_python)

    def quality_of(sid: str) -> int:
        ps = next((p for p in sample_plan(cfg) if p.id == sid), None)
        g = cfg.garments[ps.garment] if ps is not None else None
        return cfg.attempt_settings(g, attempt(sid)).quality if g is not None else cfg.simulate.quality

    run.digest = cfg.digest()
    run.quality = cfg.simulate.quality
    run.quality_of = quality_of
    return run


def simulator_axis(sim: Callable, sid: str, stored: np.ndarray, qualities, reference_q: int, learned: dict) -> dict:
    """Blender at each of ``qualities`` and at ``reference_q`` on sample ``sid``: seconds per frame, mean and
    max vertex distance to the reference (cm); the ``learned`` predictions ({name: (frames, ms/frame 1
    thread, ms/frame all threads)}) against the same reference, each with its speed-up over every quality
    (Blender seconds per frame / the model's).  ``stored``: the dataset's frames, compared with this run
    at the dataset's quality (how repeatable the simulator is)."""
    t0 = time.perf_counter()
    ref, ref_s = sim(sid, reference_q)
    rows = {}
    for q in qualities:
        x, sec = sim(sid, q)
        d = np.linalg.norm(x - ref, axis=2)
        rows[str(q)] = {
            "quality": q,
            "s_per_frame": sec,
            "vertex_cm": 100 * d.mean(),
            "max_cm": 100 * d.max(),
            "frames": x,
        }
    d_stored = 100 * np.linalg.norm(stored - ref, axis=2)
    rows[str(reference_q)] = {
        "quality": reference_q,
        "s_per_frame": ref_s,
        "vertex_cm": 0.0,
        "max_cm": 0.0,
        "reference": True,
    }
    models = {}
    for n, (x, ms1, msn) in learned.items():
        d = np.linalg.norm(x - ref, axis=2)
        models[n] = {
            "vertex_cm": 100 * d.mean(),
            "max_cm": 100 * d.max(),
            "ms_per_frame": ms1,
            "ms_per_frame_all": msn,
            "speedup": {str(q): 1e3 * r["s_per_frame"] / ms1 for q, r in rows.items()},
            "speedup_all": {str(q): 1e3 * r["s_per_frame"] / msn for q, r in rows.items()},
        }
    repeat = {}
    for q, r in rows.items():
        if "frames" in r:
            repeat[q] = 100 * float(np.linalg.norm(r.pop("frames") - stored, axis=2).mean())
    return {
        "sample": sid,
        "reference_quality": reference_q,
        "qualities": rows,
        "learned": models,
        "stored_vs_reference_cm": float(d_stored.mean()),
        "stored_vs_rerun_cm": repeat,
        "seconds": time.perf_counter() - t0,
    }
