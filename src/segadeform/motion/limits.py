"""Human joint limits for the 24-joint SMPL skeleton, as local Euler angles.

Axes are SMPL's rest-pose (T-pose) axes: +X the body's left, +Y up, +Z
forward.  Each joint has an Euler order whose *middle* angle stays inside
(-90, 90) degrees, so a rotation decodes back to the same angles
(:func:`segadeform.body.rotations.matrix_to_euler`) and "inside the limits"
is a well-defined test.  Ranges are conservative active ranges of motion from
the clinical literature, rounded; the root (joint 0) is unconstrained.

Sign conventions that follow from the axes: hip flexion (leg forward) is
negative X; knee flexion positive X; spine flexion (bend forward) positive X;
left shoulder raise positive Z, right shoulder raise negative Z; left elbow
flexion negative Y, right elbow flexion positive Y.
"""

from __future__ import annotations

import numpy as np

from ..body.rotations import axis_angle_to_matrix, euler_to_matrix, matrix_to_axis_angle, matrix_to_euler
from ..body.skeleton import SMPL_JOINT_NAMES

__all__ = ["JOINT_LIMITS", "EULER_ORDER", "euler_to_pose", "pose_to_euler", "clip_to_limits", "limit_violation"]

#: joint -> (order, ((lo, hi) for the three angles in that order)) in degrees
_L = {
    "left_hip": ("xzy", ((-120, 40), (-30, 50), (-45, 45))),
    "right_hip": ("xzy", ((-120, 40), (-50, 30), (-45, 45))),
    "spine1": ("xzy", ((-30, 45), (-25, 25), (-30, 30))),
    "left_knee": ("xzy", ((0, 150), (-10, 10), (-10, 10))),
    "right_knee": ("xzy", ((0, 150), (-10, 10), (-10, 10))),
    "spine2": ("xzy", ((-30, 45), (-25, 25), (-30, 30))),
    "left_ankle": ("xzy", ((-50, 30), (-25, 25), (-25, 25))),
    "right_ankle": ("xzy", ((-50, 30), (-25, 25), (-25, 25))),
    "spine3": ("xzy", ((-30, 45), (-25, 25), (-30, 30))),
    "left_foot": ("xzy", ((-30, 30), (-10, 10), (-10, 10))),
    "right_foot": ("xzy", ((-30, 30), (-10, 10), (-10, 10))),
    "neck": ("xzy", ((-40, 45), (-35, 35), (-50, 50))),
    "left_collar": ("zyx", ((-15, 30), (-20, 20), (-15, 15))),
    "right_collar": ("zyx", ((-30, 15), (-20, 20), (-15, 15))),
    "head": ("xzy", ((-30, 30), (-30, 30), (-40, 40))),
    "left_shoulder": ("zyx", ((-90, 150), (-85, 40), (-90, 90))),
    "right_shoulder": ("zyx", ((-150, 90), (-40, 85), (-90, 90))),
    "left_elbow": ("yzx", ((-150, 0), (-10, 10), (-90, 90))),
    "right_elbow": ("yzx", ((0, 150), (-10, 10), (-90, 90))),
    "left_wrist": ("xzy", ((-80, 80), (-70, 70), (-40, 40))),
    "right_wrist": ("xzy", ((-80, 80), (-70, 70), (-40, 40))),
    "left_hand": ("xzy", ((-20, 20), (-20, 20), (-20, 20))),
    "right_hand": ("xzy", ((-20, 20), (-20, 20), (-20, 20))),
}
EULER_ORDER = tuple(["xyz"] + [_L[n][0] for n in SMPL_JOINT_NAMES[1:]])
#: (24, 3, 2) radians; the root row is (-inf, inf)
JOINT_LIMITS = np.array([[(-np.inf, np.inf)] * 3] + [np.deg2rad(_L[n][1]) for n in SMPL_JOINT_NAMES[1:]])


def euler_to_pose(angles: np.ndarray) -> np.ndarray:
    """Per-joint Euler angles ``(..., 24, 3)`` (each joint in its ``EULER_ORDER``) to axis-angle ``(..., 72)``."""
    a = np.asarray(angles, np.float64)
    R = np.empty(a.shape[:-1] + (3, 3))
    for j, order in enumerate(EULER_ORDER):
        R[..., j, :, :] = euler_to_matrix(a[..., j, :], order)
    return matrix_to_axis_angle(R).reshape(a.shape[:-2] + (72,))


def pose_to_euler(poses: np.ndarray) -> np.ndarray:
    """Axis-angle poses ``(..., 72)`` to per-joint Euler angles ``(..., 24, 3)``."""
    p = np.asarray(poses, np.float64)
    R = axis_angle_to_matrix(p.reshape(p.shape[:-1] + (24, 3)))
    out = np.empty(p.shape[:-1] + (24, 3))
    for j, order in enumerate(EULER_ORDER):
        out[..., j, :] = matrix_to_euler(R[..., j, :, :], order)
    return out


def clip_to_limits(angles: np.ndarray) -> np.ndarray:
    return np.clip(angles, JOINT_LIMITS[..., 0], JOINT_LIMITS[..., 1])


def limit_violation(poses: np.ndarray) -> float:
    """Largest excursion (radians) of any non-root joint angle outside its limits; 0 when inside."""
    e = pose_to_euler(poses)[..., 1:, :]
    lo, hi = JOINT_LIMITS[1:, :, 0], JOINT_LIMITS[1:, :, 1]
    return float(max(0.0, np.max(lo - e), np.max(e - hi)))
