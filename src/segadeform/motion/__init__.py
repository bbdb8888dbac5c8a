"""Motions on the 24-joint SMPL skeleton: AMASS ``.npz`` and BVH IO, resampling,
motion windows, joint limits and a procedural motion library (numpy only)."""

from __future__ import annotations

import os
from pathlib import Path

from ..errors import FileFormatError
from .bvh import read_bvh, write_bvh
from .motion import N_POSE, Motion, load_motion_npz, motion_windows, resample
from .procedural import MOTION_KINDS, make_motion

__all__ = ["Motion", "N_POSE", "load_motion", "load_motion_npz", "read_bvh", "write_bvh", "resample",
           "motion_windows", "MOTION_KINDS", "make_motion"]


def load_motion(path: str | os.PathLike, **kw) -> Motion:
    """Read a motion by extension: ``.npz`` (AMASS-style) or ``.bvh``."""
    p = Path(path)
    ext = p.suffix.lower()
    if ext == ".npz":
        return load_motion_npz(p)
    if ext == ".bvh":
        return read_bvh(p, **kw)
    raise FileFormatError("unknown motion file type", path=p, expected=".npz or .bvh", got=ext or "none")
