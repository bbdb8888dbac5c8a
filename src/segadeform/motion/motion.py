"""The Motion container, AMASS-style ``.npz`` IO, resampling and motion windows."""

from __future__ import annotations

import dataclasses
import os
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from ..body.rotations import (
    axis_angle_to_matrix,
    axis_angle_to_quaternion,
    canonical_axis_angle,
    quaternion_slerp,
    quaternion_to_axis_angle,
)
from ..body.skeleton import SMPL_JOINT_NAMES
from ..bounds import check_pose_angles, frames_between, resample_positions
from ..errors import FileFormatError, InputError
from ..io.atomic import atomic_path
from ..io.sgdm import read_motion_arrays, write_motion_arrays

__all__ = [
    "Motion",
    "load_motion_npz",
    "feet_on_floor",
    "floor_shift",
    "face_forward",
    "resample",
    "motion_windows",
    "history_inputs",
    "N_POSE",
    "SMPL_PELVIS",
    "sample_frames",
    "drop_leading_jumps",
    "drop_leading_tpose",
    "joint_speeds",
    "drop_leading_glitches",
    "repair_glitches",
    "repair_capture",
    "ramp_in",
]

N_POSE = 72  # 24 SMPL joints x axis-angle


@dataclasses.dataclass(frozen=True, eq=False)
class Motion:
    """A body motion on the 24-joint SMPL skeleton.

    Attributes:
        poses: (T, 72) axis-angle per joint, root first, relative to the rest pose (angles in [0, pi]: others
            are rewritten as the same rotation, :func:`~segadeform.body.rotations.canonical_axis_angle`)
        trans: (T, 3) root translation, metres
        fps: frames per second
        betas: (B,) body shape the motion was captured with, or None
        name: a label (file name or procedural kind)
        meta: what reading the file found and did (format, joint mapping, units, up axis ...)
    """

    poses: np.ndarray
    trans: np.ndarray
    fps: float
    betas: np.ndarray | None = None
    name: str = ""
    meta: dict | None = None

    def __post_init__(self):
        from ..bounds import check_fps, check_translation

        p, t = np.asarray(self.poses), np.asarray(self.trans)
        if p.ndim != 2 or p.shape[1] != N_POSE or p.shape[0] < 1:
            raise InputError("poses must be (T, 72) with T >= 1", expected="(T, 72)", got=p.shape)
        if t.shape != (p.shape[0], 3):
            raise InputError("trans must be (T, 3) matching poses", expected=(p.shape[0], 3), got=t.shape)
        for what, a in (("poses", p), ("trans", t)):  # complex numbers would be cast with only a warning
            if a.dtype.kind not in "biuf":
                raise InputError(f"{what} must be real numbers", expected="float", got=str(a.dtype))
        if not (np.isfinite(p).all() and np.isfinite(t).all()):
            raise InputError("motion contains NaN or inf")
        check_pose_angles(p)
        check_fps(self.fps)
        check_translation(t, fps=self.fps)
        # equal rotations written alike (angles in [0, pi]): the network reads axis-angle; in range, bit for bit
        poses = canonical_axis_angle(p.astype(np.float64).reshape(-1, 24, 3)).reshape(p.shape)
        object.__setattr__(self, "poses", poses)
        object.__setattr__(self, "trans", t.astype(np.float64))
        object.__setattr__(self, "meta", dict(self.meta or {}))
        if self.betas is not None:
            b = np.asarray(self.betas, np.float64).ravel()
            if not np.isfinite(b).all():
                raise InputError("betas contain NaN or inf")
            object.__setattr__(self, "betas", b)

    @property
    def n_frames(self) -> int:
        return int(self.poses.shape[0])

    @property
    def seconds(self) -> float:
        return self.n_frames / self.fps

    def __repr__(self) -> str:
        return f"Motion({self.name!r}, frames={self.n_frames}, fps={self.fps:g})"

    def save(self, path: str | os.PathLike) -> Path:
        """Write an AMASS-compatible ``.npz`` (poses, trans, betas, mocap_framerate), atomically.

        ``trans_convention = "rest-pelvis"`` and ``up = "y"`` mark the file as segadeform's: the pelvis is at
        the body's own rest pelvis plus ``trans``, +Y up (:func:`load_motion_npz` reads it back as it is).
        """
        p = Path(path)
        with atomic_path(p) as tmp:
            with open(tmp, "wb") as fh:
                np.savez_compressed(
                    fh,
                    poses=self.poses.astype(np.float32),
                    trans=self.trans.astype(np.float32),
                    betas=(np.zeros(10) if self.betas is None else self.betas).astype(np.float32),
                    mocap_framerate=np.float64(self.fps),
                    name=np.str_(self.name),
                    trans_convention=np.str_(_TRANS_CONVENTION),
                    up=np.str_("y"),
                )
        return p


#: SMPL's rest pelvis joint (neutral template, metres, SMPL's y-up model frame).  AMASS and other SMPL
#: ``.npz`` files give ``trans`` relative to it: the pelvis is at ``R_up (SMPL_PELVIS + trans)``.
SMPL_PELVIS = np.array([-0.0018, -0.2233, 0.0282])
_Z_UP_TO_Y_UP = np.array([[1.0, 0, 0], [0, 0, 1.0], [0, -1.0, 0]])  # (x, y, z) -> (x, z, -y)
_TRANS_CONVENTION = "rest-pelvis"  # written by Motion.save: pelvis = rest pelvis of the body + trans


def _text(v) -> str:
    v = np.asarray(v)
    if v.dtype.kind == "S":
        return v.tobytes().decode("utf-8", "replace").rstrip("\0")
    if v.dtype.kind == "U":
        return str(v.item() if v.ndim == 0 else v.ravel()[0])
    return str(v)


def load_motion_npz(path: str | os.PathLike, *, up: str = "auto", rest_joints: np.ndarray | None = None) -> Motion:
    """Read an AMASS / SMPL ``.npz`` (or one written by :meth:`Motion.save`).

    * **poses**: ``poses`` as ``(T, 72)`` (SMPL), ``(T, 66)`` (body only), ``(T, 156)`` (SMPL-H) or
      ``(T, 165)`` (SMPL-X), or ``(T, J, 3)`` with J = 22, 24, 52 or 55; or AMASS SMPL-X's split
      ``root_orient (T, 3)`` + ``pose_body (T, 63)``.  The first 22 joints are SMPL's body; SMPL's two
      hand joints are kept when the file has them (72 / 24 x 3), else set to zero rotation (the hand
      models' fingers have no SMPL counterpart).
    * **up axis**: AMASS is Z-up.  ``up="auto"`` reads the root orientation (the body's up direction,
      +Y in the model, points along world +Z in Z-up data); ``"z"`` or ``"y"`` force it.  Z-up motions
      are turned to Y-up: root orientation and position both.
    * **translation**: SMPL files place the pelvis at ``SMPL_PELVIS + trans``; the motion returned places
      it at the same world point on the target body (``rest_joints[0] + trans``; by default the
      :func:`~segadeform.body.skeleton.default_rest_joints` pelvis).  Files written by
      :meth:`Motion.save` are already in that convention.
    * **frame rate**: ``mocap_framerate``, ``mocap_frame_rate`` or ``fps`` (non-integer rates kept),
      30 when absent; ``gender`` may be bytes or text (recorded in ``meta``).
    """
    p = Path(path)
    from ..io.npz import load_npz

    d = load_npz(p, what="motion .npz")
    if "poses" in d:
        poses = d["poses"]
    elif "root_orient" in d and "pose_body" in d:
        ro, pb = d["root_orient"], d["pose_body"]
        if ro.ndim != 2 or pb.ndim != 2 or ro.shape[0] != pb.shape[0] or ro.shape[1] != 3 or pb.shape[1] != 63:
            raise FileFormatError(
                "root_orient and pose_body do not fit",
                path=p,
                expected="(T, 3) and (T, 63)",
                got=f"{ro.shape} and {pb.shape}",
            )
        poses = np.concatenate([ro, pb], axis=1)
    else:
        raise FileFormatError(
            "motion file has no 'poses' array",
            path=p,
            expected="'poses' or 'root_orient' + 'pose_body'",
            got=", ".join(sorted(d)) or "no arrays",
        )
    if poses.dtype.kind not in "biuf":  # complex numbers are not rotations
        raise FileFormatError("poses must be real numeric values", path=p, expected="float", got=poses.dtype)
    if poses.ndim == 3:
        if poses.shape[2] != 3 or poses.shape[1] not in (22, 24, 52, 55):
            raise FileFormatError(
                "poses have an unknown layout", path=p, expected="(T, J, 3) with J = 22, 24, 52 or 55", got=poses.shape
            )
        poses = poses.reshape(poses.shape[0], -1)
    if poses.ndim != 2:
        raise FileFormatError("poses must be a (T, D) or (T, J, 3) array", path=p, got=poses.shape)
    if poses.shape[0] < 1:
        raise FileFormatError("motion has no frames", path=p, got=poses.shape)
    d_in = poses.shape[1]
    if d_in == 72:
        body = poses.astype(np.float64)
    elif d_in in (66, 156, 165):
        body = np.concatenate([poses[:, :66], np.zeros((poses.shape[0], 6))], axis=1).astype(np.float64)
    else:
        raise FileFormatError(
            "poses have an unknown width", path=p, expected="72 (SMPL), 66, 156 (SMPL-H) or 165 (SMPL-X)", got=d_in
        )
    if not np.isfinite(body).all():
        raise FileFormatError("poses contain NaN or inf", path=p)
    try:  # the file named (a fuzzer's 1e300 poses turned into NaN and were said of the network's input)
        check_pose_angles(body)
    except InputError as e:
        raise FileFormatError(e.problem, path=p, expected=e.expected, got=e.got) from None
    trans = d.get("trans", np.zeros((poses.shape[0], 3)))
    if trans.shape != (poses.shape[0], 3) or trans.dtype.kind not in "biuf":
        raise FileFormatError(
            "trans must be (T, 3) matching poses", path=p, expected=(poses.shape[0], 3), got=trans.shape
        )
    trans = trans.astype(np.float64)
    if not np.isfinite(trans).all():
        raise FileFormatError("trans contains NaN or inf", path=p)
    fps_key = next((k for k in ("mocap_framerate", "mocap_frame_rate", "fps") if k in d), None)
    fps_arr = np.asarray(d[fps_key]) if fps_key else np.float64(30.0)
    if fps_arr.size != 1 or fps_arr.dtype.kind not in "biuf":  # [30, 60] is two rates, not the first of them
        raise FileFormatError(
            f"{fps_key} must be one number",
            path=p,
            expected="a scalar frame rate",
            got=f"{fps_arr.dtype} {fps_arr.shape}",
        )
    fps = float(fps_arr.ravel()[0])
    if not (np.isfinite(fps) and fps > 0):
        raise FileFormatError("fps (mocap_framerate) must be positive", path=p, got=fps)
    betas = d.get("betas")
    if betas is not None and (betas.dtype.kind not in "biuf" or betas.ndim > 2):
        raise FileFormatError("betas must be a numeric vector", path=p, got=betas.shape)
    if betas is not None and betas.ndim == 2:
        betas = betas[0]
    name = _text(d["name"]) if "name" in d else p.stem
    # segadeform's own files; those written before the convention was recorded have a 'name' and no
    # 'gender' (AMASS files always carry a gender and never a name)
    ours = ("trans_convention" in d and _text(d["trans_convention"]) == _TRANS_CONVENTION) or (
        "trans_convention" not in d and "name" in d and "gender" not in d
    )
    from ..body.rotations import axis_angle_to_matrix, matrix_to_axis_angle

    if up == "auto":
        if ours:
            up = _text(d["up"]) if "up" in d else "y"
        else:
            body_up = axis_angle_to_matrix(body[:, :3])[:, :, 1].mean(axis=0)  # the body's +Y in the world
            up = "z" if abs(body_up[2]) > abs(body_up[1]) else "y"
    if up not in ("y", "z"):
        raise InputError("up must be 'auto', 'y' or 'z'", got=up)
    target_pelvis = np.asarray(rest_joints, np.float64)[0] if rest_joints is not None else _default_pelvis()
    if ours:
        pelvis = trans + target_pelvis
    else:
        pelvis = trans + SMPL_PELVIS
    if up == "z":
        Q = _Z_UP_TO_Y_UP
        body = body.copy()
        body[:, :3] = matrix_to_axis_angle(Q @ axis_angle_to_matrix(body[:, :3]))
        pelvis = pelvis @ Q.T
    trans = pelvis - target_pelvis
    meta = {"format": "npz", "up": up, "source_width": int(d_in), "convention": "segadeform" if ours else "smpl"}
    if "gender" in d:
        meta["gender"] = _text(d["gender"])
    try:
        return Motion(poses=body, trans=trans, fps=fps, betas=betas, name=name, meta=meta)
    except InputError as e:
        raise FileFormatError(e.problem, path=p, expected=e.expected, got=e.got) from None


