"""The slow, obvious reference of body collisions: :class:`BodyProxy` (rebuilt for every frame) with
:func:`push_out`, and the exact closest point on triangles (see :mod:`segadeform.body.collision`)."""

from __future__ import annotations

import dataclasses
import functools

import numpy as np
from scipy.spatial import cKDTree

from ...errors import InputError
from ...geometry._checks import check_mesh
from ...geometry.mesh_ops import face_cross

__all__ = [
    "ProximityResult",
    "closest_point_on_triangles",
    "winding_number",
    "ray_winding",
    "nearest_unburied",
    "unbury",
    "BURY",
    "BURY_TRIES",
    "PINCH",
    "CARRY_LIMB",
    "CARRY_GROW",
    "BodyProxy",
    "push_out",
    "carry_correction",
]

#: a surface point is buried if the point this far out along its face's normal, times the posed body's size (its
#: bounding box's longest side: :func:`body_size`), is inside the body (``_collide.c``'s SDC_BURY); a point nearer its
#: closest point than that is on the surface
BURY = 1e-6
#: at most this many faces tested for one point (``_collide.c``'s SDC_BURY_TRIES): past it the point keeps its closest
#: surface
BURY_TRIES = 512
#: a point inside by the winding number but outside by its closest surface (cloth pinched where an arm presses into the
#: torso) is taken to the nearest skin that is not buried only within this distance, times the body's size
#: (``_collide.c``'s SDC_PINCH: 2.1 cm on a body 1.75 m tall); deeper in the crease it keeps its closest surface, as
#: the simulator leaves such cloth pinched.  Unbounded, the nearest open skin of a T-shirt's armpit vertex on a walk
#: was 4-7 cm away, in front of the arm in one frame and behind it in the next: jumps of up to 16 cm.
PINCH = 0.012
#: the carried push-out (:func:`carry_correction`, ``_collide.c``'s SDC_CARRY_LIMB and SDC_CARRY_GROW): another exit
#: is taken only if its move is at most CARRY_LIMB times the closest exit's plus PINCH times the body's size, and at
#: most the frame before's plus CARRY_GROW times that
CARRY_LIMB = 1.5
CARRY_GROW = 0.25


@dataclasses.dataclass(frozen=True)
class ProximityResult:
    """signed_distance (P,) negative inside; closest (P, 3); normal (P, 3) unit outward; face (P,)."""

    signed_distance: np.ndarray
    closest: np.ndarray
    normal: np.ndarray
    face: np.ndarray


def closest_point_on_triangles(p, a, b, c):
    """Closest point on triangles ``abc`` to points ``p``, and its barycentric weights.

    Shapes:
        p, a, b, c: (..., 3) -> closest (..., 3), bary (..., 3)
    """
    p, a, b, c = np.broadcast_arrays(*(np.asarray(x, np.float64) for x in (p, a, b, c)))
    ab, ac, ap = b - a, c - a, p - a
    d1, d2 = np.einsum("...i,...i", ab, ap), np.einsum("...i,...i", ac, ap)
    bp = p - b
    d3, d4 = np.einsum("...i,...i", ab, bp), np.einsum("...i,...i", ac, bp)
    cp = p - c
    d5, d6 = np.einsum("...i,...i", ab, cp), np.einsum("...i,...i", ac, cp)
    va = d3 * d6 - d5 * d4
    vb = d5 * d2 - d1 * d6
    vc = d1 * d4 - d3 * d2
    shape = p.shape[:-1]
    bary = np.zeros(shape + (3,))
    done = np.zeros(shape, bool)

    def put(mask, u, v, w):
        nonlocal done
        m = mask & ~done
        bary[m] = np.stack([u, v, w], -1)[m]
        done |= m

    tiny = 1e-300
    put((d1 <= 0) & (d2 <= 0), np.ones(shape), np.zeros(shape), np.zeros(shape))  # vertex a
    put((d3 >= 0) & (d4 <= d3), np.zeros(shape), np.ones(shape), np.zeros(shape))  # vertex b
    t = d1 / np.where(np.abs(d1 - d3) > tiny, d1 - d3, tiny)
    put((vc <= 0) & (d1 >= 0) & (d3 <= 0), 1 - t, t, np.zeros(shape))  # edge ab
    put((d6 >= 0) & (d5 <= d6), np.zeros(shape), np.zeros(shape), np.ones(shape))  # vertex c
    t = d2 / np.where(np.abs(d2 - d6) > tiny, d2 - d6, tiny)
    put((vb <= 0) & (d2 >= 0) & (d6 <= 0), 1 - t, np.zeros(shape), t)  # edge ac
    den = (d4 - d3) + (d5 - d6)
    t = (d4 - d3) / np.where(np.abs(den) > tiny, den, tiny)
    put((va <= 0) & ((d4 - d3) >= 0) & ((d5 - d6) >= 0), np.zeros(shape), 1 - t, t)  # edge bc
    s = va + vb + vc
    s = np.where(np.abs(s) > tiny, s, tiny)
    put(np.ones(shape, bool), va / s, vb / s, vc / s)  # interior
    bary = np.clip(bary, 0.0, 1.0)
    bary /= np.maximum(bary.sum(-1, keepdims=True), tiny)
    closest = bary[..., :1] * a + bary[..., 1:2] * b + bary[..., 2:] * c
    return closest, bary


