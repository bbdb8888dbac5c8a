"""CMU's own motion capture format: an ASF skeleton (one per subject) and AMC motions (one per trial).

Reading (:func:`read_asf`, :func:`read_amc_values`, :func:`amc_skeleton`, :func:`read_amc`):

* **ASF** (Acclaim Skeleton File): ``:units`` (``mass``, ``length``, ``angle deg|rad``), ``:root``
  (``order`` of the root's AMC values, ``axis`` order, ``position``, ``orientation``), ``:bonedata``
  (``begin``/``end`` blocks with ``id``, ``name``, ``direction``, ``length``, ``axis AX AY AZ ORDER``,
  ``dof``, ``limits``, ``bodymass``, ``cofmass``) and ``:hierarchy`` (``parent child child ...`` lines).
  ``#`` starts a comment; commas and parentheses are white space.
* **AMC**: ``:FULLY-SPECIFIED`` (every bone with dofs in every frame; without it a bone left out of a frame
  keeps its previous values, zero before its first), ``:DEGREES`` / ``:RADIANS`` (default: the ASF's
  ``angle`` unit), then frames: a frame number and one line per bone, ``name v1 ... vk`` with one value
  per dof (the root's in its ``order``).  Frame numbers must run on by one.
* **Units** (:func:`metres_per_unit`): ``:units length L`` says a length ``x`` in the file is ``x / L``
  inches, so one file unit is ``0.0254 / L`` metres.  CMU's files say ``L = 0.45``: 0.05644 m per unit.
  The root's AMC translation is in the same unit.
* **Forward kinematics** (:func:`asf_forward_kinematics`): a bone's ``axis`` gives its local frame ``C``
  (a rotation in world axes at rest); its AMC values, Euler angles about the dof axes, give ``M``; its
  global rotation is ``G = G_parent C M C^-1``.  The Euler angles are applied in the order the dofs (and
  the axis letters) are listed: ``dof rx ry rz`` is ``M = Rz Ry Rx`` (``rx`` first).  The root is
  ``C_root M_root C_root^-1`` with ``C_root`` from ``orientation`` and ``axis``, at ``position`` plus its
  AMC translation.  A bone starts where its parent ends (the root has no length) and points along
  ``direction`` times ``length``, turned by ``G``.

The skeleton is returned as a :class:`~segadeform.motion.bvh.BVHSkeleton` (one joint per bone, at the
bone's start; end sites at the bone ends), so it maps onto SMPL and is retargeted by the same code as a
BVH file (:func:`segadeform.motion.bvh.skeleton_motion`; CMU's bone names are a table of
:mod:`segadeform.body.skeleton_map`: ``lhand`` starts at the wrist, ``lwrist`` is a forearm twist bone
folded into the elbow).  AMC files carry no frame rate: CMU captured at 120 fps, the default.

The conventions were checked against the data (``tests/motion/test_asf.py``): cgspeed's DAZ-style BVH
conversions of 16_15, 16_31 and 16_36 carry the AMC root rotation read this way to 1e-4 degrees in every
frame; its MotionBuilder-style 02_01 (another calibration of the subject) agrees on the posed body to
0.74 cm on average once the start is aligned, where the reversed Euler order is off by 6.9 cm.
"""

from __future__ import annotations

import dataclasses
import os
import re
from pathlib import Path

import numpy as np

from ..body.rotations import axis_angle_to_matrix
from ..errors import FileFormatError, file_error
from ..io.numbers import is_number, number
from .bvh import MAX_CHANNEL, BVHSkeleton, skeleton_motion, to_y_up
from .motion import Motion

__all__ = [
    "ASFSkeleton",
    "AMCValues",
    "read_asf",
    "read_amc_values",
    "amc_skeleton",
    "read_amc",
    "find_asf",
    "asf_forward_kinematics",
    "metres_per_unit",
    "CMU_FPS",
]

#: CMU's capture rate (frames per second); AMC files do not state one.
CMU_FPS = 120.0
_INCH = 0.0254
_ROT_DOFS = ("rx", "ry", "rz")
_ROOT_DOFS = ("tx", "ty", "tz", "rx", "ry", "rz")
_SECTIONS = (":version", ":name", ":units", ":documentation", ":root", ":bonedata", ":hierarchy", ":skin")
_FRAME_NUMBER = re.compile(r"[+-]?[0-9]{1,15}", re.ASCII)


