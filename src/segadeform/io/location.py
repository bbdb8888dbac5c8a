"""Where a job's results go: a local folder or an fsspec URL, every file committed whole.

:func:`open_location` takes a folder path or a URL that fsspec knows (``s3://bucket/prefix``,
``gs://...``, ``file:///...``, ``memory://...``; the protocol's own fsspec package must be
installed, e.g. ``s3fs``).  Paths inside a location are relative, ``/``-separated
(``"samples/ID.npz"``).

* A **local folder** keeps :mod:`segadeform.io.atomic`: a file is written under a temporary name
  beside its target and renamed onto it.
* On an **fsspec file system** a file is written locally, uploaded under a temporary key beside its
  target (``.NAME.tmp-HEX``), its size checked, moved onto the target (on object stores a
  server-side copy: the target appears whole or not at all) and its size checked again.

``once=True`` commits only while the target does not exist (the result says whether it was
committed): the marker that says a task is finished is written last and once.  A local folder does
this atomically with a hard link; an object store checks, then moves -- two steps, which is enough
for tasks that the executor runs one attempt at a time (a retry starts after the attempt died).

A task that died mid-write leaves temporaries; :meth:`Location.remove_temporaries` removes those
of one target, which the next attempt of the task that owns the target does before it writes.
"""

from __future__ import annotations

import abc
import contextlib
import os
import posixpath
import shutil
import tempfile
from collections.abc import Iterator
from pathlib import Path

from ..errors import InputError, SegadeformError
from .atomic import _tmp_sibling, atomic_path, make_folders, remove_temporaries

__all__ = ["Location", "LocalLocation", "FsspecLocation", "open_location", "is_url"]


def is_url(x) -> bool:
    """Whether ``x`` names an fsspec URL (``scheme://...``) rather than a local path."""
    return isinstance(x, str) and "://" in x and not x.startswith("/")


def _check_rel(rel: str) -> str:
    parts = rel.split("/")
    if not rel or rel.startswith("/") or any(p in ("", ".", "..") for p in parts):
        raise InputError("a path inside a location must be relative and plain", expected="e.g. samples/ID.npz", got=rel)
    return rel


class Location(abc.ABC):
    """A folder that results are committed to (see the module docstring)."""

    url: str

    @abc.abstractmethod
    def exists(self, rel: str) -> bool:
        raise NotImplementedError

    @abc.abstractmethod
    def read_bytes(self, rel: str) -> bytes:
        raise NotImplementedError

    def read_text(self, rel: str) -> str:
        return self.read_bytes(rel).decode("utf-8")

    @abc.abstractmethod
    def listdir(self, rel: str = "") -> list[str]:
        """Names of the files in folder ``rel`` (temporaries left out), sorted; [] when it does not exist."""
        raise NotImplementedError

    @abc.abstractmethod
    def size(self, rel: str) -> int | None:
        """The size in bytes of file ``rel``; None when there is no such file."""
        raise NotImplementedError

    @abc.abstractmethod
    def remove(self, rel: str) -> None:
        """Remove file ``rel`` (one the caller wrote: nothing else is ever removed); nothing when it is not there."""
        raise NotImplementedError

    @abc.abstractmethod
    @contextlib.contextmanager
    def writing(self, rel: str, *, once: bool = False) -> Iterator[Path]:
        """Yield a local path to write; committed to ``rel`` when the block succeeds.  With ``once``
        and ``rel`` already there, :class:`FileExistsError` (the existing file untouched)."""
        raise NotImplementedError
        yield  # pragma: no cover

    def put_bytes(self, rel: str, data: bytes, *, once: bool = False) -> bool:
        """Commit ``data`` to ``rel``; False when ``once`` and ``rel`` existed (nothing written)."""
        try:
            with self.writing(rel, once=once) as tmp:
                Path(tmp).write_bytes(data)
        except FileExistsError:
            if once:
                return False
            raise
        return True

    @abc.abstractmethod
    def local_copy(self, rel: str, into: Path) -> Path:
        """A local file with ``rel``'s content (a local folder's own file; else downloaded into ``into``)."""
        raise NotImplementedError

    @abc.abstractmethod
    def remove_temporaries(self, rel: str) -> int:
        """Remove what killed writers of ``rel`` left (see the module docstring); returns how many."""
        raise NotImplementedError

    @contextlib.contextmanager
    def scratch(self, rel: str) -> Iterator[Path]:
        """A local scratch folder for making ``rel`` (removed afterwards; one a killed writer left goes
        with :meth:`remove_temporaries` of ``rel``); :meth:`commit_tree` moves what is written there."""
        _check_rel(rel)
        d = Path(tempfile.mkdtemp(prefix="segadeform-"))
        try:
            yield d
        finally:
            shutil.rmtree(d, ignore_errors=True)

    def commit_tree(self, local: Path, rel: str = "") -> list[str]:
        """Commit every file under the local folder ``local`` to ``rel/...``, each whole; the paths written."""
        out = []
        for p in sorted(Path(local).rglob("*")):
            if p.is_file():
                r = p.relative_to(local).as_posix()
                target = f"{rel}/{r}" if rel else r
                self._commit_file(p, target)
                out.append(target)
        return out

    def _commit_file(self, local: Path, rel: str) -> None:
        with self.writing(rel) as tmp:
            shutil.copyfile(local, tmp)

    def append_text(self, rel: str, text: str) -> None:
        """Add ``text`` at the end of ``rel`` (created if missing)."""
        old = self.read_text(rel) if self.exists(rel) else ""
        self.put_bytes(rel, (old + text).encode("utf-8"))

    def __str__(self) -> str:
        return self.url


class LocalLocation(Location):
    """A folder on this machine (or a shared file system every worker mounts at the same path)."""

    def __init__(self, root: str | os.PathLike) -> None:
        self.root = Path(root)
        self.url = str(self.root)

    def path(self, rel: str) -> Path:
        return self.root / _check_rel(rel)

    def exists(self, rel: str) -> bool:
        return self.path(rel).is_file()

    def read_bytes(self, rel: str) -> bytes:
        return self.path(rel).read_bytes()

    def listdir(self, rel: str = "") -> list[str]:
        d = self.path(rel) if rel else self.root
        if not d.is_dir():
            return []
        return sorted(p.name for p in d.iterdir() if p.is_file() and not p.name.startswith("."))

    def size(self, rel: str) -> int | None:
        p = self.path(rel)
        return p.stat().st_size if p.is_file() else None

    def remove(self, rel: str) -> None:
        self.path(rel).unlink(missing_ok=True)

    @contextlib.contextmanager
    def writing(self, rel: str, *, once: bool = False) -> Iterator[Path]:
        with atomic_path(self.path(rel), exclusive=once) as tmp:
            yield tmp

    def local_copy(self, rel: str, into: Path) -> Path:
        return self.path(rel)

    def remove_temporaries(self, rel: str) -> int:
        return remove_temporaries(self.path(rel))

    @contextlib.contextmanager
    def scratch(self, rel: str) -> Iterator[Path]:
        # a temporary beside the target: what is written there is renamed into place, not copied
        d = _tmp_sibling(self.path(rel), directory=True)
        try:
            yield d
        finally:
            shutil.rmtree(d, ignore_errors=True)

    def _commit_file(self, local: Path, rel: str) -> None:
        target = self.path(rel)
        make_folders(target.parent)
        try:
            os.replace(local, target)  # same file system when ``local`` is in :meth:`scratch`
        except OSError:
            super()._commit_file(local, rel)

    def append_text(self, rel: str, text: str) -> None:
        p = self.path(rel)
        make_folders(p.parent)
        with open(p, "a", encoding="utf-8") as fh:  # a log: lines appended, each flushed whole
            fh.write(text)
            fh.flush()

    def __repr__(self) -> str:
        return f"LocalLocation({self.url!r})"


def _fsspec():
    try:
        import fsspec
    except ImportError:
        raise SegadeformError(
            "a URL output needs fsspec (expected fsspec installed: pip install "
            "segadeform[ray], got no module named fsspec)"
        ) from None
    return fsspec


class FsspecLocation(Location):
    """A folder on an fsspec file system, named by a URL (see the module docstring)."""

    def __init__(self, url: str, **storage_options) -> None:
        fsspec = _fsspec()
        self.url, self.storage_options = url, storage_options
        try:
            self.fs, root = fsspec.core.url_to_fs(url, **storage_options)
        except (ValueError, ImportError) as e:
            raise InputError(
                "cannot open this output URL",
                expected="a path, or a URL of a protocol fsspec knows with its package installed (s3:// needs s3fs)",
                got=f"{url} ({e})",
            ) from None
        self.root = root.rstrip("/")

    def __reduce__(self):  # rebuilt from its URL in each worker (file system objects hold connections)
        return (_rebuild_fsspec, (self.url, self.storage_options))

    def key(self, rel: str) -> str:
        return f"{self.root}/{_check_rel(rel)}" if self.root else _check_rel(rel)

    def exists(self, rel: str) -> bool:
        return bool(self.fs.isfile(self.key(rel)))

    def read_bytes(self, rel: str) -> bytes:
        return self.fs.cat_file(self.key(rel))

    def listdir(self, rel: str = "") -> list[str]:
        d = self.key(rel) if rel else self.root
        try:
            entries = self.fs.ls(d, detail=True)
        except (FileNotFoundError, NotADirectoryError):
            return []
        names = [posixpath.basename(e["name"].rstrip("/")) for e in entries if e.get("type") == "file"]
        return sorted(n for n in names if not n.startswith("."))

    def size(self, rel: str) -> int | None:
        key = self.key(rel)
        return int(self.fs.size(key)) if self.fs.isfile(key) else None

    def remove(self, rel: str) -> None:
        with contextlib.suppress(FileNotFoundError):
            self.fs.rm(self.key(rel))

    @contextlib.contextmanager
    def writing(self, rel: str, *, once: bool = False) -> Iterator[Path]:
        _check_rel(rel)
        d = Path(tempfile.mkdtemp(prefix="segadeform-put-"))
        try:
            local = d / posixpath.basename(rel)
            yield local
            self._upload(local, rel, once=once)
        finally:
            shutil.rmtree(d, ignore_errors=True)

    def _commit_file(self, local: Path, rel: str) -> None:
        self._upload(Path(local), rel, once=False)

    def _upload(self, local: Path, rel: str, *, once: bool) -> None:
        key = self.key(rel)
        parent, name = posixpath.split(key)
        tmp = f"{parent}/.{name}.tmp-{os.urandom(6).hex()}"
        size = os.path.getsize(local)
        self.fs.makedirs(parent, exist_ok=True)
        try:
            self.fs.put_file(str(local), tmp)
            if self.fs.size(tmp) != size:
                raise SegadeformError(
                    f"{self.url}: upload of {rel} is incomplete (expected {size} bytes, got {self.fs.size(tmp)})"
                )
            if once and self.fs.isfile(key):
                raise FileExistsError(f"{self.url}/{rel}: exists already (an exclusive commit)")
            self.fs.mv(tmp, key)
        except BaseException:
            with contextlib.suppress(Exception):
                if self.fs.exists(tmp):
                    self.fs.rm(tmp)
            raise
        got = self.fs.size(key)
        if got != size:
            raise SegadeformError(
                f"{self.url}: {rel} after the move is not what was uploaded (expected {size} bytes, got {got})"
            )

    def local_copy(self, rel: str, into: Path) -> Path:
        p = Path(into) / posixpath.basename(rel)
        self.fs.get_file(self.key(rel), str(p))
        return p

    def remove_temporaries(self, rel: str) -> int:
        parent, name = posixpath.split(self.key(rel))
        try:
            found = self.fs.glob(f"{parent}/.{name}.tmp-*")
        except FileNotFoundError:
            return 0
        for k in found:
            with contextlib.suppress(FileNotFoundError):
                self.fs.rm(k)
        return len(found)

    def __repr__(self) -> str:
        return f"FsspecLocation({self.url!r})"


def _rebuild_fsspec(url: str, storage_options: dict) -> FsspecLocation:
    return FsspecLocation(url, **storage_options)


def open_location(where: str | os.PathLike | Location) -> Location:
    """A :class:`Location` for a folder path or an fsspec URL (a Location is returned as it is)."""
    if isinstance(where, Location):
        return where
    if is_url(os.fspath(where) if not isinstance(where, str) else where):
        return FsspecLocation(str(where))
    return LocalLocation(Path(where))
