"""``segadeform motion make | info``."""

from __future__ import annotations

from pathlib import Path

import click
import numpy as np

from .main import cli


@cli.group("motion")
def motion_group():
    """Make and inspect motions (AMASS-style .npz, BVH)."""


@motion_group.command("make")
@click.argument("kind")
@click.option("--seconds", type=float, default=3.0, show_default=True)
@click.option("--fps", type=float, default=30.0, show_default=True)
@click.option("--seed", type=int, default=0, show_default=True)
@click.option("--speed", type=float, default=1.0, show_default=True, help="Cycle rate multiplier.")
@click.option("--amplitude", type=float, default=1.0, show_default=True, help="Joint angle scale (0..2).")
@click.option("--ease-in", type=float, default=1.0, show_default=True, help="Seconds to blend in from rest.")
@click.option("-o", "--output", required=True, type=click.Path(dir_okay=False, path_type=Path),
              help="Motion file (.npz, or .bvh).")
def make_cmd(kind, seconds, fps, seed, speed, amplitude, ease_in, output):
    """Make a procedural motion of KIND (idle, walk, run, jump, arm_swing, touch_high, torso_twist, dance)."""
    from segadeform.motion import make_motion, write_bvh

    m = make_motion(kind, seconds=seconds, fps=fps, seed=seed, speed=speed, amplitude=amplitude, ease_in=ease_in)
    if output.suffix.lower() == ".bvh":
        from segadeform.body.skeleton import default_rest_joints

        write_bvh(output, m, default_rest_joints(), scale=100.0)
    else:
        m.save(output)
    click.echo(f"{m.name}: {m.n_frames} frames at {m.fps:g} fps ({m.seconds:.2f} s) -> {output}")


@motion_group.command("info")
@click.argument("motion", type=click.Path(dir_okay=False, path_type=Path))
def info_cmd(motion):
    """Print frames, rate, duration and joint ranges of MOTION (.npz or .bvh)."""
    from segadeform.motion import load_motion
    from segadeform.motion.limits import limit_violation

    m = load_motion(motion)
    ang = np.linalg.norm(m.poses.reshape(-1, 24, 3), axis=-1)
    click.echo(f"{motion}: {m.n_frames} frames, {m.fps:g} fps, {m.seconds:.2f} s")
    click.echo(f"  root travel: {np.ptp(m.trans, axis=0).round(3).tolist()} m (x, y, z range)")
    click.echo(f"  largest joint rotation: {np.rad2deg(ang[:, 1:].max()):.1f} deg")
    click.echo(f"  outside joint limits by: {np.rad2deg(limit_violation(m.poses)):.2f} deg")
    if m.betas is not None:
        click.echo(f"  betas: {np.round(m.betas[:10], 3).tolist()}")
