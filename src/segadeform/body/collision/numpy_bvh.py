"""The numpy backend of the body collider: a bounding-volume hierarchy over the triangles, built once and refitted
to each posed frame, walked for all points together (see :class:`segadeform.body.collision.BodyCollider`)."""

from __future__ import annotations

import dataclasses

import numpy as np

from .reference import BURY, ProximityResult, nearest_unburied

__all__ = ["NumpyBVH", "closest_point_fast"]


def _dot(x, y):
    """Row-wise dot product of (3, K) arrays -> (K,)."""
    return x[0] * y[0] + x[1] * y[1] + x[2] * y[2]


def _cross(x, y):
    """Cross product of (3, K) arrays -> (3, K)."""
    return np.stack([x[1] * y[2] - x[2] * y[1], x[2] * y[0] - x[0] * y[2], x[0] * y[1] - x[1] * y[0]])


def _closest_soa(p, a, b, c):
    """Closest point on triangles ``abc`` to ``p`` with its barycentric weights: the projection onto the
    plane when it falls inside the triangle, else the nearest point of the three edges.

    Shapes:
        p, a, b, c: (3, K) -> closest (3, K), bary (3, K)
    """
    ab, ac, ap = b - a, c - a, p - a
    d00, d01, d11 = _dot(ab, ab), _dot(ab, ac), _dot(ac, ac)
    d20, d21 = _dot(ap, ab), _dot(ap, ac)
    den = d00 * d11 - d01 * d01
    ok = den > 1e-300
    inv = np.where(ok, 1.0 / np.where(ok, den, 1.0), 0.0)
    v = (d11 * d20 - d01 * d21) * inv
    w = (d00 * d21 - d01 * d20) * inv
    u = 1.0 - v - w
    inside = ok & (u >= 0) & (v >= 0) & (w >= 0)
    # the three edges: parameter t along ab, ac and bc, and the squared distance (only to pick one)
    tiny = 1e-300
    dbc = d00 + d11 - 2.0 * d01
    pbc = d21 - d20 - d01 + d00  # (p - b) . (c - b)
    t_ab = np.clip(d20 / np.maximum(d00, tiny), 0.0, 1.0)
    t_ac = np.clip(d21 / np.maximum(d11, tiny), 0.0, 1.0)
    t_bc = np.clip(pbc / np.maximum(dbc, tiny), 0.0, 1.0)
    s_ab = t_ab * (t_ab * d00 - 2.0 * d20)  # |ap - t ab|^2 - |ap|^2
    s_ac = t_ac * (t_ac * d11 - 2.0 * d21)
    s_bc = t_bc * (t_bc * dbc - 2.0 * pbc) + d00 - 2.0 * d20  # |p - b - t bc|^2 - |ap|^2
    use_ac = s_ac < s_ab
    use_bc = s_bc < np.minimum(s_ab, s_ac)
    eu = np.where(use_bc, 0.0, np.where(use_ac, 1.0 - t_ac, 1.0 - t_ab))
    ev = np.where(use_bc, 1.0 - t_bc, np.where(use_ac, 0.0, t_ab))
    ew = np.where(use_bc, t_bc, np.where(use_ac, t_ac, 0.0))
    u, v, w = np.where(inside, u, eu), np.where(inside, v, ev), np.where(inside, w, ew)
    return a + v * ab + w * ac, np.stack([u, v, w])


def closest_point_fast(p, a, b, c):
    """The same closest point and barycentric weights as :func:`closest_point_on_triangles` (the slow,
    obvious reference beside it, compared in the tests), by another route: the projection onto the
    plane when it falls inside the triangle, else the nearest of the three edges (:func:`_closest_soa`).

    Shapes:
        p, a, b, c: (..., 3) -> closest (..., 3), bary (..., 3)
    """
    p, a, b, c = np.broadcast_arrays(*(np.asarray(x, np.float64) for x in (p, a, b, c)))
    shape = p.shape
    p, a, b, c = (np.ascontiguousarray(x.reshape(-1, 3).T) for x in (p, a, b, c))
    closest, bary = _closest_soa(p, a, b, c)
    return closest.T.reshape(shape), bary.T.reshape(shape)


def _spread_bits(x):
    """Spread the low 10 bits of ``x`` (int64) to every third bit (Morton codes)."""
    x = x & 0x3FF
    x = (x | (x << 16)) & 0x030000FF
    x = (x | (x << 8)) & 0x0300F00F
    x = (x | (x << 4)) & 0x030C30C3
    return (x | (x << 2)) & 0x09249249


def _build_bvh(vertices, faces, leaf_size: int):
    """A complete binary tree over the faces, built once from one pose of the body: level ``l`` has
    ``2**l`` nodes and node ``i`` has the children ``2i`` and ``2i + 1``; each node's faces are split at
    the median of their centroids along the node's longest axis.  Only the topology is kept: the boxes
    are recomputed from the posed vertices every frame (:meth:`BodyCollider._frames`), so the tree is
    valid for any pose; only its tightness depends on the pose it was built in.

    Shapes:
        vertices: (V, 3), faces: (F, 3) -> depth, leaf faces (L, w) padded with the leaf's first face,
        their validity mask (L, w), and every leaf's vertices, one after another, with where each leaf's
        start (T,), (L,); L = 2**depth
    """
    c = vertices[faces].mean(axis=1)
    nf = len(faces)
    depth = max(0, int(np.ceil(np.log2(max(nf / leaf_size, 1.0)))))
    order = np.arange(nf)
    for level in range(depth):
        n = 2**level
        bounds = (np.arange(n + 1) * nf) // n  # node i holds order[bounds[i]:bounds[i + 1]]
        cc = c[order]
        lo = np.minimum.reduceat(cc, bounds[:-1], axis=0)
        hi = np.maximum.reduceat(cc, bounds[:-1], axis=0)
        axis = np.argmax(hi - lo, axis=1)
        key = cc[np.arange(nf), np.repeat(axis, np.diff(bounds))]
        slot = bounds[:-1, None] + np.arange(int(np.diff(bounds).max()))[None, :]  # (n, w) one row per node
        valid = slot < bounds[1:, None]
        rows = np.argsort(np.where(valid, key[np.minimum(slot, nf - 1)], np.inf), axis=1)
        order = order[(bounds[:-1, None] + rows)[valid]]  # padding sorts last, so `valid` keeps each row's faces
    n = 2**depth
    bounds = (np.arange(n + 1) * nf) // n  # every leaf holds at least one face (n <= nf)
    width = int(np.diff(bounds).max())
    slot = bounds[:-1, None] + np.arange(width)[None, :]
    valid = slot < bounds[1:, None]
    leaf_faces = order[np.where(valid, slot, bounds[:-1, None])]
    lv = np.sort(np.where(np.repeat(valid, 3, axis=1), faces[leaf_faces].reshape(n, -1), -1), axis=1)
    lv[:, 1:][lv[:, 1:] == lv[:, :-1]] = -1
    keep = lv >= 0
    starts = np.concatenate([[0], np.cumsum(keep.sum(axis=1))[:-1]])
    return depth, leaf_faces, valid, (lv[keep], starts)


def _group_starts(pt):
    """First index of each run of equal values in the sorted ``pt (M,)``."""
    return np.flatnonzero(np.concatenate([[True], pt[1:] != pt[:-1]]))


@dataclasses.dataclass
class _Frames:
    """Per-call data of ``B`` stacked frames: vertices (3, B * V) (frame b's vertex i is column b V + i),
    node boxes per tree level (lists of float32 (3, B * 2**l), grown by ``slack``), each frame's centre
    (3, B), the long axis and the largest extent."""

    verts: np.ndarray
    lo: list
    hi: list
    centre: np.ndarray
    axis: int
    scale: float
    slack: float


