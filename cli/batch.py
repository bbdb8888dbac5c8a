"""``segadeform batch``: every garment x motion of a jobs file through the runtime."""

from __future__ import annotations

from pathlib import Path

import click

from .main import cli


@cli.command("batch")
@click.argument("jobs_file", metavar="JOBS.toml", type=click.Path(dir_okay=False, path_type=Path))
@click.option("-o", "--output", help="Folder or fsspec URL for the outputs (overrides [batch] output).")
@click.option("-j", "--jobs", type=click.IntRange(min=1),
              help="Jobs at a time (default: 1 on the local pool, every CPU of a Ray cluster).")
@click.option("--executor", default="local", show_default=True, metavar="local|ray|ray://HOST:PORT|ray:ADDRESS",
              help="Where the jobs run: this machine's process pool or a Ray cluster (needs the 'ray' extra).")
@click.option("--limit", type=click.IntRange(min=1), help="Run at most this many jobs now.")
def batch_cmd(jobs_file, output, jobs, executor, limit):
    """Animate every garment x motion of JOBS.toml (resumable: done jobs are skipped)."""
    from segadeform.executors import make_executor
    from segadeform.runtime.batch import load_batch, run_batch

    cfg = load_batch(jobs_file)
    n = [0]

    def progress(rec):
        n[0] += 1
        how = "already done" if rec.get("resumed") else f"{rec['frames']} frames, {rec['ms_per_frame']:.1f} ms/frame"
        click.echo(f"[{n[0]}] {rec['id']}: {how} -> {rec['output']}", err=True)

    with make_executor(executor, jobs) as ex:
        s = run_batch(cfg, out=output, executor=ex, limit=limit, progress=progress)
    click.echo(f"{s.planned} jobs, {s.skipped} already done, {s.made} made -> {s.output}")
