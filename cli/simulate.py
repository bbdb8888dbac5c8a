"""``segadeform simulate``: ground truth by cloth simulation (Blender, out of process), written like ``run``."""

from __future__ import annotations

import dataclasses
import sys
from pathlib import Path

import click

from .main import PathParam, cli


@cli.command("simulate")
@click.argument("scene", type=PathParam(dir_okay=False, path_type=Path))
@click.option("-o", "--output", type=PathParam(path_type=Path), help="Output (overrides the scene's).")
@click.option(
    "--effects",
    help="Simulation effects, as for run: a complete list replaces the scene's "
    "(e.g. 'gravity,body_collision'; 'none' for none), signed items change it "
    "(e.g. '+wind,-bending').  A scene without [simulate] starts from "
    "gravity, body_collision, bending, air_damping.",
)
@click.option("--material", help="Material preset (cotton, silk, denim, jersey, leather).")
@click.option("--quality", type=click.IntRange(1, 80), help="Solver steps per frame.")
@click.option("--frames", help="Frame range A:B of the motion (B exclusive).")
@click.option(
    "--body-out",
    type=PathParam(path_type=Path),
    help="Write the posed body here (overrides the scene's output.body), in the format its extension names.",
)
@click.option(
    "--sim-python",
    type=PathParam(dir_okay=False, path_type=Path),
    help="The simulator environment's Python (default: SEGADEFORM_SIM_PYTHON or .venv-sim).",
)
@click.option(
    "--force",
    is_flag=True,
    help="Write into an output folder that holds other files (beside them, never "
    "over a file segadeform did not write).",
)
def simulate_cmd(scene, output, effects, material, quality, frames, body_out, sim_python, force):
    """Simulate SCENE.toml's garment on its body with Blender's cloth solver; write it like `run`."""
    from segadeform.io.outputs import output_format_for
    from segadeform.physics import SimSettings
    from segadeform.physics.scene_sim import simulate_scene
    from segadeform.settings import load_scene, parse_frames
    from segadeform.settings.simulation import parse_sim_effects

    if effects is not None:  # the list's own mistakes are the command line's (exit 2), as run's --effects
        from segadeform.settings.simulation import DEFAULT_EFFECTS

        from .main import option_value

        option_value(lambda text: parse_sim_effects(text, DEFAULT_EFFECTS), effects, option="--effects")
    sc = load_scene(scene, sim_effects=effects)  # its [simulate] knobs judged against the effects that will run
    st = sc.simulate or SimSettings()
    kw = {}
    if effects is not None:
        kw["effects"] = parse_sim_effects(effects, st.effects)
    if material:
        kw["material"] = material
    if quality:
        kw["quality"] = quality
    st = st.replace(**kw) if kw else st
    changes = {}
    if frames:
        changes["motion"] = dataclasses.replace(sc.motion, frames=parse_frames(frames))
    if output is not None:
        changes["output_format"] = output_format_for(output)
        changes["output"] = output
    if body_out is not None:  # (a scene's body path that `run` wrote is another command's output: move it)
        changes["body_output"] = body_out
    sc = dataclasses.replace(sc, **changes)
    interactive = sys.stderr.isatty()
    with click.progressbar(length=1, label="simulating", file=sys.stderr, hidden=not interactive) as bar:

        def progress(done, total):
            bar.length = total
            bar.update(done - bar.pos)

        from segadeform.io.output_guard import OutputGuard

        guard = OutputGuard(
            "simulate",
            force=force,
            inputs=(scene, sc.garment, sc.motion.file, sc.body, sc.motion.joint_map, sc.motion.skeleton),
        )
        s = simulate_scene(
            sc,
            output=output,
            settings=st,
            sim_python=sim_python,
            progress=progress if interactive else None,
            guard=guard,
            frames_from_scene=not frames,
        )
    r = s.result
    ran = (r.blender.get("applied") or {}).get("cloth", {}).get("quality", st.quality)  # what Blender ran with
    quality = f"quality {ran}" + (
        f" (raised from {st.quality} for the clip's fast frames)" if ran != st.quality else ""
    )
    click.echo(
        f"{s.frames} frames (+{r.preroll_frames} pre-roll), {r.seconds_per_frame:.3f} s/frame in Blender "
        f"{r.blender['blender_version']} ({', '.join(st.effects) or 'no effects'}; {st.material}, {quality})"
    )
    for path in s.written:
        click.echo(f"  wrote {path}")
