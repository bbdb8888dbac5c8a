"""The Motion container, AMASS-style ``.npz`` IO, resampling and motion windows."""

from __future__ import annotations

import dataclasses
import os
from pathlib import Path
from typing import Optional

import numpy as np

from ..body.rotations import (axis_angle_to_quaternion, quaternion_slerp, quaternion_to_axis_angle)
from ..errors import FileFormatError, InputError
from ..io.atomic import atomic_path

__all__ = ["Motion", "load_motion_npz", "resample", "motion_windows", "N_POSE"]

N_POSE = 72  # 24 SMPL joints x axis-angle


@dataclasses.dataclass(frozen=True, eq=False)
class Motion:
    """A body motion on the 24-joint SMPL skeleton.

    Attributes:
        poses: (T, 72) axis-angle per joint, root first, relative to the rest pose
        trans: (T, 3) root translation, metres
        fps: frames per second
        betas: (B,) body shape the motion was captured with, or None
        name: a label (file name or procedural kind)
    """

    poses: np.ndarray
    trans: np.ndarray
    fps: float
    betas: Optional[np.ndarray] = None
    name: str = ""

    def __post_init__(self):
        p, t = np.asarray(self.poses), np.asarray(self.trans)
        if p.ndim != 2 or p.shape[1] != N_POSE or p.shape[0] < 1:
            raise InputError("poses must be (T, 72) with T >= 1", expected="(T, 72)", got=p.shape)
        if t.shape != (p.shape[0], 3):
            raise InputError("trans must be (T, 3) matching poses", expected=(p.shape[0], 3), got=t.shape)
        if not (np.isfinite(p).all() and np.isfinite(t).all()):
            raise InputError("motion contains NaN or inf")
        if not (np.isfinite(self.fps) and self.fps > 0):
            raise InputError("fps must be positive", got=self.fps)
        object.__setattr__(self, "poses", p.astype(np.float64))
        object.__setattr__(self, "trans", t.astype(np.float64))
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
        """Write an AMASS-compatible ``.npz`` (poses, trans, betas, mocap_framerate), atomically."""
        p = Path(path)
        with atomic_path(p) as tmp:
            with open(tmp, "wb") as fh:
                np.savez_compressed(fh, poses=self.poses.astype(np.float32), trans=self.trans.astype(np.float32),
                                    betas=(np.zeros(10) if self.betas is None else self.betas).astype(np.float32),
                                    mocap_framerate=np.float64(self.fps), name=np.str_(self.name))
        return p


def load_motion_npz(path: str | os.PathLike) -> Motion:
    """Read an AMASS-style ``.npz``.

    ``poses`` may be ``(T, 72)`` (SMPL), ``(T, 66)`` (body without hands) or
    ``(T, 156)`` (SMPL-H): the first 22 joints are the body and SMPL's two
    hand joints are set to zero rotation, the usual AMASS-to-SMPL practice
    (SMPL-H's finger joints have no SMPL counterpart).  ``trans`` defaults to
    zeros; the frame rate comes from ``mocap_framerate`` (or
    ``mocap_frame_rate``), default 30 when absent.
    """
    p = Path(path)
    from ..io.npz import load_npz

    d = load_npz(p, what="motion .npz")
    if "poses" not in d:
        raise FileFormatError("motion file has no 'poses' array", path=p, got=", ".join(sorted(d)) or "no arrays")
    poses = d["poses"]
    if not np.issubdtype(poses.dtype, np.number) or poses.ndim != 2:
        raise FileFormatError("poses must be a numeric (T, D) array", path=p, got=f"{poses.dtype} {poses.shape}")
    if poses.shape[0] < 1:
        raise FileFormatError("motion has no frames", path=p, got=poses.shape)
    d_in = poses.shape[1]
    if d_in == 72:
        body = poses
    elif d_in in (66, 156, 165):
        body = np.concatenate([poses[:, :66], np.zeros((poses.shape[0], 6))], axis=1)
    else:
        raise FileFormatError("poses have an unknown width", path=p, expected="72 (SMPL), 66, 156 (SMPL-H) or 165",
                              got=d_in)
    trans = d.get("trans", np.zeros((poses.shape[0], 3)))
    if trans.shape != (poses.shape[0], 3) or not np.issubdtype(trans.dtype, np.number):
        raise FileFormatError("trans must be (T, 3) matching poses", path=p, expected=(poses.shape[0], 3), got=trans.shape)
    fps_arr = d.get("mocap_framerate", d.get("mocap_frame_rate", np.float64(30.0)))
    try:
        fps = float(fps_arr)
    except (TypeError, ValueError):
        raise FileFormatError("mocap_framerate must be a number", path=p, got=fps_arr.shape) from None
    betas = d.get("betas")
    if betas is not None and (not np.issubdtype(betas.dtype, np.number) or betas.ndim > 2):
        raise FileFormatError("betas must be a numeric vector", path=p, got=betas.shape)
    if betas is not None and betas.ndim == 2:
        betas = betas[0]
    name = str(d["name"]) if "name" in d else p.stem
    try:
        return Motion(poses=body.astype(np.float64), trans=trans.astype(np.float64), fps=fps, betas=betas, name=name)
    except InputError as e:
        raise FileFormatError(e.problem, path=p, expected=e.expected, got=e.got) from None


def resample(motion: Motion, fps: float) -> Motion:
    """Resample to ``fps``: slerp on each joint's rotation, linear on translation.

    The first frame is kept; the last output frame is the last time <= the
    input's last frame time.
    """
    if not (np.isfinite(fps) and fps > 0):
        raise InputError("target fps must be positive", got=fps)
    if abs(fps - motion.fps) < 1e-9:
        return motion
    duration = (motion.n_frames - 1) / motion.fps
    n_out = int(np.floor(duration * fps + 1e-9)) + 1
    t = np.arange(n_out) / fps * motion.fps  # in input frames
    i0 = np.clip(np.floor(t).astype(int), 0, motion.n_frames - 1)
    i1 = np.clip(i0 + 1, 0, motion.n_frames - 1)
    a = (t - i0)[:, None]
    q = axis_angle_to_quaternion(motion.poses.reshape(-1, 24, 3))
    qs = quaternion_slerp(q[i0], q[i1], np.repeat(a, 24, axis=1))
    poses = quaternion_to_axis_angle(qs).reshape(n_out, N_POSE)
    trans = (1 - a) * motion.trans[i0] + a * motion.trans[i1]
    return Motion(poses=poses, trans=trans, fps=float(fps), betas=motion.betas, name=motion.name)


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
