"""Atomic file output: write to a temporary name beside the target, then rename.

A failed or interrupted write leaves the target untouched (the old file, or
nothing) and removes its temporary file.  ``os.replace`` is atomic on POSIX
and Windows when source and target are on the same file system, which holds
because the temporary file is created in the target's directory.
"""

from __future__ import annotations

import contextlib
import glob
import os
import shutil
from pathlib import Path
from typing import IO, Iterator

__all__ = ["atomic_path", "atomic_open", "atomic_directory", "remove_temporaries"]


def _tmp_sibling(target: Path, *, directory: bool) -> Path:
    """A new, empty temporary file (or folder) beside ``target``.

    Created with mode 0o666 (0o777 for folders) filtered by the umask, like
    ``open()`` and ``mkdir()`` -- not ``mkstemp``'s 0o600, which would make
    every output readable by its owner only.
    """
    target.parent.mkdir(parents=True, exist_ok=True)
    prefix = f".{target.name}.tmp-"
    for _ in range(100):
        name = target.parent / f"{prefix}{os.urandom(6).hex()}"
        try:
            if directory:
                os.mkdir(name, 0o777)
            else:
                os.close(os.open(name, os.O_CREAT | os.O_EXCL | os.O_WRONLY, 0o666))
            return name
        except FileExistsError:
            continue
    raise FileExistsError(f"could not create a temporary file beside {target}")


@contextlib.contextmanager
def atomic_path(path: str | os.PathLike, *, exclusive: bool = False) -> Iterator[Path]:
    """Yield a temporary path; on success it is renamed to ``path``.

    The caller writes the temporary path by any means (numpy, meshio, ...).
    On an exception the temporary file is removed and the error re-raised.

    ``exclusive``: commit only if ``path`` does not exist yet (a hard link, which fails when the
    target exists, then the temporary name removed); :class:`FileExistsError` otherwise, the
    existing file untouched.  On file systems without hard links the check and the rename are
    two steps.
    """
    target = Path(path)
    tmp = _tmp_sibling(target, directory=False)
    try:
        yield tmp
        if exclusive:
            _link_exclusive(tmp, target)
        else:
            os.replace(tmp, target)
    except BaseException:
        with contextlib.suppress(FileNotFoundError):
            tmp.unlink()
        raise


def _link_exclusive(tmp: Path, target: Path) -> None:
    try:
        os.link(tmp, target)
    except FileExistsError:
        raise FileExistsError(f"{target}: exists already (an exclusive commit)") from None
    except OSError:  # no hard links here (some network and FUSE file systems)
        if target.exists():
            raise FileExistsError(f"{target}: exists already (an exclusive commit)") from None
        os.replace(tmp, target)
        return
    tmp.unlink()


def remove_temporaries(path: str | os.PathLike) -> int:
    """Remove the temporary files and folders a killed writer of ``path`` left beside it; returns
    how many.  Only for a writer that owns ``path``: a live writer's temporary would go too."""
    target = Path(path)
    n = 0
    if not target.parent.is_dir():
        return 0
    for p in target.parent.glob(f".{glob.escape(target.name)}.tmp-*"):
        if p.is_dir() and not p.is_symlink():
            shutil.rmtree(p, ignore_errors=True)
        else:
            with contextlib.suppress(FileNotFoundError):
                p.unlink()
        n += 1
    return n


@contextlib.contextmanager
def atomic_open(path: str | os.PathLike, mode: str = "wb", **kwargs) -> Iterator[IO]:
    """``open`` for writing, committed by rename when the block succeeds."""
    if not any(c in mode for c in "wx"):
        raise ValueError(f"atomic_open writes new files: expected mode 'w' or 'wb', got {mode!r}")
    with atomic_path(path) as tmp:
        with open(tmp, mode.replace("x", "w"), **kwargs) as fh:
            yield fh
            fh.flush()
            os.fsync(fh.fileno())


@contextlib.contextmanager
def atomic_directory(path: str | os.PathLike) -> Iterator[Path]:
    """Yield a temporary directory; on success it replaces ``path``.

    An existing directory at ``path`` is moved aside first and deleted only
    after the new one is in place.
    """
    target = Path(path)
    tmp = _tmp_sibling(target, directory=True)
    try:
        yield tmp
        old = None
        if target.exists():
            if not target.is_dir():
                raise FileExistsError(f"{target}: exists and is not a directory")
            old = _tmp_sibling(target, directory=True)
            old.rmdir()
            os.replace(target, old)
        os.replace(tmp, target)
        if old is not None:
            shutil.rmtree(old, ignore_errors=True)
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise
