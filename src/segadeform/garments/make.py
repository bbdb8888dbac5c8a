"""Parametric garments cut from the body's own surface, offset outward, with flared skirts extruded.

How a garment is made (rest pose, y-up metres, SMPL joint names)::

    body surface --Taubin-smooth (creases filled)--> field phi (> 0 in the region)
          --cut along phi = 0 (crossing points on the edges)--> patch with smooth boundary --clean-->
          --offset along smoothed normals by `ease`, relax--> planar loops made convex, boundary
            loops low-pass filtered --> [--extrude the lowest loop into a flared skirt-->]
          --subdivide `subdivisions` times--> check: manifold, one piece, no vertex inside the body

The region is a smooth field (smooth minimum of signed distances to the
cuts), so hems, necklines, armholes, cuffs and waistbands are smooth curves
with rounded corners, not the body mesh's triangle staircase
(:func:`boundary_turning` measures them).  With ``cloth_pose`` (e.g. an
A-pose) the same cut is also made on the body in that pose: the two garments
share vertices and faces, and a simulation can rest and drape there.

Regions are defined by joint positions in the rest pose, so garments follow
the body shape (betas) they are made for.  Kinds (:data:`GARMENT_KINDS`)
and their garment-type label (:data:`GARMENT_TYPES`):

=============  ============  =================================================
kind           type          region and skirt
=============  ============  =================================================
skirt          skirt         waist to the hips, then a flared skirt (`length`)
dress          dress         torso without sleeves (scoop neck), then a skirt
sleeved-dress  dress         torso with short sleeves, then a skirt
tshirt         top           torso and short sleeves (`sleeve` 0..1 of the arm)
tank           top           torso, 4 cm straps, deep scoop neck, wide armholes
jacket         open-front    torso and long sleeves, open down the front
trousers       trousers      waist to the ankles (`length` 0..1 of the leg)
shorts         trousers      waist to mid-thigh
jumpsuit       jumpsuit      neck to the ankles, short sleeves
=============  ============  =================================================

``length``: skirts: hem height as a fraction of hip-to-ankle (0.3 short,
0.8 long); trousers/shorts: leg covered, 0..1 of hip-to-ankle.  ``flare``:
how much wider than the hips the hem is (0 = straight).  ``ease``: metres
between skin and cloth.  ``waist_ease`` (trousers, shorts, skirts; None: ``ease``
everywhere): metres between skin and cloth at the waistband, tapering to ``ease``
over :data:`WAIST_TAPER` below it -- trousers sit on the waist and have their
room in the hips and legs, and a waistband standing off the body by the legs'
ease is what a hanging forearm passes through when the waistband is pinned.
``subdivisions``: each multiplies the vertex count by about 4 (0 gives roughly
1k-4k vertices on the default body, 1 gives 4k-16k).
"""

from __future__ import annotations

import dataclasses

import numpy as np

from ..body.collision import BodyProxy
from ..body.model import BodyModel
from ..body.resample import subdivide
from ..body.skeleton import SMPL_JOINT_NAMES
from ..errors import InputError
from ..geometry.mesh_ops import boundary_loops, connected_components, mean_edge_length, unique_edges, vertex_normals
from ..io.obj import betas_record

__all__ = [
    "GARMENT_KINDS",
    "GARMENT_TYPES",
    "GarmentParams",
    "GarmentCheckError",
    "Garment",
    "make_garment",
    "check_garment",
    "boundary_turning",
    "waistband_ease",
    "WAIST_TAPER",
    "WAISTBAND_KINDS",
    "KIND_PARAMS",
]

GARMENT_TYPES = {
    "skirt": "skirt",
    "dress": "dress",
    "sleeved-dress": "dress",
    "tshirt": "top",
    "tank": "top",
    "jacket": "open-front",
    "trousers": "trousers",
    "shorts": "trousers",
    "jumpsuit": "jumpsuit",
}
GARMENT_KINDS = tuple(GARMENT_TYPES)
_J = {n: i for i, n in enumerate(SMPL_JOINT_NAMES)}
#: metres below the waistband over which ``waist_ease`` tapers to ``ease``
WAIST_TAPER = 0.08
#: kinds whose top edge is a waistband (``waist_ease`` applies)
WAISTBAND_KINDS = ("skirt", "trousers", "shorts")
#: the shape parameters each kind uses besides ``ease``, ``resolution`` and ``subdivisions`` (every kind's); see
#: :func:`_region` and the skirt's extrusion (``flare``).  :func:`make_garment` ignores the others (dataset configs
#: draw ``length`` and ``flare`` for T-shirts, and their sample specs hold them); ``garment make`` refuses them
KIND_PARAMS = {
    "skirt": ("length", "flare", "waist_ease"),
    "dress": ("length", "flare"),
    "sleeved-dress": ("length", "flare", "sleeve"),
    "tshirt": ("sleeve",),
    "tank": (),
    "jacket": ("sleeve",),
    "trousers": ("length", "waist_ease"),
    "shorts": ("length", "waist_ease"),
    "jumpsuit": ("length", "sleeve"),
}


class GarmentCheckError(InputError):
    """A garment made from valid parameters failed :func:`check_garment` (it is not returned)."""


@dataclasses.dataclass(frozen=True)
class GarmentParams:
    length: float | None = None  # kind-specific default
    flare: float = 0.25
    ease: float = 0.015
    sleeve: float | None = None  # fraction of the arm (shoulder to wrist) the sleeve covers
    subdivisions: int = 0
    resolution: int | None = None  # target vertex count: picks the subdivisions closest to it
    waist_ease: float | None = None  # metres at the waistband, tapering to `ease` (None: `ease` everywhere)

    def __post_init__(self):
        if self.resolution is not None and not (isinstance(self.resolution, int) and 100 <= self.resolution <= 200_000):
            raise InputError("garment resolution out of range", expected="100..200000 vertices", got=self.resolution)
        for name, lo, hi in (
            ("length", 0.05, 1.0),
            ("flare", 0.0, 2.0),
            ("ease", 0.002, 0.1),
            ("sleeve", 0.0, 1.0),
            ("waist_ease", 0.002, 0.1),
        ):
            v = getattr(self, name)
            if v is not None and not (isinstance(v, (int, float)) and lo <= v <= hi):
                raise InputError(f"garment {name} out of range", expected=f"{lo}..{hi}", got=v)
        if self.subdivisions not in (0, 1, 2):
            raise InputError("garment subdivisions must be 0, 1 or 2", got=self.subdivisions)


@dataclasses.dataclass
class Garment:
    """vertices (N, 3) rest pose, faces (F, 3) outward-oriented triangles, ``kind``, ``type`` label,
    parameters; ``cloth_rest`` (N, 3) the same garment made on the body in another pose, or None."""

    vertices: np.ndarray
    faces: np.ndarray
    kind: str
    type: str
    params: GarmentParams
    betas: tuple
    cloth_rest: np.ndarray | None = None  # (N, 3) the same garment made in ``cloth_pose`` (see make_garment)

    def header(self) -> str:
        p = dataclasses.asdict(self.params)
        return "\n".join(
            [
                f"segadeform garment: kind={self.kind} type={self.type}",
                "params: " + " ".join(f"{k}={v}" for k, v in p.items() if v is not None),
                betas_record(self.betas),
            ]
        )


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
    """Uniform Laplacian smoothing of interior vertices, keeping ``ease / 2`` clearance from the body
    (``ease / 4`` on the boundary)."""
    from ..geometry.mesh_ops import boundary_vertices

    ease = _per_vertex(ease, len(v))
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
        # boundary vertices only when near the skin (see _smooth_boundary)
        q = proxy.query(v)
        bad = q.signed_distance < np.where(interior, 0.5, 0.25) * ease
        v[bad] = q.closest[bad] + (np.where(interior, 1.0, 0.25) * ease)[bad, None] * q.normal[bad]
    return v


