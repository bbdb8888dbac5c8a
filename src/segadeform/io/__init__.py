"""Mesh, point-cache and sequence IO, one module per format, chosen by extension.

``read_mesh`` / ``write_mesh`` dispatch on the file extension through
:data:`MESH_READERS` / :data:`MESH_WRITERS`; OBJ has a strict reader of its
own, other formats go through meshio.  Output sequence formats live in one
registry (:mod:`segadeform.io.formats`); their writers share one lifecycle
(:class:`~segadeform.io.writer.SequenceWriter`: ``write(frames)``, ``close()``,
``abort()``, context manager, an ``up`` axis option) so callers stream frames
without caring about the format.
"""

from __future__ import annotations

import os
from collections.abc import Callable
from pathlib import Path

from ..errors import InputError
from .atomic import atomic_directory, atomic_open, atomic_path
from .formats import (
    SEQUENCE_FORMATS,
    SequenceFormat,
    format_for_path,
    open_sequence_writer,
    read_sequence,
    register_sequence_format,
    sequence_format,
)
from .gltf import read_gltf_mesh
from .mesh import Mesh, validate_mesh_arrays
from .meshio_formats import read_meshio, write_meshio
from .obj import read_obj, write_obj
from .off import read_off
from .outputs import SceneOutput
from .pc2 import PC2Writer, PointCache, read_pc2, read_pc2_header, write_pc2
from .sequence import (
    ObjSequenceWriter,
    XdmfSequenceWriter,
    read_obj_sequence,
    read_xdmf_sequence,
    write_obj_sequence,
    write_xdmf_sequence,
)
from .writer import UNIT_SCALES, UP_AXES, Y_TO_Z, SequenceWriter, output_unit, to_output, to_up

__all__ = [
    "Mesh",
    "read_mesh",
    "write_mesh",
    "MESH_READERS",
    "MESH_WRITERS",
    "read_obj",
    "write_obj",
    "read_off",
    "read_pc2",
    "read_pc2_header",
    "write_pc2",
    "PC2Writer",
    "PointCache",
    "read_obj_sequence",
    "write_obj_sequence",
    "read_xdmf_sequence",
    "write_xdmf_sequence",
    "ObjSequenceWriter",
    "XdmfSequenceWriter",
    "SEQUENCE_FORMATS",
    "SequenceFormat",
    "SequenceWriter",
    "open_sequence_writer",
    "read_sequence",
    "register_sequence_format",
    "sequence_format",
    "format_for_path",
    "UP_AXES",
    "Y_TO_Z",
    "to_up",
    "to_output",
    "output_unit",
    "UNIT_SCALES",
    "SceneOutput",
    "atomic_path",
    "atomic_open",
    "atomic_directory",
    "validate_mesh_arrays",
]

MESH_READERS: dict[str, Callable[[Path], Mesh]] = {
    ".obj": read_obj,
    ".off": read_off,
    ".glb": read_gltf_mesh,  # an engine's export (extra gltf: pygltflib)
    ".gltf": read_gltf_mesh,
}
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
    if ext == ".mhclo":  # a binding, not a mesh: it places its OBJ on a body (at a body shape)
        raise InputError(
            "a MakeHuman binding is not a mesh: fit it to the body first",
            path=p,
            expected=f"a garment mesh: run `segadeform garment fit {p} -o FITTED.obj` (--betas for a body shape)",
            got=".mhclo",
        )
    raise InputError(
        "unknown mesh file extension",
        path=p,
        expected=", ".join(sorted(set(MESH_READERS) | set(_MESHIO_EXTS))),
        got=ext or "none",
    )


def write_mesh(path: str | os.PathLike, mesh: Mesh, **kw) -> None:
    """Write a mesh atomically; the writer is chosen by extension."""
    p = Path(path)
    writer = MESH_WRITERS.get(p.suffix.lower())
    if writer is not None:
        writer(p, mesh, **kw)
    else:
        write_meshio(p, mesh, **kw)