@dataclasses.dataclass(frozen=True)
class ASFSkeleton:
    """An ASF skeleton (file units, file axes).

    Attributes:
        path: the ASF file.
        names: (J,) ``"root"`` then the bones, parents before children (depth first, in the hierarchy's order).
        parents: (J,) parent index, -1 for the root.
        directions: (J, 3) unit bone directions at rest (world axes; the root's is zero).
        lengths: (J,) bone lengths in file units (the root's is 0).
        axes: (J, 3, 3) each bone's local frame ``C`` (the root's from its ``orientation``).
        dofs: (J,) the AMC values of each bone, in file order: ``("rx", "rz")``; the root's are its
            ``order`` (``"tx" ... "rz"``).
        limits: (J,) ``((lo, hi), ...)`` per dof, in the file's angle unit, empty where none are given.
        position: (3,) the root's position offset, file units.
        length_unit: the ``:units length`` multiplier; angle: ``"deg"`` or ``"rad"`` (the ``:units angle``).
        lines: (J,) the line each bone is defined on (the root's ``:root`` line).
    """

    path: Path
    names: tuple
    parents: np.ndarray
    directions: np.ndarray
    lengths: np.ndarray
    axes: np.ndarray
    dofs: tuple
    limits: tuple
    position: np.ndarray
    length_unit: float
    angle: str
    lines: tuple

    @property
    def metres(self) -> float:
        """Metres per file length unit (:func:`metres_per_unit`)."""
        return metres_per_unit(self.length_unit)

    def rest(self) -> tuple[np.ndarray, np.ndarray]:
        """``(starts, ends)``: (J, 3) each bone's start and end at rest (file units, file axes)."""
        n = len(self.names)
        start, end = np.zeros((n, 3)), np.zeros((n, 3))
        for i in range(n):
            p = int(self.parents[i])
            start[i] = self.position if p < 0 else end[p]
            end[i] = start[i] + self.directions[i] * self.lengths[i]
        return start, end


def metres_per_unit(length_unit: float) -> float:
    """Metres per ASF length unit: a length ``x`` in the file is ``x / length_unit`` inches
    (CMU: ``length 0.45`` -> 0.0254 / 0.45 = 0.05644 m)."""
    return _INCH / float(length_unit)


# ---------------------------------------------------------------------------------------------------------
# ASF


def _read_text(path: Path, what: str) -> str:
    try:
        data = path.read_bytes()
    except OSError as e:
        raise file_error(e, path, what) from None
    if b"\0" in data:
        raise FileFormatError(f"not a text {what} file", path=path, expected="text", got="binary data")
    return data.decode("utf-8", errors="replace")


def _asf_lines(text: str):
    """(line number, tokens) of each non-empty line: comments cut, commas and parentheses as spaces."""
    table = str.maketrans({",": " ", "(": " ", ")": " "})
    for ln, line in enumerate(text.splitlines(), 1):
        if "#" in line:
            line = line[: line.index("#")]
        toks = line.translate(table).split()
        if toks:
            yield ln, toks


def _floats(toks, n, what, path, ln, *, allow_inf=False):
    if len(toks) != n:
        raise FileFormatError(
            f"{what} takes {n} number{'s' if n != 1 else ''}", path=path, line=ln, expected=n, got=len(toks)
        )
    out = []
    for t in toks:
        try:
            v = number(t)
        except ValueError:
            raise FileFormatError(f"{what} must be numbers", path=path, line=ln, expected="a number", got=t) from None
        if np.isnan(v) or (np.isinf(v) and not allow_inf):
            raise FileFormatError(f"{what} is not finite", path=path, line=ln, expected="a finite number", got=t)
        out.append(v)
    return out


def _rotation_order(tok: str, path, ln, what) -> str:
    order = tok.lower()
    if sorted(order) != ["x", "y", "z"]:
        raise FileFormatError(
            f"{what} order must be a permutation of XYZ", path=path, line=ln, expected="XYZ, ZYX, ...", got=tok
        )
    return order


def _euler(angles: np.ndarray, axes: str) -> np.ndarray:
    """Rotations about ``axes`` applied in the order listed: ``"xyz"`` is ``Rz Ry Rx`` (x first).

    Shapes:
        angles: (..., k) radians, k = len(axes) -> (..., 3, 3)
    """
    angles = np.asarray(angles, np.float64)
    R = np.broadcast_to(np.eye(3), angles.shape[:-1] + (3, 3)).copy()
    for k, ax in enumerate(axes):
        r = np.zeros(angles.shape[:-1] + (3,))
        r[..., "xyz".index(ax)] = angles[..., k]
        R = axis_angle_to_matrix(r) @ R
    return R


