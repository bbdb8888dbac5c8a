"""``segadeform export``: checkpoint (or a random initialisation) -> model package."""

from __future__ import annotations

import json
from pathlib import Path

import click

from .main import PathParam, cli

_inline_weights_option = click.option(
    "--inline-weights",
    is_flag=True,
    help="Self-contained graph files (each with its own weights) instead of one shared weights.bin.",
)


_TRAINING_OPTIONS = {
    "garments": (
        "training_files",
        "Garment mesh files the model was trained on (repeatable); recorded in the manifest so runtimes warn about "
        "garments far from all of them.",
    ),
    "motions": (
        "training_motions",
        "A dataset config (.toml) whose training split's motions the model was trained on (repeatable): their "
        "fingerprints are recorded in the manifest, so `eval` says when a sample it scores plays one of them.",
    ),
}


def _training_option(what: str, default: str):
    """``--training-garments`` / ``--training-motions`` (export and repack), the default named in the help."""
    dest, text = _TRAINING_OPTIONS[what]
    return click.option(
        f"--training-{what}",
        dest,
        multiple=True,
        type=PathParam(dir_okay=False, exists=True, path_type=Path),
        help=f"{text}  Default: {default}.",
    )


@cli.command("export")
@click.argument("checkpoint", required=False, type=PathParam(dir_okay=False, path_type=Path))
@click.option(
    "-o",
    "--output",
    required=True,
    type=PathParam(file_okay=False, path_type=Path),
    help="Model package directory to write.",
)
@click.option("--random-init", is_flag=True, help="Export a randomly initialised model (for tests).")
@click.option(
    "--config",
    "config_json",
    default=None,
    help='ModelConfig overrides as JSON (with --random-init), e.g. \'{"skinning": "dqs"}\'.',
)
@click.option("--seed", type=int, default=0, show_default=True, help="Seed for --random-init.")
@click.option(
    "--check/--no-check",
    default=True,
    show_default=True,
    help="Compare torch and onnxruntime on random inputs and print the errors.",
)
@click.option("--legacy", is_flag=True, help="Use the legacy (TorchScript) exporter instead of dynamo.")
@click.option(
    "--variants/--no-variants",
    default=True,
    show_default=True,
    help="Also export a deformer for every other combination of skinning, dynamics and wrinkles (--no-variants: "
    "the model's own only, a smaller package whose runtimes refuse the other effects).",
)
@click.option(
    "--body",
    type=PathParam(dir_okay=False, exists=True, path_type=Path),
    help="The body the model was trained on (.npz/.pkl), exported as the package's body graphs (default: the "
    "shipped body).  A checkpoint that records another body is refused: runtimes take the package's body for "
    "the model's.",
)
@_inline_weights_option
@_training_option("garments", "what the checkpoint records")
@_training_option("motions", "what the checkpoint records")
def export_cmd(
    checkpoint,
    output,
    random_init,
    config_json,
    seed,
    check,
    legacy,
    variants,
    body,
    inline_weights,
    training_files,
    training_motions,
):
    """Export CHECKPOINT (or --random-init) to an ONNX model package (needs the 'torch' extra)."""
    try:
        import torch
    except ImportError:
        raise click.ClickException("export needs the 'torch' extra: pip install 'segadeform[torch]'") from None
    from segadeform.errors import InputError
    from segadeform.export import export_package
    from segadeform.model import ModelConfig, load_checkpoint
    from segadeform.model.ensemble import build_model

    if (checkpoint is None) == (not random_init):
        raise click.UsageError("give a CHECKPOINT or --random-init (not both)")
    guard = _package_guard(output, (checkpoint, body, *training_files, *training_motions))
    if random_init:
        try:
            overrides = json.loads(config_json) if config_json else {}
        except json.JSONDecodeError as e:
            raise InputError(f"--config is not valid JSON ({e.msg})", got=config_json) from None
        if not isinstance(overrides, dict):
            raise InputError("--config must be a JSON object", got=config_json)
        import dataclasses

        cfg = ModelConfig.from_dict({**dataclasses.asdict(ModelConfig()), **overrides})
        torch.manual_seed(seed)
        model = build_model(cfg)
    else:
        if config_json:
            raise click.UsageError("--config applies to --random-init only (a checkpoint carries its config)")
        model = load_checkpoint(checkpoint)
    body_model, trained = _export_body(checkpoint, body)
    extra = {}
    if trained is not None:  # the record of the model's body, which export-body --force does not replace
        extra["training_body"] = trained
    garments = _training_garments(training_files, model.cfg.n_star)
    if garments is None and checkpoint is not None:
        from segadeform.model.network import checkpoint_training_garments

        garments = checkpoint_training_garments(checkpoint)
    if garments is not None:
        from segadeform.export.training_set import training_garments_entry

        extra["training_garments"] = training_garments_entry(*garments)
    motions = _training_motions(training_motions, checkpoint)
    if motions is not None:
        extra["training_motions"] = motions
    m = export_package(
        model,
        output,
        dynamo=not legacy,
        check=check,
        variants=variants,
        shared_weights=not inline_weights,
        extra_manifest=extra,
        body=body_model,
        progress=lambda line: click.echo(line, err=True),
    )
    guard.record()
    click.echo(
        f"{output}: {len(m['graphs'])} graphs (default {m['default_deformer']}), manifest.json, "
        f"{_size(output) / 1e6:.2f} MB (opset {m['opset']}, {m['exporter']} exporter"
        f"{', weights shared in ' + m['weights']['file'] if 'weights' in m else ''})"
    )
    if check:
        for g, outs in m["parity"].items():
            for o, e in outs.items():
                click.echo(f"  {g}.{o}: max abs {e['max_abs']:.3g}, max rel {e['max_rel']:.3g} (torch vs onnxruntime)")


