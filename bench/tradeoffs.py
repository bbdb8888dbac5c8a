"""What accuracy costs in time: every knob of the learned runtime, and the simulator's own quality, in one run.

    .venv/bin/python bench/tradeoffs.py DATASET --package PKG [--model NAME=SPEC ...] -o docs
        [--split test] [--threads-all N] [--repeats 3] [--sim SAMPLE_ID | --no-sim]
        [--sim-config DATASET_PLAN.toml] [--sim-qualities 2,5,10,20] [--sim-reference 40]
    .venv/bin/python bench/tradeoffs.py DATASET --package PKG -o docs --redraw   # docs again from the JSON

On the held-out (``--split``) samples of DATASET, every row is measured on the same samples, in the same
process, one after another (errors against the Blender simulation stored in the dataset):

* effects: all on; no wrinkles; no dynamics; neither; dual-quaternion skinning (all effects);
* collisions: the runtime's push-out (:class:`BodyCollider`, built once, frames in batches as
  ``segadeform run`` does) at 2, 4 and 8 mm on "all effects" and "no wrinkles", at 4 mm on every other
  effects, precision and model row;
* precision: fp16 weights (float32 arithmetic) and int8 dynamic quantisation (``segadeform quantize``);
* batch: frames per deformer call (8 elsewhere, the runtime's default);
* K: neighbours per vertex in the garment graph, made at precompute (``neighbour_graph(k=K)``; the
  models were trained at K = the garment's largest valence, capped at 16);
* N*: furthest-point samples of the garment descriptor, its eigenvalues rescaled to the model's length
  (:func:`segadeform.geometry.descriptor.rescale_descriptor`);
* garment resolution: the model run on a decimated and a subdivided copy of each garment
  (:mod:`segadeform.garments.resample`), the result carried to the full-resolution vertices by a
  :class:`SurfaceMap` and compared there;
* models: each ``NAME=SPEC`` (e.g. width/depth variants trained on the same data);
* cloth: the runtime's cloth stage (:mod:`segadeform.body.cloth`, as ``segadeform run --effects=+cloth``) on
  "all effects" at 1, 2, 4, 8 and 16 sweeps per frame (the other knobs at their defaults) and at two other
  stiffnesses, contact at 4 mm (``--cloth-iterations``, ``--cloth-stiffness``);
* presets: ``segadeform run --quality`` (:mod:`segadeform.settings.presets`), each the row with its effects and margin
  (and cloth settings).

Every row: ms/frame at one onnxruntime thread and at ``--threads-all`` threads (best of ``--repeats``),
deformer calls and push-out only (plus carrying results back to full resolution for the resolution rows);
"setup" is the once-per-garment cost (precompute and encoder).  The simulator's axis: one sample
(``--sim``) re-simulated by Blender at several cloth qualities and at a reference quality, each
quality's seconds per frame and its distance to the reference, the learned presets' distance to the
same reference and how many times faster they run, all in this run.

Writes ``accuracy-vs-time.md`` (tables, frontier, presets), ``.json`` and ``.png``/``.svg`` (error
against ms/frame for both thread counts, the Pareto frontier, and the simulator's quality axis).
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import os
import platform
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Callable, Optional

import numpy as np

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))

#: effects rows: name -> (complete effects list for the package, what it is)
EFFECTS_ROWS = {
    "all effects": ("lbs,dynamics,wrinkles", "lbs + dynamics + wrinkles"),
    "no wrinkles": ("lbs,dynamics", "-wrinkles"),
    "no dynamics": ("lbs,wrinkles", "-dynamics"),
    "static, no wrinkles": ("lbs", "-dynamics,-wrinkles"),
    "dqs": ("dqs,dynamics,wrinkles", "dqs skinning, all effects"),
}
DEFAULT_BATCH = 8


def frontier(points: dict[str, tuple[float, float]]) -> list[str]:
    """Names of the points (ms, error) no other point beats on both (ties kept), fastest first."""
    out = []
    for n, (t, e) in points.items():
        if not any((t2 <= t and e2 <= e) and (t2 < t or e2 < e) for m, (t2, e2) in points.items() if m != n):
            out.append(n)
    return sorted(out, key=lambda n: points[n][0])


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
    margin: Optional[float] = None
    batch: int = DEFAULT_BATCH
    k: Optional[int] = None
    n_star: Optional[int] = None
    res: Optional[str] = None
    base: Optional[str] = None
    #: the cloth stage's settings (their text form, "default" for the defaults) on ``base``'s prediction
    cloth: Optional[str] = None


def cloth_key(e) -> Optional[str]:
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
    """A model row's setting: its width and depth when the spec is a package."""
    mpath = Path(spec) / "manifest.json"
    if not mpath.is_file():
        return spec
    c = json.loads(mpath.read_text())["config"]
    return (f"hidden {c['hidden']}, {c['enc_layers']}+{c['dec_layers']} graph blocks, {c.get('heads', '?')} heads, "
            f"window T = {c.get('window', '?')} ({spec})")


