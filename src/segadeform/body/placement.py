"""How a garment sits on a body, and the checks that refuse one that does not (the runtime's, ``garment export``'s
and ``bundle``'s), with the plain unit/axis fix they suggest (:func:`fix_units_and_axes`).
"""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np

from ..errors import InputError
from ..io.writer import UNIT_SCALES
from .collision import BodyCollider, BodyProxy, push_out

__all__ = [
    "UNIT_SCALES",
    "fix_units_and_axes",
    "turn_about_up",
    "TURNS",
    "FACING",
    "facing_turn",
    "FitReport",
    "placement_report",
    "push_off_body",
    "PlacementError",
    "check_placement",
    "check_recorded_shape",
]


def _length(metres: float) -> str:
    """A distance as a message says it: centimetres under a metre, metres from there (a garment in centimetres read
    as metres was "10692.7 cm" from the body)."""
    return f"{100 * metres:.1f} cm" if abs(metres) < 1.0 else f"{metres:.2f} m"


def turn_about_up(degrees: float) -> np.ndarray:
    """The rotation ``(3, 3)`` by ``degrees`` about +Y (the up axis), counterclockwise seen from above: +Z (the
    body's front) goes to +X at 90."""
    t = np.radians(float(degrees))
    c, s = np.cos(t), np.sin(t)
    if abs(c) < 1e-12:
        c = 0.0
    if abs(s) < 1e-12:
        s = 0.0
    return np.array([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]])


def fix_units_and_axes(
    vertices, *, units: str | float | None = None, up: str = "y", scale: float = 1.0, offset=None, turn: float = 0.0
) -> np.ndarray:
    """A plain similarity: file units to metres, the file's up axis to +Y, a turn of ``turn`` degrees about it (about
    the origin, counterclockwise seen from above: :func:`turn_about_up`), an extra scale, then ``offset`` (metres,
    after the rest).

    ``up``: ``"y"`` (no change), ``"z"`` (Blender / 3ds Max: (x, y, z) -> (x, z, -y)), ``"-z"``, ``"x"``.

    Shapes:
        vertices: (N, 3) -> (N, 3)
    """
    v = np.asarray(vertices, np.float64)
    if v.ndim != 2 or v.shape[1] != 3:
        raise InputError("vertices must be (N, 3)", got=v.shape)
    if units is None:
        f = 1.0
    elif isinstance(units, str):
        if units not in UNIT_SCALES:
            raise InputError("unknown units", expected=", ".join(UNIT_SCALES), got=units)
        f = UNIT_SCALES[units]
    else:
        f = float(units)
        if not 1e-4 <= f <= 1e3:  # NaN too (units 0 was refused as "scale must be positive", 1e308 overflowed)
            raise InputError(
                "units out of range",
                expected=" | ".join(UNIT_SCALES) + " or metres per file unit (0.0001..1000)",
                got=units,
            )
    if not 1e-4 <= float(scale) <= 1e4:
        raise InputError("scale out of range", expected="a positive factor (0.0001..10000)", got=scale)
    f *= float(scale)
    rot = {
        "y": np.eye(3),
        "z": np.array([[1.0, 0, 0], [0, 0, 1.0], [0, -1.0, 0]]),
        "-z": np.array([[1.0, 0, 0], [0, 0, -1.0], [0, 1.0, 0]]),
        "x": np.array([[0, 1.0, 0], [-1.0, 0, 0], [0, 0, 1.0]]),
    }.get(up)
    if rot is None:
        raise InputError("unknown up axis", expected="y, z, -z or x", got=up)
    if not np.isfinite(turn):
        raise InputError("turn must be finite degrees", got=turn)
    if turn % 360:
        rot = turn_about_up(turn) @ rot
    with np.errstate(over="ignore", invalid="ignore"):
        out = (v @ rot.T) * f
    if not np.isfinite(out).all():
        raise InputError("the garment's coordinates overflow at this scale", expected="finite coordinates", got=f)
    if offset is not None:
        o = np.asarray(offset, np.float64).reshape(3)
        if not np.isfinite(o).all():
            raise InputError("offset must be finite", got=o)
        out = out + o
    return out


