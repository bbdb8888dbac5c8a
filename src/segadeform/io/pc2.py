"""PC2 point caches (3ds Max / Blender Mesh Cache).

Layout (little-endian)::

    header  <12siiffi   32 bytes: b"POINTCACHE2\\0", version=1, numPoints,
                        startFrame, sampleRate, numSamples
    data    numSamples x numPoints x 3 float32, frame-major

``numSamples`` sits at byte 28, so a writer can append frames and patch the
count at the end; a long run never holds more than one batch of frames.
``sampleRate`` is frames per sample (1.0 = one sample per frame).  Blender's
Mesh Cache modifier reads PC2 with its "frame start" / "frame scale" settings;
vertex order must match the mesh exactly.  Coordinates are written in the
package's convention (metres, +Y up) unless the caller converts them.
"""

from __future__ import annotations

import dataclasses
import os
import struct
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from ..errors import FileFormatError, InputError, file_error
from .atomic import _tmp_sibling
from .sequence import LazyFrames
from .writer import SequenceWriter

__all__ = [
    "PC2_HEADER",
    "PC2_MAGIC",
    "PC2Header",
    "PC2Frames",
    "PointCache",
    "PC2Writer",
    "read_pc2_header",
    "read_pc2",
    "write_pc2",
]

PC2_HEADER = struct.Struct("<12siiffi")
PC2_MAGIC = b"POINTCACHE2\0"
_FRAME_DTYPE = np.dtype("<f4")


@dataclasses.dataclass(frozen=True)
class PC2Header:
    num_points: int
    start_frame: float
    sample_rate: float
    num_samples: int
    version: int = 1


@dataclasses.dataclass(frozen=True, eq=False)
class PointCache:
    """A read PC2 file. ``frames`` is ``(S, N, 3) float32``, memory-mapped when read with mmap."""

    header: PC2Header
    frames: np.ndarray
    path: str | None = None

    def __len__(self) -> int:
        return self.header.num_samples


def read_pc2_header(path: str | os.PathLike) -> PC2Header:
    """Read and validate a PC2 header against the file's length."""
    p = Path(path)
    try:
        size = p.stat().st_size
        with open(p, "rb") as fh:
            raw = fh.read(PC2_HEADER.size)
    except OSError as e:
        raise file_error(e, p) from None
    if len(raw) < PC2_HEADER.size:
        raise FileFormatError("file too short for a PC2 header", path=p, expected="32 bytes", got=f"{len(raw)} bytes")
    magic, version, n_points, start, rate, n_samples = PC2_HEADER.unpack(raw)
    if magic != PC2_MAGIC:
        raise FileFormatError("not a PC2 file (bad magic)", path=p, expected=repr(PC2_MAGIC), got=repr(magic))
    if version != 1:
        raise FileFormatError("unsupported PC2 version", path=p, expected=1, got=version)
    if n_points <= 0:
        raise FileFormatError("PC2 numPoints must be positive", path=p, got=n_points)
    if n_samples < 0:
        raise FileFormatError("PC2 numSamples must not be negative", path=p, got=n_samples)
    if not np.isfinite(start):
        raise FileFormatError("PC2 startFrame is not finite", path=p, got=start)
    if not (np.isfinite(rate) and rate > 0):
        raise FileFormatError("PC2 sampleRate must be finite and positive", path=p, got=rate)
    expected = PC2_HEADER.size + n_samples * n_points * 12
    if size != expected:
        raise FileFormatError(
            f"PC2 size does not match its header ({n_samples} samples x {n_points} points)",
            path=p,
            expected=f"{expected} bytes",
            got=f"{size} bytes",
        )
    return PC2Header(
        num_points=n_points, start_frame=float(start), sample_rate=float(rate), num_samples=n_samples, version=version
    )


