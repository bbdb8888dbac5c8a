"""``segadeform run``: animate a garment (a scene file or the flag form)."""

from __future__ import annotations

import sys
from pathlib import Path

import click

from segadeform.io.writer import UP_AXES

from .main import PathParam, bvh_units_option, cli, usable_threads


def _fmt_from(path: Path, fmt: str | None) -> str:
    """-o's format: --format, else the extension's; an error naming the writable ones when neither says (glTF
    is read, not written), or when --format contradicts the extension."""
    from segadeform.io.outputs import output_format_for

    return output_format_for(path, fmt)


def _betas_from(betas: str, body, force: bool) -> tuple:
    """--betas as numbers, checked as the run shapes ``body`` with them (within the shape space; unless ``force``, a
    human's height and a skin that does not fold through itself): errors name the option."""
    from segadeform.body import default_body_path, load_body
    from segadeform.bounds import check_betas, check_body_height
    from segadeform.errors import InputError

    try:
        vals = tuple(float(x) for x in betas.split(","))
    except ValueError:
        raise click.UsageError(f"--betas must be comma-separated numbers, got {betas!r}") from None
    vals = check_betas(vals, what="--betas")
    b = load_body(body or default_body_path())
    try:
        check_body_height(b, vals, force=force)
    except InputError as e:
        raise InputError(f"--betas: {e.problem}", expected=e.expected, got=e.got) from None
    return vals


def _format_choice():
    from segadeform.io import SEQUENCE_FORMATS

    return click.Choice(list(SEQUENCE_FORMATS))


def _quality_choice():
    from segadeform.settings.presets import QUALITY_PRESETS

    return click.Choice(list(QUALITY_PRESETS))


def _effects_option(text, base=None, *, check_only: bool = False):
    """``--effects``: :func:`parse_effects`, its errors naming the option (an unknown effect named none);
    ``check_only``: the list's own rule only (what a scene's reading then applies)."""
    from segadeform.errors import InputError
    from segadeform.settings.effects import DEFAULT_EFFECTS, EFFECT_NAMES, parse_effect_list, parse_effects

    try:
        if check_only:
            return parse_effect_list(text, EFFECT_NAMES, choices=("lbs", "dqs"))
        return parse_effects(text, DEFAULT_EFFECTS if base is None else base)
    except InputError as e:
        if e.path is not None:  # (a scene's own list: the file's problem, exit 1)
            raise type(e)(f"--effects: {e.problem}", path=e.path, line=e.line, expected=e.expected, got=e.got) from None
        # a command-line mistake, exit 2 (an unknown effect exited 1: a QA trial), as Node and C++ say it
        detail = ", ".join(f"{k} {v}" for k, v in (("expected", e.expected), ("got", e.got)) if v is not None)
        raise click.BadParameter(e.problem + (f" ({detail})" if detail else ""), param_hint="'--effects'") from None


