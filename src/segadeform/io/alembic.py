"""Alembic (``.abc``) mesh sequences through the optional ``alembic3d`` package (extra ``alembic``).

One ``OPolyMesh`` named after the file (``out/dress_walk.abc`` -> ``dress_walk``, as the USD writer names its
prim; a body written beside the garment is then its own object on import): topology written once with the
first frame, positions per frame, uniform time sampling ``1 / fps`` from
``start / fps``.  Alembic (as Maya writes it) winds faces clockwise, so
triangles are stored reversed and reversed back on reading; DCC importers
(Blender, Maya, Houdini) then show outward normals.  Vertex order is the
garment file's.  The archive is written under a temporary name and renamed
when closed.
"""

from __future__ import annotations

import gc
import os
import re
from pathlib import Path

import numpy as np

from ..errors import FileFormatError, InputError, check_readable, unreadable_error
from .atomic import _tmp_sibling
from .mesh import validate_mesh_arrays
from .writer import SequenceWriter

__all__ = ["AlembicSequenceWriter", "read_alembic_sequence", "alembic_available"]


def _modules():
    try:
        import imath
        from alembic3d import Abc, AbcCoreAbstract, AbcGeom
    except ImportError:
        raise InputError("Alembic output needs the 'alembic' extra: pip install 'segadeform[alembic]'") from None
    return Abc, AbcGeom, AbcCoreAbstract, imath


def alembic_available() -> bool:
    try:
        _modules()
        return True
    except InputError:
        return False


def _v3(imath, a: np.ndarray):
    arr = imath.V3fArray(len(a))
    np.asarray(memoryview(arr))[:] = a
    return arr


def _ints(imath, a: np.ndarray):
    arr = imath.IntArray(len(a))
    np.asarray(memoryview(arr))[:] = a
    return arr


class AlembicSequenceWriter(SequenceWriter):
    """Stream frames into an ``.abc`` file; the file appears when :meth:`close` succeeds."""

    def __init__(
        self,
        path: str | os.PathLike,
        faces: np.ndarray,
        num_points: int,
        *,
        fps: float = 30.0,
        start_frame: int = 0,
        name: str | None = None,
        up: str = "y",
    ) -> None:
        super().__init__(path, num_points, up=up)
        Abc, AbcGeom, AbcCoreAbstract, self._imath = _modules()
        _, self.faces = validate_mesh_arrays(np.zeros((num_points, 3)), faces)
        if not (np.isfinite(fps) and fps > 0):
            raise InputError("fps must be positive", got=fps)
        self._tmp = _tmp_sibling(self.path, directory=False)
        self._archive = Abc.OArchive(str(self._tmp))
        ts = self._archive.addTimeSampling(AbcCoreAbstract.TimeSampling(1.0 / fps, start_frame / fps))
        if name is None:  # the file's name, as an identifier (Alembic object names are paths' parts)
            name = re.sub(r"[^0-9A-Za-z_]", "_", self.path.stem) or "mesh"
        self._schema = AbcGeom.OPolyMesh(self._archive.getTop(), name, ts).getSchema()
        self._sample = AbcGeom.OPolyMeshSchemaSample

    def _append(self, frames: np.ndarray) -> None:
        im = self._imath
        for k, fr in enumerate(frames.astype(np.float32)):
            if self.num_samples + k == 0:
                s = self._sample(
                    _v3(im, fr), _ints(im, self.faces[:, ::-1].ravel()), _ints(im, np.full(len(self.faces), 3))
                )
            else:
                s = self._sample(_v3(im, fr))
            self._schema.set(s)

    def _release(self) -> None:
        self._schema = None
        self._archive = None  # the archive is written out when its last reference goes
        gc.collect()

    def _commit(self) -> None:
        self._release()
        os.replace(self._tmp, self.path)

    def _discard(self) -> None:
        self._release()
        self._tmp.unlink(missing_ok=True)


def read_alembic_sequence(path: str | os.PathLike) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Read the first PolyMesh of an ``.abc`` file: faces ``(F, 3)``, frames ``(S, N, 3)``, times ``(S,)``."""
    p = Path(path)
    check_readable(p)  # a missing file is worded like every reader's, with or without the extra
    Abc, AbcGeom, _, _ = _modules()
    try:
        top = Abc.IArchive(str(p)).getTop()
        meshes = [
            top.getChild(i)
            for i in range(top.getNumChildren())
            if AbcGeom.IPolyMesh.matches(top.getChild(i).getMetaData())
        ]
        if not meshes:
            raise FileFormatError("Alembic file has no polygon mesh at its top level", path=p)
        schema = AbcGeom.IPolyMesh(top, meshes[0].getName()).getSchema()
        ts = schema.getTimeSampling()
        n = schema.getNumSamples()
        first = schema.getValue(Abc.ISampleSelector(ts.getSampleTime(0)))
        counts = np.array(memoryview(first.getFaceCounts()))
        if (counts != 3).any():
            raise FileFormatError("Alembic mesh is not all triangles", path=p)
        faces = np.array(memoryview(first.getFaceIndices())).reshape(-1, 3)[:, ::-1].astype(np.int64)
        times = np.array([ts.getSampleTime(i) for i in range(n)])
        frames = np.stack(
            [np.array(memoryview(schema.getValue(Abc.ISampleSelector(t)).getPositions())) for t in times]
        ).astype(np.float64)
    except FileFormatError:
        raise
    except Exception as e:
        raise unreadable_error(e, p, "Alembic") from None
    return faces, frames, times