def _extrude_skirt(v, f, hem_y, flare, proxy: BodyProxy, ease):
    """Extrude the lowest boundary loop down to ``hem_y``, widening to ``1 + flare`` at the hem and
    never closer than ``ease`` to the body."""
    loops = boundary_loops(f, len(v))
    loop = min(loops, key=lambda lp: v[lp, 1].mean())
    ring0 = v[loop]
    y0 = ring0[:, 1].mean()
    if hem_y >= y0 - 0.02:
        return v, f, np.asarray(loop)
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
        scale = max(prev_scale, 1.0 + flare * t**1.2)
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
    for r0, r1 in zip(rings[:-1], rings[1:], strict=True):
        a, b = r0, np.roll(r0, -1)
        c, d = r1, np.roll(r1, -1)
        # the loop runs along its owning faces' half-edges a->b, so new faces use b->a
        faces.append(np.stack([b, a, c], 1))
        faces.append(np.stack([b, c, d], 1))
    return np.concatenate(verts), np.concatenate(faces), np.asarray(loop)


# ---------------------------------------------------------------- smooth cuts
def _smin(fields, r: float) -> np.ndarray:
    """Smooth minimum (log-sum-exp with radius ``r`` metres) of fields ``(K, N)`` -> ``(N,)``.

    Equal to the minimum where one field is lower than the others by a few ``r``; rounds the
    corners where two level sets meet to a radius of about ``r``.
    """
    f = np.stack([np.asarray(x, np.float64) for x in fields])
    m = f.min(0)
    return m - r * np.log(np.exp(-(f - m) / r).sum(0))


def _smax(fields, r: float) -> np.ndarray:
    return -_smin([-np.asarray(x, np.float64) for x in fields], r)


def _level_set_cut(faces, phi, x=None, snap: float = 0.25):
    """Cut a triangle mesh along the zero level set of a per-vertex field, keeping ``phi > 0``.

    Every output vertex is ``(1 - t) x[a] + t x[b]`` for the input positions ``x`` of any pose, so
    one cut serves several poses of the same mesh.  The boundary follows the level set (crossing
    points on the mesh edges), not the triangles; a vertex whose crossing point is within ``snap``
    of an edge's length is moved onto it (no sliver triangles).  Cut quads are split along their
    shorter diagonal in positions ``x`` (else the first).

    Shapes: faces (F, 3), phi (N,), x (N, 3) -> a (M,), b (M,), t (M,), faces (F', 3) into the M new vertices
    """
    f = np.asarray(faces, np.int64)
    phi = np.where(phi == 0, 1e-12, np.asarray(phi, np.float64))
    n = len(phi)
    e = unique_edges(f, n)
    pa, pb = phi[e[:, 0]], phi[e[:, 1]]
    cr = (pa > 0) != (pb > 0)
    t = pa[cr] / (pa[cr] - pb[cr])
    ec = e[cr]
    # snapping: a vertex next to the level set moves to its nearest crossing point (on one edge)
    cand_v = np.concatenate([ec[:, 0], ec[:, 1]])
    cand_w = np.concatenate([ec[:, 1], ec[:, 0]])
    cand_t = np.concatenate([t, 1 - t])
    keep = cand_t < snap
    order = np.argsort(-cand_t[keep])  # the smallest t is written last and wins
    snap_w = np.arange(n)
    snap_t = np.zeros(n)
    cv, cw, ct = cand_v[keep][order], cand_w[keep][order], cand_t[keep][order]
    snap_w[cv] = cw
    snap_t[cv] = ct
    sign = np.sign(phi)
    sign[cv] = 0
    # crossing points left: edges between strictly positive and strictly negative vertices
    sa, sb = sign[e[:, 0]], sign[e[:, 1]]
    xe = e[sa * sb < 0]
    xt = phi[xe[:, 0]] / (phi[xe[:, 0]] - phi[xe[:, 1]])
    m = np.int64(n + 1)
    xkey = {int(k): i for i, k in enumerate(xe[:, 0] * m + xe[:, 1])}
    fs = sign[f]
    whole = (fs >= 0).all(1) & (fs > 0).any(1)
    mixed = (fs > 0).any(1) & (fs < 0).any(1)
    out = [f[whole]]
    new = []  # polygons with crossing points as -(1 + index into xe)
    for tri, sg in zip(f[mixed].tolist(), fs[mixed].tolist(), strict=True):
        poly = []
        for k in range(3):
            i, j = tri[k], tri[(k + 1) % 3]
            if sg[k] >= 0:
                poly.append(i)
            if sg[k] * sg[(k + 1) % 3] < 0:
                poly.append(-1 - xkey[int(min(i, j) * m + max(i, j))])
        new.append(poly)
    # vertices: body vertices (possibly snapped) then crossing points
    a = np.concatenate([np.arange(n), xe[:, 0]])
    b = np.concatenate([snap_w, xe[:, 1]])
    tt = np.concatenate([snap_t, xt])
    idx = lambda q: q if q >= 0 else n - 1 - q  # noqa: E731
    tris = []
    for poly in new:
        q = [idx(x) for x in poly]
        if len(q) == 3:
            tris.append(q)
        elif len(q) == 4:
            if x is not None:
                pos = (1 - tt[q])[:, None] * x[a[q]] + tt[q][:, None] * x[b[q]]
                if np.linalg.norm(pos[1] - pos[3]) < np.linalg.norm(pos[0] - pos[2]):
                    q = q[1:] + q[:1]
            tris += [[q[0], q[1], q[2]], [q[0], q[2], q[3]]]
    f2 = np.concatenate([out[0], np.asarray(tris, np.int64).reshape(-1, 3)])
    used = np.unique(f2)
    remap = np.full(len(a), -1, np.int64)
    remap[used] = np.arange(len(used))
    return a[used], b[used], tt[used], remap[f2]


