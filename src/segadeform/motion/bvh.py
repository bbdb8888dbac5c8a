"""BVH motion files from any common humanoid skeleton, retargeted onto the SMPL skeleton of a body; and written.

Reading (:func:`read_bvh`):

* **any channel layout**: channels in any order and number per joint, any
  Euler order (``Zrotation Xrotation Yrotation`` means ``R = Rz Rx Ry``),
  degrees; position channels on any joint (they replace its OFFSET, as game
  rigs with six channels on every joint use them; where such a rig's OFFSETs
  are all zero, the channels' mean is the rest bone).  A UTF-8 byte order
  mark is skipped.
* **any humanoid naming**: :func:`segadeform.body.skeleton_map.map_skeleton`
  finds SMPL's joints (name tables for SMPL, Mixamo, the CMU conversions,
  Unity, Character Creator, Unreal, Xsens, VRM, Rigify, Rokoko; a rule that
  reads the skeleton's shape; ``joint_map`` for the rest).  Extra joints --
  eyes, face, fingers, toe ends, twist and share helpers, ``LHipJoint`` --
  are folded into the joints they hang from.
* **rest-pose differences** (T- vs A-pose, bone rolls, proportions) are
  retargeted by :func:`segadeform.body.retarget.retarget_to_smpl`.
* **units**: ``scale="auto"`` fits the file's legs to the target body's
  (:func:`~segadeform.body.retarget.limb_scale`), whatever the unit; the
  unit the file is most likely in (m, dm, cm, mm, inches or CMU's
  0.45-inch unit, judged from its leg length) is reported in
  ``Motion.meta["units"]``.  ``units="cm"`` (etc.) or a number uses that
  factor as it is (metres per file unit).
* **up axis**: ``up="auto"`` takes the rest skeleton's tallest axis of y and
  z; ``"y"``/``"z"`` force it.  Z-up files are turned to y-up.

Writing (:func:`write_bvh`): the 24-joint SMPL skeleton, offsets from rest
joints, the root with 6 channels (``Xposition Yposition Zposition Zrotation
Yrotation Xrotation``) and the others with 3.
"""

from __future__ import annotations

import dataclasses
import logging
import os
from pathlib import Path

import numpy as np

from ..body.retarget import limb_scale, retarget_to_smpl
from ..body.rotations import axis_angle_to_matrix, euler_to_matrix, matrix_to_axis_angle, matrix_to_euler
from ..body.skeleton import SMPL_JOINT_NAMES, SMPL_PARENTS
from ..body.skeleton_map import MIXAMO_TO_SMPL, SMPL_SHORT_NAMES, map_skeleton, read_joint_map
from ..errors import FileFormatError, InputError, file_error
from ..io.atomic import atomic_open
from ..io.numbers import integer, is_number, number
from .motion import Motion

__all__ = [
    "read_bvh",
    "write_bvh",
    "read_bvh_skeleton",
    "BVHSkeleton",
    "skeleton_motion",
    "to_y_up",
    "UNITS",
    "MIXAMO_TO_SMPL",
    "SMPL_SHORT_NAMES",
]

#: metres per file unit of the units a BVH file may be in (``units=`` in :func:`read_bvh`).
UNITS = {"m": 1.0, "dm": 0.1, "cm": 0.01, "mm": 0.001, "inch": 0.0254, "cmu": 0.0254 / 0.45}


def bvh_units(units):
    """``units`` (a name of :data:`UNITS` or metres per file unit, as text or a number) checked: returned as given,
    or refused as :class:`InputError` (the command line's ``--units``: a usage error naming the option)."""
    if units is None or units in UNITS:
        return units
    try:
        f = float(units)
    except (TypeError, ValueError):
        raise InputError("unknown units", expected=", ".join(UNITS) + " or metres per unit", got=units) from None
    if not (np.isfinite(f) and f > 0):
        raise InputError("units must be a positive number of metres per unit", got=units)
    return units


log = logging.getLogger(__name__)

_TYPICAL_LEGS_M = 1.64  # hip-knee-ankle, both legs, of an adult (metres); only for reporting the unit
Z_UP_TO_Y_UP = np.array([[1.0, 0, 0], [0, 0, 1.0], [0, -1.0, 0]])  # (x, y, z) -> (x, z, -y)


class _Joint:
    def __init__(self, name, parent):
        self.name, self.parent = name, parent
        self.offset = np.zeros(3)
        self.end: np.ndarray | None = None  # the first End Site's offset
        self.channels: list[str] = []


def _parse(text: str, path: Path):
    tok = [(ln, t) for ln, line in enumerate(text.splitlines(), 1) for t in line.split()]
    pos = 0

    def nxt(expect=None):
        nonlocal pos
        if pos >= len(tok):
            raise FileFormatError("BVH ends too early", path=path, expected=expect or "more data")
        ln, t = tok[pos]
        pos += 1
        if expect is not None and t.upper() != expect.upper():
            raise FileFormatError(f"unexpected token {t!r}", path=path, line=ln, expected=expect)
        return ln, t

    def num(what):
        ln, t = nxt()
        try:
            v = number(t)
        except ValueError:
            raise FileFormatError(f"expected a number for {what}", path=path, line=ln, got=t) from None
        if not np.isfinite(v):
            raise FileFormatError(f"{what} is not finite", path=path, line=ln, got=t)
        return v

    nxt("HIERARCHY")
    joints: list[_Joint] = []

    def parse_joint(parent_idx, depth=0):
        ln, kw = tok[pos - 1]
        if depth >= MAX_DEPTH:  # (a fuzzer's 2,000 nested joints: a RecursionError traceback; the root is level 1)
            raise FileFormatError(
                "joints nest too deeply", path=path, line=ln, expected=f"at most {MAX_DEPTH} levels", got="more"
            )
        _, name = nxt()
        j = _Joint(name, parent_idx)
        idx = len(joints)
        joints.append(j)
        nxt("{")
        while True:
            ln, t = nxt()
            u = t.upper()
            if u == "OFFSET":
                j.offset = np.array([num("OFFSET"), num("OFFSET"), num("OFFSET")])
            elif u == "CHANNELS":
                n_ln, n = nxt()
                try:
                    n = integer(n)
                except ValueError:
                    raise FileFormatError("bad channel count", path=path, line=n_ln, got=n) from None
                if not 0 <= n <= 6:
                    raise FileFormatError("channel count out of range", path=path, line=n_ln, expected="0..6", got=n)
                for _ in range(n):
                    c_ln, c = nxt()
                    if c.lower() not in ("xposition", "yposition", "zposition", "xrotation", "yrotation", "zrotation"):
                        raise FileFormatError(f"unknown channel {c!r}", path=path, line=c_ln)
                    j.channels.append(c.lower())
            elif u == "JOINT":
                parse_joint(idx, depth + 1)
            elif u == "END":
                nxt("Site")
                nxt("{")
                nxt("OFFSET")
                e = np.array([num("End Site OFFSET") for _ in range(3)])
                if j.end is None:
                    j.end = e
                nxt("}")
            elif t == "}":
                return
            else:
                raise FileFormatError(f"unexpected token {t!r} in joint {name!r}", path=path, line=ln)

    nxt("ROOT")
    parse_joint(-1)
    nxt("MOTION")
    nxt("Frames:")
    f_ln, nf = nxt()
    try:
        n_frames = integer(nf)
    except ValueError:
        raise FileFormatError("bad frame count", path=path, line=f_ln, got=nf) from None
    nxt("Frame")
    nxt("Time:")
    ft = num("Frame Time")
    if ft <= 0:
        raise FileFormatError("Frame Time must be positive", path=path, got=ft)
    n_ch = sum(len(j.channels) for j in joints)
    rest = tok[pos:]
    if n_frames < 1:
        raise FileFormatError("BVH has no frames", path=path, got=n_frames)
    if len(rest) != n_frames * n_ch:
        # a frame a line, as every exporter writes them: the first line with another count (a user's trial: a
        # value deleted on line 192 was reported at the Frames: line); else the Frames: line, which the data contradicts
        per_line: dict[int, int] = {}
        for ln, _ in rest:
            per_line[ln] = per_line.get(ln, 0) + 1
        off = [ln for ln, k in per_line.items() if k != n_ch]
        one_a_line = len(per_line) - len(off) >= len(per_line) / 2
        raise FileFormatError(
            "BVH motion data does not match its declared size"
            + (f" (this line has {per_line[off[0]]} numbers, a frame {n_ch})" if off and one_a_line else ""),
            path=path,
            line=off[0] if off and one_a_line else f_ln,
            expected=f"{n_frames} frames x {n_ch} channels = {n_frames * n_ch} numbers",
            got=f"{len(rest)} numbers"
            + (f", {len(rest) / n_ch:g} frames (cut short?)" if len(rest) < n_frames * n_ch else ""),
        )
    try:
        data = np.array([number(t) for _, t in rest], np.float64).reshape(n_frames, n_ch)
    except ValueError:
        bad = next((ln, t) for ln, t in rest if not is_number(t))
        raise FileFormatError("motion data has a non-numeric value", path=path, line=bad[0], got=bad[1]) from None
    if not np.isfinite(data).all():  # the first such number's line (a user's trial: the file alone was named)
        k = int(np.flatnonzero(~np.isfinite(data.ravel()))[0])
        raise FileFormatError(
            "motion data contains NaN or inf", path=path, line=rest[k][0], got=f"{rest[k][1]} (frame {k // n_ch})"
        )
    # a rotation past MAX_CHANNEL degrees: 1e308 overflowed into inf later, named without a line and with warnings
    # (positions have their own bound, the root's translation, with its own words)
    rot = np.array([c.endswith("rotation") for j in joints for c in j.channels], bool)
    huge = (np.abs(data) > MAX_CHANNEL) & rot[None, :]
    if huge.any():
        k = int(np.flatnonzero(huge.ravel())[0])
        raise FileFormatError(
            "motion data has a value no capture holds",
            path=path,
            line=rest[k][0],
            expected=f"|rotation| <= {MAX_CHANNEL:g} degrees",
            got=f"{rest[k][1]} (frame {k // n_ch})",
        )
    return joints, data, ft


