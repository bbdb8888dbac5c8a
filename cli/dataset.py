"""``segadeform dataset make``, ``info`` and ``regate``."""

from __future__ import annotations

import json
from pathlib import Path

import click

from .main import PathParam, cli

#: what `dataset make` writes at the top of its folder (segadeform.dataset.make), and what marks a dataset
#: folder made before folders had an outputs manifest
DATASET_LAYOUT = ("config.toml", "configs", "garments", "samples", "rejected", "log.jsonl")


def DATASET_LEGACY(loc, names) -> bool:
    """A dataset folder made before folders had a manifest: samples/ or rejected/ holding sample files only, or
    config.toml with configs/ holding the numbered configs (a run stopped before its first sample)."""
    if "config.toml" in names and "configs" in names:
        cfgs = loc.listdir("configs")
        if cfgs and all(f[:-5].isdigit() and f.endswith(".toml") for f in cfgs):
            return True
    found = False
    for d in ("samples", "rejected"):
        if d in names:
            files = loc.listdir(d)
            if not files or not all(f.endswith((".json", ".npz")) for f in files):
                return False
            found = True
    return found


@cli.group("dataset")
def dataset_group():
    """Ground-truth datasets made with the cloth simulator."""


@dataset_group.command("make")
@click.argument("config", type=PathParam(dir_okay=False, path_type=Path))
@click.option(
    "-o",
    "--output",
    required=True,
    help="Dataset folder or fsspec URL, e.g. s3://bucket/ds (an existing one is continued).",
)
@click.option(
    "-j",
    "--jobs",
    type=click.IntRange(min=1),
    help="Simulations at a time (default: 1 on the local pool, every CPU of a Ray cluster).",
)
@click.option(
    "--executor",
    default="local",
    show_default=True,
    metavar="local|ray|ray://HOST:PORT|ray:ADDRESS",
    help="Where the samples are simulated: this machine's process pool or a Ray cluster (needs the 'ray' extra).",
)
@click.option("--body", type=PathParam(dir_okay=False, path_type=Path), help="Body .npz (default: shipped body).")
@click.option("--limit", type=click.IntRange(min=1), help="Make at most this many samples now.")
@click.option("--sim-python", type=PathParam(dir_okay=False, path_type=Path), help="The simulator's Python.")
@click.option(
    "--dataset",
    "roots",
    multiple=True,
    type=PathParam(exists=True, path_type=Path),
    help="A read-only dataset root (a pack, a folder of packs, a dataset folder): samples it holds are "
    "done and not made again. Repeatable; the config's dataset.roots are read too.",
)
@click.option(
    "--force",
    is_flag=True,
    help="Write into a folder that holds other files (beside them, never over "
    "them); a dataset folder is continued without it.",
)
@click.option(
    "--retry-rejected",
    is_flag=True,
    help="First simulate again the rejected samples whose clip motion loading now prepares differently "
    "(after a fix to it); their old files move to rejected/retried/.",
)
@click.option(
    "--retry",
    "retry",
    multiple=True,
    metavar="GLOB",
    help="First simulate again the rejected samples whose ids match GLOB (after a change to the simulator "
    "that a sample's spec does not record); their old files move to rejected/retried/. Repeatable.",
)
@click.option(
    "--split",
    "splits",
    multiple=True,
    type=click.Choice(["train", "val", "test"]),  # segadeform.dataset.config.SPLITS (not imported: a lazy CLI)
    help="Make only the samples of this split (repeatable; default: every split), in the config's order: "
    "'--split test' makes the held-out split a fresh machine needs to repeat an evaluation.",
)
def dataset_make_cmd(
    config, output, jobs, executor, body, limit, sim_python, roots, force, retry_rejected, retry, splits
):
    """Simulate every garment x body x motion of CONFIG.toml into OUTPUT (resumable).

    CONFIG's format: the docstring of segadeform.dataset.config (samples/datasets/tiny.toml is a complete one);
    a garment OBJ of your own is an entry with mesh = "FILE.obj".
    """
    from segadeform.dataset import load_dataset_config, make_dataset
    from segadeform.distributed.executors import make_executor
    from segadeform.io.output_guard import OutputGuard
    from segadeform.physics import find_sim_python

    cfg = load_dataset_config(config)
    guard = OutputGuard("dataset", force=force, inputs=(config, body, *roots))
    loc = guard.resumable(output, layout=DATASET_LAYOUT, legacy=DATASET_LEGACY)
    ex = make_executor(executor, jobs)
    if not ex.remote:
        find_sim_python(sim_python)  # fail before planning anything (a cluster's workers make theirs)
    n = [0]

    def progress(rec):
        n[0] += 1
        why = "" if rec["status"] == "kept" else ": " + "; ".join(rec.get("reasons", []))
        q = rec.get("quality") or {}
        if rec["status"] != "kept" and q.get("frames"):  # (how much of the clip passes: what min_frames could keep)
            why += f" (the first {q.get('passing_frames', 0)} of {q['frames']} frames pass)"
        spf = f"{rec['seconds_per_frame']:.3f} s/frame" if "seconds_per_frame" in rec else ""
        click.echo(f"[{n[0]}] {rec['id']} ({rec['vertices']} v) {rec['status']} {spf}{why}", err=True)

    try:
        with ex:
            guard.start()
            s = make_dataset(
                cfg,
                loc,
                body_path=body,
                sim_python=sim_python,
                progress=progress,
                limit=limit,
                executor=ex,
                roots=roots,
                retry_rejected=retry_rejected,
                retry=tuple(retry),
                splits=tuple(splits),
            )
    finally:
        guard.abandon()  # a run that made nothing leaves no empty folder
    click.echo(f"{s.planned} planned, {s.skipped} already done, {s.kept} kept, {s.rejected} rejected -> {output}")
    if s.rejected:  # (a first dataset of one's own kept nothing and said nothing of what to do: an ML user's trial)
        click.echo(
            f"note: a rejected sample keeps its frames: `segadeform dataset regate CONFIG -o {output}` applies a "
            "looser [quality] gate (max_strain, max_strained_edges, min_frames: keep a clip's passing first frames) "
            "without simulating again, and [[fallback]] tables simulate rejected samples again with other settings"
        )
    if s.unplanned:
        click.echo(
            f"note: {len(s.unplanned)} kept sample{'s' if len(s.unplanned) != 1 else ''} in {output} "
            f"{'are' if len(s.unplanned) != 1 else 'is'} not in this config (first: {s.unplanned[0]}): "
            f"train and eval read every sample a folder holds; a training config's exclude leaves them out"
        )


