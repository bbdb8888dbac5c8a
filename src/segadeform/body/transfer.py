"""Skinning-weight transfer from a body to a garment (nearest body point), and garment LBS.

Used to drive pinned garment vertices in the simulator and as the LBS
baseline of the evaluation (issue #7, baseline (a)).
"""

from __future__ import annotations

import numpy as np

from ..errors import InputError
from .collision import BodyProxy
from .model import BodyModel
from .skinning import dual_quaternion_skinning, linear_blend_skinning

__all__ = ["transfer_weights", "skin_garment", "residual_log_weights", "RESIDUAL_EPS"]

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
    return out / out.sum(1, keepdims=True)


def skin_garment(rest, weights, body: BodyModel, poses, betas=None, trans=None, *, skinning: str = "lbs"):
    """Pose a rest-pose garment with transferred weights (no blend shapes): ``(T, P, 3)``.

    Shapes:
        rest: (P, 3), weights: (P, S), poses: (T, 3 S), trans: (T, 3) -> (T, P, 3)
    """
    out = body.forward(poses, betas, trans, skinning=skinning)
    skin = {"lbs": linear_blend_skinning, "dqs": dual_quaternion_skinning}[skinning]
    rest = np.asarray(rest, np.float64)
    return skin(np.broadcast_to(rest, (len(out.transforms),) + rest.shape), weights, out.transforms)
