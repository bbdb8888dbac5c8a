"""``segadeform bundle``: a scene's model inputs for runtimes in other languages (and the test vector)."""

from __future__ import annotations

from pathlib import Path

import click

from .main import PathParam, cli


@cli.command("bundle")
@click.argument("scene", type=PathParam(dir_okay=False, path_type=Path))
@click.option("-o", "--output", required=True, type=PathParam(dir_okay=False, path_type=Path), help="OUT.sgdb")
@click.option("--model", type=PathParam(file_okay=False, path_type=Path, package=True), help="Model package directory.")
@click.option("--no-expected", is_flag=True, help="Leave out the Python runtime's output.")
@click.option(
    "--frames",
    help="Frame range A:B of the motion (B exclusive): the bundle's motion starts at A, with no look-back before it "
    "(as `motion export --frames A:B`), so with dynamics its first frames differ from `run --frames A:B` (which "
    "looks back) by up to about a millimetre; the bundle's own parity frames are computed the same way.",
)
@click.option("--force", is_flag=True, help="Bundle a garment even when it does not sit on the body.")
def bundle_cmd(scene, output, model, no_expected, frames, force):
    """Write SCENE's garment, body-shape and motion inputs as a bundle (docs/package.md) for Node, browser
    and C++ runtimes, with the Python runtime's output as the parity vector."""
    import dataclasses

    from segadeform.io.output_guard import OutputGuard
    from segadeform.runtime.scene_bundle import scene_bundle
    from segadeform.settings import load_scene, parse_frames

    sc = load_scene(scene)
    guard = OutputGuard("bundle", inputs=(scene, sc.garment, sc.motion.file, sc.body, model or sc.model))
    guard.file(output)
    if frames:
        sc = dataclasses.replace(sc, motion=dataclasses.replace(sc.motion, frames=parse_frames(frames)))
    from .motion_convert import motion_spec_read

    with motion_spec_read(sc.motion) as motion:  # an FBX file: the BVH Blender makes of it, as `run` reads it
        p = scene_bundle(
            dataclasses.replace(sc, motion=motion), output, model=model, expected=not no_expected, force=force
        )
    guard.record()
    click.echo(f"wrote {p}")
    if sc.units != 1.0:  # the runtimes write metres (a review: a scene's units were dropped without a word)
        click.echo(
            f"note: the scene's output units ({sc.units:g} m per unit) are not in the bundle: Node and C++ write "
            "metres",
            err=True,
        )
    e = sc.effects
    post = [n for n, on in (("collisions", e.collisions), ("cloth", e.cloth)) if on]
    if post:  # the host runtime's post-processes: not in the bundle, named on its command line with their knobs
        knobs = f" --collision-margin {e.collision_margin:g}" if e.collision_margin != 0.004 else ""
        if e.cloth and e.cloth_settings.label():  # (a scene's margin and cloth knobs were left out: 6-7 mm off)
            knobs += f" --cloth {e.cloth_settings.label()}"
        click.echo(
            f"note: the scene's {' and '.join(post)} are not in the bundle (a bundle plays the network alone): to "
            "run them in Node or C++, export the garment and motion (`segadeform garment export`, `segadeform "
            "motion export`) and pass segadeform-node or segadeform-run --package/--garment/--motion with --effects "
            f"{e.skinning},{'dynamics,' if e.dynamics else ''}"
            f"{'wrinkles,' if e.wrinkles else ''}{','.join(post)}{knobs}",
            err=True,
        )
