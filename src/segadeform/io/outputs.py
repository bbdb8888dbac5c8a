"""Everything a run or a simulation writes for a scene, as one unit: the garment sequence and, if asked,
the posed body sequence with (for point caches) the body's rest mesh the cache animates.

All of it is written atomically and committed or discarded together; :meth:`SceneOutput.close`
returns every path written, so callers can announce each one.  With an
:class:`~segadeform.io.output_guard.OutputGuard` (the command's output rule), every target is claimed first
(:func:`claim_scene_outputs`), checked again just before the commit, and recorded after it.
"""

from __future__ import annotations

import logging
import os
from pathlib import Path
from typing import cast

import numpy as np

from ..errors import FileFormatError, InputError
from .formats import SEQUENCE_FORMATS, format_for_path, open_sequence_writer, sequence_format
from .writer import output_unit, to_output

__all__ = ["SceneOutput", "claim_scene_outputs", "body_output_format", "output_format_for", "garment_surface"]

log = logging.getLogger(__name__)

#: formats whose files say nothing of their up axis and whose importers (Blender's, Maya's, Houdini's) read them +Y up
#: and turn them to their own world: ``up = "z"`` there lays the garment on its back (USD says ``upAxis``; PC2 is
#: README's recipe, where a Z-up cache is for tools that read raw positions)
Y_UP_FORMATS = ("abc", "obj-seq")


def _warn_z_up(path, fmt: str, up: str) -> None:
    if up == "z" and fmt in Y_UP_FORMATS:
        log.warning(
            "%s: up axis z (--up z) writes Z-up points into %s, which have no up-axis field; importers (Blender, "
            "Maya, Houdini) read them Y-up and turn them themselves, so the mesh comes in on its back: use up y",
            path,
            "Alembic files" if fmt == "abc" else "OBJ files",
        )


def _extensions() -> str:
    return " | ".join(e for f in SEQUENCE_FORMATS.values() for e in f.extensions) + " | a folder (no extension)"


def _check_name(path) -> None:
    """An output's name must be more than an extension: ``nm/.usda`` has none (pathlib calls all of it the stem, so it
    was a hidden OBJ-sequence folder named ``.usda``)."""
    p = Path(path)
    known = {e for f in SEQUENCE_FORMATS.values() for e in f.extensions} | set(_NOT_SEQUENCES)
    if p.name.startswith(".") and p.name.lower() in known:
        raise InputError(
            "the output's file name is only an extension, with no name before it",
            path=path,
            expected=f"e.g. {p.with_name('out' + p.name)}",
            got=p.name,
        )


def output_format_for(path, fmt: str | None = None) -> str:
    """The format a sequence output at ``path`` is written in: ``fmt`` where given, else the one its extension
    names (no extension: the folder format).  An error when neither says, when ``fmt`` contradicts the
    extension (``out.usda`` with ``fmt = "pc2"`` would be a point cache no USD reader opens), when the name is only an
    extension (``.usda``), or when a folder format's name has a mesh file's extension (``d.obj``)."""
    _check_name(path)
    named = format_for_path(path)
    if fmt is None:
        if named is None:
            raise InputError(
                "cannot tell the output format from the file extension",
                path=path,
                expected=_extensions(),
                got=Path(path).suffix,
            )
        return named.name
    f = sequence_format(fmt)
    if f.folder and Path(path).suffix.lower() in _NOT_SEQUENCES:  # a folder called d.obj holding frame_00000.obj
        raise InputError(
            "an OBJ sequence is a folder",
            path=path,
            expected=f"a folder name without {Path(path).suffix}",
            got=Path(path).name,
        )
    if named is not None and Path(path).suffix and named.name != f.name:
        raise InputError(
            f"the extension says {named.name}, the format asked for is {f.name}",
            path=path,
            expected=" | ".join(f.extensions) or "no extension (a folder)",
            got=Path(path).suffix,
        )
    return f.name