#: the largest rotation channel read, in degrees (about 280,000 turns)
MAX_CHANNEL = 1.0e8
#: joints nested deeper than this are refused (a human's skeleton is about 10 deep, a hand's fingers add 4)
MAX_DEPTH = 256


@dataclasses.dataclass(frozen=True)
class BVHSkeleton:
    """A BVH file's skeleton and motion, by forward kinematics (file units, +Y up after ``up``); an ASF/AMC
    motion comes in the same form (:func:`segadeform.motion.asf.amc_skeleton`).

    Attributes:
        names: (J,) joint names; parents: (J,) parent index (-1: root).
        rest: (J, 3) rest joint positions (all rotations zero); ends: (J, 3) end-site positions
            (a joint's own position when it has none).
        rotations: (T, J, 3, 3) global joint rotations; positions: (T, J, 3) joint positions.
        fps: frames per second; up: the file's up axis ("y" or "z").
    """

    names: tuple
    parents: np.ndarray
    rest: np.ndarray
    ends: np.ndarray
    rotations: np.ndarray
    positions: np.ndarray
    fps: float
    up: str


def read_bvh_skeleton(path: str | os.PathLike, *, up: str = "auto") -> BVHSkeleton:
    """Parse a BVH and run its forward kinematics (no mapping to SMPL)."""
    p = Path(path)
    try:
        text = p.read_text(encoding="utf-8-sig", errors="replace")  # a UTF-8 byte order mark is dropped
    except OSError as e:
        raise file_error(e, p) from None
    joints, data, frame_time = _parse(text, p)
    nj, nf = len(joints), data.shape[0]
    local = np.broadcast_to(np.eye(3), (nf, nj, 3, 3)).copy()
    offs = np.broadcast_to(np.stack([j.offset for j in joints]), (nf, nj, 3)).copy()
    rest_offs = np.stack([j.offset for j in joints])  # (J, 3) the skeleton with every rotation zero
    col = 0
    for i, j in enumerate(joints):
        rot_axes = [c[0] for c in j.channels if c.endswith("rotation")]
        rot_cols = [col + k for k, c in enumerate(j.channels) if c.endswith("rotation")]
        pos_cols = {}
        for k, c in enumerate(j.channels):
            if c.endswith("position"):
                offs[:, i, "xyz".index(c[0])] = data[:, col + k]
                pos_cols["xyz".index(c[0])] = col + k
        if j.parent >= 0 and len(pos_cols) == 3 and not np.any(j.offset):
            # six channels on every joint and all OFFSETs zero (some game exporters): the bones are in the
            # position channels
            for ax, cc in pos_cols.items():
                rest_offs[i, ax] = data[:, cc].mean()
        if rot_axes:
            order = "".join(rot_axes)
            if len(order) == 3 and len(set(order)) == 3:
                local[:, i] = euler_to_matrix(np.deg2rad(data[:, rot_cols]), order)
            else:  # fewer (or repeated) rotation channels: multiply single-axis rotations in order
                for k, ax in enumerate(order):
                    r = np.zeros((nf, 3))
                    r[:, "xyz".index(ax)] = np.deg2rad(data[:, rot_cols[k]])
                    local[:, i] = local[:, i] @ axis_angle_to_matrix(r)
        col += len(j.channels)
    parents = np.array([j.parent for j in joints], np.int64)
    glob = np.empty_like(local)
    pos = np.empty((nf, nj, 3))
    rest = np.zeros((nj, 3))
    for i, j in enumerate(joints):
        if j.parent < 0:
            glob[:, i] = local[:, i]
            pos[:, i] = offs[:, i]
            rest[i] = rest_offs[i]
        else:
            glob[:, i] = glob[:, j.parent] @ local[:, i]
            pos[:, i] = pos[:, j.parent] + np.einsum("tij,tj->ti", glob[:, j.parent], offs[:, i])
            rest[i] = rest[j.parent] + rest_offs[i]
    ends = np.stack([rest[i] + (j.end if j.end is not None else 0.0) for i, j in enumerate(joints)])
    return to_y_up(tuple(j.name for j in joints), parents, rest, ends, glob, pos, 1.0 / frame_time, up)


