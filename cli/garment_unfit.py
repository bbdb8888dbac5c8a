"""`segadeform garment unfit`: a point cache of a fitted garment put back in the frame of the file it was fitted from.

An engine integrator's trial: a cm, Z-up garment brought onto the body by ``garment fit --units cm --up z --turn 90``
played, and ``run --up z --output-units cm`` wrote frames turned against the asset, its units and axes undone but not
its turn (nor a scale or an offset).  ``unfit`` reads the fit's record in the fitted OBJ's first line and writes each
frame through the inverse of that similarity: the cache then lies on the asset as the engine has it.  Any runtime's
PC2 (Python, Node, C++) is taken; the result must be in metres and +Y up, as every runtime writes it by default.
"""

from __future__ import annotations

import re
from pathlib import Path

import click
import numpy as np

from segadeform.errors import FileFormatError, InputError

from .garment import garment_group
from .main import PathParam

#: the similarity a plain `garment fit` records: "fit: units U, up A[, turn T], scale S[, offset (x, y, z)]"
_RECORD = re.compile(
    r"fit: units (?P<units>[^,]+), up (?P<up>[^,]+)(?:, turn (?P<turn>[^,]+))?, scale (?P<scale>[^,(]+)"
    r"(?:, offset \((?P<offset>[^)]*)\))?"
)


def fit_similarity(garment: Path) -> tuple[np.ndarray, float, np.ndarray]:
    """``(R (3, 3), f, o (3,))`` of the plain fit recorded in the fitted OBJ ``garment``: fitted = f R source + o
    (:func:`segadeform.body.placement.fix_units_and_axes`).  An OBJ with no record, or fitted by registration to a
    body or a MakeHuman binding (no similarity), is an error naming the file."""
    from segadeform.body.placement import UNIT_SCALES, fix_units_and_axes
    from segadeform.io.obj import recorded_fit

    text = recorded_fit(garment)
    if text is None:
        raise InputError(
            "the garment has no record of `segadeform garment fit`",
            path=garment,
            expected="the OBJ `garment fit` wrote (its first line says how it moved the vertices)",
        )
    m = _RECORD.search(text)
    if m is None:
        raise InputError(
            "the garment was fitted by registration to a body or a binding, which moves every vertex its own way: "
            "there is no frame of the source file to put its frames back in",
            path=garment,
            expected="a garment `garment fit --units/--up/--turn/--scale/--offset` wrote",
            got=text[:80],
        )
    units = m["units"].strip()
    units_v: str | float = units if units in UNIT_SCALES or units == "m" else float(units)
    turn = float(m["turn"]) if m["turn"] else 0.0
    scale = float(m["scale"])
    offset = np.array([float(x) for x in m["offset"].split(",")]) if m["offset"] else np.zeros(3)
    basis = fix_units_and_axes(np.eye(3), units=None if units_v == "m" else units_v, up=m["up"].strip(), turn=turn,
                               scale=scale)  # fmt: skip
    f = float(np.linalg.norm(basis[0]))  # rows: f R e_i
    return basis.T / f, f, offset


@garment_group.command("unfit")
@click.argument("result", type=PathParam(dir_okay=False, exists=True, path_type=Path))
@click.option(
    "--garment",
    "garment",
    required=True,
    type=PathParam(dir_okay=False, exists=True, path_type=Path),
    help="The OBJ `segadeform garment fit` wrote (its first line records how it was fitted).",
)
@click.option("-o", "--output", required=True, type=PathParam(dir_okay=False, path_type=Path), help="Output .pc2.")
def garment_unfit_cmd(result, garment, output):
    """Write RESULT (a .pc2 of the fitted garment, in metres and +Y up as every runtime writes it) in the units, axes
    and place of the file the garment was fitted from: each frame through the inverse of the fit's units, up axis,
    turn, scale and offset, so that it lies on the asset as the engine or DCC has it.  The vertex order and count,
    start frame and rate are RESULT's."""
    from segadeform.io import read_mesh
    from segadeform.io.output_guard import OutputGuard
    from segadeform.io.pc2 import PC2Frames, PC2Writer, read_pc2_header

    if result.suffix.lower() != ".pc2" or output.suffix.lower() != ".pc2":
        raise click.UsageError(
            f"RESULT and -o are point caches (expected .pc2, got {result.suffix} and {output.suffix})"
        )
    R, f, o = fit_similarity(garment)
    n = read_mesh(garment).n_vertices
    h = read_pc2_header(result)
    if h.num_points != n:
        raise FileFormatError(
            f"the point cache is not of this garment ({garment.name} has {n} vertices)",
            path=result,
            expected=n,
            got=h.num_points,
        )
    guard = OutputGuard("garment unfit", inputs=(result, garment))
    guard.file(output)
    frames = PC2Frames(result)
    with guard.writing(), PC2Writer(output, num_points=n, start_frame=h.start_frame, sample_rate=h.sample_rate) as w:
        for lo in range(0, h.num_samples, 64):
            x = np.asarray(frames[lo : lo + 64], np.float64)
            w.write(((x - o) @ R) / f)  # source = R^T (fitted - o) / f; as row vectors (x - o) R / f
    click.echo(f"wrote {output} ({h.num_samples} frames of {n} vertices, in the frame of the file {garment.name} "
               "was fitted from)")  # fmt: skip
