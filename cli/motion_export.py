"""``segadeform motion export``: any motion segadeform reads -> a motion file (.sgdm) for the runtimes
without Python (Node, the browser, C++; the format: docs/package.md, ``segadeform.io.sgdb``)."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import click

from .main import PathParam, bvh_units_option
from .motion import motion_group


@motion_group.command("export")
@click.argument("source")
@click.option(
    "-o",
    "--output",
    required=True,
    type=PathParam(dir_okay=False, path_type=Path),
    help="The motion file to write (.sgdm).",
)
@click.option(
    "--body",
    type=PathParam(dir_okay=False, exists=True, path_type=Path),
    help="Retarget onto this body (default: the shipped body); the body the garment asset is for.",
)
@click.option("--betas", help="Comma-separated body shape coefficients (as for the garment asset).")
@click.option("--fps", type=float, help="Resample to this frame rate (procedural motions: made at it; default 30).")
@click.option(
    "--frames",
    help="Keep frames A:B (B exclusive): the file starts at A with nothing before it, so a player starts there "
    "afresh: its frames differ from `run --frames A:B`, which looks back before A and steps the collision and cloth "
    "stages over the frames before it (export from frame 0 for those).",
)
@click.option(
    "--up",
    type=click.Choice(["auto", "y", "z"]),
    default="auto",
    show_default=True,
    help="Up axis of a motion file (AMASS is z-up).",
)
@click.option(
    "--units",
    callback=bvh_units_option,
    help="BVH units: m, dm, cm, mm, inch, cmu or metres per unit (default: fit the legs).",
)
@click.option("--joint-map", type=PathParam(dir_okay=False, path_type=Path), help="BVH/AMC joint map (TOML/JSON).")
@click.option(
    "--skeleton",
    type=PathParam(dir_okay=False, path_type=Path),
    help="AMC motions: the ASF skeleton (default: the one .asf beside the .amc).",
)
@click.option("--floor", is_flag=True, help="Move the motion so the feet touch the floor.")
@click.option(
    "--repair-glitches",
    is_flag=True,
    help="Motion capture: hold the first settled pose over the frames the capture settles from and rebuild frames "
    "it jumps to and back from, as `segadeform run --repair-glitches` does (the frame count is kept).",
)
@click.option("--seconds", type=float, default=3.0, show_default=True, help="Procedural motions: duration.")
@click.option("--seed", type=int, default=0, show_default=True, help="Procedural motions: seed.")
@click.option("--speed", type=float, default=1.0, show_default=True, help="Procedural motions: cycle rate.")
@click.option("--amplitude", type=float, default=1.0, show_default=True, help="Procedural motions: joint angle scale.")
@click.option(
    "--animation", help="glTF (.glb/.gltf) and FBX motions: the animation (default: the first; FBX: the armature's)."
)
@click.option("--force", is_flag=True, help="Write it for a body shape no human has (as run and garment export take).")
def motion_export_cmd(
    source,
    output,
    body,
    betas,
    fps,
    frames,
    up,
    units,
    joint_map,
    skeleton,
    floor,
    repair_glitches,
    seconds,
    seed,
    speed,
    amplitude,
    animation,
    force,
):
    """Write SOURCE (a .bvh, .amc, .npz, .glb/.gltf or .fbx motion, or a procedural kind: idle, walk, dance, ...) as a
    motion file: poses (T, 24, 3) and translations (T, 3) on the body's skeleton, as `segadeform run` would play it.
    An FBX file is read through Blender, as `segadeform motion convert` reads it."""
    from segadeform.body import default_body_path, load_body
    from segadeform.body.identity import body_label
    from segadeform.errors import InputError
    from segadeform.io.sgdm import MOTION_SUFFIX
    from segadeform.motion import (
        MOTION_KINDS,
        MotionSpec,
        build_motion,
        glitches_in_range,
        select_frames,
        write_motion_file,
    )
    from segadeform.settings import parse_frames
    from segadeform.settings.scene import check_motion_fps

    from .main import option_value

    if output.suffix.lower() != MOTION_SUFFIX:
        raise click.UsageError(f"-o must end in {MOTION_SUFFIX}, got {output.name!r}")
    if fps is not None:  # naming the option, as `run --fps` does
        option_value(check_motion_fps, fps, option="--fps")
    try:
        beta_vals = tuple(float(x) for x in betas.split(",")) if betas else ()
    except ValueError:
        raise click.UsageError(f"--betas must be comma-separated numbers, got {betas!r}") from None
    from segadeform.io.output_guard import OutputGuard

    path = Path(source)
    guard = OutputGuard("motion export", inputs=(path, body, joint_map, skeleton))
    guard.file(output)
    fbx = path.suffix.lower() == ".fbx"
    if path.suffix.lower() in (".bvh", ".npz", ".amc", ".glb", ".gltf", ".fbx") or path.exists():
        spec = MotionSpec(
            file=path,
            animation=None if fbx else animation,
            fps=fps,
            up=up,
            units=units,
            joint_map=joint_map,
            floor=floor,
            skeleton=skeleton,
            repair_glitches=repair_glitches,
        )
    elif source in MOTION_KINDS:
        spec = MotionSpec(
            kind=source, seconds=seconds, fps=fps, seed=seed, speed=speed, amplitude=amplitude, floor=floor
        )
    else:
        raise InputError(
            "SOURCE is neither a motion file nor a procedural kind",
            expected=".bvh, .amc, .npz, .glb, .gltf, .fbx or one of " + ", ".join(MOTION_KINDS),
            got=source,
        )
    if animation is not None and spec.file is None:
        raise click.UsageError("--animation picks an animation of a glTF or FBX file; a procedural motion has none")
    if repair_glitches and spec.file is None:
        raise click.UsageError("--repair-glitches repairs motion capture; a procedural motion has no glitches")
    b = load_body(body or default_body_path())
    if not force:  # a shape no human has (--betas 4: a 2.86 m body), refused as run and garment export refuse it
        from segadeform.bounds import check_body_height

        check_body_height(b, beta_vals)
    from .motion_convert import bvh_up, fbx_as_bvh

    with fbx_as_bvh(path, animation if fbx else None) as read_from:  # an FBX file: the BVH Blender writes of it
        if fbx:  # the BVH made of an FBX is +Y up
            spec = dataclasses.replace(spec, file=read_from, up=bvh_up(spec.up))
        built = build_motion(spec, b.rest_joints(beta_vals)[0])
    settle, jumps = glitches_in_range(built, parse_frames(frames) if frames else None)
    m, first = select_frames(built, parse_frames(frames) if frames else None)
    full = [0.0] * b.n_betas
    full[: len(beta_vals)] = beta_vals
    first += int((m.meta or {}).get("start_frame", 0))  # a motion file cut before: numbers of its source
    said = (
        [
            f"the capture has {settle} leading frames it settles from and {jumps} frames it jumps to and back from "
            "(joints faster than 20 m/s), which throw the cloth about in every runtime; `motion export "
            "--repair-glitches` rebuilds them"
        ]
        if settle or jumps
        else []
    )
    # kept in the file for the runtimes that play it to say again (Node and C++ said nothing: a developer's trial)
    write_motion_file(output, m, body=body_label(b), betas=full, source=str(source), start_frame=first, warnings=said)
    guard.record()
    for w in said:  # what `run` warns of, said where the file is made
        click.echo(f"warning: {w}", err=True)
    if first > int((built.meta or {}).get("start_frame", 0)):  # said, as a user took it for run --frames A:B
        click.echo(
            f"note: the file starts at frame {first} with no motion before it: played, its frames differ from "
            f"`segadeform run --frames {first}:...`, which looks back before frame {first} and steps the collision "
            "and cloth stages over the frames before it (export from frame 0 for those)",
            err=True,
        )
    click.echo(
        f"{m.name}: {m.n_frames} frames at {m.fps:g} fps ({m.seconds:.2f} s) on "
        f"{body_label(b)['name'] or 'the body'} -> {output}"
    )
