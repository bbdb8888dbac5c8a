"""Garments made for another body, brought onto ours: MakeHuman ``.mhclo`` bindings, another body's mesh,
and plain unit/axis fixes.  Vertex order and count are always kept.

* :func:`read_mhclo` / :func:`fit_mhclo`: a MakeHuman garment binds each vertex
  to three hm08 base-mesh vertices (weights, offset; ``../shared/data/MHCLO_FORMAT.md``).
  The default body *is* the hm08 mesh (T-posed, metres), and its file says
  where every hm08 vertex is for any shape (:mod:`segadeform.body.makehuman`),
  so the garment is fitted in MakeHuman's A-pose at the requested ``betas``
  exactly as MakeHuman does it (``p = sum w_k B[v_k] + diag(s) d``, with the
  per-axis scales measured on the shaped body), then carried to the body's
  T-pose rest by inverse linear blend skinning with weights taken from the
  three bound vertices.
* :func:`fit_to_body_mesh`: a garment modelled on another body (any topology,
  pose, units): the body is registered to that mesh (scale and placement,
  shape ``betas`` and joint rotations, then a smooth surface correction), each
  garment vertex is attached to the registered surface (closest point and
  offset in the local surface frame), and carried onto the body's rest.
* :func:`fix_units_and_axes`: a plain similarity (units, up axis, scale).
"""

from __future__ import annotations

import dataclasses
import os
from pathlib import Path
from typing import Optional

import numpy as np

from ..bounds import BETA_LIMIT
from ..errors import FileFormatError, InputError, file_error

__all__ = ["MhcloBinding", "read_mhclo", "fit_mhclo", "fix_units_and_axes", "UNIT_SCALES", "rewrite_obj_vertices",
           "corner_normals",
           "FitReport", "placement_report", "push_off_body", "fit_to_body_mesh", "BodyFit", "check_placement",
           "PlacementError"]

UNIT_SCALES = {"m": 1.0, "dm": 0.1, "cm": 0.01, "mm": 0.001, "inch": 0.0254, "ft": 0.3048}
_MH_TO_M = 0.1  # MakeHuman mesh units are decimetres


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
    obj_file: Optional[str]
    basemesh: str

    @property
    def n_vertices(self) -> int:
        return int(self.verts.shape[0])

    def obj_path(self) -> Optional[Path]:
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
    verts, weights, offsets, lines = [], [], [], []
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
                raise FileFormatError("a binding line needs 1, 6 or 9 numbers", path=p, line=ln,
                                      expected="v1 v2 v3 w1 w2 w3 [d1 d2 d3] or v", got=len(tok))
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
                raise FileFormatError(f"{key} needs 3 values", path=p, line=ln, expected="vertex vertex reference",
                                      got=len(tok) - 1)
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
        raise FileFormatError("binding weights must sum to 1", path=p, line=lines[k], expected="w1 + w2 + w3 = 1",
                              got=f"{w[k].sum():g}")
    return MhcloBinding(path=p, name=name, verts=v, weights=w, offsets=d, scales=scales,
                        delete_verts=np.array(sorted(set(deletes)), np.int64), obj_file=obj_file, basemesh=basemesh)


#: the largest base-mesh index a binding may name (hm08 has 19,158 vertices with its helpers; found by fuzzing:
#: a 30-digit index overflowed numpy's int64, and a delete range of 10^12 would fill memory)
_MAX_INDEX = 10 ** 6


def _int(t, p, ln) -> int:
    try:
        i = int(t)
    except ValueError:
        raise FileFormatError("expected an integer", path=p, line=ln, got=t[:30]) from None
    if abs(i) > _MAX_INDEX:
        raise FileFormatError("base-mesh index out of range", path=p, line=ln, expected=f"0..{_MAX_INDEX}",
                              got=t[:30])
    return i


def _float(t, p, ln) -> float:
    try:
        v = float(t)
    except ValueError:
        raise FileFormatError("expected a number", path=p, line=ln, got=t[:30]) from None
    if not np.isfinite(v):
        raise FileFormatError("value is not finite", path=p, line=ln, got=t[:30])
    return v


def fit_mhclo(binding: MhcloBinding, body, betas=None, *, return_apose: bool = False):
    """The garment's vertices on ``body`` at shape ``betas``, in the body's T-pose rest (metres, +Y up).

    With ``return_apose`` also the fit in MakeHuman's A-pose (the body posed by ``rest_pose_a``), before
    it is carried to the T-pose: the shape the garment was designed in, which the cloth simulator uses
    as the rest shape (``simulate(..., cloth_rest=, start_pose=)``).

    Shapes:
        -> (N, 3), the ``.mhclo``'s (= its OBJ's) vertex order [, (N, 3)]
    """
    from ..body.makehuman import makehuman_vertices, makehuman_weights

    mh = getattr(body, "makehuman", None)
    if mh is None:
        raise InputError("this body has no MakeHuman binding, so .mhclo garments cannot be fitted to it",
                         expected="the default body, or one baked with `segadeform body bake`")
    n_hm = len(mh["hm08_index"]) + len(mh["extra_index"])
    idx = binding.verts
    used = np.concatenate([idx.ravel(), np.array([a for s in binding.scales.values() for a in s[:2]], np.int64)])
    if used.max() >= n_hm:
        raise FileFormatError("binding names a base-mesh vertex the body does not have", path=binding.path,
                              expected=f"indices < {n_hm}", got=int(used.max()))
    H = makehuman_vertices(body, mh, betas)  # (19158, 3), A-pose, metres
    s = np.ones(3)
    for ax, (a, b, ref) in binding.scales.items():
        k = "xyz".index(ax)
        s[k] = abs(H[a, k] - H[b, k]) / (ref * _MH_TO_M)
    p_a = np.einsum("nk,nkc->nc", binding.weights, H[idx]) + binding.offsets * _MH_TO_M * s
    W = makehuman_weights(body, mh)  # (19158, S)
    wg = np.einsum("nk,nks->ns", binding.weights, W[idx])
    wg = np.clip(wg, 0.0, None)
    wg /= np.maximum(wg.sum(axis=1, keepdims=True), 1e-12)
    pose_a = mh["rest_pose_a"].reshape(1, 72)
    A = body.forward(pose_a, betas).transforms[0]  # (S, 4, 4): T-pose rest -> A-pose
    M = np.einsum("ns,sij->nij", wg, A)
    ph = np.concatenate([p_a, np.ones((len(p_a), 1))], axis=1)
    p_t = np.linalg.solve(M, ph[..., None])[..., 0][:, :3]
    return (p_t, p_a) if return_apose else p_t


def fix_units_and_axes(vertices, *, units: str | float | None = None, up: str = "y", scale: float = 1.0,
                       offset=None) -> np.ndarray:
    """A plain similarity: file units to metres, the file's up axis to +Y, an extra scale, then ``offset``
    (metres, after the rest).

    ``up``: ``"y"`` (no change), ``"z"`` (Blender / 3ds Max: (x, y, z) -> (x, z, -y)), ``"-z"``, ``"x"``.

    Shapes:
        vertices: (N, 3) -> (N, 3)
    """
    v = np.asarray(vertices, np.float64)
    if v.ndim != 2 or v.shape[1] != 3:
        raise InputError("vertices must be (N, 3)", got=v.shape)
    if units is None:
        f = 1.0
    elif isinstance(units, str):
        if units not in UNIT_SCALES:
            raise InputError("unknown units", expected=", ".join(UNIT_SCALES), got=units)
        f = UNIT_SCALES[units]
    else:
        f = float(units)
    f *= float(scale)
    if not (np.isfinite(f) and f > 0):
        raise InputError("scale must be positive", got=f)
    rot = {"y": np.eye(3), "z": np.array([[1.0, 0, 0], [0, 0, 1.0], [0, -1.0, 0]]),
           "-z": np.array([[1.0, 0, 0], [0, 0, -1.0], [0, 1.0, 0]]),
           "x": np.array([[0, 1.0, 0], [-1.0, 0, 0], [0, 0, 1.0]])}.get(up)
    if rot is None:
        raise InputError("unknown up axis", expected="y, z, -z or x", got=up)
    out = (v @ rot.T) * f
    if offset is not None:
        o = np.asarray(offset, np.float64).reshape(3)
        if not np.isfinite(o).all():
            raise InputError("offset must be finite", got=o)
        out = out + o
    return out


