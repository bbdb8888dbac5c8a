"""glTF 2.0 files (``.glb``, ``.gltf``) through ``pygltflib`` (extra ``gltf``): the file and its accessors
(:class:`GltfFile`, which :mod:`segadeform.motion.gltf` reads motions with) and a garment mesh (:func:`read_gltf_mesh`).

A garment as an engine exports it (an engine integrator's trial: `run` took no ``.glb``):

* **what is read**: the triangles of every mesh the default scene's nodes hold (depth first, each node's primitives
  in order; triangle strips and fans made triangles; points and lines left out), their ``POSITION`` and indices.
  Vertices are the file's, in that order and count: an engine binds a point cache by vertex index, and exports split
  vertices at UV and normal seams (the run welds those for the model and writes every copy).
  Primitives of one node that share a ``POSITION`` accessor (a mesh of several materials) share its vertices.  With
  no scene, the nodes that are no node's child are the roots.  Compressed meshes (Draco, meshopt) are refused.
* **where**: an unskinned mesh at its node's world transform (a mirroring one's triangles wound back, as glTF's
  front faces turn clockwise there); a skinned one as its vertices are stored (glTF places a skinned mesh by its
  joints and ignores its node's transform; at the bind pose that is where they are).
* **units and axes**: glTF's, metres and +Y up, which are this package's.  Morph targets are not read.

Errors name the file: not glTF, no mesh with triangles, an index outside its vertices, accessors outside their
buffers.
"""

from __future__ import annotations

import os
import urllib.parse
from pathlib import Path

import numpy as np

from ..errors import FileFormatError, InputError, check_readable, unreadable_error
from .mesh import Mesh, validate_mesh_arrays

__all__ = ["GltfFile", "read_gltf_mesh"]

_DTYPES = {5120: np.int8, 5121: np.uint8, 5122: np.int16, 5123: np.uint16, 5125: np.uint32, 5126: np.float32}
_WIDTH = {"SCALAR": 1, "VEC2": 2, "VEC3": 3, "VEC4": 4, "MAT2": 4, "MAT3": 9, "MAT4": 16}
_TRIANGLES, _STRIP, _FAN = 4, 5, 6
#: mesh compression extensions (their accessors hold no plain data)
_COMPRESSED = {"KHR_draco_mesh_compression", "EXT_meshopt_compression"}


def _pygltflib():
    try:
        import pygltflib
    except ImportError:
        raise InputError("glTF files need the 'gltf' extra: pip install 'segadeform[gltf]'") from None
    return pygltflib


class GltfFile:
    """A loaded glTF and its buffers, with accessors read as float64 arrays."""

    def __init__(self, path: Path):
        self.path = path
        check_readable(path, "glTF")
        lib = _pygltflib()
        try:
            with open(path, "rb") as fh:
                magic = fh.read(4)
            g = lib.GLTF2().load_binary(str(path)) if magic == b"glTF" else lib.GLTF2().load_json(str(path))
        except Exception as e:
            raise unreadable_error(e, path, "glTF") from None
        if g is None:
            raise FileFormatError("not a readable glTF file", path=path)
        self.g = g
        self._buffers: dict[int, bytes] = {}

    def error(self, problem, **kw):
        return FileFormatError(problem, path=self.path, **kw)

    def buffer(self, i: int) -> bytes:
        if i not in self._buffers:
            if not 0 <= i < len(self.g.buffers):
                raise self.error(
                    "bufferView names a buffer that is not there", expected=f"0..{len(self.g.buffers) - 1}", got=i
                )
            uri = self.g.buffers[i].uri
            if uri is None:  # the GLB's own binary chunk
                data = self.g.binary_blob()
            elif uri.startswith("data:"):
                try:
                    data = self.g.decode_data_uri(uri)
                except Exception as e:
                    raise self.error(f"buffer {i} has a data URI that does not decode ({type(e).__name__})") from None
            else:
                data = self._external(i, uri)
            if data is None:
                raise self.error(f"buffer {i} has no data")
            self._buffers[i] = bytes(data)
        return self._buffers[i]

    def _external(self, i: int, uri: str) -> bytes:
        """Buffer ``i``'s bytes from its file ``uri`` (relative to the glTF's folder, as the format says): a regular
        file, read no further than the buffer's ``byteLength`` (a fuzzer's buffer at /dev/zero was read until the
        kernel killed the process, with no word)."""
        import stat

        rel = urllib.parse.unquote(uri)
        parts = rel.replace("\\", "/").split("/")
        if Path(rel).is_absolute() or rel.startswith(("/", "\\")) or ".." in parts or ":" in parts[0]:
            # a file beside the glTF or below its folder, as the format's relative URIs are: an absolute or ../ URI
            # read any file and copied it into the output (a security review)
            raise self.error(
                f"buffer {i}'s file is outside the glTF's folder",
                expected="a relative path beside the glTF (no .., no absolute path)",
                got=uri,
            )
        f = self.path.parent / rel
        n = self.g.buffers[i].byteLength
        # byteLength is required; a file without it (or with none above 0) is read whole, as before (a review)
        want = int(n) if isinstance(n, int) and not isinstance(n, bool) and n > 0 else None
        try:
            st = f.stat()
        except OSError:
            raise self.error(f"buffer {i}'s file is missing", expected="a readable file beside it", got=uri) from None
        if not stat.S_ISREG(st.st_mode):
            raise self.error(f"buffer {i}'s file is not a regular file", expected="a .bin file beside it", got=uri)
        if want is not None and st.st_size < want:
            raise self.error(
                f"buffer {i}'s file is shorter than the glTF says",
                expected=f"{want} bytes",
                got=f"{st.st_size} ({uri})",
            )
        try:
            with open(f, "rb") as fh:
                return fh.read() if want is None else fh.read(want)
        except OSError:
            raise self.error(
                f"buffer {i}'s file cannot be read", expected="a readable file beside it", got=uri
            ) from None

    def accessor(self, i, what: str) -> np.ndarray:
        """Accessor ``i`` as a float64 ``(count, width)`` array (normalised integers scaled to [-1, 1] / [0, 1])."""
        acc = self.g.accessors
        if i is None or not 0 <= i < len(acc):
            raise self.error(f"{what} names an accessor that is not there", expected=f"0..{len(acc) - 1}", got=i)
        a = acc[i]
        if getattr(a, "sparse", None) is not None:
            raise self.error(f"{what}: sparse accessors are not read", expected="a plain accessor", got="sparse")
        if a.componentType not in _DTYPES or a.type not in _WIDTH:
            raise self.error(f"{what}: unknown accessor layout", got=f"{a.componentType} {a.type}")
        dt, width, count = np.dtype(_DTYPES[a.componentType]).newbyteorder("<"), _WIDTH[a.type], int(a.count)
        if a.bufferView is None:  # zeros, as the format says; a count no garment has is refused (a 276-byte file asked
            # for 30 million and took 6 GB: a security review)
            if not 0 <= count <= MAX_UNBACKED:
                raise self.error(
                    f"{what} has no bufferView and a count too large", expected=f"<= {MAX_UNBACKED}", got=count
                )
            return np.zeros((count, width))
        if not 0 <= a.bufferView < len(self.g.bufferViews):
            raise self.error(f"{what} names a bufferView that is not there", got=a.bufferView)
        bv = self.g.bufferViews[a.bufferView]
        data = self.buffer(bv.buffer)
        start = int(bv.byteOffset or 0) + int(a.byteOffset or 0)
        elem = dt.itemsize * width
        stride = int(bv.byteStride or elem)
        need = start + (count - 1) * stride + elem if count else start
        if need > int(bv.byteOffset or 0) + int(bv.byteLength) or need > len(data) or stride < elem:
            raise self.error(
                f"{what} reaches outside its buffer",
                expected=f"<= {min(len(data), bv.byteLength)} bytes",
                got=f"{need} bytes",
            )
        raw = np.ndarray((count, width), dtype=dt, buffer=data, offset=start, strides=(stride, dt.itemsize))
        out = raw.astype(np.float64)
        if a.normalized and dt.kind in "iu":
            out = np.maximum(out / float(np.iinfo(dt.name).max), -1.0)
        return out


#: an accessor without a bufferView (zeros) may have at most this many elements
MAX_UNBACKED = 2_000_000
#: nodes nested deeper than this are refused (a character's skeleton is a few tens deep; 5,000 nested nodes gave a
#: RecursionError traceback: a fuzzer's trial)
MAX_DEPTH = 256


def unit_quaternion(q, *, where: str = "", error=None) -> np.ndarray:
    """A node's rotation ``q (x, y, z, w)`` at unit length, scaled by its largest component first so that no square
    overflows or underflows (a fuzzer's [0, 1e300, 0, 1e300] and [0, 1e-300, 0, 1e-300] were read as no rotation);
    a zero or non-finite one is refused through ``error`` (a callable taking the problem and keywords, e.g.
    ``GltfFile.error``; default: a plain :class:`FileFormatError`), naming ``where``."""
    q = np.asarray(q, np.float64).reshape(4)
    big = float(np.abs(q).max()) if np.isfinite(q).all() else float("nan")
    if not (np.isfinite(big) and big > 0):
        make = error or (lambda problem, **kw: FileFormatError(problem, **kw))
        got = [float(x) for x in q]
        raise make(f"{where}rotation is not a rotation", expected="a non-zero finite quaternion", got=got)
    q = q / big
    return q / np.sqrt(float(q @ q))


