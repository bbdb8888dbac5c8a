"""Atomic file output: write to a temporary name beside the target, then rename.

A failed or interrupted write leaves the target untouched (the old file, or
nothing) and removes its temporary file.  ``os.replace`` is atomic on POSIX
and Windows when source and target are on the same file system, which holds
because the temporary file is created in the target's directory.

The folders an output goes in are made by :func:`make_folders`, one level at a time: inside
:func:`removing_made_folders` (the CLI runs every command in it) those it made are noted, and a command that fails
or is stopped removes them again where they are still empty -- only folders this process made, never one that
someone else made meanwhile, and ``os.rmdir`` removes nothing else.
"""

from __future__ import annotations

import contextlib
import contextvars
import errno
import glob
import os
import shutil
from collections.abc import Iterator
from pathlib import Path
from typing import IO, cast

from ..errors import SegadeformError

__all__ = [
    "atomic_path",
    "atomic_open",
    "atomic_directory",
    "remove_temporaries",
    "merge_directory",
    "WriteError",
    "write_error",
    "make_folders",
    "removing_made_folders",
]

#: the folders :func:`make_folders` made inside the innermost :func:`removing_made_folders`, in the order made
_MADE: contextvars.ContextVar[list | None] = contextvars.ContextVar("segadeform_made_folders", default=None)


def make_folders(folder: str | os.PathLike) -> None:
    """``mkdir -p folder``, one level at a time, noting each folder this call made (see the module docstring).  A
    folder that appeared meanwhile is not counted; a file in the way raises as ``mkdir`` does."""
    folder = Path(folder)
    missing = []
    for a in [folder, *folder.parents]:
        if os.path.lexists(a):
            break
        missing.append(a)
    made = _MADE.get()
    for a in reversed(missing):
        try:
            os.mkdir(a)
        except FileExistsError:
            continue
        if made is not None:
            made.append(a)


@contextlib.contextmanager
def removing_made_folders() -> Iterator[None]:
    """``with removing_made_folders(): <one command>`` -- when the block raises (an error, KeyboardInterrupt), the
    folders :func:`make_folders` made inside it are removed where they are empty, deepest first, then the exception
    goes on (``run -o new/out.pc2`` stopped mid-write left ``new/``: a user's trial)."""
    made: list = []
    token = _MADE.set(made)
    try:
        yield
    except BaseException:
        for d in reversed(made):
            try:
                os.rmdir(d)
            except OSError:
                pass  # not empty (what is in it stays), or already gone
        raise
    finally:
        _MADE.reset(token)


class WriteError(SegadeformError, OSError):
    """An output could not be written (disk full, file-size limit, read-only or missing folder); the message
    names the target.  Nothing partial is left: the temporary file is removed.  Also an :class:`OSError` (with the
    ``errno``), so code that treats a failed optional write (a cache) as a warning keeps doing so."""

    def __init__(self, path, reason: str, err: int | None = None) -> None:
        self.path, self.reason = os.fspath(path), reason
        super().__init__(err, f"{self.path}: cannot write: {reason}")
        self.filename = self.path

    def __str__(self) -> str:
        return cast(str, self.strerror)  # set by __init__


_WHY: dict[int | None, str] = {
    errno.ENOSPC: "no space left on the device",
    errno.EFBIG: "the file-size limit is reached (ulimit -f)",
    errno.EDQUOT: "the disk quota is exceeded",
    errno.EROFS: "the file system is read-only",
    errno.EACCES: "permission denied (is the folder read-only?)",
    errno.EPERM: "permission denied (is the folder read-only?)",
}


def write_error(e: OSError, target) -> SegadeformError:
    """The one wording for an output that could not be written: the target and the reason, e.g.
    ``out/x.pc2: cannot write: no space left on the device (expected free space, got ...)``.  A :class:`WriteError`
    already is one: it is given back as it is (wrapped again, a USD writer's said its target twice: a review)."""
    if isinstance(e, WriteError):
        return e
    why = _WHY.get(e.errno, e.strerror or str(e))
    return WriteError(target, f"{why}; nothing was left behind", e.errno)


def _tmp_sibling(target: Path, *, directory: bool) -> Path:
    """A new, empty temporary file (or folder) beside ``target``.

    Created with mode 0o666 (0o777 for folders) filtered by the umask, like
    ``open()`` and ``mkdir()`` -- not ``mkstemp``'s 0o600, which would make
    every output readable by its owner only.
    """
    for a in [target.parent, *target.parent.parents]:  # `-o file.obj/x.pc2`: say so, not "File exists"
        if a.exists():
            if not a.is_dir():
                raise WriteError(target, f"{a} is a file, not a folder", errno.ENOTDIR)
            break
    try:
        make_folders(target.parent)
    except OSError as e:
        raise write_error(e, target) from None
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
        except OSError as e:
            raise write_error(e, target) from None
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
    except OSError as e:
        with contextlib.suppress(FileNotFoundError):
            tmp.unlink()
        if e.errno in _WHY and (e.filename is None or Path(e.filename) in (tmp, target)):
            raise write_error(e, target) from None  # disk full, ulimit -f ...: name the output
        raise
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


def merge_directory(tmp: Path, target: Path) -> None:
    """Move the files of folder ``tmp`` into ``target``: renamed whole when ``target`` does not exist (or is
    empty), else file by file (each replacing the file of its name; nothing else in ``target`` is touched), then
    ``tmp`` removed.  Which files may be replaced is the caller's rule (:mod:`segadeform.io.output_guard`)."""
    tmp, target = Path(tmp), Path(target)
    if target.exists() and not target.is_dir():
        raise FileExistsError(f"{target}: exists and is not a directory")
    if not target.exists():
        os.replace(tmp, target)
        return
    with contextlib.suppress(OSError):  # an empty folder (not the working directory): replaced whole
        if not any(target.iterdir()) and Path.cwd().resolve() != target.resolve():
            os.replace(tmp, target)
            return
    for src in sorted(tmp.iterdir()):
        dst = target / src.name
        if src.is_dir() and not src.is_symlink() and dst.is_dir():
            merge_directory(src, dst)
        else:
            os.replace(src, dst)
    shutil.rmtree(tmp, ignore_errors=True)


@contextlib.contextmanager
def atomic_directory(path: str | os.PathLike) -> Iterator[Path]:
    """Yield a temporary directory; on success its files go to ``path`` (:func:`merge_directory`): the whole
    folder renamed into place when ``path`` is new, else file by file -- nothing already in ``path`` is removed.
    """
    target = Path(path)
    tmp = _tmp_sibling(target, directory=True)
    try:
        yield tmp
        merge_directory(tmp, target)
    except OSError as e:
        shutil.rmtree(tmp, ignore_errors=True)
        if e.errno in _WHY and e.filename is None:
            raise write_error(e, target) from None
        raise
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise
