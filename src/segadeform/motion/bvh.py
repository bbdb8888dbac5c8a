"""BVH motion files with SMPL- or Mixamo-named joints, read onto the SMPL skeleton, and written.

Reading:

* joint names are matched in three vocabularies: SMPL (``left_hip``), SMPL's
  short form (``L_Hip``) and Mixamo (``LeftUpLeg``, with or without a
  ``mixamorig:`` prefix).  All 24 SMPL joints must be found; extra joints of a
  known vocabulary (fingers, toe and head ends) are ignored; any other name is
  an error that lists the expected names.
* channels may come in any order and any Euler order (``Zrotation Xrotation
  Yrotation`` means ``R = Rz Rx Ry``); angles are degrees.
* rest-pose offsets: a BVH skeleton at zero rotation need not be in SMPL's
  T-pose (an A-pose, say).  Each joint's global rotation is corrected by the
  rotation that takes the target skeleton's rest bone direction onto the BVH
  rest bone direction, so the bones point where the file says; bone twist
  follows the file.
* units: ``scale="auto"`` reads centimetres when the rest skeleton is taller
  than 5 units (Mixamo exports are in cm), metres otherwise.
* translation: the root position per frame, scaled, minus the target's rest
  pelvis position, so the posed pelvis lands where the file puts it.

Writing: the 24-joint SMPL skeleton, offsets from rest joints, the root
with 6 channels (``Xposition Yposition Zposition Zrotation Yrotation
Xrotation``) and the others with 3.
"""

from __future__ import annotations

import os
import re
from pathlib import Path

import numpy as np

from ..body.rotations import axis_angle_to_matrix, euler_to_matrix, matrix_to_axis_angle, matrix_to_euler
from ..body.skeleton import SMPL_JOINT_NAMES, SMPL_PARENTS
from ..errors import FileFormatError, InputError
from ..io.atomic import atomic_open
from .motion import Motion

__all__ = ["read_bvh", "write_bvh", "MIXAMO_TO_SMPL", "SMPL_SHORT_NAMES"]

MIXAMO_TO_SMPL = {
    "Hips": "pelvis", "LeftUpLeg": "left_hip", "RightUpLeg": "right_hip", "Spine": "spine1",
    "LeftLeg": "left_knee", "RightLeg": "right_knee", "Spine1": "spine2", "LeftFoot": "left_ankle",
    "RightFoot": "right_ankle", "Spine2": "spine3", "LeftToeBase": "left_foot", "RightToeBase": "right_foot",
    "Neck": "neck", "LeftShoulder": "left_collar", "RightShoulder": "right_collar", "Head": "head",
    "LeftArm": "left_shoulder", "RightArm": "right_shoulder", "LeftForeArm": "left_elbow",
    "RightForeArm": "right_elbow", "LeftHand": "left_wrist", "RightHand": "right_wrist",
    "LeftHandMiddle1": "left_hand", "RightHandMiddle1": "right_hand",
}
SMPL_SHORT_NAMES = {
    "Pelvis": "pelvis", "L_Hip": "left_hip", "R_Hip": "right_hip", "Spine1": "spine1", "L_Knee": "left_knee",
    "R_Knee": "right_knee", "Spine2": "spine2", "L_Ankle": "left_ankle", "R_Ankle": "right_ankle",
    "Spine3": "spine3", "L_Foot": "left_foot", "R_Foot": "right_foot", "Neck": "neck", "L_Collar": "left_collar",
    "R_Collar": "right_collar", "Head": "head", "L_Shoulder": "left_shoulder", "R_Shoulder": "right_shoulder",
    "L_Elbow": "left_elbow", "R_Elbow": "right_elbow", "L_Wrist": "left_wrist", "R_Wrist": "right_wrist",
    "L_Hand": "left_hand", "R_Hand": "right_hand",
}
_FINGERS = {f"{s}Hand{f}{i}" for s in ("Left", "Right") for f in ("Thumb", "Index", "Middle", "Ring", "Pinky")
            for i in range(1, 5)}
_IGNORABLE = _FINGERS | {"HeadTop_End", "LeftToe_End", "RightToe_End", "End Site"}


_VOCABULARIES = {
    "smpl": {n: n for n in SMPL_JOINT_NAMES},
    "smpl-short": SMPL_SHORT_NAMES,
    "mixamo": MIXAMO_TO_SMPL,
}