@dataset_group.command("info")
@click.argument("roots", nargs=-1, required=True, type=PathParam(exists=True, path_type=Path))
@click.option("--json", "as_json", is_flag=True, help="Print the statistics as JSON (several roots: by root).")
@click.option("--by-garment", is_flag=True, help="Also kept / made per garment (each drawn or MakeHuman garment).")
def dataset_info_cmd(roots, as_json, by_garment):
    """Statistics of dataset ROOTS (folders, packs, folders of packs; each on its own, as train and eval take
    several): samples per split, rejection reasons, seconds per frame by size."""
    from segadeform.dataset.report import dataset_stats

    stats = {str(r): dataset_stats(r) for r in roots}  # every root read before anything is said
    if as_json:
        click.echo(json.dumps(stats[str(roots[0])] if len(roots) == 1 else stats, indent=1))
        return
    for folder in roots:
        _say_stats(folder, stats[str(folder)], by_garment)


def _say_stats(folder, st: dict, by_garment: bool) -> None:
    """`dataset info`'s lines for one root."""
    notes = [f"{st['trimmed']} of them their leading frames that pass"] if st["trimmed"] else []
    notes += [f"{st['fallback']} on a fallback attempt"] if st["fallback"] else []
    cut = f" ({'; '.join(notes)})" if notes else ""
    click.echo(f"{folder}: {st['kept']} kept{cut}, {st['rejected']} rejected ({100 * st['rejection_rate']:.1f} %)")
    for k, v in st["splits"].items():
        click.echo(f"  split {k}: {v} samples")
    for r, c in st["reasons"].items():
        click.echo(f"  rejected: {c} x {r}")
    for k, v in [*st["by_kind_source"].items(), *(st["by_garment"].items() if by_garment else ())]:
        notes = [f"{v['trimmed']} trimmed"] if v["trimmed"] else []
        notes += [f"{v['fallback']} on a fallback"] if v["fallback"] else []
        cut = f"  ({', '.join(notes)})" if notes else ""
        click.echo(f"  kept {v['samples'] - v['rejected']:4d} / {v['samples']:4d} made  {k}{cut}")
    for row in st["by_size"]:
        click.echo(f"  {row['garment']:24s} {row['vertices']:6d} v  {row['seconds_per_frame']:.3f} s/frame")