@cli.command("quantize")
@click.argument("package", type=PathParam(file_okay=False, exists=True, path_type=Path, package=True))
@click.option(
    "-o", "--output", required=True, type=PathParam(file_okay=False, path_type=Path), help="The new package folder."
)
@click.option(
    "--precision",
    type=click.Choice(["int8", "fp16-weights"]),
    default="int8",
    show_default=True,
    help="int8: onnxruntime dynamic quantisation (weights int8, inputs and outputs float32); "
    "fp16-weights: weights stored as float16, arithmetic float32 (half the file, fp32 speed).",
)
def quantize_cmd(package, output, precision):
    """Copy model PACKAGE at another precision (needs the 'torch' extra for onnx)."""
    try:
        import onnx  # noqa: F401 (only whether the extra is installed)
    except ImportError:
        raise click.ClickException("quantize needs onnx: pip install 'segadeform[torch]'") from None
    from segadeform.export.precision import convert_package

    guard = _package_guard(output, (package,))
    convert_package(package, output, precision)
    guard.record()
    click.echo(f"{output}: {precision} package, graphs {_size(output) / 1e6:.1f} MB")


@cli.command("repack")
@click.argument("package", type=PathParam(file_okay=False, exists=True, path_type=Path, package=True))
@click.option(
    "-o", "--output", required=True, type=PathParam(file_okay=False, path_type=Path), help="The new package folder."
)
@_inline_weights_option
@_training_option("garments", "the package's own list")
@_training_option("motions", "the package's own record")
@click.option(
    "--opset",
    type=click.IntRange(15, 21),
    default=None,
    help="Convert every graph to this ONNX opset (default: the exporter's, 18); 15 for Unity Sentis.",
)
def repack_cmd(package, output, inline_weights, training_files, training_motions, opset):
    """Rewrite model PACKAGE (any schema) in the current layout, same graphs (needs onnx)."""
    try:
        import onnx  # noqa: F401 (only whether the extra is installed)
    except ImportError:
        raise click.ClickException("repack needs onnx: pip install 'segadeform[torch]'") from None
    from segadeform.contracts import model_package as contract
    from segadeform.export.packing import repack_package

    guard = _package_guard(output, (package, *training_files, *training_motions))
    before = _size(package)
    garments = _training_garments(
        training_files,
        contract.read_manifest_text((package / contract.MANIFEST_FILE).read_text(encoding="utf-8"))["config"]["n_star"],
    )
    entry = None
    if garments is not None:
        from segadeform.export.training_set import training_garments_entry

        entry = training_garments_entry(*garments)
    m = repack_package(
        package,
        output,
        shared=not inline_weights,
        training_garments=entry,
        training_motions=_training_motions(training_motions, None),
        opset=opset,
    )
    guard.record()
    click.echo(
        f"{output}: schema {m['schema_version']}, opset {m['opset']}, {len(m['graphs'])} graphs, "
        f"{before / 1e6:.2f} MB -> {_size(output) / 1e6:.2f} MB"
    )


def _export_body(checkpoint, body):
    """``(body, trained)``: the body whose graphs the package gets (``--body`` or the shipped one) and the body the
    checkpoint records it was trained on (``{"name", "sha256"}``, or None).  Another body than the recorded one is
    refused (a model trained on a second body was exported with the first's graphs, and runtimes posed the first under
    it).  A checkpoint that records no body (written before training recorded it, or --random-init) takes the body
    given."""
    from segadeform.body import default_body_path, load_body
    from segadeform.body.identity import body_text, other_body
    from segadeform.errors import InputError

    b = load_body(body or default_body_path())
    if checkpoint is None:
        return b, None
    from segadeform.model.network import checkpoint_body

    trained = checkpoint_body(checkpoint)
    mine = other_body(trained, b)
    if mine is not None:
        raise InputError(
            "the checkpoint was trained on another body than "
            + ("--body's" if body else "the shipped one (export's default; give its body with --body)"),
            path=checkpoint,
            expected=body_text(trained),
            got=body_text(mine),
        )
    return b, trained


def _package_guard(output, inputs):
    """The output rule for a model package folder (segadeform.io.output_guard): a new or empty folder, or one
    holding only a package segadeform wrote (kind "package": export, repack, quantize, export-body), replaced."""
    from segadeform.io.output_guard import OutputGuard

    guard = OutputGuard("package", inputs=inputs)
    guard.folder(output)
    return guard


def _training_garments(files, n_star: int):
    """``(names, descriptors)`` of the garment files given, or None when none are."""
    if not files:
        return None
    from segadeform.export.training_set import mesh_descriptors

    return mesh_descriptors(files, n_star)


def _training_motions(configs, checkpoint) -> dict | None:
    """The ``training_motions`` record: the training split's motions of the dataset ``configs`` when any are
    given, else what ``checkpoint`` records (None: nothing to record)."""
    if configs:
        from segadeform.dataset.make import config_training_motions

        return config_training_motions(configs)
    if checkpoint is None:
        return None
    from segadeform.model.network import checkpoint_training_motions

    return checkpoint_training_motions(checkpoint)


def _size(folder) -> int:
    """Bytes of a package's graph and weights files."""
    return sum(f.stat().st_size for f in Path(folder).iterdir() if f.is_file() and f.suffix in (".onnx", ".bin"))