def _strip(name: str) -> str:
    return re.sub(r"^mixamorig\d*[:_]", "", name)


def _vocabulary(names: list[str]) -> dict[str, str]:
    """The naming scheme matching the most joint names (the schemes overlap: Mixamo's
    ``Spine1`` is SMPL's ``spine2`` but SMPL-short's ``Spine1`` is ``spine1``)."""
    base = [_strip(n) for n in names]
    best = max(_VOCABULARIES.values(), key=lambda voc: sum(b in voc for b in base))
    return best


class _Joint:
    def __init__(self, name, parent):
        self.name, self.parent = name, parent
        self.offset = np.zeros(3)
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
            v = float(t)
        except ValueError:
            raise FileFormatError(f"expected a number for {what}", path=path, line=ln, got=t) from None
        if not np.isfinite(v):
            raise FileFormatError(f"{what} is not finite", path=path, line=ln, got=t)
        return v

    nxt("HIERARCHY")
    joints: list[_Joint] = []

    def parse_joint(parent_idx):
        ln, kw = tok[pos - 1]
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
                    n = int(n)
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
                parse_joint(idx)
            elif u == "END":
                nxt("Site")
                nxt("{")
                nxt("OFFSET")
                for _ in range(3):
                    num("End Site OFFSET")
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
        n_frames = int(nf)
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
        raise FileFormatError("BVH motion data does not match its declared size", path=path,
                              expected=f"{n_frames} frames x {n_ch} channels = {n_frames * n_ch} numbers",
                              got=len(rest))
    try:
        data = np.array([float(t) for _, t in rest], np.float64).reshape(n_frames, n_ch)
    except ValueError:
        bad = next((ln, t) for ln, t in rest if not _isfloat(t))
        raise FileFormatError("motion data has a non-numeric value", path=path, line=bad[0], got=bad[1]) from None
    if not np.isfinite(data).all():
        raise FileFormatError("motion data contains NaN or inf", path=path)
    return joints, data, ft


def _isfloat(t):
    try:
        float(t)
        return True
    except ValueError:
        return False


