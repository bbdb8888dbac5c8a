"""``segadeform train`` and ``segadeform eval`` (need the 'torch' extra; imported only when run)."""

from __future__ import annotations

import sys
from pathlib import Path

import click

from .main import PathParam, cli, usable_threads


def _body(path):
    from segadeform.body import default_body_path, load_body

    return load_body(path or default_body_path())


@cli.command("train")
@click.argument("config", type=PathParam(dir_okay=False, path_type=Path))
@click.option(
    "-o",
    "--output",
    required=True,
    type=PathParam(file_okay=False, path_type=Path),
    help="Run folder (an existing run of the same config is resumed).",
)
@click.option(
    "--dataset",
    multiple=True,
    type=PathParam(exists=True, path_type=Path),
    help="A dataset root (a folder, a .sgdpack, a folder of packs); repeatable; replaces the config's [data] "
    "dataset and optional roots.",
)
@click.option("--steps", type=click.IntRange(min=1), help="Overrides optim.steps.")
@click.option(
    "--init",
    type=PathParam(exists=True, dir_okay=False, path_type=Path),
    help="Overrides optim.init: a checkpoint (model.pt) whose weights a new run starts from, to fine-tune a trained "
    "model on your own samples (its [model] must be the config's; a resumed run goes on from its own last.pt).",
)
@click.option("--device", type=click.Choice(["auto", "cpu", "cuda"]), help="Overrides optim.device.")
@click.option(
    "--seconds",
    type=click.FloatRange(min=0),
    help="Overrides optim.seconds: a time budget for the run, loading included (the config's warm-up, >= 20 "
    "steps, times the machine and fixes the step count, at most optim.steps; 0: off).",
)
@click.option("--body", type=PathParam(dir_okay=False, path_type=Path), help="Body .npz (default: shipped body).")
@click.option("--val", "val_ids", multiple=True, help="Sample id to validate on at each checkpoint (repeatable).")
@click.option("--threads", type=click.IntRange(min=1), help="torch CPU threads (default: torch's choice).")
@click.option(
    "--force",
    is_flag=True,
    help="Write into a run folder that holds other files (beside them, never over "
    "them); a run folder of the same config is resumed without it.",
)
def train_cmd(config, output, dataset, steps, init, device, seconds, body, val_ids, threads, force):
    """Train the SEGA model on a simulated dataset (CONFIG.toml; see segadeform.train.config; needs the 'torch'
    extra)."""
    _need_torch("train")
    from segadeform.io.output_guard import OutputGuard

    guard = OutputGuard("train", force=force, inputs=(config, *dataset, body, init))
    written = ("config.toml", "train.json", "last.pt", "best.pt", "model.pt", "loss.csv", "loss.png")
    guard.resumable(
        output,
        layout=("config.toml", "train.json", "last.pt", "model.pt", "loss.csv", "loss.png"),
        legacy=("config.toml", "loss.csv", "last.pt"),
    )
    guard.check_files_in(output, written)  # a file of the run's that the user edited is never written over
    from segadeform.train import load_train_config
    from segadeform.train.trainer import train

    if threads:
        import torch

        threads, threads_note = usable_threads(threads)
        if threads_note:
            click.echo(threads_note)
        torch.set_num_threads(threads)

    ov = {}
    if steps:
        ov["optim.steps"] = steps
    if device:
        ov["optim.device"] = device
    if seconds is not None:
        ov["optim.seconds"] = seconds
    if init is not None:
        ov["optim.init"] = str(init.resolve())
    cfg = load_train_config(config, dataset=list(dataset) or None, overrides=ov)
    interactive = sys.stderr.isatty()

    def progress(step, row):
        of = row.get("of", cfg.optim.steps)  # the step count (under a time budget: the one it fixed)
        if interactive or step % 100 == 0 or step == of:
            val = f" held-out {100 * float(row['val_vertex']):.2f} cm" if row.get("val_vertex") != "" else ""
            click.echo(
                f"step {step}/{of} loss {row['total']:.4g} vertex {100 * row['vertex']:.2f} cm"
                f"{val} ({row['seconds']:.0f} s)",
                err=True,
            )

    import json

    def done_steps():
        try:
            return json.loads((output / "train.json").read_text()).get("steps")
        except (OSError, ValueError):
            return None

    before = done_steps()

    def resumed(step, of):
        click.echo(f"resuming at step {step}/{of} from {output / 'last.pt'}", err=True)

    guard.start()
    try:
        final = train(cfg, output, _body(body), progress=progress, val_ids=list(val_ids) or None, resumed=resumed)
    except KeyboardInterrupt:  # Ctrl-C, SIGTERM: click said "Aborted!" alone (a user's trial)
        raise click.ClickException(_interrupted(output)) from None
    finally:
        guard.abandon()
        guard.record_files_in(output, written)  # whatever the run wrote, stopped or not: the next run resumes
    info = json.loads((output / "train.json").read_text())
    if before is not None and before == info["steps"]:  # a finished run run again (a user read it as trained now)
        click.echo(
            f"already trained: {info['steps']} steps in {info['train_seconds']:.0f} s -> {final} (nothing to do)"
        )
    else:
        click.echo(f"trained {info['steps']} steps in {info['train_seconds']:.0f} s -> {final}")
    chosen = info.get("chosen") or {}
    if chosen.get("step") is not None and chosen.get("val_vertex") is not None:  # which network model.pt is
        split = chosen.get("val_split") or "validation"
        click.echo(
            f"model.pt is step {chosen['step']}: the lowest '{split}' vertex error, "
            f"{100 * float(chosen['val_vertex']):.2f} cm"
            + (
                " -- the untrained network: no step of this run did better on that split (more steps, another "
                "learning rate, or more training data)"
                if chosen["step"] == 0
                else ""
            )
        )


