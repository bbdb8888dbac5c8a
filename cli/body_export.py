"""``segadeform export-body``: a body file -> the body graphs of a model package (docs/package.md)."""

from __future__ import annotations

from pathlib import Path

import click

from .main import PathParam, cli


@cli.command("export-body")
@click.argument("body", required=False, type=PathParam(dir_okay=False, exists=True, path_type=Path))
@click.option(
    "-o",
    "--output",
    required=True,
    type=PathParam(file_okay=False, exists=True, path_type=Path),
    help="The model package to give the body graphs (replaced in place, atomically).",
)
@click.option(
    "--to",
    "copy_to",
    type=PathParam(file_okay=False, path_type=Path),
    help="Write the package with the body graphs here instead of replacing it.",
)
@click.option(
    "--force",
    is_flag=True,
    help="Give the package another body than its model's training body (the manifest's training_body, else the "
    "body its body graphs record).",
)
def export_body_cmd(body, output, copy_to, force):
    """Export BODY (.npz or SMPL .pkl; default: the shipped body) as the package's body graphs body_lbs and
    body_dqs: betas, poses and translations in, posed vertices, joints, rest joints and triangles out, so
    runtimes without Python pose the body (needs the 'torch' extra).  The package records the body its model was
    trained on (`segadeform run` refuses another): another body needs --force, and the record stays."""
    try:
        import torch  # noqa: F401
    except ImportError:
        raise click.ClickException("export-body needs the 'torch' extra: pip install 'segadeform[torch]'") from None
    from segadeform.body import default_body_path, load_body
    from segadeform.export.body import add_body_to_package
    from segadeform.io.output_guard import OutputGuard, OutputRefused

    if copy_to is not None:
        guard = OutputGuard("package", inputs=(body, output))
        guard.folder(copy_to)
    else:  # in place: only a package segadeform wrote (its manifest lists every file) is rewritten
        guard = OutputGuard("package", inputs=(body,))
        try:
            guard.folder(output)
        except OutputRefused as e:
            raise OutputRefused(
                f"{e.problem}; export-body replaces only a package segadeform wrote",
                path=output,
                expected="--to NEW_DIR to write the package with the body graphs there",
                got="a package segadeform did not write",
            ) from None
    b = load_body(body or default_body_path())
    if not force:  # the record of the model's body (a review: this replaced it without a word)
        import json

        from segadeform.body.identity import body_text, other_body
        from segadeform.errors import InputError
        from segadeform.runtime.body import manifest_body

        try:
            recorded = manifest_body(json.loads((output / "manifest.json").read_text()))
        except (OSError, ValueError):
            recorded = None  # not a package: add_body_to_package says so
        mine = other_body(recorded, b)
        if mine is not None:
            raise InputError(
                "the package's model was trained on another body than BODY (its body graphs record it)",
                path=output,
                expected=f"{body_text(recorded or {})}, or --force to give it another",
                got=body_text(mine),
            )
    m = add_body_to_package(output, b, copy_to)
    guard.record()
    names = sorted(k for k, g in m["graphs"].items() if g["role"] == "body")
    click.echo(
        f"{copy_to or output}: body graphs {', '.join(names)} of {Path(b.path).name if b.path else 'the body'} "
        f"({b.n_vertices} vertices, {len(b.faces)} triangles, {b.n_betas} betas)"
    )
