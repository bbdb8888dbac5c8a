"""The **motion file** (``.sgdm``): a motion on the SMPL skeleton of one body, ready to feed a model package and its
body graph, in the scene-bundle container (:mod:`segadeform.io.sgdb`):

=============  ============  ===================================================================
poses          f32 (T, S, 3) each frame's local axis-angle joint rotations (radians, SMPL order)
trans          f32 (T, 3)    each frame's root translation (metres, +Y up), added to the root's rest joint
=============  ============  ===================================================================

``meta``: ``kind`` = ``"segadeform-motion"``, ``schema_version`` (1), ``fps``, ``name``, ``joint_names``
(S names), and when it was retargeted onto a body ``body`` (``{"name", "sha256"}``) and ``betas``.

:func:`write_motion_arrays` / :func:`read_motion_arrays` write and read the file's arrays and ``meta`` (every array
and key checked); :func:`segadeform.motion.write_motion_file` / :func:`~segadeform.motion.read_motion_file` turn a
:class:`~segadeform.motion.Motion` into one and back.
"""

from __future__ import annotations

import os
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from ..errors import FileFormatError
from .sgdb import DTYPES, read_bundle, write_bundle

__all__ = ["MOTION_KIND", "MOTION_SUFFIX", "MOTION_SCHEMA_VERSION", "write_motion_arrays", "read_motion_arrays"]

MOTION_KIND = "segadeform-motion"
MOTION_SUFFIX = ".sgdm"
MOTION_SCHEMA_VERSION = 1


def write_motion_arrays(
    path: str | os.PathLike,
    poses,
    trans,
    *,
    fps: float,
    name: str,
    joint_names: Sequence[str],
    source: str = "",
    body: dict | None = None,
    betas=None,
    start_frame: int = 0,
    warnings: Sequence[str] = (),
) -> Path:
    """Write a motion file: ``poses`` (T, S, 3) local axis-angle and ``trans`` (T, 3), as float32 (what the graphs
    take), ``fps``, ``name``, the S ``joint_names`` and ``source`` in ``meta``; ``body`` (``{"name", "sha256"}``)
    and ``betas``: the body it was retargeted onto; ``start_frame``: the source's frame number of its first frame
    (``motion export --frames 10:70``: 10; the runtimes write it as their point caches' start frame); ``warnings``:
    what ``motion export`` said of the motion (one-line texts), for the runtimes that play it to say again."""
    poses = np.asarray(poses, np.float64)
    meta = {
        "kind": MOTION_KIND,
        "schema_version": MOTION_SCHEMA_VERSION,
        "fps": float(fps),
        "name": str(name),
        "joint_names": list(joint_names),
        "source": str(source),
    }
    if body is not None:
        meta["body"] = dict(body)
    if betas is not None:
        meta["betas"] = [float(x) for x in np.asarray(betas, np.float64).ravel()]
    if start_frame:
        meta["start_frame"] = int(start_frame)
    if warnings:
        meta["warnings"] = [str(w) for w in warnings]
    arrays = {"poses": poses.astype(np.float32), "trans": np.asarray(trans, np.float32)}
    return write_bundle(path, arrays, meta)


def read_motion_arrays(path: str | os.PathLike) -> tuple[np.ndarray, np.ndarray, float, dict]:
    """``(poses (T, S, 3) f32, trans (T, 3) f32, fps, meta)`` of a motion file; every array and key checked."""
    p = Path(path)
    arrays, meta = read_bundle(p)
    if meta.get("kind") != MOTION_KIND:
        raise FileFormatError("not a motion file", path=p, expected=f"meta.kind {MOTION_KIND!r}", got=meta.get("kind"))
    if meta.get("schema_version") != MOTION_SCHEMA_VERSION:
        raise FileFormatError(
            "unsupported motion file schema version",
            path=p,
            expected=MOTION_SCHEMA_VERSION,
            got=meta.get("schema_version"),
        )
    poses, trans = arrays.get("poses"), arrays.get("trans")
    if poses is None or poses.dtype != DTYPES["f32"] or poses.ndim != 3 or poses.shape[2] != 3 or not len(poses):
        raise FileFormatError(
            "motion file poses must be f32 (T, S, 3), T >= 1",
            path=p,
            expected="f32 (T, S, 3)",
            got=None if poses is None else f"{poses.dtype} {poses.shape}",
        )
    if trans is None or trans.dtype != DTYPES["f32"] or trans.shape != (len(poses), 3):
        raise FileFormatError(
            "motion file trans must be f32 (T, 3) matching poses",
            path=p,
            expected=f"f32 ({len(poses)}, 3)",
            got=None if trans is None else f"{trans.dtype} {trans.shape}",
        )
    for name, a in (("poses", poses), ("trans", trans)):  # the first bad value named, as the runtimes name it
        bad = np.argwhere(~np.isfinite(a))
        if len(bad):
            where = ", ".join(str(int(i)) for i in bad[0])
            raise FileFormatError(f"field {name!r} contains NaN or inf (first at index [{where}])", path=p)
    try:
        fps = float(meta["fps"])
    except (KeyError, TypeError, ValueError):
        raise FileFormatError("motion file meta has no fps", path=p) from None
    said = meta.get("warnings", [])
    if not (isinstance(said, list) and all(isinstance(w, str) and w and "\n" not in w for w in said)):
        raise FileFormatError(
            "motion file meta.warnings is not a list of one-line texts", path=p, expected="strings without line breaks"
        )
    return poses, trans, fps, meta
