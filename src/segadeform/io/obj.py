"""Wavefront OBJ, read strictly and written simply.

meshio mis-reads real OBJ exports (facts.md): it raises when the ``vt``/``vn``
counts differ from ``v``, silently mis-reads negative indices, accepts
out-of-range indices and 2-vertex faces.  This reader handles, per the OBJ
spec: ``v x y z [w]`` and ``v x y z r g b`` (vertex colours), ``vt``/``vn``
with any counts, face corners ``v``, ``v/vt``, ``v//vn``, ``v/vt/vn``,
negative (relative) indices, quads and n-gons (fan-triangulated), groups,
objects, materials, smoothing groups, comments, ``\\`` line continuations,
and ignores ``l``/``p`` elements.  **Vertex order and count are kept exactly
as in the file**: unused vertices stay, nothing is merged or split at seams.

Rejected with ``FileFormatError`` naming file and line: out-of-range or zero
indices, faces with fewer than 3 corners, non-numeric or non-finite values,
and files with no vertices or no faces.
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np

from ..bounds import MAX_POSITION
from ..errors import FileFormatError, InputError, file_error
from .atomic import atomic_open
from .mesh import Mesh, validate_mesh_arrays
from .numbers import integer, number

__all__ = [
    "read_obj",
    "write_obj",
    "write_obj_positions",
    "obj_text",
    "obj_logical_lines",
    "obj_objects",
    "obj_line_vertices",
    "BETAS_RECORD",
    "betas_record",
    "recorded_betas",
    "material_libraries",
]

_IGNORED = {
    "vp",
    "l",
    "p",
    "g",
    "o",
    "s",
    "usemtl",
    "mtllib",
    "cstype",
    "deg",
    "bmat",
    "step",
    "curv",
    "curv2",
    "surf",
    "parm",
    "trim",
    "hole",
    "scrv",
    "sp",
    "end",
    "con",
    "mg",
    "bevel",
    "c_interp",
    "d_interp",
    "lod",
    "shadow_obj",
    "trace_obj",
    "ctech",
    "stech",
    "call",
    "csh",
}


def _logical_lines(text: str):
    """Yield ``(line_number, line)`` joining ``\\`` continuations."""
    pending = ""
    start = 0
    for i, raw in enumerate(text.splitlines(), start=1):
        if not pending:
            start = i
        line = raw.rstrip()
        if line.endswith("\\"):
            pending += line[:-1] + " "
            continue
        yield start, pending + line
        pending = ""
    if pending:
        yield start, pending


def obj_text(path: Path) -> str:
    """The text of an OBJ file: UTF-8 (a leading byte-order mark dropped: editors on Windows write one, and it
    would hide the first line), else Latin-1.  ``OSError`` when it cannot be read."""
    data = Path(path).read_bytes()
    if data.startswith(b"\xef\xbb\xbf"):
        data = data[3:]
    try:
        return data.decode("utf-8")
    except UnicodeDecodeError:
        return data.decode("latin-1")


def obj_logical_lines(path) -> list[tuple[int, str]]:
    """``(line number, logical line)`` of an OBJ file (:func:`obj_text`, ``\\`` continuations joined)."""
    return list(_logical_lines(obj_text(path)))


def obj_line_vertices(path) -> set[int]:
    """The (0-based) vertices the OBJ file's ``l`` (line) elements name: the reader keeps triangles alone, while an
    import (Blender's) keeps these vertices as edges.  Indices as the file gives them (negative ones count back from
    the vertices read so far); what is not a whole number is skipped."""
    out: set[int] = set()
    n = 0
    for _, line in obj_logical_lines(path):
        words = line.split()
        if not words:
            continue
        if words[0] == "v":
            n += 1
        elif words[0] == "l":
            for w in words[1:]:
                try:
                    k = integer(w.split("/")[0])
                except ValueError:
                    continue
                out.add(k - 1 if k > 0 else n + k)
    return out


def obj_objects(path) -> list[str]:
    """The names of the OBJ file's objects (``o`` statements) that own faces, in file order: what Blender's OBJ
    import makes separate objects of (faces before the first ``o`` make one more, named ``""``).  The file is read as
    one mesh here, so a point cache of it fits none of them alone."""
    names: list[str] = []
    current, counted = "", False
    for _, line in obj_logical_lines(path):
        words = line.split(None, 1)
        if not words:
            continue
        if words[0] == "o":
            current, counted = (words[1].strip() if len(words) > 1 else ""), False
        elif words[0] == "f" and not counted:
            names.append(current)
            counted = True
    return names


def _resolve(tok: str, count: int, kind: str, path, lineno) -> int:
    try:
        i = integer(tok)
    except ValueError:
        raise FileFormatError(f"bad {kind} index {tok!r}", path=path, line=lineno) from None
    if i > 0:
        if i > count:
            raise FileFormatError(
                f"{kind} index out of range",
                path=path,
                line=lineno,
                expected=f"1..{count} or -{count}..-1" if count else f"a {kind} defined before this line",
                got=i,
            )
        return i - 1
    if i < 0:
        if -i > count:
            raise FileFormatError(
                f"relative {kind} index out of range",
                path=path,
                line=lineno,
                expected=f"-{count}..-1" if count else f"a {kind} defined before this line",
                got=i,
            )
        return count + i
    raise FileFormatError(f"{kind} index 0 is not valid (OBJ indices start at 1)", path=path, line=lineno)


def _cut_short(path, line: int, key: str) -> FileFormatError:
    return FileFormatError(
        f"the file ends in the middle of its last '{key}' line, with no line break: is it cut short? "
        "(a whole file ends with a line break: add one if this one is whole)",
        path=path,
        line=line,
    )


def read_obj(path: str | os.PathLike, *, bounded: bool = True) -> Mesh:
    """Read an OBJ file into a :class:`Mesh` (vertex order kept).  ``bounded``: a vertex beyond 10 km of the origin
    (:data:`segadeform.bounds.MAX_POSITION`) is an error naming its line (False: the frames of an output, which
    ``run --output-units mm`` may write past 10,000 units; their reader checks them in their units).

    Returns:
        Mesh with ``vertices (N, 3)``, ``faces (F, 3)`` (polygons
        fan-triangulated), ``colors (N, 3)`` if every vertex had colours, and
        ``face_origin (F,)`` mapping triangles to file polygons.
    """
    p = Path(path)
    try:
        text = obj_text(p)
    except OSError as e:
        raise file_error(e, p) from None
    if "\x00" in text:
        raise FileFormatError("not a text OBJ file (contains NUL bytes)", path=p)
    # a copy or download that stopped mid-line (a user's trial: an OBJ cut at 90 % ran with a tenth of its faces gone,
    # exit 0).  A last line with no line break is how some exporters end a whole file (pytorch3d's save_obj), so it is
    # refused only when it looks cut: it ends in whitespace or a '/', it is a face with another corner count than
    # the face before it (a quad cut to a triangle) or with corners in mixed forms, or some vertices are in no face;
    # an error on that line says the file may be cut short
    cut_at = None  # the line number of an element line the file ends in, unbroken
    cut_key = ""  # its statement
    if text and not text.endswith(("\n", "\r")):
        last = list(_logical_lines(text))[-1]
        words = last[1].split()
        if words and words[0] in ("v", "vt", "vn", "vp", "f", "l", "p"):
            cut_at, cut_key = last[0], words[0]
            if text.splitlines()[-1][-1:].isspace() or last[1].rstrip().endswith("/"):
                raise _cut_short(p, cut_at, words[0])
    face_sizes: list[int] = []  # the corner counts of the last two faces

    verts: list[list[float]] = []
    colors: list[list[float] | None] = []
    n_vt = n_vn = 0
    tris: list[tuple[int, int, int]] = []
    origin: list[int] = []
    n_poly = 0
    try:
        for lineno, line in _logical_lines(text):
            s = line.strip()
            if not s or s[0] == "#":
                continue
            parts = s.split()
            key = parts[0]
            if key == "v":
                vals = parts[1:]
                if len(vals) not in (3, 4, 6, 7):
                    raise FileFormatError(
                        "vertex line needs x y z, x y z w, or x y z r g b",
                        path=p,
                        line=lineno,
                        expected="3, 4 or 6 numbers",
                        got=f"{len(vals)}",
                    )
                try:
                    nums = [number(x) for x in vals]
                except ValueError:
                    raise FileFormatError(f"vertex has a non-numeric value in {s!r}", path=p, line=lineno) from None
                xyz = nums[:3]
                if len(nums) == 4:  # homogeneous weight
                    w = nums[3]
                    if w == 0 or not np.isfinite(w):
                        raise FileFormatError("vertex weight w must be finite and non-zero", path=p, line=lineno, got=w)
                    xyz = [c / w for c in xyz]
                if not all(np.isfinite(xyz)):
                    raise FileFormatError("vertex coordinate is not finite", path=p, line=lineno, got=vals[:3])
                if bounded and max(abs(c) for c in xyz) > MAX_POSITION:
                    raise FileFormatError(
                        "vertex lies beyond 10 km of the origin (another unit?)",
                        path=p,
                        line=lineno,
                        expected=f"|x| <= {MAX_POSITION:g}",
                        got=vals[:3],
                    )
                verts.append(xyz)
                colors.append(nums[3:6] if len(nums) == 6 else (nums[4:7] if len(nums) == 7 else None))
            elif key == "vt":
                n_vt += 1
            elif key == "vn":
                n_vn += 1
            elif key == "f":
                corners = parts[1:]
                face_sizes = [*face_sizes[-1:], len(corners)]
                if lineno == cut_at and len(face_sizes) == 2 and face_sizes[0] != face_sizes[1]:
                    raise _cut_short(p, cut_at, key)
                # corners in mixed forms (v/vt, v/vt, then v): a number cut off its '/vt' (a user's trial)
                if lineno == cut_at and len({c.count("/") for c in corners}) > 1:
                    raise _cut_short(p, cut_at, key)
                if len(corners) < 3:
                    raise FileFormatError(
                        "face has fewer than 3 vertices", path=p, line=lineno, expected=">= 3", got=len(corners)
                    )
                idx = []
                for c in corners:
                    sub = c.split("/")
                    if len(sub) > 3 or sub[0] == "":
                        raise FileFormatError(
                            f"bad face corner {c!r}", path=p, line=lineno, expected="v, v/vt, v//vn or v/vt/vn"
                        )
                    idx.append(_resolve(sub[0], len(verts), "vertex", p, lineno))
                    if len(sub) > 1 and sub[1] != "":
                        _resolve(sub[1], n_vt, "texture coordinate", p, lineno)
                    if len(sub) > 2 and sub[2] != "":
                        _resolve(sub[2], n_vn, "normal", p, lineno)
                for k in range(1, len(idx) - 1):
                    tris.append((idx[0], idx[k], idx[k + 1]))
                    origin.append(n_poly)
                n_poly += 1
            elif key in _IGNORED or key.startswith("#"):
                continue
            else:
                # Unknown statements are rare vendor extensions; skipping them is
                # what every OBJ importer does, and they cannot affect geometry.
                continue
    except FileFormatError as e:  # on the last line of a file that ends unbroken there: say it may be cut short
        if cut_at is None or e.line != cut_at or "cut short" in e.problem:
            raise
        raise FileFormatError(
            f"{e.problem} (the file ends on this line with no line break: is it cut short?)",
            path=p,
            line=e.line,
            expected=e.expected,
            got=e.got,
        ) from None

    cut = "" if cut_at is None else f" (the file ends on line {cut_at} with no line break: is it cut short?)"
    if not verts:
        raise FileFormatError(f"mesh has no vertices ('v' lines){cut}", path=p)
    if not tris:
        raise FileFormatError(f"mesh has no faces ('f' lines){cut}", path=p)
    if cut_at is not None and cut_key == "f" and np.unique(np.asarray(tris, dtype=np.int64)).size < len(verts):
        # unbroken on a face line with vertices no face uses: the faces that used them were cut off (a user's trial:
        # an OBJ cut in its faces inside a number ran, a third of its triangles gone, exit 0)
        raise FileFormatError(
            f"{len(verts) - np.unique(np.asarray(tris)).size} of its {len(verts)} vertices are in no face and the file "
            f"ends on line {cut_at} with no line break: is it cut short? (a whole file ends with a line break: add one "
            "if this one is whole)",
            path=p,
            line=cut_at,
        )
    v, f = validate_mesh_arrays(
        np.asarray(verts, dtype=np.float64), np.asarray(tris, dtype=np.int64), path=p, bounded=bounded
    )
    col = None
    if all(c is not None for c in colors):
        col = np.asarray(colors, dtype=np.float64)
    return Mesh(vertices=v, faces=f, path=str(p), colors=col, face_origin=np.asarray(origin, dtype=np.int64))


#: the leading OBJ comment that records the body shape a garment was made or fitted for (``garment make``,
#: ``garment fit``): ``# betas: 1.5 -1 0.5``; ``# betas:`` alone, or zeros, is the default shape.  It is read only
#: where the leading comments are segadeform's own (one of them starts with :data:`OWN_COMMENT`).
BETAS_RECORD = "betas:"
OWN_COMMENT = "segadeform garment"
#: the leading comment lines read for the record, at most
_RECORD_LINES = 200


def betas_record(betas) -> str:
    """The comment (without ``#``) recording body shape ``betas``: ``betas: 1.5 -1 0.5``."""
    b = np.asarray(betas if betas is not None else (), np.float64).ravel()
    return " ".join([BETAS_RECORD] + [f"{x:.9g}" for x in b])


def _own_comments(p: Path) -> list[tuple[int, str]] | None:
    """The leading comment lines of OBJ ``p`` (line number, text without ``#``) when they are segadeform's own (one
    starts with :data:`OWN_COMMENT`); None for another file."""
    if p.suffix.lower() != ".obj":
        return None
    comments: list[tuple[int, str]] = []
    try:
        with open(p, encoding="utf-8", errors="replace") as fh:
            for no, line in enumerate(fh, 1):
                s = line.strip().lstrip("\ufeff")  # a byte-order mark before the first line
                if not s:
                    continue
                if not s.startswith("#") or no > _RECORD_LINES:
                    break
                comments.append((no, s.lstrip("#").strip()))
    except OSError as e:
        raise file_error(e, p) from None
    return comments if any(c.startswith(OWN_COMMENT) for _, c in comments) else None


def recorded_fit(path: str | os.PathLike) -> str | None:
    """The record `segadeform garment fit` wrote in OBJ ``path``'s leading comments (``"segadeform garment fit:
    units cm, up z, turn 90, scale 1 ..."``), or None."""
    return next((c for _, c in _own_comments(Path(path)) or [] if c.startswith(f"{OWN_COMMENT} fit:")), None)


def recorded_betas(path: str | os.PathLike) -> tuple[float, ...] | None:
    """The body shape recorded in the leading comments of OBJ ``path`` (:func:`betas_record`, under a comment
    starting ``segadeform garment``): a tuple (``()``: the default shape), or None -- a file that is not an OBJ,
    or an OBJ that records none (a garment from elsewhere).

    Raises:
        FileFormatError: a segadeform record whose values are not finite numbers.
    """
    p = Path(path)
    for no, c in _own_comments(p) or []:
        if c.split()[:1] == [BETAS_RECORD]:
            try:
                b = tuple(number(x) for x in c.split()[1:])
            except ValueError:
                b = (float("nan"),)
            if not np.isfinite(b).all():
                raise FileFormatError("the recorded body shape is not a list of numbers", path=p, line=no, got=c[:60])
            return b
    return None


def recorded_params(path: str | os.PathLike) -> dict | None:
    """The garment parameters recorded by ``garment make`` in the leading comments of OBJ ``path``
    (``# params: length=0.7 flare=0.6 ...``) as ``{name: number}``; None where there is no such record (a garment
    from elsewhere, or fitted).  A value that is not a number is kept as its text."""
    for _, c in _own_comments(Path(path)) or []:
        if c.split()[:1] == ["params:"]:
            out: dict = {}
            for item in c.split()[1:]:
                k, sep, v = item.partition("=")
                if not sep:
                    continue
                try:
                    out[k] = number(v)
                except ValueError:
                    out[k] = v
            return out
    return None


def _format_block(fmt: str, rows: np.ndarray) -> str:
    if rows.size == 0:
        return ""
    return (fmt + "\n") * rows.shape[0] % tuple(rows.ravel())


def write_obj(
    path: str | os.PathLike,
    mesh: Mesh,
    *,
    vertices: np.ndarray | None = None,
    precision: int = 9,
    header: str | None = None,
) -> None:
    """Write ``mesh`` (or its faces with other ``vertices``) as OBJ, atomically.

    Vertices are written in order, faces as triangles with 1-based indices.

    Shapes:
        vertices: (N, 3), defaults to ``mesh.vertices``
    """
    v = mesh.vertices if vertices is None else np.asarray(vertices)
    v, f = validate_mesh_arrays(v, mesh.faces, allow_no_faces=True)
    with atomic_open(path, "w", encoding="utf-8", newline="\n") as fh:
        fh.write(f"# segadeform OBJ: {v.shape[0]} vertices, {f.shape[0]} triangles\n")
        if header:
            for line in header.splitlines():
                fh.write(f"# {line}\n")
        fh.write(_format_block(f"v %.{precision}g %.{precision}g %.{precision}g", v))
        fh.write(_format_block("f %d %d %d", f + 1))


def write_obj_positions(path, faces: np.ndarray, vertices: np.ndarray, **kw) -> None:
    """Write one frame of a sequence: ``vertices (N, 3)`` with ``faces (F, 3)``."""
    write_obj(path, Mesh(vertices=np.asarray(vertices, np.float64), faces=faces), **kw)


def _library_at(name: str, folder: Path) -> Path | None:
    """The material library ``name`` (an ``mtllib`` name: relative to the OBJ's folder, or absolute) as found from
    ``folder``; None when no file is there."""
    p = Path(name.replace("\\", "/"))
    p = p if p.is_absolute() else folder / p
    return p if p.is_file() else None


def material_libraries(src: str | os.PathLike, dst: str | os.PathLike) -> dict[str, str | None]:
    """What a copy of OBJ ``src`` written at ``dst`` names for each material library ``src``'s ``mtllib`` lines name:
    the name itself when it is found from ``dst``'s folder, a path from there to the file ``src`` names when only
    that is found (relative, with ``/``), or None when neither is (the ``mtllib`` is left out: a ``garment fit`` into
    another folder kept ``mtllib garment.mtl`` with no such file beside it, and Blender's OBJ import logs an error on
    each import of a file naming a missing library).  A name with spaces is one name when the whole of it is found.

    Returns:
        ``{name in src: name to write, or None}``, in the order named
    """
    src, dst = Path(src), Path(dst)
    out: dict[str, str | None] = {}
    try:
        lines = obj_logical_lines(src)
    except OSError as e:
        raise file_error(e, src) from None
    for _, ln in lines:
        words = ln.split()
        if words[:1] != ["mtllib"] or len(words) < 2:
            continue
        whole = ln.split(maxsplit=1)[1].strip()
        found = _library_at(whole, dst.parent) or _library_at(whole, src.parent)
        for name in [whole] if found is not None or len(words) == 2 else words[1:]:
            if name in out:
                continue
            if _library_at(name, dst.parent) is not None:
                out[name] = name
            elif (at := _library_at(name, src.parent)) is not None:
                try:
                    out[name] = Path(os.path.relpath(at.resolve(), dst.parent.resolve())).as_posix()
                except ValueError:  # another drive (Windows): no relative path
                    out[name] = at.resolve().as_posix()
            else:
                out[name] = None
    return out


def _mtllib_line(ln: str, libraries: dict[str, str | None]) -> str | None:
    """An ``mtllib`` line of the source as the copy writes it (:func:`material_libraries`); None: left out."""
    whole = ln.split(maxsplit=1)[1].strip() if len(ln.split()) > 1 else ""
    names = [whole] if whole in libraries else ln.split()[1:]
    kept = [w for w in (libraries.get(n, n) for n in names) if w is not None]
    return "mtllib " + " ".join(kept) if kept else None


def rewrite_obj_vertices(
    src: str | os.PathLike,
    vertices: np.ndarray,
    dst: str | os.PathLike,
    *,
    header: tuple[str, ...] = (),
    weld: np.ndarray | None = None,
) -> Path:
    """Copy an OBJ file with its ``v`` lines replaced by ``vertices`` (same order) and its ``vn`` lines
    recomputed for them (:func:`corner_normals`), keeping faces (quads and polygons as they are), UVs, groups,
    materials and every other line; written atomically.  ``header``: comment lines written first; with them, the
    source's own body-shape record and ``segadeform garment fit`` lines (a garment fitted before) are dropped.  A
    material library (``mtllib``) is named as it is found from ``dst``'s folder, or left out when it is not there
    (:func:`material_libraries`).  ``weld``: for each vertex, the vertex it is merged onto (itself, or a lower one
    that is kept: :func:`segadeform.geometry.mesh_ops.coincident_map`); only the kept vertices' ``v`` lines are
    written, and every face, line and point names the kept vertex (as an absolute index); texture coordinates and
    normals stay per corner, so a seam's UVs are kept.

    Shapes:
        vertices: (N, 3), N = the file's ``v`` lines; weld: (N,)
    """
    src, dst = Path(src), Path(dst)
    v = np.asarray(vertices, np.float64)
    try:
        lines = list(obj_logical_lines(src))
    except OSError as e:
        raise file_error(e, src) from None
    n = sum(1 for _, ln in lines if ln.split()[:1] == ["v"])
    if v.ndim != 2 or v.shape[1:] != (3,) or n != len(v):
        raise InputError("vertex count differs from the OBJ's", path=src, expected=n, got=v.shape)
    if not np.isfinite(v).all():
        raise InputError("fitted vertices are not finite", path=src)
    target = written = None
    if weld is not None:
        w = np.asarray(weld)
        ok = w.shape == (n,) and np.issubdtype(w.dtype, np.integer)
        if ok and n:
            w = w.astype(np.int64)
            ok = bool((w >= 0).all() and (w < n).all() and (w[w] == w).all() and (w <= np.arange(n)).all())
        if not ok:
            raise InputError(
                "weld must map each vertex onto itself or a lower vertex kept", path=src, expected=(n,), got=w.shape
            )
        written = w == np.arange(n)
        target = (np.cumsum(written) - 1)[w]  # each vertex's index among those written
    normals = corner_normals(lines, v, path=src)
    libraries = material_libraries(src, dst)
    it, k, seen = iter(v), 0, 0
    superseded = (BETAS_RECORD, OWN_COMMENT + " fit:")
    with atomic_open(dst, "w", encoding="utf-8", newline="\n") as fh:
        for line in header:
            fh.write(f"# {line}\n")
        for no, ln in lines:
            key = ln.split()[:1]
            if header and ln.lstrip().startswith("#") and ln.lstrip().lstrip("#").strip().startswith(superseded):
                continue
            if key == ["v"]:
                x = next(it)
                seen += 1
                if written is not None and not written[seen - 1]:
                    continue
                extra = ln.split()[4:]  # vertex colours stay
                fh.write(f"v {x[0]:.6f} {x[1]:.6f} {x[2]:.6f}" + (" " + " ".join(extra) if extra else "") + "\n")
            elif target is not None and key and key[0] in ("f", "l", "p"):
                fh.write(_renumbered(ln, target, seen, src, no) + "\n")
            elif key == ["vn"]:
                nx = normals[k]
                k += 1
                fh.write(f"vn {nx[0]:.6f} {nx[1]:.6f} {nx[2]:.6f}\n")
            elif key == ["mtllib"]:
                library = _mtllib_line(ln, libraries)
                if library is not None:
                    fh.write(library + "\n")
            else:
                fh.write(ln + "\n")
    return dst


def _renumbered(ln: str, target: np.ndarray, seen: int, path, line: int) -> str:
    """A face, line or point element with each corner's vertex index replaced by ``target``'s for it (1-based,
    absolute), the texture and normal indices as they were; ``seen``: the ``v`` lines before it (what a negative
    index counts back from)."""
    words = ln.split()
    out = [words[0]]
    for c in words[1:]:
        sub = c.split("/")
        sub[0] = str(int(target[_obj_index(sub[0], seen, path, line)]) + 1)
        out.append("/".join(sub))
    return " ".join(out)


def corner_normals(lines, vertices: np.ndarray, *, path=None) -> np.ndarray:
    """New ``vn`` vectors for an OBJ whose vertices moved to ``vertices``: normal ``k`` is the unit sum of the
    (Newell, area-weighted) normals of the polygons with a corner that names ``vn`` ``k``, so shared normals stay
    smooth and a normal of one flat face stays flat.  A ``vn`` no face names keeps its value.

    Args:
        lines: ``(line number, text)`` of the file (:func:`obj_logical_lines`).
    Shapes:
        vertices: (N, 3) -> (K, 3), K = the file's ``vn`` lines
    """
    old, acc = [], []
    n_v = 0
    for ln_no, ln in lines:
        t = ln.split()
        if not t:
            continue
        if t[0] == "v":
            n_v += 1
        elif t[0] == "vn":
            try:
                old.append([number(x) for x in t[1:4]])
            except ValueError:
                raise FileFormatError("normal has a non-numeric value", path=path, line=ln_no) from None
            if len(old[-1]) != 3:
                raise FileFormatError("normal line needs x y z", path=path, line=ln_no, got=len(old[-1]))
            acc.append(np.zeros(3))
        elif t[0] == "f" and len(t) >= 4:
            idx, nrm = [], []
            for c in t[1:]:
                sub = c.split("/")
                idx.append(_obj_index(sub[0], n_v, path, ln_no))
                nrm.append(_obj_index(sub[2], len(old), path, ln_no) if len(sub) > 2 and sub[2] else None)
            if all(x is None for x in nrm):
                continue
            q = vertices[idx]
            fn = np.cross(q, np.roll(q, -1, axis=0)).sum(axis=0)  # Newell: 2 x area x unit normal
            for x in nrm:
                if x is not None:
                    acc[x] += fn
    out = np.asarray(old, np.float64).reshape(-1, 3)
    for k, a in enumerate(acc):
        length = float(np.linalg.norm(a))
        if length > 0:
            out[k] = a / length
    return out


def _obj_index(tok: str, count: int, path, line: int) -> int:
    try:
        i = integer(tok)
    except ValueError:
        raise FileFormatError(f"bad index {tok!r}", path=path, line=line) from None
    j = i - 1 if i > 0 else count + i
    if i == 0 or not 0 <= j < count:
        raise FileFormatError("index out of range", path=path, line=line, expected=f"1..{count} or -{count}..-1", got=i)
    return j
