"""Garments made for another body, registered onto ours: MakeHuman ``.mhclo`` bindings and another body's mesh.
Vertex order and count are always kept.  (Reading ``.mhclo`` files is :mod:`segadeform.io.mhclo`'s, the rewritten
OBJ :func:`segadeform.io.obj.rewrite_obj_vertices`'s, placement checks and the plain unit/axis fix
:mod:`segadeform.body.placement`'s.)

* :func:`fit_mhclo`: a MakeHuman garment binds each vertex
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
"""

from __future__ import annotations

import dataclasses

import numpy as np

from ..body.collision import BodyProxy, closest_point_on_triangles
from ..body.kinematics import forward_kinematics, relative_transforms
from ..body.makehuman import makehuman_vertices, makehuman_weights
from ..body.rotations import axis_angle_to_matrix
from ..body.skinning import linear_blend_skinning
from ..bounds import BETA_LIMIT
from ..errors import FileFormatError, InputError
from ..geometry.mesh_ops import adjacency, face_areas, face_cross, vertex_normals
from ..io.mhclo import MhcloBinding

__all__ = ["fit_mhclo", "fit_to_body_mesh", "BodyFit", "guess_units_and_up", "edge_distortion", "folded_edges"]

_MH_TO_M = 0.1  # MakeHuman mesh units are decimetres


def fit_mhclo(binding: MhcloBinding, body, betas=None, *, return_apose: bool = False):
    """The garment's vertices on ``body`` at shape ``betas``, in the body's T-pose rest (metres, +Y up).

    With ``return_apose`` also the fit in MakeHuman's A-pose (the body posed by ``rest_pose_a``), before
    it is carried to the T-pose: the shape the garment was designed in, which the cloth simulator uses
    as the rest shape (``simulate(..., cloth_rest=, start_pose=)``).

    Shapes:
        -> (N, 3), the ``.mhclo``'s (= its OBJ's) vertex order [, (N, 3)]
    """
    mh = getattr(body, "makehuman", None)
    if mh is None:
        raise InputError(
            "this body has no MakeHuman binding, so .mhclo garments cannot be fitted to it",
            expected="the default body, or one baked with `segadeform body bake`",
        )
    n_hm = len(mh["hm08_index"]) + len(mh["extra_index"])
    idx = binding.verts
    used = np.concatenate([idx.ravel(), np.array([a for s in binding.scales.values() for a in s[:2]], np.int64)])
    if used.max() >= n_hm:
        raise FileFormatError(
            "binding names a base-mesh vertex the body does not have",
            path=binding.path,
            expected=f"indices < {n_hm}",
            got=int(used.max()),
        )
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


#: limbs tried from other directions by :func:`fit_to_body_mesh`: (joint, its child, the joints below it, the first
#: one's bends about x to try); shoulders, then hips
_LIMBS = (
    (16, 18, (18, 20), (0.0,)),
    (17, 19, (19, 21), (0.0,)),
    (1, 4, (4, 7), (0.0, 1.2)),
    (2, 5, (5, 8), (0.0, 1.2)),
)
#: directions (x outward from the body's side, y up, z forward) a limb is tried in: arms, legs
_LIMB_DIRECTIONS = (
    ((0.3, -1, 0), (0.3, -1, 1), (0, 0, 1), (0.3, 1, 0.5), (0.3, -1, -0.7), (1, -0.4, 0), (1, 0.2, 0.6)),
    ((0, -1, 0), (0, -1, 1), (0, -0.2, 1), (0, -1, -0.6), (0.6, -1, 0)),
)


