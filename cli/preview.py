"""``segadeform preview``: render a result (garment and body) to PNG, GIF or MP4 without Blender."""

from __future__ import annotations

from pathlib import Path

import click

from segadeform.io.writer import UP_AXES

from .main import PathParam, cli

#: frames a PNG strip holds side by side (at the default size, 2,880 pixels wide); more are evenly spaced to these
PNG_FRAMES = 8


@cli.command("preview")
@click.argument("result", type=PathParam(path_type=Path))
@click.option(
    "--garment",
    required=True,
    type=PathParam(dir_okay=False, path_type=Path),
    help="The garment mesh the result animates (its faces; same vertex count and order).",
)
@click.option(
    "--body",
    "body_seq",
    type=PathParam(path_type=Path),
    help="The posed body sequence (`run --body-out`); its faces come from the OBJ beside it, else from --body-model.",
)
@click.option("--body-model", type=PathParam(dir_okay=False, path_type=Path), help="Body .npz (default: shipped).")
@click.option(
    "-o",
    "--output",
    required=True,
    type=PathParam(dir_okay=False, path_type=Path),
    help=f"preview.png (a strip of at most {PNG_FRAMES} frames, evenly spaced over those chosen), .gif or .mp4 "
    "(needs ffmpeg; every frame chosen).",
)
@click.option(
    "--frames",
    help="Frame range A:B, in the result's own frame numbers (a run of --frames 10:40 starts at 10; default: all).",
)
@click.option(
    "--every",
    type=click.IntRange(min=1),
    default=1,
    show_default=True,
    help=f"Render every Nth frame (a PNG keeps {PNG_FRAMES} of them, evenly spaced, when there are more).",
)
@click.option(
    "--view",
    type=click.Choice(["front", "side", "back", "three-quarter", "turntable"]),
    default="three-quarter",
    show_default=True,
    help="Camera about the vertical axis, fixed in the world: front looks at the +Z side (a body facing +Z shows "
    "its front; a motion that faces -Z shows its back), side and back a quarter and a half turn round, "
    "three-quarter 30 degrees round, turntable once round over the frames.",
)
@click.option("--size", default="360x480", show_default=True, help="WIDTHxHEIGHT of one view in pixels.")
@click.option("--fps", type=float, help="Animation rate (default: the result's 30 fps over --every).")
@click.option(
    "--up",
    type=click.Choice(UP_AXES),
    default="y",
    show_default=True,
    help="Up axis the result was written with (run --up).",
)
@click.option(
    "--output-units",
    metavar="UNITS",
    help="Units the result and --body were written in (run --output-units: m, dm, cm, mm, inch, ft or metres per "
    "unit); default: what a USD records (metersPerUnit; a body from the same run is read in the same units), else "
    "metres.",
)
def preview_cmd(result, garment, body_seq, body_model, output, frames, every, view, size, fps, up, output_units=None):
    """Render RESULT (PC2, OBJ sequence folder, XDMF, Alembic or USD) with its garment and, if given, the body.

    Frames are numbered as the result numbers them (a PC2's start frame, USD time codes, OBJ frame names)."""
    import numpy as np

    from segadeform.body import default_body_path, load_body
    from segadeform.bounds import MAX_POSITION
    from segadeform.errors import FileFormatError, InputError
    from segadeform.io import read_mesh
    from segadeform.io.formats import sequence_start_frame, sequence_units
    from segadeform.io.output_guard import OutputGuard
    from segadeform.io.sequence import CHUNK_VALUES, open_sequence_frames
    from segadeform.io.writer import output_unit
    from segadeform.preview.render import MeshLayer, check_encoder, fit_bounds, render, save_animation, save_image
    from segadeform.settings import Y_TO_Z, parse_frames

    from .main import option_value

    ext = output.suffix.lower()
    if ext not in (".png", ".gif", ".mp4"):  # before any rendering
        raise InputError("unknown preview format", path=output, expected=".png, .gif or .mp4", got=ext or "none")
    check_encoder(output)  # MP4's ffmpeg, before any rendering (it rendered every frame, then refused)
    if fps is not None and not (np.isfinite(fps) and 0 < fps <= 1000):
        raise click.UsageError(f"--fps must be a frame rate in (0, 1000], got {fps!r}")
    try:  # the titles and image files are matplotlib's: said before any rendering (a traceback after it, before)
        import matplotlib  # noqa: F401
    except ImportError:
        raise click.ClickException("preview needs matplotlib: pip install 'segadeform[plot]'") from None
    guard = OutputGuard("preview", inputs=(result, garment, body_seq, body_model))
    guard.file(output)
    try:
        w, h = (int(x) for x in size.lower().split("x"))
    except ValueError:
        raise click.UsageError(f"--size must be WIDTHxHEIGHT, got {size!r}") from None
    if not (16 <= w <= 8192 and 16 <= h <= 8192):  # 0x10 was a traceback, 99999x99999 "out of memory"
        raise click.UsageError(f"--size must be WIDTHxHEIGHT, each from 16 to 8192 pixels, got {size!r}")
    g = read_mesh(garment)
    # frames are read when drawn (a PC2 by seeking to them, an Alembic's or a USD's time samples one at a time):
    # `preview --frames 0:3` of a long cache read the whole of it (2.5 GB to draw 3 frames; a user's trial)
    G = open_sequence_frames(result, faces=g.faces)
    if G.shape[1] != g.n_vertices:
        raise InputError(
            "the result and the garment have different vertex counts",
            path=result,
            expected=g.n_vertices,
            got=G.shape[1],
        )
    B = bf = None
    if body_seq is not None:
        side = body_seq.with_suffix(".obj")
        bf = (
            read_mesh(side).faces
            if side.is_file() and body_seq.suffix.lower() != ".obj"
            else load_body(body_model or default_body_path()).faces
        )
        B = open_sequence_frames(body_seq, faces=bf)
        n_rest = int(np.asarray(bf).max()) + 1 if np.asarray(bf).size else 0
        if B.shape[1] != n_rest:  # a garment's cache given as the body, or another body's (a user's trial)
            rest = (
                f"the OBJ beside it ({side.name})"
                if side.is_file() and body_seq.suffix.lower() != ".obj"
                else ("the body model")
            )
            raise InputError(
                f"the body sequence does not match its rest mesh, {rest}",
                path=body_seq,
                expected=f"{n_rest} vertices (the posed body `run --body-out` writes)",
                got=f"{B.shape[1]} vertices",
            )
        if len(B) != len(G):
            raise InputError(
                "the body and garment sequences have different frame counts", path=body_seq, expected=len(G), got=len(B)
            )
    if len(G) == 0:
        raise InputError("the result has no frames", path=result, expected="a sequence of at least 1 frame")
    first = sequence_start_frame(result)  # the motion frame the result starts at
    a, b = parse_frames(frames) if frames else (first, None)
    b = first + len(G) if b is None else b
    if not first <= a < b <= first + len(G):
        raise InputError(
            f"frame range {a}:{b} is outside the result's frames {first}..{first + len(G) - 1}",
            path=result,
            expected=f"{first} <= A < B <= {first + len(G)}",
        )
    idx = list(range(a - first, b - first, every))
    az = {"front": 0.0, "side": 90.0, "back": 180.0, "three-quarter": 30.0, "turntable": 0.0}[view]
    angles = [az + (360.0 * k / max(len(idx), 1) if view == "turntable" else 0.0) for k in range(len(idx))]
    chosen = len(idx)
    if ext == ".png" and chosen > PNG_FRAMES:  # chosen before rendering (all were rendered, then 8 kept, unsaid)
        pick = np.linspace(0, chosen - 1, PNG_FRAMES).round().astype(int)
        idx, angles = [idx[i] for i in pick], [angles[i] for i in pick]
    R = np.array(Y_TO_Z) if up == "z" else None  # back to +Y up for rendering

    # metres per unit of the result and the body: --output-units, else what each file records, else what the other
    # records (one run wrote both: a centimetre USD beside a PC2 body, which records nothing), else 1
    if output_units is not None:
        u = option_value(output_unit, output_units, option="--output-units")
        scale = {"g": u, "b": u}
    else:
        g_rec = sequence_units(result)
        b_rec = None if body_seq is None else sequence_units(body_seq)
        scale = {"g": g_rec or b_rec or 1.0, "b": b_rec or g_rec or 1.0}

    def drawn(seq, path, ks, unit):
        """Frames ``ks`` of ``seq`` as float64, +Y up, metres; NaN or inf in one of them is an error naming it."""
        pts = np.asarray(seq[ks], np.float64)
        bad = np.flatnonzero(~np.isfinite(pts).all(axis=(1, 2)))
        if bad.size:
            raise FileFormatError(
                f"frame {first + ks[int(bad[0])]} has a non-finite coordinate (NaN or inf)",
                path=path,
                expected="finite positions",
            )
        pts = pts if unit == 1.0 else pts * unit
        far = float(np.abs(pts).max()) if pts.size else 0.0
        if far > MAX_POSITION:  # as inspect refuses it (a fuzzer's 3e38 was drawn, with a warning: exit 0)
            raise FileFormatError(
                f"frame {first + ks[int(np.argmax(np.abs(pts).max(axis=(1, 2))))]} has a point beyond 10 km of the "
                "origin (another unit? --output-units says the one it was written in)",
                path=path,
                expected=f"|x| <= {MAX_POSITION:g} m",
                got=f"{far:.3g} m",
            )
        return pts if R is None else pts @ R

    def read(ks):
        """The garment's and the body's frames ``ks`` (the body None without one)."""
        return drawn(G, result, ks, scale["g"]), None if B is None else drawn(B, body_seq, ks, scale["b"])

    _say_units_and_up(read([idx[0]]), result, body_seq, up, output_units)
    # one scale for the whole animation (the largest frame), the camera following the subject: the frames drawn
    # are framed a bounded chunk at a time, then read again one by one to be drawn (all at once when one chunk)
    per = max(1, CHUNK_VALUES // (3 * (G.shape[1] + (0 if B is None else B.shape[1]))))
    boxes, kept = [], None
    for c in range(0, len(idx), per):
        gs, bs = read(idx[c : c + per])
        pts = gs if bs is None else np.concatenate([gs, bs], axis=1)
        boxes += [fit_bounds(q, azimuth=ang, size=(w, h)) for q, ang in zip(pts, angles[c : c + per], strict=True)]
        kept = (gs, bs) if len(idx) <= per else None
        del pts
    half = max(max(bx[0][1] - bx[0][0], bx[1][1] - bx[1][0]) / np.array([w, h]).max() for bx in boxes) / 2
    images = []
    for k, t in enumerate(idx):
        if kept is not None:
            gk, bk = kept[0][k], None if kept[1] is None else kept[1][k]
        else:
            gs, bs = read([t])
            gk, bk = gs[0], None if bs is None else bs[0]
        (x0, x1), (y0, y1) = boxes[k]
        cx, cy = (x0 + x1) / 2, (y0 + y1) / 2
        bounds = ((cx - half * w, cx + half * w), (cy - half * h, cy + half * h))
        layers = [] if bk is None else [MeshLayer(bk, bf, (0.86, 0.72, 0.62))]
        layers.append(MeshLayer(gk, g.faces, (0.28, 0.45, 0.82), depth_bias=0.004))
        images.append(
            # the frame's number first: a narrow image cut the title short ("frar" for frame 192: a technical artist)
            render(layers, azimuth=angles[k], size=(w, h), bounds=bounds, title=f"frame {first + t}  {result.name}")
        )
    if ext == ".png":
        save_image(output, np.concatenate(images, axis=1))
    else:
        save_animation(output, images, fps if fps is not None else 30.0 / every)
    guard.record()
    if len(images) < chosen:
        click.echo(
            f"{len(images)} of the {chosen} frames chosen rendered, evenly spaced (a PNG strip holds {PNG_FRAMES}; "
            f"a .gif or .mp4 holds them all): frames {', '.join(str(first + t) for t in idx)} -> {output}"
        )
    else:
        click.echo(f"{len(images)} frames rendered -> {output}")


def _say_units_and_up(first, result, body_seq, up, output_units) -> None:
    """Warn when the first frame drawn does not look like a person in metres, +Y up: a result written in centimetres
    or with +Z up (run --output-units, --up) that nothing records was drawn 100 times too big or lying on its back,
    with no word (a technical artist's trial).  The body is judged when there is one (it stands), else the garment
    when it is far taller along z than y."""
    import numpy as np

    g, b = first
    pts = (b if b is not None else g)[0]
    ext = np.ptp(pts, axis=0)
    what = body_seq.name if b is not None else result.name
    if output_units is None and ext.max() > 10.0:
        click.echo(
            f"warning: {what} is {ext.max():.0f} m across as read (metres): written in other units (run --output-units "
            f"{'mm' if ext.max() > 300.0 else 'cm'} ...)? pass the same --output-units to preview",
            err=True,
        )
    # a garment alone: only one tall enough to be a body's length (a belt or a collar is flat top to bottom: a review)
    tall_z = ext[2] > 1.5 * ext[1] if b is not None else (ext[2] > 2.0 * ext[1] and ext[2] > 0.5)
    if up != "z" and tall_z:
        click.echo(
            f"warning: {what} stands along z as read (+Y up): written with +Z up (run --up z)? pass --up z to preview",
            err=True,
        )
