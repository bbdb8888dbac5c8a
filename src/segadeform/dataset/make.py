"""``segadeform dataset make``: plan, simulate, gate and store every sample, resumably and in parallel.

Layout of the output folder::

    DIR/config.toml             the config that made it (copied)
    DIR/garments/G-bK.obj       garment G made for body K (rest pose)
    DIR/samples/ID.npz|.json    kept samples (arrays, metadata)
    DIR/rejected/ID.json        samples the quality gate rejected, with the reasons
    DIR/log.jsonl               one line per finished sample (kept or rejected), appended

A sample is done when its ``samples/ID.json`` or ``rejected/ID.json`` exists;
a killed run simply starts again and skips those.  Sample ids are
``G__bK__M`` (garment, body index, motion).
"""

from __future__ import annotations

import concurrent.futures as cf
import dataclasses
import json
import shutil
import time
from pathlib import Path
from typing import Callable, Optional

import numpy as np

from ..body.model import BodyModel, load_body
from ..errors import SegadeformError
from ..garments import GARMENT_TYPES, make_garment
from ..io import Mesh, read_mesh, write_obj
from ..io.atomic import atomic_path
from ..motion import load_motion, make_motion, resample
from ..motion.motion import Motion
from .config import DatasetConfig, MotionEntry
from .quality import quality_check
from .store import Sample, save_sample

__all__ = ["PlannedSample", "sample_plan", "make_dataset", "DatasetSummary"]


@dataclasses.dataclass(frozen=True)
class PlannedSample:
    id: str
    garment: int
    body: int
    motion: int
    split: str


def sample_plan(cfg: DatasetConfig) -> list[PlannedSample]:
    """Every sample the config asks for, in a stable order (see the config's split rules)."""
    out = []
    bsplit = cfg.body_splits or ("train",) * len(cfg.bodies)
    for gi, g in enumerate(cfg.garments):
        for bi, _ in enumerate(cfg.bodies):
            for mi, m in enumerate(cfg.motions):
                if g.split == m.split == "test":
                    split = "test"
                elif g.split == m.split == bsplit[bi] == "train":
                    split = "train"
                elif not cfg.cross_splits:
                    continue
                elif g.split == "test":
                    split = "test-garment"
                elif m.split == "test":
                    split = "test-motion"
                else:
                    split = "test-body"
                out.append(PlannedSample(f"{g.name}__b{bi}__{m.name}", gi, bi, mi, split))
    return out


def _motion(m: MotionEntry, cfg: DatasetConfig, rest_joints=None) -> Motion:
    if m.kind is not None:
        return make_motion(m.kind, seconds=cfg.seconds, fps=cfg.fps, speed=m.speed, amplitude=m.amplitude, seed=m.seed)
    mo = load_motion(m.file, rest_joints=rest_joints, floor=True)
    if abs(mo.fps - cfg.fps) > 1e-9:
        mo = resample(mo, cfg.fps)
    a = min(int(round(m.start * cfg.fps)), mo.n_frames - 1)
    n = min(mo.n_frames - a, int(round(cfg.seconds * cfg.fps)))
    # the clip starts where the body stands: its root is moved to x = z = 0 at the clip's first frame
    trans = mo.trans[a:a + n] - np.array([mo.trans[a, 0], 0.0, mo.trans[a, 2]])
    return dataclasses.replace(mo, poses=mo.poses[a:a + n], trans=trans)


def _garment_file(root: Path, cfg: DatasetConfig, gi: int, bi: int, body: BodyModel) -> Path:
    g = cfg.garments[gi]
    p = root / "garments" / f"{g.name}-b{bi}.obj"
    if not p.is_file():
        if g.mhclo is not None:  # a MakeHuman garment: fitted to this body, 3 mm off the skin
            from ..garments.fit import fit_mhclo, push_off_body, read_mhclo

            binding = read_mhclo(g.mhclo)
            betas = cfg.bodies[bi] or None
            v = fit_mhclo(binding, body, betas)
            v, _ = push_off_body(v, body.shaped_vertices(betas)[0], body.faces, 0.003)
            faces = read_mesh(binding.obj_path()).faces
            write_obj(p, Mesh(vertices=v, faces=faces), header=f"MakeHuman garment {binding.name} (CC0), "
                                                                f"fitted by segadeform")
        else:
            gar = make_garment(g.kind, body, cfg.bodies[bi] or None, g.params)
            write_obj(p, Mesh(vertices=gar.vertices, faces=gar.faces), header=gar.header())
    return p