# ---------------------------------------------------------------- regions
#: radius (metres) over which the cut rounds the corners where two of its level sets meet
CORNER_RADIUS = 0.015


def _region(kind: str, p: GarmentParams, j: np.ndarray, bv: np.ndarray):
    """The garment's region on the rest body as a smooth field (metres, > 0 inside) and the skirt
    hem height (None: no skirt).

    Shapes: j (S, 3) rest joints, bv (V, 3) rest vertices -> phi (V,), hem
    """
    x, y, z = bv[:, 0], bv[:, 1], bv[:, 2]
    ax = np.abs(x)
    r = CORNER_RADIUS
    pelvis, hip, ankle = j[_J["pelvis"]], j[_J["left_hip"]], j[_J["left_ankle"]]
    neck, shoulder, wrist = j[_J["neck"]], j[_J["left_shoulder"]], j[_J["left_wrist"]]
    waist_y = j[_J["spine1"]][1] - 0.02
    cut_y = hip[1] - 0.01  # above the crotch: one loop around the pelvis
    arm = wrist[0] - shoulder[0]
    # neckline: an elliptic scoop (front and back) down to 10 cm below the neck joint, joined to a
    # cut across the shoulders 2 cm below it; all of it rounded by the smooth min/max
    scoop = (np.sqrt(x**2 / 0.09**2 + (z - neck[2]) ** 2 / 0.10**2) - 1.0) * 0.09
    not_neck_hole = _smax([scoop, (neck[1] - 0.10) - y], r)
    neck_cut = (neck[1] - 0.02) - y
    leg_len = hip[1] - ankle[1]
    hem = None
    if kind == "skirt":
        fields = [y - cut_y, waist_y - y]
        hem = hip[1] - (0.3 if p.length is None else p.length) * leg_len
    elif kind == "dress":
        # armhole: around the arm's root, just outside the shoulder joint (a plane nearer the neck
        # grazes the armpit's crease and gives a pinched loop)
        fields = [y - cut_y, neck_cut, not_neck_hole, (shoulder[0] + 0.005) - ax]
        hem = hip[1] - (0.45 if p.length is None else p.length) * leg_len
    elif kind == "tank":
        # 4 cm straps over the shoulders between a deep scoop neck and wide armholes that reach
        # 15 cm below the shoulder joint at the torso's side (no cloth in the armpit)
        scoop_t = (np.sqrt(x**2 / 0.075**2 + (z - neck[2]) ** 2 / 0.12**2) - 1.0) * 0.075
        cx, rx, ry = shoulder[0] + 0.05, shoulder[0] + 0.05 - 0.115, 0.16
        armhole = ((((ax - cx) / rx) ** 4 + ((y - shoulder[1]) / ry) ** 4) ** 0.25 - 1.0) * rx
        fields = [y - cut_y, _smax([scoop_t, (neck[1] - 0.14) - y], r), armhole, (neck[1] + 0.03) - y, cx - ax]
    elif kind in ("tshirt", "sleeved-dress", "jacket", "jumpsuit"):
        sl = p.sleeve if p.sleeve is not None else (0.9 if kind == "jacket" else 0.3)
        low = cut_y if kind != "jumpsuit" else ankle[1] + 0.03 + (1 - (p.length or 1.0)) * leg_len
        fields = [y - low, neck_cut, not_neck_hole, (shoulder[0] + sl * arm) - ax]
        if kind == "jacket":  # open down the front: a 2.4 cm slit on the front half
            fields.append(_smax([ax - 0.012, pelvis[2] - z], 0.005))
        if kind == "sleeved-dress":
            hem = hip[1] - (0.45 if p.length is None else p.length) * leg_len
    elif kind in ("trousers", "shorts"):
        length = p.length if p.length is not None else (1.0 if kind == "trousers" else 0.35)
        low = hip[1] - length * (leg_len - 0.03)
        fields = [waist_y - y, y - low]
    else:
        raise InputError("unknown garment kind", expected=" | ".join(GARMENT_KINDS), got=kind)
    return _smin(fields, r), hem