def winding_number(points, vertices, faces) -> np.ndarray:
    """Generalised winding number (Jacobson et al. 2013): ~1 inside a closed mesh, ~0 outside. O(P F).

    Shapes:
        points: (P, 3) -> (P,)
    """
    v = np.asarray(vertices, np.float64)
    out = np.zeros(len(points))
    for lo in range(0, len(points), 256):
        p = np.asarray(points[lo : lo + 256], np.float64)[:, None, None, :]
        abc = v[faces][None] - p  # (P, F, 3, 3)
        a, b, c = abc[..., 0, :], abc[..., 1, :], abc[..., 2, :]
        la, lb, lc = (np.linalg.norm(x, axis=-1) for x in (a, b, c))
        num = np.einsum("...i,...i", a, np.cross(b, c))
        den = (
            la * lb * lc
            + np.einsum("...i,...i", a, b) * lc
            + np.einsum("...i,...i", b, c) * la
            + np.einsum("...i,...i", c, a) * lb
        )
        out[lo : lo + 256] = np.arctan2(num, den).sum(-1) / (2 * np.pi)
    return out


def _root_box(vertices, faces) -> np.ndarray:
    """The posed body's bounding box over the vertices its faces use (lo xyz, hi xyz), as the tree's root box."""
    used = np.asarray(vertices, np.float64)[np.unique(faces)]
    return np.concatenate([used.min(axis=0), used.max(axis=0)])


def body_size(vertices, faces) -> float:
    """The posed body's size, which the rules' tolerances are measured in: its bounding box's longest side (the same
    wherever the body stands; the largest coordinate magnitude made them 100x larger 100 m from the origin)."""
    box = _root_box(vertices, faces)
    return float((box[3:] - box[:3]).max())


def _closed(faces) -> bool:
    """Whether the mesh is closed as ``_collide.c`` counts it: every edge has exactly two faces, which run along it in
    opposite directions (only then does a ray's count of crossings tell inside from outside)."""
    f = np.ascontiguousarray(faces, np.int64)
    return _closed_cached(f.tobytes(), len(f))


@functools.lru_cache(maxsize=8)
def _closed_cached(data: bytes, n: int) -> bool:
    f = np.frombuffer(data, np.int64).reshape(n, 3)
    d = np.concatenate([f[:, [0, 1]], f[:, [1, 2]], f[:, [2, 0]]])  # directed edges
    if len(np.unique(d, axis=0)) != len(d):  # an edge run twice the same way (or by more than two faces)
        return False
    fwd = {(int(a), int(b)) for a, b in d}
    return all((b, a) in fwd for a, b in fwd)


