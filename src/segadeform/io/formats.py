"""The one home of the file formats: the output (sequence) formats -- name, extensions, writer and reader,
registered by name -- and the other files (:data:`FILE_FORMATS`: the portable ``.sgdb``/``.sgda``/``.sgdm`` files
and ``.mhclo`` bindings, each with its reader and writer in this package).

Scenes (``output.format``), the CLI (``--format``, ``inspect``, ``preview``) and the
runtime and simulator all read this registry; adding a format is one
:func:`register_sequence_format` call with a :class:`~segadeform.io.writer.SequenceWriter`
subclass and a reader (and, optionally, an ``inspect`` hook that describes a file's header for
``segadeform inspect``; without one, inspect reads the frames with ``read`` and counts them).

=========  ==================  =====================================================  =========
name       extensions          what                                                    extra
=========  ==================  =====================================================  =========
pc2        .pc2                point cache (3ds Max, Blender Mesh Cache, Houdini)
obj-seq    (a folder)          one OBJ per frame, ``frame_00000.obj`` ...
xdmf       .xdmf .xmf          XDMF time series (ParaView)
abc        .abc                Alembic polygon mesh (Blender, Maya, Houdini)           alembic
usd        .usd .usda .usdc    USD mesh, time-sampled points (Blender, Houdini ...)    usd
=========  ==================  =====================================================  =========
"""

from __future__ import annotations

import dataclasses
import os
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

from ..errors import InputError

__all__ = [
    "SequenceFormat",
    "SEQUENCE_FORMATS",
    "register_sequence_format",
    "sequence_format",
    "format_for_path",
    "sequence_format_of",
    "open_sequence_writer",
    "read_sequence",
    "inspect_sequence",
    "sequence_start_frame",
    "FileFormat",
    "FILE_FORMATS",
    "register_file_format",
    "file_format_for",
]


@dataclasses.dataclass(frozen=True)
class SequenceFormat:
    """An output format.

    Attributes:
        name: what scenes and ``--format`` call it.
        extensions: file extensions (lower case, with the dot); empty for a folder format.
        open: ``open(path, *, faces, num_points, fps, start_frame, rest, up, surface) -> SequenceWriter``;
            ``surface``: the garment file's own polygons and texture coordinates
            (:class:`~segadeform.io.surface.Surface`, or None), which a format keeps where it can.
        read: ``read(path, faces) -> frames (S, N, 3)``.
        description: one line for help texts.
        extra: the optional dependency group it needs, if any.
        inspect: optional ``inspect(path) -> (summary, frames)`` for ``segadeform inspect``: a one-line
            summary of the file (its header: counts, start frame ...) and its frames ``(S, N, 3)`` (an array,
            or :class:`~segadeform.io.sequence.LazyFrames` read when indexed) with non-finite values kept
            (inspect reports them).  None: ``read`` and a summary of the counts.
        start: optional ``start(path) -> int``: the frame number of the file's first frame (``run --frames
            10:40`` writes 10), for :func:`sequence_start_frame`.  None: the format keeps none (0).
        units: optional ``units(path) -> float``: the metres per unit the file records (USD's ``metersPerUnit``),
            for :func:`sequence_units`.  None: the format records none (its points are read as they are).
    """

    name: str
    extensions: tuple
    open: Callable
    read: Callable
    description: str
    extra: str | None = None
    inspect: Callable | None = None
    start: Callable | None = None
    units: Callable | None = None

    @property
    def folder(self) -> bool:
        return not self.extensions


SEQUENCE_FORMATS: dict[str, SequenceFormat] = {}


def _register(registry: dict, fmt, what: str):
    """Add ``fmt`` to ``registry`` under its name; an error if the name is taken."""
    if fmt.name in registry:
        raise InputError(f"{what} format {fmt.name!r} is already registered")
    registry[fmt.name] = fmt
    return fmt


def register_sequence_format(fmt: SequenceFormat) -> SequenceFormat:
    return _register(SEQUENCE_FORMATS, fmt, "sequence")


def sequence_format(name: str) -> SequenceFormat:
    """The format called ``name``; an error listing the known ones otherwise."""
    try:
        return SEQUENCE_FORMATS[name]
    except KeyError:
        raise InputError("unknown sequence format", expected=" | ".join(SEQUENCE_FORMATS), got=name) from None


def format_for_path(path: str | os.PathLike) -> SequenceFormat | None:
    """The format a path's extension names (no extension: the folder format), or None."""
    p = Path(path)
    ext = p.suffix.lower()
    for f in SEQUENCE_FORMATS.values():
        if (ext and ext in f.extensions) or (not ext and f.folder):
            return f
    return None


