"""``segadeform motion make | info``."""

from __future__ import annotations

from pathlib import Path

import click
import numpy as np

from .main import PathParam, bvh_units_option, cli


@cli.group("motion")
def motion_group():
    """Make, inspect and export motions (AMASS-style .npz, BVH, .sgdm)."""


@motion_group.command("make")
@click.argument("kind")
@click.option("--seconds", type=float, default=3.0, show_default=True)
@click.option("--fps", type=float, default=30.0, show_default=True)
@click.option("--seed", type=int, default=0, show_default=True)
@click.option("--speed", type=float, default=1.0, show_default=True, help="Cycle rate multiplier.")
@click.option("--amplitude", type=float, default=1.0, show_default=True, help="Joint angle scale (0..2).")
@click.option("--ease-in", type=float, default=1.0, show_default=True, help="Seconds to blend in from rest.")
@click.option(
    "-o",
    "--output",
    required=True,
    type=PathParam(dir_okay=False, path_type=Path),
    help="Motion file (.npz, .bvh or .sgdm).",
)
@click.option(
    "--body",
    type=PathParam(dir_okay=False, path_type=Path),
    help="BVH output: the body whose skeleton the file carries (default: the shipped body).",
)
def make_cmd(kind, seconds, fps, seed, speed, amplitude, ease_in, output, body):
    """Make a procedural motion of KIND (idle, walk, run, jump, arm_swing, touch_high, torso_twist, dance).

    A .bvh is written in centimetres on the skeleton of --body (the shipped body by default), so that it reads back
    as the same motion on that body; .npz and .sgdm hold the poses and root path themselves."""
    from segadeform.io.output_guard import OutputGuard
    from segadeform.motion import make_motion, write_bvh
    from segadeform.settings.scene import check_motion_fps

    from .main import option_value

    option_value(check_motion_fps, fps, option="--fps")  # naming the option, as `run --fps` does
    guard = OutputGuard("motion make")
    guard.file(output)
    m = make_motion(kind, seconds=seconds, fps=fps, seed=seed, speed=speed, amplitude=amplitude, ease_in=ease_in)
    is_bvh = output.suffix.lower() == ".bvh"
    if body is not None and not is_bvh:
        raise click.UsageError(f"--body is for a .bvh output (its skeleton), not {output.suffix or 'no extension'}")
    if is_bvh:
        from segadeform.body import default_body_path, load_body

        # the body's own joints: a BVH read back is retargeted by fitting its legs to the body, so a skeleton of
        # other proportions (the hand-made 1.7 m stand-in, written before) came back with strides 17 % longer
        write_bvh(output, m, load_body(body or default_body_path()).rest_joints()[0], scale=100.0)
    else:
        m.save(output)
    guard.record()
    click.echo(f"{m.name}: {m.n_frames} frames at {m.fps:g} fps ({m.seconds:.2f} s) -> {output}")


