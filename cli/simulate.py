"""``segadeform simulate`` (ground truth by cloth simulation) and ``segadeform garment make``."""

from __future__ import annotations

import dataclasses
import sys
from pathlib import Path

import click

from .main import cli


@cli.command("simulate")
@click.argument("scene", type=click.Path(dir_okay=False, path_type=Path))
@click.option("-o", "--output", type=click.Path(path_type=Path), help="Output (overrides the scene's).")
@click.option("--effects", help="Comma-separated simulation effects, replacing the scene's (e.g. "
                                "'gravity,body_collision'); 'none' for none.")
@click.option("--material", help="Material preset (cotton, silk, denim, jersey, leather).")
@click.option("--quality", type=click.IntRange(1, 80), help="Solver steps per frame.")
@click.option("--frames", help="Frame range A:B of the motion (B exclusive).")
@click.option("--sim-python", type=click.Path(dir_okay=False, path_type=Path),
              help="The simulator environment's Python (default: SEGADEFORM_SIM_PYTHON or .venv-sim).")
def simulate_cmd(scene, output, effects, material, quality, frames, sim_python):
    """Simulate SCENE.toml's garment on its body with Blender's cloth solver; write it like `run`."""
    from segadeform.physics import SimSettings
    from segadeform.physics.scene_sim import simulate_scene
    from segadeform.scene import SEQUENCE_FORMAT_BY_EXT, load_scene, parse_frames

    sc = load_scene(scene)
    st = sc.simulate or SimSettings()
    kw = {}
    if effects is not None:
        kw["effects"] = () if effects.strip() == "none" else tuple(e.strip() for e in effects.split(",") if e.strip())
    if material:
        kw["material"] = material
    if quality:
        kw["quality"] = quality
    st = st.replace(**kw) if kw else st
    changes = {}
    if frames:
        changes["motion"] = dataclasses.replace(sc.motion, frames=parse_frames(frames))
    if output is not None:
        fmt = SEQUENCE_FORMAT_BY_EXT.get(output.suffix.lower())
        if fmt is None:
            raise click.UsageError(f"cannot tell the output format from {output.name!r}")
        changes["output_format"] = fmt
    sc = dataclasses.replace(sc, **changes)
    interactive = sys.stderr.isatty()
    with click.progressbar(length=1, label="simulating", file=sys.stderr, hidden=not interactive) as bar:
        def progress(done, total):
            bar.length = total
            bar.update(done - bar.pos)

        s = simulate_scene(sc, output=output, settings=st, sim_python=sim_python,
                           progress=progress if interactive else None)
    r = s.result
    click.echo(f"{s.frames} frames (+{r.preroll_frames} pre-roll), {r.seconds_per_frame:.3f} s/frame in Blender "
               f"{r.blender['blender_version']} ({', '.join(st.effects) or 'no effects'}; {st.material}, "
               f"quality {st.quality}) -> {s.output}")


@cli.group("garment")
def garment_group():
    """Procedural garments."""


@garment_group.command("make")
@click.argument("kind")
@click.option("-o", "--output", required=True, type=click.Path(dir_okay=False, path_type=Path), help="Output OBJ.")
@click.option("--body", type=click.Path(dir_okay=False, path_type=Path), help="Body .npz (default: shipped body).")
@click.option("--betas", help="Comma-separated body shape coefficients.")
@click.option("--length", type=float, help="Skirt hem / trouser leg length, 0..1 of hip-to-ankle.")
@click.option("--flare", type=float, default=0.25, show_default=True, help="Skirt widening at the hem.")
@click.option("--ease", type=float, default=0.015, show_default=True, help="Metres between skin and cloth.")
@click.option("--sleeve", type=float, help="Sleeve length, 0..1 of shoulder-to-wrist.")
@click.option("--resolution", type=int, help="Target vertex count (picks the refinement level).")
def garment_make_cmd(kind, output, body, betas, length, flare, ease, sleeve, resolution):
    """Make a KIND garment dressed on the body in rest pose (kinds: see `segadeform garment kinds`)."""
    from segadeform.body import load_body
    from segadeform.garments import GarmentParams, check_garment, make_garment
    from segadeform.io import Mesh, write_obj
    from segadeform.body import default_body_path

    try:
        b = tuple(float(x) for x in betas.split(",")) if betas else None
    except ValueError:
        raise click.UsageError(f"--betas must be comma-separated numbers, got {betas!r}") from None
    bm = load_body(body or default_body_path())
    g = make_garment(kind, bm, b, GarmentParams(length=length, flare=flare, ease=ease, sleeve=sleeve,
                                                  resolution=resolution))
    info = check_garment(g.vertices, g.faces, bm, b)
    write_obj(output, Mesh(vertices=g.vertices, faces=g.faces), header=g.header())
    click.echo(f"{kind} ({g.type}): {info['vertices']} vertices, {info['faces']} triangles, "
               f"{info['boundary_loops']} openings, clearance >= {1e3 * info['min_clearance']:.1f} mm -> {output}")


@garment_group.command("kinds")
def garment_kinds_cmd():
    """List the garment kinds and their type labels."""
    from segadeform.garments import GARMENT_TYPES

    for k, t in GARMENT_TYPES.items():
        click.echo(f"{k:14s} {t}")