def sequence_format_of(path: str | os.PathLike) -> SequenceFormat | None:
    """The format of an existing output: a folder is the folder format, a file goes by its extension; None
    when no registered format claims it."""
    p = Path(path)
    if p.is_dir():
        return next((f for f in SEQUENCE_FORMATS.values() if f.folder), None)
    f = format_for_path(p)
    return None if f is None or f.folder else f


def open_sequence_writer(
    path,
    fmt: str,
    *,
    faces: np.ndarray,
    num_points: int,
    fps: float = 30.0,
    start_frame: int = 0,
    rest: np.ndarray | None = None,
    up: str = "y",
    surface=None,
    unit: float = 1.0,
):
    """A streaming writer (:class:`~segadeform.io.writer.SequenceWriter`) for the format called ``fmt``;
    ``surface``: polygons and texture coordinates to keep (:class:`~segadeform.io.surface.Surface`; OBJ frames,
    USD and Alembic keep them, the others write ``faces``); ``unit``: metres per written unit (0.01: centimetres;
    USD records it as ``metersPerUnit``, the other formats have no field for it)."""
    f = sequence_format(fmt)
    kw = (
        {"surface": surface} if surface is not None and _takes_parameter(f.open, "surface") else {}
    )  # formats from before it
    if unit != 1.0:
        if not _takes_parameter(f.open, "unit"):
            raise InputError(f"the {fmt} writer cannot write other units than metres", path=path, got=unit)
        kw["unit"] = unit
    return f.open(path, faces=faces, num_points=num_points, fps=fps, start_frame=start_frame, rest=rest, up=up, **kw)


def _takes_parameter(open_fn, name: str) -> bool:
    """Whether a format's opener takes the keyword ``name`` (formats registered before it existed do not)."""
    import inspect

    try:
        params = inspect.signature(open_fn).parameters
    except (TypeError, ValueError):
        return False
    return name in params or any(p.kind is p.VAR_KEYWORD for p in params.values())


def read_sequence(path: str | os.PathLike, *, faces: np.ndarray | None = None) -> np.ndarray:
    """Frames ``(S, N, 3)`` (float64) of any registered format, chosen by extension (a folder: OBJ sequence)."""
    p = Path(path)
    f = sequence_format_of(p)
    if f is None and not p.suffix:  # a folder output that is not there (its reader says so)
        f = format_for_path(p)
    if f is None:
        known = ", ".join(e for f2 in SEQUENCE_FORMATS.values() for e in f2.extensions)
        raise InputError(
            "unknown sequence format", path=p, expected=f"{known} or a folder of OBJ frames", got=p.suffix or "none"
        )
    return np.asarray(f.read(p, faces), np.float64)


def sequence_start_frame(path: str | os.PathLike) -> int:
    """The frame number of a written sequence's first frame: the motion frame its run started at (the PC2 header's
    start frame, the first USD time code, the first OBJ frame's number, the first XDMF or Alembic time over the
    time per frame); 0 for a format that keeps none."""
    p = Path(path)
    f = sequence_format_of(p)
    return 0 if f is None or f.start is None else int(round(f.start(p)))


def sequence_units(path: str | os.PathLike) -> float | None:
    """The metres per unit an output records (a USD's ``metersPerUnit``), or None when its format records none
    (PC2, OBJ, XDMF and Alembic points are numbers only: ``run --output-units`` is the reader's to know)."""
    f = sequence_format_of(Path(path))
    return None if f is None or f.units is None else float(f.units(Path(path)))


def inspect_sequence(path: str | os.PathLike) -> tuple[SequenceFormat, str, Any]:
    """``(format, summary, frames (S, N, 3))`` of an output of any registered format, for ``segadeform inspect``:
    the format's ``inspect`` hook, else its reader and the counts.  Non-finite values are kept, not refused.
    Frames a hook gives as :class:`~segadeform.io.sequence.LazyFrames` (PC2, Alembic, USD) stay so: read when
    indexed, a bounded part at a time (:func:`~segadeform.io.sequence.frame_chunks`)."""
    from .sequence import LazyFrames

    p = Path(path)
    f = sequence_format_of(p)
    if f is None:
        raise InputError(
            "not a registered sequence format", path=p, expected=", ".join(SEQUENCE_FORMATS), got=p.suffix or "none"
        )
    if f.inspect is not None:
        summary, frames = f.inspect(p)
    else:
        frames = np.asarray(f.read(p, None))
        summary = f"{frames.shape[0]} frames x {frames.shape[1]} vertices"
    return f, summary, frames if isinstance(frames, LazyFrames) else np.asarray(frames)