def _interrupted(output: Path) -> str:
    """What a train run stopped by Ctrl-C (or SIGTERM) says: that the same command resumes it, and from where."""
    import torch

    try:
        at = int(torch.load(output / "last.pt", map_location="cpu", weights_only=False)["step"])
    except Exception:  # none written yet, or not a checkpoint of ours: nothing to resume from
        at = 0
    if at:
        return f"interrupted: run the same command again to resume from step {at} (the checkpoint {output / 'last.pt'})"
    return "interrupted before the run's first checkpoint: run the same command again to start it afresh"


def _need_torch(command: str) -> None:
    """One line, exit 1, when torch is not installed: the training package imports it (a new user's `eval` without
    the extra ended in a ModuleNotFoundError traceback)."""
    import importlib.util

    if importlib.util.find_spec("torch") is None:
        raise click.ClickException(f"{command} needs the 'torch' extra: pip install 'segadeform[torch]'")


@cli.command("eval")
@click.argument("dataset", nargs=-1, required=True, type=PathParam(exists=True, path_type=Path))
@click.option(
    "-m",
    "--model",
    "models",
    multiple=True,
    required=True,
    help="NAME=SPEC with SPEC a model package folder, a .pt checkpoint, 'lbs' or 'lbs-PRIOR' (lbs-inpaint, "
    "lbs-idw, lbs-gaussian, lbs-smooth, lbs-smooth-light, lbs-drape: smooth weights on the garment draped at "
    "rest; 'simulation': the simulator's own frames, for its penetration and stretch; repeatable).",
)
@click.option(
    "-o",
    "--output",
    required=True,
    type=PathParam(file_okay=False, path_type=Path),
    help="Report folder (eval.md, eval.json, PNG plots).",
)
@click.option(
    "--split",
    "splits",
    multiple=True,
    help="Dataset split to evaluate (default: test); one split a report, so given once.",
)
@click.option(
    "--sample",
    "sample_ids",
    multiple=True,
    metavar="ID",
    help="Evaluate only this sample of the split (repeatable; default: every kept sample of it); eval.json's "
    "by_sample holds every metric of each sample, so any subset's table can be made again.",
)
@click.option("--body", type=PathParam(dir_okay=False, path_type=Path), help="Body .npz (default: shipped body).")
@click.option(
    "--push-out",
    "push_margin",
    type=float,
    multiple=True,
    help="Also report every model but plain lbs and simulation with the runtime's collision post-process at this "
    "margin (m); repeatable (rows 'NAME + push-out N mm').",
)
@click.option(
    "--cloth",
    "cloth",
    multiple=True,
    metavar="NAME=VALUE,..|default",
    help="Also report every model but lbs, lbs-inpaint and simulation with the runtime's cloth stage at these "
    "settings (as run --cloth; 'default' for its defaults); repeatable (rows 'NAME + cloth [settings]').",
)
@click.option("--heatmap", help="Model NAME whose per-vertex error map is rendered (default: the first).")
@click.option(
    "--force",
    is_flag=True,
    help="Write the report into a folder that holds other files (beside them, never over them).",
)
def eval_cmd(dataset, models, output, splits, body, push_margin, heatmap, force, cloth=(), sample_ids=()):
    """Evaluate models against the simulation on DATASET (one or more roots: dataset folders, packs, folders of
    packs): the paper's metrics per model and garment type (needs the 'torch' extra)."""
    _need_torch("eval")
    from segadeform.io.output_guard import OutputGuard
    from segadeform.runtime.predictor import PackagePredictor
    from segadeform.train.evaluate import evaluate as run_eval
    from segadeform.train.evaluate import pick_samples
    from segadeform.train.predictors import make_predictors
    from segadeform.train.report import markdown_table, write_report

    if len(splits) > 1:  # the last one was evaluated alone, the others dropped without a word (a user's trial)
        raise click.UsageError(
            f"--split names one split (a report is of one), got {len(splits)}: {', '.join(splits)}; run eval once "
            "for each, each with its own -o"
        )
    split = splits[0] if splits else "test"
    guard = OutputGuard("eval", force=force, inputs=(*dataset, body))
    guard.folder(output, names=("eval.*", "*.png"))
    spec = {}
    for m in models:
        name, eq, s = m.partition("=")
        if not eq or not name or not s:
            raise click.UsageError(f"--model must be NAME=SPEC, got {m!r}")
        if name in spec:  # the second silently replaced the first (a user's trial: lbs dropped from the table)
            raise click.UsageError(f"--model names each model once: {name!r} is given twice ({spec[name]} and {s})")
        spec[name] = s
    b = _body(body)
    from segadeform.dataset.roots import DatasetRoots

    dataset = DatasetRoots(list(dataset))
    margins = None if not push_margin else push_margin[0] if len(push_margin) == 1 else list(push_margin)
    predictors = make_predictors(spec, package=PackagePredictor)
    scored = pick_samples(dataset.ids(split), sample_ids, split, dataset) if sample_ids else dataset.ids(split)
    _say_trained_on(spec, set(scored), split)
    _say_motions_trained_on(spec, dataset, sorted(scored), split)
    res = run_eval(
        dataset,
        b,
        predictors,
        split=split,
        push_out_margin=margins,
        cloth=list(cloth) or None,
        progress=lambda sid: click.echo(f"  {sid}", err=True),
        samples=list(sample_ids) or None,
    )
    write_report(res, output, dataset=dataset, body=b, heatmap=predictors.get(heatmap or next(iter(spec))))
    guard.record()
    click.echo(markdown_table(res))
    click.echo(f"-> {output}")