def _turn(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """The shortest rotation (axis-angle, (3,)) taking direction ``a`` to direction ``b``."""
    a = a / np.linalg.norm(a)
    b = b / np.linalg.norm(b)
    axis = np.cross(a, b)
    s, c = np.linalg.norm(axis), float(np.dot(a, b))
    if s < 1e-9:
        return np.zeros(3) if c > 0 else np.array([0.0, 0.0, np.pi])
    return axis / s * np.arctan2(s, c)


def _compatible_nearest(tree, normals, points, point_normals, k: int = 8) -> np.ndarray:
    """Index of each point's nearest tree point whose normal faces the same side (dot > 0) among its ``k``
    nearest, else its nearest: the inner side of one thigh is not matched to the inner side of the other, nor
    an arm held against the torso to the torso.  Without normals (zero vectors) the nearest.

    Shapes:
        normals: (M, 3) of the tree's points; points, point_normals: (P, 3) -> (P,) int
    """
    _, nn = tree.query(points, k=min(k, tree.n))
    nn = nn.reshape(len(points), -1)
    ok = np.einsum("pc,pkc->pk", point_normals, normals[nn]) > 0.0
    first = np.where(ok.any(axis=1), ok.argmax(axis=1), 0)
    return nn[np.arange(len(points)), first]


def _attach(
    g: np.ndarray, g_faces, v: np.ndarray, faces: np.ndarray, k: int = 48, margin: float = 0.02, face_labels=None
):
    """Each garment vertex's body triangle and closest point on it: the closest triangle among the ``k`` nearest
    (by centre) whose normal faces the garment's normal there (dot > 0) and that is at most ``margin`` farther
    than the closest of all, else the closest of all.  With ``face_labels`` (the body part of each triangle), a
    vertex whose part is not its neighbours' (two rings on the garment) takes the closest triangle facing its way
    of the parts more than twice as many of them attach to, where there is one: a waistband that a registered
    elbow passes through stays on the hip.  The garment's normals are turned to face the body's way where most of
    them face the other; without ``g_faces`` the closest.

    Shapes:
        g: (N, 3); g_faces: (G, 3) or None; v: (V, 3); faces: (F, 3); face_labels: (F,) int -> (N,) int, (N, 3)
    """
    from scipy.spatial import cKDTree

    q = BodyProxy(v, faces).query(g)
    if g_faces is None or not len(g_faces):
        return q.face, q.closest
    f_n = face_cross(v, faces)
    f_n /= np.maximum(np.linalg.norm(f_n, axis=1, keepdims=True), 1e-300)
    g_n = vertex_normals(g, np.asarray(g_faces, np.int64))
    if np.einsum("nc,nc->", g_n, f_n[q.face]) < 0:  # the garment is wound inward
        g_n = -g_n
    tree = cKDTree(v[faces].mean(axis=1))

    def candidates(rows, kk):  # the kk nearest triangles of g[rows], their closest points, distances (inf: facing away)
        kk = min(kk, len(faces))
        cand = tree.query(g[rows], k=kk)[1].reshape(len(rows), kk)
        tri = v[faces[cand.ravel()]]
        cp = closest_point_on_triangles(np.repeat(g[rows], kk, axis=0), tri[:, 0], tri[:, 1], tri[:, 2])[0]
        cp = cp.reshape(len(rows), kk, 3)
        d = np.linalg.norm(cp - g[rows, None], axis=2)
        d[np.einsum("nc,nkc->nk", g_n[rows], f_n[cand]) <= 0] = np.inf
        return cand, cp, d

    n = len(g)
    rows = np.arange(n)
    cand, cp, d = candidates(rows, k)
    d[d > np.linalg.norm(q.closest - g, axis=1)[:, None] + margin] = np.inf  # a far triangle's frame turns the offset
    best = d.argmin(axis=1)
    ok = np.isfinite(d[rows, best])
    face = np.where(ok, cand[rows, best], q.face)
    closest = np.where(ok[:, None], cp[rows, best], q.closest)
    if face_labels is not None:
        lab = face_labels[face]
        near = adjacency(np.asarray(g_faces, np.int64), n)
        near = (near @ near).tolil()  # two rings, without the vertex itself
        near.setdiag(0)
        near = near.tocsr()
        votes = np.asarray(near @ np.eye(int(face_labels.max()) + 1)[lab])  # (N, parts): neighbours attached to each
        liked = votes > 2 * votes[rows, lab][:, None]  # parts more than twice as many neighbours attach to
        odd = np.flatnonzero(liked.any(axis=1))
        if len(odd):
            c2, p2, d2 = candidates(odd, 16 * k)
            d2[~np.take_along_axis(liked[odd], face_labels[c2], axis=1)] = np.inf
            b2 = d2.argmin(axis=1)
            ok2 = np.isfinite(d2[np.arange(len(odd)), b2])
            face[odd[ok2]] = c2[np.arange(len(odd)), b2][ok2]
            closest[odd[ok2]] = p2[np.arange(len(odd)), b2][ok2]
    return face, closest


def _local_frames(v: np.ndarray, faces: np.ndarray, face_idx: np.ndarray):
    """Per-face orthonormal frames (t1, t2, n), each (M, 3), of faces ``face_idx``."""
    tri = v[faces[face_idx]]
    t1 = tri[:, 1] - tri[:, 0]
    n = np.cross(t1, tri[:, 2] - tri[:, 0])
    t1 /= np.maximum(np.linalg.norm(t1, axis=1, keepdims=True), 1e-300)
    n /= np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-300)
    return t1, np.cross(n, t1), n