def _smooth_body(verts, faces, passes: int = 60, lam: float = 0.5, mu: float = -0.53):
    """Taubin smoothing of the body surface (uniform weights): fills narrow creases (the buttocks'
    cleft, the armpit's fold) the way cloth bridges them, without shrinking the body.  Garments are
    cut from this surface and then kept outside the real one.

    Shapes: verts (V, 3), faces (F, 3) -> (V, 3)
    """
    import scipy.sparse as sp

    v = np.asarray(verts, np.float64)
    e = unique_edges(faces, len(v))
    a = sp.coo_matrix(
        (np.ones(2 * len(e)), (np.r_[e[:, 0], e[:, 1]], np.r_[e[:, 1], e[:, 0]])), shape=(len(v), len(v))
    ).tocsr()
    deg = np.maximum(np.asarray(a.sum(1)).ravel(), 1.0)[:, None]
    for _ in range(passes):
        for coef in (lam, mu):
            v = v + coef * (a @ v / deg - v)
    return v


def _loop_plane(p):
    """Best plane of a loop's points: centroid (3,), unit normal (3,) and planarity -- the rms
    distance to the plane over the rms distance to the centroid (0 for a planar loop).

    Shapes: p (L, 3) -> (3,), (3,), float
    """
    c = p.mean(0)
    _, sv, vt = np.linalg.svd(p - c, full_matrices=False)
    return c, vt[2], float(sv[2] / max(np.sqrt((sv**2).sum()), 1e-15))


#: loops flatter than this (see _loop_plane) are hems, waistbands and cuffs: made convex
PLANAR = 0.1