def _say_trained_on(spec: dict, scored: set, split: str) -> None:
    """Warn of a model scored on samples it was trained on: a checkpoint whose run folder's ``train.json`` lists
    some of ``scored`` (a researcher's trial: `eval` took a model's own training samples without a word)."""
    import json

    for name, s in spec.items():
        record = Path(s).parent / "train.json" if Path(s).is_file() else None
        if record is None or not record.is_file():
            continue
        try:
            trained = set(json.loads(record.read_text(encoding="utf-8")).get("samples") or [])
        except (OSError, ValueError, AttributeError):
            continue
        both = sorted(scored & trained)
        if both:
            click.echo(
                f"warning: model {name} was trained on {len(both)} of the {len(scored)} '{split}' samples it is "
                f"scored on (first: {both[0]}; {record} lists them): its numbers there are not held out",
                err=True,
            )


def _motions_record_of(s: str) -> dict | None:
    """The record of training motions that model ``s`` keeps: a package's manifest ``training_motions``, a
    checkpoint's; None for a baseline word or a model that records none."""
    import json

    p = Path(s)
    if p.is_dir() and (p / "manifest.json").is_file():
        try:
            return json.loads((p / "manifest.json").read_text(encoding="utf-8")).get("training_motions")
        except (OSError, ValueError, AttributeError):
            return None
    if p.is_file() and p.suffix == ".pt":
        from segadeform.model.network import checkpoint_training_motions

        return checkpoint_training_motions(p)
    return None