def _default_pelvis() -> np.ndarray:
    from ..body.skeleton import default_rest_joints

    return default_rest_joints()[0]


def face_forward(motion: Motion, frame: int = 0) -> Motion:
    """Turn the whole motion about the vertical axis so the body faces +Z at ``frame``, and move it so its
    root is above x = z = 0 there.  Motion capture faces wherever the subject walked; a simulator that
    blends from the rest pose (facing +Z at the origin) into a clip facing backwards whirls the cloth.

    Shapes:
        poses (T, 72), trans (T, 3) -> the same
    """
    from ..body.rotations import axis_angle_to_matrix, matrix_to_axis_angle

    if not 0 <= frame < motion.n_frames:
        raise InputError("frame outside the motion", expected=f"0..{motion.n_frames - 1}", got=frame)
    R = axis_angle_to_matrix(motion.poses[:, :3])
    fwd = R[frame] @ np.array([0.0, 0.0, 1.0])
    yaw = float(np.arctan2(fwd[0], fwd[2]))
    c, s = np.cos(-yaw), np.sin(-yaw)
    Ry = np.array([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]])
    poses = motion.poses.copy()
    poses[:, :3] = matrix_to_axis_angle(Ry @ R)
    t = motion.trans - np.array([motion.trans[frame, 0], 0.0, motion.trans[frame, 2]])
    trans = t @ Ry.T
    return dataclasses.replace(motion, poses=poses, trans=trans, meta=dict(motion.meta, turned_deg=np.degrees(-yaw)))


