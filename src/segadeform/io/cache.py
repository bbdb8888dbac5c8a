"""The user cache: precomputed garment assets, encoder outputs and (residual-weights models) the body's
weights carried to the garment, kept between runs.

Where (read when a run asks, never at import):

* ``$SEGADEFORM_CACHE_DIR`` if set;
* else the platform's convention: ``$XDG_CACHE_HOME/segadeform`` or ``~/.cache/segadeform`` (Linux and
  other Unix), ``~/Library/Caches/segadeform`` (macOS), ``%LOCALAPPDATA%\\segadeform\\Cache`` (Windows).

Nothing is written next to the user's input files.  The cache is bounded: after each write,
:func:`prune` removes the least recently used entries until the folder holds at most
``$SEGADEFORM_CACHE_MAX_MB`` (default 1024) megabytes.  Entries are named by content hashes, so a
stale entry is never used; any of them can be deleted at any time (``segadeform cache clear``).
"""

from __future__ import annotations

import os
import re
import sys
from pathlib import Path

__all__ = ["cache_dir", "prune", "is_entry", "DEFAULT_MAX_MB"]

DEFAULT_MAX_MB = 1024

#: the names of the cache's entries (content hashes): garment assets, encoder outputs (P-), body weights at a
#: garment (W-), cloth setups (C-), FBX motions as BVH (F-).  prune and `cache clear` remove these only:
#: $SEGADEFORM_CACHE_DIR may name a folder that holds the user's own files too, and no command deletes a file it did
#: not write.
_ENTRY = re.compile(r"^(?:asset-[0-9a-f]{16,}(?:-n\d+)?(?:-p\d+)?\.npz|[A-Z]-[0-9a-f]{16,}\.(?:np[yz]|bvh))$")


def is_entry(name: str) -> bool:
    """Whether ``name`` is one of the cache's entries (see :data:`_ENTRY`)."""
    return bool(_ENTRY.match(name))


def cache_dir(create: bool = True) -> Path:
    """The cache folder (see the module docstring)."""
    env = os.environ.get("SEGADEFORM_CACHE_DIR")
    if env:
        d = Path(env).expanduser()
    elif sys.platform == "win32":
        d = Path(os.environ.get("LOCALAPPDATA", Path.home() / "AppData" / "Local")) / "segadeform" / "Cache"
    elif sys.platform == "darwin":
        d = Path.home() / "Library" / "Caches" / "segadeform"
    else:
        d = Path(os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache") / "segadeform"
    if create:
        d.mkdir(parents=True, exist_ok=True)
    return d


def _max_bytes() -> int:
    try:
        mb = float(os.environ.get("SEGADEFORM_CACHE_MAX_MB", DEFAULT_MAX_MB))
    except ValueError:
        mb = DEFAULT_MAX_MB
    return int(max(mb, 0) * 1024 * 1024)


def prune(d: Path | None = None, max_bytes: int | None = None) -> int:
    """Delete least recently used cache entries (:func:`is_entry`; nothing else in ``d``) until they take at most
    ``max_bytes``; returns bytes freed."""
    d = cache_dir(create=False) if d is None else Path(d)
    limit = _max_bytes() if max_bytes is None else int(max_bytes)
    if not d.is_dir():
        return 0
    files = []
    for p in d.iterdir():
        if not is_entry(p.name):
            continue
        try:
            st = p.stat()
        except OSError:
            continue
        if p.is_file():
            files.append((max(st.st_atime, st.st_mtime), st.st_size, p))
    total = sum(f[1] for f in files)
    freed = 0
    for _, size, p in sorted(files):
        if total - freed <= limit:
            break
        try:
            p.unlink()
            freed += size
        except OSError:
            pass
    return freed
