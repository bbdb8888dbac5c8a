"""The one lifecycle every streaming sequence writer shares, and the output axis convention.

A :class:`SequenceWriter` takes frames ``(N, 3)`` or ``(B, N, 3)`` (finite, the right
vertex count) in metres, optionally turns them from the package's +Y-up convention to +Z up
and writes them in other units (``unit``: metres per written unit, 0.01 for Maya's and Unreal's
centimetres), and hands them to its format's ``_append``; ``close`` commits the output (atomically:
nothing appears under the final name before) and ``abort`` -- or leaving a ``with``
block by an exception, or dropping the writer -- discards it.  A format subclasses
it with ``_append``, ``_commit`` and ``_discard`` (and registers itself in
:mod:`segadeform.io.formats`).
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np

from ..errors import InputError

__all__ = [
    "SequenceWriter",
    "UP_AXES",
    "Y_TO_Z",
    "UNIT_SCALES",
    "to_up",
    "to_output",
    "output_unit",
    "COMMON_FPS",
    "nominal_fps",
]

#: the up axes a writer can write (``--up``, a scene's ``output.up``, a jobs file's ``batch.up``)
UP_AXES = ("y", "z")

#: +Y up -> +Z up as Blender's OBJ importer turns objects by default (forward -Z, up Y):
#: (x, y, z) -> (x, -z, y).  Rows act on column vectors: row-vector points map as ``p @ Y_TO_Z.T``.
Y_TO_Z = ((1.0, 0.0, 0.0), (0.0, 0.0, -1.0), (0.0, 1.0, 0.0))

#: metres per unit of the length units a file may be read or written in (a garment's ``--units``, an output's
#: ``--output-units``)
UNIT_SCALES = {"m": 1.0, "dm": 0.1, "cm": 0.01, "mm": 0.001, "inch": 0.0254, "ft": 0.3048}
#: metres per written unit an output may take (a number outside it is a typo: 1e-9 m is no tool's unit, and a unit
#: longer than a metre none of a garment's: ``--output-units 100`` meant "x100, centimetres" and wrote a skirt 1.2 cm
#: tall, a pipeline TD's trial; 1e3 until 2 Dec 2026)
OUTPUT_UNIT_RANGE = (1e-4, 1.0)


#: the frame rates besides whole numbers that a rate within :data:`FPS_RTOL` of stands for: NTSC film and video,
#: exactly (30000 / 1001, not 29.97)
COMMON_FPS = (24000 / 1001, 30000 / 1001, 48000 / 1001, 60000 / 1001, 120000 / 1001)
#: how far (relative) a rate may be from a common one and still be it: a BVH's ``Frame Time: 0.00833333`` is
#: 120.000048 fps (4e-7 off), a ``0.008333`` one 120.0048 (4e-5); a rate asked for on purpose, 119.99 or 25.002
#: (8e-5 off), is kept (a review)
FPS_RTOL = 5e-5


def nominal_fps(fps: float) -> float:
    """The frame rate ``fps`` stands for: a whole number or one of :data:`COMMON_FPS` within :data:`FPS_RTOL`
    (relative) of it, else ``fps`` itself.  What the writers write (USD's ``timeCodesPerSecond``, Alembic's time
    sampling, XDMF's times) and ``segadeform motion info`` says, so a file read at 1 / 0.00833333 fps is 120 in both."""
    f = float(fps)
    if not (np.isfinite(f) and f > 0):
        return f
    for rate in (float(round(f)), *COMMON_FPS):
        if rate > 0 and abs(f - rate) <= FPS_RTOL * rate:
            return rate
    return f


def _write_error(e: OSError, path):
    from .atomic import write_error

    return write_error(e, path)


def to_up(points: np.ndarray, up: str) -> np.ndarray:
    """Points in the package's +Y-up convention, as written for ``up`` ("y": unchanged, "z": Z-up).

    Shapes:
        points: (..., 3) -> (..., 3)
    """
    if up == "y":
        return points
    if up == "z":
        return np.asarray(points) @ np.array(Y_TO_Z).T
    raise InputError("unknown up axis", expected=" | ".join(UP_AXES), got=up)


def output_unit(units, *, option: str = "output units") -> float:
    """Metres per written unit of ``units``: a name of :data:`UNIT_SCALES` (``"cm"`` -> 0.01) or a positive number
    (metres per unit, as a number or its text) inside :data:`OUTPUT_UNIT_RANGE`.  ``option`` names where it came
    from in the error."""
    if isinstance(units, str) and units.strip().lower() in UNIT_SCALES:
        return UNIT_SCALES[units.strip().lower()]
    expected = " | ".join(UNIT_SCALES) + f" or metres per unit ({OUTPUT_UNIT_RANGE[0]:g}..{OUTPUT_UNIT_RANGE[1]:g})"
    if isinstance(units, bool):
        raise InputError(f"unknown {option}", expected=expected, got=units)
    try:
        f = float(units)
    except (TypeError, ValueError):
        raise InputError(f"unknown {option}", expected=expected, got=units) from None
    lo, hi = OUTPUT_UNIT_RANGE
    if not lo <= f <= hi:  # NaN too
        hint = " (a number is metres per unit: centimetres are cm or 0.01)" if f > hi else ""
        raise InputError(f"{option} out of range", expected=expected, got=f"{units}{hint}")
    return f


def to_output(points: np.ndarray, up: str, unit: float = 1.0) -> np.ndarray:
    """Points in the package's convention (+Y up, metres) as written for ``up`` and ``unit`` (metres per written
    unit: 0.01 writes centimetres).

    Shapes:
        points: (..., 3) -> (..., 3)
    """
    p = to_up(points, up)
    return p if unit == 1.0 else np.asarray(p) / unit


class SequenceWriter:
    """Base class of the streaming writers (see the module docstring).

    Attributes:
        path: the output; num_points: vertices per frame; num_samples: frames written so far.
    """

    #: a writer whose ``close`` needs at least one frame
    needs_frames = True

    def __init__(self, path: str | os.PathLike, num_points: int, *, up: str = "y", unit: float = 1.0) -> None:
        if int(num_points) <= 0:
            raise InputError("num_points must be positive", got=num_points)
        if up not in UP_AXES:
            raise InputError("unknown up axis", expected=" | ".join(UP_AXES), got=up)
        self.path = Path(path)
        self.num_points = int(num_points)
        self.num_samples = 0
        self.up = up
        self.unit = output_unit(unit)  # metres per written unit
        self._closed = False

    # ---- what a format provides ---------------------------------------------------------------
    def _append(self, frames: np.ndarray) -> None:  # (B, N, 3) finite, already in the output axes and units
        raise NotImplementedError

    def _commit(self) -> None:
        raise NotImplementedError

    def _discard(self) -> None:
        raise NotImplementedError

    # ---- the shared lifecycle ---------------------------------------------------------------------
    def check(self, frames: np.ndarray) -> np.ndarray:
        """Frames as (B, N, 3), validated."""
        a = np.asarray(frames)
        if a.ndim == 2:
            a = a[None]
        if a.ndim != 3 or a.shape[1:] != (self.num_points, 3):
            raise InputError(
                "frames have the wrong shape",
                path=self.path,
                expected=f"(N, 3) or (B, N, 3) with N = {self.num_points}",
                got=a.shape,
            )
        if not np.isfinite(a).all():
            raise InputError("frames contain NaN or inf", path=self.path)
        return a

    def write(self, frames: np.ndarray) -> None:
        """Append ``(N, 3)`` or ``(B, N, 3)`` frames (+Y up, metres; written in ``up`` and ``unit``)."""
        if self._closed:
            raise InputError(f"{type(self).__name__} is closed", path=self.path)
        a = self.check(frames)
        try:
            self._append(to_output(a, self.up, self.unit))
        except OSError as e:  # disk full, ulimit -f: name the output, leave nothing
            self.abort()
            raise _write_error(e, self.path) from None
        self.num_samples += a.shape[0]

    def close(self) -> Path:
        """Commit the output and return its path (idempotent)."""
        if self._closed:
            return self.path
        if self.needs_frames and self.num_samples == 0:
            self.abort()
            raise InputError("no frames were written", path=self.path)
        try:
            self._commit()
        except OSError as e:
            self.abort()
            raise _write_error(e, self.path) from None
        self._closed = True
        return self.path

    def abort(self) -> None:
        """Discard everything written; no output is left."""
        if self._closed:
            return
        try:
            self._discard()
        finally:
            self._closed = True

    def __enter__(self):
        return self

    def __exit__(self, exc_type, exc, tb) -> None:
        if exc_type is None:
            self.close()
        else:
            self.abort()

    def __del__(self):  # a writer dropped without close leaves nothing behind
        try:
            self.abort()
        except Exception:
            pass
