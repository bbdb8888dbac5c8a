"""USD (``.usd``, ``.usda``, ``.usdc``) mesh sequences through the optional ``usd-core`` package (extra ``usd``).

One ``UsdGeom.Mesh`` named after the file (``out/dress_walk.usd`` -> ``/dress_walk``, ``07 walk.usd`` ->
``/_07_walk``: :func:`usd_prim_name`; the stage's default prim):
faces written once (``faceVertexCounts`` all 3, ``faceVertexIndices`` in the garment file's order -- or, given the
garment file's own :class:`~segadeform.io.surface.Surface`, its quads and polygons and its texture coordinates as
the face-varying ``st`` primvar -- counter-clockwise = ``rightHanded``, no subdivision), ``points`` and ``extent``
as time samples at time codes ``start_frame, start_frame + 1, ...``. The stage says how to read them: ``upAxis``
(``Y`` as computed, or ``Z`` for ``--up z``), ``metersPerUnit = 1`` and ``timeCodesPerSecond = framesPerSecond =
fps``, with ``startTimeCode``/``endTimeCode`` spanning the frames. ``.usd`` and ``.usdc`` are written binary
(crate), ``.usda`` as text.

The stage is built in memory and exported under a temporary name when the writer closes, then renamed: a failed run
leaves nothing.
"""

from __future__ import annotations

import contextlib
import os
import re
import unicodedata
from pathlib import Path

import numpy as np

from ..errors import FileFormatError, InputError, check_readable, unreadable_error
from .atomic import WriteError, _tmp_sibling, write_error
from .mesh import validate_mesh_arrays
from .surface import fan_triangles
from .writer import SequenceWriter, nominal_fps

__all__ = [
    "UsdSequenceWriter",
    "read_usd_mesh",
    "read_usd_sequence",
    "usd_available",
    "usd_prim_name",
    "USD_EXTENSIONS",
]

USD_EXTENSIONS = (".usd", ".usda", ".usdc")


def _modules():
    try:
        from pxr import Sdf, Tf, Usd, UsdGeom, Vt
    except ImportError:
        raise InputError("USD output needs the 'usd' extra: pip install 'segadeform[usd]'") from None
    return Usd, UsdGeom, Sdf, Vt, Tf


#: letters NFKD does not take apart into a Latin letter and marks
_LATIN = str.maketrans(dict(zip("ßæÆøØœŒłŁđĐðÐþÞı", "ss ae AE o O oe OE l L d D d D th Th i".split(), strict=True)))


def usd_prim_name(stem: str) -> str:
    """A valid USD prim name (``[A-Za-z_][A-Za-z0-9_]*``) keeping ``stem``'s characters where it can: accented
    letters lose their accents (``ümlaut`` -> ``umlaut``), other characters become ``_``, and a leading digit gets
    a ``_`` before it (``07-walk crop`` -> ``_07_walk_crop``); ``mesh`` when nothing of the name is left."""
    ascii_ = "".join(c for c in unicodedata.normalize("NFKD", stem.translate(_LATIN)) if not unicodedata.combining(c))
    name = re.sub(r"[^0-9A-Za-z_]", "_", ascii_)
    if not re.search(r"[0-9A-Za-z]", name):
        return "mesh"
    return "_" + name if name[0].isdigit() else name


def usd_available() -> bool:
    try:
        _modules()
        return True
    except InputError:
        return False


