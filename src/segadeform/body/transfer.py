"""Skinning-weight transfer from a body to a garment, and garment LBS.

Priors (:data:`WEIGHT_PRIORS`, named by a model's ``weight_prior``; every one gives non-negative weights
summing to 1, equal to the closest body point's where the garment lies on the skin):

* ``"nearest"`` (:func:`transfer_weights`): the weights of the closest body point.  Drives pinned
  garment vertices in the simulator and is the LBS baseline of the evaluation (issue #7, baseline (a)).
* ``"inpaint"`` (:func:`inpaint_transfer_weights`): the closest point's weights only where the garment
  lies on the body (closer than :data:`INPAINT_MAX_DISTANCE`, normals within :data:`INPAINT_MAX_ANGLE`),
  the rest filled in by the harmonic interpolation of those over the garment (cotangent Laplacian), after
  Abdrashitov et al., *Robust skin weights transfer via weight inpainting* (2023): a skirt's hem then
  moves with a blend of the hips and both legs instead of tearing between the legs.
* ``"idw"`` (:func:`idw_transfer_weights`): an inverse-distance blend of the weights of every body vertex
  within a radius that grows with the garment vertex's distance from the body, after the weight transfer of
  Patel et al., *TailorNet* (CVPR 2020), which blends many body vertices instead of taking one.
* ``"gaussian"`` (:func:`gaussian_transfer_weights`): a Gaussian-weighted blend of body vertices whose
  width grows with the distance from the body, after Chen et al., *GAPS: Geometry-aware, physics-based,
  self-supervised neural garment draping* (3DV 2024): a hem 10 cm from the legs takes both legs' weights.
* ``"smooth"`` (:func:`smooth_transfer_weights`): the closest-point weights smoothed along the garment, the
  more the farther a vertex is from the body (implicit Laplacian smoothing), as Bertiche et al., *Neural
  Cloth Simulation* (NCS, 2022) recommend for skirts.
* ``"smooth-light"``: the same with a quarter of the strength (:data:`SMOOTH_LIGHT_STRENGTH`): a vertex
  twice as far from the body is smoothed as much as a ``smooth`` one.  On the motion capture of
  ``data/continuum`` it is closer to Blender than ``smooth`` (LBS vertex error 3.675 against 3.841 cm on
  every 8th training sample, 5.083 against 5.300 on the validation split: ``tools/prior_strength.py``) and
  puts fewer vertices inside the body (3.1 against 9.9 %, 2.2 against 7.0 %): ``smooth`` carries a trouser
  leg or a dress's front away from the thigh it lies on.  Not on the test split's held-out dresses and tops,
  where it is 3.2 % farther from Blender (5.923 against 5.740 cm) with 2.6 against 6.9 % inside: ``smooth``
  stays the default recipe's prior (``docs/gpu-training.md``, "A lighter prior").

The three kernel priors take the closest point's weights within :data:`ON_SKIN` of the body and blend
into their own over the next :data:`ON_SKIN` (a continuous prior that is exact on the skin).  Their
constants were chosen by LBS vertex error on 10 simulated samples of six garment kinds under CMU walk,
dribble and run clips that no dataset config uses (issue #27's gate study; never the test split):
``smooth`` 4.115 cm at the chosen strength (4.46 at a 15th of it, 4.59 at 3.3x), ``gaussian`` 4.44,
``idw`` 4.52, ``inpaint`` 4.60, ``nearest`` 4.97.
"""

from __future__ import annotations

import numpy as np

from ..errors import InputError
from .collision import BodyProxy
from .model import BodyModel
from .skinning import dual_quaternion_skinning, linear_blend_skinning

__all__ = [
    "transfer_weights",
    "inpaint_transfer_weights",
    "inpaint_weights",
    "garment_weights",
    "skin_garment",
    "idw_transfer_weights",
    "gaussian_transfer_weights",
    "smooth_transfer_weights",
    "residual_log_weights",
    "RESIDUAL_EPS",
    "WEIGHT_PRIORS",
    "WEIGHT_PRIOR_VERSION",
    "INPAINT_MAX_DISTANCE",
    "INPAINT_MAX_ANGLE",
    "ON_SKIN",
    "SMOOTH_LIGHT_STRENGTH",
]

