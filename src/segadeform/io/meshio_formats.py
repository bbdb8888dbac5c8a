"""Formats other than OBJ and OFF (PLY, STL, VTK, ...), read and written through meshio.

meshio keeps points in file order for PLY, OFF and VTK.  Its STL reader
merges coincident facet corners and returns them in sorted order (STL has no
shared vertices, so there is no file order to keep): point caches for an STL
garment address that order.  Quads and polygons are fan-triangulated; line
and vertex cells are ignored.
"""

from __future__ import annotations

import contextlib
import io
import os
import re
import warnings
from pathlib import Path

import numpy as np

from ..errors import FileFormatError, InputError
from .atomic import atomic_path
from .mesh import Mesh, triangulate_polygon, validate_mesh_arrays

__all__ = ["read_meshio", "write_meshio"]

_SURFACE_CELLS = {"triangle", "quad", "polygon"}
_IGNORED_CELLS = {"vertex", "line", "line3"}


def read_meshio(path: str | os.PathLike, file_format: str | None = None) -> Mesh:
    """Read any surface mesh meshio understands; see the module docstring."""
    import meshio

    p = Path(path)
    if not p.is_file():
        raise FileFormatError("no such file", path=p)
    said = io.StringIO()  # meshio prints its readers' errors and "Couldn't read file" itself, then exits
    try:
        with warnings.catch_warnings(), contextlib.redirect_stdout(said), contextlib.redirect_stderr(said):
            warnings.simplefilter("ignore")
            m = meshio.read(p, file_format=file_format)
    except InputError:
        raise
    except (Exception, SystemExit) as e:
        # meshio raises many kinds (ReadError, ValueError, struct.error ...), and exits (after printing why) when no
        # reader could read the file, or its PLY reader meets an unknown header line: the first thing it said, on
        # the one line of the error (it printed over several lines before it: a new user's trial)
        lines = [ln.strip() for ln in said.getvalue().splitlines() if ln.strip()]
        text = str(e).strip() if isinstance(e, Exception) else ""
        msg = text.splitlines()[0] if text else (lines[0] if lines else type(e).__name__)
        msg = re.sub(r"^Error: Couldn't read file .* as (.*)$", r"no \1 that meshio reads", msg)  # the path said once
        raise FileFormatError(f"cannot parse mesh: {msg}", path=p) from None
    pts = np.asarray(m.points)
    if pts.ndim == 2 and pts.shape[1] == 2:
        raise FileFormatError("mesh is 2-D", path=p, expected="3-D points", got=pts.shape)
    faces: list[np.ndarray] = []
    origin: list[np.ndarray] = []
    n_poly = 0
    for block in m.cells:
        ctype, data = block.type, block.data
        if ctype in _IGNORED_CELLS:
            continue
        if ctype not in _SURFACE_CELLS and not ctype.startswith("polygon"):
            raise FileFormatError(f"unsupported cell type {ctype!r}", path=p, expected="triangles, quads or polygons")
        if isinstance(data, list):  # ragged polygons
            polys = [np.asarray(x, dtype=np.int64) for x in data]
        else:
            data = np.asarray(data, dtype=np.int64)
            if data.ndim != 2 or data.shape[1] < 3:
                raise FileFormatError("face has fewer than 3 vertices", path=p, got=data.shape)
            if data.shape[1] == 3:
                faces.append(data)
                origin.append(np.arange(n_poly, n_poly + len(data)))
                n_poly += len(data)
                continue
            polys = list(data)
        for poly in polys:
            if len(poly) < 3:
                raise FileFormatError("face has fewer than 3 vertices", path=p, got=len(poly))
            t = triangulate_polygon(poly)
            faces.append(t)
            origin.append(np.full(len(t), n_poly))
            n_poly += 1
    f = np.concatenate(faces) if faces else np.zeros((0, 3), np.int64)
    v, f = validate_mesh_arrays(pts, f, path=p, bounded=True)
    return Mesh(
        vertices=v, faces=f, path=str(p), face_origin=np.concatenate(origin) if origin else np.zeros(0, np.int64)
    )


def write_meshio(path: str | os.PathLike, mesh: Mesh, *, vertices=None, file_format: str | None = None) -> None:
    """Write a triangle mesh through meshio, atomically."""
    import meshio

    v = mesh.vertices if vertices is None else np.asarray(vertices)
    v, f = validate_mesh_arrays(v, mesh.faces, allow_no_faces=True)
    p = Path(path)
    fmt = file_format or meshio.extension_to_filetypes.get(p.suffix.lower(), [None])[0]
    if fmt is None:
        raise InputError("unknown mesh file extension", path=p, got=p.suffix)
    with atomic_path(p) as tmp:
        meshio.write_points_cells(tmp, v, [("triangle", f)], file_format=fmt)