@dataclasses.dataclass(frozen=True)
class FitReport:
    """How a garment sits on a body: distances from the body surface (m) and the share inside it."""

    median_distance: float
    p90_distance: float
    inside_fraction: float
    deep_inside_fraction: float  # more than 1 cm inside
    garment_height: float
    body_height: float

    def line(self) -> str:
        return (
            f"median distance to the body {_length(self.median_distance)}, 90th percentile "
            f"{_length(self.p90_distance)}, {100 * self.inside_fraction:.1f} % of vertices inside "
            f"({100 * self.deep_inside_fraction:.1f} % deeper than 1 cm)"
        )


def placement_report(vertices, body_vertices, body_faces) -> FitReport:
    """Distances of garment ``vertices (N, 3)`` from a (rest) body surface, and the share inside."""
    v = np.asarray(vertices, np.float64)
    d = _RestBody(body_vertices, body_faces).signed_distance(v)
    ad = np.abs(d)
    bv = np.asarray(body_vertices)
    return FitReport(
        median_distance=float(np.median(ad)),
        p90_distance=float(np.percentile(ad, 90)),
        inside_fraction=float((d < 0).mean()),
        deep_inside_fraction=float((d < -0.01).mean()),
        garment_height=float(np.ptp(v[:, 1])),
        body_height=float(np.ptp(bv[:, 1])),
    )


def push_off_body(vertices, body_vertices, body_faces, margin: float) -> tuple[np.ndarray, int]:
    """Move vertices inside the (rest) body, or closer than ``margin`` (m), out along its normal.

    Shapes:
        vertices: (N, 3) -> (N, 3), and the number moved
    """
    if not (np.isfinite(margin) and 0 <= margin < 0.1):
        raise InputError("margin must be in [0, 0.1) metres", got=margin)
    # without the push-out's rule for buried skin (30 Nov 2026): garments made before it are made again the same
    return push_out(np.asarray(vertices, np.float64), BodyProxy(body_vertices, body_faces), float(margin), buried=False)


class _RestBody:
    """Exact signed distances to one (rest) body surface, for the placement checks: the compiled collider's query
    (the brute force's answer, :class:`~segadeform.body.collision.BodyCollider`), the tree built once for the dozens of
    readings of the garment a check tries.  (The checks used :class:`~segadeform.body.collision.BodyProxy`, the slow
    reference, whose ``k`` nearest centroids only approximate the closest triangle of a point far off the body: one
    check of a dress 3 cm off took 11.5 s, 2.6 s with the collider.)"""

    def __init__(self, vertices, faces) -> None:
        self.vertices = np.asarray(vertices, np.float64)
        self._collider = BodyCollider(self.vertices, faces)

    def signed_distance(self, points) -> np.ndarray:
        """Shapes: points (P, 3) -> (P,), negative inside."""
        p = np.asarray(points, np.float64).reshape(-1, 3)
        if not len(p):
            return np.zeros(0)
        return self._collider.query(p, self.vertices).signed_distance


class PlacementError(InputError):
    """A garment does not sit on the body it is to be animated on (units, axes, another body or pose)."""


def _stats(v, proxy, top, floor):
    d = proxy.signed_distance(v)
    return {
        "p20": float(np.percentile(np.abs(d), 20)),
        "median": float(np.median(np.abs(d))),
        "deep": float((d < -0.01).mean()),
        "outside_height": float(((v[:, 1] > top + 0.02) | (v[:, 1] < floor - 0.02)).mean()),
        "size": float(np.ptp(v, axis=0).max()),
    }


#: the fixes :func:`check_placement` names are those that leave a garment at least this large across (m), where any does
_HUMAN_SIZE = 0.25

#: a garment smaller than this across (m) is no garment of a human's: a file scaled wrongly (a user's skirt at 1/1000
#: passed the check once moved onto the body)
MIN_GARMENT_SIZE = 0.03


def _reading(units, up: str) -> tuple[str, str]:
    """A reading of a garment file in words and as ``garment fit`` options: ``(" --units cm --up z", "in cm with +z
    up")``; the file's own (metres, +Y up) parts are left out."""
    opts = (f" --units {units}" if units else "") + (f" --up {up}" if up != "y" else "")
    words = " ".join(x for x in ((f"in {units}" if units else ""), (f"with {_axis(up)} up" if up != "y" else "")) if x)
    return opts, words


def _axis(up: str) -> str:
    """An up axis as a message says it: ``+z``, ``-z``."""
    return up if up.startswith("-") else f"+{up}"