def rewrite_obj_vertices(src: str | os.PathLike, vertices: np.ndarray, dst: str | os.PathLike) -> Path:
    """Copy an OBJ file with its ``v`` lines replaced by ``vertices`` (same order) and its ``vn`` lines
    recomputed for them (:func:`corner_normals`), keeping faces (quads and polygons as they are), UVs, groups,
    materials and every other line; written atomically.

    Shapes:
        vertices: (N, 3), N = the file's ``v`` lines
    """
    from ..io.atomic import atomic_open
    from ..io.obj import obj_logical_lines

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
    normals = corner_normals(lines, v, path=src)
    it, k = iter(v), 0
    with atomic_open(dst, "w", encoding="utf-8", newline="\n") as fh:
        for _, ln in lines:
            key = ln.split()[:1]
            if key == ["v"]:
                x = next(it)
                extra = ln.split()[4:]  # vertex colours stay
                fh.write(f"v {x[0]:.6f} {x[1]:.6f} {x[2]:.6f}" + (" " + " ".join(extra) if extra else "") + "\n")
            elif key == ["vn"]:
                nx = normals[k]
                k += 1
                fh.write(f"vn {nx[0]:.6f} {nx[1]:.6f} {nx[2]:.6f}\n")
            else:
                fh.write(ln + "\n")
    return dst


