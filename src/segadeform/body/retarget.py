"""Retarget a motion from any mapped humanoid skeleton onto the 24-joint SMPL skeleton of a body.

The source is given by its forward kinematics -- global joint rotations and
positions per frame -- and a :class:`~segadeform.body.skeleton_map.SkeletonMapping`.
Each SMPL joint's *global* rotation is found from the source, so the joints
the mapping leaves out (``LHipJoint``, ``Neck1``, twist bones, fingers) are
folded in automatically: their rotations are already part of the globals
and positions of the mapped joints below them.

For SMPL joint ``j`` mapped to source joint ``m``:

* **two or more mapped children** (pelvis, chest): ``G_j = G_src[m] C_j``,
  the source joint's rotation with a rest correction ``C_j``: the rotation
  that best turns the target's rest directions to those children onto the
  source's (Kabsch);
* **one mapped child** ``c`` (limbs, spine, neck; a child at zero distance in
  the source, like CMU's ``LowerBack`` at the hips, is passed over for the
  next one down): ``G_j = S(t) G_src[m] C_j``.
  ``C_j`` is the rest correction, the smallest rotation taking the target's
  rest bone direction ``J[c] - J[j]`` onto the source's rest bone direction
  (T- vs A-pose, different proportions); ``G_src[m] C_j`` then carries the
  source's bone twist; ``S(t)``, the smallest rotation taking that bone onto
  the source's *posed* direction ``P[c] - P[m]``, absorbs the rotations of
  folded joints between ``m`` and ``c``;
* **no mapped child** (hands, toes, head): the source rotation with the
  parent's correction, ``S_p(t) G_src[m] C_p``.

The collars follow the source's collar *relative to its rest and to the
chest*, reduced to its swing about the target's collar bone: a collar's twist
moves no joint but turns the shoulder's skin, and a mocap skeleton's collar
bone (sternum to shoulder) points elsewhere than SMPL's, so matching its
direction outright would shrug the shoulders.

SMPL joints the source lacks get, when they lie between two mapped joints
(``spine2`` of a two-joint spine, a missing neck or collar), an even share of
the rotation between them (slerp of the globals), and otherwise the parent's
rotation (no local rotation).

The root position follows the source's root, scaled (``scale``: file units to
metres, see :func:`limb_scale`).
"""

from __future__ import annotations

import numpy as np

from ..errors import InputError
from .rotations import matrix_to_quaternion, quaternion_slerp, quaternion_to_matrix
from .skeleton import SMPL_JOINT_NAMES, SMPL_PARENTS

__all__ = ["min_rotation", "kabsch", "retarget_to_smpl", "limb_scale", "smpl_children"]


#: joints whose rotation is only the swing onto the source bone (no twist of their own): the collars
_SWING_ONLY = frozenset({13, 14})


