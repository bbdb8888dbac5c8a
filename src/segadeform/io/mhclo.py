"""MakeHuman ``.mhclo`` garment bindings: each garment vertex bound to three hm08 base-mesh vertices (weights and an
offset; ``../shared/data/MHCLO_FORMAT.md``).  :func:`read_mhclo` parses a file strictly (errors name the file and
line); fitting the binding onto a body is :func:`segadeform.garments.registration.fit_mhclo`.
"""

from __future__ import annotations

import dataclasses
import os
from pathlib import Path

import numpy as np

from ..errors import FileFormatError, file_error
from .numbers import integer, number

__all__ = ["MhcloBinding", "read_mhclo", "MHCLO_SUFFIX"]

MHCLO_SUFFIX = ".mhclo"


@dataclasses.dataclass(frozen=True)
class MhcloBinding:
    """A parsed ``.mhclo``.

    Attributes:
        verts: (N, 3) hm08 vertex indices per garment vertex; weights: (N, 3); offsets: (N, 3) decimetres,
            MakeHuman axes (= ours: +X the character's left, +Y up, +Z front).
        scales: {"x"|"y"|"z": (vertex_a, vertex_b, reference distance in dm)}.
        delete_verts: hm08 vertices the garment hides.
        obj_file: the garment mesh named in the file (relative to it), or None.
    """

    path: Path
    name: str
    verts: np.ndarray
    weights: np.ndarray
    offsets: np.ndarray
    scales: dict
    delete_verts: np.ndarray
    obj_file: str | None
    basemesh: str

    @property
    def n_vertices(self) -> int:
        return int(self.verts.shape[0])

    def obj_path(self) -> Path | None:
        return None if self.obj_file is None else self.path.parent / self.obj_file