def to_y_up(names, parents, rest, ends, rotations, positions, fps, up: str = "auto") -> BVHSkeleton:
    """A skeleton's forward kinematics (file axes) as a :class:`BVHSkeleton`, turned to +Y up.

    ``up``: the file's up axis, ``"y"``, ``"z"`` or ``"auto"`` (the rest skeleton's tallest axis of y and z).

    Shapes:
        rest, ends: (J, 3); rotations: (T, J, 3, 3); positions: (T, J, 3)
    """
    pos, glob = positions, rotations
    if up == "auto":
        allp = np.concatenate([rest, ends])
        up = "z" if np.ptp(allp[:, 2]) > 1.2 * np.ptp(allp[:, 1]) else "y"
    if up not in ("y", "z"):
        raise InputError("up must be 'auto', 'y' or 'z'", got=up)
    if up == "z":
        Q = Z_UP_TO_Y_UP
        rest, ends, pos = rest @ Q.T, ends @ Q.T, pos @ Q.T
        glob = Q @ glob @ Q.T
    return BVHSkeleton(
        names=tuple(names),
        parents=np.asarray(parents, np.int64),
        rest=rest,
        ends=ends,
        rotations=glob,
        positions=pos,
        fps=float(fps),
        up=up,
    )


def guess_units(leg_length: float) -> str:
    """The unit in :data:`UNITS` that makes both legs (hip-knee-ankle) closest to an adult's."""
    return min(UNITS, key=lambda u: abs(np.log(max(leg_length, 1e-12) * UNITS[u] / _TYPICAL_LEGS_M)))


