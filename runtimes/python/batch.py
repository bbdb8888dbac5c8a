"""``segadeform batch``: many garments x motions through the runtime, on an executor.

A jobs file (TOML; relative paths are relative to it)::

    [batch]
    output = "../../out/batch"     # a folder or an fsspec URL (s3://bucket/prefix, ...)
    format = "pc2"                 # pc2 | obj-seq | xdmf | abc | usd (default pc2)
    model = "../models/default"    # optional (default: the shipped model)
    body = "../bodies/default_body.npz"   # optional (default: the shipped body)
    effects = "dqs,collisions"     # optional, as `run --effects` (default: every effect)
    # quality = "best"             # optional, as `run --quality` (effects then takes +name/-name changes)
    # collision_margin = 0.004     # optional, as `run --collision-margin` (metres)
    # cloth_iterations = 8         # optional cloth stage knobs, as `run --cloth` (cloth_<knob>)
    up = "y"                       # y | z
    units = "m"                    # as `run --output-units`: m | dm | cm | mm | inch | ft or metres per unit
    resolution = 1.0               # as `run --resolution`: share of each garment's vertices the model runs on
    frames_per_call = 8            # frames per deformer call (`run --batch`)

    [[garments]]
    mesh = "../garments/skirt.obj"
    name = "skirt"                 # optional: the file's stem
    betas = [0.0, 0.5]             # optional body shape for this garment

    [[motions]]
    file = "../motions/walk.npz"   # a file (.npz, .bvh, .amc, .glb, .fbx through Blender) ...
    # kind = "walk"                # ... or a procedural kind, with seconds / speed / amplitude / seed
    name = "walk"                  # optional: the file's stem or the kind
    fps = 30.0                     # optional: resample to this rate
    frames = "0:60"                # optional frame range A:B

Every garment x motion is a job ``GARMENT__MOTION``.  A job is a function of its spec alone: it
runs in a scratch folder, commits its output to ``OUTPUT/GARMENT__MOTION.EXT`` (a folder of frames
for obj-seq), and then its record to ``OUTPUT/jobs/GARMENT__MOTION.json``, written last and once:
that file marks the job done.  A run skips done jobs (run again to resume), a job retried after its
worker died starts over and commits once, and a job whose spec changed under the same name (another
mesh, motion, model or effects) stops the run before anything is made.  The batch never writes over a file it
did not write: before committing, a job writes ``OUTPUT/jobs/GARMENT__MOTION.partial`` (removed after its
record), and a run refuses, before anything runs, a file where a job to make writes that is neither a killed
attempt's (its marker there) nor one the folder's outputs manifest lists as the batch's.  A finished job's record
keeps each file's size: one whose output is gone is made again, one whose output changed since is refused.  The executor
(:mod:`segadeform.distributed.executors`) is this machine's process pool or a Ray cluster; the files a jobs
file names must be at the same path on every worker.
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
import logging
import time
from collections.abc import Callable
from pathlib import Path
from typing import cast

from segadeform.bounds import check_betas
from segadeform.distributed.executors import Executor, LocalExecutor
from segadeform.errors import FileFormatError, InputError, SegadeformError, file_error
from segadeform.io.atomic import WriteError
from segadeform.io.location import Location, is_url, open_location
from segadeform.io.output_guard import OutputRefused
from segadeform.io.toml import config_path, key, key_line, read_table, read_toml
from segadeform.settings import DEFAULT_EFFECTS, Effects, MotionSpec, Scene, parse_effects
from segadeform.settings.cloth import CLOTH_KNOBS, ClothSettings
from segadeform.settings.presets import preset_effects
from segadeform.settings.scene import MotionTable, motion_spec_from_table, units_key

log = logging.getLogger(__name__)

__all__ = ["BatchConfig", "BatchJob", "BatchSummary", "load_batch", "batch_jobs", "run_batch", "run_job"]


# The jobs file's tables (what each key takes: segadeform.io.toml.read_table)
_BatchTable = dataclasses.make_dataclass(
    "_BatchTable",
    [
        ("output", str | None, dataclasses.field(default=None)),
        ("format", str, dataclasses.field(default="pc2")),
        ("model", str | None, dataclasses.field(default=None)),
        ("body", str | None, dataclasses.field(default=None)),
        ("effects", str | None, dataclasses.field(default=None)),
        ("quality", str | None, dataclasses.field(default=None)),
        ("collision_margin", float | None, dataclasses.field(default=None)),
        ("up", str, dataclasses.field(default="y")),
        ("units", str | int | float | None, key(None, types=(str, int, float))),
        ("resolution", float, key(1.0, range=(1e-9, 1.0))),
        ("frames_per_call", int, key(8, range=(1, 2**31))),
    ]
    # the cloth stage's knobs, as a scene's [effects] names them
    + [(f"cloth_{k}", float | None, dataclasses.field(default=None)) for k in CLOTH_KNOBS],
    frozen=True,
)


@dataclasses.dataclass(frozen=True)
class _GarmentTable:
    mesh: str
    name: str | None = None
    betas: tuple = ()


@dataclasses.dataclass(frozen=True)
class _MotionTable(MotionTable):
    name: str | None = None


@dataclasses.dataclass(frozen=True)
class BatchGarment:
    name: str
    mesh: Path
    betas: tuple = ()


@dataclasses.dataclass(frozen=True)
class BatchMotion:
    """A jobs file's motion: ``spec`` as the file gives it (the jobs' identity), and ``read_from``, the spec a job
    reads instead when the command line converted it (an ``.fbx`` file: the BVH Blender made of it, on this
    machine; its errors then name the FBX file), or ``refused``, why the command line could not (its jobs fail
    with it; the others run)."""

    name: str
    spec: MotionSpec
    read_from: MotionSpec | None = None
    refused: str | None = None


@dataclasses.dataclass(frozen=True)
class BatchConfig:
    output: str | None  # a folder path or a URL
    garments: tuple
    motions: tuple
    format: str = "pc2"
    model: Path | None = None
    body: Path | None = None
    effects: Effects = DEFAULT_EFFECTS
    up: str = "y"
    frames_per_call: int = 8
    path: Path | None = None
    units: float = 1.0  # metres per written unit (segadeform.io.writer.output_unit)
    resolution: float = 1.0  # share of each garment's vertices the model runs on (`run --resolution`)


def _name_ok(name: str, what: str, p: Path) -> str:
    if not name or "__" in name or any(c in name for c in "/\\:\x00") or name.startswith("."):
        raise FileFormatError(
            f"{what} name is not usable in a file name",
            path=p,
            expected="letters, digits, '-', '_' (no '__', '/', ':', leading '.')",
            got=repr(name),
        )
    return name


def _batch_effects(b: dict, p: Path) -> Effects:
    """What ``[batch]`` asks to run: ``effects`` (a complete list, or changes with ``quality``), ``quality`` (a
    preset of ``run --quality``), ``collision_margin`` (``run --collision-margin``) and ``cloth_<knob>`` (``run
    --cloth``); a knob whose stage is off is refused, as ``run`` refuses it (a new user's trial found none of them
    in a jobs file: ``unknown key batch.quality``)."""
    text = b.get("effects")
    try:
        if "quality" in b:
            effects = preset_effects(b["quality"], text)
        else:
            effects = parse_effects(text) if text is not None else DEFAULT_EFFECTS
    except (FileFormatError, InputError) as e:
        what = "batch.quality" if "quality" in b else "batch.effects"
        raise FileFormatError(f"{what}: {e.problem}", path=p, expected=e.expected, got=e.got) from None
    knobs = {k[len("cloth_") :]: v for k, v in b.items() if k.startswith("cloth_")}
    if knobs and not effects.cloth:
        raise FileFormatError(
            f"batch.cloth_{sorted(knobs)[0]} is set but the cloth stage is off",
            path=p,
            expected='effects with +cloth, or quality = "best"',
            got=effects.label(),
        )
    if "collision_margin" in b and not (effects.collisions or effects.cloth):
        raise FileFormatError(
            "batch.collision_margin is set but neither collisions nor the cloth stage is on",
            path=p,
            expected="effects with collisions or cloth",
            got=effects.label(),
        )
    margin = float(b.get("collision_margin", effects.collision_margin))
    try:
        effects = dataclasses.replace(effects, collision_margin=margin)
    except ValueError as e:
        raise FileFormatError(
            f"batch.collision_margin: {e}", path=p, line=key_line(p, "batch", "collision_margin")
        ) from None
    if margin > 0.05:  # as run --collision-margin says it (metres: 0.5 holds the cloth half a metre off the body)
        log.warning(
            "%s: batch.collision_margin %g holds the garment %g cm off the body (metres; the default is 0.004)",
            p,
            margin,
            100 * margin,
        )
    try:
        return dataclasses.replace(effects, cloth_settings=ClothSettings(**knobs) if knobs else effects.cloth_settings)
    except (ValueError, InputError) as e:
        raise FileFormatError(f"[batch]: {e}", path=p) from None


def load_batch(path) -> BatchConfig:
    """Read and validate a jobs file (see the module docstring)."""
    p = Path(path)
    data, _ = read_toml(p, "jobs file")
    unknown = sorted(set(data) - {"batch", "garments", "motions"})
    if unknown:
        raise FileFormatError(
            f"unknown table [{unknown[0]}]", path=p, expected="batch, garments, motions", got=", ".join(unknown)
        )
    b = read_table(data.get("batch", {}), _BatchTable, where="batch", path=p)
    base = p.resolve().parent

    def rel(s: str) -> Path:
        q = config_path(s, path=p)
        return q if q.is_absolute() else (base / q).resolve()

    gs, ms = data.get("garments", []), data.get("motions", [])
    for what, items in (("garments", gs), ("motions", ms)):
        if not isinstance(items, list) or not items or not all(isinstance(x, dict) for x in items):
            raise FileFormatError(
                f"the jobs file needs at least one [[{what}]] table",
                path=p,
                got=f"{len(items) if isinstance(items, list) else type(items).__name__}",
            )
    garments = []
    for i, g in enumerate(gs):
        read_table(g, _GarmentTable, where=f"garments[{i}]", path=p)
        mesh = rel(g["mesh"])
        betas = g.get("betas", [])
        if not all(isinstance(x, (int, float)) and not isinstance(x, bool) for x in betas):
            raise FileFormatError(f"garments[{i}].betas must be a list of numbers", path=p, got=betas)
        try:
            betas = check_betas(betas, what=f"garments[{i}].betas")  # finite, in the shape space
        except InputError as e:
            raise FileFormatError(e.problem, path=p, expected=e.expected, got=e.got) from None
        garments.append(
            BatchGarment(_name_ok(g.get("name", mesh.stem), "garment", p), mesh, tuple(float(x) for x in betas))
        )
    motions = []
    for i, m in enumerate(ms):
        read_table(m, _MotionTable, where=f"motions[{i}]", path=p)
        if ("file" in m) == ("kind" in m):
            raise FileFormatError(f"motions[{i}] needs exactly one of 'file' or 'kind'", path=p)
        if "file" in m and any(k in m for k in ("seconds", "speed", "amplitude", "seed")):
            raise FileFormatError(
                f"motions[{i}]: seconds/speed/amplitude/seed apply to procedural motions only", path=p
            )
        if "kind" in m:
            from segadeform.motion import MOTION_KINDS

            if m["kind"] not in MOTION_KINDS:
                raise FileFormatError(
                    f"motions[{i}].kind is not a motion kind",
                    path=p,
                    expected=", ".join(sorted(MOTION_KINDS)),
                    got=m["kind"],
                )
        spec = motion_spec_from_table(m, rel, where=p)
        default = Path(m["file"]).stem if "file" in m else m["kind"]
        motions.append(BatchMotion(_name_ok(m.get("name", default), "motion", p), spec))
    for what, items in (("garment", garments), ("motion", motions)):
        names = [x.name for x in items]
        dup = sorted({n for n in names if names.count(n) > 1})
        if dup:
            raise FileFormatError(f"{what} name used twice; give each entry a name", path=p, got=dup[0])
    from segadeform.io import SEQUENCE_FORMATS

    fmt = b.get("format", "pc2")
    if fmt not in SEQUENCE_FORMATS:
        raise FileFormatError(
            "batch.format is not an output format", path=p, expected=", ".join(SEQUENCE_FORMATS), got=fmt
        )
    from segadeform.io import UP_AXES

    if b.get("up", "y") not in UP_AXES:
        raise FileFormatError("unknown batch.up axis", path=p, expected=" | ".join(UP_AXES), got=b["up"])
    units = units_key(b, p, "batch")
    effects = _batch_effects(b, p)
    out = b.get("output")
    if out is not None and not is_url(out):
        out = str(rel(out))
    return BatchConfig(
        output=out,
        garments=tuple(garments),
        motions=tuple(motions),
        format=fmt,
        model=rel(b["model"]) if "model" in b else None,
        body=rel(b["body"]) if "body" in b else None,
        effects=effects,
        up=b.get("up", "y"),
        frames_per_call=int(b.get("frames_per_call", 8)),
        path=p,
        units=units,
        resolution=float(b.get("resolution", 1.0)),
    )


@dataclasses.dataclass(frozen=True)
class BatchJob:
    """One garment x motion: everything a worker needs (pickled to it)."""

    id: str
    out: Location
    garment: BatchGarment
    motion: BatchMotion
    format: str
    model: Path | None
    body: Path | None
    effects: Effects
    up: str
    frames_per_call: int
    spec: str
    force: bool = False  # accept a garment that does not sit on the body (`batch --force`; not part of the spec)
    units: float = 1.0  # metres per written unit
    resolution: float = 1.0  # share of the garment's vertices the model runs on

    @property
    def output_name(self) -> str:
        from segadeform.io import sequence_format

        exts = sequence_format(self.format).extensions
        return self.id + (exts[0] if exts else "")


def _file_digest(p: Path) -> str:
    from segadeform.io.hashing import file_sha256

    try:
        return file_sha256(p)[:16]
    except OSError as e:
        raise file_error(e, p) from None


def batch_jobs(cfg: BatchConfig, out=None) -> list[BatchJob]:
    """Every job of ``cfg`` (garment-major), writing to ``out`` (default: the file's ``[batch] output``)."""
    where = out if out is not None else cfg.output
    if where is None:
        raise InputError(
            "no output for the batch",
            expected="[batch] output in the jobs file or -o OUTPUT",
            got="neither",
            path=cfg.path,
        )
    loc = open_location(where)
    gd = {g.name: _file_digest(g.mesh) for g in cfg.garments}
    jobs = []
    for g in cfg.garments:
        for m in cfg.motions:
            spec: dict[str, object] = {
                "garment": str(g.mesh),
                "garment_sha256": gd[g.name],
                "betas": list(g.betas),
                "motion": dataclasses.asdict(m.spec),
                "format": cfg.format,
                "model": str(cfg.model),
                "body": str(cfg.body),
                "effects": dataclasses.asdict(cfg.effects),
                "up": cfg.up,
            }
            # (the specs of jobs at the defaults are those made before these keys existed: they resume)
            if cfg.units != 1.0:
                spec["units"] = cfg.units
            if cfg.resolution != 1.0:
                spec["resolution"] = cfg.resolution
            digest = hashlib.sha256(json.dumps(spec, sort_keys=True, default=str).encode()).hexdigest()[:16]
            jobs.append(
                BatchJob(
                    f"{g.name}__{m.name}",
                    loc,
                    g,
                    m,
                    cfg.format,
                    cfg.model,
                    cfg.body,
                    cfg.effects,
                    cfg.up,
                    cfg.frames_per_call,
                    digest,
                    units=cfg.units,
                    resolution=cfg.resolution,
                )
            )
    return jobs


def _pending(jid: str) -> str:
    """The marker a job writes before it commits its output and removes after its record: a file at the job's output
    name is the batch's own (a killed attempt's, to be written over) only where it is there."""
    return f"jobs/{jid}.partial"


def _occupied(loc: Location, name: str) -> list[str]:
    """What is at a job's output name: the file, or the files of the folder (obj-seq)."""
    return [name] if loc.exists(name) else [f"{name}/{n}" for n in loc.listdir(name)]


def _record(loc: Location, jid: str) -> dict | None:
    rel = f"jobs/{jid}.json"
    return dict(json.loads(loc.read_text(rel)), resumed=True) if loc.exists(rel) else None


def run_job(job: BatchJob) -> dict:
    """Run one job and commit its output and then its record (see the module docstring); returns the record, or
    ``{"id", "garment", "motion", "failed"}`` when the job's inputs were refused (nothing is committed)."""
    loc = job.out
    done = _record(loc, job.id)
    if done is not None:
        return done
    if job.motion.refused is not None:
        return {"id": job.id, "garment": job.garment.name, "motion": job.motion.name, "failed": job.motion.refused}
    t0 = time.perf_counter()
    name = job.output_name
    loc.remove_temporaries(name)  # what a killed attempt of this job left
    loc.remove_temporaries(f"jobs/{job.id}.json")
    try:
        return _run_job(job, loc, name, t0)
    except WriteError:
        raise  # the output is the whole batch's: stop
    except SegadeformError as e:  # this job's inputs: the others still run; no record, so a later run tries again
        why = str(e)
        m = job.motion
        if m.read_from is not None and m.read_from.file is not None:  # the user's file, not the converted one
            why = why.replace(str(m.read_from.file), str(m.spec.file)).replace(
                Path(m.read_from.file).name, Path(str(m.spec.file)).name
            )
        return {"id": job.id, "garment": job.garment.name, "motion": m.name, "failed": why}


def _run_job(job: BatchJob, loc, name: str, t0: float) -> dict:
    from .pipeline import run_scene

    try:
        with loc.scratch(name) as d:
            scene = Scene(
                garment=job.garment.mesh,
                motion=job.motion.read_from or job.motion.spec,
                output=Path(d) / name,
                output_format=job.format,
                up=job.up,
                units=job.units,
                resolution=job.resolution,
                body=job.body,
                betas=job.garment.betas,
                model=job.model,
                effects=job.effects,
            )
            s = run_scene(
                scene, batch=job.frames_per_call, threads=1, force=job.force, resolution_option="batch.resolution"
            )
            local = sorted(p for p in Path(d).rglob("*") if p.is_file())
            sizes = {p.relative_to(d).as_posix(): p.stat().st_size for p in local}
            pending = _pending(job.id)
            if not loc.exists(pending):  # (run_batch checked before the run; a file may have come since)
                taken = [t for t in sizes if loc.exists(t)]
                if taken:
                    return {
                        "id": job.id,
                        "garment": job.garment.name,
                        "motion": job.motion.name,
                        "failed": f"{loc}/{taken[0]} is in the way: a file segadeform batch did not write, which it "
                        "never writes over (move it, or use another output)",
                    }
            loc.put_bytes(pending, json.dumps(sorted(sizes)).encode())
            written = loc.commit_tree(Path(d))
    except WriteError as e:  # disk full, read-only: name the job's output, not its scratch folder
        raise WriteError(f"{loc}/{name}", e.reason, e.errno) from None
    rec = {
        "id": job.id,
        "garment": job.garment.name,
        "motion": job.motion.name,
        "spec": job.spec,
        "output": name,
        "files": written,
        "sizes": sizes,  # bytes per file: a finished job's output that changed since is refused, one gone made again
        "frames": s.frames,
        "ms_per_frame": s.ms_per_frame,
        "effects": job.effects.label(),
        "graph": s.variant,
        "seconds": time.perf_counter() - t0,
    }
    first = loc.put_bytes(f"jobs/{job.id}.json", json.dumps(rec, indent=1, sort_keys=True).encode(), once=True)
    loc.remove(_pending(job.id))
    if not first:
        return cast(dict, _record(loc, job.id))  # another attempt committed it first
    return rec


def _check_outputs(loc: Location, plan: list[BatchJob], done: dict, owned: Callable[[str], bool]) -> dict:
    """Before a run: ``{job id: its files there}`` for the jobs to make whose output name already holds the batch's own
    files -- a finished job (``done``: id -> record) whose output is gone in part or whole, or a job without a record
    whose files ``owned`` says the batch wrote (its record removed to have it made again).  Refused, before anything
    runs, when a finished job's output changed since the batch wrote it (its size) or when something the batch did not
    write is where a job to make writes: batch writes over neither."""
    edited, redo = [], set()
    for jid, rec in done.items():
        sizes = rec.get("sizes") or {}  # (records before 2 Dec 2026 have none: only a file gone is seen)
        for f in rec.get("files", []):
            got = loc.size(f)
            if got is None:
                redo.add(jid)
            elif f in sizes and got != sizes[f]:
                edited.append(f"{f} ({got:,} bytes, written {sizes[f]:,})")
    if edited:
        raise OutputRefused(
            f"{len(edited)} output(s) of finished jobs changed since batch wrote them (first: {edited[0]}); batch "
            "never writes over them: move them out of the folder to have their jobs made again, or use another output",
            path=str(loc),
        )
    carry = {jid: list(done[jid].get("files", [])) for jid in redo}
    in_way = []
    for j in plan:
        there = _occupied(loc, j.output_name) if j.id not in done else []
        if not there or loc.exists(_pending(j.id)):  # nothing there, or a killed attempt's (its marker)
            continue
        mine = [f for f in there if owned(f)]
        if len(mine) == len(there):
            carry[j.id] = there
        in_way += [f for f in there if f not in mine]
    if in_way:
        raise OutputRefused(
            f"the folder holds {len(in_way)} file(s) where batch writes that it did not write (first: {in_way[0]}); "
            "batch never writes over them: move them, or use another output",
            path=str(loc),
        )
    return carry


@dataclasses.dataclass
class BatchSummary:
    planned: int
    skipped: int
    made: int
    records: list
    output: str
    failed: list = dataclasses.field(default_factory=list)  # the records of jobs whose inputs were refused


def run_batch(
    cfg: BatchConfig,
    *,
    out=None,
    executor: Executor | None = None,
    jobs: int = 1,
    limit: int | None = None,
    progress: Callable[[dict], None] | None = None,
    force: bool = False,
    owned: Callable[[str], bool] | None = None,
) -> BatchSummary:
    """Run every job of ``cfg`` not done yet in ``out`` (see the module docstring) on ``executor``
    (default: a local pool of ``jobs`` processes; one given here is left open).  A job whose inputs are refused
    (a garment off the body, a frame range past its motion ...) does not stop the others: it is in the summary's
    ``failed`` with its message, and a later run tries it again.  ``force``: accept garments that do not sit on the
    body, as ``run --force``.  ``owned(path in the output)``: whether a file there is one the batch wrote (the CLI
    reads the folder's outputs manifest): a job without a record whose output holds only such files is made again
    over them; any other file where a job writes is refused before anything runs."""
    plan = batch_jobs(cfg, out)
    if force:
        plan = [dataclasses.replace(j, force=True) for j in plan]
    if not plan:
        raise InputError("the jobs file makes no jobs", path=cfg.path)
    loc = plan[0].out
    names = set(loc.listdir("jobs"))
    done = {j.id: json.loads(loc.read_text(f"jobs/{j.id}.json")) for j in plan if f"{j.id}.json" in names}
    changed = [j.id for j in plan if j.id in done and done[j.id].get("spec") != j.spec]
    if changed:
        raise InputError(
            f"{len(changed)} finished jobs in {loc} were made from another spec than the jobs file now "
            f"gives them (first: {changed[0]}); rename the entries or use another output",
            path=cfg.path,
        )
    carry = _check_outputs(loc, plan, done, owned or (lambda rel: False))
    for jid, files in carry.items():  # the batch's own files at a job made again: its marker says so, then no record
        loc.put_bytes(_pending(jid), json.dumps(files).encode())
        if jid in done:
            loc.remove(f"jobs/{jid}.json")
    todo = [j for j in plan if j.id not in done or j.id in carry]
    skipped = len(plan) - len(todo)
    if limit is not None:
        todo = todo[:limit]
    own = executor is None
    ex = LocalExecutor(jobs) if executor is None else executor
    records: list[dict] = []
    failed: list[dict] = []
    try:
        for rec in ex.map_unordered(run_job, todo):
            (failed if "failed" in rec else records).append(rec)
            if progress is not None:
                progress(rec)
    finally:
        if own:
            ex.close()
    return BatchSummary(
        planned=len(plan), skipped=skipped, made=len(records), records=records, output=str(loc), failed=failed
    )
