"""USD (``.usd``, ``.usda``, ``.usdc``) mesh sequences through the optional ``usd-core`` package (extra ``usd``).

One ``UsdGeom.Mesh`` named after the file (``out/dress_walk.usd`` -> ``/dress_walk``, ``07 walk.usd`` ->
``/_07_walk``: :func:`usd_prim_name`; the stage's default prim):
faces written once (``faceVertexCounts`` all 3, ``faceVertexIndices`` in the garment file's order -- or, given the
garment file's own :class:`~segadeform.io.surface.Surface`, its quads and polygons and its texture coordinates as
the face-varying ``st`` primvar -- counter-clockwise = ``rightHanded``, no subdivision), ``points`` and ``extent``
as time samples at time codes ``start_frame, start_frame + 1, ...``. The stage says how to read them: ``upAxis``
(``Y`` as computed, or ``Z`` for ``--up z``), ``metersPerUnit`` (1, or the unit ``--output-units`` names) and
``timeCodesPerSecond = framesPerSecond = fps``, with ``startTimeCode``/``endTimeCode`` spanning the frames.
``.usd`` and ``.usdc`` are written binary (crate), ``.usda`` as text.

A binary file (``.usd``, ``.usdc``) is streamed: written under a temporary name as the frames come, saved every
:data:`SAVE_BYTES` of points (USD's crate format appends what changed and lets the saved samples go from memory:
a writer holds about that much, however long the clip), and renamed when the writer closes.  A text file
(``.usda``) cannot be: its stage is built in memory -- about 12 bytes per vertex per frame, the whole clip -- and
exported under a temporary name when the writer closes, then renamed.  Either way a failed run leaves nothing.
"""

from __future__ import annotations

import contextlib
import os
import re
import signal
import sys
import threading
import unicodedata
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from ..errors import FileFormatError, InputError, check_readable, unreadable_error
from .atomic import WriteError, _tmp_sibling, write_error
from .mesh import validate_mesh_arrays
from .sequence import LazyFrames
from .surface import fan_triangles
from .writer import SequenceWriter, nominal_fps

__all__ = [
    "UsdFrames",
    "UsdSequenceWriter",
    "read_usd_mesh",
    "read_usd_sequence",
    "usd_available",
    "usd_prim_name",
    "usd_start_frame",
    "usd_meters_per_unit",
    "USD_EXTENSIONS",
]

USD_EXTENSIONS = (".usd", ".usda", ".usdc")

#: points (bytes, float32) a binary USD writer adds between saves of its file: what it holds of the clip at most
SAVE_BYTES = 8 << 20