# ---- the built-in formats ----------------------------------------------------------------------------------
def _pc2_open(path, *, faces, num_points, fps, start_frame, rest, up, surface=None, unit=1.0):
    from .pc2 import PC2Writer

    return PC2Writer(path, num_points, start_frame=float(start_frame), sample_rate=1.0, up=up, unit=unit)


def _pc2_read(path, faces):
    from .pc2 import read_pc2

    return read_pc2(path, check_finite=True).frames


def _pc2_inspect(path):
    from .pc2 import PC2Frames

    pc = PC2Frames(path)  # read when indexed (a memory map of the whole file is resident once read through)
    h = pc.header
    return (
        f"{h.num_samples} samples x {h.num_points} points, start frame {h.start_frame:g}, "
        f"sample rate {h.sample_rate:g}",
        pc,
    )


def _pc2_start(path):
    from .pc2 import read_pc2_header

    return read_pc2_header(path).start_frame


def _objseq_start(path):
    from .sequence import obj_sequence_files

    return obj_sequence_files(path)[0][0]


def _objseq_open(path, *, faces, num_points, fps, start_frame, rest, up, surface=None, unit=1.0):
    from .sequence import ObjSequenceWriter

    return ObjSequenceWriter(path, faces, num_points, start=start_frame, up=up, surface=surface, unit=unit)


def _objseq_read(path, faces):
    from .sequence import read_obj_sequence

    return read_obj_sequence(path)[1]


def _faces_said(polygons: int, triangles: int) -> str:
    """The faces a file holds, and the triangles they make when those are more (quads: ``862 faces (1724
    triangles)``)."""
    return f"{polygons} faces" + (f" ({triangles} triangles)" if triangles != polygons else "")


def _objseq_inspect(path):
    from .obj import read_obj
    from .sequence import obj_sequence_files, read_obj_sequence

    faces, frames = read_obj_sequence(path)
    origin = read_obj(obj_sequence_files(path)[0][1], bounded=False).face_origin  # the file's polygon of each triangle
    polygons = len(faces) if origin is None else len(np.unique(origin))
    return f"{frames.shape[0]} frames x {frames.shape[1]} vertices, {_faces_said(polygons, len(faces))}", frames


def _xdmf_open(path, *, faces, num_points, fps, start_frame, rest, up, surface=None, unit=1.0):
    from .sequence import XdmfSequenceWriter

    return XdmfSequenceWriter(path, faces, num_points, rest=rest, fps=fps, start=start_frame, up=up, unit=unit)


def _xdmf_read(path, faces):
    from .sequence import read_xdmf_sequence

    return read_xdmf_sequence(path)[1]


def _xdmf_start(path):
    from .sequence import xdmf_start_frame

    return xdmf_start_frame(path)


def _abc_start(path):
    from .alembic import alembic_start_frame

    return alembic_start_frame(path)


def _abc_inspect(path):
    """A user's trial: `inspect X.abc` gave no frame rate or start frame (USD's did)."""
    from .alembic import alembic_timing, read_alembic_sequence

    faces, frames, _ = read_alembic_sequence(path, lazy=True)
    fps, start = alembic_timing(path)
    rate = f"{fps:g} fps, start frame {start:g}" if fps > 0 else "no uniform frame rate"
    return f"{frames.shape[0]} samples x {frames.shape[1]} points, {len(faces)} triangles, {rate}", frames


def _abc_open(path, *, faces, num_points, fps, start_frame, rest, up, surface=None, unit=1.0):
    from .alembic import AlembicSequenceWriter

    return AlembicSequenceWriter(
        path, faces, num_points, fps=fps, start_frame=start_frame, up=up, surface=surface, unit=unit
    )


def _abc_read(path, faces):
    from .alembic import read_alembic_sequence

    return read_alembic_sequence(path)[1]


register_sequence_format(
    SequenceFormat(
        "pc2",
        (".pc2",),
        _pc2_open,
        _pc2_read,
        "point cache (3ds Max, Blender Mesh Cache, Houdini)",
        inspect=_pc2_inspect,
        start=_pc2_start,
    )
)
register_sequence_format(
    SequenceFormat(
        "obj-seq",
        (),
        _objseq_open,
        _objseq_read,
        "a folder of OBJ frames",
        inspect=_objseq_inspect,
        start=_objseq_start,
    )
)
register_sequence_format(
    SequenceFormat("xdmf", (".xdmf", ".xmf"), _xdmf_open, _xdmf_read, "XDMF time series (ParaView)", start=_xdmf_start)
)
register_sequence_format(
    SequenceFormat(
        "abc",
        (".abc",),
        _abc_open,
        _abc_read,
        "Alembic polygon mesh (Blender, Maya, Houdini)",
        extra="alembic",
        inspect=_abc_inspect,
        start=_abc_start,
    )
)