@dataset_group.command("regate")
@click.argument("config", type=PathParam(dir_okay=False, path_type=Path))
@click.option(
    "-o",
    "--output",
    required=True,
    type=PathParam(file_okay=False, exists=True, path_type=Path),
    help="The dataset folder.",
)
@click.option("--body", type=PathParam(dir_okay=False, path_type=Path), help="Body .npz (default: shipped body).")
def dataset_regate_cmd(config, output, body):
    """Apply CONFIG's quality gate again to every sample of the dataset that kept its arrays (kept and
    rejected alike), moving those whose status changes; nothing is simulated."""
    from segadeform.dataset import load_dataset_config
    from segadeform.dataset.make import regate
    from segadeform.io.output_guard import OutputGuard

    cfg = load_dataset_config(config)
    # regate moves a dataset's own files: a folder that is not a dataset (made by `dataset make`) is refused
    OutputGuard("dataset", inputs=(config, body), replaces=False).resumable(
        output, layout=DATASET_LAYOUT, legacy=DATASET_LEGACY
    )
    r = regate(output, cfg, body_path=body)
    for sid, status in r.moved:
        click.echo(f"{sid}: now {status}")
    click.echo(
        f"{output}: {r.kept} pass the gate, {r.rejected} do not ({len(r.moved)} moved; "
        f"{len(r.skipped)} rejected before their arrays were kept)"
    )


@dataset_group.command("pack")
@click.argument("folder", type=PathParam(file_okay=False, exists=True, path_type=Path))
@click.option(
    "-o",
    "--output",
    required=True,
    type=PathParam(dir_okay=False, path_type=Path),
    help="The new pack (NAME.sgdpack); an existing file is never replaced.",
)
@click.option(
    "--skip",
    "skip",
    multiple=True,
    type=PathParam(path_type=Path),
    help="Packs (or a folder of packs) whose samples are left out: pack only what is new; a folder that is not "
    "there yet (a store with no pack) leaves nothing out. Repeatable.",
)
@click.option("--no-rejected", is_flag=True, help="Leave out the samples the quality gate rejected.")
@click.option(
    "--body",
    type=PathParam(dir_okay=False, path_type=Path),
    help="Body .npz the dataset was made with (default: shipped body).",
)
def dataset_pack_cmd(folder, output, skip, no_rejected, body):
    """Pack the dataset FOLDER into one read-only file that lasts (segadeform.dataset.pack): frames
    to 0.1 mm steps (error <= 0.05 mm), LZMA-compressed; train, eval and dataset make read it beside
    folders (--dataset PACK)."""
    from segadeform.body.model import default_body_path, load_body
    from segadeform.dataset.pack import PACK_SUFFIX, write_pack
    from segadeform.dataset.roots import expand_root
    from segadeform.errors import InputError
    from segadeform.io.output_guard import OutputGuard

    absent = [s for s in skip if not s.exists()]
    for a in absent:  # a pack named that is not there is a mistake; a folder of packs may not be made yet
        if a.suffix == PACK_SUFFIX:
            raise InputError("--skip names a pack that does not exist", path=a)
    guard = OutputGuard("dataset pack", replaces=False, inputs=(folder, body, *skip))
    guard.file(output)
    packs = [p for s in skip if s.exists() for p in expand_root(s) if not isinstance(p, Path)]
    s = write_pack(
        folder, output, body=load_body(body or default_body_path()), skip=packs, include_rejected=not no_rejected
    )
    guard.record()
    click.echo(
        f"{s.samples} kept and {s.rejected} rejected samples ({s.skipped} already in the packs given) "
        f"-> {s.path} ({s.bytes / 1e6:.1f} MB)"
    )
    for a in absent:
        click.echo(f"--skip {a}: not there yet, so no sample was left out for it")
