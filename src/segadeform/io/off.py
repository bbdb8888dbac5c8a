"""Object File Format (OFF), read strictly.

meshio's OFF reader assumes every face is a triangle (it reads four integers
per face whatever the face's corner count), so quads and polygons come back
wrong.  This reader follows the format: an ``OFF`` header (the counts may
follow on the same line), ``nv nf ne``, ``nv`` vertex lines, then ``nf``
faces ``k i_1 ... i_k [colour]``.  ``#`` starts a comment.  Polygons are
fan-triangulated; vertex order is kept.  ``COFF``/``NOFF``/``CNOFF`` headers
are accepted and their extra vertex columns ignored.
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np

from ..errors import FileFormatError, file_error
from .mesh import Mesh, validate_mesh_arrays
from .numbers import integer, number

__all__ = ["read_off"]


def read_off(path: str | os.PathLike) -> Mesh:
    """Read an OFF file (Geomview's Object File Format, ASCII) into a :class:`Mesh`: its vertices in the file's order,
    polygons fanned into triangles; a malformed file is a :class:`FileFormatError` naming it."""
    p = Path(path)
    try:
        text = p.read_bytes().decode("utf-8-sig", errors="replace")  # a byte-order mark is dropped
    except OSError as e:
        raise file_error(e, p) from None
    lines = [(i, ln.split("#", 1)[0].split()) for i, ln in enumerate(text.splitlines(), start=1)]
    lines = [(i, t) for i, t in lines if t]
    if not lines or not lines[0][1][0].endswith("OFF"):
        raise FileFormatError(
            "not an OFF file",
            path=p,
            line=lines[0][0] if lines else None,
            expected="'OFF' header",
            got=" ".join(lines[0][1])[:40] if lines else "empty file",
        )
    head = lines[0][1]
    if head[0] not in ("OFF", "COFF", "NOFF", "CNOFF"):
        raise FileFormatError("unsupported OFF variant", path=p, line=lines[0][0], got=head[0])
    rest = lines[1:]
    counts_tokens, counts_line = (
        (head[1:], lines[0][0]) if len(head) > 1 else (rest[0][1], rest[0][0]) if rest else ([], lines[0][0])
    )
    if len(head) == 1:
        rest = rest[1:]
    try:
        nv, nf = integer(counts_tokens[0]), integer(counts_tokens[1])
    except (IndexError, ValueError):
        raise FileFormatError("bad OFF counts line", path=p, line=counts_line, expected="nv nf ne") from None
    if nv < 1 or nf < 1:
        raise FileFormatError(
            "OFF mesh is empty", path=p, line=counts_line, expected="nv >= 1 and nf >= 1", got=f"nv={nv}, nf={nf}"
        )
    if len(rest) < nv + nf:
        raise FileFormatError(
            "OFF file is truncated", path=p, expected=f"{nv} vertex and {nf} face lines", got=f"{len(rest)} lines"
        )
    verts = np.empty((nv, 3))
    for k in range(nv):
        i, t = rest[k]
        try:
            verts[k] = [number(x) for x in t[:3]]
        except ValueError:
            raise FileFormatError("vertex has a non-numeric value", path=p, line=i) from None
        if len(t) < 3:
            raise FileFormatError("vertex line needs x y z", path=p, line=i, got=len(t))
        if not np.isfinite(verts[k]).all():
            raise FileFormatError("vertex coordinate is not finite", path=p, line=i)
    tris, origin = [], []
    for k in range(nf):
        i, t = rest[nv + k]
        try:
            cnt = integer(t[0])
            idx = [integer(x) for x in t[1 : 1 + cnt]]
        except ValueError:
            raise FileFormatError("bad face line", path=p, line=i) from None
        if cnt < 3 or len(idx) != cnt:
            raise FileFormatError(
                "face needs at least 3 vertex indices",
                path=p,
                line=i,
                expected=">= 3 indices as declared",
                got=f"{len(idx)} of {cnt}",
            )
        for x in idx:
            if not 0 <= x < nv:
                raise FileFormatError("face index out of range", path=p, line=i, expected=f"0..{nv - 1}", got=x)
        for j in range(1, cnt - 1):
            tris.append((idx[0], idx[j], idx[j + 1]))
            origin.append(k)
    v, f = validate_mesh_arrays(verts, np.asarray(tris, np.int64), path=p, bounded=True)
    return Mesh(vertices=v, faces=f, path=str(p), face_origin=np.asarray(origin, np.int64))