def _ray_count(p, a, b, c, axis: int, sign: int) -> tuple[np.ndarray, np.ndarray]:
    """Per pair of a ray from ``p (K, 3)`` along ``sign`` * ``axis`` and a triangle ``a, b, c (K, 3)``: its signed
    crossing (-1, 0, 1) and whether it grazed (through an edge or a vertex, from the triangle's plane, or along an
    edge-on triangle whose own box the ray meets and which is not wholly behind it): the 2-D edge functions of
    ``_collide.c``'s ray_count, operation for operation.  -> (K,), (K,)"""
    u, w = (axis + 1) % 3, (axis + 2) % 3
    pu, pw, pa = p[:, u], p[:, w], p[:, axis]
    au, av, bu, bv = a[:, u] - pu, a[:, w] - pw, b[:, u] - pu, b[:, w] - pw
    cu, cv = c[:, u] - pu, c[:, w] - pw
    ea, eb, ec = bu * cv - bv * cu, cu * av - cv * au, au * bv - av * bu
    pos = (ea > 0).astype(np.int8) + (eb > 0) + (ec > 0)
    neg = (ea < 0).astype(np.int8) + (eb < 0) + (ec < 0)
    line = ~((pos > 0) & (neg > 0))  # the ray's line meets the triangle
    s = ea + eb + ec
    if sign > 0:
        ahead = np.maximum(np.maximum(a[:, axis], b[:, axis]), c[:, axis]) >= pa
    else:
        ahead = np.minimum(np.minimum(a[:, axis], b[:, axis]), c[:, axis]) <= pa
    box = (
        (np.minimum(np.minimum(au, bu), cu) <= 0)
        & (np.maximum(np.maximum(au, bu), cu) >= 0)
        & (np.minimum(np.minimum(av, bv), cv) <= 0)
        & (np.maximum(np.maximum(av, bv), cv) >= 0)
    )
    graze = line & (s == 0) & ahead & box
    with np.errstate(divide="ignore", invalid="ignore"):
        num = ea * (a[:, axis] - pa) + eb * (b[:, axis] - pa) + ec * (c[:, axis] - pa)
        depth = sign * num / s
    valid = line & (s != 0) & (depth >= 0)
    hit = valid & ((pos == 3) | (neg == 3)) & (depth > 0)
    graze |= valid & ~hit
    return np.where(hit, np.where(s > 0, 1, -1), 0) * sign, graze


def _column_grid(a, b, c, axis: int):
    """The triangles binned by their box across ``axis`` (the plane of the other two coordinates) on a uniform grid:
    a ray along ``axis`` can meet only the triangles of its own cell (every test of ``_ray_count`` that can count or
    graze needs the ray inside the triangle's box).  Returns a function: points (K, 3) -> (point, triangle) pairs."""
    u, w = (axis + 1) % 3, (axis + 2) % 3
    lo = np.stack([np.minimum(np.minimum(a[:, x], b[:, x]), c[:, x]) for x in (u, w)], axis=1)
    hi = np.stack([np.maximum(np.maximum(a[:, x], b[:, x]), c[:, x]) for x in (u, w)], axis=1)
    origin, extent = lo.min(axis=0), np.maximum(hi.max(axis=0) - lo.min(axis=0), 1e-300)
    g = max(1, int(np.sqrt(len(a)) / 2))  # about four triangles a cell
    size = extent / g

    def cell(x):
        return np.clip(np.floor((x - origin) / size).astype(np.int64), 0, g - 1)

    c0, c1 = cell(lo), cell(hi)
    nu, nw = c1[:, 0] - c0[:, 0] + 1, c1[:, 1] - c0[:, 1] + 1
    n = nu * nw
    tri = np.repeat(np.arange(len(a)), n)
    j = np.arange(n.sum()) - np.repeat(np.cumsum(n) - n, n)
    iu, iw = c0[tri, 0] + j // np.repeat(nw, n), c0[tri, 1] + j % np.repeat(nw, n)
    key = iu * g + iw
    order = np.argsort(key, kind="stable")
    tri, key = tri[order], key[order]
    start = np.searchsorted(key, np.arange(g * g + 1))

    def pairs(pts):
        q = cell(np.stack([pts[:, u], pts[:, w]], axis=1))
        k = q[:, 0] * g + q[:, 1]
        m = start[k + 1] - start[k]
        pt = np.repeat(np.arange(len(pts)), m)
        t = tri[np.repeat(start[k], m) + np.arange(m.sum()) - np.repeat(np.cumsum(m) - m, m)]
        return pt, t

    return pairs


