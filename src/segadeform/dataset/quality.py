"""The quality gate every simulated sample passes before it is kept.

Checks (thresholds from the dataset config's ``[quality]``):

* **finite** -- no NaN or inf anywhere;
* **strain** -- ``|l / l_rest - 1|`` over frames and edges: the share of edges past ``max_strain`` in
  some frame may be at most ``max_strained_edges`` (default 0: none may); an edge over the limit only
  where one of its ends is pinched (above) is a pinch, not a tear, and is counted apart;
* **penetration** -- per frame, the fraction of garment vertices deeper than
  ``penetration_depth`` inside the posed body (signed distance, the same
  proxy as the runtime's collision stage); the worst frame counts.  Vertices *pinched* between two
  parts of the body that touch (an arm against the torso, thigh against thigh: see :func:`pinched`)
  are counted apart, against ``max_pinched``: the posed body intersects itself there, so cloth caught
  between the two parts has no place outside both -- that is the body's doing, not a failed
  simulation.  Tunnelling (a thigh through a skirt) is not a pinch and counts as penetration;
* **jitter** -- acceleration outliers: a vertex-frame whose second difference
  exceeds ``3 x`` the body's largest vertex acceleration in that frame plus
  1 cm/frame^2 (cloth may swing, but not spike past everything driving it);
* **detached** -- no piece of the garment (a connected component of its mesh) farther than
  ``max_body_distance`` from the posed body in any frame, and no vertex farther than
  ``max_vertex_distance``: a loose piece such as a button falling to the floor strains no edge and
  penetrates nothing, yet is no ground truth.  The rule is per piece, not per vertex: the hem of a
  flared skirt or dress swings well away from the legs in a turn (0.3-0.4 m in CMU's dribble with
  turns), which is cloth, not a detached piece;
* **slipped** -- of the vertices that lie on the body at rest (``on_body``: a waistband, shoulders,
  cuffs), at most ``max_slipped`` may be farther than ``slip_distance`` from the body in any frame: a
  sleeve thrown off its arm or a skirt fallen to the knees is no ground truth either, though nothing tears
  or penetrates.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from ..body.collision import BodyProxy
from ..body.untangle import vertex_parts
from ..errors import InputError
from ..geometry.mesh_ops import connected_components, unique_edges

__all__ = ["QualityReport", "quality_check", "BodyParts", "pinched", "on_body_at_rest"]


@dataclasses.dataclass
class QualityReport:
    finite: bool
    max_strain: float
    p99_strain: float
    max_penetrating: float  # fraction of vertices, worst frame
    jitter: float  # fraction of vertex-frames
    reasons: list
    strained_edges: float = 0.0  # fraction of edges past max_strain in some frame (pinches not counted)
    detached: float = 0.0  # fraction of vertices in a detached piece or too far, worst frame
    pinched: float = 0.0  # fraction of vertices inside the body where two body parts touch, worst frame
    pinched_edges: float = 0.0  # fraction of edges past max_strain only where pinched
    slipped: float = 0.0  # fraction of the on-body vertices far from the body, worst frame

    @property
    def ok(self) -> bool:
        return not self.reasons

    def to_dict(self) -> dict:
        d = dataclasses.asdict(self)
        d["ok"] = self.ok
        return d


@dataclasses.dataclass(frozen=True)
class BodyParts:
    """What :func:`pinched` needs of a body: ``rest (V, 3)`` its vertices in the rest pose (the shape
    simulated) and ``part (V,)`` each vertex's part (torso, arms, legs) by its largest skinning weight."""

    rest: np.ndarray
    part: np.ndarray

    @classmethod
    def of(cls, body, betas=None) -> BodyParts:
        return cls(rest=np.asarray(body.shaped_vertices(betas)[0], np.float64), part=vertex_parts(body.weights))


def pinched(
    points, depth, body_posed, parts: BodyParts, *, gap: float = 0.01, separation: float = 0.08, k: int = 32
) -> np.ndarray:
    """Which ``points`` lie where two parts of the posed body touch: within ``depth + gap`` of the point
    (``depth``: how far inside the body it is, 0 outside) lie body vertices of two different parts
    (torso, arms, legs) that are more than ``separation`` apart in the rest pose -- an arm pressed
    into the side of the torso, thigh against thigh -- not the joint where a limb meets the torso.

    Shapes:
        points (P, 3), depth (P,), body_posed (V, 3) -> (P,) bool
    """
    from scipy.spatial import cKDTree

    pts = np.asarray(points, np.float64)
    if len(pts) == 0:
        return np.zeros(0, bool)
    r = np.asarray(depth, np.float64) + gap
    d, idx = cKDTree(np.asarray(body_posed, np.float64)).query(pts, k=k)
    near = d <= r[:, None]
    a0 = idx[:, :1]
    other = parts.part[idx] != parts.part[a0]
    apart = np.linalg.norm(parts.rest[idx] - parts.rest[a0], axis=2) > separation
    return (near & other & apart).any(axis=1)


def on_body_at_rest(rest, body_rest, body_faces, *, within: float = 0.015) -> np.ndarray:
    """Which garment vertices lie on the body at rest (closer than ``within`` to its surface, either side).

    Shapes:
        rest (N, 3) the garment on the body's rest pose, body_rest (V, 3) -> (N,) bool
    """
    q = BodyProxy(np.asarray(body_rest, np.float64), body_faces).query(np.asarray(rest, np.float64))
    return np.abs(q.signed_distance) < within


def quality_check(
    frames,
    rest,
    faces,
    body_frames,
    body_faces,
    spec,
    *,
    contact: dict | None = None,
    parts: BodyParts | None = None,
    on_body=None,
) -> QualityReport:
    """Shapes: frames (T, N, 3), rest (N, 3), faces (F, 3), body_frames (T, V, 3) -> report.

    ``contact``: a dict that receives ``closest`` and ``normal`` (T, N, 3) float32, the closest
    body point and its outward normal for every vertex and frame (training's collision loss uses them).
    ``parts``: the body's parts (:class:`BodyParts`), to tell pinches (:func:`pinched`); without them
    every penetrating vertex and strained edge counts.
    ``on_body``: (N,) bool, the vertices that lie on the body at rest (:func:`on_body_at_rest`), for the
    slipped check; without it the check is skipped.
    """
    x = np.asarray(frames, np.float64)
    if not np.isfinite(x).all():
        return QualityReport(
            False, float("nan"), float("nan"), float("nan"), float("nan"), ["non-finite positions"], float("nan")
        )
    e = unique_edges(faces, len(rest))
    l0 = np.linalg.norm(rest[e[:, 0]] - rest[e[:, 1]], axis=1)
    length = np.linalg.norm(x[:, e[:, 0]] - x[:, e[:, 1]], axis=2)
    strain = np.abs(length / np.maximum(l0, 1e-12) - 1)
    over_t = strain > spec.max_strain  # (T, E)
    proxy = None
    pen = pinch = 0.0
    far = 0.0
    n_comp, comp = connected_components(faces, len(rest))
    slip = 0.0
    if on_body is not None:
        on_body = np.asarray(on_body, bool)
        if on_body.shape != (len(rest),):
            raise InputError("on_body must be (N,) bool", expected=(len(rest),), got=on_body.shape)
    tear = np.zeros(len(e), bool)  # edges over the limit in some frame where neither end is pinched
    pinch_e = np.zeros(len(e), bool)
    if contact is not None:
        contact["closest"] = np.empty(x.shape, np.float32)
        contact["normal"] = np.empty(x.shape, np.float32)
    for t in range(len(x)):
        proxy = BodyProxy(body_frames[t], body_faces) if proxy is None else proxy.moved(body_frames[t])
        q = proxy.query(x[t])
        inside = q.signed_distance < -spec.penetration_depth
        hot = np.flatnonzero(over_t[t])
        if parts is not None and (inside.any() or len(hot)):
            ask = np.union1d(np.flatnonzero(inside), e[hot].ravel())
            pin = np.zeros(len(x[t]), bool)
            pin[ask] = pinched(x[t][ask], np.maximum(-q.signed_distance[ask], 0.0), body_frames[t], parts)
            pinch = max(pinch, float((inside & pin).mean()))
            inside &= ~pin
            by_pinch = pin[e[hot, 0]] | pin[e[hot, 1]]
            pinch_e[hot[by_pinch]] = True
            tear[hot[~by_pinch]] = True
        else:
            tear[hot] = True
        pen = max(pen, float(inside.mean()))
        dist = np.abs(q.signed_distance)
        near = np.full(n_comp, np.inf)
        np.minimum.at(near, comp, dist)  # each piece's nearest vertex to the body
        lost = (near[comp] > spec.max_body_distance) | (dist > spec.max_vertex_distance)
        far = max(far, float(lost.mean()))
        if on_body is not None and on_body.any():
            slip = max(slip, float((dist[on_body] > spec.slip_distance).mean()))
        if contact is not None:
            contact["closest"][t], contact["normal"][t] = q.closest, q.normal
    jit = 0.0
    if len(x) >= 3:
        acc = np.linalg.norm(x[2:] - 2 * x[1:-1] + x[:-2], axis=2)  # (T-2, N)
        b = np.asarray(body_frames, np.float64)
        bacc = np.linalg.norm(b[2:] - 2 * b[1:-1] + b[:-2], axis=2).max(axis=1)  # (T-2,)
        jit = float((acc > 3 * bacc[:, None] + 0.01).mean())
    reasons = []
    over = float(tear.mean())  # edges strained past the bound in some frame, pinches aside
    pinch_edges = float((pinch_e & ~tear).mean())
    if over > spec.max_strained_edges:
        reasons.append(
            f"strain {strain.max():.2f} > {spec.max_strain}"
            + (
                f" on {100 * over:.2f}% of edges > {100 * spec.max_strained_edges:.2f}%"
                if spec.max_strained_edges > 0
                else ""
            )
        )
    if pen > spec.max_penetrating:
        reasons.append(f"penetration {100 * pen:.2f}% of vertices > {100 * spec.max_penetrating:.2f}%")
    if pinch > spec.max_pinched:
        reasons.append(f"pinched {100 * pinch:.2f}% of vertices > {100 * spec.max_pinched:.2f}%")
    if jit > spec.max_jitter:
        reasons.append(f"jitter {100 * jit:.3f}% > {100 * spec.max_jitter:.3f}%")
    if slip > spec.max_slipped:
        reasons.append(
            f"slipped: {100 * slip:.1f}% of the vertices on the body at rest farther than "
            f"{spec.slip_distance} m from it > {100 * spec.max_slipped:.1f}%"
        )
    if far > 0:
        reasons.append(
            f"detached: {100 * far:.2f}% of vertices in a piece farther than {spec.max_body_distance} m "
            f"from the body or farther than {spec.max_vertex_distance} m themselves"
        )
    return QualityReport(
        True,
        float(strain.max()),
        float(np.percentile(strain, 99)),
        pen,
        jit,
        reasons,
        over,
        far,
        pinch,
        pinch_edges,
        slip,
    )
