"""A motion as a scene or jobs file describes it (:class:`MotionSpec`), the :class:`Motion` it builds, and the
one check of a frame range against a motion (``--frames A:B`` of ``run``, ``simulate`` and ``bundle``).

Parsing the text (``[motion]`` tables, ``"A:B"``) and :class:`MotionSpec` itself are
:mod:`segadeform.settings.scene`'s; this module only turns what was parsed into motions and frame ranges.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from ..errors import InputError
from ..settings.scene import MotionSpec
from .motion import Motion, drop_leading_glitches, feet_on_floor, repair_capture, repair_glitches, resample
from .procedural import make_motion

__all__ = ["MotionSpec", "build_motion", "frame_range", "select_frames", "glitches_in_range", "root_cuts", "CUT_SPEED"]

#: m/s: a root faster than this between two frames has cut or teleported (no person runs at it: the glitch bound)
CUT_SPEED = 20.0


def build_motion(spec: MotionSpec, rest_joints=None) -> Motion:
    """The :class:`~segadeform.motion.Motion` ``spec`` describes (its frame range not applied: see
    :func:`frame_range`).

    ``rest_joints (24, 3)``: the body that will play it (files are retargeted onto it).
    """
    from ..bounds import played_at
    from . import load_motion  # the package's reader by extension

    if spec.file is not None:
        units = spec.units
        if units is not None:
            try:
                units = float(units)
            except ValueError:
                pass
        with played_at(spec.fps):  # its refusals name the frames as resampled below: those --frames A:B counts
            m = load_motion(
                spec.file,
                rest_joints=rest_joints,
                up=spec.up,
                units=units,
                joint_map=spec.joint_map,
                floor=spec.floor,
                skeleton=spec.skeleton,
                animation=spec.animation,
            )
    else:
        m = make_motion(
            spec.kind,
            seconds=spec.seconds,
            fps=spec.fps or 30.0,
            speed=spec.speed,
            amplitude=spec.amplitude,
            seed=spec.seed,
        )
        if spec.floor and rest_joints is not None:
            m = feet_on_floor(m, rest_joints)
    if spec.file is not None:  # at the file's own rate, before any resampling
        from ..body.skeleton import default_rest_joints

        joints = default_rest_joints() if rest_joints is None else rest_joints
        if spec.repair_glitches:
            m = repair_capture(m, joints)
        else:  # counted, for a warning: a capture's solve settling or jumping shows as cloth thrown about
            _, settle = drop_leading_glitches(m, joints)
            fixed, jumps = repair_glitches(m, joints)
            if settle or jumps:  # the frames it would rebuild, in seconds: a frame range counts its own
                moved = (fixed.poses != m.poses).reshape(m.n_frames, -1).any(axis=1)
                at = np.flatnonzero(moved | (fixed.trans != m.trans).any(axis=1))
                m = dataclasses.replace(
                    m,
                    meta=dict(m.meta, unrepaired_glitches=(int(settle), [float(i / m.fps) for i in at], float(m.fps))),
                )
    if spec.fps is not None and abs(spec.fps - m.fps) > 1e-9:
        m = resample(m, spec.fps)
    return m


def frame_range(frames: tuple[int, int | None] | None, n_frames: int, *, first: int = 0) -> tuple[int, int]:
    """``(A, B)`` -- B exclusive, ``None`` meaning the end -- checked against a motion of ``n_frames``.

    Returns ``(A, B)`` with B filled in; :class:`~segadeform.errors.InputError` when the range is empty or
    goes past the motion (the one check ``run``, ``simulate`` and ``bundle`` share).  ``first``: the number the
    motion's file gives its first frame (a cut ``.sgdm``), said in the error: A and B count from 0 whatever it is.
    """
    a, b = frames if frames else (0, None)
    stop = n_frames if b is None else b
    if not 0 <= a < stop <= n_frames:
        given = f"{a}:{'' if b is None else b}"
        where = (
            f" (counted from its first frame, 0; the file numbers them {first}-{first + n_frames - 1})" if first else ""
        )
        raise InputError(
            f"frame range {given} is outside the motion's {n_frames} frames{where}",
            expected=f"0 <= A < B <= {n_frames}",
            got=given,
        )
    return int(a), int(stop)


def select_frames(motion: Motion, frames: tuple[int, int | None] | None) -> tuple[Motion, int]:
    """The motion's frames ``A:B`` as a motion of their own (checked by :func:`frame_range`), and ``A``."""
    a, b = frame_range(frames, motion.n_frames, first=int((motion.meta or {}).get("start_frame", 0)))
    if (a, b) == (0, motion.n_frames):
        return motion, 0
    return dataclasses.replace(motion, poses=motion.poses[a:b], trans=motion.trans[a:b]), a


