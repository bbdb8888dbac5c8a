"""Parametric garments cut from the body's own surface, offset outward, with flared skirts extruded.

How a garment is made (rest pose, y-up metres, SMPL joint names)::

    body surface --select region--> patch --clean--> manifold patch with boundary
          --offset along normals by `ease`--> [--extrude the lowest loop into a flared skirt-->]
          --subdivide `subdivisions` times--> check: manifold, one piece, no vertex inside the body

Regions are boxes in the rest pose defined by joint positions, so garments
follow the body shape (betas) they are made for.  Kinds (:data:`GARMENT_KINDS`)
and their garment-type label (:data:`GARMENT_TYPES`):

=============  ============  =================================================
kind           type          region and skirt
=============  ============  =================================================
skirt          skirt         waist to the hips, then a flared skirt (`length`)
dress          dress         torso without sleeves (scoop neck), then a skirt
sleeved-dress  dress         torso with short sleeves, then a skirt
tshirt         top           torso and short sleeves (`sleeve` 0..1 of the arm)
tank           top           torso, no sleeves, narrow shoulders
jacket         open-front    torso and long sleeves, open down the front
trousers       trousers      waist to the ankles (`length` 0..1 of the leg)
shorts         trousers      waist to mid-thigh
jumpsuit       jumpsuit      neck to the ankles, short sleeves
=============  ============  =================================================

``length``: skirts: hem height as a fraction of hip-to-ankle (0.3 short,
0.8 long); trousers/shorts: leg covered, 0..1 of hip-to-ankle.  ``flare``:
how much wider than the hips the hem is (0 = straight).  ``ease``: metres
between skin and cloth.  ``subdivisions``: each multiplies the vertex count
by about 4 (0 gives roughly 1k-4k vertices on the default body, 1 gives
4k-16k).
"""

from __future__ import annotations

import dataclasses
from typing import Optional

import numpy as np

from ..body.collision import BodyProxy
from ..body.model import BodyModel
from ..body.skeleton import SMPL_JOINT_NAMES
from ..errors import InputError
from ..geometry.mesh_ops import boundary_loops, connected_components, mean_edge_length, unique_edges, vertex_normals

__all__ = ["GARMENT_KINDS", "GARMENT_TYPES", "GarmentParams", "Garment", "make_garment", "check_garment"]

GARMENT_TYPES = {"skirt": "skirt", "dress": "dress", "sleeved-dress": "dress", "tshirt": "top", "tank": "top",
                 "jacket": "open-front", "trousers": "trousers", "shorts": "trousers", "jumpsuit": "jumpsuit"}
GARMENT_KINDS = tuple(GARMENT_TYPES)
_J = {n: i for i, n in enumerate(SMPL_JOINT_NAMES)}


@dataclasses.dataclass(frozen=True)
class GarmentParams:
    length: Optional[float] = None     # kind-specific default
    flare: float = 0.25
    ease: float = 0.015
    sleeve: Optional[float] = None     # fraction of the arm (shoulder to wrist) the sleeve covers
    subdivisions: int = 0
    resolution: Optional[int] = None   # target vertex count: picks the subdivisions closest to it

    def __post_init__(self):
        if self.resolution is not None and not (isinstance(self.resolution, int) and 100 <= self.resolution <= 200_000):
            raise InputError("garment resolution out of range", expected="100..200000 vertices", got=self.resolution)
        for name, lo, hi in (("length", 0.05, 1.0), ("flare", 0.0, 2.0), ("ease", 0.002, 0.1), ("sleeve", 0.0, 1.0)):
            v = getattr(self, name)
            if v is not None and not (isinstance(v, (int, float)) and lo <= v <= hi):
                raise InputError(f"garment {name} out of range", expected=f"{lo}..{hi}", got=v)
        if self.subdivisions not in (0, 1, 2):
            raise InputError("garment subdivisions must be 0, 1 or 2", got=self.subdivisions)


@dataclasses.dataclass
class Garment:
    """vertices (N, 3), faces (F, 3) outward-oriented triangles, ``kind``, ``type`` label, parameters."""

    vertices: np.ndarray
    faces: np.ndarray
    kind: str
    type: str
    params: GarmentParams
    betas: tuple

    def header(self) -> str:
        p = dataclasses.asdict(self.params)
        return "\n".join([f"segadeform garment: kind={self.kind} type={self.type}",
                          "params: " + " ".join(f"{k}={v}" for k, v in p.items() if v is not None),
                          "betas: " + " ".join(f"{b:g}" for b in self.betas)])


# ---------------------------------------------------------------- mesh helpers
def _largest_component(v, f):
    k, lab = connected_components(f, len(v))
    if k > 1:
        keep_v = np.bincount(lab[f[:, 0]], minlength=k).argmax()
        f = f[lab[f[:, 0]] == keep_v]
    return _compact(v, f)


def _compact(v, f):
    used = np.unique(f)
    remap = np.full(len(v), -1, np.int64)
    remap[used] = np.arange(len(used))
    return v[used], remap[f]


def _clean_patch(v, f):
    """Drop faces until every vertex is a manifold disc or half-disc and no face hangs by one edge."""
    for _ in range(200):
        he = np.concatenate([f[:, [0, 1]], f[:, [1, 2]], f[:, [2, 0]]])
        key = np.sort(he, axis=1)
        key = key[:, 0] * (len(v) + 1) + key[:, 1]
        _, inv, cnt = np.unique(key, return_inverse=True, return_counts=True)
        bnd = (cnt[inv.ravel()] == 1).reshape(3, len(f)).T  # (F, 3) boundary flags per face edge
        ears = bnd.sum(1) >= 2
        # a vertex with more than two boundary edges joins two fans at one point (a bow-tie)
        bv = he[bnd.T.ravel()]
        deg = np.bincount(bv.ravel(), minlength=len(v))
        bow = deg > 2
        bad = ears | bow[f].any(1)
        if not bad.any():
            break
        f = f[~bad]
        v, f = _largest_component(v, f)
    return v, f


def _subdivide(v, f):
    """Midpoint subdivision: every triangle into four."""
    e = unique_edges(f, len(v))
    n = len(v)
    key = {(int(a), int(b)): n + i for i, (a, b) in enumerate(e)}
    mid = 0.5 * (v[e[:, 0]] + v[e[:, 1]])

    def m(a, b):
        return key[(a, b) if a < b else (b, a)]

    out = []
    for a, b, c in f.tolist():
        ab, bc, ca = m(a, b), m(b, c), m(c, a)
        out += [(a, ab, ca), (ab, b, bc), (ca, bc, c), (ab, bc, ca)]
    return np.concatenate([v, mid]), np.asarray(out, np.int64)


def _smooth_normals(v, f, rounds=2):
    n = vertex_normals(v, f)
    e = unique_edges(f, len(v))
    for _ in range(rounds):
        acc = n.copy()
        np.add.at(acc, e[:, 0], n[e[:, 1]])
        np.add.at(acc, e[:, 1], n[e[:, 0]])
        n = acc / np.maximum(np.linalg.norm(acc, axis=1, keepdims=True), 1e-12)
    return n


def _relax(v, f, proxy: BodyProxy, ease, passes: int = 10, step: float = 0.5):
    """Uniform Laplacian smoothing of interior vertices, keeping ``ease / 2`` clearance from the body."""
    from ..geometry.mesh_ops import boundary_vertices

    e = unique_edges(f, len(v))
    deg = np.bincount(e.ravel(), minlength=len(v)).astype(np.float64)
    interior = np.ones(len(v), bool)
    interior[boundary_vertices(f)] = False
    for _ in range(passes):
        acc = np.zeros_like(v)
        np.add.at(acc, e[:, 0], v[e[:, 1]])
        np.add.at(acc, e[:, 1], v[e[:, 0]])
        avg = acc / np.maximum(deg, 1)[:, None]
        v = np.where(interior[:, None], v + step * (avg - v), v)
        q = proxy.query(v)
        bad = q.signed_distance < 0.5 * ease
        v[bad] = q.closest[bad] + ease * q.normal[bad]
    return v


def _extrude_skirt(v, f, hem_y, flare, proxy: BodyProxy, ease):
    """Extrude the lowest boundary loop down to ``hem_y``, widening to ``1 + flare`` at the hem and
    never closer than ``ease`` to the body."""
    loops = boundary_loops(f, len(v))
    loop = min(loops, key=lambda l: v[l, 1].mean())
    ring0 = v[loop]
    y0 = ring0[:, 1].mean()
    if hem_y >= y0 - 0.02:
        return v, f
    centre = ring0.mean(0)
    step = mean_edge_length(v, f)
    n_rings = max(2, int(np.ceil((y0 - hem_y) / step)))
    m = len(loop)
    rings = [np.asarray(loop)]
    verts = [v]
    nxt = len(v)
    prev_scale = 1.0
    base = ring0 - centre
    base[:, 1] = 0.0
    for k in range(1, n_rings + 1):
        t = k / n_rings
        y = y0 + (hem_y - y0) * t
        scale = max(prev_scale, 1.0 + flare * t ** 1.2)
        for _ in range(60):  # widen until the ring clears the body by `ease`
            pts = centre + scale * base
            pts[:, 1] = y + (ring0[:, 1] - y0) * (1 - t)
            if (proxy.query(pts).signed_distance >= ease).all():
                break
            scale *= 1.03
        prev_scale = scale
        verts.append(pts)
        rings.append(np.arange(nxt, nxt + m))
        nxt += m
    faces = [f]
    for r0, r1 in zip(rings[:-1], rings[1:]):
        a, b = r0, np.roll(r0, -1)
        c, d = r1, np.roll(r1, -1)
        # the loop runs along its owning faces' half-edges a->b, so new faces use b->a
        faces.append(np.stack([b, a, c], 1))
        faces.append(np.stack([b, c, d], 1))
    return np.concatenate(verts), np.concatenate(faces)


# ---------------------------------------------------------------- regions
def _region(kind: str, p: GarmentParams, j: np.ndarray, bv: np.ndarray):
    """Vertex mask on the rest body, the skirt hem height (None: no skirt)."""
    x, y, z = bv[:, 0], bv[:, 1], bv[:, 2]
    ax = np.abs(x)
    pelvis, hip, ankle = j[_J["pelvis"]], j[_J["left_hip"]], j[_J["left_ankle"]]
    neck, shoulder, wrist = j[_J["neck"]], j[_J["left_shoulder"]], j[_J["left_wrist"]]
    waist_y = j[_J["spine1"]][1] - 0.02
    cut_y = hip[1] - 0.01  # above the crotch: one loop around the pelvis
    arm = wrist[0] - shoulder[0]
    neck_hole = ((x ** 2) / 0.09 ** 2 + ((z - neck[2]) ** 2) / 0.10 ** 2 < 1) & (y > neck[1] - 0.10)
    neck_cut = y < neck[1] - 0.02
    leg_len = hip[1] - ankle[1]
    hem = None
    if kind == "skirt":
        mask = (y > cut_y) & (y < waist_y)
        hem = hip[1] - (0.3 if p.length is None else p.length) * leg_len
    elif kind in ("dress", "tank"):
        mask = (y > cut_y) & neck_cut & ~neck_hole & (ax < shoulder[0] - 0.01)
        if kind == "tank":
            mask &= ~((ax > 0.1) & (y > shoulder[1] - 0.01) & (ax < shoulder[0] - 0.01) & (y > neck[1] - 0.09))
        hem = hip[1] - (0.45 if p.length is None else p.length) * leg_len if kind == "dress" else None
    elif kind in ("tshirt", "sleeved-dress", "jacket", "jumpsuit"):
        sl = p.sleeve if p.sleeve is not None else (0.9 if kind == "jacket" else 0.3)
        low = cut_y if kind != "jumpsuit" else ankle[1] + 0.03 + (1 - (p.length or 1.0)) * leg_len
        mask = (y > low) & neck_cut & ~neck_hole & (ax < shoulder[0] + sl * arm)
        if kind == "jacket":
            front = z > pelvis[2]
            mask &= ~(front & (ax < 0.012))
        if kind == "sleeved-dress":
            hem = hip[1] - (0.45 if p.length is None else p.length) * leg_len
    elif kind in ("trousers", "shorts"):
        length = p.length if p.length is not None else (1.0 if kind == "trousers" else 0.35)
        low = hip[1] - length * (leg_len - 0.03)
        mask = (y < waist_y) & (y > low)
    else:
        raise InputError("unknown garment kind", expected=" | ".join(GARMENT_KINDS), got=kind)
    return mask, hem