#: the skinning-weight priors a garment can get from the body (see the module docstring)
WEIGHT_PRIORS = ("nearest", "inpaint", "idw", "gaussian", "smooth", "smooth-light")
#: the kernel priors (idw, gaussian, smooth, smooth-light) are the closest point's weights this close to the body (m)
ON_SKIN = 0.005
#: a garment vertex keeps its closest body point's weights only this close to the body (m) ...
INPAINT_MAX_DISTANCE = 0.02
#: ... and with its normal within this angle (degrees, either side) of the body's there
INPAINT_MAX_ANGLE = 35.0

#: the version of what :func:`garment_weights` computes: part of the runtime's cache key for the body's weights
#: at a garment (``W-<hash>.npy``), so a change to the priors must bump it
WEIGHT_PRIOR_VERSION = 2

#: added to the body's weights before the log that residual-weights models take (``log_wbody``): a joint
#: the body does not use starts at log(1e-5) = -11.5, and softmax(log(w + eps)) differs from w by < S eps
RESIDUAL_EPS = 1e-5


def residual_log_weights(weights) -> np.ndarray:
    """``log(w + RESIDUAL_EPS)`` as float32: the ``log_wbody`` input of residual-weights models.

    Shapes:
        weights: (N, S) -> (N, S)
    """
    w = np.asarray(weights, np.float64)
    if w.ndim != 2 or not np.isfinite(w).all() or (w < -1e-6).any():
        raise InputError("weights must be finite, non-negative (N, S)", got=w.shape)
    return np.log(np.clip(w, 0.0, None) + RESIDUAL_EPS).astype(np.float32)


def _barycentric(p, a, b, c):
    v0, v1, v2 = b - a, c - a, p - a
    d00, d01, d11 = (v0 * v0).sum(-1), (v0 * v1).sum(-1), (v1 * v1).sum(-1)
    d20, d21 = (v2 * v0).sum(-1), (v2 * v1).sum(-1)
    den = d00 * d11 - d01 * d01
    safe = np.abs(den) > 1e-30
    den = np.where(safe, den, 1.0)
    v = np.where(safe, (d11 * d20 - d01 * d21) / den, 1 / 3)
    w = np.where(safe, (d00 * d21 - d01 * d20) / den, 1 / 3)
    bary = np.clip(np.stack([1 - v - w, v, w], -1), 0, None)
    return bary / np.maximum(bary.sum(-1, keepdims=True), 1e-30)


def transfer_weights(points, body_vertices, body_faces, body_weights) -> np.ndarray:
    """Skinning weights of the closest point on the body surface, barycentrically interpolated.

    Shapes:
        points: (P, 3), body_vertices: (V, 3), body_faces: (F, 3), body_weights: (V, S) -> (P, S)
    """
    return _closest_point_weights(points, body_vertices, body_faces, body_weights)[2]


def _closest_point_weights(points, body_vertices, body_faces, body_weights):
    """``(points (P, 3) float64, the body query at them, the body's weights there (P, S))``, validated."""
    p = np.asarray(points, np.float64)
    w = np.asarray(body_weights, np.float64)
    if p.ndim != 2 or p.shape[1] != 3 or len(p) == 0:
        raise InputError("points must be (P, 3) with P >= 1", got=p.shape)
    if w.ndim != 2 or w.shape[0] != len(body_vertices):
        raise InputError("body_weights must be (V, S)", expected=f"({len(body_vertices)}, S)", got=w.shape)
    proxy = BodyProxy(body_vertices, body_faces)
    r = proxy.query(p)
    tri = proxy.faces[r.face]
    v = proxy.vertices
    bary = _barycentric(r.closest, v[tri[:, 0]], v[tri[:, 1]], v[tri[:, 2]])
    out = np.einsum("pc,pcs->ps", bary, w[tri])
    return p, r, out / out.sum(1, keepdims=True)