class UsdSequenceWriter(SequenceWriter):
    """Stream frames into a USD stage; the file appears when :meth:`close` succeeds.

    Args:
        path: ``.usd``, ``.usda`` or ``.usdc``.
        faces: (F, 3) triangles; num_points: N.
        fps: frames per second (the stage's time codes per second, as :func:`~segadeform.io.writer.nominal_fps`
            rounds it); start_frame: the first frame's time code.
        up: "y" (as computed) or "z" (points turned to Z-up, ``upAxis = Z``).
    """

    def __init__(
        self,
        path: str | os.PathLike,
        faces: np.ndarray,
        num_points: int,
        *,
        fps: float = 30.0,
        start_frame: int = 0,
        up: str = "y",
        surface=None,
    ) -> None:
        super().__init__(path, num_points, up=up)
        ext = self.path.suffix.lower()
        if ext not in USD_EXTENSIONS:
            raise InputError("not a USD file name", path=self.path, expected=" | ".join(USD_EXTENSIONS), got=ext)
        Usd, UsdGeom, Sdf, self._Vt, _ = _modules()
        _, self.faces = validate_mesh_arrays(np.zeros((num_points, 3)), faces)
        if not (np.isfinite(fps) and fps > 0):
            raise InputError("fps must be positive", got=fps)
        self._Usd = Usd
        self.fps, self.start = nominal_fps(fps), float(start_frame)  # 120, not a BVH's 120.000048
        self._stage = Usd.Stage.CreateInMemory()
        UsdGeom.SetStageUpAxis(self._stage, UsdGeom.Tokens.z if up == "z" else UsdGeom.Tokens.y)
        UsdGeom.SetStageMetersPerUnit(self._stage, 1.0)
        self._stage.SetTimeCodesPerSecond(self.fps)
        self._stage.SetFramesPerSecond(self.fps)
        self._stage.SetStartTimeCode(self.start)
        mesh = UsdGeom.Mesh.Define(self._stage, Sdf.Path("/" + usd_prim_name(self.path.stem)))
        self._stage.SetDefaultPrim(mesh.GetPrim())
        if surface is None:
            counts, corners = np.full(len(self.faces), 3, np.int32), self.faces.astype(np.int32).ravel()
        else:  # the garment's own polygons (and texture coordinates: the `st` primvar, face-varying)
            if surface.n_vertices_used > num_points:
                raise InputError("the surface indexes more vertices than the frames have", path=self.path)
            counts, corners = np.asarray(surface.counts, np.int32), np.asarray(surface.indices, np.int32)
        mesh.CreateFaceVertexCountsAttr(self._Vt.IntArray.FromNumpy(counts))
        mesh.CreateFaceVertexIndicesAttr(self._Vt.IntArray.FromNumpy(corners))
        if surface is not None and surface.uvs is not None:
            st = UsdGeom.PrimvarsAPI(mesh.GetPrim()).CreatePrimvar(
                "st", Sdf.ValueTypeNames.TexCoord2fArray, UsdGeom.Tokens.faceVarying
            )
            st.Set(self._Vt.Vec2fArray.FromNumpy(np.asarray(surface.uvs, np.float32)))
            st.SetIndices(self._Vt.IntArray.FromNumpy(np.asarray(surface.uv_indices, np.int32)))
        mesh.CreateSubdivisionSchemeAttr(UsdGeom.Tokens.none)
        mesh.CreateOrientationAttr(UsdGeom.Tokens.rightHanded)
        self._points = mesh.CreatePointsAttr()
        self._extent = mesh.CreateExtentAttr()

    def _append(self, frames: np.ndarray) -> None:
        Vt, Usd = self._Vt, self._Usd
        for k, fr in enumerate(frames.astype(np.float32)):
            t = Usd.TimeCode(self.start + self.num_samples + k)
            self._points.Set(Vt.Vec3fArray.FromNumpy(fr), t)
            self._extent.Set(Vt.Vec3fArray.FromNumpy(np.stack([fr.min(axis=0), fr.max(axis=0)])), t)

    def _commit(self) -> None:
        self._stage.SetEndTimeCode(self.start + max(self.num_samples - 1, 0))
        ext = self.path.suffix.lower()
        hold = _tmp_sibling(self.path, directory=False)  # reserves the name; USD needs the extension
        tmp = hold.with_name(hold.name + ext)
        try:
            args = {"format": "usdc"} if ext == ".usd" else {}
            if not self._stage.GetRootLayer().Export(str(tmp), "", args):
                raise WriteError(self.path, "USD could not export the stage; nothing was left behind")
            os.replace(tmp, self.path)
        except OSError as e:
            raise write_error(e, self.path) from None
        finally:
            with contextlib.suppress(FileNotFoundError):
                tmp.unlink()
            with contextlib.suppress(FileNotFoundError):
                hold.unlink()
            self._stage = None

    def _discard(self) -> None:
        self._stage = None