def match_presets(rows: dict, pkg: str) -> dict:
    """``{preset: row name}``: the row of package ``pkg`` with each preset's effects and margin."""
    from segadeform.settings.presets import QUALITY_PRESETS

    out = {}
    for name, p in QUALITY_PRESETS.items():
        key = preset_key(p.effects)
        hit = [n for n, r in rows.items() if r["spec"] == pkg and r["knob"] in ("effects", "collisions", "cloth", "preset")
               and (r["effects"], r["margin"], r.get("cloth")) == key]
        if not hit:
            raise SystemExit(f"preset {name} ({key}) was not measured in this run")
        out[name] = hit[0]
    return out


def plan_rows(pkg: str, int8: Optional[str], models: dict, *, fp16: Optional[str] = None, margins=(0.002, 0.004, 0.008), ks=(4, 6, 12),
              n_stars=(8, 16, 64), batches=(1, 32), resolutions=("1/4", "1/2", "4x"),
              cloth_iterations=(1, 2, 4, 8, 16), cloth_stiffness=(0.5, 0.2)) -> tuple[list[Row], dict]:
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
            rows.append(dataclasses.replace(r, name=f"{r.name} + push-out {_mm(m)}", knob="collisions",
                                            setting=f"{r.name}, push-out at {_mm(m)}", margin=m, base=r.name))
    from segadeform.settings.cloth import ClothSettings

    cloths = [f"iterations={k}" if k != ClothSettings().iterations else "default" for k in cloth_iterations] + \
        [f"stiffness={k:g}" for k in cloth_stiffness]
    for r in [r for r in rows if r.name == "all effects"]:
        for c in cloths:
            rows.append(dataclasses.replace(r, name=f"{r.name} + cloth {c}", knob="cloth",
                                            setting=f"{r.name}, the cloth stage ({c}), contact at 4 mm", margin=0.004,
                                            base=r.name, cloth=c))
    presets = {}
    for name, p in QUALITY_PRESETS.items():
        key = preset_key(p.effects)
        hit = [r.name for r in rows if r.spec == pkg and r.knob in ("effects", "collisions", "cloth")
               and (r.effects, r.margin, r.cloth) == key]
        if hit:
            presets[name] = hit[0]
        else:
            base = [r.name for r in rows if r.spec == pkg and r.knob == "effects" and r.effects == key[0]]
            rows.append(Row(f"preset {name}", "preset", f"--quality {name}", pkg, key[0], margin=key[1],
                            base=base[0] if base and key[1] is not None else None, cloth=key[2]))
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
    from segadeform.garments.resample import decimate, subdivide

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
        from segadeform.garments.resample import SurfaceMap
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


def measure(dataset: Path, body, rows: list[Row], *, split: str, threads_all: int, repeats: int,
            keep: tuple = (), only: tuple = (), progress: Callable[[str], None] = lambda s: None) -> dict:
    """Every row on every sample of ``split`` (or those of them in ``only``): mean metrics and times, and the
    predictions of the samples in ``keep`` (for the simulator's axis)."""
    from segadeform.body.collision import BodyCollider
    from segadeform.dataset.store import list_samples, load_sample
    from segadeform.geometry.laplacian import SpectralBasis
    from segadeform.settings.cloth import ClothSettings
    from segadeform.runtime.predictor import PackagePredictor
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
                    x = cloth_frames(preds[r.base], s, ref, body,
                                     ClothSettings.parse("" if r.cloth == "default" else r.cloth), margin=r.margin,
                                     batch=r.batch)
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
        out[r.name].update(knob=r.knob, setting=r.setting, spec=r.spec, effects=r.effects, margin=r.margin,
                           batch=r.batch, k=r.k, n_star=r.n_star, res=r.res, cloth=r.cloth)
    return {"rows": out, "samples": ids, "per_sample": per_sample, "kept": kept, "metrics": list(METRICS)}