def garment_surface(path, n_vertices: int, fmt: str):
    """The polygons and texture coordinates of garment file ``path`` for a writer of format ``fmt`` that keeps
    them: an OBJ's own (:func:`~segadeform.io.surface.obj_surface`) when its faces index ``n_vertices`` vertices or
    fewer (the frames' vertices are the file's, in its order); else None (formats that write triangles only, other
    garment files, precomputed assets, an OBJ whose polygons or UVs cannot be read: the triangles then)."""
    from .formats import _takes_parameter
    from .surface import obj_surface

    if Path(path).suffix.lower() != ".obj" or not _takes_parameter(sequence_format(fmt).open, "surface"):
        return None
    try:
        s = obj_surface(path)
    except FileFormatError:
        return None
    return s if s.n_vertices_used <= n_vertices else None


#: extensions of files that are not frame sequences (meshes, motions): a body output named so is an error, not
#: the garment's format under a misleading name
_NOT_SEQUENCES = (".obj", ".ply", ".stl", ".off", ".glb", ".gltf", ".fbx", ".npz", ".bvh", ".amc", ".png", ".gif")


def body_output_format(body_path, fmt: str | None = None, garment_path=None) -> str:
    """The format the posed body is written in: the one ``body_path``'s own extension names, whatever the
    garment's output is (``--body-out body.pc2`` beside ``-o dress.usd`` writes a point cache); with no
    extension a folder of OBJ frames, as for the garment's own path -- unless the garment's path (``garment_path``)
    has none either, its format ``fmt`` then given apart (``-o anim --format pc2 --body-out body``: both point
    caches, as before); with an extension no format claims (``body.cache``), the garment's format ``fmt``, as before;
    an error for the extension of a mesh or another kind of file (``body.obj``).  (An extension-less body beside
    ``-o dress.abc`` was written in the garment's format: an Alembic file with no extension, which ``inspect``
    refused, and a USD refused as no USD name -- while ``run --help`` said a folder of OBJ frames: a new user's
    trial.)"""
    p = Path(body_path)
    _check_name(p)
    named = format_for_path(p)
    if p.suffix and named is not None:
        return named.name
    if fmt is not None and p.suffix and p.suffix.lower() not in _NOT_SEQUENCES:
        return sequence_format(fmt).name
    if fmt is not None and not p.suffix and garment_path is not None and not Path(garment_path).suffix:
        return sequence_format(fmt).name
    return output_format_for(p)


def _targets(path, fmt: str, body_path=None) -> list[tuple[Path, bool]]:
    """Every path a scene output writes, each with whether it is a folder of frames; an error when two are the
    same path (the body would overwrite the garment, or a point cache's rest mesh the body)."""
    out = [(Path(path), sequence_format(fmt).folder)]
    if body_path is not None:
        bf = body_output_format(body_path, fmt, path)
        out.append((Path(body_path), sequence_format(bf).folder))
        if bf == "pc2":  # the rest mesh the body's cache animates
            out.append((Path(body_path).with_suffix(".obj"), False))
    seen: set = set()
    for p, _ in out:
        key = os.path.normcase(os.path.abspath(p))
        if key in seen:
            raise InputError(
                "two outputs of this run would be written to this one path",
                path=p,
                expected="a garment output and a body output at different paths",
            )
        seen.add(key)
    return out


def claim_scene_outputs(guard, path, fmt: str, body_path=None) -> None:
    """Claim with ``guard`` (:class:`~segadeform.io.output_guard.OutputGuard`) every path a scene output writes:
    the garment output (a file, or for a folder format a folder of ``frame_*.obj``), the body output (in the
    format its own extension names: :func:`body_output_format`) and, for a point-cached body, its rest mesh
    beside it (``.obj``).  Two outputs at one path are an error, before anything is claimed."""
    for p, folder in _targets(path, fmt, body_path):
        if folder:
            guard.folder(p, names="frame_*.obj")
        else:
            guard.file(p)


