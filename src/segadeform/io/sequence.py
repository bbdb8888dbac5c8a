"""Mesh sequences: a folder of per-frame OBJ files, and meshio's XDMF time series.

Both hold one topology (faces) and S frames of positions ``(S, N, 3)``.
:class:`LazyFrames` is the frames of a file read when indexed (a PC2's, an Alembic's, a USD's, an OBJ folder's:
:func:`open_sequence_frames`), so that a summary or a preview of a long clip holds a bounded part of it at a time.
Writers take frames in batches and publish their output atomically on
``close`` (a folder is built under a temporary name and renamed; an XDMF
file likewise).  Readers check that every frame has the same topology.

XDMF is written with meshio's inline ``XML`` data format: a single
self-contained file that ParaView opens.  The mesh holds the rest positions
and each time step a point field ``displacement`` (frame - rest), so
ParaView's "Warp By Vector" shows the animation.  meshio's ``Binary`` and
``HDF`` formats write their side files into the current working directory
rather than beside the XDMF file, and HDF needs h5py, so they are not used.
XDMF is text and meshio keeps the whole document in memory: use PC2 for long
sequences.
"""

from __future__ import annotations

import os
import re
import shutil
import warnings
from collections.abc import Iterator, Sequence
from pathlib import Path
from typing import Any, cast

import numpy as np

from ..errors import FileFormatError, InputError
from .atomic import _tmp_sibling, atomic_path, merge_directory
from .mesh import validate_mesh_arrays
from .obj import read_obj, write_obj_positions
from .writer import SequenceWriter, nominal_fps, to_output

__all__ = [
    "CHUNK_VALUES",
    "LazyFrames",
    "ArrayFrames",
    "ObjFrames",
    "frame_chunks",
    "open_sequence_frames",
    "ObjSequenceWriter",
    "XdmfSequenceWriter",
    "read_obj_sequence",
    "obj_sequence_files",
    "read_xdmf_sequence",
    "write_obj_sequence",
    "write_xdmf_sequence",
]

_NUM = re.compile(r"(\d+)(?!.*\d)", re.ASCII)

#: coordinates in one chunk of :func:`frame_chunks` (4 MB of float32, 8 MB as float64): a summary of a clip holds
#: about this much of it at a time, however long the clip
CHUNK_VALUES = 1 << 20


class LazyFrames:
    """The frames ``(S, N, 3)`` of a file, read when indexed, in the file's own dtype (float32 for PC2, Alembic and
    USD: not upcast): ``frames[i]`` is ``(N, 3)``, ``frames[a:b]`` and ``frames[[i, j, ...]]`` are ``(k, N, 3)``.
    Nothing of the frames is held between reads (a reader keeps the file's header, or a text USD's parsed stage);
    ``np.asarray(frames)`` reads the whole clip.

    Subclasses set ``shape`` and ``dtype`` and implement ``_read(indices) -> (k, N, 3)`` for valid, non-negative
    frame indices.
    """

    ndim = 3

    def __init__(self, n_frames: int, n_points: int, dtype, path: str | os.PathLike | None = None) -> None:
        self.shape = (int(n_frames), int(n_points), 3)
        self.dtype = np.dtype(dtype)
        self.path = None if path is None else Path(path)

    def __len__(self) -> int:
        return self.shape[0]

    def __repr__(self) -> str:
        return f"{type(self).__name__}({self.shape[0]} frames x {self.shape[1]} points, {self.dtype}, {self.path})"

    def _read(self, indices: Sequence[int]) -> np.ndarray:
        raise NotImplementedError

    def _index(self, i) -> int:
        n = self.shape[0]
        k = int(i)
        if not -n <= k < n:
            raise InputError("frame index out of range", path=self.path, expected=f"0..{n - 1}", got=k)
        return k % n

    def __getitem__(self, key) -> np.ndarray:
        if isinstance(key, slice):
            idx: Sequence[int] = range(*key.indices(self.shape[0]))
        elif isinstance(key, (int, np.integer)):
            return self[[self._index(key)]][0]
        else:
            a = np.asarray(key)
            if a.ndim != 1 or not (a.size == 0 or np.issubdtype(a.dtype, np.integer)):
                raise InputError(
                    "frames are indexed by a frame, a slice or a list of frames",
                    expected="an int, a slice or a 1-D sequence of ints",
                    got=repr(key),
                )
            idx = [self._index(i) for i in a.tolist()]
        if len(idx) == 0:
            return np.empty((0, *self.shape[1:]), self.dtype)
        out = np.asarray(self._read(idx))
        if out.shape != (len(idx), *self.shape[1:]):
            raise FileFormatError(
                "frame has another number of points than the first",
                path=self.path,
                expected=(len(idx), *self.shape[1:]),
                got=out.shape,
            )
        return out

    def read_all(self, dtype=None) -> np.ndarray:
        """The whole clip ``(S, N, 3)`` in ``dtype`` (default: the file's), filled chunk by chunk (one copy)."""
        out = np.empty(self.shape, self.dtype if dtype is None else dtype)
        for s, block in frame_chunks(self):
            out[s : s + len(block)] = block
        return out

    def __array__(self, dtype=None, copy=None) -> np.ndarray:
        return self.read_all(dtype)