@cli.command("run")
@click.argument("scene", required=False, type=PathParam(dir_okay=False, path_type=Path))
@click.option("-o", "--output", type=PathParam(path_type=Path), help="Output (overrides the scene's).")
@click.option("--garment", type=PathParam(dir_okay=False, path_type=Path), help="Garment mesh (flag form).")
@click.option(
    "--motion",
    "motion_path",
    type=PathParam(dir_okay=False, path_type=Path),
    help="Motion .npz/.bvh/.amc/.glb/.gltf/.sgdm, or .fbx through Blender (flag form; CMU's .amc at 120 fps).",
)
@click.option(
    "--body",
    type=PathParam(dir_okay=False, path_type=Path),
    help="Body .npz/.pkl (default: shipped body); a body other than the one the model package's body graphs pose "
    "is refused without --force.",
)
@click.option("--betas", help="Comma-separated body shape coefficients.")
@click.option("--effects", help="e.g. 'dqs,-wrinkles,-collisions' (default: lbs, all effects on).")
@click.option(
    "--quality",
    type=_quality_choice(),
    help="A preset from the measured accuracy/time frontier (segadeform.settings.presets, "
    "docs/accuracy-vs-time.md); replaces the scene's effects; --effects may then only change "
    "it (+name/-name).",
)
@click.option(
    "--cloth",
    "cloth",
    metavar="NAME=VALUE,..",
    help="The cloth stage's knobs (iterations, stiffness, stretch, compress, bending, damping, follow, "
    "gravity, attachment, max_distance, reset, backstop: segadeform.settings.cloth) over the scene's; the "
    "stage is on when the scene or --effects names it (--effects=+cloth).",
)
@click.option(
    "--collision-margin",
    "collision_margin",
    type=float,
    metavar="M",
    help="Metres the push-out keeps the garment off the body, with collisions or the cloth stage on (default "
    "0.004; over the scene's collision_margin), as Node's and C++'s --collision-margin.",
)
@click.option(
    "--format",
    "fmt",
    type=_format_choice(),
    help="Output format (see segadeform.io.formats; abc needs the 'alembic' extra).  A .usda (text) and xdmf are "
    "built in memory, the whole clip (a .usda about 12 bytes per vertex per frame, garment and body each; a .usd is "
    "written as it runs): use .pc2, .abc or .usd for long clips.",
)
@click.option("--model", type=PathParam(file_okay=False, path_type=Path, package=True), help="Model package directory.")
@click.option("--frames", help="Frame range A:B of the motion (B exclusive).")
@click.option("--fps", type=float, help="Resample the motion to this frame rate.")
@click.option(
    "--batch",
    type=click.IntRange(min=1),
    default=8,
    show_default=True,
    help="Frames per deformer call, at most (big garments use fewer: <= 32,768 vertex-frames per call).",
)
@click.option(
    "--resolution",
    type=click.FloatRange(min=0.0, max=1.0, min_open=True),
    help="Share of the garment's vertices the model runs on: the garment decimated, the frames carried back to every "
    "vertex of the file (collisions, the cloth stage and the outputs stay at full resolution); 0.5 is on the measured "
    "accuracy/time frontier (docs/accuracy-vs-time.md).  Default: the scene's [model] resolution, else 1.",
)
@click.option("--threads", type=click.IntRange(min=1), default=1, show_default=True, help="onnxruntime threads.")
@click.option("--providers", help="Comma-separated onnxruntime providers, or 'auto' (default: CPU).")
@click.option(
    "--body-out",
    type=PathParam(path_type=Path),
    help="Also write the posed body sequence here, in the format its extension names (.pc2 also writes the "
    "body's rest mesh beside it as .obj; no extension: a folder of OBJ frames).",
)
@click.option("--up", type=click.Choice(UP_AXES), help="Up axis of the written coordinates (default y).")
@click.option(
    "--output-units",
    metavar="UNITS",
    help="Units of the written coordinates: m (default, as computed), dm, cm (Maya, Unreal), mm, inch, ft, or "
    "metres per unit; the body's (--body-out) too.  USD records them (metersPerUnit); PC2, OBJ, Alembic and "
    "XDMF have no field for them: preview and import them in the same units.",
)
@click.option(
    "--no-cache",
    is_flag=True,
    help="Do not use the user cache of precompute/encoder results "
    "($SEGADEFORM_CACHE_DIR or the platform's cache folder).",
)
@click.option(
    "--motion-up",
    type=click.Choice(["auto", "y", "z"]),
    help="Up axis of the motion file (default auto; AMASS is z-up).",
)
@click.option(
    "--units",
    callback=bvh_units_option,
    help="BVH units: m, dm, cm, mm, inch, cmu or metres per unit (default: fit the legs).",
)
@click.option(
    "--joint-map",
    type=PathParam(dir_okay=False, path_type=Path),
    help='BVH joint map (TOML/JSON: smpl_name = "FileJoint") for skeletons not recognised.',
)
@click.option(
    "--skeleton",
    type=PathParam(dir_okay=False, path_type=Path),
    help="AMC motions: the ASF skeleton (default: the one .asf beside the .amc).",
)
@click.option(
    "--animation",
    help="glTF (.glb/.gltf) and FBX motions: the animation to play (default: the first; FBX: the armature's own).",
)
@click.option("--floor", is_flag=True, default=None, help="Move the motion so the feet touch the floor.")
@click.option(
    "--repair-glitches",
    is_flag=True,
    default=None,
    help="Motion capture: hold the first settled pose over the frames the capture settles from and rebuild "
    "frames it jumps to and back from (faster than 20 m/s); the frame count is kept.",
)
@click.option(
    "--force",
    is_flag=True,
    help="Write into an output folder that holds other files (beside them, never "
    "over a file segadeform did not write: segadeform.io.output_guard), and accept inputs that do not fit "
    "the body: a garment off it, a body no human's height, an asset or motion file made for another "
    "shape, a model package made for another body (--body).",
)
@click.option(
    "--body-backend",
    type=click.Choice(["auto", "graph", "numpy"]),
    default="auto",
    show_default=True,
    help="How the body is posed for collisions and --body-out: the package's body graph (float32, as "
    "every other runtime), numpy (float64), or auto: the graph when it poses this body, else numpy.",
)
def run_cmd(
    scene,
    output,
    garment,
    motion_path,
    body,
    betas,
    effects,
    quality,
    fmt,
    model,
    frames,
    fps,
    batch,
    threads,
    providers,
    body_out,
    up,
    no_cache,
    motion_up,
    units,
    joint_map,
    skeleton,
    animation,
    floor,
    repair_glitches,
    force,
    body_backend,
    cloth=None,
    collision_margin=None,
    resolution=None,
    output_units=None,
):
    """Animate a garment: SCENE.toml, or the flag form --garment G --motion M -o OUT."""
    import dataclasses

    from segadeform.io.writer import output_unit
    from segadeform.runtime.pipeline import MAX_VERTEX_FRAMES, run_scene
    from segadeform.settings import Effects, MotionSpec, Scene, load_scene, parse_frames
    from segadeform.settings.scene import check_motion_fps

    from .main import option_value

    # a bad option value is a command-line mistake, exit 2, as in the C++ and Node runtimes and as click's own ranges
    # (--batch 0) are (a technical artist's trial: --output-units furlong and --fps 0 gave 1); said first, naming it
    if fps is not None:
        option_value(check_motion_fps, fps, option="--fps")
    out_unit = None if output_units is None else option_value(output_unit, output_units, option="--output-units")
    if frames:
        option_value(parse_frames, frames, option="--frames")
    preset = None
    if quality:
        from segadeform.settings.presets import is_change_list, preset_effects

        if effects and not is_change_list(effects):
            raise click.UsageError(
                f"--quality {quality} sets the effects; --effects may only change them with "
                f"signed items (e.g. --effects=+collisions), got the complete list {effects!r}"
            )
        preset = option_value(lambda text: preset_effects(quality, text), effects, option="--effects")
    if scene is not None:
        if garment or motion_path:
            raise click.UsageError("give a SCENE or --garment/--motion, not both")
        # the scene's knobs judged against the effects that will run (--effects=+cloth may use its cloth_ knobs)
        if effects is not None and preset is None:  # its errors name the option before the scene's are read
            _effects_option(effects, check_only=True)
        sc = load_scene(scene, effects=effects if preset is None else None)
        changes = {}
        if preset is not None:  # the preset's effects; a scene's own cloth knobs kept when both run the stage
            keep = preset.cloth and sc.effects.cloth  # (an earlier user's trial: best dropped iterations = 6)
            changes["effects"] = (
                dataclasses.replace(preset, cloth_settings=sc.effects.cloth_settings) if keep else preset
            )
        elif effects is not None:  # (an empty one is refused by the parser, not taken as not given)
            changes["effects"] = _effects_option(effects, sc.effects)
        if fmt or output:
            changes["output_format"] = _fmt_from(output or sc.output, fmt)
        if output:  # the scene checks its format against its output (a review: -o x.usda on a .pc2 scene refused)
            changes["output"] = output
        if up:
            changes["up"] = up
        if out_unit is not None:
            changes["units"] = out_unit
        if body_out:
            changes["body_output"] = body_out
        if body:
            changes["body"] = body
        if betas:
            changes["betas"] = _betas_from(betas, body or sc.body, force)
        mchanges = {
            k: v
            for k, v in (
                ("up", motion_up),
                ("units", units),
                ("joint_map", joint_map),
                ("skeleton", skeleton),
                ("animation", animation),
                ("floor", floor),
                ("repair_glitches", repair_glitches),
            )
            if v is not None
        }
        if frames or fps is not None or mchanges:
            changes["motion"] = dataclasses.replace(
                sc.motion,
                frames=parse_frames(frames) if frames else sc.motion.frames,
                fps=fps if fps is not None else sc.motion.fps,
                **mchanges,
            )
        sc = dataclasses.replace(sc, **changes)
    else:
        if not (garment and motion_path and output):
            raise click.UsageError("give a SCENE, or --garment, --motion and -o")
        beta_vals = _betas_from(betas, body, force) if betas else ()
        sc = Scene(
            garment=garment,
            motion=MotionSpec(
                file=motion_path,
                fps=fps,
                frames=parse_frames(frames) if frames else None,
                up=motion_up or "auto",
                units=units,
                joint_map=joint_map,
                skeleton=skeleton,
                animation=animation,
                floor=bool(floor),
                repair_glitches=bool(repair_glitches),
            ),
            output=output,
            output_format=_fmt_from(output, fmt),
            up=up or "y",
            units=1.0 if out_unit is None else out_unit,
            body=body,
            betas=beta_vals,
            model=None,
            body_output=body_out,
            # (an empty --effects is refused by the parser, not taken as not given: the scene path's rule)
            effects=preset if preset is not None else _effects_option(effects) if effects is not None else Effects(),
        )
    if cloth:
        from segadeform.settings.cloth import ClothSettings

        if not sc.effects.cloth:
            raise click.UsageError(
                "--cloth sets the cloth stage's knobs, but the stage is off (turn it on with --effects=+cloth)"
            )
        try:
            knobs = ClothSettings.parse(cloth, sc.effects.cloth_settings)
        except ValueError as e:
            raise click.BadParameter(str(e), param_hint="--cloth") from None
        sc = dataclasses.replace(sc, effects=dataclasses.replace(sc.effects, cloth_settings=knobs))
    if collision_margin is not None:
        if not (sc.effects.collisions or sc.effects.cloth):
            raise click.UsageError(
                "--collision-margin sets the push-out's margin, but neither collisions nor the cloth stage is on"
            )
        try:
            sc = dataclasses.replace(sc, effects=dataclasses.replace(sc.effects, collision_margin=collision_margin))
        except ValueError as e:
            raise click.BadParameter(str(e), param_hint="--collision-margin") from None
        if collision_margin > 0.05:  # metres: 0.5 held the cloth half a metre off the body, unsaid (a user's trial)
            click.echo(
                f"warning: --collision-margin {collision_margin:g} holds the garment {100 * collision_margin:g} cm off "
                "the body (metres; the default is 0.004)",
                err=True,
            )
    prov = None
    if providers:
        prov = "auto" if providers == "auto" else [p.strip() for p in providers.split(",") if p.strip()]
    interactive = sys.stderr.isatty()
    from segadeform.motion import build_motion, frame_range

    from .motion_convert import motion_spec_read

    given_motion = sc.motion.file  # an FBX file is read through Blender, as `motion convert` reads it
    with motion_spec_read(sc.motion) as motion:
        sc = dataclasses.replace(sc, motion=motion)
        total = None
        if interactive:
            a, b = frame_range(sc.motion.frames, build_motion(sc.motion, None).n_frames)
            total = b - a
        from segadeform.io.output_guard import OutputGuard

        guard = OutputGuard(
            "run",
            force=force,
            inputs=(
                scene,
                sc.garment,
                given_motion,
                sc.body,
                sc.motion.joint_map,
                sc.motion.skeleton,
                model or sc.model,
            ),
        )
        threads, threads_note = usable_threads(threads)
        if threads_note:
            click.echo(threads_note)
        with click.progressbar(length=total or 1, label="deforming", file=sys.stderr, hidden=not interactive) as bar:
            summary = run_scene(
                sc,
                model=model,
                output=output,
                batch=batch,
                threads=threads,
                providers=prov,
                progress=bar.update if interactive else None,
                cache=not no_cache,
                force=force,
                body_backend=body_backend,
                guard=guard,
                frames_from_scene=not frames,
                resolution=resolution,
            )
    off = summary.effects.off()
    q = f"quality {quality}: " if quality else ""
    # a cut motion file numbers its frames from its own start, and the output keeps that numbering while --frames
    # counts from 0: said, so that a TD finds frame 25 where the file says 25 (a new user's trial)
    numbered = (
        f" (written as frames {summary.first_frame}-{summary.first_frame + summary.frames - 1})"
        if summary.first_frame != summary.start
        else ""
    )
    # the time per frame without the garment's set-up (read, checked, encoded or read from the cache), said apart: a
    # QA trial read 20.5 ms/frame on 20 frames of `--quality fast`, which docs/accuracy-vs-time.md puts at 0.4 (the
    # set-up divided by the frames)
    setup = summary.stage_seconds.get("precompute", 0.0)
    per_frame = 1e3 * max(summary.seconds - setup, 0.0) / max(summary.frames, 1)
    click.echo(
        f"{summary.frames} frames{numbered}, {per_frame:.1f} ms/frame after {setup:.2f} s of set-up ({q}effects "
        f"{summary.effects.label()}{'; off: ' + ', '.join(off) if off else ''}; graph {summary.variant})"
    )
    if summary.resolution_vertices is not None:
        m, n = summary.resolution_vertices
        r = resolution if resolution is not None else sc.resolution
        if r < 1.0:
            click.echo(f"resolution {r:g}: the model ran on {m} of the garment's {n} vertices, carried to all")
        else:  # a garment asset exported with --resolution
            click.echo(f"the garment asset's model garment: the model ran on {m} of its {n} vertices, carried to all")
    if summary.batch < batch:  # a big garment: fewer frames a call (the runtimes lower it alike)
        click.echo(
            f"batch: {summary.batch} frames a call, not {batch} (at most {MAX_VERTEX_FRAMES} vertex-frames a call)"
        )
    if summary.cloth is not None:
        c = summary.cloth
        click.echo(
            f"  cloth: {c['contacts']} vertex-frames in contact, {c['pushed']} pushed out after the sweeps, "
            f"{c['traced']} traced out by the backstop, {c['resets']} reset(s), "
            f"{1e3 * summary.stage_seconds['cloth'] / max(summary.frames, 1):.2f} ms/frame"
        )
    elif summary.effects.collisions:  # as the Node and C++ runtimes say it
        click.echo(
            f"  collisions: {summary.pushed_vertices} vertex-frames pushed out, "
            f"{1e3 * summary.stage_seconds['collisions'] / max(summary.frames, 1):.2f} ms/frame"
        )
    for path in summary.written:
        click.echo(f"  wrote {path}")
