"""A collision body without self-intersection: the posed body with the parts that pass into each other
(an arm into the torso, thigh into thigh in a stride, a hand into a thigh) moved apart, for the cloth
simulator's collider.

Why (issue #27, ``docs/simulator-gate.md``): the posed body of a skinned model intersects itself where two
parts touch.  Cloth caught there is inside one part whichever way it goes, so Blender's impulse-based collision
either shoots it through (large responses) or, with the impulse clamp that the datasets use, drops the
responses that a fast thigh needs and lets the thigh through the cloth.  With the parts moved apart the cloth
has a place between them, at the cost of a collider that is thinner than the body where two parts touch.
Measured (``docs/simulator-gate.md``, third study): the simulator keeps no more samples with it (30 of 58
against 31 of 58), so no dataset config turns it on (``simulate.untangle_body``).

The rule, per frame: each vertex of a part that lies inside another part or closer to it than ``gap`` (the
signed distance to that part's triangles is below ``gap``) and whose closest point there is more than
``separation`` away at rest (so not the joint where a limb meets the torso) is moved out along that part's
normal to ``gap`` outside it -- the whole way when the other part ranks higher (:data:`RANK`: the torso never
moves, a hand gives way to a thigh), half of it between two parts of one rank (thigh and thigh both move).  Only
a vertex that faces the other part's closest triangle (not one beside an open edge of the part, where the sign
of the distance means nothing) and is less than ``max_depth`` inside is moved.  The gate keeps measuring
penetration against the true posed body (:mod:`segadeform.dataset.quality`).

Parts are the pinch test's: torso, left and right arm, left and right leg, each vertex by its largest SMPL
skinning weight (:func:`vertex_parts`); a triangle belongs to a part when its three corners do.
"""

from __future__ import annotations

import numpy as np

from ..errors import InputError
from ..geometry._checks import check_mesh
from .collision import BodyCollider

__all__ = ["PART_OF_JOINT", "RANK", "vertex_parts", "untangle"]

#: SMPL joint -> body part (torso 0, left arm 1, right arm 2, left leg 3, right leg 4)
PART_OF_JOINT = np.array([0, 3, 4, 0, 3, 4, 0, 3, 4, 0, 3, 4, 0, 0, 0, 0, 1, 2, 1, 2, 1, 2, 1, 2])
#: which part gives way: a part moves wholly out of a higher-ranked one, halfway out of one of its own rank
#: (torso 2 never moves, legs 1, arms 0: a hand moves out of a thigh, thigh and thigh meet in the middle)
RANK = {0: 2, 1: 0, 2: 0, 3: 1, 4: 1}


def vertex_parts(weights) -> np.ndarray:
    """Each body vertex's part (:data:`PART_OF_JOINT`) by its largest skinning weight; a body without SMPL's 24
    joints is one part (torso).

    Shapes:
        weights (V, J) -> (V,) int64
    """
    w = np.asarray(weights)
    if w.ndim != 2 or len(w) == 0:
        raise InputError("skinning weights must be (V, J)", got=w.shape)
    if w.shape[1] != len(PART_OF_JOINT):
        return np.zeros(len(w), np.int64)
    return PART_OF_JOINT[w.argmax(axis=1)].astype(np.int64)