def _convexify_loops(v, f):
    """Move the points of every planar boundary loop (hem, waistband, cuff) out to the loop's
    convex hull in its plane: cloth pulled around the body bridges what is concave there (the small
    of the back, the buttocks' cleft) instead of following it in.

    Shapes: v (N, 3), f (F, 3) -> (N, 3)
    """
    from scipy.spatial import ConvexHull

    v = np.array(v, np.float64)
    for loop in boundary_loops(f, len(v)):
        p = v[loop]
        c, nrm, flat = _loop_plane(p)
        if len(loop) < 5 or flat > PLANAR:
            continue
        u = np.linalg.svd(p - c, full_matrices=False)[2][:2]  # in-plane axes
        q = (p - c) @ u.T  # (L, 2)
        hull = q[ConvexHull(q).vertices]
        # every point moves along its ray from the centroid out to the hull's edge
        a, b = hull, np.roll(hull, -1, axis=0)
        r = np.linalg.norm(q, axis=1)
        d = q / np.maximum(r, 1e-15)[:, None]
        e = b - a
        den = d[:, None, 0] * e[None, :, 1] - d[:, None, 1] * e[None, :, 0]  # (L, H)
        with np.errstate(divide="ignore", invalid="ignore"):
            s = (a[None, :, 0] * e[None, :, 1] - a[None, :, 1] * e[None, :, 0]) / den  # ray length
            w = (a[None, :, 0] * d[:, None, 1] - a[None, :, 1] * d[:, None, 0]) / den  # edge parameter
        ok = (s > 0) & (w >= -1e-9) & (w <= 1 + 1e-9) & np.isfinite(s)
        reach = np.where(ok, s, np.inf).min(1)
        grow = np.where(np.isfinite(reach) & (reach > r), reach - r, 0.0)
        v[loop] = p + (d * grow[:, None]) @ u
    return v


def _per_vertex(ease, n: int) -> np.ndarray:
    """``ease``: one number or one per vertex -> (n,) metres."""
    return np.broadcast_to(np.asarray(ease, np.float64), (n,))


def waistband_ease(rest, ease: float, waist_ease: float, taper: float = WAIST_TAPER) -> np.ndarray:
    """Per-vertex ease of a garment whose top edge is a waistband: ``waist_ease`` at the top (the highest
    point of ``rest``), ``ease`` from ``taper`` metres below it down, a smoothstep between (no crease where
    the fitted waist meets the looser hips).

    Shapes: rest (N, 3) y-up, the patch on the body's rest pose -> (N,)
    """
    y = np.asarray(rest, np.float64)[:, 1]
    s = np.clip((y.max() - y) / taper, 0.0, 1.0)
    s = s * s * (3.0 - 2.0 * s)
    return waist_ease + (ease - waist_ease) * s


def _offset(v, f, proxy: BodyProxy, ease):
    """Offset a patch of the body surface by ``ease`` (metres: one number or one per vertex) along its
    smoothed normals, push what lands inside back out, and even the triangles (see :func:`_relax`).

    Shapes: v (N, 3), ease () or (N,) -> (N, 3)"""
    ease = _per_vertex(ease, len(v))
    v = v + ease[:, None] * _smooth_normals(v, f, rounds=12)
    # where the offset lands inside (concave creases), push out along the body normal
    q = proxy.query(v)
    bad = q.signed_distance < 0.5 * ease
    v[bad] = q.closest[bad] + ease[bad, None] * q.normal[bad]
    # crease vertices pushed out above bunch up (armpits: 3 mm edges that the simulator then
    # stretched 300 %); a few smoothing passes even the triangles, each followed by the push-out
    v = _relax(v, f, proxy, ease)
    v = _smooth_boundary(_convexify_loops(v, f), f, proxy, ease)
    return _relax(v, f, proxy, ease, passes=5)


