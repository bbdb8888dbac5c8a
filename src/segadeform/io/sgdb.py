"""Scene bundles: everything a runtime in another language needs to animate one garment on one body
shape with one motion, in one little-endian binary file with a text header (``.sgdb``).

A bundle holds the model inputs that depend on the garment, the body shape and the motion -- what
``precompute``, the body model and the motion readers make in Python -- so a runtime that has only
onnxruntime (Node, a browser, C++, a game engine) runs the model package's graphs on it without
reimplementing them; ``docs/package.md`` says what each graph does with each array.  With
``expected`` it also carries the Python runtime's output, the shared test vector every runtime is
checked against.

File layout::

    SEGADEFORM-BUNDLE 1\\n
    <array count>\\n
    <name> <dtype> <ndim> <d0> ... <d(ndim-1)> <offset> <nbytes>\\n     (one line per array)
    meta <one line of JSON>\\n
    END\\n
    zero padding to a multiple of 64 bytes, then the arrays (offsets from here, each 64-byte aligned)

``dtype`` is one of ``f32 f64 i32 i64 u8``; arrays are C-order, little-endian.

Arrays (N garment vertices, K neighbour slots, S joints, T frames, F faces):

=============  ============  ===================================================================
features       f32 (N, 6+S)  encoder input: position, unit normal, distance to each rest joint
nbr            i32 (N, K)    padded neighbour indices (a vertex's own index in unused slots)
mask           u8 (N, K)     1 where ``nbr`` is a real neighbour
descriptor     f32 (N*,)     garment type descriptor
betas          f32 (B,)      body shape (the model's |beta|, zero-padded)
rest           f32 (N, 3)    garment rest positions (metres, +Y up)
faces          i32 (F, 3)    garment triangles (for writing meshes)
joints         f32 (S, 3)    the body's rest joints for ``betas``
log_wbody      f32 (N, S)    log(body weights at the garment + 1e-5) (residual-weights models)
poses          f32 (T, 3S)   axis-angle per joint per frame (the motion, retargeted to the body)
trans          f32 (T, 3)    root translation per frame
expected       f32 (T, N, 3) optional: the Python runtime's output for ``meta.effects``
=============  ============  ===================================================================

``meta``: ``fps``, ``window`` (the motion window T of the graph for ``effects``), ``effects``,
``graph`` (the deformer variant's name), ``model`` (the package's config hash), source names.

The same container holds the other portable files: the garment asset (``.sgda``,
:mod:`segadeform.io.garment_asset`) and the motion file (``.sgdm``, :mod:`segadeform.io.sgdm`).
"""

from __future__ import annotations

import json
import os
from pathlib import Path

import numpy as np

from ..errors import FileFormatError, InputError, file_error
from .atomic import atomic_open

__all__ = ["BUNDLE_MAGIC", "BUNDLE_SUFFIX", "write_bundle", "read_bundle", "DTYPES"]

BUNDLE_MAGIC = b"SEGADEFORM-BUNDLE 1\n"
BUNDLE_SUFFIX = ".sgdb"
#: the container's dtype names
DTYPES: dict[str, np.dtype] = {
    "f32": np.dtype("<f4"),
    "f64": np.dtype("<f8"),
    "i32": np.dtype("<i4"),
    "i64": np.dtype("<i8"),
    "u8": np.dtype("u1"),
}
_NAMES = {v: k for k, v in DTYPES.items()}
_ALIGN = 64


def write_bundle(path: str | os.PathLike, arrays: dict, meta: dict | None = None) -> Path:
    """Write ``arrays`` (name -> array of a supported dtype) and ``meta`` (JSON-able) atomically."""
    p = Path(path)
    entries, blobs, off = [], [], 0
    for name, a in arrays.items():
        a = np.asarray(a)
        a = np.ascontiguousarray(a) if a.ndim else a  # (ascontiguousarray would make a scalar 1-d)
        if a.dtype == np.bool_:
            a = a.astype(np.uint8)
        dt = a.dtype.newbyteorder("<") if a.dtype.byteorder == ">" else a.dtype
        key = _NAMES.get(np.dtype(dt))
        if key is None or not name.isidentifier():
            raise InputError(
                f"bundle array {name!r} has an unsupported dtype or name", expected="f32 f64 i32 i64 u8", got=a.dtype
            )
        a = a.astype(DTYPES[key], copy=False)
        entries.append(f"{name} {key} {a.ndim} {' '.join(map(str, a.shape))}{' ' if a.ndim else ''}{off} {a.nbytes}")
        blobs.append((off, a.tobytes()))
        off += -(-a.nbytes // _ALIGN) * _ALIGN
    header = (
        BUNDLE_MAGIC
        + f"{len(entries)}\n".encode()
        + "".join(e + "\n" for e in entries).encode()
        + b"meta "
        + json.dumps(meta or {}, sort_keys=True).encode()
        + b"\nEND\n"
    )
    header += b"\0" * (-len(header) % _ALIGN)
    with atomic_open(p, "wb") as fh:
        fh.write(header)
        pos = 0
        for o, b in blobs:
            fh.write(b"\0" * (o - pos))
            fh.write(b)
            pos = o + len(b)
        fh.write(b"\0" * (off - pos))
    return p


def read_bundle(path: str | os.PathLike) -> tuple[dict, dict]:
    """``(arrays, meta)`` of a bundle, every entry checked against the file's size."""
    p = Path(path)
    try:
        data = p.read_bytes()
    except OSError as e:
        raise file_error(e, p) from None
    if not data.startswith(BUNDLE_MAGIC):
        raise FileFormatError(
            "not a segadeform bundle", path=p, expected=BUNDLE_MAGIC.decode().strip(), got=repr(data[:20])
        )
    end = data.find(b"\nEND\n")
    if end < 0:
        raise FileFormatError("bundle header has no END line", path=p)
    lines = data[len(BUNDLE_MAGIC) : end].decode("utf-8", "replace").split("\n")
    start = -(-(end + 5) // _ALIGN) * _ALIGN
    try:
        n = int(lines[0])
        if not 0 <= n <= 1000 or len(lines) != n + 2 or not lines[n + 1].startswith("meta "):
            raise ValueError
        meta = json.loads(lines[n + 1][5:])
    except (ValueError, IndexError, RecursionError):
        raise FileFormatError("malformed bundle header", path=p) from None
    if not isinstance(meta, dict):
        raise FileFormatError(
            "bundle meta must be a JSON object", path=p, expected="meta {...}", got=f"a JSON {type(meta).__name__}"
        )
    arrays = {}
    for ln in lines[1 : n + 1]:
        t = ln.split()
        try:
            name, dt, nd = t[0], DTYPES[t[1]], int(t[2])
            shape = tuple(int(x) for x in t[3 : 3 + nd])
            off, nbytes = int(t[3 + nd]), int(t[4 + nd])
        except (KeyError, ValueError, IndexError):
            raise FileFormatError(f"malformed bundle entry {ln[:60]!r}", path=p) from None
        if min((*shape, off, nbytes, nd), default=0) < 0:  # (read as sizes that matched, or as "at least -4888")
            raise FileFormatError(
                f"bundle array {name!r} has a negative size or offset",
                path=p,
                expected="dimensions, offset and byte count >= 0",
                got=f"shape {shape}, offset {off}, {nbytes} bytes",
            )
        count = 1
        for d in shape:  # Python integers: a huge shape cannot wrap around to a small size
            count *= d
        if count * dt.itemsize != nbytes:
            raise FileFormatError(
                f"bundle array {name!r} declares a size its shape does not have",
                path=p,
                expected=f"{count * dt.itemsize} bytes for shape {shape}",
                got=f"{nbytes} bytes",
            )
        if off < 0 or start + off + nbytes > len(data):
            raise FileFormatError(
                f"bundle array {name!r} runs past the end of the file (truncated?)",
                path=p,
                expected=f"at least {start + off + nbytes} bytes",
                got=f"{len(data)} bytes",
            )
        arrays[name] = np.frombuffer(data, dt, count, start + off).reshape(shape)
    return arrays, meta
