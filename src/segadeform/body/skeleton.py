"""The 24-joint SMPL skeleton: names, parents, and reading rest-pose joints from files."""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np

from ..errors import FileFormatError, check_readable, unreadable_error

__all__ = ["SMPL_JOINT_NAMES", "SMPL_PARENTS", "load_rest_joints", "default_rest_joints"]

SMPL_JOINT_NAMES = (
    "pelvis",
    "left_hip",
    "right_hip",
    "spine1",
    "left_knee",
    "right_knee",
    "spine2",
    "left_ankle",
    "right_ankle",
    "spine3",
    "left_foot",
    "right_foot",
    "neck",
    "left_collar",
    "right_collar",
    "head",
    "left_shoulder",
    "right_shoulder",
    "left_elbow",
    "right_elbow",
    "left_wrist",
    "right_wrist",
    "left_hand",
    "right_hand",
)
#: Parent of each joint; -1 for the root.
SMPL_PARENTS = np.array(
    [-1, 0, 0, 0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 9, 9, 12, 13, 14, 16, 17, 18, 19, 20, 21], dtype=np.int64
)


def _finite_joints(j, p: Path, what: str) -> np.ndarray:
    j = np.asarray(j)
    if j.ndim != 2 or j.shape[1] != 3 or j.shape[0] < 1:
        raise FileFormatError(f"{what} must be an (S, 3) array", path=p, expected="(S, 3)", got=j.shape)
    if not np.issubdtype(j.dtype, np.number):
        raise FileFormatError(f"{what} must be numeric", path=p, got=j.dtype)
    j = j.astype(np.float64)
    if not np.isfinite(j).all():
        raise FileFormatError(f"{what} contains NaN or inf", path=p)
    return j


def load_rest_joints(path: str | os.PathLike) -> np.ndarray:
    """Rest-pose joint positions ``(S, 3)`` from a ``.npy`` array or a body ``.npz``.

    A body ``.npz`` provides ``joints (S, 3)``, ``joint_template (S, 3)`` (segadeform's body
    format: the mean shape) or ``J_regressor (S, V)``
    with ``v_template (V, 3)`` (SMPL's form; joints = J_regressor @ v_template).
    Files are read with ``allow_pickle=False``.
    """
    p = Path(path)
    if p.suffix.lower() == ".npz":
        from ..io.npz import load_npz

        z = load_npz(p, what="body .npz")
    else:
        check_readable(p)
        try:
            z = np.load(p, allow_pickle=False)
        except (OSError, ValueError, EOFError) as e:
            raise unreadable_error(e, p, ".npy") from None
    if isinstance(z, np.ndarray):
        return _finite_joints(z, p, "joints")
    if "joints" in z:
        return _finite_joints(z["joints"], p, "joints")
    if "joint_template" in z:  # segadeform's own body format: the mean shape's rest joints
        return _finite_joints(z["joint_template"], p, "joint_template")
    if "J_regressor" in z and "v_template" in z:
        jr, vt = np.asarray(z["J_regressor"]), np.asarray(z["v_template"])
        if jr.ndim != 2 or vt.ndim != 2 or vt.shape[1] != 3 or jr.shape[1] != vt.shape[0]:
            raise FileFormatError(
                "J_regressor and v_template do not fit",
                path=p,
                expected="J_regressor (S, V) and v_template (V, 3)",
                got=f"{jr.shape} and {vt.shape}",
            )
        return _finite_joints(jr.astype(np.float64) @ vt.astype(np.float64), p, "joints")
    raise FileFormatError(
        "body file has no joints",
        path=p,
        expected="'joints', 'joint_template' or 'J_regressor' + 'v_template'",
        got=", ".join(z),
    )


def default_rest_joints() -> np.ndarray:
    """A 24-joint T-pose skeleton (metres, +Y up, facing +Z), roughly a 1.7 m adult.

    Hand-made stand-in proportions (not SMPL data), used where a skeleton is
    needed without a body file: writing BVH, tests.  The same values ship as
    ``samples/skeletons/tpose_joints_24.npy``.
    """
    return _TPOSE.copy()


_TPOSE = np.array(
    [
        [0.000, 0.950, 0.000],
        [0.090, 0.870, 0.000],
        [-0.090, 0.870, 0.000],
        [0.000, 1.060, -0.010],
        [0.100, 0.500, 0.000],
        [-0.100, 0.500, 0.000],
        [0.000, 1.190, 0.000],
        [0.110, 0.090, -0.020],
        [-0.110, 0.090, -0.020],
        [0.000, 1.250, 0.010],
        [0.120, 0.030, 0.100],
        [-0.120, 0.030, 0.100],
        [0.000, 1.480, -0.010],
        [0.070, 1.400, 0.000],
        [-0.070, 1.400, 0.000],
        [0.000, 1.580, 0.030],
        [0.180, 1.420, -0.010],
        [-0.180, 1.420, -0.010],
        [0.440, 1.420, -0.020],
        [-0.440, 1.420, -0.020],
        [0.690, 1.420, -0.010],
        [-0.690, 1.420, -0.010],
        [0.770, 1.420, -0.010],
        [-0.770, 1.420, -0.010],
    ]
)
