"""Where the character stands: the graphs run at the root and the translation is added after them.

The deformer and body graphs compute in float32.  Fed the world translation, they rounded every vertex to float32's
spacing at that distance (61 µm at 1 km), and a vertex the network put deep inside the body could then leave it on
the other side: the same clip 100 m from the origin gave a garment up to 5.9 cm off (a new user's trial, 30 Nov
2026).  So every runtime runs the graphs with ``trans`` zero -- the frames relative to the root, the same numbers
wherever the character stands -- and adds the translation afterwards in float64, rounded to float32 first as motion
files hold it (``.sgdm``): Python here, ``runtimes/node/src/core.js`` and ``runtimes/cpp/src/engine.hpp`` the same
way, so that their frames stay equal.  Collisions are resolved at the root too; the cloth stage, which keeps its state
from frame to frame, runs in world coordinates in float64."""

from __future__ import annotations

import numpy as np

__all__ = ["at_translation"]


def at_translation(frames, trans) -> np.ndarray:
    """Frames computed at the root, moved to the translation.

    Shapes:
        frames: (B, N, 3), trans: (B, 3) metres -> (B, N, 3) float64: ``frames + float32(trans)``
    """
    t = np.asarray(trans, np.float32).astype(np.float64)
    return np.asarray(frames, np.float64) + t[:, None, :]