@motion_group.command("info")
@click.argument("motion", type=PathParam(dir_okay=False, path_type=Path))
@click.option(
    "--body",
    type=PathParam(dir_okay=False, path_type=Path),
    help="Retarget onto this body (default: the shipped body).",
)
@click.option(
    "--up", type=click.Choice(["auto", "y", "z"]), default="auto", show_default=True, help="Up axis of the file."
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
@click.option(
    "--animation", help="glTF (.glb/.gltf) and FBX motions: the animation (default: the first; FBX: the armature's)."
)
def info_cmd(motion, body, up, units, joint_map, skeleton, animation):
    """Print frames, rate, duration, joint ranges and (BVH, AMC) the joint mapping of MOTION (.npz, .bvh, .amc,
    .glb, .gltf, .sgdm, or .fbx through Blender as `motion convert` reads it)."""
    from segadeform.body import default_body_path, load_body
    from segadeform.motion import load_motion
    from segadeform.motion.limits import limit_violation

    from .motion_convert import bvh_up, fbx_as_bvh

    J = load_body(body or default_body_path()).rest_joints()[0]
    try:
        units_v = float(units) if units is not None else None
    except ValueError:
        units_v = units
    fbx = motion.suffix.lower() == ".fbx"
    with fbx_as_bvh(motion, animation) as path:
        m = load_motion(
            path,
            rest_joints=J,
            up=bvh_up(up) if fbx else up,
            units=units_v,
            joint_map=joint_map,
            skeleton=skeleton,
            animation=None if fbx else animation,
        )
    ang = np.linalg.norm(m.poses.reshape(-1, 24, 3), axis=-1)
    from segadeform.io.writer import nominal_fps

    meta = m.meta
    first = int((meta or {}).get("start_frame", 0))
    numbered = f" (numbered {first}-{first + m.n_frames - 1}: run --frames counts them from 0)" if first else ""
    click.echo(  # the rate as outputs write it; a cut file's numbering, which the outputs keep
        f"{motion}: {m.n_frames} frames{numbered}, {nominal_fps(m.fps):g} fps, {m.seconds:.2f} s"
    )
    if meta.get("format") == "amc":
        click.echo(
            f"  skeleton: {meta['skeleton']} ({meta['scheme']} names), length unit {meta['length_unit']:g} "
            f"= {meta['metres_per_unit']:.5g} m, up {meta['up']}, scale {meta['scale']:.5g} m per unit "
            f"(legs fitted to the body); {meta['source_fps']:g} fps (CMU's rate: AMC states none)"
        )
    elif meta.get("format") in ("bvh", "gltf"):
        names = "read by its shape" if meta["scheme"].startswith("shape") else f"{meta['scheme']} names"
        click.echo(
            f"  skeleton: {names}, up {meta['up']}, units look like {meta['units_guess']}, "
            f"scale {meta['scale']:.5g} m per unit"
            + (f"; animation {meta['animation']!r} of {len(meta['animations'])}" if "animation" in meta else "")
        )
    if meta.get("format") in ("bvh", "amc", "gltf"):
        how = meta.get("found_by", {})
        for by in dict.fromkeys(how.get(k, meta["scheme"]) for k in meta["mapped"]):  # one line per way found
            click.echo(
                f"  mapped by {by}: "
                + ", ".join(f"{k}={v}" for k, v in meta["mapped"].items() if how.get(k, meta["scheme"]) == by)
            )
        if meta["virtual"]:
            click.echo("  filled in (not in the file): " + ", ".join(meta["virtual"]))
        if meta["ignored"]:
            click.echo(
                f"  folded into their parents ({len(meta['ignored'])}): "
                + ", ".join(meta["ignored"][:20])
                + (" ..." if len(meta["ignored"]) > 20 else "")
            )
    elif meta.get("format") == "npz":
        click.echo(
            f"  {meta['convention']} npz, {meta['source_width']} pose values per frame, up {meta['up']}"
            + (f", gender {meta['gender']}" if "gender" in meta else "")
        )
    from segadeform.body.kinematics import forward_kinematics, poses_to_rotmats
    from segadeform.body.skeleton import SMPL_PARENTS

    _, posed = forward_kinematics(poses_to_rotmats(m.poses, 24), J, SMPL_PARENTS, m.trans)
    feet = posed[:, [7, 8, 10, 11], 1]
    click.echo(f"  root travel: {np.ptp(m.trans, axis=0).round(3).tolist()} m (x, y, z range)")
    click.echo(
        f"  lowest foot joint: {feet.min():.3f} m (rest pose: {J[[7, 8, 10, 11], 1].min():.3f} m; "
        f"--floor moves it there)"
    )
    click.echo(f"  largest joint rotation: {np.rad2deg(ang[:, 1:].max()):.1f} deg")
    click.echo(f"  outside joint limits by: {np.rad2deg(limit_violation(m.poses)):.2f} deg")
    from segadeform.motion.motion import drop_leading_glitches, joint_speeds, repair_glitches

    sp = joint_speeds(m, J)
    if len(sp):
        _, settle = drop_leading_glitches(m, J)
        _, jumps = repair_glitches(m, J)
        click.echo(
            f"  fastest joint: {sp.max():.1f} m/s (frames {int(sp.argmax())}-{int(sp.argmax()) + 1}); "
            f"glitches: {settle} leading frames the capture settles from, {jumps} frames it jumps to and back "
            f"from (> 20 m/s)" + ("; repair_glitches = true repairs them" if settle or jumps else "")
        )
    from segadeform.motion import root_cuts

    cuts = root_cuts(m)  # (a root 18 m away every other frame: "0 frames it jumps to and back from" alone, a fuzzer)
    if cuts:
        first, metres = cuts[0]
        click.echo(
            f"  root: {len(cuts)} step{'s' if len(cuts) != 1 else ''} faster than 20 m/s, the first {metres:.3g} m "
            f"into frame {first}: a cut, a teleport or a root that jumps about (the garment jumps with it)"
        )
    if m.betas is not None:
        click.echo(f"  betas: {np.round(m.betas[:10], 3).tolist()}")