def read_pc2(
    path: str | os.PathLike, *, mmap: bool = True, check_finite: bool = False, num_points: int | None = None
) -> PointCache:
    """Read a PC2 file; frames are memory-mapped (no copy) unless ``mmap=False``.

    Args:
        num_points: if given, the file must have exactly this many points
            (e.g. the garment's vertex count).
        check_finite: scan the frames (in chunks) and reject NaN/inf.

    Returns:
        PointCache with ``frames (S, N, 3) float32``.
    """
    p = Path(path)
    h = read_pc2_header(p)
    if num_points is not None and h.num_points != num_points:
        raise FileFormatError("PC2 point count does not match the mesh", path=p, expected=num_points, got=h.num_points)
    shape = (h.num_samples, h.num_points, 3)
    if h.num_samples == 0:
        frames = np.zeros(shape, np.float32)
    elif mmap:
        frames = np.memmap(p, dtype=_FRAME_DTYPE, mode="r", offset=PC2_HEADER.size, shape=shape)
    else:
        frames = np.fromfile(p, dtype=_FRAME_DTYPE, offset=PC2_HEADER.size).reshape(shape)
    if check_finite:
        step = max(1, (1 << 22) // max(1, h.num_points * 3))
        for s in range(0, h.num_samples, step):
            block = np.asarray(frames[s : s + step])
            if not np.isfinite(block).all():
                bad = s + int(np.flatnonzero(~np.isfinite(block).reshape(len(block), -1).all(axis=1))[0])
                raise FileFormatError(f"PC2 sample {bad} has a non-finite coordinate", path=p)
    return PointCache(header=h, frames=frames, path=str(p))


class PC2Frames(LazyFrames):
    """The frames of a PC2 file ``(S, N, 3) float32``, read from the file when indexed (a seek to the frame, one
    read per run of consecutive frames): a summary or a preview of a long cache holds the frames it asks for and
    no more (a memory map of the whole file is resident once every page is read).  ``header``: the file's.

    Args:
        num_points: if given, the file must have exactly this many points.
    """

    def __init__(self, path: str | os.PathLike, *, num_points: int | None = None) -> None:
        p = Path(path)
        self.header = h = read_pc2_header(p)
        if num_points is not None and h.num_points != num_points:
            raise FileFormatError(
                "PC2 point count does not match the mesh", path=p, expected=num_points, got=h.num_points
            )
        super().__init__(h.num_samples, h.num_points, _FRAME_DTYPE, p)
        self._file = p

    def _read(self, indices: Sequence[int]) -> np.ndarray:
        n = self.shape[1]
        out = np.empty((len(indices), n, 3), _FRAME_DTYPE)
        frame_bytes = n * 3 * _FRAME_DTYPE.itemsize
        try:
            with open(self._file, "rb") as fh:
                j = 0
                while j < len(indices):
                    k = j + 1  # a run of consecutive frames is one read
                    while k < len(indices) and indices[k] == indices[k - 1] + 1:
                        k += 1
                    fh.seek(PC2_HEADER.size + indices[j] * frame_bytes)
                    got = fh.readinto(out[j:k].data.cast("B"))
                    if got != (k - j) * frame_bytes:
                        raise FileFormatError(
                            f"PC2 file ends inside frame {indices[j] + got // frame_bytes} (was it cut short?)",
                            path=self._file,
                            expected=f"{PC2_HEADER.size + self.shape[0] * frame_bytes} bytes",
                            got=f"{PC2_HEADER.size + indices[j] * frame_bytes + got} bytes",
                        )
                    j = k
        except OSError as e:
            raise file_error(e, self._file) from None
        return out


class PC2Writer(SequenceWriter):
    """Stream frames into a PC2 file; the file appears (atomically) on :meth:`close`.

    Frames go to a temporary file beside the target; ``close`` patches
    numSamples and renames.  Used as a context manager, an exception inside
    the block removes the temporary file and leaves no output.

    Example::

        with PC2Writer("out.pc2", num_points=n, start_frame=1, sample_rate=1) as w:
            for batch in batches:           # (B, N, 3) or (N, 3)
                w.write(batch)
    """

    needs_frames = False  # a PC2 with zero samples is a valid file

    def __init__(
        self,
        path: str | os.PathLike,
        num_points: int,
        *,
        start_frame: float = 0.0,
        sample_rate: float = 1.0,
        up: str = "y",
        unit: float = 1.0,
    ) -> None:
        super().__init__(path, num_points, up=up, unit=unit)
        if not np.isfinite(start_frame):
            raise InputError("start_frame must be finite", got=start_frame)
        if not (np.isfinite(sample_rate) and sample_rate > 0):
            raise InputError("sample_rate must be finite and positive", got=sample_rate)
        self.start_frame = float(start_frame)
        self.sample_rate = float(sample_rate)
        self._tmp = _tmp_sibling(self.path, directory=False)
        self._fh = open(self._tmp, "wb")
        self._fh.write(self._header())

    def _header(self) -> bytes:
        return PC2_HEADER.pack(PC2_MAGIC, 1, self.num_points, self.start_frame, self.sample_rate, self.num_samples)

    def _append(self, frames: np.ndarray) -> None:
        self._fh.write(np.ascontiguousarray(frames, dtype=_FRAME_DTYPE).tobytes())

    def write(self, frames: np.ndarray) -> None:
        """Append ``(N, 3)`` or ``(B, N, 3)`` frames (cast to float32 first, then they must be finite)."""
        a = np.asarray(frames)
        super().write(a.astype(_FRAME_DTYPE) if np.issubdtype(a.dtype, np.number) else a)

    def _commit(self) -> None:
        """Patch the header, flush, and move the file into place."""
        self._fh.seek(0)
        self._fh.write(self._header())
        self._fh.flush()
        os.fsync(self._fh.fileno())
        self._fh.close()
        os.replace(self._tmp, self.path)

    def _discard(self) -> None:
        self._fh.close()
        try:
            self._tmp.unlink()
        except FileNotFoundError:
            pass


def write_pc2(
    path: str | os.PathLike, frames: np.ndarray, *, start_frame: float = 0.0, sample_rate: float = 1.0
) -> Path:
    """Write all ``frames (S, N, 3)`` at once (S >= 1)."""
    a = np.asarray(frames)
    if a.ndim != 3 or a.shape[2] != 3 or a.shape[0] < 1:
        raise InputError("frames must be (S, N, 3) with S >= 1", path=path, got=a.shape)
    with PC2Writer(path, a.shape[1], start_frame=start_frame, sample_rate=sample_rate) as w:
        w.write(a)
    return Path(path)
