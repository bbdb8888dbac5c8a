"""``segadeform garment make | kinds | fit``: procedural garments, and garments made for another body."""

from __future__ import annotations

from pathlib import Path

import click
import numpy as np

from .main import PathParam, cli


def _betas(betas):
    try:
        return tuple(float(x) for x in betas.split(",")) if betas else None
    except ValueError:
        raise click.UsageError(f"--betas must be comma-separated numbers, got {betas!r}") from None


def _obj_output(output: Path) -> None:
    """Refuse an output that is not named .obj (OBJ text went into a file named .pc2: a user's trial), as `preview`
    refuses a format it does not write: one line, before anything is made."""
    from segadeform.errors import InputError

    if output.suffix.lower() != ".obj":
        raise InputError("a garment is written as an OBJ", path=output, expected=".obj", got=output.suffix or "none")


#: the share of a written garment inside the body above which `garment fit` warns: a suit scaled by 0.95 and moved as
#: the advice then said was 62 % inside (2 % deeper than 1 cm), and `run` took it (a pipeline TD's trial); a garment
#: fitted from a body or MakeHuman binding has none inside, the sample skirt 7 %
INSIDE_WARNING = 0.25


@cli.group("garment")
def garment_group():
    """Procedural garments, and garments made for another body (fit)."""


@garment_group.command("make")
@click.argument("kind")
@click.option("-o", "--output", required=True, type=PathParam(dir_okay=False, path_type=Path), help="Output OBJ.")
@click.option("--body", type=PathParam(dir_okay=False, path_type=Path), help="Body .npz (default: shipped body).")
@click.option("--betas", help="Comma-separated body shape coefficients.")
@click.option(
    "--length",
    type=float,
    help="Skirts and dresses: hem height; trousers, shorts, jumpsuit: leg covered; 0..1 of hip-to-ankle.",
)
@click.option("--flare", type=float, help="Skirts and dresses: widening at the hem (default 0.25).")
@click.option("--ease", type=float, default=0.015, show_default=True, help="Metres between skin and cloth.")
@click.option(
    "--sleeve", type=float, help="tshirt, sleeved-dress, jacket, jumpsuit: sleeve length, 0..1 of shoulder-to-wrist."
)
@click.option(
    "--resolution",
    type=int,
    help="Target vertex count: picks the refinement level nearest it (each about 4x the vertices; the coarsest is "
    "about 850-3,000 vertices by kind); a target under half the coarsest level makes that level, with a warning.",
)
@click.option(
    "--waist-ease",
    type=float,
    help="Trousers, shorts, skirts: metres at the waistband, tapering to --ease 8 cm below it (default: --ease).",
)
@click.option("--force", is_flag=True, help="Make it for a body shape no human has (as `run --force` plays one).")
def garment_make_cmd(kind, output, body, betas, length, flare, ease, sleeve, resolution, waist_ease, force):
    """Make a KIND garment dressed on the body in rest pose (kinds: see `segadeform garment kinds`).

    An option the kind does not use (--sleeve for a tank, --flare for trousers) is refused."""
    from segadeform.body import default_body_path, load_body
    from segadeform.bounds import check_betas, check_body_height
    from segadeform.errors import InputError
    from segadeform.garments import KIND_PARAMS, GarmentParams, check_garment, make_garment
    from segadeform.garments.make import GarmentCheckError
    from segadeform.io import Mesh, write_obj
    from segadeform.io.output_guard import OutputGuard

    _obj_output(output)
    shape = {"length": length, "flare": flare, "sleeve": sleeve, "waist_ease": waist_ease}
    if kind in KIND_PARAMS:  # an unknown kind is the library's error
        takes = ("ease", *KIND_PARAMS[kind], "resolution")
        for name, value in shape.items():
            if value is not None and name not in takes:  # it changed nothing, yet was recorded in the OBJ
                opts = ", ".join("--" + n.replace("_", "-") for n in takes)
                raise InputError(f"--{name.replace('_', '-')} does not apply to {kind}; it takes: {opts}")
    b = _betas(betas)
    if b is not None:
        b = check_betas(b, what="--betas")
    guard = OutputGuard("garment make", inputs=(body,))
    guard.file(output)
    bm = load_body(body or default_body_path())
    try:  # a shape every other command refuses (--betas 3,-2: a 2.6 m body) was dressed, exit 0 (a user's trial)
        check_body_height(bm, b, force=force)
    except InputError as e:
        raise InputError(f"--betas: {e.problem}", expected=e.expected, got=e.got) from None
    try:
        g = make_garment(
            kind,
            bm,
            b,
            GarmentParams(ease=ease, resolution=resolution, **{k: v for k, v in shape.items() if v is not None}),
        )
    except GarmentCheckError as e:  # the garment made failed its check: named by the file it was to be
        raise e.with_path(output) from None
    info = check_garment(g.vertices, g.faces, bm, b)
    write_obj(output, Mesh(vertices=g.vertices, faces=g.faces), header=g.header())
    guard.record()
    if resolution is not None and info["vertices"] > 2 * resolution:  # the nearest level is within 2x of any other
        click.echo(
            f"warning: --resolution {resolution} is below the coarsest {kind} ({info['vertices']:,} vertices), "
            "which was made",
            err=True,
        )
    click.echo(
        f"{kind} ({g.type}): {info['vertices']} vertices, {info['faces']} triangles, "
        f"{info['boundary_loops']} openings, clearance >= {1e3 * info['min_clearance']:.1f} mm -> {output}"
    )


