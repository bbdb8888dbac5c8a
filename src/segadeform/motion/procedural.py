"""Procedural motions for samples and training data.

Each kind builds per-joint Euler angles over time (see ``limits``), clips
them to the joint limits, and converts to SMPL axis-angle poses.  Every
kind takes ``seconds``, ``fps``, ``speed`` (cycle rate multiplier),
``amplitude`` (angle scale) and ``seed``; the seed drives phases and
small smooth variations, so a (kind, parameters, seed) triple always gives
the same motion.  The first second eases in from the rest pose (arms
lowered) so simulations can start from rest.

Kinds: idle, walk, walk_arms_down, run, jump, arm_swing, touch_high, torso_twist, dance.
``walk_arms_down`` is a walk with the arms hanging at the sides (88 degrees below the
T-pose, as in motion capture), where sleeves are squeezed between arm and torso.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from ..body.skeleton import SMPL_JOINT_NAMES
from ..errors import InputError
from .limits import clip_to_limits, euler_to_pose
from .motion import Motion

__all__ = ["MOTION_KINDS", "make_motion"]

J = {n: i for i, n in enumerate(SMPL_JOINT_NAMES)}
D = np.pi / 180.0
# index of each Euler slot by axis name, per joint order (see limits.EULER_ORDER)
from .limits import EULER_ORDER  # noqa: E402

_SLOT = [{ax: k for k, ax in enumerate(order)} for order in EULER_ORDER]


class _Pose:
    """Per-frame Euler angle buffer addressed by joint name and axis."""

    def __init__(self, n: int):
        self.a = np.zeros((n, 24, 3))

    def add(self, joint: str, axis: str, values) -> None:
        j = J[joint]
        self.a[:, j, _SLOT[j][axis]] += values


def _smooth_noise(rng, t, n_terms=3, max_freq=0.7):
    """A smooth zero-mean signal in [-1, 1]: a few slow sines with random phases."""
    f = rng.uniform(0.1, max_freq, n_terms)
    ph = rng.uniform(0, 2 * np.pi, n_terms)
    return np.sum(np.sin(2 * np.pi * f[:, None] * t[None] + ph[:, None]), axis=0) / n_terms


def _arms_down(p: _Pose, w, amount=70.0):
    p.add("left_shoulder", "z", -amount * D * w)
    p.add("right_shoulder", "z", amount * D * w)


def _idle(p, t, w, rng, speed, amp):
    br = np.sin(2 * np.pi * 0.25 * speed * t)
    p.add("spine3", "x", 2 * D * amp * br)
    p.add("spine1", "z", 2 * D * amp * _smooth_noise(rng, t))
    p.add("neck", "y", 8 * D * amp * _smooth_noise(rng, t))
    p.add("head", "x", 4 * D * amp * _smooth_noise(rng, t))
    _arms_down(p, w)
    p.add("left_elbow", "y", -10 * D * w)
    p.add("right_elbow", "y", 10 * D * w)
    return np.zeros((len(t), 3))


def _gait(p, t, w, rng, speed, amp, run: bool, arms_down=None, arm_swing=None, elbow=None):
    freq = (1.4 if run else 0.9) * speed  # strides per second (one left + one right step)
    ph = 2 * np.pi * freq * t + rng.uniform(0, 2 * np.pi)
    s = np.sin(ph)
    hip = (45 if run else 25) * amp
    knee = (90 if run else 40) * amp
    p.add("left_hip", "x", -hip * D * s * w)
    p.add("right_hip", "x", hip * D * s * w)
    p.add("left_knee", "x", knee * D * np.maximum(0, np.sin(ph + 1.2)) * w)
    p.add("right_knee", "x", knee * D * np.maximum(0, np.sin(ph + np.pi + 1.2)) * w)
    p.add("left_ankle", "x", 10 * D * amp * np.sin(ph + 0.5) * w)
    p.add("right_ankle", "x", -10 * D * amp * np.sin(ph + 0.5) * w)
    _arms_down(p, w, arms_down if arms_down is not None else (65 if run else 75))
    arm = (arm_swing if arm_swing is not None else (40 if run else 25)) * amp
    p.add("left_shoulder", "y", -arm * D * -s * w)  # left arm swings against the left leg
    p.add("right_shoulder", "y", arm * D * -s * w)
    bend = elbow if elbow is not None else (70 if run else 20)
    p.add("left_elbow", "y", -bend * D * w)
    p.add("right_elbow", "y", bend * D * w)
    p.add("spine2", "y", 5 * D * amp * s * w)
    p.add("spine1", "x", (10 if run else 3) * D * w)
    v = (2.5 if run else 1.2) * speed
    trans = np.zeros((len(t), 3))
    trans[:, 2] = v * np.cumsum(w) / max(1, len(t)) * t[-1] if len(t) > 1 else 0.0
    trans[:, 1] = (0.05 if run else 0.02) * amp * np.abs(np.sin(ph)) * w
    return trans


def _walk(p, t, w, rng, speed, amp):
    return _gait(p, t, w, rng, speed, amp, run=False)


def _walk_arms_down(p, t, w, rng, speed, amp):
    return _gait(p, t, w, rng, speed, amp, run=False, arms_down=88.0, arm_swing=15.0, elbow=10.0)


def _run(p, t, w, rng, speed, amp):
    return _gait(p, t, w, rng, speed, amp, run=True)


def _jump(p, t, w, rng, speed, amp):
    period = 1.6 / speed
    ph = (t % period) / period  # 0..1 per jump: crouch 0-0.35, air 0.35-0.7, land 0.7-1
    crouch = np.where(ph < 0.35, np.sin(np.pi * ph / 0.35), 0.0) + np.where(
        ph > 0.7, np.sin(np.pi * (ph - 0.7) / 0.3), 0.0
    )
    air = np.where((ph >= 0.35) & (ph <= 0.7), np.sin(np.pi * (ph - 0.35) / 0.35), 0.0)
    c = crouch * w * amp
    for side in ("left", "right"):
        p.add(f"{side}_hip", "x", -60 * D * c)
        p.add(f"{side}_knee", "x", 100 * D * c)
        p.add(f"{side}_ankle", "x", 30 * D * c - 20 * D * air * w)
    p.add("spine1", "x", 20 * D * c)
    _arms_down(p, w, 70)
    p.add("left_shoulder", "y", -60 * D * (air - 0.5 * c) * w * amp)
    p.add("right_shoulder", "y", 60 * D * (air - 0.5 * c) * w * amp)
    trans = np.zeros((len(t), 3))
    trans[:, 1] = 0.35 * amp * air * w - 0.25 * c
    return trans


def _arm_swing(p, t, w, rng, speed, amp):
    ph = 2 * np.pi * 0.6 * speed * t + rng.uniform(0, 2 * np.pi)
    _arms_down(p, w, 40)
    p.add("left_shoulder", "y", -70 * D * amp * np.sin(ph) * w)
    p.add("right_shoulder", "y", -70 * D * amp * np.sin(ph) * w)
    p.add("left_shoulder", "z", 35 * D * amp * np.cos(ph) * w)
    p.add("right_shoulder", "z", -35 * D * amp * np.cos(ph) * w)
    p.add("spine2", "y", 8 * D * amp * np.sin(ph) * w)
    return np.zeros((len(t), 3))


def _touch_high(p, t, w, rng, speed, amp):
    period = 2.5 / speed
    raise_ = 0.5 - 0.5 * np.cos(2 * np.pi * t / period)
    side = np.sign(np.sin(np.pi * t / period + rng.uniform(0, 0.5)))  # alternate the reaching arm
    left = raise_ * (side > 0) * w * amp
    right = raise_ * (side <= 0) * w * amp
    _arms_down(p, w, 70)
    p.add("left_shoulder", "z", 200 * D * left)
    p.add("right_shoulder", "z", -200 * D * right)
    p.add("left_collar", "z", 25 * D * left)
    p.add("right_collar", "z", -25 * D * right)
    p.add("spine2", "z", -10 * D * left + 10 * D * right)
    p.add("left_ankle", "x", 20 * D * (left + right))
    p.add("right_ankle", "x", 20 * D * (left + right))
    trans = np.zeros((len(t), 3))
    trans[:, 1] = 0.04 * (left + right)
    return trans


def _torso_twist(p, t, w, rng, speed, amp):
    ph = 2 * np.pi * 0.5 * speed * t + rng.uniform(0, 2 * np.pi)
    for jn, k in (("spine1", 12), ("spine2", 12), ("spine3", 10)):
        p.add(jn, "y", k * D * amp * np.sin(ph) * w)
    p.add("pelvis", "y", -8 * D * amp * np.sin(ph) * w)
    _arms_down(p, w, 55)
    p.add("left_elbow", "y", -60 * D * w)
    p.add("right_elbow", "y", 60 * D * w)
    return np.zeros((len(t), 3))


def _dance(p, t, w, rng, speed, amp):
    beat = 2 * np.pi * 1.0 * speed * t
    hips = np.sin(beat)
    p.add("pelvis", "z", 6 * D * amp * hips * w)
    p.add("spine1", "z", -6 * D * amp * hips * w)
    p.add("left_knee", "x", 25 * D * amp * np.maximum(0, np.sin(beat)) * w)
    p.add("right_knee", "x", 25 * D * amp * np.maximum(0, -np.sin(beat)) * w)
    p.add("left_hip", "x", -15 * D * amp * np.maximum(0, np.sin(beat)) * w)
    p.add("right_hip", "x", -15 * D * amp * np.maximum(0, -np.sin(beat)) * w)
    trans = 0.03 * amp * np.stack([hips, -np.abs(np.cos(beat)), np.zeros_like(t)], 1) * w[:, None]
    # the upper body switches between arm moves every four beats, in a seeded order
    moves = [_arm_swing, _touch_high, _torso_twist]
    seg = np.floor(t * speed / 4.0).astype(int)
    order = rng.permutation(len(moves))
    for k, fn in enumerate(moves):
        mask = (order[seg % len(moves)] == k).astype(float)
        # smooth the switches over 0.25 s (no longer than the motion: np.convolve's "same" mode returns
        # the longer of its inputs)
        width = min(max(3, int(0.25 * len(t) / max(t[-1], 1e-6)) | 1), len(t) - 1 + len(t) % 2)
        if width >= 3:
            kern = np.hanning(width)
            mask = np.convolve(mask, kern / kern.sum(), mode="same")
        sub = _Pose(len(t))
        tr = fn(sub, t, w, rng, speed, amp)
        p.a += sub.a * mask[:, None, None]
        trans = trans + tr * mask[:, None]
    return trans


MOTION_KINDS: dict[str, Callable] = {
    "idle": _idle,
    "walk": _walk,
    "walk_arms_down": _walk_arms_down,
    "run": _run,
    "jump": _jump,
    "arm_swing": _arm_swing,
    "touch_high": _touch_high,
    "torso_twist": _torso_twist,
    "dance": _dance,
}


def make_motion(
    kind: str,
    *,
    seconds: float = 3.0,
    fps: float = 30.0,
    speed: float = 1.0,
    amplitude: float = 1.0,
    seed: int = 0,
    ease_in: float = 1.0,
) -> Motion:
    """A procedural motion (see the module docstring); deterministic per seed.

    Args:
        kind: one of :data:`MOTION_KINDS`.
        ease_in: seconds over which the motion blends in from the rest pose
            with arms lowered (0 for none).
    """
    if kind not in MOTION_KINDS:
        raise InputError("unknown motion kind", expected=" | ".join(MOTION_KINDS), got=kind)
    for name, val, lo, hi in (
        ("seconds", seconds, 1e-3, 3600),
        ("fps", fps, 1, 1000),
        ("speed", speed, 0.05, 5),
        ("amplitude", amplitude, 0, 2),
        ("ease_in", ease_in, 0, 3600),
    ):
        if not (np.isfinite(val) and lo <= val <= hi):
            raise InputError(f"{name} out of range", expected=f"{lo}..{hi}", got=val)
    from ..bounds import check_seed

    seed = check_seed(seed)
    n = max(1, int(round(seconds * fps)))
    t = np.arange(n) / fps
    w = np.ones(n) if ease_in <= 0 else np.clip(t / ease_in, 0, 1)
    w = w * w * (3 - 2 * w)  # smoothstep
    rng = np.random.default_rng(int(seed))
    p = _Pose(n)
    trans = MOTION_KINDS[kind](p, t, w, rng, float(speed), float(amplitude))
    poses = euler_to_pose(clip_to_limits(p.a))
    return Motion(
        poses=poses,
        trans=np.asarray(trans, np.float64),
        fps=float(fps),
        name=f"{kind}(speed={speed:g}, amplitude={amplitude:g}, seed={seed})",
    )