def read_usd_sequence(path: str | os.PathLike) -> tuple[np.ndarray, np.ndarray, np.ndarray, dict]:
    """The first mesh of a USD file: faces ``(F, 3)``, frames ``(S, N, 3)`` (its points' time samples, or its
    one default value), time codes ``(S,)`` and the stage's ``{"up", "meters_per_unit", "fps", "start",
    "end", "prim"}``.  Non-finite points are returned as they are (``segadeform inspect`` reports them)."""
    counts, idx, frames, times, info = read_usd_mesh(path)
    return fan_triangles(counts, idx), frames, times, info


def read_usd_mesh(path: str | os.PathLike) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, dict]:
    """:func:`read_usd_sequence` with the mesh's own polygons for its triangles: ``faceVertexCounts (F,)`` and
    ``faceVertexIndices (C,)``, then frames, time codes and the stage's values."""
    p = Path(path)
    check_readable(p)
    Usd, UsdGeom, _, _, _ = _modules()
    try:
        stage = Usd.Stage.Open(str(p))
    except Exception as e:  # pxr raises Tf.ErrorException on a file it cannot parse
        raise unreadable_error(e, p, "USD") from None
    if stage is None:
        raise FileFormatError("not a readable USD file", path=p)
    mesh = next((UsdGeom.Mesh(prim) for prim in stage.Traverse() if prim.IsA(UsdGeom.Mesh)), None)
    if mesh is None:
        raise FileFormatError("USD file has no mesh", path=p, expected="a UsdGeom.Mesh prim", got="none")
    counts = np.asarray(mesh.GetFaceVertexCountsAttr().Get() or [], np.int64)
    idx = np.asarray(mesh.GetFaceVertexIndicesAttr().Get() or [], np.int64)
    if counts.size == 0 or (counts < 3).any() or idx.size != counts.sum():
        raise FileFormatError(
            "USD mesh faces are not polygons of 3 or more corners",
            path=p,
            expected="faceVertexCounts >= 3 summing to the faceVertexIndices",
            got=f"{counts.size} faces, counts {sorted(set(counts.tolist()))[:5]}, {idx.size} indices",
        )
    attr = mesh.GetPointsAttr()
    times = np.asarray(attr.GetTimeSamples(), np.float64)
    if times.size:
        frames = np.stack([np.asarray(attr.Get(t), np.float64) for t in times])
    else:
        pts = attr.Get()
        if pts is None:
            raise FileFormatError("USD mesh has no points", path=p, got=str(mesh.GetPath()))
        frames, times = np.asarray(pts, np.float64)[None], np.zeros(1)
    if frames.ndim != 3 or frames.shape[2] != 3:
        raise FileFormatError("USD points are not 3-vectors", path=p, got=frames.shape)
    if idx.size and (idx.min() < 0 or idx.max() >= frames.shape[1]):
        raise FileFormatError(
            "USD face index out of range", path=p, expected=f"0..{frames.shape[1] - 1}", got=f"{idx.min()}..{idx.max()}"
        )
    info = {
        "up": str(UsdGeom.GetStageUpAxis(stage)),
        "meters_per_unit": float(UsdGeom.GetStageMetersPerUnit(stage)),
        "fps": float(stage.GetTimeCodesPerSecond()),
        "start": float(stage.GetStartTimeCode()),
        "end": float(stage.GetEndTimeCode()),
        "prim": str(mesh.GetPath()),
    }
    return counts, idx, frames, times, info