def _say_motions_trained_on(spec: dict, dataset, ids: list, split: str) -> None:
    """Warn of a model scored on samples that play a motion it was trained on: one capture by the joints'
    speeds (:mod:`segadeform.motion.fingerprint`), whatever the file, its format, frame rate or rig (a
    researcher's trial: the shipped package was scored on CMU clips it had been trained on, and nothing said)."""
    from segadeform.errors import InputError
    from segadeform.motion.fingerprint import SAME_CAPTURE, joint_speeds, nearest_capture, read_motions_record

    records = {n: r for n, s in spec.items() if (r := _motions_record_of(s)) is not None}
    if not records or not ids:
        return
    prints = {}
    for sid in ids:
        smp = dataset.load(sid)
        prints[sid] = joint_speeds(smp.poses, float(smp.meta.get("fps", 30.0)))
    for name, record in records.items():
        try:
            motions = read_motions_record(record)
        except InputError as e:
            click.echo(f"warning: model {name}'s record of its training motions cannot be read: {e}", err=True)
            continue
        hits = []
        for sid, fp in prints.items():
            i, d = nearest_capture(fp, [sp for _, sp in motions])
            if d <= SAME_CAPTURE:
                hits.append((sid, motions[i][0]))
        if hits:
            click.echo(
                f"warning: model {name} was trained on the motion of {len(hits)} of the {len(ids)} '{split}' samples "
                f"it is scored on (first: {hits[0][0]} plays its training motion {hits[0][1]!r}, one capture by the "
                "joints' speeds): its numbers there are not held out on motion",
                err=True,
            )


@cli.command("ensemble")
@click.argument("checkpoints", nargs=-1, required=True, type=PathParam(dir_okay=False, path_type=Path))
@click.option(
    "-o",
    "--output",
    required=True,
    type=PathParam(dir_okay=False, path_type=Path),
    help="Ensemble checkpoint (.pt) to write.",
)
def ensemble_cmd(checkpoints, output):
    """Average two or more trained CHECKPOINTS of one configuration into one model (a .pt that eval, export and
    every runtime take like one network; it costs its members' time).  The members' training garments are
    recorded together."""
    try:
        import torch  # noqa: F401
    except ImportError:
        raise click.ClickException("ensemble needs the 'torch' extra: pip install 'segadeform[torch]'") from None
    from segadeform.body.identity import body_text
    from segadeform.errors import InputError
    from segadeform.io.output_guard import OutputGuard
    from segadeform.model import load_checkpoint, save_checkpoint
    from segadeform.model.ensemble import combine
    from segadeform.model.network import checkpoint_body, checkpoint_training_garments

    if output.suffix != ".pt":
        raise click.UsageError(f"the ensemble is a checkpoint: expected OUTPUT.pt, got {output}")
    guard = OutputGuard("ensemble", inputs=checkpoints)
    guard.file(output)
    first: dict = {}
    for p in checkpoints:
        if p.resolve() in first:
            raise InputError(
                "a checkpoint given twice averages with itself at twice the cost",
                path=p,
                expected="distinct checkpoints",
                got=f"{first[p.resolve()]} and {p}",
            )
        first[p.resolve()] = p
    models = [load_checkpoint(p) for p in checkpoints]
    base = models[0].cfg.replace(ensemble=1)
    for p, m in zip(checkpoints[1:], models[1:], strict=True):
        c = m.cfg.replace(ensemble=1)
        if c != base:
            diff = [k for k, v in vars(base).items() if getattr(c, k) != v]
            raise InputError(
                f"its network's configuration differs from {checkpoints[0]}'s (an ensemble's share one)",
                path=p,
                expected=", ".join(f"{k} = {getattr(base, k)!r}" for k in diff),
                got=", ".join(f"{k} = {getattr(c, k)!r}" for k in diff),
            )
    bodies = [checkpoint_body(p) for p in checkpoints]  # the body each was trained on (None: not recorded)
    known = [(p, b) for p, b in zip(checkpoints, bodies, strict=True) if b is not None]
    for p, b in known[1:]:
        if b["sha256"] != known[0][1]["sha256"]:
            raise InputError(
                f"it was trained on another body than {known[0][0]} (an ensemble's members share one)",
                path=p,
                expected=body_text(known[0][1]),
                got=body_text(b),
            )
    ens = combine(models)
    seen: dict = {}  # (name, descriptor) -> openings, in the members' order
    for p in checkpoints:
        t = checkpoint_training_garments(p)
        if t is None:  # a member that does not say: the ensemble does not either
            seen = {}
            break
        for i, n in enumerate(t[0]):
            seen.setdefault((n, tuple(float(x) for x in t[1][i])), None if t[2] is None else t[2][i])
    extra: dict = {"members": [str(p) for p in checkpoints]}
    if known and len(known) == len(checkpoints):  # a member that does not say: the ensemble does not either
        extra["body"] = known[0][1]
    if seen:
        extra["training_garments"] = {
            "names": [k[0] for k in seen],
            "descriptors": [list(k[1]) for k in seen],
            "openings": None if None in seen.values() else list(seen.values()),
        }
    save_checkpoint(output, ens, **extra)
    guard.record()
    click.echo(f"{output}: {ens.cfg.ensemble} networks averaged")
