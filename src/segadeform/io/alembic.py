"""Alembic (``.abc``) mesh sequences through the optional ``alembic3d`` package (extra ``alembic``).

One ``OPolyMesh`` (triangles, or the garment file's own polygons and texture coordinates -- a face-varying
``uv`` -- when given its :class:`~segadeform.io.surface.Surface`) named after the file (``out/dress_walk.abc``
-> ``dress_walk``, as the USD writer names its prim; a body written beside the garment is then its own object on
import): topology written once with the first frame, positions per frame, uniform time sampling ``1 / fps`` from
``start / fps`` (``fps`` as :func:`~segadeform.io.writer.nominal_fps` rounds it).  Alembic (as Maya writes it)
winds faces clockwise, so faces are stored reversed and reversed back on reading; DCC importers
(Blender, Maya, Houdini) then show outward normals.  Vertex order is the
garment file's.  The archive is written under a temporary name and renamed
when closed.
"""

from __future__ import annotations

import gc
import os
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from ..errors import FileFormatError, InputError, check_readable, unreadable_error
from .atomic import _tmp_sibling
from .mesh import validate_mesh_arrays
from .sequence import LazyFrames
from .surface import fan_triangles
from .usd import usd_prim_name
from .writer import SequenceWriter, nominal_fps

__all__ = ["AlembicFrames", "AlembicSequenceWriter", "read_alembic_sequence", "alembic_available"]


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


def _reversed_corners(counts) -> np.ndarray:
    """The corner order that reverses every polygon (``counts`` corners each, face after face)."""
    c = np.asarray(counts, np.int64)
    end = np.cumsum(c)
    k = np.arange(int(c.sum())) - np.repeat(end - c, c)
    return np.repeat(end, c) - 1 - k


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
        surface=None,
        unit: float = 1.0,
    ) -> None:
        super().__init__(path, num_points, up=up, unit=unit)
        Abc, AbcGeom, AbcCoreAbstract, self._imath = _modules()
        _, self.faces = validate_mesh_arrays(np.zeros((num_points, 3)), faces)
        if not (np.isfinite(fps) and fps > 0):
            raise InputError("fps must be positive", got=fps)
        fps = nominal_fps(fps)  # 1 / 120, not 1 / 120.000048 (a BVH's Frame Time: 0.00833333)
        self._tmp = _tmp_sibling(self.path, directory=False)
        self._archive = Abc.OArchive(str(self._tmp))
        ts = self._archive.addTimeSampling(AbcCoreAbstract.TimeSampling(1.0 / fps, start_frame / fps))
        if name is None:  # the file's name, as an identifier (Alembic object names are paths' parts)
            name = usd_prim_name(self.path.stem)  # accents dropped, not the letters (ümlaut -> umlaut)
        self._schema = AbcGeom.OPolyMesh(self._archive.getTop(), name, ts).getSchema()
        self._sample = AbcGeom.OPolyMeshSchemaSample
        self._uvs = None
        if surface is None:
            self._counts, self._corners = np.full(len(self.faces), 3), self.faces[:, ::-1].ravel()
        else:  # the garment's own polygons, each reversed (Alembic's winding), and its texture coordinates
            if surface.n_vertices_used > num_points:
                raise InputError("the surface indexes more vertices than the frames have", path=self.path)
            self._counts = np.asarray(surface.counts, np.int64)
            order = _reversed_corners(self._counts)
            self._corners = np.asarray(surface.indices, np.int64)[order]
            if surface.uvs is not None:  # one per corner (face-varying, not indexed), in the reversed order
                per_corner = np.asarray(surface.uvs, np.float32)[np.asarray(surface.uv_indices)[order]]
                uv = self._imath.V2fArray(len(per_corner))
                np.asarray(memoryview(uv))[:] = per_corner
                self._uvs = AbcGeom.OV2fGeomParamSample(uv, AbcGeom.GeometryScope.kFacevaryingScope)

    def _append(self, frames: np.ndarray) -> None:
        im = self._imath
        for k, fr in enumerate(frames.astype(np.float32)):
            if self.num_samples + k == 0:
                args = (_v3(im, fr), _ints(im, self._corners), _ints(im, self._counts))
                s = self._sample(*args) if self._uvs is None else self._sample(*args, self._uvs)
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