def _blender_resimulate(config: Path, dataset: Path, body, sim_python=None):
    """A function ``(sample_id, quality) -> (frames (T, N, 3), Blender seconds per simulated frame)`` that
    makes a dataset sample again as ``segadeform dataset make`` did (its garment files, the motion with
    its simulated lead, the config's settings) at another cloth quality."""
    from segadeform.dataset.config import load_dataset_config
    from segadeform.dataset.make import _motion, sample_plan
    from segadeform.io import read_mesh
    from segadeform.physics.blender import A_POSE, simulate

    cfg = load_dataset_config(config)

    def run(sid: str, quality: int):
        ps = next((p for p in sample_plan(cfg) if p.id == sid), None)
        if ps is None:
            raise SystemExit(f"{sid} is not a sample of {config}")
        g, m, betas = cfg.garments[ps.garment], cfg.motions[ps.motion], cfg.bodies[ps.body]
        gfile = dataset / "garments" / f"{g.name}-b{ps.body}.obj"
        cfile = gfile.with_name(gfile.stem + ".cloth.obj")
        mesh = read_mesh(gfile)
        kw = {"cloth_rest": read_mesh(cfile).vertices, "start_pose": A_POSE} if cfile.is_file() else {}
        motion, lead = _motion(m, cfg, body.rest_joints(betas or None)[0], with_lead=True)
        st = (cfg.simulate.replace(pin=g.pin) if g.pin else cfg.simulate).replace(quality=int(quality))
        res = simulate(mesh.vertices, mesh.faces, body, motion, betas=betas or None, settings=st,
                       sim_python=sim_python, **kw)
        return res.frames[lead:].astype(np.float64), res.seconds_per_frame

    run.digest = cfg.digest()
    run.quality = cfg.simulate.quality
    return run


def simulator_axis(sim: Callable, sid: str, stored: np.ndarray, qualities, reference_q: int,
                   learned: dict) -> dict:
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
        rows[str(q)] = {"quality": q, "s_per_frame": sec, "vertex_cm": 100 * d.mean(), "max_cm": 100 * d.max(),
                        "frames": x}
    d_stored = 100 * np.linalg.norm(stored - ref, axis=2)
    rows[str(reference_q)] = {"quality": reference_q, "s_per_frame": ref_s, "vertex_cm": 0.0, "max_cm": 0.0,
                              "reference": True}
    models = {}
    for n, (x, ms1, msn) in learned.items():
        d = np.linalg.norm(x - ref, axis=2)
        models[n] = {"vertex_cm": 100 * d.mean(), "max_cm": 100 * d.max(), "ms_per_frame": ms1,
                     "ms_per_frame_all": msn,
                     "speedup": {str(q): 1e3 * r["s_per_frame"] / ms1 for q, r in rows.items()},
                     "speedup_all": {str(q): 1e3 * r["s_per_frame"] / msn for q, r in rows.items()}}
    repeat = {}
    for q, r in rows.items():
        if "frames" in r:
            repeat[q] = 100 * float(np.linalg.norm(r.pop("frames") - stored, axis=2).mean())
    return {"sample": sid, "reference_quality": reference_q, "qualities": rows, "learned": models,
            "stored_vs_reference_cm": float(d_stored.mean()), "stored_vs_rerun_cm": repeat,
            "seconds": time.perf_counter() - t0}


def _training_note(rows: dict) -> str:
    """' Training took: NAME N s, ...' from each model row's run folder (``train.json`` beside its package)."""
    done = []
    for n, r in rows.items():
        if r["knob"] != "model":
            continue
        tj = Path(r["spec"]).parent / "train.json"
        if tj.is_file():
            d = json.loads(tj.read_text())
            done.append(f"{n} {d['train_seconds']:.0f} s")
    return f" Training took (one thread, other work on the machine): {', '.join(done)}." if done else ""


def _fmt(k, v):
    return f"{v:.1f}" if k.startswith("ms_per_frame") or k == "setup_ms" else f"{v:.3f}"