def _smooth_boundary(v, f, proxy: BodyProxy, ease, passes: int = 20, lam: float = 0.5, mu: float = -0.53):
    """Taubin smoothing along every boundary loop (a low-pass filter that does not shrink the loop):
    removes what the body mesh leaves in a cut -- a dent where a hem crosses the buttocks' cleft,
    kinks where two cuts meet -- keeping ``ease / 2`` clearance from the body.

    Shapes: v (N, 3), f (F, 3) -> (N, 3)
    """
    v = np.array(v, np.float64)
    loops = [lp for lp in boundary_loops(f, len(v)) if len(lp) >= 5]
    if not loops:
        return v
    every = np.concatenate(loops)
    ease = _per_vertex(ease, len(v))[every]
    for _ in range(passes):
        for coef in (lam, mu):
            for loop in loops:
                p = v[loop]
                v[loop] = p + coef * (0.5 * (np.roll(p, 1, axis=0) + np.roll(p, -1, axis=0)) - p)
        # only what comes near the skin is pushed back: a hem bridging a narrow crease is within
        # ease / 2 of its walls, and pushing it along their normals would fold it into the crease
        q = proxy.query(v[every])
        bad = q.signed_distance < 0.25 * ease
        v[every[bad]] = q.closest[bad] + (0.25 * ease[bad])[:, None] * q.normal[bad]
    return v


def _refine(x, f, levels: int, proxy: BodyProxy, ease):
    """Midpoint-subdivide ``levels`` times; a midpoint that lands inside the rest body is pushed out along the body
    normal to ``ease / 2``, the clearance :func:`_relax` keeps.

    Flat midpoints sit below the offset surface by about ``edge**2 / (8 radius)``: over the groin or the shoulders
    that is more than the ``ease / 2`` the coarse vertices may keep, so a small ease put midpoints inside the body
    (jumpsuit, ease 5 mm, one level: 1.3 mm inside).  Only midpoints inside are moved, so a garment that was
    outside the body at every level is unchanged.

    Shapes: x (N, 3 P) rest pose first, f (F, 3), ease (N,) metres -> x (M, 3 P), f (4**levels F, 3); only the rest
    pose's midpoints are pushed
    """
    ease = np.asarray(ease, np.float64)
    for _ in range(levels):
        n = len(x)
        e = unique_edges(f, n)
        ease = np.concatenate([ease, 0.5 * (ease[e[:, 0]] + ease[e[:, 1]])])
        x, f = subdivide(x, f)
        q = proxy.query(x[n:, :3])
        bad = np.flatnonzero(q.signed_distance < 0)
        x[n + bad, :3] = q.closest[bad] + 0.5 * ease[n + bad, None] * q.normal[bad]
    return x, f