def _fits(st) -> bool:
    return (
        st["p20"] <= 0.05
        and st["deep"] <= 0.05
        and st["outside_height"] <= 0.02
        and st.get("size", MIN_GARMENT_SIZE) >= MIN_GARMENT_SIZE
    )


def _shape_text(b) -> str:
    return ",".join(f"{x:g}" for x in b) if np.abs(b).max(initial=0.0) > 0 else "0 (the default shape)"


def check_recorded_shape(recorded, betas, *, path=None) -> None:
    """Refuse a garment whose file records another body shape than ``betas`` (``recorded``: what
    :func:`segadeform.io.obj.recorded_betas` read; None: the file records none, nothing to check).  Shapes are
    compared with zeros appended to the shorter, to 1e-4: a garment made or fitted for one shape sits wrongly on
    another however well its geometry passes :func:`check_placement` (a skirt for a tall body lands on a short
    body's chest).

    Raises:
        PlacementError
    """
    if recorded is None:
        return
    a = np.asarray(recorded, np.float64).ravel()
    b = np.asarray(betas if betas is not None else (), np.float64).ravel()
    n = max(a.size, b.size)
    if np.allclose(np.pad(a, (0, n - a.size)), np.pad(b, (0, n - b.size)), rtol=0.0, atol=1e-4):
        return
    made, want = _shape_text(a), _shape_text(b)
    flag = f"--betas {','.join(f'{x:g}' for x in a)}" if np.abs(a).max(initial=0.0) > 0 else "no --betas"
    again = f" --betas {','.join(f'{x:g}' for x in b)}" if np.abs(b).max(initial=0.0) > 0 else ""
    raise PlacementError(
        f"the garment was made for body shape betas {made}, not for this body's betas {want}",
        path=path,
        expected=f"{flag} (the shape it was made for), the garment made or fitted again for this shape "
        f"(`segadeform garment fit SOURCE{again}`, `segadeform garment make KIND{again}`), or --force",
    )


def _centre_offset(v, bv) -> np.ndarray:
    """How far the middle of the garment's bounding box lies from the middle of the body's, across (x) and front
    to back (z), the body taken between the garment's lowest and highest vertex.  Shapes: v (N, 3), bv (M, 3) ->
    (3,) with y = 0."""
    band = bv[(bv[:, 1] >= v[:, 1].min()) & (bv[:, 1] <= v[:, 1].max())]
    if len(band) == 0:
        return np.zeros(3)
    off = (v.min(axis=0) + v.max(axis=0)) / 2 - (band.min(axis=0) + band.max(axis=0)) / 2
    off[1] = 0.0
    return off


def _check_centred(v, bv, proxy, top, floor, st, path) -> None:
    """Refuse a garment that passes the lenient test but sits off the body's middle by a wrong offset: its box's
    middle 8 cm or more from the body's (every garment made or fitted here is within 2 cm), and moved back it
    fits and lies clearly closer to the skin (median distance 2 cm or more less).  A garment that cannot be moved
    onto the middle (one sleeve, a bag on one side) is left alone: moved there it would sit inside the body."""
    off = _centre_offset(v, bv)
    if np.abs(off).max() < 0.08:
        return
    back = _stats(v - off, proxy, top, floor)
    if not (_fits(back) and back["median"] <= st["median"] - 0.02):
        return
    g = path if path is not None else "GARMENT"
    where = ", ".join(
        f"{100 * abs(d):.0f} cm {name[int(d > 0)]}"
        for d, name in ((off[0], ("to the body's right", "to the body's left")), (off[2], ("behind", "in front")))
        if abs(d) >= 0.01
    )
    raise PlacementError(
        f"the garment sits off the body's middle ({where}; median distance to the skin {_length(st['median'])}, "
        f"{_length(back['median'])} once moved back): it was placed with a wrong offset",
        path=path,
        expected=f"a garment around the body: run `segadeform garment fit {g} -o FIXED.obj --offset "
        f"{-off[0]:.2f},0.00,{-off[2]:.2f}`, or pass --force",
    )


