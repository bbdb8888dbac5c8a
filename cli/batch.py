"""``segadeform batch``: every garment x motion of a jobs file through the runtime."""

from __future__ import annotations

import contextlib
import dataclasses
from pathlib import Path

import click

from .main import PathParam, cli

#: the top-level names a batch writes: jobs/ (the records) and GARMENT__MOTION outputs
BATCH_LAYOUT = ("jobs", "*__*")


def _made_by_batch(loc, names) -> bool:
    """Whether a folder without a manifest is one an earlier batch made: its ``jobs/`` holds job records (``*.json``,
    and the markers of jobs being committed) and nothing else, and every other name is a job's output
    (``GARMENT__MOTION...``).  A folder that merely has a ``jobs/`` (a render farm's) is not."""
    import fnmatch

    records = loc.listdir("jobs")
    return (
        "jobs" in names
        and any(n.endswith(".json") for n in records)
        and all(n.endswith((".json", ".partial")) for n in records)
        and all(n == "jobs" or fnmatch.fnmatchcase(n, "*__*") for n in names)
    )


@cli.command("batch")
@click.argument("jobs_file", metavar="JOBS.toml", type=PathParam(dir_okay=False, path_type=Path))
@click.option("-o", "--output", help="Folder or fsspec URL for the outputs (overrides [batch] output).")
@click.option(
    "-j",
    "--jobs",
    type=click.IntRange(min=1),
    help="Jobs at a time (default: 1 on the local pool, every CPU of a Ray cluster).",
)
@click.option(
    "--executor",
    default="local",
    show_default=True,
    metavar="local|ray|ray://HOST:PORT|ray:ADDRESS",
    help="Where the jobs run: this machine's process pool or a Ray cluster (needs the 'ray' extra).",
)
@click.option("--limit", type=click.IntRange(min=1), help="Run at most this many jobs now.")
@click.option(
    "--force",
    is_flag=True,
    help="Write into an output folder that holds other files (beside them, "
    "never over them; a folder an earlier batch made is resumed without it), and animate garments that do not "
    "sit on the body (as run --force).",
)
def batch_cmd(jobs_file, output, jobs, executor, limit, force):
    """Animate every garment x motion of JOBS.toml (resumable: done jobs are skipped).

    \b
    JOBS.toml (relative paths are relative to it):
      [batch]        output = "out/batch", format = "pc2" (| obj-seq | xdmf | abc | usd), and optionally
                     model, body, effects ("dqs,collisions", as run --effects), quality, collision_margin,
                     cloth_<knob>, up, units ("cm", as run --output-units), resolution (as run --resolution),
                     frames_per_call
      [[garments]]   mesh = "skirt.obj", and optionally name, betas = [0.0, 0.5]
      [[motions]]    file = "walk.bvh" (.fbx: read through Blender, as run reads it) or kind = "walk"
                     (with seconds, speed, amplitude, seed), and
                     optionally name, fps, frames = "0:60"
    Each garment x motion is the job GARMENT__MOTION; a job whose inputs are refused is named and the others
    are made (exit 1); run again to resume."""
    from segadeform.distributed.executors import make_executor
    from segadeform.runtime.batch import load_batch, run_batch

    cfg = load_batch(jobs_file)
    from segadeform.io.location import is_url
    from segadeform.io.output_guard import OutputGuard, written_by

    guard = OutputGuard(
        "batch",
        force=force,
        inputs=(jobs_file, cfg.model, cfg.body, *(g.mesh for g in cfg.garments), *(m.spec.file for m in cfg.motions)),
    )
    where = output if output is not None else cfg.output
    if where is not None:  # (none: run_batch says so)
        output = guard.resumable(where, layout=BATCH_LAYOUT, legacy=_made_by_batch)
    n = [0]

    local = Path(str(output)) if output is not None and not is_url(str(output)) else None

    def owned(rel: str) -> bool:  # a file the batch wrote, unchanged since (the folder's outputs manifest)
        return local is not None and written_by(local / rel) == "batch"

    def progress(rec):
        n[0] += 1
        if "failed" in rec:
            click.echo(f"[{n[0]}] {rec['id']}: FAILED: {rec['failed']}", err=True)
            return
        if local is not None and not rec.get("resumed"):  # the job's files are the batch's: in the manifests
            by_folder: dict[Path, list[str]] = {}
            for f in rec.get("files", []):
                by_folder.setdefault((local / f).parent, []).append(Path(f).name)
            for folder, names in by_folder.items():
                guard.record_files_in(folder, names)
        how = "already done" if rec.get("resumed") else f"{rec['frames']} frames, {rec['ms_per_frame']:.1f} ms/frame"
        click.echo(f"[{n[0]}] {rec['id']}: {how} -> {rec['output']}", err=True)

    try:
        with contextlib.ExitStack() as stack:
            cfg = _fbx_read(cfg, executor, stack, output)
            with make_executor(executor, jobs) as ex:
                guard.start()
                s = run_batch(cfg, out=output, executor=ex, limit=limit, progress=progress, force=force, owned=owned)
    finally:
        guard.abandon()  # a run that made nothing leaves no empty output folder
    click.echo(
        f"{s.planned} jobs, {s.skipped} already done, {s.made} made"
        + (f", {len(s.failed)} failed" if s.failed else "")
        + f" -> {s.output}"
    )
    if s.failed:  # every job that could run did; the failed ones run again next time
        f0 = s.failed[0]
        # --force accepts only what a refusal says it would (a garment off the body): offered for nothing else (a
        # units error ended "or pass --force" too: a new user's trial)
        forced = not force and any("--force" in f["failed"] for f in s.failed)
        raise click.ClickException(
            f"{len(s.failed)} of {s.planned} jobs failed (first: job {f0['id']}, garment {f0['garment']!r}, motion "
            f"{f0['motion']!r}: {f0['failed']}); fix the jobs file{' or pass --force' if forced else ''}, then run "
            "again to make them"
        )