def corner_normals(lines, vertices: np.ndarray, *, path=None) -> np.ndarray:
    """New ``vn`` vectors for an OBJ whose vertices moved to ``vertices``: normal ``k`` is the unit sum of the
    (Newell, area-weighted) normals of the polygons with a corner that names ``vn`` ``k``, so shared normals stay
    smooth and a normal of one flat face stays flat.  A ``vn`` no face names keeps its value.

    Args:
        lines: ``(line number, text)`` of the file (:func:`segadeform.io.obj.obj_logical_lines`).
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
                old.append([float(x) for x in t[1:4]])
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
        i = int(tok)
    except ValueError:
        raise FileFormatError(f"bad index {tok!r}", path=path, line=line) from None
    j = i - 1 if i > 0 else count + i
    if i == 0 or not 0 <= j < count:
        raise FileFormatError("index out of range", path=path, line=line, expected=f"1..{count} or -{count}..-1",
                              got=i)
    return j


@dataclasses.dataclass(frozen=True)
class FitReport:
    """How a garment sits on a body: distances from the body surface (m) and the share inside it."""

    median_distance: float
    p90_distance: float
    inside_fraction: float
    deep_inside_fraction: float  # more than 1 cm inside
    garment_height: float
    body_height: float

    def line(self) -> str:
        return (f"median distance to the body {100 * self.median_distance:.1f} cm, 90th percentile "
                f"{100 * self.p90_distance:.1f} cm, {100 * self.inside_fraction:.1f} % of vertices inside "
                f"({100 * self.deep_inside_fraction:.1f} % deeper than 1 cm)")


def placement_report(vertices, body_vertices, body_faces) -> FitReport:
    """Distances of garment ``vertices (N, 3)`` from a (rest) body surface, and the share inside."""
    from ..body.collision import BodyProxy

    v = np.asarray(vertices, np.float64)
    q = BodyProxy(body_vertices, body_faces).query(v)
    d = q.signed_distance
    ad = np.abs(d)
    bv = np.asarray(body_vertices)
    return FitReport(median_distance=float(np.median(ad)), p90_distance=float(np.percentile(ad, 90)),
                     inside_fraction=float((d < 0).mean()), deep_inside_fraction=float((d < -0.01).mean()),
                     garment_height=float(np.ptp(v[:, 1])), body_height=float(np.ptp(bv[:, 1])))


def push_off_body(vertices, body_vertices, body_faces, margin: float) -> tuple[np.ndarray, int]:
    """Move vertices inside the (rest) body, or closer than ``margin`` (m), out along its normal.

    Shapes:
        vertices: (N, 3) -> (N, 3), and the number moved
    """
    from ..body.collision import BodyProxy, push_out

    if not (np.isfinite(margin) and 0 <= margin < 0.1):
        raise InputError("margin must be in [0, 0.1) metres", got=margin)
    return push_out(np.asarray(vertices, np.float64), BodyProxy(body_vertices, body_faces), float(margin))


class PlacementError(InputError):
    """A garment does not sit on the body it is to be animated on (units, axes, another body or pose)."""


def _stats(v, proxy, top, floor):
    d = proxy.query(v).signed_distance
    return {"p20": float(np.percentile(np.abs(d), 20)), "median": float(np.median(np.abs(d))),
            "deep": float((d < -0.01).mean()), "outside_height": float(((v[:, 1] > top + 0.02) |
                                                                         (v[:, 1] < floor - 0.02)).mean())}


def _fits(st) -> bool:
    return st["p20"] <= 0.05 and st["deep"] <= 0.05 and st["outside_height"] <= 0.02


def check_placement(vertices, body_vertices, body_faces, *, path=None, max_points: int = 4000,
                    template_vertices=None, betas=()) -> dict:
    """Refuse a garment that does not sit on the (rest) body, naming the likely cause and the fix.

    A garment sits on the body when the closest fifth of its vertices are within 5 cm of the skin, at
    most 5 % are more than 1 cm inside the body, and at most 2 % lie above the head or below the feet.
    Otherwise the garment is tried in other units (dm, cm, mm, inch), with other up axes (z, -z) and moved
    up or down (another body's origin, e.g. SMPL's pelvis at y = 0); the first of those that fits is named
    in the error with its ``segadeform garment fit`` command, else the garment was made for another body
    or pose (``--mhclo`` or ``--from-body``).  With ``template_vertices`` (the body at betas 0) and ``betas`` (the
    shape ``body_vertices`` has), a garment that sits on the default shape is named as made for it: it needs
    making (or fitting) again for ``betas``, not another origin or units.

    Returns the statistics (``p20``, ``median`` distance in m, ``deep`` and ``outside_height`` fractions).

    Raises:
        PlacementError
    """
    from ..body.collision import BodyProxy

    v = np.asarray(vertices, np.float64)
    if len(v) > max_points:
        v = v[np.linspace(0, len(v) - 1, max_points).astype(np.int64)]
    bv = np.asarray(body_vertices, np.float64)
    proxy = BodyProxy(bv, body_faces)
    top, floor = float(bv[:, 1].max()), float(bv[:, 1].min())
    st = _stats(v, proxy, top, floor)
    if _fits(st):
        return st
    what = (f"median distance to the body {100 * st['median']:.1f} cm (closest fifth beyond "
            f"{100 * st['p20']:.1f} cm), {100 * st['deep']:.1f} % of vertices more than 1 cm inside it, "
            f"{100 * st['outside_height']:.1f} % above the head or below the feet")
    g = path if path is not None else "GARMENT"
    b = np.asarray(betas if betas is not None else (), np.float64).ravel()
    if template_vertices is not None and b.size and np.abs(b).max() > 0:
        tv = np.asarray(template_vertices, np.float64)
        if _fits(_stats(v, BodyProxy(tv, body_faces), float(tv[:, 1].max()), float(tv[:, 1].min()))):
            shape = ",".join(f"{x:g}" for x in b)
            raise PlacementError(f"the garment was made for the default body shape (betas 0), not for betas {shape} "
                                 f"({what})", path=path,
                                 expected=f"a garment made for betas {shape}: `segadeform garment make KIND --betas "
                                          f"{shape}`, `segadeform garment fit G.mhclo --betas {shape}`, or --force")
    for units in (None, "dm", "cm", "mm", "inch"):
        for up in ("y", "z", "-z"):
            if units is None and up == "y":
                continue
            w = fix_units_and_axes(v, units=units, up=up)
            if _fits(_stats(w, proxy, top, floor)):
                opts = (f" --units {units}" if units else "") + (f" --up {up}" if up != "y" else "")
                read = " and ".join(x for x in ((f"in {units}" if units else ""),
                                                (f"with +{up.lstrip('-')} up" if up != "y" else "")) if x)
                raise PlacementError(f"the garment does not sit on the body ({what}); it does once read {read}",
                                     path=path, expected=f"metres, +Y up: run `segadeform garment fit {g} -o FIXED.obj"
                                     f"{opts}`, or pass --force")
    size = np.ptp(v, axis=0)
    if size.max() < 2.0 * (top - floor):  # a plausible size: try moving it
        for dy in np.arange(-1.5, 1.51, 0.05):
            w = v + np.array([0.0, dy, 0.0])
            if abs(dy) >= 0.25 and _fits(_stats(w, proxy, top, floor)):  # an origin, not a shape, is off
                raise PlacementError(f"the garment does not sit on the body ({what}); it does {abs(dy):.2f} m "
                                     f"{'higher' if dy > 0 else 'lower'}: it was placed for another body's "
                                     "origin (SMPL-fitted garments sit around SMPL's pelvis at y = 0)", path=path,
                                     expected=f"a garment on this body: run `segadeform garment fit {g} -o FIXED.obj "
                                              f"--offset 0,{dy:.2f},0` or `--from-body THEIR_BODY.obj`, or pass --force")
    raise PlacementError(f"the garment does not sit on the body ({what}); it was made for another body, pose or "
                         "body shape (betas)",
                         path=path, expected=f"a garment on this body: run `segadeform garment fit {g} -o FIXED.obj "
                                             "--from-body THEIR_BODY.obj` (MakeHuman clothes: --mhclo FILE), "
                                             "or pass --force")


@dataclasses.dataclass(frozen=True)
class BodyFit:
    """The result of :func:`fit_to_body_mesh`.

    Attributes:
        vertices: (N, 3) the garment on the target body's rest (T-pose, metres).
        body_error: mean distance (m) from the source body's points to the registered body surface.
        scale, trans: the similarity placing the body on the source; pose: (72,) its fitted pose;
        betas: its fitted shape.
    """

    vertices: np.ndarray
    body_error: float
    scale: float
    trans: np.ndarray
    pose: np.ndarray
    betas: np.ndarray


def _local_frames(v: np.ndarray, faces: np.ndarray, face_idx: np.ndarray):
    """Per-face orthonormal frames (t1, t2, n), each (M, 3), of faces ``face_idx``."""
    tri = v[faces[face_idx]]
    t1 = tri[:, 1] - tri[:, 0]
    n = np.cross(t1, tri[:, 2] - tri[:, 0])
    t1 /= np.maximum(np.linalg.norm(t1, axis=1, keepdims=True), 1e-300)
    n /= np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-300)
    return t1, np.cross(n, t1), n


def fit_to_body_mesh(garment_vertices, source_vertices, source_faces, body, betas=None, *,
                     samples: int = 1500, rounds: int = 8, seed: int = 0,
                     scale: Optional[float] = None) -> BodyFit:
    """Carry a garment modelled on another body mesh (any topology and pose, +Y up, metres) onto ``body``.

    1. **register** the body to the source mesh: scale (``None``: free, from the height ratio; a number
       fixes it), translation, shape and joint rotations by iterative closest points in both
       directions (body samples -> source, source samples -> body), with priors pulling pose and shape
       to zero; two rounds from each of the T-pose, MakeHuman's A-pose (when the body file has it) and
       arms down, then the best one to the end;
    2. **correct the surface**: every registered body vertex within 3 cm of the source moves onto it,
       the displacement smoothed over the mesh;
    3. **attach** each garment vertex to the closest point of that surface: triangle, barycentric
       weights and the offset in the triangle's own frame;
    4. **carry** it to the body's rest at ``betas``: the same triangle point and local offset.

    Shapes:
        garment_vertices: (N, 3); source_vertices: (S, 3); source_faces: (F, 3) -> BodyFit.vertices (N, 3)
    """
    from scipy.optimize import least_squares
    from scipy.spatial import cKDTree

    from ..body.collision import BodyProxy, closest_point_on_triangles
    from ..body.kinematics import forward_kinematics, poses_to_rotmats, relative_transforms
    from ..body.skinning import linear_blend_skinning
    from ..geometry.mesh_ops import adjacency

    g = np.asarray(garment_vertices, np.float64)
    sv = np.asarray(source_vertices, np.float64)
    sf = np.asarray(source_faces, np.int64)
    if g.ndim != 2 or g.shape[1] != 3 or sv.ndim != 2 or sv.shape[1] != 3:
        raise InputError("garment and source body must be (N, 3) vertex arrays", got=(g.shape, sv.shape))
    if not (np.isfinite(g).all() and np.isfinite(sv).all()):
        raise InputError("garment or source body contains NaN or inf")
    rng = np.random.default_rng(seed)
    nb = body.n_betas
    bidx = rng.choice(body.n_vertices, size=min(samples, body.n_vertices), replace=False)
    sidx = rng.choice(len(sv), size=min(samples, len(sv)), replace=False)
    s_pts = sv[sidx]
    s_tree = cKDTree(sv)
    joints_free = [0, 1, 2, 3, 4, 5, 6, 9, 12, 13, 14, 15, 16, 17, 18, 19, 20, 21]
    W = body.weights[bidx]
    n_th = 3 * len(joints_free)
    v0 = body.shaped_vertices()[0]
    height_s, height_b = float(np.ptp(sv[:, 1])), float(np.ptp(v0[:, 1]))
    if not height_s > 0:
        raise InputError("the source body has no height (is it flat, or not +Y up?)", got=height_s)

    def unpack(x):
        th = np.zeros(72)
        th.reshape(24, 3)[joints_free] = x[4 + nb:].reshape(-1, 3)
        return float(np.exp(x[0])), x[1:4], x[4:4 + nb], th

    def body_points(x):
        sc, t, beta, th = unpack(x)
        rest = body.v_template[bidx] + np.einsum("vcb,b->vc", body.shapedirs[bidx], beta)
        J = body.rest_joints(beta)[0]
        g4, _ = forward_kinematics(poses_to_rotmats(th[None], 24), J, body.parents)
        return linear_blend_skinning(rest, W, relative_transforms(g4, J))[0] * sc + t

    def fit_from(init_pose: np.ndarray, n_rounds: int, x=None):
        if x is None:
            x = np.zeros(4 + nb + n_th)
            x[0] = np.log(height_s / height_b) if scale is None else np.log(scale)
            x[4 + nb:] = init_pose.reshape(24, 3)[joints_free].ravel()
            p = body_points(x)
            x[1:4] = [sv[:, 0].mean() - p[:, 0].mean(), sv[:, 1].min() - p[:, 1].min(),
                      sv[:, 2].mean() - p[:, 2].mean()]
        lo = np.full_like(x, -np.inf)
        hi = np.full_like(x, np.inf)
        lo[4:4 + nb], hi[4:4 + nb] = -BETA_LIMIT, BETA_LIMIT  # the shape space (segadeform.bounds)
        if scale is not None:  # a fixed scale: bounds pin it
            lo[0], hi[0] = np.log(scale) - 1e-9, np.log(scale) + 1e-9
            x[0] = np.log(scale)
        for _ in range(n_rounds):
            p = body_points(x)
            q = sv[s_tree.query(p)[1]]  # body sample -> nearest source vertex
            near_b = cKDTree(p).query(s_pts)[1]  # source sample -> nearest body sample

            def res(xx):
                pp = body_points(xx)
                return np.concatenate([(pp - q).ravel(), (pp[near_b] - s_pts).ravel(),
                                       0.01 * xx[4:4 + nb], 0.02 * xx[4 + nb:]])

            x = least_squares(res, x, max_nfev=20, method="trf", x_scale="jac", bounds=(lo, hi)).x
        p = body_points(x)
        return x, 0.5 * (s_tree.query(p)[0].mean() + cKDTree(p).query(s_pts)[0].mean())

    starts = [np.zeros(72)]
    mh = getattr(body, "makehuman", None)
    if mh is not None:
        starts.append(np.asarray(mh["rest_pose_a"], np.float64))
    down = np.zeros((24, 3))
    down[16] = [0, 0, -1.2]
    down[17] = [0, 0, 1.2]
    starts.append(down.ravel())
    trials = [fit_from(s0, 2) for s0 in starts]  # a short fit from each start, then the best one to the end
    x, _ = min(trials, key=lambda r: r[1])
    x, _ = fit_from(None, rounds, x)
    scale_f, t, beta, th = unpack(x)
    B1 = body.forward(th[None], beta).vertices[0] * scale_f + t
    # surface correction: registered vertices near the source move onto it, smoothed
    sp_proxy = BodyProxy(sv, sf) if len(sf) else None
    if sp_proxy is not None:
        c = sp_proxy.query(B1).closest
    else:
        c = sv[s_tree.query(B1)[1]]
    d = c - B1
    d[np.linalg.norm(d, axis=1) > 0.03] = 0.0
    A = adjacency(body.faces, body.n_vertices)
    deg = np.asarray(A.sum(axis=1)).ravel()
    for _ in range(10):
        d = 0.5 * d + 0.5 * (A @ d) / np.maximum(deg, 1)[:, None]
    B2 = B1 + d
    body_error = float(BodyProxy(B2, body.faces).query(s_pts).signed_distance.__abs__().mean())
    # attach the garment to B2 and carry it to the rest body
    q = BodyProxy(B2, body.faces).query(g)
    tri = B2[body.faces[q.face]]
    _, bary = closest_point_on_triangles(g, tri[:, 0], tri[:, 1], tri[:, 2])
    t1, t2, n = _local_frames(B2, body.faces, q.face)
    o = g - q.closest
    coef = np.stack([np.einsum("ij,ij->i", o, t1), np.einsum("ij,ij->i", o, t2), np.einsum("ij,ij->i", o, n)], 1)
    R = body.shaped_vertices(betas)[0]
    c_r = np.einsum("mk,mkc->mc", bary, R[body.faces[q.face]])
    r1, r2, rn = _local_frames(R, body.faces, q.face)
    out = c_r + coef[:, :1] * r1 + coef[:, 1:2] * r2 + coef[:, 2:] * rn
    return BodyFit(vertices=out, body_error=body_error, scale=scale_f, trans=np.asarray(t), pose=th, betas=beta)