class ArrayFrames(LazyFrames):
    """Frames already in memory ``(S, N, 3)`` (a format read whole, e.g. XDMF), indexed as :class:`LazyFrames`."""

    def __init__(self, frames, path: str | os.PathLike | None = None) -> None:
        a = np.asarray(frames)
        if a.ndim != 3 or a.shape[2] != 3:
            raise FileFormatError("frames are not (S, N, 3)", path=path, expected="(S, N, 3)", got=a.shape)
        super().__init__(a.shape[0], a.shape[1], a.dtype, path)
        self._frames = a

    def _read(self, indices: Sequence[int]) -> np.ndarray:
        return self._frames[list(indices)]


def frame_chunks(frames: Any, max_values: int = CHUNK_VALUES) -> Iterator[tuple[int, np.ndarray]]:
    """``(first frame, block (k, N, 3))`` over ``frames`` (an array or :class:`LazyFrames`), each block at most
    ``max_values`` coordinates (at least one frame): the clip read a bounded part at a time."""
    n, per = len(frames), 3 * int(frames.shape[1])
    step = max(1, int(max_values) // max(per, 1))
    for s in range(0, n, step):
        yield s, np.asarray(frames[s : min(n, s + step)])


def _surface_obj_text(surface, num_points: int) -> str:
    """The ``vt`` and ``f`` lines of a :class:`~segadeform.io.surface.Surface` (written after each frame's ``v``)."""
    if surface.n_vertices_used > num_points:
        raise InputError(
            "the surface indexes more vertices than the frames have", expected=num_points, got=surface.n_vertices_used
        )
    lines = []
    if surface.uvs is not None:
        lines += [f"vt {u:.9g} {v:.9g}" for u, v in surface.uvs]
    idx = np.asarray(surface.indices) + 1
    uv = None if surface.uv_indices is None else np.asarray(surface.uv_indices) + 1
    at = 0
    for c in np.asarray(surface.counts):
        ids = idx[at : at + c]
        corners = ids if uv is None else [f"{a}/{b}" for a, b in zip(ids, uv[at : at + c], strict=True)]
        lines.append("f " + " ".join(str(x) for x in corners))
        at += c
    return "\n".join(lines) + "\n"


class ObjSequenceWriter(SequenceWriter):
    """Write frames as ``DIR/{prefix}_{i:05d}.obj``; the folder appears on close."""

    needs_frames = False

    def __init__(
        self,
        directory: str | os.PathLike,
        faces: np.ndarray,
        num_points: int,
        *,
        prefix: str = "frame",
        start: int = 0,
        precision: int = 9,
        up: str = "y",
        surface=None,
        unit: float = 1.0,
    ) -> None:
        super().__init__(directory, num_points, up=up, unit=unit)
        _, self.faces = validate_mesh_arrays(np.zeros((num_points, 3)), faces)
        self._surface_text = None if surface is None else _surface_obj_text(surface, num_points)
        if self.path.exists() and not self.path.is_dir():
            raise InputError("output for an OBJ sequence must be a folder", path=self.path)
        self.prefix, self.index, self.precision = prefix, int(start), precision
        self._tmp = _tmp_sibling(self.path, directory=True)

    def _append(self, frames: np.ndarray) -> None:
        for frame in frames:
            out = self._tmp / f"{self.prefix}_{self.index:05d}.obj"
            if self._surface_text is None:
                write_obj_positions(out, self.faces, frame, precision=self.precision)
            else:  # the garment's own polygons and texture coordinates
                v = "".join(
                    f"v {x:.{self.precision}g} {y:.{self.precision}g} {z:.{self.precision}g}\n" for x, y, z in frame
                )
                out.write_text(v + self._surface_text, encoding="utf-8", newline="\n")
            self.index += 1

    def _commit(self) -> None:
        # a new folder appears whole; into an existing one the frames go file by file, nothing else touched
        # (which frames may be replaced is segadeform.io.output_guard's rule)
        merge_directory(self._tmp, self.path)

    def _discard(self) -> None:
        shutil.rmtree(self._tmp, ignore_errors=True)


def write_obj_sequence(directory, faces, frames, **kw) -> Path:
    """Write ``frames (S, N, 3)`` as a folder of OBJ files."""
    a = np.asarray(frames)
    if a.ndim != 3:
        raise InputError("frames must be (S, N, 3)", got=a.shape)
    with ObjSequenceWriter(directory, faces, a.shape[1], **kw) as w:
        w.write(a)
    return Path(directory)


def obj_sequence_files(directory: str | os.PathLike) -> list[tuple[int, Path]]:
    """The frames of a folder of OBJ frames, ``(frame number, file)`` in frame order (the number in each name)."""
    d = Path(directory)
    if not d.is_dir():
        raise FileFormatError("not a folder of OBJ frames", path=d)
    files = [f for f in d.iterdir() if f.suffix.lower() == ".obj"]
    if not files:
        raise FileFormatError("folder has no .obj frames", path=d)
    keyed = []
    for f in files:
        m = _NUM.search(f.stem)
        if m is None:
            raise FileFormatError("frame file name has no frame number", path=f)
        keyed.append((int(m.group(1)), f))
    keyed.sort()
    nums = [k for k, _ in keyed]
    if len(set(nums)) != len(nums):
        dup = next(k for k in nums if nums.count(k) > 1)
        raise FileFormatError(f"two frame files have the number {dup}", path=d)
    return keyed


def read_obj_sequence(directory: str | os.PathLike) -> tuple[np.ndarray, np.ndarray]:
    """Read a folder of per-frame OBJ files, ordered by the last number in each name.

    Returns:
        faces ``(F, 3) int64`` and frames ``(S, N, 3) float64``.
    """
    seq = ObjFrames(directory)
    return seq.faces, seq.read_all()


class ObjFrames(LazyFrames):
    """The frames of a folder of OBJ files (:func:`obj_sequence_files`), each file read when its frame is, its
    topology checked against the first's; ``faces`` the first's, frames float64."""

    def __init__(self, directory: str | os.PathLike) -> None:
        self._files = [f for _, f in obj_sequence_files(directory)]
        self._first = read_obj(self._files[0], bounded=False)  # an output: checked in its units by its reader
        self.faces = self._first.faces
        super().__init__(len(self._files), self._first.n_vertices, np.float64, directory)

    def _read(self, indices: Sequence[int]) -> np.ndarray:
        first = self._first
        out = np.empty((len(indices), *self.shape[1:]))
        for j, i in enumerate(indices):
            mesh = first if i == 0 else read_obj(self._files[i], bounded=False)
            if mesh.n_vertices != first.n_vertices or not np.array_equal(mesh.faces, first.faces):
                raise FileFormatError(
                    "frame topology differs from the first frame",
                    path=self._files[i],
                    expected=f"{first.n_vertices} vertices, {first.n_faces} faces as in {self._files[0].name}",
                    got=f"{mesh.n_vertices} vertices, {mesh.n_faces} faces",
                )
            out[j] = mesh.vertices
        return out


def open_sequence_frames(path: str | os.PathLike, *, faces: np.ndarray | None = None) -> LazyFrames:
    """The frames of a sequence of any registered format, read when indexed (:class:`LazyFrames`): a PC2's from
    the file, frame by frame; an Alembic's or a USD's time samples, one at a time; an OBJ folder's files, one at a
    time.  Any other format (XDMF, one registered elsewhere) is read whole
    (:func:`~segadeform.io.formats.read_sequence`).  Values are as the file holds them, non-finite ones included."""
    from .formats import read_sequence, sequence_format_of

    p = Path(path)
    f = sequence_format_of(p)
    name = None if f is None else f.name
    if name == "pc2":
        from .pc2 import PC2Frames

        return PC2Frames(p)
    if name == "abc":
        from .alembic import read_alembic_sequence

        return cast(LazyFrames, read_alembic_sequence(p, lazy=True)[1])
    if name == "usd":
        from .usd import read_usd_mesh

        return cast(LazyFrames, read_usd_mesh(p, lazy=True)[2])
    if name == "obj-seq":
        return ObjFrames(p)
    return ArrayFrames(read_sequence(p, faces=faces), p)


class XdmfSequenceWriter(SequenceWriter):
    """Collect frames and write an XDMF time series on close (see module notes)."""

    def __init__(
        self,
        path: str | os.PathLike,
        faces: np.ndarray,
        num_points: int,
        *,
        rest: np.ndarray | None = None,
        fps: float = 30.0,
        start: int = 0,
        up: str = "y",
        unit: float = 1.0,
    ) -> None:
        super().__init__(path, num_points, up=up, unit=unit)
        _, self.faces = validate_mesh_arrays(np.zeros((num_points, 3)), faces)
        self.rest = None if rest is None else to_output(self.check(rest)[0].astype(np.float64), up, self.unit)
        if not (np.isfinite(fps) and fps > 0):
            raise InputError("fps must be positive", got=fps)
        self.fps, self.start = nominal_fps(fps), int(start)
        self._frames: list[np.ndarray] = []

    def _append(self, frames: np.ndarray) -> None:
        if self.rest is None:
            self.rest = frames[0].astype(np.float64)
        self._frames.extend(np.asarray(f, np.float32) for f in frames)

    def _commit(self) -> None:
        import meshio

        with atomic_path(self.path) as tmp:
            # meshio derives nothing from the name in XML mode; the suffix matters to readers only.
            with meshio.xdmf.TimeSeriesWriter(tmp, data_format="XML") as w:
                w.write_points_cells(self.rest, [("triangle", self.faces)])
                for i, fr in enumerate(self._frames):
                    disp = (fr.astype(np.float64) - cast(np.ndarray, self.rest)).astype(np.float32)
                    w.write_data((self.start + i) / self.fps, point_data={"displacement": disp})
            _add_rate(tmp, self.fps)
        self._frames.clear()

    def _discard(self) -> None:
        self._frames.clear()


#: the name of the ``<Information>`` element (a child of ``<Domain>``, which readers skip) that keeps the frame rate:
#: the times alone give it only from two steps on
XDMF_RATE = "segadeform.fps"


def _add_rate(path, fps: float) -> None:
    """Write ``fps`` into the XDMF file at ``path`` as an ``<Information>`` element of its ``<Domain>``."""
    import xml.etree.ElementTree as ET

    tree = ET.parse(path)
    domain = tree.getroot().find("Domain")
    if domain is not None:
        domain.insert(0, ET.Element("Information", Name=XDMF_RATE, Value=repr(float(fps))))
        tree.write(path)


def xdmf_start_frame(path: str | os.PathLike) -> float:
    """The frame number of an XDMF time series' first step: its time times the rate the writer recorded
    (:data:`XDMF_RATE`); for a file without it, over the step between its first two times (30 fps for a single
    step).  Reads the XML's times alone, not the frames."""
    import xml.etree.ElementTree as ET

    p = Path(path)
    if not p.is_file():
        raise FileFormatError("no such file", path=p)
    try:
        root = ET.parse(p).getroot()
    except ET.ParseError as e:
        raise FileFormatError(f"cannot parse XDMF time series: {e}", path=p) from None
    times = [float(t.get("Value", "nan")) for t in root.iter("Time")]
    if not times or not np.isfinite(times[0]):
        raise FileFormatError("XDMF file has no time steps", path=p)
    rate = next((i.get("Value") for i in root.iter("Information") if i.get("Name") == XDMF_RATE), None)
    try:
        fps = float(rate) if rate is not None else None
    except ValueError:
        fps = None
    if fps is None or not (np.isfinite(fps) and fps > 0):
        fps = 1.0 / (times[1] - times[0]) if len(times) > 1 and times[1] > times[0] else 30.0
    return times[0] * fps


def write_xdmf_sequence(path, faces, frames, *, rest=None, fps: float = 30.0) -> Path:
    a = np.asarray(frames)
    if a.ndim != 3:
        raise InputError("frames must be (S, N, 3)", got=a.shape)
    with XdmfSequenceWriter(path, faces, a.shape[1], rest=rest, fps=fps) as w:
        w.write(a)
    return Path(path)


def read_xdmf_sequence(path: str | os.PathLike) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Read an XDMF time series of a triangle mesh.

    Positions are the mesh points plus the point field ``displacement`` (or
    ``position`` when present) of each step.

    Returns:
        faces ``(F, 3)``, frames ``(S, N, 3) float64``, times ``(S,)``.
    """
    import meshio

    p = Path(path)
    if not p.is_file():
        raise FileFormatError("no such file", path=p)
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            with meshio.xdmf.TimeSeriesReader(p) as r:
                points, cells = r.read_points_cells()
                tri = [c.data for c in cells if c.type == "triangle"]
                if len(tri) != len(cells) or not tri:
                    raise FileFormatError("XDMF mesh must be made of triangles only", path=p)
                faces = np.concatenate(tri).astype(np.int64)
                frames, times = [], []
                for k in range(r.num_steps):
                    t, pd, _ = r.read_data(k)
                    if "position" in pd:
                        fr = np.asarray(pd["position"], np.float64)
                    elif "displacement" in pd:
                        fr = np.asarray(points, np.float64)[:, :3] + np.asarray(pd["displacement"], np.float64)
                    else:
                        raise FileFormatError(f"time step {k} has no 'displacement' or 'position' field", path=p)
                    frames.append(fr)
                    times.append(float(t))
    except InputError:
        raise
    except Exception as e:
        msg = str(e).strip().splitlines()[0] if str(e).strip() else type(e).__name__
        raise FileFormatError(f"cannot parse XDMF time series: {msg}", path=p) from None
    if not frames:
        raise FileFormatError("XDMF file has no time steps", path=p)
    v, faces = validate_mesh_arrays(np.asarray(points)[:, :3], faces, path=p)
    out = np.stack(frames)
    if out.shape[1:] != v.shape or not np.isfinite(out).all():
        raise FileFormatError("XDMF frames are not finite (N, 3) arrays", path=p, got=out.shape)
    return faces, out, np.asarray(times)