def floor_shift(motion: Motion, rest_joints: np.ndarray, *, floor: float = 0.0, typical: bool = False) -> float:
    """How far (m, up positive) the whole motion must move for its lowest foot joint (ankles, toes) over all frames
    to be as high above ``floor`` as in the rest pose: what :func:`feet_on_floor` applies.  ``typical``: the lowest
    foot of the median frame instead of all frames' lowest (a few glitched frames of a capture do not count); far
    from 0, the motion came from another origin, convention or units (a run warns).

    Shapes:
        rest_joints: (24, 3)
    """
    from ..body.kinematics import forward_kinematics, poses_to_rotmats
    from ..body.skeleton import SMPL_PARENTS

    J = np.asarray(rest_joints, np.float64)
    if J.shape != (24, 3):
        raise InputError("rest_joints must be (24, 3)", got=J.shape)
    feet = [7, 8, 10, 11]
    _, posed = forward_kinematics(poses_to_rotmats(motion.poses, 24), J, SMPL_PARENTS, motion.trans)
    lowest = posed[:, feet, 1].min(axis=1)
    return float((J[feet, 1].min() + floor) - (np.median(lowest) if typical else lowest.min()))


def feet_on_floor(motion: Motion, rest_joints: np.ndarray, *, floor: float = 0.0) -> Motion:
    """Shift the whole motion vertically so its lowest foot joint (ankles, toes) over all frames is as
    high above ``floor`` as in the rest pose (where the body stands on the floor).  One constant shift:
    jumps stay jumps.

    Shapes:
        rest_joints: (24, 3)
    """
    shift = floor_shift(motion, rest_joints, floor=floor)
    trans = motion.trans + np.array([0.0, shift, 0.0])
    meta = dict(motion.meta, floor_shift=float(shift))
    return dataclasses.replace(motion, trans=trans, meta=meta)


def sample_frames(motion: Motion, t) -> tuple[np.ndarray, np.ndarray]:
    """The motion at fractional frame indices ``t`` (clamped to the motion): slerp on each joint's rotation,
    linear on translation.

    Shapes:
        t: (M,) -> poses (M, 72), trans (M, 3)
    """
    i0, i1, a = frames_between(t, motion.n_frames)
    q = axis_angle_to_quaternion(motion.poses.reshape(-1, 24, 3))
    qs = quaternion_slerp(q[i0], q[i1], np.repeat(a, 24, axis=1))
    poses = quaternion_to_axis_angle(qs).reshape(len(i0), N_POSE)
    return poses, (1 - a) * motion.trans[i0] + a * motion.trans[i1]