class NumpyBVH:
    """The ``"numpy"`` backend of :class:`~segadeform.body.collision.BodyCollider` (see its docstring for the
    algorithm): the tree, adjacency and gathers of one body topology, and the vectorised walks."""

    def __init__(self, v, f, leaf_size: int, step: int) -> None:
        """The tree, adjacency and gathers of the body ``v (V, 3)``, ``f (F, 3)``."""
        self.faces, self.n_vertices = f, len(v)
        self._used = np.unique(f)  # the vertices the faces use: the root box's
        nv = np.int64(len(v)) + 1
        # per face slot (edge opposite corner c): the face across that edge, -1 on a boundary
        e = np.sort(np.stack([f[:, [1, 2]], f[:, [2, 0]], f[:, [0, 1]]], axis=1), axis=2).reshape(-1, 2)
        key = e[:, 0] * nv + e[:, 1]
        order = np.argsort(key, kind="stable")
        ks = key[order]
        other = np.full(len(key), -1, np.int64)
        same = ks[1:] == ks[:-1]
        i0, i1 = order[:-1][same], order[1:][same]
        other[i0], other[i1] = i1 // 3, i0 // 3
        self._across = other.reshape(len(f), 3)
        # closed: every edge has exactly two faces, which run along it in opposite directions
        start = np.stack([f[:, 1], f[:, 2], f[:, 0]], axis=1).ravel()  # where each slot's edge starts
        triple = (ks[2:] == ks[:-2]).any() if len(ks) > 2 else False
        self.closed = bool((other >= 0).all() and not triple and (start[i0] != start[i1]).all())
        # the faces around each vertex, -1 padded (vertex pseudo-normals)
        count = np.bincount(f.ravel(), minlength=len(v))
        ptr = np.concatenate([[0], np.cumsum(count)])
        vf = np.argsort(f.ravel(), kind="stable") // 3
        fan = np.full((len(v), max(1, int(count.max()))), -1, np.int64)
        fan[np.repeat(np.arange(len(v)), count), np.arange(len(vf)) - np.repeat(ptr[:-1], count)] = vf
        self._fan = fan
        self.depth, self._leaf_faces, self._leaf_valid, (ids, starts) = _build_bvh(v, f, leaf_size)
        # each leaf's vertices as a dense block of the first `w` (padded with its first vertex) and, for the
        # leaves with more, an overflow block: fewer gathers than padding every leaf to the largest
        count = np.diff(np.append(starts, len(ids)))
        n_leaf, u = len(starts), int(count.max())
        w = min(range(1, u + 1), key=lambda w: w * n_leaf + (u - w) * int((count > w).sum()))
        col = lambda j, rows: ids[starts[rows] + np.minimum(j, count[rows] - 1)]  # noqa: E731
        every = np.arange(n_leaf)
        self._over = np.flatnonzero(count > w)
        self._dense = np.stack([col(j, every) for j in range(w)])  # (w, L)
        self._overflow = np.stack([col(j, self._over) for j in range(w, u)]) if u > w else np.zeros((0, 0), int)
        self._gather: dict = {}  # per number of frames: the stacked-frame columns of both blocks
        self._levels = list(range(self.depth % step, self.depth + 1, step))
        if self._levels[0]:
            self._levels.insert(0, 0)
        self.chunk = 8192  # points per walk
        self.group = 16  # points per run in the top of the walks
        self._split = min(3, len(self._levels) - 1)  # the walks follow runs of points down to _levels[_split]

    # ---- per call -----------------------------------------------------------------------------------
    def _frames(self, posed) -> _Frames:
        """Stack the frames ``posed (B, V, 3)`` and fit the tree's boxes to them."""
        nb, nv = posed.shape[:2]
        verts = np.ascontiguousarray(posed.transpose(2, 0, 1)).reshape(3, nb * nv)
        if nb not in self._gather:
            base = np.arange(nb) * nv
            n_leaf = self._dense.shape[1]
            self._gather[nb] = (
                (self._dense[:, None, :] + base[None, :, None]).reshape(len(self._dense), -1),
                (self._overflow[:, None, :] + base[None, :, None]).reshape(len(self._overflow), -1),
                ((np.arange(nb) * n_leaf)[:, None] + self._over).ravel(),
            )
        dense, over, at = self._gather[nb]
        lo, hi = np.empty((3, dense.shape[1])), np.empty((3, dense.shape[1]))
        for k in range(3):  # leaf boxes, one axis at a time from contiguous rows
            x = np.take(verts[k], dense)
            lo[k], hi[k] = x.min(axis=0), x.max(axis=0)
            if over.size:
                y = np.take(verts[k], over)
                lo[k, at], hi[k, at] = np.minimum(lo[k, at], y.min(axis=0)), np.maximum(hi[k, at], y.max(axis=0))
        los, his = [lo], [hi]
        for _ in range(self.depth):
            lo, hi = np.minimum(lo[:, 0::2], lo[:, 1::2]), np.maximum(hi[:, 0::2], hi[:, 1::2])
            los.append(lo)
            his.append(hi)
        ext = verts.max(axis=1) - verts.min(axis=1)
        scale = float(ext.max())
        # the walks run in float32 on boxes grown by `slack`, far above float32 rounding at this scale, so
        # they keep every box the float64 test would; the triangles themselves are measured in float64
        slack = 1e-5 * max(scale, float(np.abs(verts).max()), 1e-30)
        lo32 = [(x - slack).astype(np.float32) for x in los[::-1]]
        hi32 = [(x + slack).astype(np.float32) for x in his[::-1]]
        return _Frames(
            verts=verts,
            lo=lo32,
            hi=hi32,
            centre=verts.reshape(3, nb, nv).mean(axis=2),
            axis=int(np.argmax(ext)),
            scale=scale,
            slack=slack,
        )

    def _descend(self, pt, nd, level):
        """The children of the nodes ``nd`` at ``level`` on the next level walked, paired with ``pt``."""
        step = self._levels[self._levels.index(level) + 1] - level
        k = 2**step
        return np.repeat(pt, k), ((nd[:, None] << step) | np.arange(k, dtype=nd.dtype)).ravel()

    def _groups(self, P, frame):
        """Runs of up to ``self.group`` points close together (Morton order of their cells, frame by frame).

        ``P (3, M)`` float32.  Returns the order (M,), where each run starts in it (R,), each run's frame
        and the box of its points (3, R) twice."""
        lo, ext = P.min(axis=1, keepdims=True), np.maximum(np.ptp(P, axis=1).max(), 1e-30)
        q = np.clip(((P - lo) * (1023.0 / ext)).astype(np.int64), 0, 1023)
        code = (
            (np.asarray(frame, np.int64) << 30)
            | (_spread_bits(q[0]) << 2)
            | (_spread_bits(q[1]) << 1)
            | _spread_bits(q[2])
        )
        order = np.argsort(code, kind="stable")
        f = np.asarray(frame)[order]
        first = np.flatnonzero(np.concatenate([[True], f[1:] != f[:-1]]))  # where each frame's points start
        pos = np.arange(len(order)) - np.repeat(first, np.diff(np.append(first, len(order))))
        starts = np.flatnonzero(pos % self.group == 0)
        Ps = np.take(P, order, axis=1)
        return (
            order,
            starts,
            f[starts],
            np.minimum.reduceat(Ps, starts, axis=1),
            np.maximum.reduceat(Ps, starts, axis=1),
        )

    def _seed(self, fr: _Frames, order, starts, run_frame, keep):
        """Walk the top of the tree with the runs of :meth:`_groups` instead of single points:
        ``keep(level, run, node) -> bool`` must hold for a run wherever it holds for one of its points.
        Returns (point, node) pairs at level ``self._levels[self._split]``, grouped by point."""
        run, nd = np.arange(len(starts), dtype=np.int32), np.asarray(run_frame, np.int32)
        prev = 0
        for level in self._levels[: self._split + 1]:
            if level:
                run, nd = self._descend(run, nd, prev)
            prev = level
            k = keep(level, run, nd)
            run, nd = run[k], nd[k]
        if not len(run):  # every run's rays (or boxes) miss the body
            return np.zeros(0, np.int32), np.zeros(0, np.int32)
        # every point of a run with every node kept for the run, point after point
        size = np.diff(np.append(starts, len(order)))
        g = _group_starts(run)  # the runs' node lists, one after another
        n_nodes = np.diff(np.append(g, len(run)))
        runs = run[g]
        block = size[runs] * n_nodes
        total = int(block.sum())
        j = np.arange(total) - np.repeat(np.cumsum(block) - block, block)
        per = np.repeat(n_nodes, block)
        pt = order[np.repeat(starts[runs], block) + j // per].astype(np.int32)
        return pt, nd[np.repeat(g, block) + j % per]

    def _leaves_near(self, fr: _Frames, P, frame, ub2):
        """Branch and bound: pairs (point, leaf column) whose box is within the point's radius.

        ``P (3, M)`` float32 points, ``frame (M,)`` their frames, ``ub2 (M,)`` squared radius (inf: none,
        then the radius shrinks to the farthest corner of the nearest box of each level walked: a surface
        point lies within it).  Returns point indices, leaf columns (grouped by point) and their squared
        box distances (float32, boxes grown by ``fr.slack``)."""
        s = fr.slack
        ub2 = ((np.sqrt(np.asarray(ub2, np.float64)) + s) ** 2).astype(np.float32)
        shrink = bool(np.isinf(ub2).any())
        levels = self._levels
        if P.shape[1] >= 4 * self.group and self._split:
            order, starts, run_frame, rlo, rhi = self._groups(P, frame)
            rub2 = np.maximum.reduceat(ub2[order], starts)

            def keep(level, run, nd):  # the gap between the run's box and the node's
                gap = np.maximum(
                    np.maximum(
                        np.take(fr.lo[level], nd, axis=1) - np.take(rhi, run, axis=1),
                        np.take(rlo, run, axis=1) - np.take(fr.hi[level], nd, axis=1),
                    ),
                    0.0,
                )
                return _dot(gap, gap) <= rub2[run]

            pt, nd = self._seed(fr, order, starts, run_frame, keep)
            levels = levels[self._split :]
        else:
            pt, nd = np.arange(P.shape[1], dtype=np.int32), np.asarray(frame, np.int32)
        prev = levels[0]
        for level in levels:
            if level != prev:
                pt, nd = self._descend(pt, nd, prev)
            prev = level
            q = np.take(P, pt, axis=1)
            a, b = np.take(fr.lo[level], nd, axis=1) - q, q - np.take(fr.hi[level], nd, axis=1)
            d = np.maximum(np.maximum(a, b), 0.0)
            lb2 = _dot(d, d)
            if shrink:
                c = np.maximum(np.abs(a), np.abs(b))
                g = _group_starts(pt)
                ps = pt[g]
                ub2[ps] = np.minimum(ub2[ps], (np.sqrt(np.minimum.reduceat(_dot(c, c), g)) + s) ** 2)
            keep = lb2 <= ub2[pt]
            pt, nd, lb2 = pt[keep], nd[keep], lb2[keep]
            if not len(pt):
                break
        return pt, nd, lb2

    def _leaf_pairs(self, fr: _Frames, pt, leaf, frame):
        """(point, face) pairs of the (point, leaf column) pairs, and each face's three vertex columns."""
        nleaf = self._leaf_faces.shape[0]
        lf = leaf % nleaf
        valid = self._leaf_valid[lf]
        face = self._leaf_faces[lf][valid]
        pt = np.broadcast_to(pt[:, None], valid.shape)[valid]
        cols = self.faces[face] + (frame[pt] * self.n_vertices)[:, None]  # (K, 3)
        return pt, face, cols

    def _closest(self, fr: _Frames, P, frame, ub2, *, tighten: bool = False):
        """Exact closest point for the points of ``P (3, M)`` with a triangle within ``sqrt(ub2)``;
        ``tighten`` when the radii are loose (measure each point's nearest box first, then only the boxes
        within that).

        Returns (indices of the points found, closest (3, K), face (K,), bary (3, K), squared distance)."""
        pt, leaf, lb2 = self._leaves_near(fr, P.astype(np.float32), frame, ub2)
        if not len(pt):
            return pt, np.zeros((3, 0)), pt, np.zeros((3, 0)), np.zeros(0)
        if tighten:
            # the triangles of each point's nearest box give a tight radius, and only the boxes within it
            # need their triangles measured
            order = np.lexsort((lb2, pt))
            best = order[_group_starts(pt[order])]  # each point's nearest box
            found, _, _, _, d2 = self._measure(fr, P, frame, pt[best], leaf[best])
            tight = np.zeros(P.shape[1])
            tight[found] = (np.sqrt(d2) + fr.slack) ** 2
            keep = lb2 <= tight[pt]
            pt, leaf = pt[keep], leaf[keep]
        return self._measure(fr, P, frame, pt, leaf)

    def _measure(self, fr: _Frames, P, frame, pt, leaf):
        """The nearest point on the triangles of the leaves paired with each point (pairs grouped by point).

        Returns (the points, closest (3, K), face (K,), bary (3, K), squared distance (K,))."""
        pt, face, cols = self._leaf_pairs(fr, pt, leaf, frame)
        q = np.take(P, pt, axis=1)
        a, b, c = (np.take(fr.verts, cols[:, k], axis=1) for k in range(3))
        x, bary = _closest_soa(q, a, b, c)
        diff = x - q
        d2 = _dot(diff, diff)
        order = np.lexsort((d2, pt))
        first = order[_group_starts(pt[order])]
        return pt[first], x[:, first], face[first], bary[:, first], d2[first]

    def _winding(self, fr: _Frames, P, frame, centre):
        """Signed count of the crossings of a ray from each point of ``P (3, M)`` (direction: away from
        ``centre (3, B)`` of its frame, mostly across the body's long axis) with the surface: 0 outside a
        closed mesh, 1 inside, more where the posed body overlaps itself; whether the ray grazed an edge or
        a vertex or started on a triangle (the count is then unreliable); and where along the ray it first
        meets the surface (inf: nowhere), a bound on the distance to the surface."""

        def direction(x, f):
            d = x - np.take(centre, f, axis=1)
            d[fr.axis] *= 0.25  # sideways: fewer boxes on the way
            n = np.sqrt(_dot(d, d))
            d = np.where(n > 1e-9, d / np.maximum(n, 1e-300), np.array([[0.6], [0.48], [0.64]]))
            return np.where(np.abs(d) < 1e-6, np.where(d < 0, -1e-6, 1e-6), d)  # no zero component: finite 1/d

        P32 = P.astype(np.float32)  # the walk in float32 on boxes grown by fr.slack: see _frames
        levels = self._levels
        if P.shape[1] >= 4 * self.group and self._split:
            # a run of nearby points casts parallel rays (any direction will do): the rays from its box hit
            # the node's box only if the ray from its centre hits the node's box grown by the run's box
            order, starts, run_frame, rlo, rhi = self._groups(P32, frame)
            rc, rh = 0.5 * (rlo + rhi), 0.5 * (rhi - rlo)
            rd = direction(rc.astype(np.float64), run_frame)
            rinv = (1.0 / rd).astype(np.float32)
            d = np.empty_like(P)
            d[:, order] = np.repeat(rd, np.diff(np.append(starts, P.shape[1])), axis=1)

            def keep(level, run, nd):
                o, iv, h = np.take(rc, run, axis=1), np.take(rinv, run, axis=1), np.take(rh, run, axis=1)
                t1 = (np.take(fr.lo[level], nd, axis=1) - h - o) * iv
                t2 = (np.take(fr.hi[level], nd, axis=1) + h - o) * iv
                near_end, far_end = np.minimum(t1, t2), np.maximum(t1, t2)
                t_in = np.maximum(np.maximum(near_end[0], near_end[1]), np.maximum(near_end[2], 0.0))
                return np.minimum(np.minimum(far_end[0], far_end[1]), far_end[2]) >= t_in

            pt, nd = self._seed(fr, order, starts, run_frame, keep)
            levels = levels[self._split :]
        else:
            d = direction(P, frame)
            pt, nd = np.arange(P.shape[1], dtype=np.int32), np.asarray(frame, np.int32)
        inv = (1.0 / d).astype(np.float32)
        prev = levels[0]
        for level in levels:
            if level != prev:
                pt, nd = self._descend(pt, nd, prev)
            prev = level
            o, iv = np.take(P32, pt, axis=1), np.take(inv, pt, axis=1)
            t1, t2 = (np.take(fr.lo[level], nd, axis=1) - o) * iv, (np.take(fr.hi[level], nd, axis=1) - o) * iv
            near_end = np.minimum(t1, t2)
            far_end = np.maximum(t1, t2)
            t_in = np.maximum(np.maximum(near_end[0], near_end[1]), np.maximum(near_end[2], 0.0))
            t_out = np.minimum(np.minimum(far_end[0], far_end[1]), far_end[2])
            keep = t_out >= t_in
            pt, nd = pt[keep], nd[keep]
            if not len(pt):
                break
        wind = np.zeros(P.shape[1])
        graze = np.zeros(P.shape[1], bool)
        reach = np.full(P.shape[1], np.inf)
        if not len(pt):
            return wind, graze, reach
        pt, _, cols = self._leaf_pairs(fr, pt, nd, frame)
        o = np.take(P, pt, axis=1)
        A, B, C = (np.take(fr.verts, cols[:, k], axis=1) - o for k in range(3))
        dd = np.take(d, pt, axis=1)
        # edge functions d . (X x Y): the same edge seen from its two faces gives exactly opposite values
        e0, e1, e2 = _dot(dd, _cross(B, C)), _dot(dd, _cross(C, A)), _dot(dd, _cross(A, B))
        s = e0 + e1 + e2  # d . n
        plane = _dot(A, _cross(B - A, C - A))  # (a - o) . n: the hit is at t = plane / s
        hit = (((e0 > 0) & (e1 > 0) & (e2 > 0)) | ((e0 < 0) & (e1 < 0) & (e2 < 0))) & (plane * s > 0)
        closed = ((e0 >= 0) & (e1 >= 0) & (e2 >= 0)) | ((e0 <= 0) & (e1 <= 0) & (e2 <= 0))
        touch = closed & (s != 0) & (plane * s >= 0) & ~hit  # through an edge or a vertex, or from the plane
        wind += np.bincount(pt[hit], weights=np.sign(s[hit]), minlength=P.shape[1])
        graze[pt[touch]] = True
        np.minimum.at(reach, pt[hit], plane[hit] / s[hit])  # how far along the ray it first meets the surface
        return wind, graze, reach

    def _normals(self, verts, face, bary, voff):
        """Pseudo-normal of the closest feature (face, edge or vertex) per point, as :class:`BodyProxy`.

        Shapes:
            verts: (3, B * V) stacked frames; face (K,), bary (3, K), voff (K,) the first column of each
            point's frame -> (K, 3)
        """
        flat = verts.T
        bary = bary.T
        f = self.faces
        tri = flat[f[face] + voff[:, None]]
        fn = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
        fn /= np.maximum(np.linalg.norm(fn, axis=1, keepdims=True), 1e-300)
        count = (bary > 1e-9).sum(axis=1)
        normal = fn.copy()
        edge = count == 2
        if edge.any():
            slot = np.argmin(bary[edge], axis=1)  # the corner with ~0 weight is opposite the edge
            g = self._across[face[edge], slot]
            tg = flat[f[np.maximum(g, 0)] + voff[edge, None]]
            gn = np.cross(tg[:, 1] - tg[:, 0], tg[:, 2] - tg[:, 0])
            gn /= np.maximum(np.linalg.norm(gn, axis=1, keepdims=True), 1e-300)
            gn[g < 0] = 0.0
            en = fn[edge] + gn
            normal[edge] = en / np.maximum(np.linalg.norm(en, axis=1, keepdims=True), 1e-300)
        vert = count <= 1
        if vert.any():
            vid = f[face[vert], np.argmax(bary[vert], axis=1)]
            fan = self._fan[vid]  # (M, valence), -1 padded
            ff = f[np.maximum(fan, 0)]  # (M, valence, 3)
            t = flat[ff + voff[vert, None, None]]
            n = np.cross(t[..., 1, :] - t[..., 0, :], t[..., 2, :] - t[..., 0, :])
            n /= np.maximum(np.linalg.norm(n, axis=-1, keepdims=True), 1e-300)
            corner = np.argmax(ff == vid[:, None, None], axis=-1)  # the vertex's corner in each fan face

            def pick(k):
                return np.take_along_axis(t, ((corner + k) % 3)[..., None, None].repeat(3, -1), -2)[..., 0, :]

            e1, e2 = pick(1) - pick(0), pick(2) - pick(0)
            cosang = np.einsum("...i,...i", e1, e2) / np.maximum(
                np.linalg.norm(e1, axis=-1) * np.linalg.norm(e2, axis=-1), 1e-300
            )
            ang = np.arccos(np.clip(cosang, -1, 1)) * (fan >= 0)
            vn = (ang[..., None] * n).sum(axis=1)
            normal[vert] = vn / np.maximum(np.linalg.norm(vn, axis=1, keepdims=True), 1e-300)
        return normal

    def _signed(self, fr: _Frames, P, frame, found, closest, face, bary):
        """Normals (K, 3) and signed distances (K,) of the points ``found`` at their closest points."""
        normal = self._normals(fr.verts, face, bary, frame[found] * self.n_vertices)
        diff = (np.take(P, found, axis=1) - closest).T
        sign = np.where(np.einsum("ij,ij->i", diff, normal) < 0, -1.0, 1.0)
        return normal, sign * np.linalg.norm(diff, axis=1)

    def _within(self, fr: _Frames, P, frame, margin):
        """Exact signed distance, closest point and normal for every point of ``P (3, M)`` closer to the
        body than ``margin`` or inside it; the others are proven farther and outside.
        Returns (their indices, closest (K, 3), normal (K, 3), signed distance (K,))."""
        m = P.shape[1]
        # a radius a little over the margin: a point just pushed out to the margin is found here too
        rho2 = (margin * (1.0 + 1e-3) + 1e-9) ** 2
        found, closest, face, bary, d2 = self._closest(fr, P, frame, np.full(m, rho2))
        ok = d2 < rho2
        found, closest, face, bary = found[ok], closest[:, ok], face[ok], bary[:, ok]
        rest = np.ones(m, bool)
        rest[found] = False
        rest = np.flatnonzero(rest)
        reach = np.full(len(rest), np.inf)
        if len(rest) and self.closed:
            wind, graze, reach = self._winding(fr, P[:, rest], frame[rest], fr.centre)
            tilts = np.array([[0.071, -0.113, 0.097], [-0.131, 0.089, 0.053]]) * fr.scale
            for tilt in tilts:  # a grazing ray is cast again in another direction
                g = np.flatnonzero(graze)
                if not len(g):
                    break
                wind[g], graze[g], reach[g] = self._winding(
                    fr, P[:, rest[g]], frame[rest[g]], fr.centre + tilt[:, None]
                )
            inside = (wind != 0) | graze
            rest, reach = rest[inside], np.where(graze, np.inf, reach)[inside]
        if len(rest):
            # the ray's first hit is a surface point: the closest one is no farther
            ub2 = (reach * (1.0 + 1e-9) + fr.slack) ** 2
            f2, c2, fa2, b2, _ = self._closest(fr, P[:, rest], frame[rest], ub2, tighten=True)
            found = np.concatenate([found, rest[f2]])
            closest, face = np.concatenate([closest, c2], axis=1), np.concatenate([face, fa2])
            bary = np.concatenate([bary, b2], axis=1)
        normal, sd = self._signed(fr, P, frame, found, closest, face, bary)
        if self.closed and len(found):
            self._unbury(fr, P, frame, found, closest, normal, sd)
        return found, closest.T, normal, sd

    def _unbury(self, fr: _Frames, P, frame, found, closest, normal, sd) -> None:
        """The rule for buried surfaces (:func:`~segadeform.body.collision.reference.unbury`), in place on the
        points ``found`` with their closest (3, K), normal (K, 3) and sd (K,): those the closest feature calls
        outside but the winding number inside take the nearest point that is not buried within ``PINCH`` times the
        body's size (the reference's brute force with this walk's winding number: such points are few, only where
        the posed body intersects itself)."""
        nv = self.n_vertices
        nb = fr.verts.shape[1] // nv
        h = np.array([BURY * np.ptp(fr.verts[:, b * nv + self._used], axis=1).max() for b in range(nb)])
        cand = np.flatnonzero(sd > h[frame[found]])
        if not len(cand):
            return
        pts = found[cand]
        wind, graze = self._winding_retry(fr, P[:, pts], frame[pts])
        cand = cand[(wind != 0) & ~graze]
        for j in cand:
            b = int(frame[found[j]])
            r = nearest_unburied(
                P[:, found[j]],
                fr.verts[:, b * nv : (b + 1) * nv].T,
                self.faces,
                winding=lambda q, b=b: self._decided(fr, q, b),
            )
            if r is None:
                continue
            g_face, c, bary, d2 = r
            closest[:, j] = c
            normal[j] = self._normals(fr.verts, np.array([g_face]), bary[:, None], np.array([b * nv]))[0]
            sd[j] = -np.sqrt(d2)

    def _decided(self, fr: _Frames, q, b: int) -> tuple[np.ndarray, np.ndarray]:
        """The winding number of the points ``q (K, 3)`` in frame ``b`` and whether a ray decided it."""
        wind, graze = self._winding_retry(fr, np.ascontiguousarray(q.T), np.full(len(q), b))
        return wind, ~graze

    def _winding_retry(self, fr: _Frames, P, frame) -> tuple[np.ndarray, np.ndarray]:
        """:meth:`_winding` of ``P (3, M)``, a grazing ray cast again in two other directions: (wind, graze)."""
        wind, graze, _ = self._winding(fr, P, frame, fr.centre)
        tilts = np.array([[0.071, -0.113, 0.097], [-0.131, 0.089, 0.053]]) * fr.scale
        for tilt in tilts:
            g = np.flatnonzero(graze)
            if not len(g):
                break
            wind[g], graze[g], _ = self._winding(fr, P[:, g], frame[g], fr.centre + tilt[:, None])
        return wind, graze

    def query(self, p, v) -> ProximityResult:
        """Exact closest point and signed distance of every point ``p (P, 3)`` against ``v (1, V, 3)``."""
        fr = self._frames(v)
        P = np.ascontiguousarray(p[0].T)
        frame = np.zeros(P.shape[1], np.int64)
        found, closest, face, bary, _ = self._closest(fr, P, frame, np.full(P.shape[1], np.inf), tighten=True)
        normal, sd = self._signed(fr, P, frame, found, closest, face, bary)
        return ProximityResult(signed_distance=sd, closest=closest.T.copy(), normal=normal, face=face)

    def push_out(self, p, v, margin: float, iterations: int):
        """:func:`~segadeform.body.collision.reference.push_out` of ``p (B, N, 3)`` against ``v (B, V, 3)``: the moved
        points (3, B N) transposed back by the caller, and how many moved."""
        nb, n = p.shape[:2]
        out = np.ascontiguousarray(p.reshape(-1, 3).T)  # (3, B N)
        frame = np.repeat(np.arange(nb), n)
        fr = self._frames(v)
        moved = np.zeros(out.shape[1], bool)
        idx = np.arange(out.shape[1])
        for _ in range(max(1, int(iterations))):
            hits = []
            for lo in range(0, len(idx), self.chunk):  # a few thousand points at a time stay in cache
                part = idx[lo : lo + self.chunk]
                sel, closest, normal, sd = self._within(fr, out[:, part], frame[part], margin)
                hit = sd < margin
                h = part[sel[hit]]
                out[:, h] = (closest[hit] + margin * normal[hit]).T
                hits.append(h)
            idx = np.sort(np.concatenate(hits))
            if not len(idx):
                break
            moved[idx] = True
        return out.T.copy(), int(moved.sum())