def ray_winding(points, vertices, faces) -> tuple[np.ndarray, np.ndarray]:
    """The body's winding number at ``points`` by a ray's signed crossings, as ``_collide.c``'s winding_at: the six
    axis directions, the shortest way out of the root box first, until one does not graze.  Every triangle whose box
    the ray meets is tested (found on a uniform grid across the ray's axis: the slow reference, without the kernel's
    tree).  0 outside a closed mesh, 1 inside, 2 where two parts overlap.

    Shapes:
        points: (P, 3) -> winding (P,) int64 and decided (P,) bool (False: all six rays grazed, or the mesh is not
        closed)
    """
    v = np.asarray(vertices, np.float64)
    f = np.asarray(faces, np.int64)
    if not _closed(f):
        n = len(np.asarray(points).reshape(-1, 3))
        return np.zeros(n, np.int64), np.zeros(n, bool)
    a, b, c = v[f[:, 0]], v[f[:, 1]], v[f[:, 2]]
    box = _root_box(v, f)
    pts = np.asarray(points, np.float64).reshape(-1, 3)
    wind = np.zeros(len(pts), np.int64)
    decided = np.zeros(len(pts), bool)
    grids: dict = {}
    # each point's six directions (+x, -x, +y, -y, +z, -z), the shortest way out first (ties: that order)
    dist = np.stack([box[3:] - pts, pts - box[:3]], axis=2).reshape(-1, 6)
    order = np.argsort(dist, axis=1, kind="stable")
    for tried in range(6):
        for k in range(6):
            i = np.flatnonzero(~decided & (order[:, tried] == k))
            if not len(i):
                continue
            axis = k // 2
            if axis not in grids:
                grids[axis] = _column_grid(a, b, c, axis)
            pt, t = grids[axis](pts[i])
            cross, graze = _ray_count(pts[i][pt], a[t], b[t], c[t], axis, -1 if k % 2 else 1)
            w = np.bincount(pt, weights=cross, minlength=len(i)).astype(np.int64)
            g = np.bincount(pt, weights=graze, minlength=len(i)) > 0
            wind[i[~g]], decided[i[~g]] = np.abs(w[~g]), True
    return wind, decided


def nearest_unburied(point, vertices, faces, *, batch: int = 64, winding=None, bound: float | None = None):
    """The nearest point to ``point (3,)`` over the faces whose own nearest point to it is not buried (the point
    ``BURY`` * scale out from it along the face's normal is inside the body by its winding number; undecided: not
    buried), as ``_collide.c``'s nearest_open: the minimum of (squared distance, face index) over them, by brute
    force (the faces tried nearest first, in batches that double; a face of zero area is never taken; after
    ``BURY_TRIES`` faces, None: the point keeps its closest surface), among the faces within ``bound`` (default
    ``PINCH`` times the body's size, the rule's; None when none of them is open: a point pinched deeper keeps its
    closest surface).  ``winding(points (K, 3)) -> (wind, decided)``:
    how the winding number is found (default :func:`ray_winding`, brute force).  Returns (face, closest (3,),
    barycentric weights (3,), squared distance), or None when every face's point is buried."""
    v = np.asarray(vertices, np.float64)
    f = np.asarray(faces, np.int64)
    p = np.asarray(point, np.float64)
    cp, bary = closest_point_on_triangles(p[None], v[f[:, 0]], v[f[:, 1]], v[f[:, 2]])
    d2 = ((cp - p) ** 2).sum(axis=1)
    order = np.lexsort((np.arange(len(f)), d2))
    size = body_size(v, f)
    h = BURY * size
    cr = face_cross(v, f)
    n = cr / np.maximum(np.linalg.norm(cr, axis=1), 1e-300)[:, None]
    winding = winding if winding is not None else (lambda q: ray_winding(q, v, f))
    lim = PINCH * size if bound is None else float(bound)
    order = order[d2[order] <= lim * lim]  # deeper in a crease: pinched (the kernel's ub * ub)
    order = order[:BURY_TRIES]  # past that many faces tested the point keeps its closest surface
    lo = 0
    while lo < len(order):  # the nearest first, in batches that double
        g = order[lo : lo + batch]
        wind, decided = winding(cp[g] + h * n[g])
        # a face of zero area is never taken (its edges are its neighbours')
        open_ = ~(decided & (wind != 0)) & np.any(n[g] != 0, axis=1)
        if open_.any():
            k = g[np.argmax(open_)]
            return int(k), cp[k], bary[k], float(d2[k])
        lo, batch = lo + batch, 2 * batch
    return None