#: rates this close (relative) are one rate: a BVH's "Frame Time: 0.008333" is 120.005 fps, and resampled to 120 it
#: lost its last frame (343 -> 342: an engine integrator's trial); six decimals of a frame time are 6e-5 off at most
SAME_RATE = 1e-4


def resample(motion: Motion, fps: float) -> Motion:
    """Resample to ``fps``: slerp on each joint's rotation, linear on translation.  A rate within :data:`SAME_RATE`
    of the motion's is its own, written rounded: its frames are kept, at ``fps``.

    The first frame is kept; the last output frame is the last time <= the
    input's last frame time.  A motion cut from a longer one (``meta["start_frame"]``, the source's number of
    its first frame) keeps its first frame's time: the number is counted again at the new rate.
    """
    if not (np.isfinite(fps) and fps > 0):
        raise InputError("target fps must be positive", got=fps)
    if abs(fps - motion.fps) < 1e-9:
        return motion
    if abs(fps - motion.fps) <= SAME_RATE * fps:  # a file's rounded frame time: its frames, at the rate asked
        return dataclasses.replace(motion, fps=float(fps))
    poses, trans = sample_frames(motion, resample_positions(motion.n_frames, motion.fps, fps))
    return Motion(
        poses=poses,
        trans=trans,
        fps=float(fps),
        betas=motion.betas,
        name=motion.name,
        meta=_renumbered(dict(motion.meta, resampled_from=motion.fps), motion.fps, fps),
    )


def _renumbered(meta: dict, fps_from: float, fps_to: float) -> dict:
    """``meta`` with its ``start_frame`` (a frame number at ``fps_from``) counted at ``fps_to``."""
    if meta.get("start_frame"):
        meta["start_frame"] = int(round(int(meta["start_frame"]) * fps_to / fps_from))
    return meta


def drop_leading_jumps(motion: Motion, max_degrees: float = 60.0, *, max_frames: int = 3) -> tuple[Motion, int]:
    """Drop first frames that the motion jumps away from: while some joint turns more than ``max_degrees``
    from frame 0 to frame 1 (or the root moves more than 0.5 m), frame 0 goes (at most ``max_frames``).
    Several CMU conversions (cgspeed's MotionBuilder release) put a T-pose in front of the capture: played as
    it is, the body teleports out of it on the next frame.  Returns the motion and how many frames went.
    """
    from ..body.rotations import axis_angle_to_matrix

    dropped = 0
    m = motion
    while dropped < max_frames and m.n_frames >= 3:
        r = axis_angle_to_matrix(m.poses[:2].reshape(2, 24, 3))
        rel = np.einsum("jab,jac->jbc", r[0], r[1])  # R0^T R1 per joint
        cos = np.clip((np.trace(rel, axis1=1, axis2=2) - 1.0) / 2.0, -1.0, 1.0)
        turn = np.degrees(np.arccos(cos)).max()
        if turn <= max_degrees and np.linalg.norm(m.trans[1] - m.trans[0]) <= 0.5:
            break
        m = dataclasses.replace(m, poses=m.poses[1:], trans=m.trans[1:])
        dropped += 1
    if dropped:
        m = dataclasses.replace(m, meta=dict(m.meta, dropped_leading_frames=dropped))
    return m, dropped


def joint_speeds(motion: Motion, rest_joints) -> np.ndarray:
    """How fast the fastest joint moves between each pair of frames, in m/s (forward kinematics on the
    24-joint skeleton with ``rest_joints``, translation included).

    Shapes: rest_joints (24, 3) -> (T - 1,)
    """
    from ..body.kinematics import forward_kinematics
    from ..body.rotations import axis_angle_to_matrix
    from ..body.skeleton import SMPL_PARENTS

    j = np.asarray(rest_joints, np.float64)
    if j.shape != (24, 3) or not np.isfinite(j).all():
        raise InputError("rest joints must be finite (24, 3)", expected=(24, 3), got=j.shape)
    if motion.n_frames < 2:
        return np.zeros(0)
    rot = axis_angle_to_matrix(motion.poses.reshape(-1, 24, 3))
    _, posed = forward_kinematics(rot, j, SMPL_PARENTS, motion.trans)
    return np.linalg.norm(np.diff(posed, axis=0), axis=2).max(axis=1) * motion.fps