class _Bone:
    __slots__ = ("name", "line", "direction", "length", "axis", "order", "dofs", "limits")

    def __init__(self, line):
        self.line = line
        self.name = None
        self.direction = None
        self.length = None
        self.axis, self.order = (0.0, 0.0, 0.0), "xyz"
        self.dofs: tuple = ()
        self.limits: list = []


def read_asf(path: str | os.PathLike) -> ASFSkeleton:
    """Parse an ASF skeleton (module docstring); every error names the file and line."""
    p = Path(path)
    text = _read_text(p, "ASF skeleton")
    units = {"mass": 1.0, "length": 1.0, "angle": "deg"}
    root = {"order": None, "axis": "xyz", "position": [0.0, 0.0, 0.0], "orientation": [0.0, 0.0, 0.0], "line": None}
    bones: list[_Bone] = []
    hier: list[tuple[int, list[str]]] = []
    section, bone, in_block, limits_open = None, None, False, False
    seen_sections = set()
    for ln, toks in _asf_lines(text):
        key = toks[0].lower()
        if key.startswith(":"):
            if key not in _SECTIONS:
                raise FileFormatError(
                    f"unknown ASF keyword {toks[0]!r}", path=p, line=ln, expected=" ".join(_SECTIONS), got=toks[0]
                )
            if bone is not None:
                raise FileFormatError("bone block not closed", path=p, line=ln, expected="end", got=toks[0])
            if key in seen_sections and key in (":units", ":root", ":bonedata", ":hierarchy"):
                raise FileFormatError(f"{key} given twice", path=p, line=ln)
            seen_sections.add(key)
            section, in_block = key, False
            if key == ":root":
                root["line"] = ln
            continue
        if section is None:
            raise FileFormatError(
                "ASF data before any keyword",
                path=p,
                line=ln,
                expected=":version, :units, :root, :bonedata ...",
                got=toks[0],
            )
        if section in (":version", ":name", ":documentation", ":skin"):
            continue
        if section == ":units":
            if key in ("mass", "length"):
                v = _floats(toks[1:], 1, f"units {key}", p, ln)[0]
                if v <= 0:
                    raise FileFormatError(f"units {key} must be positive", path=p, line=ln, expected="> 0", got=v)
                units[key] = v
            elif key == "angle":
                if len(toks) != 2 or toks[1].lower() not in ("deg", "rad"):
                    raise FileFormatError(
                        "units angle must be deg or rad",
                        path=p,
                        line=ln,
                        expected="deg | rad",
                        got=" ".join(toks[1:]) or "nothing",
                    )
                units["angle"] = toks[1].lower()
            else:
                raise FileFormatError(
                    f"unknown unit {toks[0]!r}", path=p, line=ln, expected="mass, length, angle", got=toks[0]
                )
        elif section == ":root":
            if key == "order":
                order = tuple(t.lower() for t in toks[1:])
                if not order or any(t not in _ROOT_DOFS for t in order) or len(set(order)) != len(order):
                    raise FileFormatError(
                        "root order must list TX TY TZ RX RY RZ, each at most once",
                        path=p,
                        line=ln,
                        expected="e.g. TX TY TZ RX RY RZ",
                        got=" ".join(toks[1:]) or "nothing",
                    )
                root["order"] = order
            elif key == "axis":
                if len(toks) != 2:
                    raise FileFormatError(
                        "root axis takes one rotation order",
                        path=p,
                        line=ln,
                        expected="e.g. XYZ",
                        got=" ".join(toks[1:]) or "nothing",
                    )
                root["axis"] = _rotation_order(toks[1], p, ln, "root axis")
            elif key in ("position", "orientation"):
                root[key] = _floats(toks[1:], 3, f"root {key}", p, ln)
            else:
                raise FileFormatError(
                    f"unknown root entry {toks[0]!r}",
                    path=p,
                    line=ln,
                    expected="order, axis, position, orientation",
                    got=toks[0],
                )
        elif section == ":bonedata":
            if bone is None:
                if key != "begin":
                    raise FileFormatError("expected 'begin' of a bone", path=p, line=ln, expected="begin", got=toks[0])
                bone, limits_open = _Bone(ln), False
                continue
            if key == "end":
                _finish_bone(bone, p, ln)
                bones.append(bone)
                bone = None
                continue
            if limits_open and is_number(toks[0]):
                bone.limits.append((ln, toks))
                continue
            limits_open = False
            if key == "id":
                if len(toks) != 2:
                    raise FileFormatError("id takes one value", path=p, line=ln, expected=1, got=len(toks) - 1)
            elif key == "name":
                if len(toks) != 2:
                    raise FileFormatError(
                        "bone name must be one word", path=p, line=ln, got=" ".join(toks[1:]) or "nothing"
                    )
                bone.name = toks[1]
            elif key == "direction":
                bone.direction = _floats(toks[1:], 3, "direction", p, ln)
            elif key == "length":
                bone.length = _floats(toks[1:], 1, "length", p, ln)[0]
                if bone.length < 0:
                    raise FileFormatError("bone length is negative", path=p, line=ln, expected=">= 0", got=bone.length)
            elif key == "axis":
                if len(toks) != 5:
                    raise FileFormatError(
                        "axis takes three angles and an order",
                        path=p,
                        line=ln,
                        expected="e.g. axis 0 0 20 XYZ",
                        got=" ".join(toks[1:]) or "nothing",
                    )
                bone.axis = tuple(_floats(toks[1:4], 3, "axis", p, ln))
                bone.order = _rotation_order(toks[4], p, ln, "axis")
            elif key == "dof":
                dofs = tuple(t.lower() for t in toks[1:])
                bad = [d for d in dofs if d not in _ROT_DOFS]
                if not dofs or bad or len(set(dofs)) != len(dofs):
                    raise FileFormatError(
                        "dof must list rotations rx, ry, rz, each at most once",
                        path=p,
                        line=ln,
                        expected="e.g. dof rx ry rz (translation and length dofs are not read)",
                        got=" ".join(toks[1:]) or "nothing",
                    )
                bone.dofs = dofs
            elif key == "limits":
                limits_open = True
                if len(toks) > 1:
                    bone.limits.append((ln, toks[1:]))
            elif key in ("bodymass", "cofmass"):
                _floats(toks[1:], 1, key, p, ln)
            else:
                raise FileFormatError(
                    f"unknown bone entry {toks[0]!r}",
                    path=p,
                    line=ln,
                    expected="id, name, direction, length, axis, dof, limits, bodymass, cofmass",
                    got=toks[0],
                )
        elif section == ":hierarchy":
            if not in_block:
                if key != "begin":
                    raise FileFormatError(
                        "expected 'begin' of the hierarchy", path=p, line=ln, expected="begin", got=toks[0]
                    )
                in_block = True
                continue
            if key == "end":
                section = None
                continue
            if len(toks) < 2:
                raise FileFormatError(
                    "hierarchy line names a parent and no children",
                    path=p,
                    line=ln,
                    expected="parent child [child ...]",
                    got=toks[0],
                )
            hier.append((ln, toks))
    if bone is not None:
        raise FileFormatError("the file ends inside a bone block", path=p, expected="end", got="end of file")
    if section is None and not seen_sections:
        raise FileFormatError(
            "ASF is empty",
            path=p,
            expected="an ASF skeleton (:units, :root, :bonedata, :hierarchy)",
            got="no keywords" if text.strip() else "an empty file",
        )
    if root["order"] is None:
        raise FileFormatError(
            "ASF has no :root order",
            path=p,
            line=root["line"],
            expected="a :root section with order TX TY TZ RX RY RZ",
            got="none",
        )
    if not bones:
        raise FileFormatError(
            "ASF has no bones", path=p, expected="a :bonedata section with begin/end blocks", got="none"
        )
    if not hier:
        raise FileFormatError("ASF has no :hierarchy", path=p, expected="a :hierarchy section", got="none")
    return _assemble(p, units, root, bones, hier)