def unbury(points, signed_distance, vertices, faces, *, winding=None, bound: float | None = None):
    """The points that the closest feature's side calls outside (``signed_distance`` > ``BURY`` * scale) but
    the body's winding number calls inside -- in the torso next to the skin of an arm buried in it -- and the
    nearest point of each that is not buried (:func:`nearest_unburied`), for those that have one within ``bound``
    (default ``PINCH`` times the body's size, the push-out's; ``inf`` for the cloth stage's backstop traces, which ask
    only whether a point is still inside): ``_collide.c``'s rule for them.

    Shapes:
        points: (P, 3), signed_distance (P,) -> indices (K,), face (K,), closest (K, 3), bary (K, 3), distance (K,)

    ``winding(points (K, 3)) -> (wind, decided)``: how the winding number is found (default :func:`ray_winding`,
    brute force; the numpy collider passes its tree's).
    """
    v = np.asarray(vertices, np.float64)
    p = np.asarray(points, np.float64)
    h = BURY * body_size(v, faces)
    cand = np.flatnonzero(np.asarray(signed_distance) > h)
    out: tuple[list, list, list, list, list] = ([], [], [], [], [])
    if len(cand):
        wind, decided = ray_winding(p[cand], v, faces) if winding is None else winding(p[cand])
        for i in cand[decided & (wind != 0)]:
            r = nearest_unburied(p[i], v, faces, winding=winding, bound=bound)
            if r is not None:
                for lst, x in zip(out, (i, r[0], r[1], r[2], np.sqrt(r[3])), strict=True):
                    lst.append(x)
    idx, face, closest, bary, dist = out
    return (
        np.asarray(idx, np.int64),
        np.asarray(face, np.int64),
        np.asarray(closest, np.float64).reshape(-1, 3),
        np.asarray(bary, np.float64).reshape(-1, 3),
        np.asarray(dist, np.float64),
    )