def _modules():
    # USD's module set-up catches an exception raised while it runs and goes on (it printed "Error occurred
    # postprocessing module pxr.Trace._trace!"): Ctrl-C or SIGTERM (which the CLI turns into KeyboardInterrupt) in
    # that half second was lost, and the run wrote its output (a session's trial).  During the import the two
    # signals are only noted, then raised again once it is done, for the handlers there were (the main thread only:
    # no other may set handlers, and the interpreter runs them there).
    held: list[int] = []
    previous = {}
    if "pxr" not in sys.modules and threading.current_thread() is threading.main_thread():
        for sig in (signal.SIGINT, getattr(signal, "SIGTERM", None)):
            if sig is not None and signal.getsignal(sig) is not None:  # (None: a handler not set from Python)
                previous[sig] = signal.signal(sig, lambda signum, frame: held.append(signum))
    try:
        from pxr import Sdf, Tf, Usd, UsdGeom, Vt
    except ImportError:
        raise InputError("USD output needs the 'usd' extra: pip install 'segadeform[usd]'") from None
    finally:
        for sig, handler in previous.items():
            signal.signal(sig, handler)
        if held:
            signal.raise_signal(held[0])
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
        unit: metres per written unit (the stage's ``metersPerUnit``: 0.01 writes centimetres).
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
        unit: float = 1.0,
    ) -> None:
        super().__init__(path, num_points, up=up, unit=unit)
        ext = self.path.suffix.lower()
        if ext not in USD_EXTENSIONS:
            raise InputError("not a USD file name", path=self.path, expected=" | ".join(USD_EXTENSIONS), got=ext)
        Usd, UsdGeom, Sdf, self._Vt, _ = _modules()
        _, self.faces = validate_mesh_arrays(np.zeros((num_points, 3)), faces)
        if not (np.isfinite(fps) and fps > 0):
            raise InputError("fps must be positive", got=fps)
        if surface is not None and surface.n_vertices_used > num_points:
            raise InputError("the surface indexes more vertices than the frames have", path=self.path)
        self._Usd = Usd
        self.fps, self.start = nominal_fps(fps), float(start_frame)  # 120, not a BVH's 120.000048
        self._hold = _tmp_sibling(self.path, directory=False)  # reserves the name; USD needs the extension
        self._tmp = self._hold.with_name(self._hold.name + ext)
        self._layer: Any = None  # a binary file's layer, streamed to self._tmp (a text one is exported when closed)
        self._unsaved = 0
        try:
            if ext == ".usda":
                self._stage = Usd.Stage.CreateInMemory()
            else:
                self._layer = Sdf.Layer.CreateNew(str(self._tmp), args={"format": "usdc"})
                if self._layer is None:
                    raise WriteError(self.path, "USD could not create the file; nothing was left behind")
                self._stage = Usd.Stage.Open(self._layer)
            self._define(UsdGeom, Sdf, up, surface)
        except WriteError:
            self._discard()
            raise
        except Exception as e:  # pxr's Tf.ErrorException
            self._discard()
            raise WriteError(
                self.path, f"USD could not create the file ({_first_line(e)}); nothing was left behind"
            ) from None

    def _define(self, UsdGeom, Sdf, up: str, surface) -> None:
        """The stage's values and the mesh: everything but the frames."""
        UsdGeom.SetStageUpAxis(self._stage, UsdGeom.Tokens.z if up == "z" else UsdGeom.Tokens.y)
        UsdGeom.SetStageMetersPerUnit(self._stage, self.unit)
        self._stage.SetTimeCodesPerSecond(self.fps)
        self._stage.SetFramesPerSecond(self.fps)
        self._stage.SetStartTimeCode(self.start)
        mesh = UsdGeom.Mesh.Define(self._stage, Sdf.Path("/" + usd_prim_name(self.path.stem)))
        self._stage.SetDefaultPrim(mesh.GetPrim())
        if surface is None:
            counts, corners = np.full(len(self.faces), 3, np.int32), self.faces.astype(np.int32).ravel()
        else:  # the garment's own polygons (and texture coordinates: the `st` primvar, face-varying)
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
        if self._layer is not None:
            self._unsaved += frames.shape[0] * frames.shape[1] * 12
            if self._unsaved >= SAVE_BYTES:  # to the file; the samples saved leave memory
                self._save()

    def _save(self) -> None:
        """Save the binary layer to its file; an OSError when USD cannot (the writer names the target)."""
        try:
            ok = self._layer.Save()
        except Exception as e:  # pxr's Tf.ErrorException (disk full ...)
            raise OSError(f"USD could not save the file ({_first_line(e)})") from None
        if not ok:
            raise OSError("USD could not save the file")
        self._unsaved = 0

    def _commit(self) -> None:
        self._stage.SetEndTimeCode(self.start + max(self.num_samples - 1, 0))
        try:
            if self._layer is not None:
                self._save()
            else:
                try:
                    ok = self._stage.GetRootLayer().Export(str(self._tmp))
                except Exception as e:  # pxr's Tf.ErrorException
                    raise OSError(f"USD could not export the stage ({_first_line(e)})") from None
                if not ok:
                    raise OSError("USD could not export the stage")
            self._release()  # the file is closed before it is renamed
            os.replace(self._tmp, self.path)
        except OSError as e:
            raise write_error(e, self.path) from None
        finally:
            self._discard()

    def _release(self) -> None:
        self._stage = self._points = self._extent = self._layer = None

    def _discard(self) -> None:
        self._release()
        for p in (self._tmp, self._hold):
            with contextlib.suppress(FileNotFoundError):
                p.unlink()


def _first_line(e: Exception) -> str:
    """An exception's message on one line without pxr's internals (its reports run over several lines of them)."""
    from ..errors import _library_message

    return _library_message(e) if str(e).strip() else type(e).__name__