def read_bvh(
    path: str | os.PathLike,
    *,
    rest_joints: np.ndarray | None = None,
    scale: float | str = "auto",
    units: str | float | None = None,
    up: str = "auto",
    joint_map=None,
) -> Motion:
    """Read a BVH onto the 24-joint SMPL skeleton (see the module docstring).

    Args:
        rest_joints: ``(24, 3)`` rest joints of the target body (T-pose, metres); defaults to the
            file's own mapped joints (no rest correction, file proportions).
        scale: metres per file unit, or ``"auto"`` (fit the legs to ``rest_joints``; without
            ``rest_joints``, the guessed unit).  ``units`` (a key of :data:`UNITS` or a number)
            overrides it.
        up: the file's up axis: ``"auto"``, ``"y"`` or ``"z"``.
        joint_map: SMPL name -> file joint name (a dict, or a TOML/JSON file path) for skeletons
            the tables and the shape rule do not cover.

    ``Motion.meta`` records the mapping scheme, the SMPL joints filled in (virtual), the file's
    joints left out, the guessed unit and the scale used.
    """
    p = Path(path)
    return skeleton_motion(
        read_bvh_skeleton(p, up=up), p, rest_joints=rest_joints, scale=scale, units=units, joint_map=joint_map
    )


def skeleton_motion(
    sk: BVHSkeleton,
    path: Path,
    *,
    rest_joints: np.ndarray | None = None,
    scale: float | str = "auto",
    units: str | float | None = None,
    joint_map=None,
    fmt: str = "bvh",
) -> Motion:
    """A mocap skeleton's motion (:class:`BVHSkeleton`, from a BVH or an ASF/AMC) mapped onto SMPL's joints
    (:func:`~segadeform.body.skeleton_map.map_skeleton`) and retargeted onto ``rest_joints``
    (:func:`~segadeform.body.retarget.retarget_to_smpl`); the arguments as for :func:`read_bvh`, ``path``
    for messages and the motion's name, ``fmt`` recorded in ``Motion.meta["format"]``."""
    p = Path(path)
    if joint_map is not None and not isinstance(joint_map, dict):
        joint_map = read_joint_map(joint_map)
    try:
        mapping = map_skeleton(sk.names, sk.parents, sk.rest, leaf_ends=sk.ends, joint_map=joint_map, path=p)
    except FileFormatError:
        raise
    except InputError as e:
        raise FileFormatError(e.problem, path=p, expected=e.expected, got=e.got) from None
    src = mapping.source
    legs = 0.0
    for a, b, c in ((1, 4, 7), (2, 5, 8)):
        legs += np.linalg.norm(sk.rest[src[a]] - sk.rest[src[b]]) + np.linalg.norm(sk.rest[src[b]] - sk.rest[src[c]])
    unit_guess = guess_units(legs)
    if units is not None:
        if isinstance(units, str) and units in UNITS:
            scale_f = UNITS[units]
        else:
            try:
                scale_f = float(units)
            except (TypeError, ValueError):
                raise InputError("unknown units", expected=", ".join(UNITS) + " or a number", got=units) from None
    elif scale == "auto":
        scale_f = UNITS[unit_guess] if rest_joints is None else None
    else:
        scale_f = float(scale)
    if scale_f is not None and not (np.isfinite(scale_f) and scale_f > 0):
        raise InputError("scale must be positive", got=scale_f)
    if units is not None and scale_f is not None:  # given units that make no adult's legs: said, not refused
        legs_m = legs * scale_f
        if not (_TYPICAL_LEGS_M / 3 <= legs_m <= 3 * _TYPICAL_LEGS_M):
            log.warning(
                "%s: units %s make the legs %.3g m long (an adult's are about %.1f m, both legs); the skeleton's "
                "legs look like units %s (leave --units out to fit them)",
                p.name,
                units,
                legs_m,
                _TYPICAL_LEGS_M,
                unit_guess,
            )
    if rest_joints is None:
        # the file's own skeleton: mapped joints, virtual ones between their neighbours
        target = _own_rest(sk.rest, src) * scale_f
    else:
        target = np.asarray(rest_joints, np.float64)
        if target.shape != (24, 3) or not np.isfinite(target).all():
            raise InputError("rest_joints must be a finite (24, 3) array", got=target.shape)
        if scale_f is None:
            try:
                scale_f = limb_scale(sk.rest, src, target)
            except InputError as e:
                raise FileFormatError(e.problem, path=p, got=e.got) from None
    turn = facing_turn(sk.rest, src)
    if turn is None:
        rot, trans = retarget_to_smpl(src, sk.rest, sk.rotations, sk.positions, target, scale_f)
    else:  # retargeted facing +Z, as SMPL's rest does, then the whole motion turned back (its world heading kept)
        rot, trans = retarget_to_smpl(
            src, sk.rest @ turn.T, turn @ sk.rotations @ turn.T, sk.positions @ turn.T, target, scale_f
        )
        rot[:, 0] = turn.T @ rot[:, 0]
        trans = (target[0] + trans) @ turn - target[0]
    poses = matrix_to_axis_angle(rot).reshape(len(rot), 72)
    meta = {
        "format": fmt,
        "scheme": mapping.scheme,
        "mapped": mapping.mapped(),
        "found_by": mapping.how(),
        "virtual": mapping.virtual,
        "ignored": mapping.ignored,
        "units_guess": unit_guess,
        "scale": float(scale_f),
        "up": sk.up,
        "source_fps": float(sk.fps),
    }
    try:  # the frame rate and root travel within physical bounds (segadeform.bounds), naming the file
        return Motion(poses=poses, trans=trans, fps=sk.fps, name=p.stem, meta=meta)
    except InputError as e:
        raise FileFormatError(e.problem, path=p, expected=e.expected, got=e.got) from None