class BodyProxy:
    """Proximity queries against a closed body mesh (see the module docstring).

    Args:
        vertices: (V, 3) posed body vertices
        faces: (F, 3) outward-facing triangles
        k: nearest-centroid candidates per query
    """

    def __init__(self, vertices, faces, *, k: int = 8, _topology: dict | None = None) -> None:
        v, f = check_mesh(vertices, faces)
        self.vertices, self.faces, self.k = v, f, int(k)
        self._topo = _topology if _topology is not None else self._build_topology(f, len(v))
        t = self._topo
        cr = face_cross(v, f)
        area2 = np.linalg.norm(cr, axis=1)
        self.face_normals = cr / np.maximum(area2, 1e-300)[:, None]
        # angle-weighted vertex pseudo-normals
        ang = np.empty((len(f), 3))
        for c in range(3):
            e1 = v[f[:, (c + 1) % 3]] - v[f[:, c]]
            e2 = v[f[:, (c + 2) % 3]] - v[f[:, c]]
            cosang = np.einsum("ij,ij->i", e1, e2) / np.maximum(
                np.linalg.norm(e1, axis=1) * np.linalg.norm(e2, axis=1), 1e-300
            )
            ang[:, c] = np.arccos(np.clip(cosang, -1, 1))
        contrib = (ang[:, :, None] * self.face_normals[:, None, :]).reshape(-1, 3)  # (3F, 3) per corner
        vn = t["corner_to_vertex"] @ contrib
        self.vertex_normals = vn / np.maximum(np.linalg.norm(vn, axis=1), 1e-300)[:, None]
        # edge pseudo-normals: sum of the (up to two) adjacent face normals, per face edge slot
        en = t["slot_to_edge"] @ np.repeat(self.face_normals, 3, axis=0)  # (E, 3)
        self.edge_normals = en[t["edge_of_slot"]].reshape(len(f), 3, 3)
        self.edge_normals /= np.maximum(np.linalg.norm(self.edge_normals, axis=2), 1e-300)[..., None]
        # unbalanced, uncompacted trees build several times faster; queries barely change
        self._tree = cKDTree(v[f].mean(axis=1), balanced_tree=False, compact_nodes=False)
        self._vtree = cKDTree(v, balanced_tree=False, compact_nodes=False)
        self._vf_faces, self._vf_ptr, self._max_valence = t["vf_faces"], t["vf_ptr"], t["max_valence"]

    @staticmethod
    def _build_topology(f: np.ndarray, nv: int) -> dict:
        """Everything that depends on the faces only (reused across frames by :meth:`moved`)."""
        import scipy.sparse as sp

        nf = len(f)
        corner_to_vertex = sp.csr_matrix((np.ones(3 * nf), (f.ravel(), np.arange(3 * nf))), shape=(nv, 3 * nf))
        e = np.sort(np.stack([f[:, [1, 2]], f[:, [2, 0]], f[:, [0, 1]]], axis=1), axis=2)  # edge opposite corner c
        key = e[..., 0] * (np.int64(nv) + 1) + e[..., 1]
        uk, inv = np.unique(key.ravel(), return_inverse=True)
        inv = inv.ravel()
        slot_to_edge = sp.csr_matrix((np.ones(3 * nf), (inv, np.arange(3 * nf))), shape=(len(uk), 3 * nf))
        order = np.argsort(f.ravel(), kind="stable")
        vf_ptr = np.concatenate([[0], np.cumsum(np.bincount(f.ravel(), minlength=nv))])
        return {
            "corner_to_vertex": corner_to_vertex,
            "slot_to_edge": slot_to_edge,
            "edge_of_slot": inv,
            "vf_faces": order // 3,
            "vf_ptr": vf_ptr,
            "max_valence": int(np.diff(vf_ptr).max()),
        }

    def moved(self, vertices) -> BodyProxy:
        """The same body surface at new vertex positions (topology reused: cheaper per frame)."""
        return BodyProxy(vertices, self.faces, k=self.k, _topology=self._topo)

    def feature_normals(self, face, bary) -> np.ndarray:
        """The pseudo-normal of the feature -- face interior, edge or vertex -- that barycentric weights ``bary``
        on ``face`` point at.  Shapes: face (K,), bary (K, 3) -> (K, 3)"""
        face, b = np.asarray(face, np.int64), np.asarray(bary, np.float64).reshape(-1, 3)
        nz = b > 1e-9
        count = nz.sum(axis=1)
        normal = self.face_normals[face].copy()
        edge = count == 2
        if edge.any():
            opp = np.argmin(b[edge], axis=1)  # the corner with ~0 weight is opposite the edge
            normal[edge] = self.edge_normals[face[edge], opp]
        vert = count <= 1
        if vert.any():
            corner = np.argmax(b[vert], axis=1)
            normal[vert] = self.vertex_normals[self.faces[face[vert], corner]]
        return normal

    def query(self, points) -> ProximityResult:
        """Signed distance (negative inside), closest point, outward normal for ``points (P, 3)``."""
        p = np.asarray(points, np.float64)
        if p.ndim != 2 or p.shape[1] != 3:
            raise InputError("points must be (P, 3)", got=p.shape)
        if not np.isfinite(p).all():
            raise InputError("points contain NaN or inf")
        k = min(self.k, len(self.faces))
        _, cand = self._tree.query(p, k=k)
        cand = np.asarray(cand).reshape(len(p), k)
        _, nv = self._vtree.query(p)
        lo, hi = self._vf_ptr[nv], self._vf_ptr[nv + 1]
        ring = np.full((len(p), self._max_valence), -1, np.int64)
        idx = lo[:, None] + np.arange(self._max_valence)[None, :]
        ok = idx < hi[:, None]
        ring[ok] = self._vf_faces[idx[ok]]
        ring = np.where(ring < 0, cand[:, :1], ring)
        cand = np.concatenate([cand, ring], axis=1)
        tri = self.vertices[self.faces[cand]]  # (P, C, 3, 3)
        cp, bary = closest_point_on_triangles(p[:, None, :], tri[..., 0, :], tri[..., 1, :], tri[..., 2, :])
        d2 = np.sum((cp - p[:, None, :]) ** 2, axis=-1)
        best = np.argmin(d2, axis=1)
        r = np.arange(len(p))
        face = cand[r, best]
        closest = cp[r, best]
        b = bary[r, best]
        normal = self.feature_normals(face, b)
        diff = p - closest
        dist = np.linalg.norm(diff, axis=1)
        sign = np.where(np.einsum("ij,ij->i", diff, normal) < 0, -1.0, 1.0)
        return ProximityResult(signed_distance=sign * dist, closest=closest, normal=normal, face=face)