def _finish_bone(b: _Bone, path, ln) -> None:
    for what in ("name", "direction", "length"):
        if getattr(b, what) is None:
            raise FileFormatError(f"bone has no {what}", path=path, line=b.line, expected=what, got="none")
    if b.name.lower() == "root":
        raise FileFormatError("a bone may not be called root", path=path, line=b.line, got=b.name)
    d = np.asarray(b.direction, np.float64)
    n = float(np.linalg.norm(d))
    if n < 1e-9:
        raise FileFormatError(
            f"bone {b.name!r} has a zero direction",
            path=path,
            line=b.line,
            expected="a non-zero vector",
            got=b.direction,
        )
    b.direction = d / n
    lims = []
    for lln, toks in b.limits:
        vals = _floats(toks, len(toks), "limits", path, lln, allow_inf=True)
        if len(vals) % 2:
            raise FileFormatError("limits come in (min max) pairs", path=path, line=lln, got=len(vals))
        lims += [(vals[k], vals[k + 1]) for k in range(0, len(vals), 2)]
    if lims and len(lims) != len(b.dofs):
        raise FileFormatError(
            f"bone {b.name!r} has {len(b.dofs)} dofs and {len(lims)} limits",
            path=path,
            line=b.limits[0][0],
            expected=f"{len(b.dofs)} (min max) pairs",
            got=len(lims),
        )
    b.limits = tuple(lims)