def untangle(
    posed,
    faces,
    part,
    rest,
    *,
    separation: float = 0.08,
    max_depth: float = 0.1,
    gap: float = 0.001,
    passes: int = 3,
    threads: int = 1,
) -> np.ndarray:
    """The posed body with every part moved out of the others (module docstring).

    Args:
        posed: the posed body, one frame or several.
        faces: its outward triangles.
        part: each vertex's part (:func:`vertex_parts`).
        rest: the body at rest (same shape), to tell two parts that touch from the joint between them.
        separation: metres at rest below which a vertex and the closest point are one joint, not two parts.
        max_depth: metres; a vertex deeper than this inside another part is left alone (no limb passes that
            far into another: what looks so is a wrong side of an open part's edge).
        gap: metres of room left between two parts: a vertex inside another part or closer to it than this
            is moved out to this distance (room for cloth caught between them, e.g. twice the simulator's
            collision distance and a bit).
        passes: rounds of moves per frame, each from where the last one left the body (two limbs that both
            move meet in the middle only after a few).
        threads: threads for the collider.

    Shapes:
        posed (V, 3) or (T, V, 3), faces (F, 3), part (V,), rest (V, 3) -> like posed
    """
    x = np.asarray(posed, np.float64)
    single = x.ndim == 2
    frames = x[None] if single else x
    if frames.ndim != 3 or frames.shape[2] != 3 or frames.shape[1] < 3:
        raise InputError("the posed body must be (V, 3) or (T, V, 3)", got=x.shape)
    if not np.isfinite(frames).all():
        raise InputError("the posed body contains NaN or inf")
    rest_v, f = check_mesh(rest, faces)
    n = frames.shape[1]
    p = np.asarray(part)
    if rest_v.shape != (n, 3) or p.shape != (n,):
        raise InputError("rest and part must match the posed body's vertices", expected=n, got=(rest_v.shape, p.shape))
    if not (np.isfinite(separation) and separation >= 0):
        raise InputError("separation must be a non-negative number of metres", got=separation)
    if isinstance(passes, bool) or not isinstance(passes, (int, np.integer)) or passes < 1:
        raise InputError("passes must be a positive integer", got=passes)
    if not (np.isfinite(max_depth) and max_depth > 0):
        raise InputError("max_depth must be a positive number of metres", got=max_depth)
    if not (np.isfinite(gap) and 0 <= gap < max_depth):
        raise InputError("gap must be a number of metres in [0, max_depth)", got=gap)
    face_part = np.where((p[f] == p[f[:, :1]]).all(axis=1), p[f[:, 0]], -1)
    parts = [int(q) for q in np.unique(p) if (face_part == q).any()]
    if len(parts) < 2:
        return x.copy()
    faces_of = {q: f[face_part == q] for q in parts}
    verts_of = {q: np.unique(faces_of[q]) for q in parts}
    ia_of = {q: np.flatnonzero(p == q) for q in parts}
    colliders = {q: BodyCollider(frames[0], faces_of[q], threads=threads) for q in parts}
    out = frames.copy()
    for t in range(len(frames)):
        out[t] = _untangle_frame(
            frames[t], parts, rest_v, faces_of, verts_of, ia_of, colliders, separation, max_depth, gap, passes
        )
    return out[0] if single else out


def _untangle_frame(v, parts, rest_v, faces_of, verts_of, ia_of, colliders, separation, max_depth, gap, passes):
    """:func:`untangle` on one frame: ``passes`` rounds of moves, each from where the last one left the body."""
    v = v.copy()
    for _ in range(passes):
        move = np.zeros_like(v)
        for a in parts:
            ia = ia_of[a]
            for b in parts:
                if b == a or RANK[a] > RANK[b]:  # the higher-ranked part stays where it is
                    continue
                vb = v[verts_of[b]]
                near = ia[((v[ia] >= vb.min(axis=0) - gap) & (v[ia] <= vb.max(axis=0) + gap)).all(axis=1)]
                if len(near) == 0:
                    continue
                q = colliders[b].query(v[near], v)
                corners = rest_v[faces_of[b][q.face]]  # (P, 3, 3): the closest triangle at rest
                apart = np.linalg.norm(corners - rest_v[near][:, None], axis=2).min(axis=1) > separation
                # inside, facing the triangle (not beside an open edge of the part, where the sign means nothing)
                off = v[near] - q.closest
                facing = np.abs(np.einsum("ij,ij->i", off, q.normal)) >= 0.9 * np.linalg.norm(off, axis=1)
                hit = (q.signed_distance < gap) & (q.signed_distance > -max_depth) & apart & facing
                if not hit.any():
                    continue
                share = 1.0 if RANK[b] > RANK[a] else 0.5
                step = (share * (gap - q.signed_distance[hit]))[:, None] * q.normal[hit]
                sel = near[hit]
                # a vertex inside two parts takes the larger move, axis by axis
                move[sel] = np.where(np.abs(step) > np.abs(move[sel]), step, move[sel])
        if not move.any():
            break
        v += move
    return v