def min_rotation(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """The smallest rotation taking direction ``a`` onto direction ``b`` (any lengths).

    Opposite directions give a half turn about an axis perpendicular to ``a``;
    a zero vector gives the identity.

    Shapes:
        a, b: (..., 3) -> (..., 3, 3)
    """
    a, b = np.broadcast_arrays(np.asarray(a, np.float64), np.asarray(b, np.float64))
    na = np.linalg.norm(a, axis=-1, keepdims=True)
    nb = np.linalg.norm(b, axis=-1, keepdims=True)
    degenerate = (na[..., 0] < 1e-12) | (nb[..., 0] < 1e-12)
    a = a / np.maximum(na, 1e-300)
    b = b / np.maximum(nb, 1e-300)
    v = np.cross(a, b)
    c = np.einsum("...i,...i", a, b)
    K = np.zeros(a.shape[:-1] + (3, 3))
    K[..., 0, 1], K[..., 0, 2], K[..., 1, 2] = -v[..., 2], v[..., 1], -v[..., 0]
    K[..., 1, 0], K[..., 2, 0], K[..., 2, 1] = v[..., 2], -v[..., 1], v[..., 0]
    opposite = c < -1 + 1e-9
    scale = 1.0 / np.where(opposite, 1.0, 1.0 + c)
    R = np.eye(3) + K + (K @ K) * scale[..., None, None]
    if opposite.any():
        ao = a[opposite]
        perp = np.cross(ao, [1.0, 0.0, 0.0])
        small = np.linalg.norm(perp, axis=-1) < 1e-6
        perp[small] = np.cross(ao[small], [0.0, 1.0, 0.0])
        perp /= np.linalg.norm(perp, axis=-1, keepdims=True)
        R[opposite] = 2 * perp[..., :, None] * perp[..., None, :] - np.eye(3)  # half turn about perp
    R[degenerate] = np.eye(3)
    return R


def kabsch(u: np.ndarray, v: np.ndarray) -> np.ndarray:
    """The rotation ``R`` minimising ``sum_k |R u_k - v_k|^2`` (proper: det = +1).

    Shapes:
        u: (..., K, 3), v: (..., K, 3) -> (..., 3, 3)
    """
    u, v = np.broadcast_arrays(np.asarray(u, np.float64), np.asarray(v, np.float64))
    H = np.swapaxes(u, -1, -2) @ v  # (..., 3, 3) = sum_k u_k v_k^T
    U, _, Vt = np.linalg.svd(H)
    V = np.swapaxes(Vt, -1, -2)
    d = np.sign(np.linalg.det(V @ np.swapaxes(U, -1, -2)))
    d = np.where(d == 0, 1.0, d)
    D = np.broadcast_to(np.eye(3), H.shape).copy()
    D[..., 2, 2] = d
    return V @ D @ np.swapaxes(U, -1, -2)


def smpl_children() -> list[list[int]]:
    out: list[list[int]] = [[] for _ in range(24)]
    for j, p in enumerate(SMPL_PARENTS):
        if p >= 0:
            out[int(p)].append(j)
    return out


def _next_mapped(c: int, src: np.ndarray, children) -> tuple[int, list[int]]:
    """First mapped joint from SMPL joint ``c`` down its single-child chain, and the unmapped joints passed."""
    passed = []
    while src[c] < 0:
        passed.append(c)
        if len(children[c]) != 1:
            return -1, passed
        c = children[c][0]
    return c, passed


def limb_scale(source_rest: np.ndarray, src: np.ndarray, target_rest: np.ndarray) -> float:
    """Target leg length over source leg length (hip-knee + knee-ankle, both legs): the factor that
    turns source units into metres *on the target body*, so feet neither skate nor sink.

    Shapes:
        source_rest: (J, 3), src: (24,), target_rest: (24, 3) -> float
    """

    def legs(p, idx):
        out: float | np.floating = 0.0
        for a, b, c in ((1, 4, 7), (2, 5, 8)):
            out += np.linalg.norm(p[idx[a]] - p[idx[b]]) + np.linalg.norm(p[idx[b]] - p[idx[c]])
        return out

    ls = legs(source_rest, src)
    lt = legs(target_rest, np.arange(24))
    if not (ls > 0 and np.isfinite(ls)):
        raise InputError("the source skeleton's legs have zero length", got=ls)
    return float(lt / ls)


def retarget_to_smpl(
    src: np.ndarray,
    source_rest: np.ndarray,
    source_global: np.ndarray,
    source_pos: np.ndarray,
    target_rest: np.ndarray,
    scale: float,
) -> tuple[np.ndarray, np.ndarray]:
    """Local SMPL joint rotations and root translation that reproduce a source motion (module docstring).

    Args:
        src: (24,) source joint per SMPL joint, -1 for none (``SkeletonMapping.source``).
        source_rest: (J, 3) source rest joint positions (file units, +Y up).
        source_global: (T, J, 3, 3) source global joint rotations relative to its rest pose.
        source_pos: (T, J, 3) source posed joint positions (file units, +Y up).
        target_rest: (24, 3) the target body's rest joints (metres, T-pose).
        scale: file units -> metres.

    Returns:
        rot (T, 24, 3, 3) local rotations, trans (T, 3) with ``pelvis = target_rest[0] + trans``.
    """
    src = np.asarray(src, np.int64)
    P0 = np.asarray(source_rest, np.float64)
    G = np.asarray(source_global, np.float64)
    P = np.asarray(source_pos, np.float64)
    Jt = np.asarray(target_rest, np.float64)
    if src.shape != (24,) or src[0] < 0:
        raise InputError("the mapping must place SMPL's pelvis", got=src.shape)
    if Jt.shape != (24, 3) or not np.isfinite(Jt).all():
        raise InputError("target rest joints must be a finite (24, 3) array", got=Jt.shape)
    T = G.shape[0]
    children = smpl_children()
    glob = np.zeros((T, 24, 3, 3))
    known = np.zeros(24, bool)
    fix = np.broadcast_to(np.eye(3), (24, T, 3, 3)).copy()  # S_j(t)
    corr = np.broadcast_to(np.eye(3), (24, 3, 3)).copy()  # C_j
    has_fix = np.zeros(24, bool)
    eps = 1e-3 * max(float(np.ptp(P0, axis=0).max()), 1e-12)

    def _target(c: int, m: int) -> int:
        """The mapped joint down from SMPL child c whose source position is away from source joint m
        (a source bone of zero length -- CMU's LowerBack at the hips -- says nothing about direction)."""
        t = _next_mapped(c, src, children)[0]
        while t >= 0 and np.linalg.norm(P0[src[t]] - P0[m]) < eps:
            t = _next_mapped(children[t][0], src, children)[0] if len(children[t]) == 1 else -1
        return t

    for j in range(24):
        m = src[j]
        if m < 0:
            continue
        targets = [t for t in (_target(c, m) for c in children[j]) if t >= 0]
        if len(targets) >= 2:
            u = np.stack([Jt[t] - Jt[j] for t in targets])  # (K, 3) target rest directions
            v = np.stack([P0[src[t]] - P0[m] for t in targets])  # (K, 3) source rest directions
            u = u / np.maximum(np.linalg.norm(u, axis=-1, keepdims=True), 1e-12)
            v = v / np.maximum(np.linalg.norm(v, axis=-1, keepdims=True), 1e-12)
            if np.linalg.norm(np.cross(v, v[0]), axis=-1).max() > 1e-6:
                corr[j] = kabsch(u, v)
            else:  # the children start at one point of the source (CMU's ASF: neck and both clavicles at the
                # thorax's end): Kabsch leaves the turn about that direction free; take the smallest rotation
                corr[j] = min_rotation(u.sum(axis=0), v[0])
            glob[:, j] = G[:, m] @ corr[j]
            has_fix[j] = True  # fix[j] stays the identity
        elif len(targets) == 1:
            t = targets[0]
            u = Jt[t] - Jt[j]
            corr[j] = min_rotation(u, P0[src[t]] - P0[m])
            p = int(SMPL_PARENTS[j])
            if j in _SWING_ONLY and known[p] and src[p] >= 0:
                # the source's rotation of the collar relative to the chest and to its rest, in the
                # target's frame, reduced to its swing about the target's collar bone
                rel = np.swapaxes(G[:, src[p]], -1, -2) @ G[:, m]  # (T, 3, 3), identity at rest
                Cp = corr[p]
                R = Cp.T @ rel @ Cp
                glob[:, j] = glob[:, p] @ min_rotation(u, R @ u)
                fix[j] = glob[:, j] @ np.swapaxes(G[:, m] @ corr[j], -1, -2)
                has_fix[j] = True
                known[j] = True
                continue
            base = G[:, m] @ corr[j]
            cur = base @ u
            fix[j] = min_rotation(cur, P[:, src[t]] - P[:, m])
            glob[:, j] = fix[j] @ base
            has_fix[j] = True
        else:
            p = int(SMPL_PARENTS[j])
            if p >= 0 and has_fix[p]:
                glob[:, j] = fix[p] @ G[:, m] @ corr[p]
            else:
                glob[:, j] = G[:, m]
        known[j] = True
    # virtual joints: an even share between the mapped joints around them, else the parent's rotation
    for j in range(1, 24):
        if known[j]:
            continue
        p = int(SMPL_PARENTS[j])
        a, steps_up = p, 1  # the nearest mapped ancestor (the root always is)
        while src[a] < 0:
            a, steps_up = int(SMPL_PARENTS[a]), steps_up + 1
        nm, passed = _next_mapped(j, src, children)
        if nm >= 0:
            w = steps_up / (steps_up + len(passed))  # j's place on the chain a -> ... -> nm
            qa = matrix_to_quaternion(glob[:, a])
            qb = matrix_to_quaternion(glob[:, nm])
            glob[:, j] = quaternion_to_matrix(quaternion_slerp(qa, qb, np.full(T, w)))
        else:
            glob[:, j] = glob[:, p]
        known[j] = True
    par = SMPL_PARENTS
    rot = np.empty_like(glob)
    rot[:, 0] = glob[:, 0]
    rot[:, 1:] = np.swapaxes(glob[:, par[1:]], -1, -2) @ glob[:, 1:]
    trans = P[:, src[0]] * float(scale) - Jt[0]
    return rot, trans


def describe(src: np.ndarray, names) -> str:
    """``pelvis=Hips, left_hip=LeftUpLeg, ...`` for messages and ``motion info``."""
    return ", ".join(f"{SMPL_JOINT_NAMES[j]}={names[i]}" for j, i in enumerate(src) if i >= 0)