def make_garment(kind: str, body: BodyModel, betas=None, params: GarmentParams = GarmentParams()) -> Garment:
    """Make a ``kind`` garment for ``body`` with shape ``betas`` (see the module docstring).

    Shapes: -> Garment.vertices (N, 3), Garment.faces (F, 3)
    """
    if kind not in GARMENT_TYPES:
        raise InputError("unknown garment kind", expected=" | ".join(GARMENT_KINDS), got=kind)
    bv = body.shaped_vertices(betas)[0]
    j = body.rest_joints(betas)[0]
    proxy = BodyProxy(bv, body.faces)
    mask, hem = _region(kind, params, j, bv)
    f = body.faces[mask[body.faces].all(1)]
    if len(f) < 20:
        raise InputError(f"the {kind} region of this body is empty; check the body and its rest pose")
    v, f = _largest_component(bv, f)
    v, f = _clean_patch(v, f)
    n = _smooth_normals(v, f)
    v = v + params.ease * n
    # where the offset lands inside (concave creases), push out along the body normal
    q = proxy.query(v)
    bad = q.signed_distance < 0.5 * params.ease
    v[bad] = q.closest[bad] + params.ease * q.normal[bad]
    # crease vertices pushed out above bunch up (armpits: 3 mm edges that the simulator then
    # stretched 300 %); a few smoothing passes even the triangles, each followed by the push-out
    v = _relax(v, f, proxy, params.ease)
    if hem is not None:
        v, f = _extrude_skirt(v, f, hem, params.flare, proxy, params.ease)
    # refine last, so skirts are refined too; flat midpoints sit < 1 mm inside the offset surface
    levels = params.subdivisions
    if params.resolution is not None:  # each level multiplies the count by about 4
        levels = int(np.clip(np.round(np.log(params.resolution / len(v)) / np.log(4.0)), 0, 2))
    for _ in range(levels):
        v, f = _subdivide(v, f)
    g = Garment(vertices=v, faces=f, kind=kind, type=GARMENT_TYPES[kind], params=params,
                betas=tuple(float(b) for b in np.ravel(betas if betas is not None else [])))
    check_garment(g.vertices, g.faces, body, betas)
    return g


def check_garment(vertices, faces, body: Optional[BodyModel] = None, betas=None, *, tolerance: float = 0.0) -> dict:
    """Check a garment mesh: one piece, edge-manifold, consistently oriented, open (has a boundary),
    no degenerate triangle, and (with a body) no vertex inside the body.  Raises :class:`InputError`
    naming the first failure; returns the measured numbers."""
    v, f = np.asarray(vertices, np.float64), np.asarray(faces, np.int64)
    he = np.concatenate([f[:, [0, 1]], f[:, [1, 2]], f[:, [2, 0]]])
    und = np.sort(he, 1)
    _, cnt = np.unique(und[:, 0] * (len(v) + 1) + und[:, 1], return_counts=True)
    if cnt.max() > 2:
        raise InputError("garment is not edge-manifold", expected="<= 2 faces per edge", got=int(cnt.max()))
    _, dcnt = np.unique(he[:, 0] * (len(v) + 1) + he[:, 1], return_counts=True)
    if dcnt.max() > 1:
        raise InputError("garment faces are not consistently oriented")
    k, _ = connected_components(f, len(v))
    if k != 1:
        raise InputError("garment is not one piece", expected=1, got=k)
    area = 0.5 * np.linalg.norm(np.cross(v[f[:, 1]] - v[f[:, 0]], v[f[:, 2]] - v[f[:, 0]]), axis=1)
    if area.min() <= 1e-10:
        raise InputError("garment has a degenerate triangle", got=float(area.min()))
    loops = boundary_loops(f, len(v))
    out = {"vertices": len(v), "faces": len(f), "boundary_loops": len(loops), "min_area": float(area.min())}
    if body is not None:
        sd = BodyProxy(body.shaped_vertices(betas)[0], body.faces).query(v).signed_distance
        inside = int((sd < -tolerance).sum())
        out["min_clearance"] = float(sd.min())
        if inside:
            raise InputError("garment starts with vertices inside the body", expected=0, got=inside)
    return out