class UsdFrames(LazyFrames):
    """The time samples of a USD mesh's ``points`` ``(S, N, 3) float32`` (or its one default value), read when
    indexed (N: the first's).  ``times``: the time codes.  Without ``stage``, each read opens the stage and lets
    it go (a binary USD file is mapped into memory: a stage kept open over a long clip's reads holds all of it); a
    text one, parsed whole when opened, is read from the ``stage`` given."""

    def __init__(self, path: Path, prim: str, times: np.ndarray, n_points: int, *, default=None, stage=None) -> None:
        super().__init__(len(times), n_points, np.float32, path)
        self._file, self._prim, self._default, self.times = path, prim, default, times
        self._stage = stage

    def _read(self, indices: Sequence[int]) -> np.ndarray:
        out = np.empty((len(indices), *self.shape[1:]), np.float32)
        attr = None
        if self._default is None:
            Usd, UsdGeom, _, _, _ = _modules()
            stage = self._stage
            if stage is None:
                try:
                    stage = Usd.Stage.Open(str(self._file))
                except Exception as e:
                    raise unreadable_error(e, self._file, "USD") from None
            prim = None if stage is None else stage.GetPrimAtPath(self._prim)
            if prim is None or not prim.IsA(UsdGeom.Mesh):
                raise FileFormatError("USD mesh is gone from the file", path=self._file, expected=self._prim)
            attr = UsdGeom.Mesh(prim).GetPointsAttr()
        for j, i in enumerate(indices):
            pts = self._default if attr is None else attr.Get(float(self.times[i]))
            a = np.asarray(pts if pts is not None else [], np.float32)
            if a.shape != out.shape[1:]:
                raise FileFormatError(
                    f"USD points at time code {self.times[i]:g} are not the first's {self.shape[1]} 3-vectors",
                    path=self._file,
                    expected=out.shape[1:],
                    got=a.shape,
                )
            out[j] = a
        return out


def _is_crate(path: Path) -> bool:
    """Whether ``path`` is a binary (crate) USD file, by its magic."""
    try:
        with open(path, "rb") as fh:
            return fh.read(8) == b"PXR-USDC"
    except OSError:
        return False


def read_usd_sequence(path: str | os.PathLike) -> tuple[np.ndarray, np.ndarray, np.ndarray, dict]:
    """The first mesh of a USD file: faces ``(F, 3)``, frames ``(S, N, 3)`` (its points' time samples, or its
    one default value), time codes ``(S,)`` and the stage's ``{"up", "meters_per_unit", "fps", "start",
    "end", "prim"}``.  Non-finite points are returned as they are (``segadeform inspect`` reports them)."""
    counts, idx, frames, times, info = read_usd_mesh(path)
    return fan_triangles(counts, idx), frames, times, info


def usd_start_frame(path: str | os.PathLike) -> float:
    """The first time code of a USD mesh's points (0 for points without time samples); reads no frame."""
    return float(read_usd_mesh(path, lazy=True)[3][0])


def usd_meters_per_unit(path: str | os.PathLike) -> float:
    """The stage's ``metersPerUnit`` (what ``run --output-units`` wrote; 0.01 for centimetres); reads no frame."""
    return float(read_usd_mesh(path, lazy=True)[4]["meters_per_unit"])


def read_usd_mesh(
    path: str | os.PathLike, *, lazy: bool = False
) -> tuple[np.ndarray, np.ndarray, Any, np.ndarray, dict]:
    """:func:`read_usd_sequence` with the mesh's own polygons for its triangles: ``faceVertexCounts (F,)`` and
    ``faceVertexIndices (C,)``, then frames (float64), time codes and the stage's values.

    ``lazy``: frames are a :class:`UsdFrames` (float32, each time sample read when indexed) instead of an array;
    the face indices are then checked against the first sample's points."""
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
    default = None
    if times.size:
        first = attr.Get(float(times[0]))
    else:
        default = first = attr.Get()
        if first is None:
            raise FileFormatError("USD mesh has no points", path=p, got=str(mesh.GetPath()))
        times = np.zeros(1)
    shape = np.shape(np.asarray(first if first is not None else [], np.float32))
    if len(shape) != 2 or shape[1] != 3:
        raise FileFormatError("USD points are not 3-vectors", path=p, got=(len(times), *shape))
    if idx.size and (idx.min() < 0 or idx.max() >= shape[0]):
        raise FileFormatError(
            "USD face index out of range", path=p, expected=f"0..{shape[0] - 1}", got=f"{idx.min()}..{idx.max()}"
        )
    mapped = lazy and _is_crate(p)  # a binary file is mapped, not parsed: lazy frames open it again per read
    seq = UsdFrames(p, str(mesh.GetPath()), times, shape[0], default=default, stage=None if mapped else stage)
    frames = seq if lazy else seq.read_all(np.float64)
    info = {
        "up": str(UsdGeom.GetStageUpAxis(stage)),
        "meters_per_unit": float(UsdGeom.GetStageMetersPerUnit(stage)),
        "fps": float(stage.GetTimeCodesPerSecond()),
        "start": float(stage.GetStartTimeCode()),
        "end": float(stage.GetEndTimeCode()),
        "prim": str(mesh.GetPath()),
    }
    return counts, idx, frames, times, info