def drop_leading_glitches(
    motion: Motion,
    rest_joints,
    *,
    within_seconds: float = 0.1,
    factor: float = 4.0,
    min_speed: float = 6.0,
) -> tuple[Motion, int]:
    """Drop the frames a capture settles from: every frame up to the last jump in its first ``within_seconds``,
    a jump being a step where the fastest joint moves faster than ``max(factor x`` the motion's median speed,
    ``min_speed)`` m/s.  Many CMU trials open with a few frames where the solve has not settled (the BVH of
    07_03, 08_08, 10_02, 135_xx, 60_03: joints at 30-90 m/s over the first 3-5 frames at 120 fps; 16_15, 16_23:
    one frame at 100 m/s): a lead that starts there throws the body's legs through the garment before the clip
    begins.  A motion that is fast from its first frame (a sprint captured mid-stride) loses at most
    ``within_seconds``.  Returns the motion and how many frames went (also in ``meta``).

    Shapes: rest_joints (24, 3)
    """
    sp = joint_speeds(motion, rest_joints)
    if len(sp) < 3:
        return motion, 0
    bound = max(factor * float(np.median(sp)), min_speed)
    window = max(1, int(np.ceil(within_seconds * motion.fps)))
    jumps = np.flatnonzero(sp[:window] > bound)
    if len(jumps) == 0:
        return motion, 0
    k = min(int(jumps[-1]) + 1, motion.n_frames - 2)  # the frame after the last jump is the first one kept
    m = dataclasses.replace(
        motion,
        poses=motion.poses[k:],
        trans=motion.trans[k:],
        meta=dict(motion.meta, dropped_leading_glitch_frames=k),
    )
    return m, k


def repair_glitches(
    motion: Motion, rest_joints, *, max_speed: float = 20.0, max_seconds: float = 0.05
) -> tuple[Motion, int]:
    """Replace the frames a capture jumps to and back from by the motion interpolated over them.

    A glitch is a jump out and a jump back at most ``max_seconds`` apart, each a step where some joint moves
    faster than ``max_speed`` m/s (no joint of a person does: CMU's 05_14 throws a knee about at 47 m/s for
    three frames); the frames between them are rebuilt from the frames on either side by slerp
    on every joint's rotation and linear translation (:func:`sample_frames`).  A single step over the bound
    (a cut in the capture, nothing in between to rebuild) and a run that reaches either end of the motion are
    left as they are.  Returns the motion and how many frames were rebuilt (also in ``meta``).
    """
    if not (np.isfinite(max_speed) and max_speed > 0):
        raise InputError("max_speed must be positive", got=max_speed)
    sp = joint_speeds(motion, rest_joints)
    fast = sp > max_speed
    if not fast.any():
        return motion, 0
    poses, trans = motion.poses.copy(), motion.trans.copy()
    fixed = 0
    steps = np.flatnonzero(fast)
    runs = np.split(steps, np.flatnonzero(np.diff(steps) > 1) + 1)
    # the jump out and the jump back may be a few calm steps apart: runs closer than ``max_seconds`` are one
    # glitch; farther apart they are two cuts (a capture that flips a limb between two solves for longer is
    # left as it is: which of the two is the person cannot be told from speeds)
    gap = max(1, int(round(max_seconds * motion.fps)))
    merged: list[list[int]] = []
    for r in runs:
        if merged and r[0] - merged[-1][1] <= gap:
            merged[-1][1] = int(r[-1])
        else:
            merged.append([int(r[0]), int(r[-1])])
    for a, b in merged:  # steps a..b: frames a+1..b are rebuilt from frames a and b+1
        if b == a or b - a > gap or a == 0 or b + 1 >= motion.n_frames - 1:
            continue
        t = np.arange(a + 1, b + 1, dtype=np.float64)
        anchor = dataclasses.replace(motion, poses=motion.poses[[a, b + 1]], trans=motion.trans[[a, b + 1]])
        p, tr = sample_frames(anchor, (t - a) / (b + 1 - a))
        poses[a + 1 : b + 1], trans[a + 1 : b + 1] = p, tr
        fixed += b - a
    if not fixed:
        return motion, 0
    m = dataclasses.replace(motion, poses=poses, trans=trans, meta=dict(motion.meta, repaired_glitch_frames=fixed))
    return m, fixed