def inpaint_weights(vertices, faces, weights, known) -> np.ndarray:
    """Harmonic inpainting: the rows of ``weights`` where ``known`` is False replaced by the solution of
    ``L w = 0`` there (cotangent Laplacian of the mesh), the known rows fixed (and returned unchanged);
    the solved rows clipped at 0 and normalised.  A connected piece with no known vertex keeps its weights.

    Shapes:
        vertices: (N, 3), faces: (F, 3), weights: (N, S), known: (N,) bool -> (N, S)
    """
    import scipy.sparse as sp
    import scipy.sparse.linalg as spl

    from ..geometry.laplacian import cotangent_laplacian
    from ..geometry.mesh_ops import connected_components

    v = np.asarray(vertices, np.float64)
    w = np.asarray(weights, np.float64)
    known = np.asarray(known, bool)
    if w.ndim != 2 or len(w) != len(v) or known.shape != (len(v),):
        raise InputError(
            "weights (N, S) and known (N,) must match the vertices",
            expected=f"N = {len(v)}",
            got=(w.shape, known.shape),
        )
    _, comp = connected_components(np.asarray(faces), len(v))
    has_known = np.bincount(comp, known.astype(np.int64), minlength=comp.max() + 1) > 0
    solve = ~known & has_known[comp]
    if not solve.any():
        return w.copy()
    lap = cotangent_laplacian(v, faces)
    u, k = np.flatnonzero(solve), np.flatnonzero(~solve)
    luu = lap[u][:, u].tocsc()
    # a tiny diagonal shift keeps the system solvable where a vertex has no area (isolated / degenerate)
    luu = luu + sp.identity(len(u), format="csc") * (1e-12 * max(abs(luu.diagonal()).max(), 1e-30))
    sol = spl.splu(luu).solve(-(lap[u][:, k] @ w[k]))
    sol = np.clip(sol, 0.0, None)
    total = sol.sum(1, keepdims=True)
    bad = ~np.isfinite(total[:, 0]) | (total[:, 0] <= 1e-12)
    sol[bad] = w[u[bad]]
    out = w.copy()
    out[u] = sol / sol.sum(1, keepdims=True)
    return out


def inpaint_transfer_weights(
    points,
    faces,
    body_vertices,
    body_faces,
    body_weights,
    *,
    max_distance: float = INPAINT_MAX_DISTANCE,
    max_angle: float = INPAINT_MAX_ANGLE,
):
    """The ``"inpaint"`` prior: closest-point weights where the garment ``points``/``faces`` lies on the body
    (distance below ``max_distance``, normals within ``max_angle`` degrees, either orientation), harmonic
    inpainting elsewhere (:func:`inpaint_weights`).

    Shapes:
        points: (P, 3), faces: (F, 3), body_vertices: (V, 3), body_faces: (G, 3), body_weights: (V, S) -> (P, S)
    """
    from ..geometry.mesh_ops import vertex_normals

    # one body query serves the closest-point weights and the on-body test
    p, q, w = _closest_point_weights(points, body_vertices, body_faces, body_weights)
    n = vertex_normals(p, np.asarray(faces))
    cos = np.abs(np.einsum("ij,ij->i", n, q.normal))
    known = (np.abs(q.signed_distance) < float(max_distance)) & (cos >= np.cos(np.radians(float(max_angle))))
    return inpaint_weights(p, faces, w, known)


def _on_skin_blend(distance, near_w, far_w) -> np.ndarray:
    """``near_w`` within :data:`ON_SKIN` of the body, ``far_w`` beyond 2 ON_SKIN, linear between."""
    lam = np.clip((np.abs(np.asarray(distance, np.float64)) - ON_SKIN) / ON_SKIN, 0.0, 1.0)[:, None]
    w = (1.0 - lam) * near_w + lam * far_w
    return w / w.sum(1, keepdims=True)


