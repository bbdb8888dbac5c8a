"""The SHA-256 of a file, read in chunks (garment sources, package graphs and weights, jobs' inputs)."""

from __future__ import annotations

import hashlib
import os

__all__ = ["file_sha256"]

_CHUNK = 1 << 20


def file_sha256(path: str | os.PathLike) -> str:
    """The hex SHA-256 of the file's bytes, read 1 MiB at a time (memory stays flat for any size).  Raises
    OSError as :func:`open` does."""
    h = hashlib.sha256()
    with open(path, "rb") as fh:
        for chunk in iter(lambda: fh.read(_CHUNK), b""):
            h.update(chunk)
    return h.hexdigest()