def _first_mesh_schema(p: Path):
    """The schema of the first polygon mesh at the top level of archive ``p``; FileFormatError when there is none."""
    Abc, AbcGeom, _, _ = _modules()
    top = Abc.IArchive(str(p)).getTop()
    meshes = [
        top.getChild(i) for i in range(top.getNumChildren()) if AbcGeom.IPolyMesh.matches(top.getChild(i).getMetaData())
    ]
    if not meshes:
        raise FileFormatError("Alembic file has no polygon mesh at its top level", path=p)
    return AbcGeom.IPolyMesh(top, meshes[0].getName()).getSchema()


def alembic_timing(path: str | os.PathLike) -> tuple[float, float]:
    """``(fps, start frame)`` of an ``.abc`` mesh: its time sampling's frames per second (0 when it has no uniform
    step) and its first sample time over the time per frame (written as ``1 / fps`` and ``start_frame / fps``)."""
    p = Path(path)
    check_readable(p)
    try:
        ts = _first_mesh_schema(p).getTimeSampling()
        per_frame = float(ts.getTimeSamplingType().getTimePerCycle())
        first = float(ts.getSampleTime(0))
    except FileFormatError:
        raise
    except Exception as e:
        raise unreadable_error(e, p, "Alembic") from None
    return (1.0 / per_frame, first / per_frame) if per_frame > 0 else (0.0, 0.0)


def alembic_start_frame(path: str | os.PathLike) -> float:
    """The frame number of an ``.abc`` mesh's first sample (:func:`alembic_timing`)."""
    return alembic_timing(path)[1]


class AlembicFrames(LazyFrames):
    """The positions of an ``.abc`` mesh's samples ``(S, N, 3) float32``, read when indexed (N: the first
    sample's).  ``times``: the sample times.  Each read opens the archive and lets it go (Alembic maps the file
    into memory: an archive kept open over a long clip's reads holds all of it)."""

    def __init__(self, path: Path, times: np.ndarray, n_points: int) -> None:
        super().__init__(len(times), n_points, np.float32, path)
        self._file = path
        self.times = times

    def _read(self, indices: Sequence[int]) -> np.ndarray:
        Abc = _modules()[0]
        out = np.empty((len(indices), *self.shape[1:]), np.float32)
        try:
            positions = _first_mesh_schema(self._file).getPositionsProperty()
            for j, i in enumerate(indices):
                pts = np.asarray(memoryview(positions.getValue(Abc.ISampleSelector(float(self.times[i])))))
                if pts.shape != out.shape[1:]:
                    raise FileFormatError(
                        f"Alembic sample {i} has another number of points than the first",
                        path=self._file,
                        expected=out.shape[1:],
                        got=pts.shape,
                    )
                out[j] = pts
        except FileFormatError:
            raise
        except Exception as e:
            raise unreadable_error(e, self._file, "Alembic") from None
        return out


def read_alembic_sequence(path: str | os.PathLike, *, lazy: bool = False) -> tuple[np.ndarray, Any, np.ndarray]:
    """Read the first PolyMesh of an ``.abc`` file: faces ``(F, 3)``, frames ``(S, N, 3)`` float64, times ``(S,)``.

    ``lazy``: frames are an :class:`AlembicFrames` (float32, each sample read when indexed) instead of an array."""
    p = Path(path)
    check_readable(p)  # a missing file is worded like every reader's, with or without the extra
    Abc, _, _, _ = _modules()
    try:
        schema = _first_mesh_schema(p)
        ts = schema.getTimeSampling()
        n = schema.getNumSamples()
        first = schema.getValue(Abc.ISampleSelector(ts.getSampleTime(0)))
        counts = np.array(memoryview(first.getFaceCounts())).astype(np.int64)
        corners = np.array(memoryview(first.getFaceIndices())).astype(np.int64)
        if not counts.size or (counts < 3).any() or corners.size != counts.sum():
            raise FileFormatError("Alembic mesh faces are not polygons of 3 or more corners", path=p)
        faces = fan_triangles(counts, corners[_reversed_corners(counts)])  # back to counter-clockwise
        times = np.array([ts.getSampleTime(i) for i in range(n)])
        frames = AlembicFrames(p, times, len(memoryview(first.getPositions())))
    except FileFormatError:
        raise
    except Exception as e:
        raise unreadable_error(e, p, "Alembic") from None
    return faces, (frames if lazy else frames.read_all(np.float64)), times