def _node_matrix(node, f: GltfFile | None = None, k: int = -1) -> np.ndarray:
    """A node's local transform, 4x4 (its matrix, else T R S)."""
    if node.matrix is not None:
        return np.asarray(node.matrix, np.float64).reshape(4, 4).T  # glTF matrices are column-major
    t = np.asarray(node.translation if node.translation is not None else [0, 0, 0], np.float64)
    x, y, z, w = unit_quaternion(
        node.rotation if node.rotation is not None else [0, 0, 0, 1],
        where=f"node {k}'s " if k >= 0 else "",
        error=None if f is None else f.error,
    )
    R = np.array(
        [
            [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
            [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
            [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)],
        ]
    )
    s = np.asarray(node.scale if node.scale is not None else [1, 1, 1], np.float64)
    M = np.eye(4)
    M[:3, :3] = R * s[None, :]
    M[:3, 3] = t
    return M


def _triangles(f: GltfFile, prim, n: int, what: str) -> np.ndarray | None:
    """A primitive's triangles (T, 3) in its own vertex numbers; None for points and lines."""
    mode = _TRIANGLES if prim.mode is None else int(prim.mode)
    if mode not in (_TRIANGLES, _STRIP, _FAN):
        return None
    idx = (
        np.arange(n, dtype=np.int64)
        if prim.indices is None
        else f.accessor(prim.indices, f"{what} indices")[:, 0].astype(np.int64)
    )
    if len(idx) and (idx.min() < 0 or idx.max() >= n):
        raise f.error(f"{what} has an index outside its vertices", expected=f"0..{n - 1}", got=int(idx.max()))
    if mode == _TRIANGLES:
        return idx[: len(idx) - len(idx) % 3].reshape(-1, 3)
    k = np.arange(max(len(idx) - 2, 0))
    if mode == _STRIP:  # every other triangle turned, so that all wind alike
        tri = np.stack([idx[k], idx[k + 1], idx[k + 2]], axis=1)
        tri[1::2] = tri[1::2][:, [1, 0, 2]]
        return tri
    return np.stack([np.full(len(k), idx[0] if len(idx) else 0), idx[k + 1], idx[k + 2]], axis=1)


def read_gltf_mesh(path: str | os.PathLike) -> Mesh:
    """The garment mesh of a ``.glb``/``.gltf`` file (the module's docstring says what is read, where and in what
    order).  Shapes: -> Mesh with vertices (N, 3), faces (F, 3)"""
    p = Path(path)
    f = GltfFile(p)
    g = f.g
    packed = sorted(set(g.extensionsRequired or []) & _COMPRESSED)
    if packed:  # its accessors hold no plain data (read as zeros before: a review)
        raise FileFormatError(
            f"the glTF file's meshes are compressed ({', '.join(packed)}), which is not read",
            path=p,
            expected="a glTF exported without mesh compression",
        )
    scene = g.scene if g.scene is not None else 0
    if g.scenes and 0 <= scene < len(g.scenes):
        roots = list(g.scenes[scene].nodes or [])
    else:  # no scene (valid glTF): the nodes that are no node's child
        children = {int(c) for n in g.nodes for c in (n.children or [])}
        roots = [k for k in range(len(g.nodes)) if k not in children]
    verts: list[np.ndarray] = []
    faces: list[np.ndarray] = []
    count = 0
    seen: set[int] = set()

    def walk(k: int, parent: np.ndarray, depth: int = 0) -> None:
        nonlocal count
        if not 0 <= k < len(g.nodes) or k in seen:  # (a node twice in the tree would loop)
            raise f.error("the node tree names a node that is not there, or one twice", got=k)
        if depth >= MAX_DEPTH:  # (root: depth 0, level 1)
            raise f.error("nodes nest too deeply", expected=f"at most {MAX_DEPTH} levels", got=f"more, at node {k}")
        seen.add(k)
        node = g.nodes[k]
        world = parent @ _node_matrix(node, f, k)
        if node.mesh is not None:
            if not 0 <= node.mesh < len(g.meshes):
                raise f.error(f"node {k} names a mesh that is not there", got=node.mesh)
            # a mirroring transform turns the front faces clockwise (glTF 2.0, 3.7.4): wound back (a review)
            mirrored = node.skin is None and float(np.linalg.det(world[:3, :3])) < 0
            blocks: dict[int, int] = {}  # POSITION accessor -> its first vertex here: primitives share vertices
            for j, prim in enumerate(g.meshes[node.mesh].primitives):
                what = f"mesh {node.mesh} primitive {j}"
                if _COMPRESSED & set((prim.extensions or {}).keys()):
                    raise f.error(f"{what} is compressed, which is not read", expected="uncompressed meshes")
                pos_i = getattr(prim.attributes, "POSITION", None)
                if pos_i is None:
                    continue
                v = f.accessor(pos_i, f"{what} POSITION")
                if v.shape[1] != 3:
                    raise f.error(f"{what} POSITION is not 3D", got=v.shape[1])
                tri = _triangles(f, prim, len(v), what)
                if tri is None:
                    continue
                if pos_i not in blocks:
                    if node.skin is None:  # a skinned mesh is placed by its joints: its vertices as stored
                        v = v @ world[:3, :3].T + world[:3, 3]
                    blocks[pos_i] = count
                    verts.append(v)
                    count += len(v)
                faces.append((tri[:, ::-1] if mirrored else tri) + blocks[pos_i])
        for c in node.children or []:
            walk(int(c), world, depth + 1)

    for r in roots:
        walk(int(r), np.eye(4))
    if not faces or not sum(len(x) for x in faces):
        raise InputError("the glTF file has no mesh with triangles", path=p, expected="a garment mesh")
    vertices, tris = validate_mesh_arrays(np.concatenate(verts), np.concatenate(faces), path=p, bounded=True)
    return Mesh(vertices=vertices, faces=tris, path=str(p))