def read_mhclo(path: str | os.PathLike) -> MhcloBinding:
    """Parse a MakeHuman ``.mhclo`` file strictly (errors name the file and line)."""
    p = Path(path)
    try:
        text = p.read_text(encoding="utf-8-sig", errors="strict")  # a byte-order mark is dropped
    except FileNotFoundError:
        raise FileFormatError("no such file", path=p) from None
    except UnicodeDecodeError:
        raise FileFormatError("not UTF-8 text", path=p) from None
    except OSError as e:
        raise file_error(e, p) from None
    name, obj_file, basemesh = p.stem, None, "hm08"
    scales: dict = {}
    verts: list[tuple[int, ...]] = []
    weights: list[tuple[float, ...]] = []
    offsets: list[tuple[float, ...]] = []
    lines = []
    deletes: list[int] = []
    section = "header"
    for ln, raw in enumerate(text.splitlines(), 1):
        tok = raw.split()
        if not tok or tok[0].startswith("#"):
            continue
        key = tok[0]
        if section == "verts" and (key[0].isdigit() or key[0] == "-"):
            lines.append(ln)
            if len(tok) == 1:
                verts.append((_int(tok[0], p, ln), 0, 0))
                weights.append((1.0, 0.0, 0.0))
                offsets.append((0.0, 0.0, 0.0))
            elif len(tok) in (6, 9):
                verts.append(tuple(_int(t, p, ln) for t in tok[:3]))
                weights.append(tuple(_float(t, p, ln) for t in tok[3:6]))
                offsets.append(tuple(_float(t, p, ln) for t in tok[6:9]) if len(tok) == 9 else (0.0, 0.0, 0.0))
            else:
                raise FileFormatError(
                    "a binding line needs 1, 6 or 9 numbers",
                    path=p,
                    line=ln,
                    expected="v1 v2 v3 w1 w2 w3 [d1 d2 d3] or v",
                    got=len(tok),
                )
            continue
        if section == "delete" and (key[0].isdigit() or key[0] == "-"):
            i = 0
            while i < len(tok):
                a = _int(tok[i], p, ln)
                if i + 2 < len(tok) and tok[i + 1] == "-":
                    b = _int(tok[i + 2], p, ln)
                    if b < a:
                        raise FileFormatError("delete_verts range runs backwards", path=p, line=ln, got=f"{a} - {b}")
                    if a < 0:
                        raise FileFormatError("negative base-mesh index in delete_verts", path=p, line=ln, got=a)
                    deletes.extend(range(a, b + 1))
                    i += 3
                else:
                    if a < 0:
                        raise FileFormatError("negative base-mesh index in delete_verts", path=p, line=ln, got=a)
                    deletes.append(a)
                    i += 1
            continue
        if key == "verts":
            section = "verts"
        elif key == "delete_verts":
            section = "delete"
        elif key == "name":
            name = raw.split(None, 1)[1].strip() if len(tok) > 1 else name
            section = "header"
        elif key == "obj_file":
            if len(tok) < 2:
                raise FileFormatError("obj_file needs a file name", path=p, line=ln)
            obj_file = raw.split(None, 1)[1].strip()
            if not Path(obj_file).suffix:
                obj_file += ".obj"
            section = "header"
        elif key == "basemesh":
            basemesh = tok[1] if len(tok) > 1 else ""
            section = "header"
        elif key in ("x_scale", "y_scale", "z_scale"):
            if len(tok) != 4:
                raise FileFormatError(
                    f"{key} needs 3 values", path=p, line=ln, expected="vertex vertex reference", got=len(tok) - 1
                )
            ref = _float(tok[3], p, ln)
            if not ref > 0:
                raise FileFormatError(f"{key} reference must be positive", path=p, line=ln, got=ref)
            a, b = _int(tok[1], p, ln), _int(tok[2], p, ln)
            if min(a, b) < 0:  # numpy would count it from the end
                raise FileFormatError(f"negative base-mesh index in {key}", path=p, line=ln, got=min(a, b))
            scales[key[0]] = (a, b, ref)
        else:
            section = "header"  # other keys (uuid, tag, material, z_depth, weights ...) are not needed here
    if basemesh != "hm08":
        raise FileFormatError("only hm08 bindings are supported", path=p, expected="basemesh hm08", got=basemesh)
    if not verts:
        raise FileFormatError("no binding lines (after 'verts 0')", path=p)
    v = np.array(verts, np.int64)
    w = np.array(weights, np.float64)
    d = np.array(offsets, np.float64)
    if v.min() < 0:  # numpy would count it from the end
        k = int(np.argwhere(v < 0)[0, 0])
        raise FileFormatError("negative base-mesh index", path=p, line=lines[k], got=int(v[k].min()))
    bad = np.flatnonzero(np.abs(w.sum(axis=1) - 1.0) > 0.01)
    if bad.size:  # barycentric: every MakeHuman binding sums to 1 (to 1e-5)
        k = int(bad[0])
        raise FileFormatError(
            "binding weights must sum to 1", path=p, line=lines[k], expected="w1 + w2 + w3 = 1", got=f"{w[k].sum():g}"
        )
    return MhcloBinding(
        path=p,
        name=name,
        verts=v,
        weights=w,
        offsets=d,
        scales=scales,
        delete_verts=np.array(sorted(set(deletes)), np.int64),
        obj_file=obj_file,
        basemesh=basemesh,
    )


#: the largest base-mesh index a binding may name (hm08 has 19,158 vertices with its helpers; found by fuzzing:
#: a 30-digit index overflowed numpy's int64, and a delete range of 10^12 would fill memory)
_MAX_INDEX = 10**6


def _int(t, p, ln) -> int:
    try:
        i = integer(t)
    except ValueError:
        raise FileFormatError("expected an integer", path=p, line=ln, got=t[:30]) from None
    if abs(i) > _MAX_INDEX:
        raise FileFormatError("base-mesh index out of range", path=p, line=ln, expected=f"0..{_MAX_INDEX}", got=t[:30])
    return i


def _float(t, p, ln) -> float:
    try:
        v = number(t)
    except ValueError:
        raise FileFormatError("expected a number", path=p, line=ln, got=t[:30]) from None
    if not np.isfinite(v):
        raise FileFormatError("value is not finite", path=p, line=ln, got=t[:30])
    return v