def _assemble(p: Path, units, root, bones: list, hier) -> ASFSkeleton:
    by_name: dict[str, int] = {}
    for i, b in enumerate(bones):
        if b.name in by_name:
            raise FileFormatError(
                f"bone {b.name!r} is defined twice", path=p, line=b.line, expected="unique bone names", got=b.name
            )
        by_name[b.name] = i
    parent: dict[str, tuple[str, int]] = {}
    children: dict[str, list[str]] = {"root": []}
    for ln, toks in hier:
        par, kids = toks[0], toks[1:]
        if par != "root" and par not in by_name:
            raise FileFormatError(
                f"unknown bone {par!r} in the hierarchy",
                path=p,
                line=ln,
                expected="root or a bone of :bonedata",
                got=par,
            )
        for k in kids:
            if k not in by_name:
                raise FileFormatError(
                    f"unknown bone {k!r} in the hierarchy", path=p, line=ln, expected="a bone of :bonedata", got=k
                )
            if k in parent:
                raise FileFormatError(
                    f"bone {k!r} has two parents in the hierarchy",
                    path=p,
                    line=ln,
                    expected="one parent per bone",
                    got=f"{parent[k][0]} and {par}",
                )
            parent[k] = (par, ln)
            children.setdefault(par, []).append(k)
    for b in bones:  # every bone hangs from the root, through no cycle
        seen, cur = [b.name], b.name
        while cur != "root":
            if cur not in parent:
                raise FileFormatError(
                    f"bone {cur!r} is not connected to the root in the hierarchy",
                    path=p,
                    line=bones[by_name[cur]].line,
                    expected="a chain of parents up to root",
                    got=" <- ".join(seen),
                )
            cur, ln = parent[cur]
            if cur in seen:
                raise FileFormatError(
                    "the hierarchy has a cycle",
                    path=p,
                    line=ln,
                    expected="a tree under root",
                    got=" -> ".join([cur] + seen[seen.index(cur) :][::-1]),
                )
            seen.append(cur)
    order: list[str] = []
    stack = ["root"]
    while stack:  # depth first, children in the hierarchy's order
        n = stack.pop()
        order.append(n)
        stack.extend(reversed(children.get(n, [])))
    idx = {n: i for i, n in enumerate(order)}
    J = len(order)
    ang = np.pi / 180.0 if units["angle"] == "deg" else 1.0
    parents = np.array([-1] + [idx[parent[n][0]] for n in order[1:]], np.int64)
    directions, lengths, axes = np.zeros((J, 3)), np.zeros(J), np.zeros((J, 3, 3))
    axes[0] = _euler(np.asarray(root["orientation"]) * ang, root["axis"])
    dofs, limits, lines = [tuple(root["order"])], [()], [root["line"]]
    for i, n in enumerate(order[1:], 1):
        b = bones[by_name[n]]
        directions[i], lengths[i] = b.direction, b.length
        axes[i] = _euler(np.asarray(b.axis) * ang, b.order)
        dofs.append(b.dofs)
        limits.append(b.limits)
        lines.append(b.line)
    return ASFSkeleton(
        path=p,
        names=tuple(order),
        parents=parents,
        directions=directions,
        lengths=lengths,
        axes=axes,
        dofs=tuple(dofs),
        limits=tuple(limits),
        position=np.asarray(root["position"], np.float64),
        length_unit=float(units["length"]),
        angle=units["angle"],
        lines=tuple(lines),
    )


# ---------------------------------------------------------------------------------------------------------
# AMC


@dataclasses.dataclass(frozen=True)
class AMCValues:
    """An AMC file's values: ``values[name]`` is (T, k), the bone's dof values per frame in the file's angle
    unit (``angle``: ``"deg"`` or ``"rad"``); ``first_frame`` the first frame number; ``path`` the file."""

    path: Path
    values: dict
    first_frame: int
    n_frames: int
    angle: str
    fully_specified: bool


def read_amc_values(path: str | os.PathLike, skeleton: ASFSkeleton) -> AMCValues:
    """Parse an AMC against its ASF skeleton (module docstring); every error names the file and line."""
    p = Path(path)
    text = _read_text(p, "AMC motion")
    ndof = {n: len(d) for n, d in zip(skeleton.names, skeleton.dofs, strict=False)}
    required = frozenset(n for n, k in ndof.items() if k)
    tokens: dict[str, list] = {n: [] for n in skeleton.names}
    line_of: dict[str, list] = {n: [] for n in skeleton.names}  # the line of each of a bone's rows
    frame_lines: list[int] = []  # the line of each frame number
    angle, fully, first, seen = skeleton.angle, False, None, set()
    n_lines = len(text.splitlines())
    cut_short = bool(text) and not text.endswith(("\n", "\r"))  # a download or copy that stopped mid-line

    def at_end(ln: int) -> str:
        return " (the file ends there without a line break: is it cut short?)" if cut_short and ln == n_lines else ""

    def close_frame():
        if fully and len(seen) != len(required):
            missing = sorted(required - seen, key=skeleton.names.index)
            raise FileFormatError(
                f"frame {first + len(frame_lines) - 1} lacks bone {missing[0]!r}",
                path=p,
                line=frame_lines[-1],
                expected="every bone with dofs in each frame (:FULLY-SPECIFIED)",
                got=f"{len(seen)} of {len(required)} bones; missing {', '.join(missing[:4])}",
            )

    for ln, line in enumerate(text.splitlines(), 1):
        parts = line.split()
        if not parts:
            continue
        if "#" in line:
            parts = line[: line.index("#")].split()
            if not parts:
                continue
        head = parts[0]
        k = ndof.get(head)
        if k is not None and first is not None:  # a bone's values: most lines
            if len(parts) - 1 != k:
                dof = " ".join(skeleton.dofs[skeleton.names.index(head)]) or "none"
                raise FileFormatError(
                    f"wrong number of values for bone {head!r}{at_end(ln)}",
                    path=p,
                    line=ln,
                    expected=f"{k} (dof {dof} in {skeleton.path.name})",
                    got=len(parts) - 1,
                )
            if head in seen:
                raise FileFormatError(
                    f"bone {head!r} given twice in frame {first + len(frame_lines) - 1}",
                    path=p,
                    line=ln,
                    expected="each bone once per frame",
                    got=head,
                )
            seen.add(head)
            tokens[head] += parts[1:]
            line_of[head].append(ln)
            continue
        if len(parts) == 1 and _FRAME_NUMBER.fullmatch(head):
            num = int(head)
            if first is None:
                first = num
            elif num != first + len(frame_lines):
                raise FileFormatError(
                    "frame numbers are not consecutive",
                    path=p,
                    line=ln,
                    expected=f"frame {first + len(frame_lines)}",
                    got=f"frame {num}",
                )
            else:
                close_frame()
            frame_lines.append(ln)
            seen = set()
        elif head.startswith(":"):
            if first is not None:
                raise FileFormatError(
                    f"header keyword {head!r} among the frames",
                    path=p,
                    line=ln,
                    expected="a bone line or a frame number",
                    got=head,
                )
            kw = head.upper()
            if kw == ":FULLY-SPECIFIED":
                fully = True
            elif kw in (":DEGREES", ":RADIANS"):
                angle = "deg" if kw == ":DEGREES" else "rad"
            else:
                raise FileFormatError(
                    f"unknown AMC keyword {head!r}",
                    path=p,
                    line=ln,
                    expected=":FULLY-SPECIFIED, :DEGREES or :RADIANS",
                    got=head,
                )
        elif first is None:
            raise FileFormatError(
                "AMC data before the first frame number", path=p, line=ln, expected="a frame number (e.g. 1)", got=head
            )
        else:
            raise FileFormatError(
                f"bone {head!r} is not in the skeleton{at_end(ln)}",
                path=p,
                line=ln,
                expected=f"a bone of {skeleton.path.name}",
                got=head,
            )
    if first is None:
        raise FileFormatError(
            "AMC has no frames",
            path=p,
            expected="frame numbers followed by bone values",
            got="an empty file" if not text.strip() else "no frame numbers",
        )
    close_frame()
    n_frames = len(frame_lines)
    values = {}
    for n in skeleton.names:
        k = ndof[n]
        if not k:
            continue
        toks = tokens[n]
        try:
            v = np.fromiter(map(number, toks), np.float64, len(toks)).reshape(-1, k)
        except ValueError:
            bad = next(i for i, t in enumerate(toks) if not is_number(t))
            raise FileFormatError(
                f"bone {n!r} has a value that is not a number",
                path=p,
                line=line_of[n][bad // k],
                expected="a number",
                got=toks[bad],
            ) from None
        ok = np.isfinite(v)
        if not ok.all():
            r, c = (int(x[0]) for x in np.nonzero(~ok))
            raise FileFormatError(
                f"bone {n!r} has a value that is not finite",
                path=p,
                line=line_of[n][r],
                expected="finite numbers",
                got=toks[r * k + c],
            )
        # a value past MAX_CHANNEL (degrees, radians or length units): the BVH reader's bound, so that 1e20 is refused
        # here at its line as it is there (it played), and 1e300 not blamed on "bone lengths" after overflow warnings
        huge = np.abs(v) > MAX_CHANNEL
        if huge.any():
            r, c = (int(x[0]) for x in np.nonzero(huge))
            raise FileFormatError(
                f"bone {n!r} has a value no capture holds",
                path=p,
                line=line_of[n][r],
                expected=f"|{skeleton.dofs[skeleton.names.index(n)][c]}| <= {MAX_CHANNEL:g}",
                got=toks[r * k + c],
            )
        if len(v) == n_frames:
            values[n] = v
            continue
        # not fully specified: a bone keeps its previous values (zero before its first)
        frame = np.searchsorted(frame_lines, line_of[n]) - 1
        given = np.full(n_frames, -1, np.int64)
        given[frame] = np.arange(len(frame))
        last = np.maximum.accumulate(given)
        out = np.zeros((n_frames, k))
        out[last >= 0] = v[last[last >= 0]]
        values[n] = out
    return AMCValues(
        path=p, values=values, first_frame=int(first), n_frames=n_frames, angle=angle, fully_specified=fully
    )


# ---------------------------------------------------------------------------------------------------------
# forward kinematics


def asf_forward_kinematics(skeleton: ASFSkeleton, amc: AMCValues) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Global bone rotations and bone start and end positions per frame (module docstring).

    Returns:
        rotations (T, J, 3, 3) relative to the rest pose, starts (T, J, 3) and ends (T, J, 3) in file
        units and file axes.
    """
    T, J = amc.n_frames, len(skeleton.names)
    ang = np.pi / 180.0 if amc.angle == "deg" else 1.0
    G = np.empty((T, J, 3, 3))
    start, end = np.empty((T, J, 3)), np.empty((T, J, 3))
    for i, name in enumerate(skeleton.names):
        dofs = skeleton.dofs[i]
        v = amc.values.get(name, np.zeros((T, len(dofs))))
        rot = [k for k, d in enumerate(dofs) if d[0] == "r"]
        M = _euler(v[:, rot] * ang, "".join(dofs[k][1] for k in rot)) if rot else np.eye(3)
        C = skeleton.axes[i]
        local = C @ M @ C.T
        p = int(skeleton.parents[i])
        if p < 0:
            G[:, i] = local
            t = np.zeros((T, 3))
            for k, d in enumerate(dofs):
                if d[0] == "t":
                    t[:, "xyz".index(d[1])] = v[:, k]
            start[:, i] = skeleton.position + t
        else:
            G[:, i] = G[:, p] @ local
            start[:, i] = end[:, p]
        end[:, i] = start[:, i] + G[:, i] @ (skeleton.directions[i] * skeleton.lengths[i])
    return G, start, end


def _fk_reference(skeleton: ASFSkeleton, amc: AMCValues) -> tuple[np.ndarray, np.ndarray]:
    """The slow, obvious forward kinematics: one frame and one bone at a time with 4x4 matrices
    (bone frame to world ``W = W_parent Cp^-1 C M``; a bone's end at ``W (0, 0, 0, 1) + W_rot C^-1 d l``).
    For tests; returns starts and ends (T, J, 3)."""
    ang = np.pi / 180.0 if amc.angle == "deg" else 1.0

    def rot4(R):
        out = np.eye(4)
        out[:3, :3] = R
        return out

    def axis_rot(a, theta):
        c, s = np.cos(theta), np.sin(theta)
        i, j = [(1, 2), (2, 0), (0, 1)]["xyz".index(a)]
        R = np.eye(3)
        R[i, i], R[i, j], R[j, i], R[j, j] = c, -s, s, c
        return R

    T, J = amc.n_frames, len(skeleton.names)
    starts, ends = np.zeros((T, J, 3)), np.zeros((T, J, 3))
    for t in range(T):
        world = [None] * J
        for i, name in enumerate(skeleton.names):
            M = np.eye(3)
            trans = np.zeros(3)
            for k, d in enumerate(skeleton.dofs[i]):
                x = amc.values[name][t, k] if name in amc.values else 0.0
                if d[0] == "r":
                    M = axis_rot(d[1], x * ang) @ M
                else:
                    trans["xyz".index(d[1])] = x
            C = skeleton.axes[i]
            p = int(skeleton.parents[i])
            if p < 0:
                W = np.eye(4)
                W[:3, 3] = skeleton.position + trans
                W = W @ rot4(C @ M)
            else:
                Cp = skeleton.axes[p]
                shift = np.eye(4)
                shift[:3, 3] = Cp.T @ (skeleton.directions[p] * skeleton.lengths[p])
                W = world[p] @ shift @ rot4(Cp.T @ C @ M)
            world[i] = W
            starts[t, i] = W[:3, 3]
            ends[t, i] = W[:3, 3] + W[:3, :3] @ C.T @ (skeleton.directions[i] * skeleton.lengths[i])
    return starts, ends


# ---------------------------------------------------------------------------------------------------------
# onto SMPL


def find_asf(amc_path: str | os.PathLike) -> Path:
    """The ASF skeleton of an AMC when none is given: the one ``.asf`` in the AMC's folder, or, among
    several, ``SUBJECT.asf`` for ``SUBJECT_TRIAL.amc`` (CMU's naming)."""
    p = Path(amc_path)
    folder = p.parent
    if not p.is_file():  # the AMC itself first: a missing one was reported as a missing skeleton (a user's trial)
        try:
            p.open("rb").close()
        except OSError as e:
            raise file_error(e, p) from None
    try:
        found = sorted(q for q in folder.iterdir() if q.suffix.lower() == ".asf" and q.is_file())
    except OSError as e:
        raise file_error(e, folder, "folder") from None
    if len(found) == 1:
        return found[0]
    subject = p.stem.split("_")[0]
    named = [q for q in found if q.stem == subject]
    if len(named) == 1:
        return named[0]
    raise FileFormatError(
        "cannot tell which skeleton this AMC uses",
        path=p,
        expected=f"one .asf in {folder} (or {subject}.asf), or --skeleton SUBJECT.asf",
        got=", ".join(q.name for q in found[:6]) if found else "no .asf there",
    )


def amc_skeleton(
    path: str | os.PathLike,
    skeleton: str | os.PathLike | ASFSkeleton | None = None,
    *,
    fps: float = CMU_FPS,
    up: str = "y",
) -> BVHSkeleton:
    """An AMC motion on its ASF skeleton by forward kinematics, as a :class:`BVHSkeleton` in file units
    (one joint per bone at the bone's start, end sites at the bone ends; ``up``: the files' up axis,
    CMU's is y).  ``skeleton``: the ASF (a path or a parsed :class:`ASFSkeleton`); default: :func:`find_asf`."""
    p = Path(path)
    if not (np.isfinite(fps) and fps > 0):
        raise FileFormatError("fps must be positive", path=p, expected="> 0", got=fps)
    if not isinstance(skeleton, ASFSkeleton):
        skeleton = read_asf(find_asf(p) if skeleton is None else skeleton)
    amc = read_amc_values(p, skeleton)
    G, starts, ends = asf_forward_kinematics(skeleton, amc)
    rest_start, rest_end = skeleton.rest()
    if not (np.isfinite(rest_end).all() and np.isfinite(ends).all()):
        raise FileFormatError(
            "bone lengths or root positions are too large: positions overflow",
            path=p,
            expected="lengths and translations below 1e300",
            got="inf",
        )
    return to_y_up(skeleton.names, skeleton.parents, rest_start, rest_end, G, starts, fps, up)


def read_amc(
    path: str | os.PathLike,
    skeleton: str | os.PathLike | ASFSkeleton | None = None,
    *,
    rest_joints: np.ndarray | None = None,
    fps: float = CMU_FPS,
    up: str = "y",
    joint_map=None,
) -> Motion:
    """Read an AMC (with its ASF) onto the 24-joint SMPL skeleton, as :func:`~segadeform.motion.read_bvh`
    reads a BVH: the same mapping and retargeting.

    Args:
        skeleton: the ASF (default: :func:`find_asf`).
        rest_joints: (24, 3) the target body's rest joints (T-pose, metres): the motion is retargeted onto
            it, its translation scaled by the legs' ratio (:func:`~segadeform.body.retarget.limb_scale`);
            default: the capture's own proportions in metres (the ASF's length unit, :func:`metres_per_unit`).
        fps: the capture rate (AMC files do not state one; CMU's is 120).
        joint_map: SMPL name -> bone name for skeletons whose bones CMU's names do not cover.
    """
    p = Path(path)
    asf = skeleton if isinstance(skeleton, ASFSkeleton) else read_asf(find_asf(p) if skeleton is None else skeleton)
    sk = amc_skeleton(p, asf, fps=fps, up=up)
    m = skeleton_motion(
        sk,
        p,
        rest_joints=rest_joints,
        scale="auto" if rest_joints is not None else asf.metres,
        joint_map=joint_map,
        fmt="amc",
    )
    m.meta.update(skeleton=str(asf.path), length_unit=asf.length_unit, metres_per_unit=asf.metres)
    return m