def facing_turn(rest: np.ndarray, src: np.ndarray, *, min_degrees: float = 0.5) -> np.ndarray | None:
    """The turn about +Y that makes a source skeleton's rest face +Z as SMPL's does (its left hip towards +X; the
    shoulders where the hips are not mapped), or ``None`` when it does already (within ``min_degrees``) or they give
    no direction.

    The retargeting matches bone directions, which leaves a vertical bone's turn about itself free: a rest that faces
    +X (an FBX character turned in its file) would give the spine, neck and knees a quarter-turn twist of their own
    (a review measured 90 degrees).  Retargeted facing +Z and turned back, the motion keeps its heading in the world.
    Every CMU skeleton here faces +Z already (turn ``None``).

    Shapes:
        rest: (J, 3) source rest joints (+Y up); src: (24,) source joint per SMPL joint (-1: none) -> (3, 3) or None
    """
    left = None
    for a, b in ((1, 2), (16, 17)):  # SMPL's left and right hip, else left and right shoulder
        if src[a] >= 0 and src[b] >= 0:
            d = rest[src[a]] - rest[src[b]]
            if np.hypot(d[0], d[2]) > 1e-3 * max(float(np.linalg.norm(d)), 1e-12):
                left = d
                break
    if left is None:
        return None
    theta = np.arctan2(-left[2], left[0])  # the source's left is R_y(theta) applied to +X
    if abs(np.degrees(theta)) < min_degrees:
        return None
    c, s = np.cos(-theta), np.sin(-theta)
    return np.array([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]])  # R_y(-theta): the source's left onto +X