def repair_capture(motion: Motion, rest_joints, *, max_speed: float = 20.0) -> Motion:
    """A capture's glitches repaired with its frame count and timing kept (a scene's ``repair_glitches``): the
    frames its solve settles from (:func:`drop_leading_glitches`) hold its first settled pose, and frames it
    jumps to and back from are rebuilt (:func:`repair_glitches`).  ``meta`` says how many of each."""
    m, k = drop_leading_glitches(motion, rest_joints)
    if k:
        m = dataclasses.replace(
            m,
            poses=np.concatenate([np.repeat(m.poses[:1], k, axis=0), m.poses]),
            trans=np.concatenate([np.repeat(m.trans[:1], k, axis=0), m.trans]),
            meta={
                **{a: b for a, b in m.meta.items() if a != "dropped_leading_glitch_frames"},
                "held_leading_glitch_frames": k,
            },
        )
    m, _ = repair_glitches(m, rest_joints, max_speed=max_speed)
    return m


def drop_leading_tpose(
    motion: Motion, *, max_degrees: float = 25.0, settle_seconds: float = 0.5, within_seconds: float = 5.0
) -> tuple[Motion, int]:
    """Drop a calibration T-pose held at the start of a capture, and ``settle_seconds`` of the move out of it:
    when both upper arms are within ``max_degrees`` of the T-pose in the first frame (SMPL's rest pose is the
    T-pose), every frame up to the first where one leaves it (within ``within_seconds``) goes, then the settling
    time.  Some CMU trials open this way (03_02, 127_02); played as they are, the arms drop from horizontal in a
    few frames and throw a shirt's sleeves off them.  Returns the motion and how many frames went.
    """
    arm = np.degrees(np.linalg.norm(motion.poses.reshape(-1, 24, 3)[:, [16, 17]], axis=2)).max(axis=1)
    held = arm < max_degrees
    if not held[0]:
        return motion, 0
    limit = min(motion.n_frames, int(round(within_seconds * motion.fps)))
    out = np.flatnonzero(~held[:limit])
    if len(out) == 0:  # a T-pose throughout (or past the window): nothing to tell capture from calibration
        return motion, 0
    k = min(int(out[0]) + int(round(settle_seconds * motion.fps)), motion.n_frames - 2)
    m = dataclasses.replace(
        motion, poses=motion.poses[k:], trans=motion.trans[k:], meta=dict(motion.meta, dropped_leading_tpose_frames=k)
    )
    return m, k


def ramp_in(motion: Motion, seconds: float) -> Motion:
    """The motion started from rest: its first ``seconds`` played with a speed rising linearly from 0 to 1
    over ``2 seconds`` (time warped ``tau(t) = t^2 / (4 seconds)``: position and speed continuous where the
    normal speed takes over), then the rest of it as it is.  A capture that starts mid-stride then starts
    like a person setting off, not at full speed out of a standstill.

    Returns a motion of ``2 seconds fps + (T - seconds fps)`` frames; its frame ``round(2 seconds fps)`` is
    the input's frame ``round(seconds fps)``.
    """
    if not (np.isfinite(seconds) and seconds > 0):
        raise InputError("ramp seconds must be positive", got=seconds)
    fps = motion.fps
    k = int(round(seconds * fps))  # input frames the ramp plays
    if k < 1 or k >= motion.n_frames:
        raise InputError(
            "the ramp must be shorter than the motion", expected=f"< {motion.n_frames / fps:.3f} s", got=seconds
        )
    n = 2 * k  # output frames of the ramp
    t = np.arange(n)  # output frame index
    tau = t * t / (4.0 * k)  # input frame index: tau(2k) = k, tau'(2k) = 1
    rp, rt = sample_frames(motion, tau)
    poses = np.concatenate([rp, motion.poses[k:]])
    trans = np.concatenate([rt, motion.trans[k:]])
    return dataclasses.replace(motion, poses=poses, trans=trans, meta=dict(motion.meta, ramp_seconds=seconds))


def motion_windows(poses: np.ndarray, window: int, *, start: int = 0, stop: int | None = None) -> np.ndarray:
    """The motion windows Theta_t = (theta_t, theta_{t-1}, ..., theta_{t-T+1}) for t in [start, stop).

    Frames before the first are padded with the first frame (the body is at
    rest in its first pose before the sequence starts), so every window has
    ``T`` real poses and the first frames see no motion.

    Shapes:
        poses: (F, D) -> (stop - start, window, D); [:, 0] is the current frame
    """
    p = np.asarray(poses)
    if p.ndim != 2 or p.shape[0] < 1:
        raise InputError("poses must be (F, D) with F >= 1", got=p.shape)
    if int(window) < 1:
        raise InputError("window must be at least 1", got=window)
    stop = p.shape[0] if stop is None else int(stop)
    if not 0 <= start <= stop <= p.shape[0]:
        raise InputError("frame range out of bounds", expected=f"0 <= start <= stop <= {p.shape[0]}", got=(start, stop))
    t = np.arange(start, stop)[:, None] - np.arange(int(window))[None, :]
    return p[np.maximum(t, 0)]