def carry_correction(before, after, carry, size: float, push) -> np.ndarray:
    """The rule for the correction carried from the frame before (``_collide.c``'s carry_point), point by point.

    ``before`` are the points before this frame's push-out, ``after`` after it, ``carry`` each point's correction
    (after minus before) of the frame before, zero for none; ``push(points (M, 3)) -> (M, 3)`` is this frame's
    push-out.  Where a point's correction ``k = after - before`` differs from its carried ``k0`` by more than
    ``lim = PINCH * size`` (its closest exit is on another side of a limb than the frame before's), the push-out is
    tried again from ``before + k0`` and ``before + k0 / 2``; the exit whose correction is nearest ``k0`` is kept if
    it is nearer than ``k``'s, its move at most ``CARRY_LIMB |k| + lim`` and at most ``|k0| + CARRY_GROW lim`` (ties:
    the earlier candidate).  Every candidate is a push-out's result, so no point is left inside that the push-out
    takes out.  Returns the points after the rule; ``carry`` is set to their correction, in place.

    Shapes:
        before, after, carry: (P, 3) -> (P, 3)
    """
    q = np.asarray(before, np.float64)
    out = np.array(after, np.float64)
    lim = PINCH * float(size)
    for i in range(len(q)):
        k0 = carry[i].copy()
        if not k0.any():
            continue
        k = out[i] - q[i]
        best = float(np.sqrt(np.sum((k - k0) ** 2)))
        if not best > lim:
            continue
        kn, k0n, pick = float(np.sqrt(np.sum(k * k))), float(np.sqrt(np.sum(k0 * k0))), out[i].copy()
        for gain in (1.0, 0.5):
            a = push((q[i] + gain * k0)[None])[0]
            ka = a - q[i]
            d, an = float(np.sqrt(np.sum((ka - k0) ** 2))), float(np.sqrt(np.sum(ka * ka)))
            if d < best and an <= CARRY_LIMB * kn + lim and an <= k0n + CARRY_GROW * lim:
                best, pick = d, a
        out[i] = pick
    carry[...] = out - q
    return out


def push_out(
    points: np.ndarray, proxy: BodyProxy, margin: float = 0.0, *, iterations: int = 3, buried: bool = True
) -> tuple[np.ndarray, int]:
    """Move points that are inside the body, or closer than ``margin`` to it, out along the body normal.

    ``p' = closest + margin * n`` for every point with signed distance below
    ``margin``; others are unchanged.  In concave regions (between the legs,
    under the arms) one move can land inside another part of the body, so the
    points still violating are moved again, up to ``iterations`` passes.
    Where the posed body penetrates itself (an arm pressed into the torso), a
    point inside the torso whose closest surface is the arm's buried skin is
    found by the body's winding number and moved to the nearest skin that is
    not buried (:func:`unbury`), never onto the buried one, when that skin is
    within ``PINCH`` times the body's size (deeper, it stays pinched; ``buried=False``:
    the closest surface alone, the rule before 30 Nov 2026, which the garment
    placement of ``dataset make`` keeps).  Where two body
    surfaces are closer than ``2 margin`` no point satisfies both.  A
    point exactly on the surface has a finite unit normal (see
    :class:`BodyProxy`), so it moves to ``margin`` along it, never to NaN.
    Vectorised over points.

    Shapes:
        points: (P, 3) -> (P, 3), and the number of points moved
    """
    out = np.array(points, dtype=np.float64)
    moved = np.zeros(len(out), bool)
    idx = np.arange(len(out))
    for _ in range(max(1, int(iterations))):
        r = proxy.query(out[idx])
        sd, closest, normal = r.signed_distance.copy(), r.closest.copy(), r.normal.copy()
        if buried:
            k, face, c, bary, dist = unbury(out[idx], sd, proxy.vertices, proxy.faces)
            sd[k], closest[k], normal[k] = -dist, c, proxy.feature_normals(face, bary)
        r = ProximityResult(signed_distance=sd, closest=closest, normal=normal, face=r.face)
        hit = r.signed_distance < margin
        if not hit.any():
            break
        out[idx[hit]] = r.closest[hit] + margin * r.normal[hit]
        moved[idx[hit]] = True
        idx = idx[hit]
    return out, int(moved.sum())