def _min_rotation(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Smallest rotation taking unit direction a to unit direction b."""
    a = a / max(np.linalg.norm(a), 1e-12)
    b = b / max(np.linalg.norm(b), 1e-12)
    axis = np.cross(a, b)
    s, c = np.linalg.norm(axis), float(np.dot(a, b))
    if s < 1e-9:
        if c > 0:
            return np.eye(3)
        perp = np.cross(a, [1.0, 0, 0])
        if np.linalg.norm(perp) < 1e-6:
            perp = np.cross(a, [0, 1.0, 0])
        return axis_angle_to_matrix(np.pi * perp / np.linalg.norm(perp))
    return axis_angle_to_matrix(axis / s * np.arctan2(s, c))


def read_bvh(path: str | os.PathLike, *, rest_joints: np.ndarray | None = None, scale: float | str = "auto") -> Motion:
    """Read a BVH onto the 24-joint SMPL skeleton (see the module docstring).

    Args:
        rest_joints: ``(24, 3)`` rest joints of the target body (bone
            directions and pelvis height); defaults to SMPL-like T-pose
            directions (each bone as in the file's own rest, i.e. no correction).
        scale: file units to metres, or ``"auto"``.
    """
    p = Path(path)
    try:
        text = p.read_text(encoding="utf-8", errors="replace")
    except OSError as e:
        raise FileFormatError(f"cannot read file: {e.strerror or e}", path=p) from None
    joints, data, frame_time = _parse(text, p)
    names = [j.name for j in joints]
    voc = _vocabulary(names)
    mapped: dict[str, int] = {}
    unknown = []
    for i, n in enumerate(names):
        base = _strip(n)
        c = voc.get(base)
        if c is None:
            if base not in _IGNORABLE:
                unknown.append(n)
            continue
        if c in mapped:
            raise FileFormatError(f"two joints map to SMPL joint {c!r}", path=p, got=f"{names[mapped[c]]}, {n}")
        mapped[c] = i
    missing = [n for n in SMPL_JOINT_NAMES if n not in mapped]
    if unknown or missing:
        what = []
        if unknown:
            what.append("unknown joint names: " + ", ".join(unknown[:8]) + (" ..." if len(unknown) > 8 else ""))
        if missing:
            what.append("missing SMPL joints: " + ", ".join(missing))
        raise FileFormatError("; ".join(what), path=p,
                              expected="SMPL names (" + ", ".join(SMPL_JOINT_NAMES) + "), their short forms "
                              "(L_Hip ...) or Mixamo names (Hips, LeftUpLeg, ...)")
    # per-frame local rotation and root position of every BVH joint
    nj, nf = len(joints), data.shape[0]
    local = np.broadcast_to(np.eye(3), (nf, nj, 3, 3)).copy()
    col = 0
    root_pos = np.zeros((nf, 3))
    for i, j in enumerate(joints):
        rot_axes = [c[0] for c in j.channels if c.endswith("rotation")]
        rot_cols = [col + k for k, c in enumerate(j.channels) if c.endswith("rotation")]
        pos_cols = {c[0]: col + k for k, c in enumerate(j.channels) if c.endswith("position")}
        if rot_axes:
            order = "".join(rot_axes)
            if len(order) == 3 and len(set(order)) == 3:
                local[:, i] = euler_to_matrix(np.deg2rad(data[:, rot_cols]), order)
            else:  # fewer (or repeated) rotation channels: multiply single-axis rotations in order
                for k, ax in enumerate(order):
                    r = np.zeros((nf, 3))
                    r[:, "xyz".index(ax)] = np.deg2rad(data[:, rot_cols[k]])
                    local[:, i] = local[:, i] @ axis_angle_to_matrix(r)
        if i == 0:
            for k, ax in enumerate("xyz"):
                root_pos[:, k] = data[:, pos_cols[ax]] if ax in pos_cols else j.offset[k]
        col += len(j.channels)
    glob = np.empty_like(local)
    rest_pos = np.zeros((nj, 3))
    for i, j in enumerate(joints):
        if j.parent < 0:
            glob[:, i] = local[:, i]
            rest_pos[i] = j.offset
        else:
            glob[:, i] = glob[:, j.parent] @ local[:, i]
            rest_pos[i] = rest_pos[j.parent] + j.offset
    height = float(np.ptp(rest_pos[:, 1])) if nj > 1 else 0.0
    if scale == "auto":
        scale_f = 0.01 if height > 5.0 else 1.0
    else:
        scale_f = float(scale)
        if not (np.isfinite(scale_f) and scale_f > 0):
            raise InputError("scale must be positive or 'auto'", got=scale)
    bvh_idx = np.array([mapped[n] for n in SMPL_JOINT_NAMES])
    bvh_rest = rest_pos[bvh_idx] * scale_f
    target = bvh_rest if rest_joints is None else np.asarray(rest_joints, np.float64)
    if target.shape != (24, 3):
        raise InputError("rest_joints must be (24, 3)", got=target.shape)
    # rest correction C_s: target bone direction -> BVH bone direction (global)
    children: dict[int, list[int]] = {}
    for s_i, par in enumerate(SMPL_PARENTS):
        if par >= 0:
            children.setdefault(int(par), []).append(s_i)
    corr = np.broadcast_to(np.eye(3), (24, 3, 3)).copy()
    for s_i in range(1, 24):
        kids = children.get(s_i, [])
        if len(kids) == 1:
            c = kids[0]
            corr[s_i] = _min_rotation(target[c] - target[s_i], bvh_rest[c] - bvh_rest[s_i])
        elif not kids:
            corr[s_i] = corr[int(SMPL_PARENTS[s_i])]
    g_smpl = glob[:, bvh_idx] @ corr[None]
    loc = np.empty_like(g_smpl)
    loc[:, 0] = g_smpl[:, 0]
    par = SMPL_PARENTS[1:]
    loc[:, 1:] = np.swapaxes(g_smpl[:, par], -1, -2) @ g_smpl[:, 1:]
    poses = matrix_to_axis_angle(loc).reshape(nf, 72)
    trans = root_pos * scale_f - target[0]
    return Motion(poses=poses, trans=trans, fps=1.0 / frame_time, name=p.stem)


def write_bvh(path: str | os.PathLike, motion: Motion, rest_joints: np.ndarray, *, scale: float = 1.0,
              order: str = "zyx", precision: int = 6) -> Path:
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