def history_inputs(poses: np.ndarray, trans: np.ndarray, fps: float) -> np.ndarray:
    """Per-frame inputs of a model's motion history (``ModelConfig.history``): the pose and the root's
    velocity in the root's own frame, ``x_t = (theta_t, R_0(theta_t)^T (p_t - p_{t-1}) fps)``; the first frame's
    velocity is 0 (nothing before it is known: pass the lead first where there is one).  The velocity does not
    depend on the heading (a walk forward reads forward whichever way it heads); the pose's root rotation does.

    Shapes:
        poses (L, 3 S), trans (L, 3) -> (L, 3 S + 3)
    """
    p = np.asarray(poses, np.float64)
    t = np.asarray(trans, np.float64)
    if p.ndim != 2 or p.shape[0] < 1 or p.shape[1] % 3 or t.shape != (p.shape[0], 3):
        raise InputError("expected poses (L, 3 S) and trans (L, 3), L >= 1", got=(p.shape, t.shape))
    if not (np.isfinite(fps) and fps > 0):
        raise InputError("fps must be a positive number", got=fps)
    v = np.zeros_like(t)
    v[1:] = (t[1:] - t[:-1]) * float(fps)
    r = axis_angle_to_matrix(p[:, :3])  # (L, 3, 3) the root's rotation
    return np.concatenate([p, np.einsum("lji,lj->li", r, v)], axis=1)


def write_motion_file(
    path,
    motion: Motion,
    *,
    body: dict | None = None,
    betas=None,
    source: str = "",
    start_frame: int = 0,
    warnings: Sequence[str] = (),
):
    """Write ``motion`` as a motion file (``.sgdm``, :mod:`segadeform.io.sgdm`): poses ``(T, S, 3)`` and trans
    ``(T, 3)`` as float32, ``fps`` and the rest in ``meta``.  ``body``: the ``{"name", "sha256"}`` of the body it was
    retargeted onto (:func:`segadeform.body.identity.body_label`), ``betas`` that body's shape; ``source``: what it
    was made from; ``start_frame``: the source's frame number of the first frame written; ``warnings``: what
    ``motion export`` said of it, for the runtimes that play it to say again."""
    poses = np.asarray(motion.poses, np.float64)
    s = poses.shape[1] // 3
    return write_motion_arrays(
        path,
        poses.reshape(len(poses), s, 3),
        motion.trans,
        fps=motion.fps,
        name=motion.name,
        joint_names=SMPL_JOINT_NAMES[:s],
        source=source,
        body=body,
        betas=betas,
        start_frame=start_frame,
        warnings=warnings,
    )


def read_motion_file(path) -> tuple[Motion, dict]:
    """``(motion, meta)`` of a motion file (``.sgdm``): a :class:`Motion` (poses ``(T, 3 S)``) and the file's
    ``meta``; every array and key checked."""
    p = Path(path)
    poses, trans, fps, meta = read_motion_arrays(p)
    start = meta.get("start_frame", 0)
    ok = isinstance(start, (int, float)) and not isinstance(start, bool) and np.isfinite(start)
    if not (ok and start == int(start) and abs(start) <= 2**31 - 1):  # 1e300 was a traceback in the PC2 writer
        raise FileFormatError(
            "meta.start_frame must be a frame number", path=p, expected="an integer of 32 bits", got=start
        )
    try:
        m = Motion(
            poses=poses.reshape(len(poses), -1).astype(np.float64),
            trans=trans.astype(np.float64),
            fps=fps,
            name=str(meta.get("name", p.stem)),
            meta={
                "format": "sgdm",
                "body": meta.get("body"),
                "betas": meta.get("betas"),
                "start_frame": int(meta.get("start_frame", 0)),
            },
        )
    except InputError as e:
        raise FileFormatError(e.problem, path=p, expected=e.expected, got=e.got) from None
    return m, meta
