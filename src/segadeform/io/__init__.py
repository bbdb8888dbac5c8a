"""Mesh, point-cache and sequence IO, one module per format, chosen by extension.

``read_mesh`` / ``write_mesh`` dispatch on the file extension through
:data:`MESH_READERS` / :data:`MESH_WRITERS`; OBJ has a strict reader of its
own, other formats go through meshio.  Sequence writers share one interface
(``write(frames)``, ``close()``, ``abort()``, context manager) so callers
stream frames without caring about the format.
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import Callable

import numpy as np

from ..errors import InputError
from .atomic import atomic_directory, atomic_open, atomic_path
from .mesh import Mesh, validate_mesh_arrays
from .meshio_formats import read_meshio, write_meshio
from .obj import read_obj, write_obj
from .off import read_off
from .pc2 import PC2Writer, PointCache, read_pc2, read_pc2_header, write_pc2
from .sequence import (ObjSequenceWriter, XdmfSequenceWriter, read_obj_sequence,
                       read_xdmf_sequence, write_obj_sequence, write_xdmf_sequence)

__all__ = [
    "Mesh", "read_mesh", "write_mesh", "MESH_READERS", "MESH_WRITERS",
    "read_obj", "write_obj", "read_off", "read_pc2", "read_pc2_header", "write_pc2", "PC2Writer", "PointCache",
    "read_obj_sequence", "write_obj_sequence", "read_xdmf_sequence", "write_xdmf_sequence",
    "SEQUENCE_FORMATS", "open_sequence_writer", "read_sequence",
    "atomic_path", "atomic_open", "atomic_directory", "validate_mesh_arrays",
]

MESH_READERS: dict[str, Callable[[Path], Mesh]] = {".obj": read_obj, ".off": read_off}
MESH_WRITERS: dict[str, Callable[..., None]] = {".obj": write_obj}
_MESHIO_EXTS = (".ply", ".stl", ".vtk", ".vtu", ".msh", ".mesh", ".gmsh")


def read_mesh(path: str | os.PathLike) -> Mesh:
    """Read a garment mesh; the reader is chosen by extension (meshio for non-OBJ)."""
    p = Path(path)
    ext = p.suffix.lower()
    if ext in MESH_READERS:
        return MESH_READERS[ext](p)
    if ext in _MESHIO_EXTS:
        return read_meshio(p)
    raise InputError("unknown mesh file extension", path=p,
                     expected=", ".join(sorted(set(MESH_READERS) | set(_MESHIO_EXTS))), got=ext or "none")


def write_mesh(path: str | os.PathLike, mesh: Mesh, **kw) -> None:
    """Write a mesh atomically; the writer is chosen by extension."""
    p = Path(path)
    writer = MESH_WRITERS.get(p.suffix.lower())
    if writer is not None:
        writer(p, mesh, **kw)
    else:
        write_meshio(p, mesh, **kw)


SEQUENCE_FORMATS = ("pc2", "obj-seq", "xdmf", "abc")


def open_sequence_writer(path, fmt: str, *, faces: np.ndarray, num_points: int, fps: float = 30.0,
                         start_frame: int = 0, rest: np.ndarray | None = None):
    """A streaming writer for ``fmt`` in :data:`SEQUENCE_FORMATS`."""
    if fmt == "pc2":
        return PC2Writer(path, num_points, start_frame=float(start_frame), sample_rate=1.0)
    if fmt == "obj-seq":
        return ObjSequenceWriter(path, faces, num_points, start=start_frame)
    if fmt == "xdmf":
        return XdmfSequenceWriter(path, faces, num_points, rest=rest, fps=fps, start=start_frame)
    if fmt == "abc":
        from .alembic import AlembicSequenceWriter

        return AlembicSequenceWriter(path, faces, num_points, fps=fps, start_frame=start_frame)
    raise InputError("unknown sequence format", expected=" | ".join(SEQUENCE_FORMATS), got=fmt)


def read_sequence(path: str | os.PathLike, *, faces: np.ndarray | None = None) -> np.ndarray:
    """Read frames ``(S, N, 3)`` from a .pc2 file, an OBJ-sequence folder or an .xdmf file."""
    p = Path(path)
    if p.is_dir():
        return read_obj_sequence(p)[1]
    ext = p.suffix.lower()
    if ext == ".pc2":
        return np.asarray(read_pc2(p, check_finite=True).frames, np.float64)
    if ext in (".xdmf", ".xmf"):
        return read_xdmf_sequence(p)[1]
    if ext == ".abc":
        from .alembic import read_alembic_sequence

        return read_alembic_sequence(p)[1]
    raise InputError("unknown sequence format", path=p, expected=".pc2, .xdmf, .abc or a folder of OBJ frames",
                     got=ext or "none")