@garment_group.command("kinds")
def garment_kinds_cmd():
    """List the garment kinds and their type labels."""
    from segadeform.garments import GARMENT_TYPES

    for k, t in GARMENT_TYPES.items():
        click.echo(f"{k:14s} {t}")


@garment_group.command("fit")
@click.argument("garment", type=PathParam(dir_okay=False, path_type=Path))
@click.option("-o", "--output", required=True, type=PathParam(dir_okay=False, path_type=Path), help="Fitted OBJ.")
@click.option(
    "--mhclo",
    type=PathParam(dir_okay=False, path_type=Path),
    help="MakeHuman binding (default: GARMENT itself if .mhclo, else a .mhclo of the same name beside it).",
)
@click.option(
    "--from-body",
    type=PathParam(dir_okay=False, path_type=Path),
    help="The body mesh the garment was modelled on: any topology and units, in a T- or A-pose or walking "
    "(its units and up axis, y or z, are read from its height unless --units/--up say).",
)
@click.option("--body", type=PathParam(dir_okay=False, path_type=Path), help="Target body .npz (default: shipped).")
@click.option("--betas", help="Target body shape, comma-separated coefficients.")
@click.option("--units", help="Units of the garment (and --from-body) file: m, dm, cm, mm, inch, ft or a number.")
@click.option(
    "--up",
    type=click.Choice(["y", "z", "-z", "x"]),
    help="Up axis of the garment (and --from-body) file (default y; with --from-body, read from the body).",
)
@click.option(
    "--turn",
    type=float,
    default=0.0,
    metavar="DEGREES",
    help="Turn the garment (and --from-body) by DEGREES about the up axis through the origin, after --units/--up: "
    "counterclockwise seen from above (the body faces +z; a garment facing +x takes 270, one facing backward 180). "
    "With --from-body, given (0 too) it says which way the source faces once turned: +z, not searched for.",
)
@click.option("--scale", type=float, default=1.0, show_default=True, help="Extra scale factor.")
@click.option(
    "--offset", help="Move by dx,dy,dz metres (after a --mhclo/--from-body fit, or after units, axes and scale)."
)
@click.option(
    "--margin",
    type=float,
    help="Push vertices out of the body to this clearance, metres "
    "(default 0.003 for --mhclo/--from-body fits, none for plain unit/axis fixes).",
)
@click.option(
    "--weld",
    is_flag=True,
    help="Merge vertices at the same place on open boundaries with no edge between them (a mesh split at its UV "
    "seams: `run` deforms the two sides apart); UVs stay per corner.  The output has fewer vertices than GARMENT.",
)
@click.option(
    "--force",
    is_flag=True,
    help="Write the garment even when it does not sit on the body, or when a --from-body fit tore it.",
)
def garment_fit_cmd(
    garment, output, mhclo, from_body, body, betas, units, up, turn, scale, offset, margin, weld, force
):
    """Bring GARMENT (OBJ or .mhclo) onto the body: a MakeHuman binding, --from-body, or --units/--up/--turn/--scale.

    Vertex order and count are kept; faces (quads and polygons as they are), UVs and groups are copied from the
    input OBJ, and its normals recomputed for the fitted vertices.  --offset moves the result (after a fit, or
    after --units/--up/--turn/--scale); --betas reshapes only what can be refitted (--mhclo, --from-body).  A
    result that does not sit on the body (a plain fix of a file in other units, axes or facing), or that a
    --from-body fit tore (a source body whose pose was not found), is refused with the fix, unless --force.
    """
    import numpy as np

    from segadeform import __version__
    from segadeform.body import default_body_path, load_body
    from segadeform.body.placement import fix_units_and_axes, placement_report, push_off_body
    from segadeform.bounds import check_betas, check_body_height
    from segadeform.errors import InputError
    from segadeform.garments.registration import (
        edge_distortion,
        fit_mhclo,
        fit_to_body_mesh,
        folded_edges,
        guess_units_and_up,
    )
    from segadeform.geometry.mesh_ops import check_has_area, coincident_map, surface_faces
    from segadeform.io import read_mesh
    from segadeform.io.mhclo import read_mhclo
    from segadeform.io.obj import OWN_COMMENT, betas_record, material_libraries, recorded_betas, rewrite_obj_vertices
    from segadeform.io.output_guard import OutputGuard

    _obj_output(output)
    b = _betas(betas)
    if b is not None:
        b = check_betas(b, what="--betas")
    try:
        off = tuple(float(x) for x in offset.split(",")) if offset else None
        if off is not None and (len(off) != 3 or not np.isfinite(off).all()):
            raise ValueError
    except ValueError:
        raise click.UsageError(f"--offset must be dx,dy,dz, got {offset!r}") from None
    if not np.isfinite(turn):
        raise click.UsageError(f"--turn must be degrees, got {turn!r}")
    obj = garment
    if garment.suffix.lower() == ".mhclo":
        if mhclo is not None and Path(mhclo).resolve() != Path(garment).resolve():
            raise click.UsageError(f"GARMENT {garment} is a binding itself: give it, or --mhclo {mhclo}, not both")
        mhclo, obj = garment, None
    elif mhclo is None and from_body is None and garment.with_suffix(".mhclo").is_file():
        mhclo = garment.with_suffix(".mhclo")
    binding = None
    if mhclo is not None:
        if from_body is not None:
            raise click.UsageError("give --mhclo or --from-body, not both")
        fixes = [
            f
            for f, given in (
                ("--units", units is not None),
                ("--up", up not in (None, "y")),
                ("--turn", turn % 360 != 0),
                ("--scale", scale != 1.0),
            )
            if given
        ]
        if fixes:  # the binding places every vertex on the body itself: these cannot apply
            raise InputError(
                f"{', '.join(fixes)} do not apply to a MakeHuman binding: it places the garment on the body itself",
                path=mhclo,
                expected="--offset, --margin, --betas",
                got=", ".join(fixes),
            )
        binding = read_mhclo(mhclo)
        obj = obj or binding.obj_path()
        if obj is None:
            raise InputError("the .mhclo names no obj_file; pass the OBJ as GARMENT", path=mhclo)
        if not obj.is_file():
            raise InputError(
                f"the garment mesh {obj.name} is missing",
                path=mhclo,
                expected=f"{obj} (obj_file in the .mhclo, or the OBJ given as GARMENT)",
            )
    elif from_body is None and b is not None:
        raise InputError(
            "--betas needs a garment that can be refitted to a body shape; a unit/axis fix does not "
            "change the garment's shape",
            path=garment,
            expected="a MakeHuman binding (--mhclo) or --from-body with --betas",
            got="a plain OBJ",
        )
    mesh = read_mesh(obj)
    check_has_area(mesh.vertices, mesh.faces, path=obj)  # a garment of flat faces was written, exit 0
    guard = OutputGuard("garment fit", inputs=(garment, mhclo, obj, from_body, body))
    guard.file(output)
    bm = load_body(body or default_body_path())
    try:  # a shape no human has (--betas 4: a 2.9 m body), unless meant; named as `run` names it
        check_body_height(bm, b, force=force)
    except InputError as e:
        raise InputError(f"--betas: {e.problem}", expected=e.expected, got=e.got) from None
    try:
        units_v = float(units) if units is not None else None
    except ValueError:
        units_v = units
    rest = bm.shaped_vertices(b)[0]
    if binding is None and from_body is None and b is None and recorded_betas(obj):
        # a plain fix (units, axes, --weld) keeps the body shape the file records: checked on that body, as `run`
        # runs it (a garment made for betas 2.5 was refused as "another body's origin", so the --weld that `run`
        # suggested could not be done: a review)
        rest = bm.shaped_vertices(np.asarray(recorded_betas(obj), np.float64)[None])[0]
    if binding is not None:
        v = fit_mhclo(binding, bm, b)
        how = f"MakeHuman binding {mhclo.name}"
        default_margin = 0.003
    elif from_body is not None:
        src = read_mesh(from_body)
        g = mesh
        try:
            u_read, up_read, _ = guess_units_and_up(src.vertices, units=units_v, up=up)
        except InputError as e:
            raise e.with_path(from_body) from None
        read_as = "" if units_v is not None and up is not None else f", read in {u_read} with +{up_read} up"
        if units_v is None:
            units_v = u_read
        src_v = fix_units_and_axes(src.vertices, units=units_v, up=up_read, scale=scale, turn=turn)
        g_v = fix_units_and_axes(g.vertices, units=units_v, up=up_read, scale=scale, turn=turn)
        # --turn given (0 too) says which way the source faces: no search (a body whose head is tilted far back reads
        # as facing backwards: registration._body_facing)
        given = click.get_current_context().get_parameter_source("turn") != click.core.ParameterSource.DEFAULT
        fit = fit_to_body_mesh(g_v, src_v, src.faces, bm, b, garment_faces=g.faces, search_facing=not given)
        v = fit.vertices
        torn, worst = edge_distortion(g_v, v, g.faces)
        if torn > 0.05 and not force:  # a carried garment keeps most edges within tens of percent (armpits may tear)
            raise InputError(
                f"the fit tore the garment: {100 * torn:.1f} % of its edges changed length more than 2x (worst "
                f"{worst:.0f}x), so the body's pose in {from_body.name} was not found (a pose far from standing, "
                "walking or a T- or A-pose -- a leg raised high, a deep crouch -- or other units or up axis)",
                path=garment,
                expected="a source body standing, walking or near a T- or A-pose (--units/--up if misread), or --force",
            )
        new_folds = folded_edges(v, g.faces) - folded_edges(g_v, g.faces)
        if new_folds > 0.001 * len(g.faces):  # a dense garment on a coarse body follows its facets: said, with the
            # count (a technical artist's 20k-vertex dress came out with 544 folded pairs and no word)
            click.echo(
                f"warning: the fit folded {new_folds} pairs of neighbouring faces onto each other (more than 90 "
                f"degrees apart; {folded_edges(g_v, g.faces)} before): a zig-zag where the garment follows the facets "
                f"of {from_body.name}, which is coarser than the garment; look at it before you run it (a denser "
                "source body, or the garment at a lower resolution, folds less)",
                err=True,
            )
        turned = f", turned {turn:g} degrees" if turn % 360 else ""
        how = f"registered to {from_body.name}{read_as}{turned} (body fit {100 * fit.body_error:.1f} cm mean)"
        default_margin = 0.003
    else:
        g = mesh
        v = fix_units_and_axes(g.vertices, units=units_v, up=up or "y", scale=scale, turn=turn)
        turned = f", turn {turn:g}" if turn % 360 else ""
        how = f"units {units or 'm'}, up {up or 'y'}{turned}, scale {scale:g}"
        default_margin = None
    if off is not None:  # after the fit (a binding's, another body's) or the unit/axis fix
        v = v + np.asarray(off, np.float64)
        how += f", offset {off}"
    if len(mesh.vertices) != len(v):
        raise InputError(
            f"the binding and {obj.name} have different vertex counts",
            path=mhclo or obj,
            expected=f"{len(mesh.vertices)} binding lines",
            got=len(v),
        )
    if binding is None and from_body is None and not force:
        given = (
            (f" --units {units}" if units is not None else "")
            + (f" --up {up}" if up not in (None, "y") else "")
            + (f" --turn {turn:g}" if turn % 360 else "")
            + (f" --scale {scale:g}" if scale != 1.0 else "")
        )
        _check_plain_fix(g.vertices, v, rest, bm.faces, garment, how, given=None if off is not None else given)
    welds, welded = None, 0
    if weld:  # the seam's vertices, found where the file has them, each group at the mean of its fitted places
        welds = coincident_map(mesh.vertices, surface_faces(mesh.vertices, mesh.faces))
        welded = int((welds != np.arange(len(v))).sum())
        counts = np.bincount(welds, minlength=len(v)).astype(np.float64)
        sums = np.stack([np.bincount(welds, weights=v[:, k], minlength=len(v)) for k in range(3)], axis=1)
        v = (sums / np.maximum(counts, 1.0)[:, None])[welds]
    m = default_margin if margin is None else margin
    pushed = 0
    if m is not None:
        v, pushed = push_off_body(v, rest, bm.faces, m)
    pushed_text = f", {pushed} pushed to {1e3 * m:.0f} mm" if m else ""
    if welded:
        pushed_text += f", {welded} vertices welded"
    # the first line says what rewrote the file, and how (a fitted file kept its source's `# Exported from Maya 2024`
    # with nothing saying segadeform had moved every vertex: a new user's trial); a refit records the body shape it
    # was fitted for (`run` refuses the garment on another); a unit/axis fix keeps the shape, and whatever record
    # the file has
    fitted = (
        f"{OWN_COMMENT} fit: {how}{pushed_text} (segadeform {__version__}; from {obj.name}: vertices moved, normals "
        "recomputed, the other lines kept)"
    )
    kept = recorded_betas(obj)
    if binding is None and from_body is None:
        header: tuple[str, ...] = (fitted,) if kept is None else (fitted, betas_record(kept))
    else:
        header = (fitted, betas_record(b or ()))
    libraries = material_libraries(obj, output)
    rewrite_obj_vertices(obj, v, output, header=header, weld=welds if welded else None)
    guard.record()
    rep = placement_report(v, rest, bm.faces)
    click.echo(f"{obj.name}: {len(v)} vertices, {how}{pushed_text}")
    click.echo(f"  {rep.line()}")
    if rep.inside_fraction > INSIDE_WARNING:  # (a fitted garment has none inside: it is pushed off to its margin)
        click.echo(
            f"  warning: {output.name}: {100 * rep.inside_fraction:.1f} % of the garment lies inside the body, where a "
            "garment that fits lies outside it: check --scale and --offset (`run` would push it out every frame)",
            err=True,
        )
    if weld:
        click.echo(
            f"  welded {welded} vertices onto those at their place: {len(v) - welded} vertices written (a point cache "
            f"of the welded garment fits {output.name}, not {obj.name})"
            if welded
            else "  --weld: no vertices at the place of another on an open boundary; none welded"
        )
    else:  # a mesh split at its seams tears wherever it is played: said here, where --weld joins it (a trial)
        split = int(
            (coincident_map(mesh.vertices, surface_faces(mesh.vertices, mesh.faces)) != np.arange(len(v))).sum()
        )
        if split:
            click.echo(
                f"  warning: {obj.name}: {split} vertices lie on an open boundary at the place of another vertex, with "
                "no edge between them: the mesh is split along a seam (as exports split it at UV seams) and the "
                "output would tear there; add --weld to join them",
                err=True,
            )
    for name, written in libraries.items():  # the copy names the material library as found from its folder
        if written is None:
            click.echo(f"  mtllib {name}: no such file beside {obj.name} or the output; left out")
        elif written != name:
            click.echo(f"  mtllib {name}: written as {written} (the file beside {obj.name})")
    click.echo(f"  -> {output}")


def _check_plain_fix(original, fixed, rest, faces, path, how: str, *, given: str | None = None) -> None:
    """Refuse a plain unit/axis fix whose result does not sit on the body, with the options that make the
    original file sit (check_placement's suggestion is for the file as given, not for this fix's result).
    ``given``: the fix's options as typed (``--units cm --up z``; None: it moved the garment too, --offset): a result
    that sits once turned about the up axis is named with them and the --turn it takes (with none, the file as given
    is the result, and its refusal names the turn)."""
    from segadeform.body.placement import FACING, PlacementError, check_placement, facing_turn
    from segadeform.errors import InputError

    try:
        check_placement(fixed, rest, faces, path=path)
        return
    except PlacementError as e:
        failed = e
    t = facing_turn(fixed, rest, faces) if given and "--turn" not in given else None
    if t is not None:  # read right, and facing another way (a cm, z-up, +x-facing garment read in cm with +z up)
        raise InputError(
            f"the garment does not sit on the body with {how}: it faces {FACING[t]}, the body +z (forward); it does "
            f"once also turned {t} degrees about the up axis",
            path=path,
            expected=f"a garment facing the body's front: run `segadeform garment fit {path} -o FIXED.obj{given} "
            f"--turn {t}`, or pass --force",
        )
    if not np.array_equal(np.asarray(original, np.float64), np.asarray(fixed, np.float64)):
        try:
            check_placement(original, rest, faces, path=path)
        except PlacementError as e:  # the suggestion for the file itself
            raise InputError(
                f"the garment does not sit on the body with {how}; as given, {e.problem}",
                path=path,
                expected=e.expected,
            ) from None
        raise InputError(
            f"the garment sits on the body as it is, and not with {how}",
            path=path,
            expected="no unit, axis or scale fix (or --force)",
        )
    raise failed