def _offset_fix(v, bv, proxy, top, floor) -> tuple[np.ndarray, str] | None:
    """The move that puts a garment of a human's size onto the body, and its words; None when none does.

    Beside the body's vertical axis first (a garment moved sideways is not fixed by moving it down: a user's skirt
    0.4 m to the side was sent 0.65 m down, onto the floor by a foot), then up or down alone."""
    size = np.ptp(v, axis=0)
    if not MIN_GARMENT_SIZE <= size.max() < 2.0 * (top - floor):
        return None
    side = -_centre_offset(v, bv)  # across the body only: its left-right middle is its axis (front to back it is
    side[2] = 0.0  # not: the feet point forward)
    shifts = ([side] if np.abs(side).max() >= 0.1 else []) + [np.zeros(3)]
    for s in shifts:
        # of the heights that fit, the one where its closest fifth lies closest to the skin (the first from below was
        # named: a skirt 1 m to the side was sent back and 0.4 m down, onto the thighs, since that fit the lenient
        # test; the median distance put a loose skirt 10 cm high, its hem nearer the hips), and no height when the
        # move across alone fits
        fit = []
        if s.any() and _fits(_stats(v + s, proxy, top, floor)):  # the move across alone
            fit.append((0.0, 0.0, 0.0))
        else:
            for dy in np.round(np.arange(-1.5, 1.51, 0.05), 2):
                if abs(dy) > 0.1 or s.any():  # an origin is off (up to 10 cm: _small_offset_fix; a suit 20 cm up
                    # was between the two and told it was made for another body: a pipeline TD's trial)
                    st = _stats(v + s + np.array([0.0, dy, 0.0]), proxy, top, floor)
                    if _fits(st):
                        fit.append((st["p20"], abs(dy), dy))
        if fit:
            dy = min(fit)[2]
            off = s + np.array([0.0, dy, 0.0])
            where = (
                f"once moved {abs(dy):.2f} m {'higher' if dy > 0 else 'lower'}"
                + (" (it sits off the body)" if abs(dy) < 0.25 else "")  # (no other body's origin is that near)
                if not s.any()
                else f"once moved by {off[0]:.2f}, {off[1]:.2f}, {off[2]:.2f} m, onto the body's axis"
            )
            return off, where
    return None


def _small_offset_fix(v, bv, proxy, top, floor) -> tuple[np.ndarray, str] | None:
    """A garment a few centimetres off where it fits (moved by hand in a modelling tool, exported with a stray
    offset): the smallest move, across and front to back onto the body's middle and up or down by up to 10 cm, that
    makes it fit.  A dress 3 cm to the side was told to be read in dm, z up and turned (a 10 cm scrap at the feet),
    a skirt 2.5 cm back to move 35 cm down (a technical artist's trial).  Of the moves that fit, the one that leaves it
    closest to the skin (median distance, within 5 mm), the shortest."""
    centre = -_centre_offset(v, bv)
    cands = []
    c = np.round(centre, 2)  # the offsets as the advice prints them (rounded, one printed could fail: a review)
    for s in (c, np.array([c[0], 0.0, 0.0]), np.array([0.0, 0.0, c[2]]), np.zeros(3)):
        for dy in np.round(np.arange(-0.10, 0.101, 0.01), 2):
            off = s + np.array([0.0, dy, 0.0]) + 0.0  # + 0.0: no -0.00 printed
            if 0.005 <= np.abs(off).max() <= 0.25:
                st = _stats(v + off, proxy, top, floor)
                if _fits(st):
                    cands.append((round(st["median"], 3), float(np.linalg.norm(off)), tuple(off)))
    if not cands:
        return None
    best = min(c[0] for c in cands)  # within 5 mm of the closest to the skin, the shortest move
    off = np.array(min((c for c in cands if c[0] <= best + 0.005), key=lambda c: c[1])[2])
    parts = [
        f"{100 * abs(d):.0f} cm {words[int(d > 0)]}"
        for d, words in (
            (off[0], ("to the body's right", "to the body's left")),
            (off[1], ("lower", "higher")),
            (off[2], ("back", "forward")),
        )
        if abs(d) >= 0.005
    ]
    return off, "once moved " + ", ".join(parts) + " (it sits a little off the body)"


def _rank(st) -> tuple[float, float]:
    """How a fix is ranked against the others (the least first): the share of the garment left more than 1 cm inside
    the body (to the per cent), then its median distance from the skin.  A garment placed right has next to nothing
    deep; the median alone chose a suit scaled by 0.95 moved 7 cm up (2 % deep, closer to the skin) over scaled back
    (none deep: a pipeline TD's trial)."""
    return round(st["deep"], 2), st["median"]