def _forward_differences(fun_batch, x0: np.ndarray, lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
    """The Jacobian of ``fun_batch`` at ``x0`` by forward differences, every step in one batched call.

    The steps are scipy's ``'2-point'`` ones (``scipy.optimize._numdiff``): ``sqrt(eps) * max(1, |x|)`` with the
    sign of ``x`` (+ at 0); where that leaves ``[lo, hi]``, the other way if it fits there, else the whole distance
    to the farther bound; the step is the representable ``(x + h) - x``.  What ``least_squares`` would compute with
    one call per parameter, in one.

    Shapes:
        fun_batch: (R, P) -> (R, M); x0, lo, hi: (P,) -> (M, P)
    """
    h = np.finfo(np.float64).eps ** 0.5 * np.where(x0 >= 0, 1.0, -1.0) * np.maximum(1.0, np.abs(x0))
    below, above = x0 - lo, hi - x0
    fits = np.abs(h) <= np.maximum(below, above)
    h = np.where(((x0 + h > hi) | (x0 + h < lo)) & fits, -h, h)
    h = np.where(fits, h, np.where(above >= below, above, -below))  # a box narrower than the step
    h = (x0 + h) - x0
    f = fun_batch(np.vstack([x0[None], x0 + np.diag(h)]))
    return ((f[1:] - f[0]) / h[:, None]).T


def fit_to_body_mesh(
    garment_vertices,
    source_vertices,
    source_faces,
    body,
    betas=None,
    *,
    samples: int = 1500,
    rounds: int = 8,
    seed: int = 0,
    scale: float | None = None,
    garment_faces=None,
    search_facing: bool = True,
) -> BodyFit:
    """Carry a garment modelled on another body mesh (any topology and pose, +Y up, metres, facing any way about
    +Y) onto ``body``.

    1. **register** the body to the source mesh: scale (``None``: from the ratio of surface areas, which a pose
       changes little, or of heights for a point cloud; a number fixes it), translation, shape and joint rotations
       by iterative closest points in both directions (body samples -> source, source samples -> body), each
       point paired with the nearest one facing the same way, with priors pulling pose and shape to zero: pose and
       placement alone from each of the T-pose, MakeHuman's A-pose (when the body file has it) and arms down; from
       the best, each arm and leg tried in a few directions (a stride, an arm raised forward) and kept where the
       body fits closer; then everything, shape included, to the end.  With ``search_facing``, a source facing
       another way than +Z (the way its shoulders and head face, :func:`_facing_candidates`; where they do not
       tell, the quarter turns whose T-pose fits closest) is turned to face +Z first, garment with it
       (``BodyFit``'s ``trans`` and ``pose`` are then those of the turned source); without it the source is taken
       to face +Z (``garment fit --turn`` has turned it so);
    2. **correct the surface**: every registered body vertex within 3 cm of the source moves onto it (the
       closest point facing its way), the displacement smoothed over the mesh;
    3. **attach** each garment vertex to the closest point of that surface: triangle, barycentric
       weights and the offset in the triangle's own frame; with ``garment_faces``, the closest facing the same
       way as the garment there (a sleeve on an arm held against the torso attaches to the arm) and on a body part
       its neighbours attach to (:func:`_attach`);
    4. **carry** it to the body's rest at ``betas``: the same triangle point and local offset.

    Shapes:
        garment_vertices: (N, 3); source_vertices: (S, 3); source_faces: (F, 3) -> BodyFit.vertices (N, 3)
    """
    from scipy.optimize import least_squares
    from scipy.spatial import cKDTree

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
    joints_free = [0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 12, 13, 14, 15, 16, 17, 18, 19, 20, 21]
    W = body.weights[bidx]
    n_th = 3 * len(joints_free)
    v0 = body.shaped_vertices()[0]
    height_s, height_b = float(np.ptp(sv[:, 1])), float(np.ptp(v0[:, 1]))
    if not height_s > 0:
        raise InputError("the source body has no height (is it flat, or not +Y up?)", got=height_s)

    def unpack(x):
        th = np.zeros(72)
        th.reshape(24, 3)[joints_free] = x[4 + nb :].reshape(-1, 3)
        return float(np.exp(x[0])), x[1:4], x[4 : 4 + nb], th

    # the samples' rest positions and the joints are linear in the shape: J(beta) = J0 + sum_b beta_b dJ_b
    v_b, dirs_b = body.v_template[bidx], body.shapedirs[bidx]
    j_rest = body.rest_joints()[0]
    dJ = np.stack([body.rest_joints(row)[0] - j_rest for row in np.eye(nb)], axis=-1)  # (S, 3, nb)

    def body_points_batch(X):
        """The body samples for each row of parameters ``X (R, P)`` at once: ``(R, V, 3)``."""
        th = np.zeros((len(X), 24, 3))
        th[:, joints_free] = X[:, 4 + nb :].reshape(len(X), -1, 3)
        beta = X[:, 4 : 4 + nb]
        rest = v_b + np.einsum("vcb,rb->rvc", dirs_b, beta)
        J = j_rest + np.einsum("scb,rb->rsc", dJ, beta)
        g4, _ = forward_kinematics(axis_angle_to_matrix(th), J, body.parents)
        posed = linear_blend_skinning(rest, W, relative_transforms(g4, J))
        return posed * np.exp(X[:, 0])[:, None, None] + X[:, None, 1:4]

    def body_points(x):
        return body_points_batch(x[None])[0]

    # the scale from the surface areas where the source has faces (a pose changes a body's area little, its height a
    # lot: arms raised, knees bent), else from the heights
    area_s = float(face_areas(sv, sf).sum()) if len(sf) else 0.0
    scale0 = np.sqrt(area_s / face_areas(v0, body.faces).sum()) if area_s > 0 else height_s / height_b
    # outward normals of the source (zero without faces: plain nearest points), turned outward if its winding is inward
    s_n = vertex_normals(sv, sf) if len(sf) else np.zeros_like(sv)
    if len(sf) and np.einsum("vc,vc->", sv - sv.mean(axis=0), s_n) < 0:
        s_n = -s_n

    # the pose prior's weight per angle: five times the limbs' on the spine, neck and head, whose chain of three
    # joints can twist one way and back for the same torso surface (a root 9 cm off on a CMU walk's first frame)
    prior = np.full(n_th, 0.02)
    for k, j in enumerate(joints_free):
        if j in (3, 6, 9, 12, 15):
            prior[3 * k : 3 * k + 3] = 0.1
    dominant = np.asarray(body.weights[bidx]).argmax(axis=1)  # the joint that moves each body sample most
    slot = {j: 4 + nb + 3 * k for k, j in enumerate(joints_free)}

    def start(init_pose: np.ndarray) -> np.ndarray:
        x = np.zeros(4 + nb + n_th)
        x[0] = np.log(scale0) if scale is None else np.log(scale)
        x[4 + nb :] = init_pose.reshape(24, 3)[joints_free].ravel()
        p = body_points(x)
        x[1:4] = [sv[:, 0].mean() - p[:, 0].mean(), sv[:, 1].min() - p[:, 1].min(), sv[:, 2].mean() - p[:, 2].mean()]
        return x

    def fit(x, n_rounds: int, *, joints=None, shape: bool = True, nfev: int = 20):
        """``n_rounds`` of closest points from ``x``: the joints in ``joints`` (all: None) turn, the body samples
        they move are matched (and, with every joint, the source's samples to the body's); shape and scale
        move with ``shape`` (the scale only where not given)."""
        free = np.zeros(len(x), bool)
        free[1:4] = True
        if shape:
            free[0] = scale is None and not area_s > 0  # the area gives the scale whatever the pose
            free[4 : 4 + nb] = True
        for j in joints_free if joints is None else joints:
            free[slot[j] : slot[j] + 3] = True
        use = np.ones(len(bidx), bool) if joints is None else np.isin(dominant, list(joints))
        lo = np.full(int(free.sum()), -np.inf)
        hi = np.full(int(free.sum()), np.inf)
        in_beta = (np.flatnonzero(free) >= 4) & (np.flatnonzero(free) < 4 + nb)
        lo[in_beta], hi[in_beta] = -BETA_LIMIT, BETA_LIMIT  # the shape space (segadeform.bounds)
        for _ in range(n_rounds):
            p = body_points(x)
            _, _, beta_, th_ = unpack(x)
            p_n = vertex_normals(body.forward(th_[None], beta_).vertices[0], body.faces)[bidx]
            q = sv[_compatible_nearest(s_tree, s_n, p[use], p_n[use])]  # body sample -> source vertex facing its way
            near_b = _compatible_nearest(cKDTree(p), p_n, s_pts, s_n[sidx])  # source sample -> body sample
            mine = use[near_b]  # the pairs whose body sample the free joints move

            def res_batch(XF, x=x, q=q, near_b=near_b[mine], s_mine=s_pts[mine]):  # this round's pairs, per row
                XX = np.repeat(x[None], len(XF), axis=0)
                XX[:, free] = XF
                pp = body_points_batch(XX)
                r = len(XF)
                return np.concatenate(
                    [
                        (pp[:, use] - q).reshape(r, -1),
                        (pp[:, near_b] - s_mine).reshape(r, -1),
                        0.05 * XX[:, 4 : 4 + nb],
                        prior * XX[:, 4 + nb :],
                    ],
                    axis=1,
                )

            x = x.copy()
            x[free] = least_squares(
                lambda xf: res_batch(xf[None])[0],
                x[free],
                jac=lambda xf: _forward_differences(res_batch, xf, lo, hi),
                max_nfev=nfev,
                method="trf",
                x_scale="jac",
                bounds=(lo, hi),
            ).x
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
    # From each start, pose and placement alone (shape and scale held: free, they bend to fit a wrong pose), with
    # the pairs found again every few steps; the best start on.  The source may face any way about its up axis (an
    # Unreal character faces +X), and closest points do not turn a body a quarter round: unless the caller knows the
    # facing, the rest pose is tried facing the quarters the body's shape points to (:func:`_facing_candidates`: one
    # where it is clear), and a source that faces another way than +Z is turned to face it (with the garment) and
    # fitted again -- as `--turn` would have it (a technical artist's source facing +X was fitted facing +Z, legs
    # crossed and 46 cm off, with exit 0).
    facings: dict = {}
    if search_facing:
        for q in _facing_candidates(sv):
            rest = np.concatenate([[0.0, np.radians(90.0 * q), 0.0], starts[0][3:]])
            facings[q] = fit(start(rest), 12, shape=False, nfev=5)
        quarter = min(facings, key=lambda q: facings[q][1])
        if quarter:
            r = axis_angle_to_matrix(np.array([0.0, np.radians(90.0 * quarter), 0.0]))  # the body turned so fits
            return fit_to_body_mesh(
                g @ r,  # (rows: R^T v) the source and garment turned back, to face the body's way
                sv @ r,
                sf,
                body,
                betas,
                samples=samples,
                rounds=rounds,
                seed=seed,
                scale=scale,
                garment_faces=garment_faces,
                search_facing=False,
            )
    trials = [facings[0]] if 0 in facings else []  # (the rest pose facing +Z: tried already)
    trials += [fit(start(s0), 12, shape=False, nfev=5) for s0 in starts[len(trials) :]]
    x, err = min(trials, key=lambda r: r[1])
    # Then each limb from a few directions (closest points alone leave an arm or a leg where it started when the
    # source holds it far from there -- a stride, an arm raised forward), kept where the whole body fits closer.
    J0 = body.rest_joints()[0]
    for root, child, chain, bends in _LIMBS:
        rest_dir = J0[child] - J0[root]
        side = float(np.sign(rest_dir[0]))
        for d in _LIMB_DIRECTIONS[root in (1, 2)]:
            for bend in bends:
                x2 = x.copy()
                x2[slot[root] : slot[root] + 3] = _turn(rest_dir, np.array([d[0] * side, d[1], d[2]]))
                for j in chain:
                    x2[slot[j] : slot[j] + 3] = 0.0
                x2[slot[chain[0]]] = bend
                x2, e2 = fit(x2, 3, joints=[root, *chain], shape=False, nfev=5)
                if e2 < err:
                    x, err = x2, e2
    x, _ = fit(x, rounds)
    scale_f, t, beta, th = unpack(x)
    B1 = body.forward(th[None], beta).vertices[0] * scale_f + t
    # surface correction: registered vertices near the source move onto it, smoothed
    if len(sf):  # the closest source point facing the same way (an arm next to the hip is not pulled onto the hip)
        c = _attach(B1, body.faces, sv, sf, margin=0.03)[1]
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
    part = np.asarray(body.weights)[body.faces].sum(axis=1).argmax(axis=1)  # (F,): the joint moving each triangle most
    face, closest = _attach(g, garment_faces, B2, body.faces, face_labels=part)
    tri = B2[body.faces[face]]
    _, bary = closest_point_on_triangles(g, tri[:, 0], tri[:, 1], tri[:, 2])
    t1, t2, n = _local_frames(B2, body.faces, face)
    o = g - closest
    coef = np.stack([np.einsum("ij,ij->i", o, t1), np.einsum("ij,ij->i", o, t2), np.einsum("ij,ij->i", o, n)], 1)
    R = body.shaped_vertices(betas)[0]
    c_r = np.einsum("mk,mkc->mc", bary, R[body.faces[face]])
    r1, r2, rn = _local_frames(R, body.faces, face)
    out = c_r + coef[:, :1] * r1 + coef[:, 1:2] * r2 + coef[:, 2:] * rn
    if garment_faces is not None:
        out = _smooth_carry(g, out, garment_faces)
    return BodyFit(vertices=out, body_error=body_error, scale=scale_f, trans=np.asarray(t), pose=th, betas=beta)


def _facing_candidates(v: np.ndarray) -> list[int]:
    """The quarter turns about +Y (0-3: 0, 90, 180, 270 degrees from +Z) a standing source body mesh ``v`` (N, 3), +Y
    up, may face, to be fitted and the closest kept: those within 60 degrees of the way its shape faces
    (:func:`_body_facing`: one, or two where it lies between them; both ways along its shoulders' normal where the
    head does not tell), else of its feet (:func:`_toes_facing`), else all four.  The fit's error alone does not
    tell: a body seen from behind fits about as close as from the front, and a body in a stride fits its rest pose
    turned a quarter or a half closer than facing its way (CMU 02_01 frame 0 was fitted facing +X, joints 39 cm off:
    a docs audit); and the feet point every way in a stride (07_03: 146-165 degrees off in 5 of 8 frames)."""
    facing = _body_facing(v)
    if facing is not None:
        cues = [facing[0]] if facing[1] else [facing[0], facing[0] + 180.0]
    else:
        toes = _toes_facing(v)
        cues = [] if toes is None else [toes]
    if not cues:
        return [0, 1, 2, 3]
    return [q for q in range(4) if any(abs((90.0 * q - c + 180.0) % 360.0 - 180.0) < 60.0 for c in cues)]


def _body_facing(v: np.ndarray) -> tuple[float, bool] | None:
    """``(degrees, sure)``: the way about +Y from +Z that a standing body mesh ``v`` (N, 3), +Y up, faces by its
    shape: across its shoulders (the widest horizontal direction of the torso at 72-82 % of its height: the points
    within 15 % of the height of the band's median, so arms held out or reaching forward are left out; within 24
    degrees of the truth on 16 frames of two CMU walks), towards the side its head stands out to (above 90 % of the
    height, against the neck at 84-88 %: 0.2-10 cm forward on those frames, 8.5 at rest).  ``sure`` False: the head
    within 0.2 % of the height of the neck along that axis, or the top band wider than 20 % of the height (hands on
    the head, arms raised): the body faces ``degrees`` or the opposite way.  None where the torso is less than 1.2x
    as wide as deep (or the bands are nearly empty).  A head tilted far back (a pose no modeller stands a body in)
    reads as facing backwards: ``fit_to_body_mesh(..., search_facing=False)``, ``garment fit --turn``, decides."""
    h = v[:, 1]
    lo, height = float(h.min()), float(np.ptp(h))

    def band(a, b):
        return v[(h > lo + a * height) & (h <= lo + b * height)][:, [0, 2]]

    shoulders, head, neck = band(0.72, 0.82), band(0.90, 1.0), band(0.84, 0.88)
    if min(len(shoulders), len(head), len(neck)) < 10 or not height > 0:
        return None
    shoulders = shoulders[np.linalg.norm(shoulders - np.median(shoulders, axis=0), axis=1) < 0.15 * height]
    if len(shoulders) < 10:
        return None
    c = shoulders - shoulders.mean(axis=0)
    w, e = np.linalg.eigh(c.T @ c / len(c))
    if not w[1] > 1.44 * w[0]:  # (variances: 1.2x the width)
        return None
    across = e[:, 1]  # (x, z)
    ahead = np.array([across[1], -across[0]])  # a quarter turn from it, one of the two ways
    lead = float((head.mean(axis=0) - neck.mean(axis=0)) @ ahead)
    ahead = ahead if lead > 0 else -ahead
    alone = float(np.ptp(head, axis=0).max()) <= 0.2 * height  # a head, no hands or arms beside it
    return float(np.degrees(np.arctan2(ahead[0], ahead[1]))), alone and abs(lead) >= 0.002 * height


def _toes_facing(v: np.ndarray) -> float | None:
    """Degrees about +Y from +Z that a standing body mesh ``v`` (N, 3), +Y up, faces by its feet: the lowest 3 % of
    its height against its shins (10-20 %), whose toes point forward; None where the feet are not told apart from
    the shins (fewer than 10 vertices either way, or under 2 % of the height between them)."""
    h = v[:, 1]
    lo, height = float(h.min()), float(np.ptp(h))
    feet = v[h < lo + 0.03 * height]
    shins = v[(h > lo + 0.1 * height) & (h < lo + 0.2 * height)]
    if len(feet) < 10 or len(shins) < 10:
        return None
    d = feet[:, [0, 2]].mean(axis=0) - shins[:, [0, 2]].mean(axis=0)
    if not np.linalg.norm(d) > 0.02 * height:
        return None
    return float(np.degrees(np.arctan2(d[0], d[1])))


def _smooth_carry(g: np.ndarray, out: np.ndarray, faces, iterations: int = 10) -> np.ndarray:
    """The carried garment with its displacement ``out - g`` smoothed over the garment's own edges (``iterations``
    steps halfway to the neighbours' mean, as the body surface's correction above).  Neighbouring garment vertices
    attached to neighbouring triangles of a body coarser than the garment turn with those triangles' frames, so a
    loose garment's offsets came out in a zig-zag: a technical artist's 20k-vertex dress had 433 pairs of faces
    folded onto each other after the fit; smoothed, 3, the vertices moved 1.2 mm on average and none into the body.
    It blends the pose change too where neighbouring parts move apart (a crotch, an armpit): on a source body in a
    stride, 2-3x as many vertices end inside the body before the fit's push-off to its margin (a review measured
    trousers 3.6 -> 8.2 %, a T-shirt 2.9 -> 6.8 %, a dress 1.0 -> 2.5 % more than 1 mm inside).  Smoothing only the
    offsets from the attached body points kept those inside but folded the trial's dress more (665 pairs): not
    taken.  docs/garment-fit.md, "Folds"."""
    f = np.asarray(faces, np.int64)
    A = adjacency(f, len(g)).tocsr()
    A.data[:] = 1.0
    deg = np.asarray(A.sum(axis=1)).ravel()
    d = out - g
    alone = (deg == 0)[:, None]  # a vertex in no face keeps its own
    for _ in range(iterations):
        d = 0.5 * d + 0.5 * np.where(alone, d, (A @ d) / np.maximum(deg, 1)[:, None])
    return g + d


#: a standing adult's height in metres: the range :func:`guess_units_and_up` reads a body mesh's units from
HUMAN_HEIGHT_M = (0.9, 2.5)


def guess_units_and_up(vertices, *, units=None, up=None) -> tuple[str, str, float]:
    """The units and up axis of a human body mesh, where not given: up is ``y`` or ``z``, whichever the body is
    longer along; where it is about as long along both (a T-pose whose arm span lies along one of them: a Z-up
    body facing +x, an arm span longer than the height), the one its vertices spread farther along for their
    extent (a standing body's vertices fill its height; along the arm span most of them -- torso, legs, head --
    lie in the middle quarter, between the arms).  The units are those in which its height along up is a
    standing adult's (:data:`HUMAN_HEIGHT_M`; m, then cm, dm, mm, inch).

    Returns ``(units, up, height in the file's units)``.

    Raises:
        InputError: no unit makes the height a human's (pass the units).

    Shapes:
        vertices: (V, 3)
    """
    from ..body.placement import UNIT_SCALES

    v = np.asarray(vertices, np.float64)
    if v.ndim != 2 or v.shape[1] != 3 or not len(v) or not np.isfinite(v).all():
        raise InputError("a body mesh needs finite (V, 3) vertices", got=v.shape)
    ext = np.ptp(v, axis=0)
    if up is None:
        if min(ext[1], ext[2]) < 0.6 * max(ext[1], ext[2]):
            up = "z" if ext[2] > ext[1] else "y"
        else:  # height and arm span: the vertices' spread for the extent (about 0.33 along the height, 0.24 the span)
            spread = v.std(axis=0) / np.maximum(ext, 1e-300)
            up = "z" if spread[2] > spread[1] else "y"
    height = float(ext[{"y": 1, "z": 2, "-z": 2, "x": 0}[up]])
    if units is None:
        lo, hi = HUMAN_HEIGHT_M
        units = next((u for u in ("m", "cm", "dm", "mm", "inch") if lo <= height * UNIT_SCALES[u] <= hi), None)
        if units is None:
            raise InputError(
                f"cannot tell the body mesh's units: it is {height:g} units tall along {up}, no human's height in "
                "m, cm, dm, mm or inches",
                expected="--units (and --up)",
                got=f"{height:g}",
            )
    return str(units), up, height


def folded_edges(vertices, faces) -> int:
    """How many edges of a mesh join two faces folded onto each other (their normals more than 90 degrees apart:
    a crease sharper than any cloth's rest shape; a fit that follows a coarse body's facets leaves a zig-zag of them).

    Shapes:
        vertices: (N, 3); faces: (F, 3)
    """
    f = np.asarray(faces, np.int64)
    if f.size == 0:
        return 0
    v = np.asarray(vertices, np.float64)
    n = np.cross(v[f[:, 1]] - v[f[:, 0]], v[f[:, 2]] - v[f[:, 0]])
    n /= np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-30)
    e = np.concatenate([f[:, [0, 1]], f[:, [1, 2]], f[:, [2, 0]]])
    key = np.sort(e, axis=1)
    owner = np.tile(np.arange(len(f)), 3)
    order = np.lexsort((key[:, 1], key[:, 0]))
    k, o = key[order], owner[order]
    same = np.all(k[1:] == k[:-1], axis=1)  # consecutive rows of one edge: the two faces that share it
    a, b = o[:-1][same], o[1:][same]
    return int((np.einsum("ij,ij->i", n[a], n[b]) < 0.0).sum())


def edge_distortion(before, after, faces, *, factor: float = 2.0) -> tuple[float, float]:
    """How far a fit moved a garment's edges from their lengths: the fraction of edges now more than ``factor``
    times longer or shorter, and the largest such ratio.  A garment carried from one body to another keeps its
    edges within a few tens of percent; a registration that found the wrong pose tears it (edges 10-60x).

    Shapes:
        before, after: (N, 3); faces: (F, 3)
    """
    f = np.asarray(faces, np.int64)
    e = np.unique(np.sort(np.concatenate([f[:, [0, 1]], f[:, [1, 2]], f[:, [2, 0]]]), axis=1), axis=0)
    a, b = np.asarray(before, np.float64), np.asarray(after, np.float64)
    la = np.linalg.norm(a[e[:, 0]] - a[e[:, 1]], axis=1)
    lb = np.linalg.norm(b[e[:, 0]] - b[e[:, 1]], axis=1)
    ok = (la > 1e-9) & (lb > 1e-9)  # zero-length edges (welds, duplicates) carry no length to keep
    if not ok.any():
        return 0.0, 1.0
    r = lb[ok] / la[ok]
    r = np.maximum(r, 1.0 / r)
    return float((r > factor).mean()), float(r.max())