def glitches_in_range(motion: Motion, frames: tuple[int, int | None] | None = None) -> tuple[int, int]:
    """``(settling frames, frames jumped to and back from)`` of a capture built without ``repair_glitches``
    (:func:`build_motion` records them in ``meta["unrepaired_glitches"]``) that fall inside ``frames`` (``(A, B)``
    of the built motion, B exclusive; None: all).  The settling frames are counted at the file's rate, the jumps
    by their time; ``(0, 0)`` for a motion with none or built with the repair."""
    glitches = (motion.meta or {}).get("unrepaired_glitches")
    if not glitches:
        return 0, 0
    settle, jump_times, file_fps = glitches
    start, stop = frames or (0, None)
    stop = motion.n_frames if stop is None else stop
    settle = max(0, min(settle, int(round(stop / motion.fps * file_fps))) - int(round(start / motion.fps * file_fps)))
    t0, t1 = (start - 0.5) / motion.fps, (stop - 0.5) / motion.fps
    return settle, sum(1 for t in jump_times if t0 <= t < t1)


def glitch_words(settle: int, jumps: int) -> str:
    """:func:`glitches_in_range`'s counts in words, the parts that are not 0, each singular or plural ("1 leading frame
    its capture settles from and 3 frames it jumps to and back from"; "1 leading frames" and "0 leading frames ..."
    read oddly: a new user's trial)."""
    parts = []
    if settle:
        parts.append(f"{settle} leading frame{'s' if settle != 1 else ''} its capture settles from")
    if jumps:
        parts.append(f"{jumps} frame{'s' if jumps != 1 else ''} it jumps to and back from")
    return " and ".join(parts)


def root_cuts(motion: Motion, frames: tuple[int, int | None] | None = None) -> list[tuple[int, float]]:
    """The steps inside ``frames`` (``(A, B)`` of the motion, B exclusive; None: all) where the root moves faster
    than :data:`CUT_SPEED`: ``[(frame after the step, metres moved), ...]``.  A cut or a teleport in the motion's
    translation (a root moved 100 m in one frame played without a word: a QA engineer's trial) that stays there for
    the next 0.05 s (and not the way back of one before); a jump and a jump back are the capture's glitches
    (:func:`glitches_in_range`).

    Shapes: motion.trans (T, 3) -> list of (int, float)"""
    t = np.asarray(motion.trans, np.float64)
    start, stop = frames or (0, None)
    stop = len(t) if stop is None else stop
    if stop - start < 2:
        return []
    glitches = (motion.meta or {}).get("unrepaired_glitches")
    # the leading frames a capture settles from are the glitches' warning's (CMU's 09_10 jumps 2 m into frame 4)
    settled = int(np.ceil(glitches[0] / glitches[2] * motion.fps)) if glitches else 0
    t = t[start:stop]
    step = np.linalg.norm(np.diff(t, axis=0), axis=1)
    gap = max(1, int(round(0.05 * motion.fps)))  # a jump back within this is a glitch, not a cut
    cuts = []
    for k in np.flatnonzero(step * motion.fps > CUT_SPEED).tolist():
        later, earlier = t[min(k + 1 + gap, len(t) - 1)], t[max(k - gap, 0)]
        # it stays away, and it is not the way back of a jump
        stays = np.linalg.norm(later - t[k]) > 0.5 * step[k] and np.linalg.norm(t[k + 1] - earlier) > 0.5 * step[k]
        if stays and start + k + 1 > settled:
            cuts.append((int(start + k + 1), float(step[k])))
    return cuts
