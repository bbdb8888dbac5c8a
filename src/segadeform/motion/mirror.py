"""Left-right mirror images of motions and point sets (the body's sagittal plane, x = 0 in the body's frame).

A reflection ``M = diag(-1, 1, 1)`` (x mirrored, +Y up) turns a rotation ``R`` into ``M R M``; in axis-angle
``w -> (w_x, -w_y, -w_z)``.  A mirrored skeleton also swaps each ``left_*`` joint with its ``right_*`` twin, so
the mirrored motion of a body that is left-right symmetric (the default body is, to 0.06 mm on average) poses it
into the mirror image of the original's frames::

    forward(mirror_poses(p), betas, mirror_points(t)) == mirror_points(forward(p, betas, t))   (joints exactly)

Shapes::

    poses   (..., 3 S) axis-angle per joint, in ``joint_names`` order
    points  (..., 3)
"""

from __future__ import annotations

import numpy as np

from ..errors import InputError

__all__ = ["mirror_joint_order", "mirror_poses", "mirror_points", "mirror_faces"]


def mirror_joint_order(joint_names) -> np.ndarray:
    """``perm`` (S,) int: joint ``j`` of a mirrored pose takes joint ``perm[j]``'s rotation (``left_x`` <->
    ``right_x``, every other joint itself).  A ``left_`` joint without its ``right_`` twin (or the reverse) is an
    error: such a skeleton has no mirror image."""
    names = [str(n) for n in joint_names]
    index = {n: i for i, n in enumerate(names)}
    perm = np.arange(len(names))
    for i, n in enumerate(names):
        for a, b in (("left_", "right_"), ("right_", "left_")):
            if n.startswith(a):
                twin = b + n[len(a) :]
                if twin not in index:
                    raise InputError(
                        f"joint '{n}' has no mirror twin: the skeleton has no left-right mirror image",
                        expected=f"a joint named '{twin}'",
                        got=", ".join(names),
                    )
                perm[i] = index[twin]
    return perm


def mirror_poses(poses, joint_names) -> np.ndarray:
    """The mirror image of ``poses`` (..., 3 S): twins swapped, each axis-angle ``(x, y, z) -> (x, -y, -z)``."""
    p = np.asarray(poses)
    s = len(joint_names)
    if p.ndim < 1 or p.shape[-1] != 3 * s:
        raise InputError("poses must be (..., 3 S) axis-angle", expected=f"(..., {3 * s})", got=p.shape)
    q = p.reshape(p.shape[:-1] + (s, 3))[..., mirror_joint_order(joint_names), :] * np.array([1.0, -1.0, -1.0])
    return q.reshape(p.shape).astype(p.dtype, copy=False)


def mirror_points(x) -> np.ndarray:
    """``x`` (..., 3) reflected in the plane x = 0 (a new array)."""
    y = np.array(x, copy=True)
    if y.ndim < 1 or y.shape[-1] != 3:
        raise InputError("points must be (..., 3)", expected="(..., 3)", got=y.shape)
    y[..., 0] *= -1
    return y


def mirror_faces(faces) -> np.ndarray:
    """Triangles (F, 3) of a mirrored mesh: each wound the other way, so that normals still point outward."""
    f = np.asarray(faces)
    if f.ndim != 2 or f.shape[1] != 3:
        raise InputError("faces must be (F, 3)", expected="(F, 3)", got=f.shape)
    return f[:, ::-1].copy()