def _run_one(root: str, cfg: DatasetConfig, ps: PlannedSample, body_path: str, sim_python) -> dict:
    """Simulate and gate one sample (in a worker process); returns its log record."""
    from ..physics.blender import simulate

    t0 = time.perf_counter()
    root_p = Path(root)
    body = load_body(body_path)
    g, m = cfg.garments[ps.garment], cfg.motions[ps.motion]
    betas = cfg.bodies[ps.body]
    mesh = read_mesh(_garment_file(root_p, cfg, ps.garment, ps.body, body))
    motion = _motion(m, cfg, body.rest_joints(betas or None)[0])
    rec = {"id": ps.id, "split": ps.split, "garment": g.name, "kind": g.kind, "type": GARMENT_TYPES[g.kind],
           "body": ps.body, "motion": m.name, "vertices": len(mesh.vertices), "frames": motion.n_frames}
    try:
        st = cfg.simulate.replace(pin=g.pin) if g.pin else cfg.simulate
        res = simulate(mesh.vertices, mesh.faces, body, motion, betas=betas or None, settings=st,
                       sim_python=sim_python)
    except SegadeformError as e:
        rec.update(status="rejected", reasons=[f"simulation failed: {e}"], seconds=time.perf_counter() - t0)
        return rec
    posed = body.forward(motion.poses, betas or None, motion.trans).vertices
    contact = {}
    # strain against the cloth's own rest (the A-posed garment when the simulation rests there)
    strain_rest = res.cloth_rest if res.cloth_rest is not None else mesh.vertices
    q = quality_check(res.frames, strain_rest, mesh.faces, posed, body.faces, cfg.quality, contact=contact)
    rec.update(quality=q.to_dict(), seconds_per_frame=res.seconds_per_frame, blender=res.blender["blender_version"],
               sim_seconds=res.blender["simulate_seconds"], preroll_frames=res.preroll_frames)
    if q.ok:
        meta = dict(rec, status="kept", fps=motion.fps, betas=list(betas), settings=res.settings,
                    garment_params=dataclasses.asdict(g.params), config_digest=cfg.digest(),
                    blender_info=res.blender)
        save_sample(root_p, Sample(id=ps.id, rest=mesh.vertices, faces=mesh.faces,
                                   betas=np.asarray(betas, np.float64), poses=motion.poses, trans=motion.trans,
                                   frames=res.frames.astype(np.float32), meta=meta,
                                   contact_p=contact["closest"], contact_n=contact["normal"]))
        rec["status"] = "kept"
    else:
        rec.update(status="rejected", reasons=q.reasons)
        (root_p / "rejected").mkdir(exist_ok=True)
        with atomic_path(root_p / "rejected" / f"{ps.id}.json") as tmp:
            Path(tmp).write_text(json.dumps(rec, indent=1))
    rec["seconds"] = time.perf_counter() - t0
    return rec


@dataclasses.dataclass
class DatasetSummary:
    planned: int
    skipped: int
    kept: int
    rejected: int
    records: list


def make_dataset(cfg: DatasetConfig, out: Path, *, body_path: Path, jobs: int = 1, sim_python=None,
                 progress: Optional[Callable[[dict], None]] = None, limit: Optional[int] = None) -> DatasetSummary:
    """Make (or continue) the dataset ``cfg`` in ``out``; see the module docstring."""
    out = Path(out)
    (out / "samples").mkdir(parents=True, exist_ok=True)
    (out / "garments").mkdir(exist_ok=True)
    if cfg.path is not None:
        shutil.copyfile(cfg.path, out / "config.toml")
    plan = sample_plan(cfg)
    # held-out samples first, then body-major, motion, garment: a run stopped early still has
    # every garment and motion of the bodies it reached, and a complete test split
    order = sorted(plan, key=lambda p: (p.split == "train", p.body, p.motion, p.garment))
    todo = [p for p in order if not ((out / "samples" / f"{p.id}.json").is_file()
                                    or (out / "rejected" / f"{p.id}.json").is_file())]
    skipped = len(plan) - len(todo)
    if limit is not None:
        todo = todo[:limit]
    body = load_body(body_path)
    for gi, bi in sorted({(p.garment, p.body) for p in todo}):  # garments first, in this process: no races
        _garment_file(out, cfg, gi, bi, body)
    records = []
    log = open(out / "log.jsonl", "a")
    try:
        def done(rec):
            records.append(rec)
            log.write(json.dumps(rec) + "\n")
            log.flush()
            if progress is not None:
                progress(rec)

        if jobs <= 1:
            for p in todo:
                done(_run_one(str(out), cfg, p, str(body_path), sim_python))
        else:
            with cf.ProcessPoolExecutor(max_workers=jobs) as ex:
                futs = [ex.submit(_run_one, str(out), cfg, p, str(body_path), sim_python) for p in todo]
                for f in cf.as_completed(futs):
                    done(f.result())
    finally:
        log.close()
    kept = sum(r["status"] == "kept" for r in records)
    return DatasetSummary(planned=len(plan), skipped=skipped, kept=kept, rejected=len(records) - kept, records=records)