def _near_scale_fix(v, proxy, top, floor) -> tuple[float, dict] | None:
    """A garment a few per cent too small or too large (scaled about the origin, at the feet): the scale, in steps of
    0.01 from 0.8 to 1.25 as the advice prints it, after which it sits closest to the skin (median distance), and its
    statistics; None when none makes it fit.  A suit scaled by 0.95 was told to move 7 cm up, which put 62 % of it
    inside the body, and the run then took that (a pipeline TD's trial)."""
    best = None
    for scale in np.round(np.arange(0.8, 1.2501, 0.01), 2):
        if scale == 1.0:
            continue
        st = _stats(v * scale, proxy, top, floor)
        if _fits(st) and (best is None or _rank(st) < _rank(best[1])):
            best = (float(scale), st)
    return best


#: the turns about the up axis (degrees, counterclockwise seen from above) :func:`check_placement` tries, and the
#: way a garment faces that sits on the body once turned by each (the body faces +z)
FACING = {90: "-x (the body's right)", 180: "-z (backward)", 270: "+x (the body's left)"}
TURNS = tuple(FACING)


def _turned_fixes(v, proxy, top, floor, what: str, g) -> list[tuple[tuple[float, float], float, int, str, str]]:
    """The fixes (as :func:`_check_placement` lists them) that turn the garment about the up axis (:data:`TURNS`),
    read as it is or in other units or up axis, and put it on the body: a garment facing another way than the body
    (+z).  A shirt turned 180 degrees, or a cm, z-up, +x-facing one (Unreal Engine's) read in cm with +z up, was sent
    to `--from-body` as made for another body (a new user's trial).  A turn changes no height: only the readings
    whose heights could fit are turned."""
    out: list[tuple[tuple[float, float], float, int, str, str]] = []
    for units in (None, "dm", "cm", "mm", "inch"):
        for up in ("y", "z", "-z"):
            read = fix_units_and_axes(v, units=units, up=up)
            outside = float(((read[:, 1] > top + 0.02) | (read[:, 1] < floor - 0.02)).mean())
            if outside > 0.02 or np.ptp(read, axis=0).max() < MIN_GARMENT_SIZE:
                continue
            for turn in TURNS:
                fst = _stats(read @ turn_about_up(turn).T, proxy, top, floor)
                if not _fits(fst):
                    continue
                opts, how = _reading(units, up)
                out.append(
                    (
                        _rank(fst),
                        fst["size"],
                        len(out),
                        f"the garment does not sit on the body ({what}); it does once "
                        + (f"read {how}, " if how else "")
                        + f"turned {turn} degrees about the up axis: it faces {FACING[turn]}, the body +z (forward)",
                        f"a garment facing the body's front: run `segadeform garment fit {g} -o FIXED.obj{opts} "
                        f"--turn {turn}`, or pass --force",
                    )
                )
    return out


def facing_turn(vertices, body_vertices, body_faces, *, max_points: int = 4000) -> int | None:
    """The turn about the up axis (:data:`TURNS`, degrees) that puts a garment read in metres with +Y up on the (rest)
    body by :func:`check_placement`'s measure, where it is not on it as it is: a garment facing another way (the one
    it then sits closest to the skin); None when it sits as it is, or no turn puts it there.

    Shapes:
        vertices: (N, 3), body_vertices: (M, 3), body_faces: (K, 3)
    """
    v = np.asarray(vertices, np.float64)
    if len(v) > max_points:
        v = v[np.linspace(0, len(v) - 1, max_points).astype(np.int64)]
    bv = np.asarray(body_vertices, np.float64)
    proxy = _RestBody(bv, body_faces)
    top, floor = float(bv[:, 1].max()), float(bv[:, 1].min())
    if _fits(_stats(v, proxy, top, floor)):
        return None
    fit = [(st["median"], t) for t in TURNS if _fits(st := _stats(v @ turn_about_up(t).T, proxy, top, floor))]
    return min(fit)[1] if fit else None


#: metres: a vertex in no face farther than this from the body at rest is refused (unless --force): it is no cloth,
#: and skinning swings it with the body by its distance times the turn (a fuzzer's vertex 9 km out moved 3.9 km in a
#: frame, with exit 0)
LOOSE_FAR = 1.0