def _kernel_blend(points, distance, body_vertices, body_weights, radius, kernel) -> np.ndarray:
    """``sum_k kernel(r_k, i) W_k / sum_k kernel(r_k, i)`` over the body vertices k within ``radius[i]`` of
    point i (at least its 8 nearest).  Shapes: points (P, 3), distance, radius (P,) -> (P, S)."""
    from scipy.spatial import cKDTree

    tree = cKDTree(np.asarray(body_vertices, np.float64))
    w = np.asarray(body_weights, np.float64)
    out = np.empty((len(points), w.shape[1]))
    k = 8
    for i, idx in enumerate(tree.query_ball_point(points, radius)):
        if len(idx) < k:
            idx = tree.query(points[i], k=k)[1]
        idx = np.asarray(idx)
        r = np.linalg.norm(body_vertices[idx] - points[i], axis=1)
        c = kernel(r, i)
        out[i] = c @ w[idx] / max(c.sum(), 1e-300)
    return out


#: idw: body vertices within IDW_RADIUS_SCALE x the distance + IDW_RADIUS_MIN, weighted 1 / (r^2 + eps^2)
IDW_RADIUS_SCALE, IDW_RADIUS_MIN, IDW_EPS = 8.0, 0.1, 0.005


def idw_transfer_weights(points, body_vertices, body_faces, body_weights) -> np.ndarray:
    """The ``"idw"`` prior (module docstring): inverse-distance weights of the body vertices within
    ``8 d + 10 cm`` of a garment vertex ``d`` from the body (TailorNet-style), the closest point's on the skin.

    Shapes:
        points: (P, 3), body_vertices: (V, 3), body_faces: (F, 3), body_weights: (V, S) -> (P, S)
    """
    p, q, w_cp = _closest_point_weights(points, body_vertices, body_faces, body_weights)
    d = np.abs(q.signed_distance)
    bv = np.asarray(body_vertices, np.float64)
    far = _kernel_blend(
        p, d, bv, body_weights, IDW_RADIUS_SCALE * d + IDW_RADIUS_MIN, lambda r, i: 1.0 / (r * r + IDW_EPS**2)
    )
    return _on_skin_blend(d, w_cp, far)


#: gaussian: sigma = GAUSS_SIGMA_MIN + GAUSS_SIGMA_SCALE x the distance from the body; cut at 3 sigma
GAUSS_SIGMA_MIN, GAUSS_SIGMA_SCALE = 0.05, 2.0


def gaussian_transfer_weights(points, body_vertices, body_faces, body_weights) -> np.ndarray:
    """The ``"gaussian"`` prior (module docstring): Gaussian weights ``exp(-r^2 / 2 sigma^2)`` of the body
    vertices, ``sigma = 5 cm + 2 d`` for a garment vertex ``d`` from the body (GAPS-style), the closest
    point's on the skin.

    Shapes:
        points: (P, 3), body_vertices: (V, 3), body_faces: (F, 3), body_weights: (V, S) -> (P, S)
    """
    p, q, w_cp = _closest_point_weights(points, body_vertices, body_faces, body_weights)
    d = np.abs(q.signed_distance)
    sigma = GAUSS_SIGMA_MIN + GAUSS_SIGMA_SCALE * d
    bv = np.asarray(body_vertices, np.float64)
    # the kernel is centred on the closest body point, not the garment vertex: the blend widens with the
    # distance without shifting towards whatever body part happens to be nearest in space
    far = _kernel_blend(q.closest, d, bv, body_weights, 3.0 * sigma, lambda r, i: np.exp(-0.5 * (r / sigma[i]) ** 2))
    return _on_skin_blend(d, w_cp, far)


#: smooth: implicit smoothing strength (I + s L) w = w_cp with s = SMOOTH_STRENGTH (d / SMOOTH_DISTANCE)^2
SMOOTH_STRENGTH, SMOOTH_DISTANCE = 600.0, 0.03
#: smooth-light: the strength of ``smooth`` over 4 (chosen among 1, 1/2.25, 1/4, 1/9 and 1/16 of it by LBS vertex
#: error on the training and validation splits of ``data/continuum``; never the test split)
SMOOTH_LIGHT_STRENGTH = SMOOTH_STRENGTH / 4


