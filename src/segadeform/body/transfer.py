"""Skinning-weight transfer from a body to a garment, and garment LBS.

Two priors (:data:`WEIGHT_PRIORS`, named by a model's ``weight_prior``):

* ``"nearest"`` (:func:`transfer_weights`): the weights of the closest body point.  Drives pinned
  garment vertices in the simulator and is the LBS baseline of the evaluation (issue #7, baseline (a)).
* ``"inpaint"`` (:func:`inpaint_transfer_weights`): the closest point's weights only where the garment
  lies on the body (closer than :data:`INPAINT_MAX_DISTANCE`, normals within :data:`INPAINT_MAX_ANGLE`),
  the rest filled in by the harmonic interpolation of those over the garment (cotangent Laplacian), after
  Abdrashitov et al., *Robust skin weights transfer via weight inpainting* (2023): a skirt's hem then
  moves with a blend of the hips and both legs instead of tearing between the legs.
"""

from __future__ import annotations

import numpy as np

from ..errors import InputError
from .collision import BodyProxy
from .model import BodyModel
from .skinning import dual_quaternion_skinning, linear_blend_skinning

__all__ = ["transfer_weights", "inpaint_transfer_weights", "inpaint_weights", "garment_weights", "skin_garment",
           "residual_log_weights", "RESIDUAL_EPS", "WEIGHT_PRIORS", "WEIGHT_PRIOR_VERSION", "INPAINT_MAX_DISTANCE",
           "INPAINT_MAX_ANGLE"]

#: the skinning-weight priors a garment can get from the body (see the module docstring)
WEIGHT_PRIORS = ("nearest", "inpaint")
#: a garment vertex keeps its closest body point's weights only this close to the body (m) ...
INPAINT_MAX_DISTANCE = 0.02
#: ... and with its normal within this angle (degrees, either side) of the body's there
INPAINT_MAX_ANGLE = 35.0

#: the version of what :func:`garment_weights` computes: part of the runtime's cache key for the body's weights
#: at a garment (``W-<hash>.npy``), so a change to the priors must bump it
WEIGHT_PRIOR_VERSION = 1

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
        raise InputError("weights (N, S) and known (N,) must match the vertices", expected=f"N = {len(v)}",
                         got=(w.shape, known.shape))
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


def inpaint_transfer_weights(points, faces, body_vertices, body_faces, body_weights, *,
                             max_distance: float = INPAINT_MAX_DISTANCE, max_angle: float = INPAINT_MAX_ANGLE):
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


def garment_weights(points, faces, body: BodyModel, betas=None, prior: str = "nearest") -> np.ndarray:
    """The body's skinning weights carried to a garment in the rest pose of the body shaped by ``betas``,
    by the named prior (:data:`WEIGHT_PRIORS`).  Shapes: points (P, 3), faces (F, 3) -> (P, S)."""
    if prior not in WEIGHT_PRIORS:
        raise InputError("unknown skinning-weight prior", expected=" | ".join(WEIGHT_PRIORS), got=prior)
    bv = body.shaped_vertices(betas)[0]
    if prior == "inpaint":
        return inpaint_transfer_weights(points, faces, bv, body.faces, body.weights)
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
