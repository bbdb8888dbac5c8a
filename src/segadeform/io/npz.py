"""Reading ``.npz`` files safely: no pickles, and no allocation larger than the file holds.

``np.load`` on an ``.npz`` member allocates the array its header declares
before reading the data, so a crafted header (shape 10^10, say) can exhaust
memory.  :func:`load_npz` reads every member's header first and refuses a
declared size that differs from the member's stored byte count.
"""

from __future__ import annotations

import os
import zipfile
from pathlib import Path

import numpy as np

from ..errors import FileFormatError

__all__ = ["load_npz"]


#: a compressed member may unpack to at most this many times its compressed size once past UNPACKED_MIN bytes: real
#: arrays (floats, indices, masks) compress a few times at most; a member of zeros compresses about 1,000 times
UNPACKED_RATIO = 200
UNPACKED_MIN = 64 * 2**20


def check_unpacked(info: zipfile.ZipInfo, path, what: str) -> None:
    """Refuse zip member ``info`` (``what`` names it) when it would unpack past :data:`UNPACKED_MIN` bytes to more than
    :data:`UNPACKED_RATIO` times its compressed size: a decompression bomb, refused before it is read (npz arrays,
    dataset packs and their samples)."""
    if info.compress_type != zipfile.ZIP_STORED and info.file_size > max(
        UNPACKED_MIN, UNPACKED_RATIO * info.compress_size
    ):
        raise FileFormatError(
            f"{what} unpacks to far more than its compressed size (a decompression bomb?)",
            path=path,
            expected=f"at most {UNPACKED_RATIO}x its {info.compress_size} compressed bytes above "
            f"{UNPACKED_MIN // 2**20} MiB",
            got=f"{info.file_size} bytes",
        )


def load_npz(path: str | os.PathLike, *, what: str = ".npz") -> dict[str, np.ndarray]:
    """All arrays of an ``.npz`` file as a dict, each checked against its stored size first."""
    p = Path(path)
    if not p.is_file():
        raise FileFormatError("is a folder, not a file" if p.is_dir() else "no such file", path=p)
    try:
        zf = zipfile.ZipFile(p)
    except Exception as e:  # BadZipFile, OSError, NotImplementedError ("zip file version 22.7", found by fuzzing) ...
        raise FileFormatError(f"not a readable {what} file ({type(e).__name__}: {e})", path=p) from None
    out = {}
    with zf:
        for info in zf.infolist():
            name = info.filename[:-4] if info.filename.endswith(".npy") else info.filename
            check_unpacked(info, p, f"array '{name}'")  # (a security review: 3.2 MB of zeros grew to 24 GB)
            try:
                with zf.open(info) as fh:
                    version = np.lib.format.read_magic(fh)
                    if version == (1, 0):
                        shape, fortran, dtype = np.lib.format.read_array_header_1_0(fh)
                    else:
                        shape, fortran, dtype = np.lib.format.read_array_header_2_0(fh)
                    if dtype.hasobject:
                        raise FileFormatError(f"array '{name}' holds pickled objects, which are not read", path=p)
                    declared = int(np.prod(shape, dtype=object)) * dtype.itemsize
                    header_len = fh.tell()
                    stored = info.file_size - header_len
                    if declared != stored:
                        raise FileFormatError(
                            f"array '{name}' declares more data than the file holds"
                            if declared > stored
                            else f"array '{name}' has trailing data",
                            path=p,
                            expected=f"{declared} bytes for shape {tuple(shape)} {dtype}",
                            got=f"{stored} bytes",
                        )
                    data = fh.read(stored)
                a = np.frombuffer(data, dtype=dtype)
                a = a.reshape(shape, order="F" if fortran else "C").copy()
            except FileFormatError:
                raise
            except Exception as e:  # bad magic, bad header, truncated member, CRC error
                raise FileFormatError(f"array '{name}' cannot be read ({type(e).__name__}: {e})", path=p) from None
            out[name] = a
    return out
