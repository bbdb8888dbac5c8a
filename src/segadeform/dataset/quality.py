"""The quality gate every simulated sample passes before it is kept.

Checks (thresholds from the dataset config's ``[quality]``):

* **finite** -- no NaN or inf anywhere;
* **strain** -- ``|l / l_rest - 1|`` over frames and edges: the share of edges past ``max_strain`` in
  some frame may be at most ``max_strained_edges`` (default 0: none may); an edge over the limit only
  where one of its ends is pinched (above) is a pinch, not a tear, and is counted apart; an edge longer
  than its rest by ``min_stretch`` metres or less is not counted (default 0: every edge is): the short
  edges of a scanned or modelled garment's seams (MakeHuman's, 0.4-2 mm) stretched by a few millimetres
  by the solver's 2 mm collision distance pass 100 % strain without anything torn;
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
  or penetrates;
* **slid** -- those vertices, as a whole, no farther than ``slip_distance`` (median) from the points of the body
  they lay on at rest (:func:`body_anchors`, carried with the posed body's triangles): an unpinned skirt that slides
  down the hips stays close to the body, so the slipped check passed it (a researcher's trial: a waistband 9-12 cm
  below its place from the first frame, kept).  ``max_slipped = 1`` turns both checks off.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from ..body.collision import BodyProxy
from ..body.untangle import vertex_parts
from ..errors import InputError
from ..geometry.mesh_ops import connected_components, unique_edges

__all__ = [
    "QualityReport",
    "FrameStats",
    "frame_stats",
    "quality_check",
    "kept_frames",
    "BodyParts",
    "pinched",
    "on_body_at_rest",
    "BodyAnchors",
    "body_anchors",
]


def _apart(value: float, limit: float, digits: int = 2) -> tuple[str, str]:
    """``value`` and the ``limit`` it passed as text, with as many decimals as it takes (``digits`` up to 6) for
    the two to read apart ("0.10% > 0.10%" was a gate's verdict once, "5.0% > 5.0%" another)."""
    for d in range(digits, 7):
        a, b = f"{value:.{d}f}", f"{limit:.{d}f}"
        if a != b:
            break
    return a, b


def _pair(value: float, limit: float, unit: str = "%", digits: int = 2) -> str:
    """``"0.104% > 0.100"`` (then the caller's unit): :func:`_apart`'s two."""
    a, b = _apart(value, limit, digits)
    return f"{a}{unit} > {b}"


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
    passing_frames: int = 0  # how many leading frames pass the gate (all of them when ok)
    frames: int = 0  # how many frames were judged

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


@dataclasses.dataclass(frozen=True)
class BodyAnchors:
    """Where garment vertices ``index`` lay on the body at rest: at barycentric ``bary`` of the body triangle whose
    corners are body vertices ``corners``.  Shapes: index (M,) int, corners (M, 3) int, bary (M, 3)."""

    index: np.ndarray
    corners: np.ndarray
    bary: np.ndarray

    def distance(self, x, body) -> np.ndarray:
        """How far each anchored vertex of garment frame ``x`` is from its anchor on the posed body ``body``.
        Shapes: x (N, 3), body (V, 3) -> (M,)"""
        return np.linalg.norm(x[self.index] - np.einsum("mk,mkc->mc", self.bary, body[self.corners]), axis=1)


def body_anchors(rest, body_rest, body_faces, on_body) -> BodyAnchors:
    """The closest body points at rest of the garment vertices ``on_body`` (:func:`on_body_at_rest`).

    Shapes: rest (N, 3) the garment on the body's rest pose, body_rest (V, 3), body_faces (F, 3), on_body (N,) bool
    -> :class:`BodyAnchors`"""
    from ..body.collision.reference import closest_point_on_triangles

    idx = np.flatnonzero(np.asarray(on_body, bool))
    b = np.asarray(body_rest, np.float64)
    bf = np.asarray(body_faces, np.int64)
    p = np.asarray(rest, np.float64)[idx]
    face = BodyProxy(b, bf).query(p).face if len(idx) else np.zeros(0, np.int64)
    tri = b[bf[face]]
    _, bary = closest_point_on_triangles(p, tri[:, 0], tri[:, 1], tri[:, 2])
    return BodyAnchors(idx, bf[np.asarray(face, np.int64)], np.asarray(bary, np.float64))


def on_body_at_rest(rest, body_rest, body_faces, *, within: float = 0.015) -> np.ndarray:
    """Which garment vertices lie on the body at rest (closer than ``within`` to its surface, either side).

    Shapes:
        rest (N, 3) the garment on the body's rest pose, body_rest (V, 3) -> (N,) bool
    """
    q = BodyProxy(np.asarray(body_rest, np.float64), body_faces).query(np.asarray(rest, np.float64))
    return np.abs(q.signed_distance) < within


@dataclasses.dataclass(frozen=True)
class FrameStats:
    """What the gate measured of each frame of a clip, from which the verdict on any leading run of its frames
    (a prefix) follows without measuring again (:meth:`report`, :meth:`passing_prefix`).

    Shapes: strain (T, E) ``|l / l_rest - 1|``; pen, pinch, far, slip (T,) the fractions of the checks of
    :func:`quality_check`; tear_from, pinch_from (E,) the first frame an edge is over the strain limit where
    neither end is pinched / only where one is (T: never); jitter (T - 2,) acceleration outliers per frame
    (vertex count).  ``finite``: no NaN or inf anywhere; ``n`` vertices."""

    finite: bool
    strain: np.ndarray
    pen: np.ndarray
    pinch: np.ndarray
    far: np.ndarray
    slip: np.ndarray
    tear_from: np.ndarray
    pinch_from: np.ndarray
    jitter: np.ndarray
    n: int
    #: (T,) the median distance of the on-body vertices from their anchors (:func:`body_anchors`), metres; None
    #: without anchors (the slid check is skipped)
    slid: np.ndarray | None = None

    @property
    def n_frames(self) -> int:
        return len(self.pen)

    def _prefix_ok(self, spec) -> np.ndarray:
        """(T + 1,) bool: whether the first k frames pass the gate, k = 0 .. T (cheap: running maxima)."""
        t = self.n_frames
        ks = np.arange(t + 1)
        ok = np.ones(t + 1, bool)
        for series, bound in (
            (self.pen, spec.max_penetrating),
            (self.pinch, spec.max_pinched),
            (self.slip, spec.max_slipped),
        ):
            worst = np.concatenate([[0.0], np.maximum.accumulate(series)]) if t else np.zeros(1)
            ok &= worst <= bound
        far = np.concatenate([[0.0], np.maximum.accumulate(self.far)]) if t else np.zeros(1)
        ok &= far <= 0
        if self.slid is not None and t and spec.max_slipped < 1.0:  # (max_slipped = 1: no slipping is checked)
            ok &= np.concatenate([[0.0], np.maximum.accumulate(self.slid)]) <= spec.slip_distance
        n_e = max(len(self.tear_from), 1)
        torn = np.searchsorted(np.sort(self.tear_from), ks, side="left") / n_e  # edges torn before frame k
        ok &= torn <= spec.max_strained_edges
        jit = np.zeros(t + 1)
        if t >= 3:
            c = np.cumsum(self.jitter)  # outliers of the frames 1 .. k-2 (second differences of the first k)
            k = ks[3:]
            jit[3:] = c[k - 3] / ((k - 2) * max(self.n, 1))
        ok &= jit <= spec.max_jitter
        ok[0] = False
        return ok

    def passing_prefix(self, spec, within: int | None = None) -> int:
        """The largest k (at most ``within``, the whole clip by default) for which the clip's first k frames pass
        the gate; 0 when none does.  The simulation is causal, so those frames are exactly what a clip k frames
        long gives."""
        if not self.finite:
            return 0
        ok = self._prefix_ok(spec)[: (self.n_frames if within is None else within) + 1]
        good = np.flatnonzero(ok)
        return int(good[-1]) if len(good) else 0

    def report(self, spec, frames: int | None = None) -> QualityReport:
        """The gate's verdict on the first ``frames`` frames (all by default)."""
        if not self.finite:
            return QualityReport(
                False, float("nan"), float("nan"), float("nan"), float("nan"), ["non-finite positions"], float("nan")
            )
        k = self.n_frames if frames is None else int(frames)
        if not 1 <= k <= self.n_frames:
            raise InputError("frames must be within the clip", expected=f"1..{self.n_frames}", got=k)
        strain = self.strain[:k]
        pen = float(self.pen[:k].max())
        pinch = float(self.pinch[:k].max())
        far = float(self.far[:k].max())
        slip = float(self.slip[:k].max())
        slid = float(self.slid[:k].max()) if self.slid is not None and spec.max_slipped < 1.0 else 0.0
        tear = self.tear_from < k
        pinch_e = self.pinch_from < k
        jit = float(self.jitter[: k - 2].sum() / ((k - 2) * max(self.n, 1))) if k >= 3 else 0.0
        reasons = []
        over = float(tear.mean()) if len(tear) else 0.0  # edges strained past the bound in some frame, pinches aside
        pinch_edges = float((pinch_e & ~tear).mean()) if len(tear) else 0.0
        if over > spec.max_strained_edges:
            reasons.append(
                "strain {} > {}".format(*_apart(float(strain.max()), float(spec.max_strain)))
                + (
                    f" on {_pair(100 * over, 100 * spec.max_strained_edges)}% of edges"
                    if spec.max_strained_edges > 0
                    else ""
                )
            )
        if pen > spec.max_penetrating:
            reasons.append(f"penetration {_pair(100 * pen, 100 * spec.max_penetrating, '% of vertices')}%")
        if pinch > spec.max_pinched:
            reasons.append(f"pinched {_pair(100 * pinch, 100 * spec.max_pinched, '% of vertices')}%")
        if jit > spec.max_jitter:
            reasons.append(f"jitter {_pair(100 * jit, 100 * spec.max_jitter, '%', digits=3)}%")
        if slip > spec.max_slipped:
            a, b = _apart(100 * slip, 100 * spec.max_slipped, digits=1)
            reasons.append(
                f"slipped: {a}% of the vertices on the body at rest farther than {spec.slip_distance} m from it > {b}%"
            )
        if slid > spec.slip_distance:
            reasons.append(
                f"slid: the vertices on the body at rest {slid:.3f} m (median) from where they lay on it > "
                f'{spec.slip_distance} m (a waistband down the hips: pin it, [simulate] effects "pinning")'
            )
        if far > 0:
            reasons.append(
                f"detached: {100 * far:.2f}% of vertices in a piece farther than {spec.max_body_distance} m "
                f"from the body or farther than {spec.max_vertex_distance} m themselves"
            )
        size = strain.size
        return QualityReport(
            True,
            float(strain.max()) if size else 0.0,
            float(np.percentile(strain, 99)) if size else 0.0,
            pen,
            jit,
            reasons,
            over,
            far,
            pinch,
            pinch_edges,
            slip,
            passing_frames=self.passing_prefix(spec, k),
            frames=k,
        )


def frame_stats(
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
    anchors: BodyAnchors | None = None,
) -> FrameStats:
    """The gate's measurements of every frame (:class:`FrameStats`); arguments as :func:`quality_check`'s.

    Shapes: frames (T, N, 3), rest (N, 3), faces (F, 3), body_frames (T, V, 3) -> FrameStats."""
    x = np.asarray(frames, np.float64)
    e = unique_edges(faces, len(rest))
    t_n = len(x)
    if not np.isfinite(x).all():
        z = np.zeros(t_n)
        return FrameStats(
            False, np.zeros((t_n, len(e))), z, z, z, z, np.full(len(e), t_n), np.full(len(e), t_n), z, x.shape[1]
        )
    l0 = np.linalg.norm(rest[e[:, 0]] - rest[e[:, 1]], axis=1)
    length = np.linalg.norm(x[:, e[:, 0]] - x[:, e[:, 1]], axis=2)
    strain = np.abs(length / np.maximum(l0, 1e-12) - 1)
    over_t = strain > spec.max_strain  # (T, E)
    if spec.min_stretch > 0:  # stretched by a few millimetres only: the solver's resolution, not a tear
        over_t &= length - l0 > spec.min_stretch
    proxy = None
    pen, pinch, far, slip = (np.zeros(t_n) for _ in range(4))
    slid = np.zeros(t_n) if anchors is not None else None
    n_comp, comp = connected_components(faces, len(rest))
    if on_body is not None:
        on_body = np.asarray(on_body, bool)
        if on_body.shape != (len(rest),):
            raise InputError("on_body must be (N,) bool", expected=(len(rest),), got=on_body.shape)
    tear_from = np.full(len(e), t_n)  # first frame an edge is over the limit where neither end is pinched
    pinch_from = np.full(len(e), t_n)  # ... where one end is
    if contact is not None:
        contact["closest"] = np.empty(x.shape, np.float32)
        contact["normal"] = np.empty(x.shape, np.float32)
    for t in range(t_n):
        proxy = BodyProxy(body_frames[t], body_faces) if proxy is None else proxy.moved(body_frames[t])
        q = proxy.query(x[t])
        inside = q.signed_distance < -spec.penetration_depth
        hot = np.flatnonzero(over_t[t])
        if parts is not None and (inside.any() or len(hot)):
            ask = np.union1d(np.flatnonzero(inside), e[hot].ravel())
            pin = np.zeros(len(x[t]), bool)
            pin[ask] = pinched(x[t][ask], np.maximum(-q.signed_distance[ask], 0.0), body_frames[t], parts)
            pinch[t] = float((inside & pin).mean())
            inside &= ~pin
            by_pinch = pin[e[hot, 0]] | pin[e[hot, 1]]
            pinch_from[hot[by_pinch]] = np.minimum(pinch_from[hot[by_pinch]], t)
            tear_from[hot[~by_pinch]] = np.minimum(tear_from[hot[~by_pinch]], t)
        else:
            tear_from[hot] = np.minimum(tear_from[hot], t)
        pen[t] = float(inside.mean())
        dist = np.abs(q.signed_distance)
        near = np.full(n_comp, np.inf)
        np.minimum.at(near, comp, dist)  # each piece's nearest vertex to the body
        lost = (near[comp] > spec.max_body_distance) | (dist > spec.max_vertex_distance)
        far[t] = float(lost.mean())
        if on_body is not None and on_body.any():
            slip[t] = float((dist[on_body] > spec.slip_distance).mean())
        if slid is not None and len(anchors.index):
            slid[t] = float(np.median(anchors.distance(x[t], np.asarray(body_frames[t], np.float64))))
        if contact is not None:
            contact["closest"][t], contact["normal"][t] = q.closest, q.normal
    jitter = np.zeros(max(t_n - 2, 0))
    if t_n >= 3:
        acc = np.linalg.norm(x[2:] - 2 * x[1:-1] + x[:-2], axis=2)  # (T-2, N)
        b = np.asarray(body_frames, np.float64)
        bacc = np.linalg.norm(b[2:] - 2 * b[1:-1] + b[:-2], axis=2).max(axis=1)  # (T-2,)
        jitter = (acc > 3 * bacc[:, None] + 0.01).sum(axis=1).astype(np.float64)
    return FrameStats(True, strain, pen, pinch, far, slip, tear_from, pinch_from, jitter, x.shape[1], slid)


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
    anchors: BodyAnchors | None = None,
) -> QualityReport:
    """Shapes: frames (T, N, 3), rest (N, 3), faces (F, 3), body_frames (T, V, 3) -> report.

    ``contact``: a dict that receives ``closest`` and ``normal`` (T, N, 3) float32, the closest
    body point and its outward normal for every vertex and frame (training's collision loss uses them).
    ``parts``: the body's parts (:class:`BodyParts`), to tell pinches (:func:`pinched`); without them
    every penetrating vertex and strained edge counts.
    ``on_body``: (N,) bool, the vertices that lie on the body at rest (:func:`on_body_at_rest`), for the
    slipped check; without it the check is skipped.  ``anchors``: where they lay on the body at rest
    (:func:`body_anchors`), for the slid check; without them it is skipped.

    The report is the verdict on the whole clip; its ``passing_frames`` is how many leading frames pass
    (:meth:`FrameStats.passing_prefix`), which a dataset with ``[quality] min_frames`` keeps of a clip that
    fails later on.
    """
    kw = {"contact": contact, "parts": parts, "on_body": on_body, "anchors": anchors}
    st = frame_stats(frames, rest, faces, body_frames, body_faces, spec, **kw)
    return st.report(spec)


def kept_frames(report: QualityReport, spec) -> int:
    """How many leading frames of a judged clip a dataset keeps: all when the whole clip passes, else its passing
    prefix when ``spec.min_frames`` (> 0) allows one that long, else 0 (rejected)."""
    if report.ok:
        return report.frames
    if spec.min_frames > 0 and report.passing_frames >= spec.min_frames:
        return report.passing_frames
    return 0