class SceneOutput:
    """Writers for a scene's outputs.

    Args:
        path, fmt: the garment output and its format (a name in :data:`~segadeform.io.SEQUENCE_FORMATS`).
        up: axes of the written coordinates ("y" as computed, "z" turned to Z-up).
        unit: metres per written unit (1: metres as computed; 0.01: centimetres, as Maya and Unreal work), the
            body's frames and its rest mesh alike (:func:`~segadeform.io.writer.output_unit`).
        fps, start_frame: timing of the first written frame.
        garment_faces (F, 3), garment_rest (N, 3): the garment mesh.
        garment_surface: the garment file's own polygons and texture coordinates
            (:class:`~segadeform.io.surface.Surface`; :func:`garment_surface`), kept by the formats that can.
        body_path: also write the posed body here, in the format its extension names
            (:func:`body_output_format`), with ``body_faces`` and ``body_rest`` (V, 3) -- for PC2 the rest mesh
            goes beside it as ``.obj``.
        guard: the command's :class:`~segadeform.io.output_guard.OutputGuard` that claimed these outputs
            (:func:`claim_scene_outputs`; None: no rule, library use): checked again before the commit and
            recorded after it.
    """

    def __init__(
        self,
        *,
        path: str | os.PathLike,
        fmt: str,
        up: str = "y",
        unit: float = 1.0,
        fps: float = 30.0,
        start_frame: int = 0,
        garment_faces: np.ndarray,
        garment_rest: np.ndarray,
        body_path: os.PathLike | None = None,
        body_faces: np.ndarray | None = None,
        body_rest: np.ndarray | None = None,
        guard=None,
        garment_surface=None,
    ) -> None:
        _targets(path, fmt, body_path)  # unknown formats and clashing paths fail before anything is opened
        self.fmt, self.up, self.unit, self.guard = fmt, up, output_unit(unit), guard
        self.body_fmt = body_output_format(body_path, fmt, path) if body_path is not None else None
        _warn_z_up(path, fmt, up)
        if body_path is not None:
            _warn_z_up(body_path, cast(str, self.body_fmt), up)
        rest = np.asarray(garment_rest, np.float64)
        self.garment = open_sequence_writer(
            path,
            fmt,
            faces=garment_faces,
            num_points=len(rest),
            fps=fps,
            start_frame=start_frame,
            rest=rest,
            up=up,
            surface=garment_surface,
            unit=self.unit,
        )
        self.body = None
        self._body_rest = None
        if body_path is not None:
            try:
                self.body = open_sequence_writer(
                    body_path,
                    cast(str, self.body_fmt),
                    faces=cast(np.ndarray, body_faces),
                    num_points=len(cast(np.ndarray, body_rest)),
                    fps=fps,
                    start_frame=start_frame,
                    rest=np.asarray(body_rest),
                    up=up,
                    unit=self.unit,
                )
            except BaseException:
                self.garment.abort()
                raise
            self._body_faces, self._body_rest = body_faces, np.asarray(body_rest, np.float64)

    def write(self, garment_frames: np.ndarray, body_frames: np.ndarray | None = None) -> None:
        """Append frames ``(B, N, 3)`` (+Y up) of the garment and, when writing it, the body."""
        self.garment.write(garment_frames)
        if self.body is not None:
            self.body.write(body_frames)

    def close(self) -> list[Path]:
        """Commit everything; the paths written, garment first."""
        from .mesh import Mesh
        from .obj import write_obj

        if self.guard is not None:
            self.guard.recheck()  # nothing appeared at the targets since they were claimed
        written = [self.garment.close()]
        if self.body is not None:
            written.append(self.body.close())
            if self.body_fmt == "pc2":  # the rest mesh the cache animates (Blender's Mesh Cache, 3ds Max)
                obj = Path(self.body.path).with_suffix(".obj")
                write_obj(
                    obj,
                    Mesh(
                        vertices=to_output(cast(np.ndarray, self._body_rest), self.up, self.unit),
                        faces=cast(np.ndarray, self._body_faces),
                    ),
                )
                written.append(obj)
        if self.guard is not None:
            self.guard.record()
        return written

    def abort(self) -> None:
        self.garment.abort()
        if self.body is not None:
            self.body.abort()

    def __enter__(self):
        return self

    def __exit__(self, exc_type, exc, tb) -> None:
        if exc_type is not None:
            self.abort()