def _check_loose(v: np.ndarray, used: np.ndarray, proxy, path) -> None:
    """Refuse vertices in no face (``~used``) farther than :data:`LOOSE_FAR` from the body ``proxy``, naming how many
    and the farthest."""
    loose = np.flatnonzero(~used)
    if not loose.size:
        return
    d = proxy.signed_distance(v[loose])
    far = loose[d > LOOSE_FAR]
    if not far.size:
        return
    k = int(far[np.argmax(d[d > LOOSE_FAR])])
    raise PlacementError(
        f"{far.size} {'vertex' if far.size == 1 else 'vertices'} in no face more than {_length(LOOSE_FAR)} from the "
        f"body (the farthest, vertex {k}, {_length(float(d.max()))} away): no cloth, and the skinning swings "
        f"{'it' if far.size == 1 else 'them'} with the body",
        path=path,
        expected="a garment without vertices in no face far off: delete them (Blender: Mesh > Clean Up > Delete "
        "Loose) and run again, or pass --force",
    )


def _check_placement(
    vertices,
    body_vertices,
    body_faces,
    *,
    path=None,
    max_points: int = 4000,
    template_vertices=None,
    betas=(),
    recorded_betas=None,
    faces=None,
) -> dict:
    """Refuse a garment that does not sit on the (rest) body, naming the likely cause and the fix.

    A garment sits on the body when the closest fifth of its vertices are within 5 cm of the skin, at
    most 5 % are more than 1 cm inside the body, and at most 2 % lie above the head or below the feet, and it
    is not 8 cm or more off the body's middle when moved back it would fit closer (a wrong ``--offset``).
    Otherwise the garment is tried in other units (dm, cm, mm, inch), with other up axes (z, -z) and moved
    up or down (another body's origin, e.g. SMPL's pelvis at y = 0); the first of those that fits is named
    in the error with its ``segadeform garment fit`` command, else the garment was made for another body
    or pose (``--mhclo`` or ``--from-body``).  With ``template_vertices`` (the body at betas 0) and ``betas`` (the
    shape ``body_vertices`` has), a garment that sits on the default shape is named as made for it: it needs
    making (or fitting) again for ``betas``, not another origin or units.  ``recorded_betas``: the shape the
    garment's file records (:func:`check_recorded_shape`), checked first.  ``faces``: the garment's; vertices in no
    face are then left out (stray vertices tipped the check and got the advice of another origin).
    ``forceable``: whether the caller's command skips the check with ``--force`` (``dataset make`` does not: its
    error gave that advice, and ``--force`` failed the same way); without, the advice is left out.

    Returns the statistics (``p20``, ``median`` distance in m, ``deep`` and ``outside_height`` fractions).

    Raises:
        PlacementError
    """
    check_recorded_shape(recorded_betas, betas, path=path)
    v = np.asarray(vertices, np.float64)
    bv = np.asarray(body_vertices, np.float64)
    proxy = _RestBody(bv, body_faces)
    given, used = v, None
    if faces is not None:
        fi = np.asarray(faces, np.int64).ravel()
        if fi.size and fi.min() >= 0 and fi.max() < len(v):
            used = np.zeros(len(v), bool)
            used[fi] = True
            v = v[used]
    if len(v) > max_points:
        v = v[np.linspace(0, len(v) - 1, max_points).astype(np.int64)]
    top, floor = float(bv[:, 1].max()), float(bv[:, 1].min())
    st = _stats(v, proxy, top, floor)
    if _fits(st):
        _check_centred(v, bv, proxy, top, floor, st, path)
        if used is not None:  # once the garment sits on the body (a garment in cm with a stray vertex among its
            # own was told to delete the vertex, not to be read in cm: a review)
            _check_loose(given, used, proxy, path)
        return st
    small = (
        f"{1000 * st['size']:.1f} mm across (a garment is at least {100 * MIN_GARMENT_SIZE:.0f} cm), "
        if st["size"] < MIN_GARMENT_SIZE
        else ""
    )
    what = small + (
        f"median distance to the body {100 * st['median']:.1f} cm (closest fifth beyond "
        f"{100 * st['p20']:.1f} cm), {100 * st['deep']:.1f} % of vertices more than 1 cm inside it, "
        f"{100 * st['outside_height']:.1f} % above the head or below the feet"
    )
    g = path if path is not None else "GARMENT"
    binding = Path(path).with_suffix(".mhclo") if path is not None else None
    if binding is not None and binding.is_file():  # a MakeHuman garment's own OBJ: its binding places it
        raise PlacementError(
            f"the garment does not sit on the body ({what}); it is a MakeHuman garment, placed on a body by the "
            f"binding beside it ({binding.name})",
            path=path,
            expected=f"a garment on this body: run `segadeform garment fit {g} -o FIXED.obj` (add --betas for "
            "a body shape), or pass --force",
        )
    b = np.asarray(betas if betas is not None else (), np.float64).ravel()
    if template_vertices is not None and b.size and np.abs(b).max() > 0:
        tv = np.asarray(template_vertices, np.float64)
        if _fits(_stats(v, _RestBody(tv, body_faces), float(tv[:, 1].max()), float(tv[:, 1].min()))):
            shape = ",".join(f"{x:g}" for x in b)
            raise PlacementError(
                f"the garment was made for the default body shape (betas 0), not for betas {shape} ({what})",
                path=path,
                expected=f"a garment made for betas {shape}: `segadeform garment make KIND --betas "
                f"{shape}`, `segadeform garment fit G.mhclo --betas {shape}`, or --force",
            )
    # every fix that puts the garment on the body -- a move (another body's origin), other units or up axis, a scale
    # -- and the one it sits closest to the skin after is named: the first that fit was named before, and a move
    # was asked first because a dress 1 m to the side also fit once read in dm (a 10 cm dress on the hips), but then
    # a top scaled by 0.1 fit once moved between the thighs (a 7 cm "garment" 5 cm from the skin: a user's trial);
    # read right, each sits as a garment does (median ~1 cm)
    fixes: list[
        tuple[tuple[float, float], float, int, str, str]
    ] = []  # (_rank after, size after, order, message, expected)
    for moved in (_offset_fix(v, bv, proxy, top, floor), _small_offset_fix(v, bv, proxy, top, floor)):
        if moved is None:
            continue
        off, where = moved
        fst = _stats(v + off, proxy, top, floor)
        fixes.append(
            (
                _rank(fst),
                fst["size"],
                len(fixes),
                f"the garment does not sit on the body ({what}); it does {where}"
                + (
                    ""
                    if "(it sits" in where
                    else ": it was placed for another body's origin (SMPL-fitted garments sit around SMPL's pelvis "
                    "at y = 0)"
                ),
                f"a garment on this body: run `segadeform garment fit {g} -o FIXED.obj "
                f"--offset {off[0]:.2f},{off[1]:.2f},{off[2]:.2f}` or `--from-body THEIR_BODY.obj`, "
                "or pass --force",
            )
        )
    for units in (None, "dm", "cm", "mm", "inch"):
        for up in ("y", "z", "-z"):
            if units is None and up == "y":
                continue
            fst = _stats(fix_units_and_axes(v, units=units, up=up), proxy, top, floor)
            if _fits(fst):
                opts, read = _reading(units, up)
                fixes.append(
                    (
                        _rank(fst),
                        fst["size"],
                        len(fixes),
                        f"the garment does not sit on the body ({what}); it does once read {read}",
                        f"metres, +Y up: run `segadeform garment fit {g} -o FIXED.obj{opts}`, or pass --force",
                    )
                )
    near = _near_scale_fix(v, proxy, top, floor)  # a garment a few % too small or large (scaled about the origin)
    if near is not None:
        scale, fst = near
        fixes.append(
            (
                _rank(fst),
                fst["size"],
                len(fixes),
                f"the garment does not sit on the body ({what}); it does once scaled by {scale:g} about the origin",
                f"a garment on this body: run `segadeform garment fit {g} -o FIXED.obj --scale {scale:g}`, or pass "
                "--force",
            )
        )
    for scale in (10.0, 100.0, 1000.0):  # a file scaled down (the units above scale it the other way)
        for up in ("y", "z", "-z"):
            fst = _stats(fix_units_and_axes(v, up=up, scale=scale), proxy, top, floor)
            if _fits(fst):
                opts = f" --scale {scale:g}" + (f" --up {up}" if up != "y" else "")
                fixes.append(
                    (
                        _rank(fst),
                        fst["size"],
                        len(fixes),
                        f"the garment does not sit on the body ({what}); it does once scaled by {scale:g}"
                        + (f" with {_axis(up)} up" if up != "y" else ""),
                        f"metres, +Y up: run `segadeform garment fit {g} -o FIXED.obj{opts}`, or pass --force",
                    )
                )
    if not fixes:  # nothing else puts it on the body: turned about the up axis (a garment facing another way)
        fixes = _turned_fixes(v, proxy, top, floor, what, g)
    if fixes:  # among the fixes that leave a garment of a human's size, if any does (a skirt 1 m to the side also sat
        # on the skin once read in dm, at 7 cm across, closer to it than the loose skirt moved back: a review)
        sized = [fx for fx in fixes if fx[1] >= _HUMAN_SIZE]
        if sized or st["size"] < _HUMAN_SIZE:  # a garment of a human's size is never told to shrink below one (a
            # dress 3 cm off was told to be read in dm: a 10 cm scrap at the feet, a technical artist's trial)
            _, _, _, message, expected = min(sized or fixes, key=lambda fx: (fx[0], fx[2]))
            raise PlacementError(message, path=path, expected=expected)
    raise PlacementError(
        f"the garment does not sit on the body ({what}); it was made for another body, pose or body shape (betas)",
        path=path,
        expected=f"a garment on this body: run `segadeform garment fit {g} -o FIXED.obj "
        "--from-body THEIR_BODY.obj` (MakeHuman clothes: --mhclo FILE), "
        "or pass --force",
    )


