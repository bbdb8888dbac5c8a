"""Everything a run or a simulation writes for a scene, as one unit: the garment sequence and, if asked,
the posed body sequence with (for point caches) the body's rest mesh the cache animates.

All of it is written atomically and committed or discarded together; :meth:`SceneOutput.close`
returns every path written, so callers can announce each one.
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import Optional

import numpy as np

from .formats import open_sequence_writer, sequence_format
from .writer import to_up

__all__ = ["SceneOutput"]


class SceneOutput:
    """Writers for a scene's outputs.

    Args:
        path, fmt: the garment output and its format (a name in :data:`~segadeform.io.SEQUENCE_FORMATS`).
        up: axes of the written coordinates ("y" as computed, "z" turned to Z-up).
        fps, start_frame: timing of the first written frame.
        garment_faces (F, 3), garment_rest (N, 3): the garment mesh.
        body_path: also write the posed body here (same format), with ``body_faces`` and ``body_rest``
            (V, 3) -- for PC2 the rest mesh goes beside it as ``.obj``.
    """

    def __init__(self, *, path: str | os.PathLike, fmt: str, up: str = "y", fps: float = 30.0, start_frame: int = 0,
                 garment_faces: np.ndarray, garment_rest: np.ndarray, body_path: Optional[os.PathLike] = None,
                 body_faces: Optional[np.ndarray] = None, body_rest: Optional[np.ndarray] = None) -> None:
        sequence_format(fmt)  # unknown formats fail before anything is opened
        self.fmt, self.up = fmt, up
        rest = np.asarray(garment_rest, np.float64)
        self.garment = open_sequence_writer(path, fmt, faces=garment_faces, num_points=len(rest), fps=fps,
                                            start_frame=start_frame, rest=rest, up=up)
        self.body = None
        self._body_rest = None
        if body_path is not None:
            try:
                self.body = open_sequence_writer(body_path, fmt, faces=body_faces, num_points=len(body_rest), fps=fps,
                                                 start_frame=start_frame, rest=np.asarray(body_rest), up=up)
            except BaseException:
                self.garment.abort()
                raise
            self._body_faces, self._body_rest = body_faces, np.asarray(body_rest, np.float64)

    def write(self, garment_frames: np.ndarray, body_frames: Optional[np.ndarray] = None) -> None:
        """Append frames ``(B, N, 3)`` (+Y up) of the garment and, when writing it, the body."""
        self.garment.write(garment_frames)
        if self.body is not None:
            self.body.write(body_frames)

    def close(self) -> list[Path]:
        """Commit everything; the paths written, garment first."""
        from .mesh import Mesh
        from .obj import write_obj

        written = [self.garment.close()]
        if self.body is not None:
            written.append(self.body.close())
            if self.fmt == "pc2":  # the rest mesh the cache animates (Blender's Mesh Cache, 3ds Max)
                obj = Path(self.body.path).with_suffix(".obj")
                write_obj(obj, Mesh(vertices=to_up(self._body_rest, self.up), faces=self._body_faces))
                written.append(obj)
        return written

    def abort(self) -> None:
        self.garment.abort()
        if self.body is not None:
            self.body.abort()

    def __enter__(self):
        return self

    def __exit__(self, exc_type, exc, tb) -> None:
        if exc_type is not None:
            self.abort()