def write_docs(res: dict, out: Path, *, command: str, seconds: float, threads_all: int, load: tuple,
               presets: dict, sim: Optional[dict], sim_error: str, split: str, dataset: Path,
               git: Optional[str] = None) -> list[str]:
    """The markdown, JSON and plots; returns the markdown lines."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from segadeform.settings.presets import QUALITY_PRESETS

    rows = res["rows"]
    pts1 = {n: (m["ms_per_frame"], m["vertex_cm"]) for n, m in rows.items()}
    ptsn = {n: (m["ms_per_frame_all"], m["vertex_cm"]) for n, m in rows.items()}
    front, front_n = frontier(pts1), frontier(ptsn)
    metrics = res["metrics"]
    cols = list(metrics) + ["ms_per_frame", "ms_per_frame_all", "setup_ms"]
    head = ["knob", "setting"] + [c if c != "ms_per_frame_all" else f"ms_per_frame_{threads_all}t" for c in cols] \
        + ["frontier"]
    lines = ["| " + " | ".join(head) + " |", "|---" * len(head) + "|"]
    for n, m in sorted(rows.items(), key=lambda kv: kv[1]["ms_per_frame"]):
        mark = "yes" if n in front else ""
        if n in front_n:
            mark += (", " if mark else "") + f"{threads_all}t"
        lines.append(f"| {m['knob']} | {n} | " + " | ".join(_fmt(k, m[k]) for k in cols) + f" | {mark} |")
    if git is None:
        git = subprocess.run(["git", "rev-parse", "--short", "HEAD"], cwd=REPO, capture_output=True,
                             text=True).stdout.strip()
        dirty = subprocess.run(["git", "status", "--porcelain"], cwd=REPO, capture_output=True,
                               text=True).stdout.strip()
        git += " (with uncommitted changes)" if dirty else ""
    ptab = ["| preset | effects | push-out | row | vertex_cm | penetration_pct | ms/frame (1 thread) | fps (1 thread) "
            f"| ms/frame ({threads_all} threads) | fps ({threads_all} threads) |", "|---" * 10 + "|"]
    for name, rn in presets.items():
        p, m = QUALITY_PRESETS[name], rows[rn]
        e = p.effects
        ptab.append(f"| {name} | {effects_key(e) + ('+cloth' if e.cloth else '')} | "
                    f"{_mm(e.collision_margin) if e.collisions or e.cloth else 'off'} | {rn} | "
                    f"{m['vertex_cm']:.3f} | {m['penetration_pct']:.3f} | {m['ms_per_frame']:.1f} | "
                    f"{1e3 / m['ms_per_frame']:.0f} | {m['ms_per_frame_all']:.1f} | "
                    f"{1e3 / m['ms_per_frame_all']:.0f} |")
    n_samples = len(res["samples"])
    md = [f"# Accuracy against time ({split} split of `{dataset.name}`, {n_samples} samples)", "",
          f"Made by `{command}` at {git}; {seconds:.0f} s "
          f"({seconds / 60:.1f} min) on {platform.processor() or platform.machine()} with {os.cpu_count()} "
          f"CPU cores; load average {load[0]:.2f} at the start and {load[1]:.2f} at the end (other work shared "
          "the machine when it is above ~0: the times are this run's, the ratios between rows hold better "
          "than the absolute values).", "",
          "Errors are against the Blender simulation stored in the dataset; units: vertex and band errors cm, "
          "normal degrees, edge mm, penetration % of vertices deeper than 2 mm inside the body, jitter mm/frame². "
          f"`ms_per_frame` is one onnxruntime thread, `ms_per_frame_{threads_all}t` {threads_all} threads "
          "(best of the repeats): the deformer calls and the collision push-out (the runtime's BodyCollider, "
          "frames in batches of 8), not the once-per-garment `setup_ms` (precompute and encoder) nor writing. "
          "LBS is numpy (both columns are one timing); LBS is the body's skinning weights moved to the "
          "garment, no learned part.", "",
          f"The dataset is `{dataset}` (its plan: `{dataset}/config.toml`, made by `segadeform dataset make`); "
          f"its {split} split is what the models never trained on (garment kinds, motion families and a body "
          "shape held out by the plan).", "",
          "\n".join(lines), "",
          f"Pareto frontier at one thread (fastest first): {', '.join(front)}.", "",
          f"Pareto frontier at {threads_all} threads: {', '.join(front_n)}.", "",
          "## Presets", "",
          "`segadeform run --quality fast|balanced|best` (`src/segadeform/settings/presets.py`) picks these rows; "
          "`--effects=+name/-name` changes a preset, a complete `--effects` list with `--quality` is an error. "
          "Frames per second are 1000 / ms per frame (deformer and push-out; setup and writing excluded).", "",
          "\n".join(ptab), ""]
    for name, p in QUALITY_PRESETS.items():
        md.append(f"* **{name}**: {p.why}.")
    md += ["", "## The knobs", "",
           "* **threads**: every row at one thread and at all of this machine's threads; the predictions agree "
           "(largest difference over rows: "
           f"{max(v.get('threads_max_diff_mm', 0.0) for s in res['per_sample'].values() for v in s.values()):.2g}"
           " mm).",
           "* **batch**: frames per deformer call; the same prediction (checked to 1e-5 m; its errors are "
           "those of `all effects`), only the time differs.",
           "* **K**: neighbours kept per vertex in the garment graph (the nearest by rest edge length). The "
           "models were trained with K = the garment's largest valence capped at 16, which is 8 on these "
           "garments (`all effects`); K = 12 adds only padding.",
           "* **N\\***: descriptor samples; the eigenvalues at N* are rescaled to the model's 32 "
           "(`rescale_descriptor`). N* changes only `setup_ms` (one geodesic solve per sample), not ms/frame.",
           "* **garment resolution**: each garment decimated (shortest-edge collapse) or subdivided (midpoint), "
           "the model run there and its frames carried to the full-resolution vertices (barycentric "
           "place on the nearest triangle plus the rest offset along its normal: `garments/resample.py`); "
           "errors on the full-resolution garment, ms/frame including the carry, setup including the resampling.",
           "* **collisions**: the push-out at the margin named, on the row named.",
           "* **cloth**: the runtime's cloth stage (`segadeform run --effects=+cloth --cloth ...`: stretch limit, "
           "contact with neighbours following, inertia and gravity, attachment to the network's frame; "
           "`src/segadeform/body/_cloth.c`) on the row named, contact at 4 mm, its knobs at their defaults but the "
           "one named (`iterations`: sweeps per frame; `stiffness`: of the stretch limit); ms/frame includes its "
           "per-garment setup spread over the sample's frames.",
           "* **models**: variants of the package's recipe in width, depth, heads or window T (the setting "
           "column, read from each package's manifest), each trained on the training split of the same dataset "
           "with the same steps and seed (`segadeform train CONFIG -o runs/NAME --dataset DATASET --threads 1`, "
           "then `segadeform export runs/NAME/model.pt -o runs/NAME/pkg`)." + _training_note(rows), ""]
    if sim is not None:
        md += ["## The simulator's quality axis", "",
               f"Sample `{sim['sample']}` made again by Blender (the dataset config's settings, its garment "
               f"files and the motion with its simulated lead) at cloth quality (steps per frame) "
               f"{', '.join(q for q, r in sim['qualities'].items() if not r.get('reference'))} and at "
               f"{sim['reference_quality']}, the reference; {sim['seconds']:.0f} s of this run. Seconds per frame "
               "are Blender's own (pre-roll frames included, its own threads); errors are the mean (max) vertex "
               "distance to the reference over the sample's frames. The learned rows are the same run's "
               "predictions of this sample against the same reference (every row is in the JSON); "
               "speed-up = Blender's s/frame at the "
               "quality named / the model's.", "",
               "| simulator | s/frame | vertex_cm vs reference | max_cm |", "|---|---|---|---|"]
        for q, r in sim["qualities"].items():
            md.append(f"| Blender quality {q}{' (reference)' if r.get('reference') else ''} | "
                      f"{r['s_per_frame']:.3f} | {r['vertex_cm']:.3f} | {r['max_cm']:.2f} |")
        dq = str(sim.get("dataset_quality", ""))
        md += ["", f"| learned | ms/frame (1 thread) | vertex_cm vs reference | max_cm | speed-up vs quality {dq} "
               f"(1 thread) | speed-up vs quality {dq} ({threads_all} threads) | speed-up vs reference (1 thread) |",
               "|---|---|---|---|---|---|---|"]
        shown = {"lbs": "lbs", "all effects": "all effects"}
        shown.update({rn: f"{name} ({rn})" for name, rn in presets.items()})
        shown = {n: label for n, label in shown.items() if n in sim["learned"]}
        for n, label in shown.items():
            r = sim["learned"][n]
            md.append(f"| {label} | {r['ms_per_frame']:.1f} | {r['vertex_cm']:.3f} | {r['max_cm']:.2f} | "
                      f"{r['speedup'].get(dq, float('nan')):.0f}x | {r['speedup_all'].get(dq, float('nan')):.0f}x | "
                      f"{r['speedup'][str(sim['reference_quality'])]:.0f}x |")
        md += ["", f"The dataset's stored frames (quality {dq}) are {sim['stored_vs_reference_cm']:.3f} cm from the "
               "reference; a re-run at each quality is this far from the stored frames (cm; 0 at the dataset's "
               "quality when Blender repeats itself exactly): "
               + ", ".join(f"quality {q}: {v:.3f}" for q, v in sim["stored_vs_rerun_cm"].items()) + ".", ""]
    elif sim_error:
        md += ["## The simulator's quality axis", "", f"Not measured in this run: {sim_error}.", ""]
    md += ["![error against time](accuracy-vs-time.png)", ""]
    out.mkdir(parents=True, exist_ok=True)
    from segadeform.io.atomic import atomic_path

    with atomic_path(out / "accuracy-vs-time.md") as tmp:
        Path(tmp).write_text("\n".join(md))
    data = {"rows": rows, "metrics": metrics, "frontier": front, f"frontier_{threads_all}t": front_n,
            "presets": presets,
            "samples": res["samples"], "per_sample": res["per_sample"], "simulator": sim, "seconds": seconds,
            "threads_all": threads_all, "load_average": list(load), "command": command, "git": git,
            "simulator_error": sim_error}
    with atomic_path(out / "accuracy-vs-time.json") as tmp:
        Path(tmp).write_text(json.dumps(data, indent=1, default=float))
    fig, axes = plt.subplots(1, 2 if sim else 1, figsize=(14 if sim else 8, 6), squeeze=False,
                             gridspec_kw={"width_ratios": [3, 2]} if sim else None)
    ax = axes[0, 0]
    # rows far above the rest (more than 1.5x LBS's error) sit on the top edge, named, so the rest can be read
    errs = sorted(e for _, e in pts1.values())
    cap = max(1.5 * rows["lbs"]["vertex_cm"], errs[0] * 1.3) if "lbs" in rows else errs[-1] * 1.05
    top = min(cap, errs[-1] * 1.02)
    clip = lambda e: min(e, top)  # noqa: E731
    knobs = sorted({m["knob"] for m in rows.values()})
    for i, k in enumerate(knobs):
        names = [n for n, m in rows.items() if m["knob"] == k]
        c = f"C{i % 10}"
        ax.scatter([pts1[n][0] for n in names], [clip(pts1[n][1]) for n in names], color=c, label=k, s=18)
        ax.scatter([ptsn[n][0] for n in names], [clip(ptsn[n][1]) for n in names], facecolors="none", edgecolors=c,
                   s=18)
        for n in names:
            ax.plot([pts1[n][0], ptsn[n][0]], [clip(pts1[n][1]), clip(ptsn[n][1])], color=c, lw=0.4)
    named = set(front) | {"lbs", "all effects"} | {n for n, m in rows.items() if m["knob"] in ("model",)}
    off = 0
    for n, (t, e) in pts1.items():
        if e > top:
            off += 1
            right = t > np.sqrt(min(x for x, _ in pts1.values()) * max(x for x, _ in pts1.values()))
            ax.annotate(f"{n}: {e:.2f} cm (off scale)", (t, top), xytext=(-3 if right else 3, -4 - 7 * off),
                        textcoords="offset points", fontsize=5, ha="right" if right else "left")
        elif n in named:
            ax.annotate(n, (t, e), fontsize=6)
    ax.plot([pts1[n][0] for n in front], [pts1[n][1] for n in front], "k--", lw=0.8, label="frontier (1 thread)")
    for i, (name, rn) in enumerate(presets.items()):
        ax.annotate(name, (pts1[rn][0], clip(pts1[rn][1])), xytext=(-10 + 14 * i, -12 - 9 * (i % 2)),
                    textcoords="offset points", fontsize=8, weight="bold")
    ax.set_xscale("log")
    ax.set_ylim(min(errs) - 0.1, top + 0.1)
    ax.set_xlabel(f"ms per frame (filled: 1 thread, hollow: {threads_all} threads)")
    ax.set_ylabel("mean vertex error (cm) vs the simulation")
    ax.set_title(f"{split} split of {dataset.name}, {n_samples} samples (every row in the table; frontier, "
                 "presets and models named)", fontsize=9)
    ax.legend(fontsize=7, loc="center right")
    if sim:
        ax = axes[0, 1]
        qs = [(q, r) for q, r in sim["qualities"].items()]
        ax.plot([1e3 * r["s_per_frame"] for _, r in qs], [r["vertex_cm"] for _, r in qs], "o-", label="Blender")
        for q, r in qs:
            ax.annotate(f"q{q}", (1e3 * r["s_per_frame"], r["vertex_cm"]), fontsize=7)
        for n in shown:
            r = sim["learned"][n]
            ax.scatter([r["ms_per_frame"]], [r["vertex_cm"]], marker="s", s=18)
            ax.annotate(shown[n].split(" (")[0], (r["ms_per_frame"], r["vertex_cm"]), xytext=(3, 3),
                        textcoords="offset points", fontsize=7)
        ax.set_xscale("log")
        ax.set_xlabel("ms per frame (Blender: its own threads; learned: 1 thread)")
        ax.set_ylabel(f"mean vertex distance (cm) to Blender quality {sim['reference_quality']}")
        ax.set_title(f"simulator quality: {sim['sample']}", fontsize=9)
    fig.tight_layout()
    fig.savefig(out / "accuracy-vs-time.png", dpi=90)
    fig.savefig(out / "accuracy-vs-time.svg")
    plt.close(fig)
    return md


def main(argv=None, *, _simulate: Optional[Callable] = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("dataset", type=Path)
    ap.add_argument("--package", type=Path, required=True)
    ap.add_argument("--model", action="append", default=[], help="NAME=SPEC, repeatable")
    ap.add_argument("--split", default="test")
    ap.add_argument("--threads-all", type=int, default=os.cpu_count() or 1)
    ap.add_argument("--repeats", type=int, default=3, help="timed runs per row and sample (the best counts)")
    ap.add_argument("--ks", default="4,6,12")
    ap.add_argument("--n-stars", default="8,16,64")
    ap.add_argument("--batches", default="1,32")
    ap.add_argument("--resolutions", default="1/4,1/2,4x")
    ap.add_argument("--cloth-iterations", default="1,2,4,8,16", help="the cloth stage's sweeps per frame, one row each")
    ap.add_argument("--cloth-stiffness", default="0.5,0.2", help="its other stiffnesses, one row each")
    ap.add_argument("--no-int8", action="store_true")
    ap.add_argument("--no-fp16", action="store_true")
    ap.add_argument("--samples", default="", help="comma-separated sample ids (default: the whole split)")
    ap.add_argument("--sim", help="sample id for the simulator's quality axis (default: the test sample with "
                                  "the fewest vertices x frames)")
    ap.add_argument("--no-sim", action="store_true")
    ap.add_argument("--sim-config", type=Path, default=REPO / "samples" / "datasets" / "continuum.toml")
    ap.add_argument("--sim-qualities", default="2,5,10,20")
    ap.add_argument("--sim-reference", type=int, default=40)
    ap.add_argument("--redraw", action="store_true",
                    help="write the docs again from OUTPUT/accuracy-vs-time.json (e.g. after the preset table "
                         "changed) without measuring; the recorded command and duration stay")
    ap.add_argument("-o", "--output", type=Path, required=True)
    a = ap.parse_args(argv)
    if a.redraw:
        d = json.loads((a.output / "accuracy-vs-time.json").read_text())
        res = {"rows": d["rows"], "samples": d["samples"], "per_sample": d["per_sample"], "metrics": d["metrics"]}
        sim = d.get("simulator")
        md = write_docs(res, a.output, command=d["command"], seconds=d["seconds"], threads_all=d["threads_all"],
                        load=tuple(d["load_average"]), presets=match_presets(d["rows"], str(a.package)), sim=sim,
                        sim_error=d.get("simulator_error", ""), split=a.split, dataset=a.dataset,
                        git=d.get("git"))
        print("\n".join(md))
        return 0

    from segadeform.body import load_body
    from segadeform.dataset.store import list_samples, load_sample
    from segadeform.export.precision import convert_package

    ints = lambda t: tuple(int(x) for x in t.split(",") if x.strip())  # noqa: E731
    body = load_body(REPO / "samples" / "bodies" / "default_body.npz")
    pkg = str(a.package)
    models = {}
    for m in a.model:
        n, eq, s = m.partition("=")
        if not eq:
            raise SystemExit(f"--model must be NAME=SPEC, got {m!r}")
        models[n] = s
    load0 = os.getloadavg()[0]
    t0 = time.perf_counter()
    sim_sid = None
    if not a.no_sim:
        ids = [i for i in list_samples(a.dataset, a.split) if not a.samples or i in a.samples.split(",")]
        if a.sim:
            sim_sid = a.sim
        else:
            sizes = {i: load_sample(a.dataset, i) for i in ids}
            sim_sid = min(ids, key=lambda i: (sizes[i].frames.shape[0] * sizes[i].frames.shape[1], i))
    with tempfile.TemporaryDirectory() as tmp:
        q8 = None if a.no_int8 else str(convert_package(pkg, Path(tmp) / "int8", "int8"))
        h16 = None if a.no_fp16 else str(convert_package(pkg, Path(tmp) / "fp16", "fp16-weights"))
        rows, presets = plan_rows(pkg, q8, models, fp16=h16, ks=ints(a.ks), n_stars=ints(a.n_stars), batches=ints(a.batches),
                                  resolutions=tuple(x for x in a.resolutions.split(",") if x.strip()),
                                  cloth_iterations=ints(a.cloth_iterations),
                                  cloth_stiffness=tuple(float(x) for x in a.cloth_stiffness.split(",") if x.strip()))
        res = measure(a.dataset, body, rows, split=a.split, threads_all=a.threads_all, repeats=a.repeats,
                      keep=(sim_sid,) if sim_sid else (), only=tuple(x for x in a.samples.split(",") if x),
                      progress=lambda sid: print(f"  {sid}", file=sys.stderr))
    sim, sim_error = None, "" if not a.no_sim else "--no-sim"
    if sim_sid:
        try:
            run = _simulate or _blender_resimulate(a.sim_config, a.dataset, body)
            s = load_sample(a.dataset, sim_sid)
            if getattr(run, "digest", None) and s.meta.get("config_digest") not in (None, run.digest):
                print(f"note: {sim_sid} was made from another version of {a.sim_config}", file=sys.stderr)
            kept = res["kept"][sim_sid]
            learned = {n: (x, *tm[:2]) for n, (x, tm) in kept.items()}  # every row: presets may change later
            sim = simulator_axis(run, sim_sid, s.frames.astype(np.float64), ints(a.sim_qualities), a.sim_reference,
                                 learned)
            sim["dataset_quality"] = getattr(run, "quality", s.meta.get("settings", {}).get("segadeform", {})
                                             .get("quality", ""))
        except Exception as e:  # the simulator is optional: a machine without it still gets the rest
            sim_error = f"{type(e).__name__}: {e}"
            print(f"simulator axis not measured: {sim_error}", file=sys.stderr)
    seconds = time.perf_counter() - t0
    res.pop("kept")
    shown = [str(a.dataset), "--package", pkg] + [x for m in a.model for x in ("--model", m)] + ["-o", str(a.output)]
    for flag, val, default in (("--split", a.split, "test"), ("--repeats", a.repeats, 3), ("--samples", a.samples, ""),
                               ("--threads-all", a.threads_all, os.cpu_count() or 1)):
        if val != default:
            shown += [flag, str(val)]
    md = write_docs(res, a.output, command=".venv/bin/python bench/tradeoffs.py " + " ".join(shown),
                    seconds=seconds, threads_all=a.threads_all, load=(load0, os.getloadavg()[0]), presets=presets,
                    sim=sim, sim_error=sim_error, split=a.split, dataset=a.dataset)
    print("\n".join(md))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