def _usd_open(path, *, faces, num_points, fps, start_frame, rest, up, surface=None, unit=1.0):
    from .usd import UsdSequenceWriter

    return UsdSequenceWriter(
        path, faces, num_points, fps=fps, start_frame=start_frame, up=up, surface=surface, unit=unit
    )


def _usd_read(path, faces):
    from .usd import read_usd_sequence

    frames = read_usd_sequence(path)[1]
    if not np.isfinite(frames).all():
        from ..errors import FileFormatError

        raise FileFormatError("USD points contain NaN or inf", path=path)
    return frames


def _usd_start(path):
    from .usd import usd_start_frame

    return usd_start_frame(path)


def _usd_units(path):
    from .usd import usd_meters_per_unit

    return usd_meters_per_unit(path)


def _usd_inspect(path):
    from .surface import fan_triangles
    from .usd import read_usd_mesh

    counts, idx, frames, times, info = read_usd_mesh(path, lazy=True)
    faces = _faces_said(len(counts), len(fan_triangles(counts, idx)))
    return (
        f"{frames.shape[0]} time samples x {frames.shape[1]} points, {faces} ({info['prim']}), "
        f"upAxis {info['up']}, {info['meters_per_unit']:g} m per unit, {info['fps']:g} fps, time codes "
        f"{times[0]:g}..{times[-1]:g}",
        frames,
    )


register_sequence_format(
    SequenceFormat(
        "usd",
        (".usd", ".usda", ".usdc"),
        _usd_open,
        _usd_read,
        "USD mesh with time-sampled points (Blender, Houdini, usdview)",
        extra="usd",
        inspect=_usd_inspect,
        start=_usd_start,
        units=_usd_units,
    )
)


# ---- portable and input files (not frame sequences) -------------------------------------------------------------


@dataclasses.dataclass(frozen=True)
class FileFormat:
    """A file format other than a frame sequence: the portable files of other runtimes and garment inputs.

    Attributes:
        name: its short name.
        extensions: file extensions (lower case, with the dot).
        read: ``read(path)`` -> what the file holds (every field checked; errors name the file).
        description: one line for help texts.
        write: ``write(path, ...)``, written atomically; None for formats segadeform only reads.
    """

    name: str
    extensions: tuple
    read: Callable
    description: str
    write: Callable | None = None


FILE_FORMATS: dict[str, FileFormat] = {}


def register_file_format(fmt: FileFormat) -> FileFormat:
    return _register(FILE_FORMATS, fmt, "file")


def file_format_for(path: str | os.PathLike) -> FileFormat | None:
    """The registered file format a path's extension names, or None."""
    ext = Path(path).suffix.lower()
    return next((f for f in FILE_FORMATS.values() if ext in f.extensions), None)


def _register_file_formats() -> None:
    from .garment_asset import PORTABLE_SUFFIX, GarmentAsset
    from .mhclo import MHCLO_SUFFIX, read_mhclo
    from .sgdb import BUNDLE_SUFFIX, read_bundle, write_bundle
    from .sgdm import MOTION_SUFFIX, read_motion_arrays, write_motion_arrays

    def write_asset(path, asset):
        return asset.save(path)

    register_file_format(
        FileFormat(
            "sgdb",
            (BUNDLE_SUFFIX,),
            read_bundle,
            "scene bundle: named little-endian arrays and JSON meta (the container of .sgda and .sgdm)",
            write_bundle,
        )
    )
    register_file_format(
        FileFormat(
            "sgda", (PORTABLE_SUFFIX,), GarmentAsset.load, "garment asset, portable form (other runtimes)", write_asset
        )
    )
    register_file_format(
        FileFormat(
            "sgdm",
            (MOTION_SUFFIX,),
            read_motion_arrays,
            "motion file: poses and translations on one body's skeleton",
            write_motion_arrays,
        )
    )
    register_file_format(FileFormat("mhclo", (MHCLO_SUFFIX,), read_mhclo, "MakeHuman garment binding (read only)"))
    from .gltf import read_gltf_mesh

    register_file_format(
        FileFormat(
            "gltf-mesh",
            (".glb", ".gltf"),
            read_gltf_mesh,
            "glTF garment mesh, as an engine exports it (read only; --motion reads the same files' animations)",
        )
    )


_register_file_formats()