def smooth_transfer_weights(
    points, faces, body_vertices, body_faces, body_weights, *, strength: float = SMOOTH_STRENGTH
) -> np.ndarray:
    """The ``"smooth"`` prior (module docstring): ``(I + diag(s) L) w = w_cp`` with ``L`` the garment's
    graph Laplacian (degree-normalised), ``w_cp`` the closest-point weights and ``s = strength (d / 3 cm)^2``
    (``strength`` 600: ``smooth``; :data:`SMOOTH_LIGHT_STRENGTH`: ``smooth-light``) for a vertex ``d`` from the
    body beyond :data:`ON_SKIN` (0 on the skin: those rows are ``w_cp`` exactly).

    Shapes:
        points: (P, 3), faces: (F, 3), body_vertices: (V, 3), body_faces: (G, 3), body_weights: (V, S) -> (P, S)
    """
    import scipy.sparse as sp
    import scipy.sparse.linalg as spl

    from ..geometry.mesh_ops import adjacency

    p, q, w_cp = _closest_point_weights(points, body_vertices, body_faces, body_weights)
    d = np.abs(q.signed_distance)
    if not (np.isfinite(strength) and strength >= 0):
        raise InputError("smoothing strength must be finite and >= 0", got=strength)
    s = np.where(d <= ON_SKIN, 0.0, strength * (d / SMOOTH_DISTANCE) ** 2)
    a = adjacency(np.asarray(faces), len(p))
    a = (a > 0).astype(np.float64)
    deg = np.asarray(a.sum(1)).ravel()
    inv = np.where(deg > 0, 1.0 / np.maximum(deg, 1e-300), 0.0)
    lap = sp.identity(len(p), format="csr") - sp.diags(inv) @ a  # an isolated vertex's row: w = w_cp / (1 + s)
    m = (sp.identity(len(p), format="csc") + sp.diags(s) @ lap).tocsc()
    w = spl.splu(m).solve(w_cp)
    w = np.clip(w, 0.0, None)
    return w / w.sum(1, keepdims=True)


def garment_weights(points, faces, body: BodyModel, betas=None, prior: str = "nearest") -> np.ndarray:
    """The body's skinning weights carried to a garment in the rest pose of the body shaped by ``betas``,
    by the named prior (:data:`WEIGHT_PRIORS`).  Shapes: points (P, 3), faces (F, 3) -> (P, S)."""
    if prior not in WEIGHT_PRIORS:
        raise InputError("unknown skinning-weight prior", expected=" | ".join(WEIGHT_PRIORS), got=prior)
    bv = body.shaped_vertices(betas)[0]
    if prior == "inpaint":
        return inpaint_transfer_weights(points, faces, bv, body.faces, body.weights)
    if prior == "idw":
        return idw_transfer_weights(points, bv, body.faces, body.weights)
    if prior == "gaussian":
        return gaussian_transfer_weights(points, bv, body.faces, body.weights)
    if prior in ("smooth", "smooth-light"):
        k = SMOOTH_STRENGTH if prior == "smooth" else SMOOTH_LIGHT_STRENGTH
        return smooth_transfer_weights(points, faces, bv, body.faces, body.weights, strength=k)
    return transfer_weights(points, bv, body.faces, body.weights)


def skin_garment(rest, weights, body: BodyModel, poses, betas=None, trans=None, *, skinning: str = "lbs"):
    """Pose a rest-pose garment with transferred weights (no blend shapes): ``(T, P, 3)``.

    Shapes:
        rest: (P, 3), weights: (P, S), poses: (T, 3 S), trans: (T, 3) -> (T, P, 3)
    """
    out = body.forward(poses, betas, trans, skinning=skinning)
    skin = {"lbs": linear_blend_skinning, "dqs": dual_quaternion_skinning}[skinning]
    rest = np.asarray(rest, np.float64)
    return skin(np.broadcast_to(rest, (len(out.transforms),) + rest.shape), weights, out.transforms)