def _asset_source(path) -> tuple[str, tuple[float, ...]] | None:
    """For a garment asset at ``path`` (``.sgda``, ``.npz``): the mesh it was exported from -- its recorded
    ``source_name``, as a path beside the asset when that file is there with the recorded bytes, else the bare name
    (``MESH`` when none is recorded) -- and the body shape it was prepared for; None for a mesh or an unreadable
    file."""
    if path is None or Path(path).suffix.lower() not in (".sgda", ".npz"):
        return None
    from ..io.garment_asset import GarmentAsset

    try:
        a = GarmentAsset.load(path)
    except Exception:  # not an asset (or unreadable): the advice is left as it is
        return None
    name = a.source_name or "MESH"
    beside = Path(path).parent / name
    if a.source_name and a.source_sha256 and beside.is_file():
        from ..io.hashing import file_sha256

        try:
            if file_sha256(beside) == a.source_sha256:
                name = str(beside)
        except OSError:
            pass
    betas = tuple(float(x) for x in np.asarray(a.betas if a.betas is not None else (), np.float64).ravel())
    return name, betas


def _advice_for_asset(expected: str, path) -> str:
    """``expected`` with its ``segadeform garment fit`` command run on the mesh the garment asset at ``path`` was
    exported from, then exported again: `garment fit` reads meshes, not assets (a new user's trial ran the advice on
    a forced asset and got an error)."""
    cmd = f"`segadeform garment fit {path} "
    if cmd not in expected or "`" not in expected[expected.index(cmd) + len(cmd) :]:
        return expected
    found = _asset_source(path)
    if found is None:
        return expected
    name, betas = found
    shape = f" --betas {','.join(f'{x:g}' for x in betas)}" if any(betas) else ""
    i = expected.index(cmd)
    j = expected.index("`", i + len(cmd))  # the command's closing quote
    return (
        f"{expected[:i]}`segadeform garment fit {name} {expected[i + len(cmd) : j]}` on the mesh {path} was "
        f"exported from, then `segadeform garment export FIXED.obj -o ASSET.sgda{shape}`{expected[j + 1 :]}"
    )


def check_placement(vertices, body_vertices, body_faces, *, forceable: bool = True, **kw) -> dict:
    # the rule and its docs: _check_placement; without ``forceable``, the advice to pass --force left out; for a
    # garment asset, the advice to fit it made advice to fit the mesh it was exported from
    try:
        return _check_placement(vertices, body_vertices, body_faces, **kw)
    except InputError as e:
        advice = None if e.expected is None else _advice_for_asset(str(e.expected), kw.get("path"))
        if advice is not None and advice != str(e.expected):
            e = type(e)(e.problem, path=e.path, line=e.line, expected=advice, got=e.got)
            if forceable:
                raise e from None
        if forceable:
            raise

        def drop(t: str) -> str:
            return t.replace(", or pass --force", "").replace(", or --force", "")

        expected = None if e.expected is None else drop(str(e.expected))
        raise type(e)(drop(e.problem), path=e.path, line=e.line, expected=expected, got=e.got) from None


check_placement.__doc__ = _check_placement.__doc__