def _fbx_read(cfg, executor: str, stack: contextlib.ExitStack, output):
    """``cfg`` with each ``.fbx`` motion that has a job left to make read from the BVH Blender makes of it (once per
    motion, in a temporary folder that ``stack`` removes), as `segadeform run` reads one; the jobs keep the FBX file
    as their identity, so a batch resumes, and a motion whose jobs are all done is not read again.  A file Blender
    cannot read fails its own jobs only.  The BVH lives on this machine: a Ray cluster's workers would not find it."""
    from segadeform.errors import InputError, SegadeformError
    from segadeform.runtime.batch import batch_jobs

    from .motion_convert import motion_spec_read

    fbx = [m for m in cfg.motions if m.spec.file is not None and Path(m.spec.file).suffix.lower() == ".fbx"]
    if not fbx or (output is None and cfg.output is None):  # (no output: run_batch says so)
        return cfg
    plan = batch_jobs(cfg, output)
    loc = plan[0].out
    done = set(loc.listdir("jobs"))
    left = {j.motion.name for j in plan if f"{j.id}.json" not in done}
    fbx = [m for m in fbx if m.name in left]
    if fbx and executor != "local":
        raise InputError(
            f"motion {fbx[0].name!r} is an FBX file, which is read through Blender on this machine, and the jobs "
            f"run on {executor}",
            path=fbx[0].spec.file,
            expected="--executor local, or the motion converted first (`segadeform motion convert FILE.fbx -o "
            "FILE.bvh`) and the .bvh in the jobs file",
            got=".fbx",
        )
    motions = []
    for m in cfg.motions:
        if m in fbx:
            try:
                m = dataclasses.replace(m, read_from=stack.enter_context(motion_spec_read(m.spec)))
            except SegadeformError as e:  # this motion's jobs fail with it; the others are made
                m = dataclasses.replace(m, refused=str(e))
        motions.append(m)
    return dataclasses.replace(cfg, motions=tuple(motions))