def make_garment(
    kind: str, body: BodyModel, betas=None, params: GarmentParams = GarmentParams(), *, cloth_pose=None
) -> Garment:
    """Make a ``kind`` garment for ``body`` with shape ``betas`` (see the module docstring).

    ``cloth_pose`` (72,) axis-angle, e.g. an A-pose: the same garment (vertex for vertex, the same
    cut) is also made on the body in that pose, as ``Garment.cloth_rest`` -- the shape a cloth
    simulation that starts in that pose takes its rest lengths from (a T-posed garment is too
    short over the shoulders and bunched in the armpits for lowered arms).

    Shapes: -> Garment.vertices (N, 3), Garment.faces (F, 3), Garment.cloth_rest (N, 3) or None
    """
    if kind not in GARMENT_TYPES:
        raise InputError("unknown garment kind", expected=" | ".join(GARMENT_KINDS), got=kind)
    if params.waist_ease is not None and kind not in WAISTBAND_KINDS:
        raise InputError("waist_ease is for garments with a waistband", expected=" | ".join(WAISTBAND_KINDS), got=kind)
    bv = body.shaped_vertices(betas)[0]
    j = body.rest_joints(betas)[0]
    poses = [bv]
    if cloth_pose is not None:
        cp = np.asarray(cloth_pose, np.float64)
        if cp.shape not in ((72,), (1, 72)) or not np.isfinite(cp).all():
            raise InputError("cloth_pose must be a finite (72,) axis-angle pose", got=cp.shape)
        poses.append(body.forward(cp.reshape(1, 72), betas).vertices[0])
    # cut from the smoothed body (creases filled), the region's field evaluated there too
    smooth = [_smooth_body(pv, body.faces) for pv in poses]
    phi, hem = _region(kind, params, j, smooth[0])
    a, b, t, f = _level_set_cut(body.faces, phi, smooth[0])
    if len(f) < 20:
        raise InputError(f"the {kind} region of this body is empty; check the body and its rest pose")
    # every pose's positions side by side (N, 3 P): cleaning and refining act on all of them at once
    x = np.concatenate([(1 - t)[:, None] * sv[a] + t[:, None] * sv[b] for sv in smooth], axis=1)
    x, f = _largest_component(x, f)
    x, f = _clean_patch(x, f)
    ease = params.ease
    if params.waist_ease is not None:  # fitted at the waist, room below
        ease = waistband_ease(x[:, :3], params.ease, params.waist_ease)
    out = [_offset(x[:, 3 * k : 3 * k + 3].copy(), f, BodyProxy(pv, body.faces), ease) for k, pv in enumerate(poses)]
    ease = _per_vertex(ease, len(out[0]))
    if hem is not None:  # the skirt is extruded in the rest pose; other poses move it with its waist
        n0 = len(out[0])
        v0, f2, loop = _extrude_skirt(out[0], f, hem, params.flare, BodyProxy(bv, body.faces), params.ease)
        rings = v0[n0:].reshape(-1, len(loop), 3)
        out = [v0] + [np.concatenate([o, (rings + (o[loop] - out[0][loop])[None]).reshape(-1, 3)]) for o in out[1:]]
        f = f2
        ease = np.concatenate([ease, np.full(len(v0) - n0, params.ease)])
    x = np.concatenate(out, axis=1)
    # refine last, so skirts are refined too
    levels = params.subdivisions
    if params.resolution is not None:  # each level multiplies the count by about 4: the level nearest the target
        # (in ratio; a target <= 200,000 gives at most twice it), not capped at 2 (150,000 gave 38,866 then)
        levels = max(0, int(np.round(np.log(params.resolution / len(x)) / np.log(4.0))))
    if levels:
        x, f = _refine(x, f, levels, BodyProxy(bv, body.faces), ease)
    g = Garment(
        vertices=x[:, :3].copy(),
        faces=f,
        kind=kind,
        type=GARMENT_TYPES[kind],
        params=params,
        betas=tuple(float(b) for b in np.ravel(betas if betas is not None else [])),
        cloth_rest=x[:, 3:6].copy() if cloth_pose is not None else None,
    )
    try:
        check_garment(g.vertices, g.faces, body, betas)
    except InputError as e:
        inside = "inside the body" in e.problem  # what the parameters can change: the ease
        raise GarmentCheckError(
            f"the {kind} made ({len(g.vertices)} vertices) "
            + (f"starts with {e.got} vertices inside the body" if inside else f"failed its check: {e.problem}"),
            expected=f"a larger ease than {params.ease} m" if inside else e.expected,
            got=None if inside else e.got,
        ) from None
    return g


def boundary_turning(vertices, faces) -> list[np.ndarray]:
    """The turning angle (radians) at every vertex of every boundary loop: the angle between the
    loop's incoming and outgoing edge there (0 on a straight run, about ``h / R`` on a smooth curve
    of radius ``R`` sampled every ``h``; a staircase along mesh triangles turns by 45-90 degrees).
    A loop's total is its total curvature, ``2 pi`` for a convex planar loop and more otherwise.

    Shapes: vertices (N, 3), faces (F, 3) -> one (L,) array per boundary loop
    """
    v = np.asarray(vertices, np.float64)
    out = []
    for loop in boundary_loops(faces, len(v)):
        p = v[loop]
        d = np.roll(p, -1, axis=0) - p
        d /= np.maximum(np.linalg.norm(d, axis=1, keepdims=True), 1e-15)
        out.append(np.arccos(np.clip((np.roll(d, 1, axis=0) * d).sum(1), -1.0, 1.0)))
    return out


def check_garment(vertices, faces, body: BodyModel | None = None, betas=None, *, tolerance: float = 0.0) -> dict:
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
