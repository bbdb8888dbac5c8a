"""Reading TOML configuration files with errors that name the file (scenes, dataset and training configs)."""

from __future__ import annotations

import sys
from pathlib import Path

from .errors import FileFormatError, file_error

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover
    import tomli as tomllib

__all__ = ["read_toml"]


def read_toml(path, what: str) -> tuple[dict, str]:
    """``(data, text)`` of a UTF-8 TOML file; :class:`FileFormatError` naming the file otherwise."""
    p = Path(path)
    try:
        raw = p.read_bytes()
    except OSError as e:
        raise file_error(e, p, what) from None
    try:
        text = raw.decode("utf-8-sig")  # a byte-order mark (Windows editors write one) is not TOML
    except UnicodeDecodeError:
        raise FileFormatError(f"{what} is not UTF-8 text", path=p) from None
    try:
        return tomllib.loads(text), text
    except tomllib.TOMLDecodeError as e:
        raise FileFormatError(f"invalid TOML: {e}", path=p) from None
    except RecursionError:  # arrays or tables nested thousands deep
        raise FileFormatError(f"{what} nests too deeply to be read", path=p) from None