def _own_rest(rest: np.ndarray, src: np.ndarray) -> np.ndarray:
    """(24, 3) rest joints from a file's mapped joints; a virtual joint sits between its neighbours."""
    from ..body.retarget import smpl_children

    out = np.zeros((24, 3))
    children = smpl_children()
    for j in range(24):
        if src[j] >= 0:
            out[j] = rest[src[j]]
    for j in range(24):
        if src[j] >= 0:
            continue
        par = int(SMPL_PARENTS[j])
        c, n = j, 1
        while src[c] < 0 and len(children[c]) == 1:
            c, n = children[c][0], n + 1
        out[j] = out[par] + (out[c] - out[par]) / n if src[c] >= 0 else out[par]
    return out


def write_bvh(
    path: str | os.PathLike,
    motion: Motion,
    rest_joints: np.ndarray,
    *,
    scale: float = 1.0,
    order: str = "zyx",
    precision: int = 6,
) -> Path:
    """Write ``motion`` on the SMPL skeleton with ``rest_joints (24, 3)`` as a BVH, atomically.

    ``scale`` converts metres to file units (100 for centimetres).
    """
    rj = np.asarray(rest_joints, np.float64)
    if rj.shape != (24, 3) or not np.isfinite(rj).all():
        raise InputError("rest_joints must be a finite (24, 3) array", got=rj.shape)
    order = order.lower()
    if sorted(order) != ["x", "y", "z"]:
        raise InputError("order must be a permutation of xyz", got=order)
    ch = " ".join(f"{a.upper()}rotation" for a in order)
    children: dict[int, list[int]] = {}
    for s_i, par in enumerate(SMPL_PARENTS):
        if par >= 0:
            children.setdefault(int(par), []).append(s_i)
    lines = ["HIERARCHY"]
    dfs: list[int] = []  # motion columns follow the order joints appear in the hierarchy

    def emit(j, depth):
        dfs.append(j)
        ind = "  " * depth
        off = rj[j] * scale if j == 0 else (rj[j] - rj[SMPL_PARENTS[j]]) * scale
        lines.append(f"{ind}{'ROOT' if j == 0 else 'JOINT'} {SMPL_JOINT_NAMES[j]}")
        lines.append(f"{ind}{{")
        lines.append(f"{ind}  OFFSET {off[0]:.{precision}f} {off[1]:.{precision}f} {off[2]:.{precision}f}")
        lines.append(f"{ind}  CHANNELS {'6 Xposition Yposition Zposition ' if j == 0 else '3 '}{ch}")
        for c in children.get(j, []):
            emit(c, depth + 1)
        if not children.get(j):
            lines.append(f"{ind}  End Site")
            lines.append(f"{ind}  {{")
            lines.append(f"{ind}    OFFSET 0 {0.05 * scale:.{precision}f} 0")
            lines.append(f"{ind}  }}")
        lines.append(f"{ind}}}")

    emit(0, 0)
    R = axis_angle_to_matrix(motion.poses.reshape(-1, 24, 3))
    eul = np.rad2deg(matrix_to_euler(R, order))  # (T, 24, 3)
    root = (motion.trans + rj[0]) * scale
    lines += ["MOTION", f"Frames: {motion.n_frames}", f"Frame Time: {1.0 / motion.fps:.8f}"]
    fmt = f"%.{precision}f"
    for t in range(motion.n_frames):
        vals = np.concatenate([root[t], eul[t][dfs].ravel()])
        lines.append(" ".join(fmt % x for x in vals))
    p = Path(path)
    with atomic_open(p, "w", encoding="utf-8", newline="\n") as fh:
        fh.write("\n".join(lines) + "\n")
    return p
