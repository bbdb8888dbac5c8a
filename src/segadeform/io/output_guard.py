"""The one output rule: no command deletes or overwrites a file it did not write.

Every command that writes files builds an :class:`OutputGuard` -- its *kind* (the command: ``"run"``,
``"garment fit"`` ...; the model-package writers share ``"package"``), the user's ``--force`` and the
files it reads -- and claims each output before any work starts:

* **A file** (:meth:`OutputGuard.file`).  A new path is written; a file an earlier run of the same kind wrote
  (the folder's manifest lists it, unchanged since) is replaced.  Anything else is refused with the reason and
  a way out, ``--force`` or not: a file segadeform did not write (or that was edited since), another command's
  output, an input of the command, a folder, a path inside a file.
* **A folder of files** (:meth:`OutputGuard.folder`: an OBJ sequence, a model package, a report).  A new or
  empty folder, or one holding only an earlier output of the same kind, is written (the earlier files this run
  does not write again are removed).  A folder that holds anything else is refused; with ``force`` the new
  files go beside what is there, replacing only what an earlier run of the same kind wrote, and a file
  segadeform did not write at a name the output uses (``names``, globs) is refused.  Without ``names`` (the
  files are not known in advance: a model package) such a folder is refused even with ``force``.
* **A resumable folder** (:meth:`OutputGuard.resumable`: ``dataset make``, ``batch``, ``train``, on a local
  folder or an fsspec URL).  A new or empty folder is started; one that a run of the same kind made (its
  manifest says so, or it has that command's layout, ``legacy``) is continued, which is how these commands
  resume.  One that holds other files is refused without ``force``; with it the run writes beside them, and is
  refused if any of them sits where its layout writes (``layout``: the top-level names).

An output inside an input's folder is written like any other; inputs are never replaced or removed.

**The manifest.**  ``.segadeform-outputs.json`` in each folder that receives outputs lists, per file name,
the kind that wrote it and the file's size and modification time (ns) when written; a file whose size or
time changed since is no longer counted as written by segadeform (someone edited it).  A resumable folder's
manifest also says whose folder it is (``"folder": kind``).  :meth:`OutputGuard.record` updates it after a
successful commit (under an advisory lock, so parallel writers into one folder do not lose entries).

**The write itself** stays atomic (:mod:`segadeform.io.atomic`): claims are checked before any work and again
just before the commit (:meth:`OutputGuard.recheck`), so a file that appeared meanwhile is refused too.
"""

from __future__ import annotations

import contextlib
import dataclasses
import fnmatch
import json
import os
import shutil
from collections.abc import Callable, Iterable, Iterator, Sequence
from pathlib import Path

from ..errors import InputError

__all__ = ["MANIFEST_NAME", "OutputRefused", "OutputGuard", "written_by", "read_manifest"]

#: the manifest each output folder gets
MANIFEST_NAME = ".segadeform-outputs.json"
_MANIFEST_VERSION = 1


class OutputRefused(InputError):
    """An output would delete or overwrite something segadeform did not write (or an input, or a previous
    output without ``--force``).  The message says why and what to do instead."""


def _is_temporary(name: str) -> bool:
    return name.startswith(".") and ".tmp-" in name


# ---- the manifest --------------------------------------------------------------------------------------------
def read_manifest(folder: str | os.PathLike) -> dict:
    """The manifest of ``folder`` (``{"files": {name: {"kind", "size", "mtime_ns"}}, "folder": kind?}``);
    an empty one when there is none.  A manifest that is not one is refused (it is never overwritten)."""
    p = Path(folder) / MANIFEST_NAME
    try:
        raw = p.read_bytes()
    except FileNotFoundError:
        return {"files": {}}
    except NotADirectoryError:
        return {"files": {}}
    except OSError as e:
        raise OutputRefused(f"cannot read the outputs manifest ({e.strerror or e})", path=p) from None
    try:
        m = json.loads(raw.decode("utf-8"))
        if (
            not isinstance(m, dict)
            or m.get("segadeform_outputs") != _MANIFEST_VERSION
            or not isinstance(m.get("files"), dict)
            or not all(isinstance(v, dict) and isinstance(v.get("kind"), str) for v in m["files"].values())
        ):
            raise ValueError
    except (ValueError, UnicodeDecodeError):
        raise OutputRefused(
            "not a segadeform outputs manifest, and segadeform does not overwrite it",
            path=p,
            expected=f'JSON with "segadeform_outputs": {_MANIFEST_VERSION}',
            got=repr(raw[:40]),
        ) from None
    return m


def _stat(p: Path) -> os.stat_result | None:
    try:
        return os.lstat(p)
    except (FileNotFoundError, NotADirectoryError):
        return None


def _entry(kind: str, st: os.stat_result) -> dict:
    return {"kind": kind, "size": int(st.st_size), "mtime_ns": int(st.st_mtime_ns)}


def _unchanged(entry: dict, st: os.stat_result | None) -> bool:
    import stat as stat_mod

    return (
        st is not None
        and stat_mod.S_ISREG(st.st_mode)
        and entry.get("size") == st.st_size
        and entry.get("mtime_ns") == st.st_mtime_ns
    )


def written_by(path: str | os.PathLike) -> str | None:
    """The kind of the command that wrote ``path`` when its folder's manifest lists it and the file is unchanged
    since; None otherwise (not written by segadeform, edited since, or missing)."""
    p = Path(path)
    e = read_manifest(p.parent)["files"].get(p.name)
    return e["kind"] if e is not None and _unchanged(e, _stat(p)) else None


@contextlib.contextmanager
def _locked(folder: Path) -> Iterator[None]:
    """An advisory lock on ``folder`` (flock on the folder itself; none where the platform has no flock)."""
    try:
        import fcntl
    except ImportError:  # pragma: no cover  (Windows)
        yield
        return
    fd = os.open(folder, os.O_RDONLY)
    try:
        fcntl.flock(fd, fcntl.LOCK_EX)
        yield
    finally:
        os.close(fd)  # releases the lock


def _update_manifest(folder: Path, add: dict, drop: Iterable[str] = (), mark: str | None = None) -> None:
    """Add entries ``add`` (name -> entry), drop names, optionally mark the folder as ``mark``'s; atomic."""
    from .atomic import atomic_path

    with _locked(folder):
        m = read_manifest(folder)
        files = dict(m["files"])
        for n in drop:
            files.pop(n, None)
        files.update(add)
        out = {
            "segadeform_outputs": _MANIFEST_VERSION,
            "note": "files segadeform wrote here (name: command, size, mtime); see segadeform.io.output_guard",
        }
        if mark or m.get("folder"):
            out["folder"] = m.get("folder") or mark
        out["files"] = dict(sorted(files.items()))
        if m.get("folder") == out.get("folder") and m["files"] == out["files"] and (folder / MANIFEST_NAME).is_file():
            return  # nothing new: the manifest is left as it is (a resumed run with nothing to do touches nothing)
        with atomic_path(folder / MANIFEST_NAME) as tmp:
            Path(tmp).write_text(json.dumps(out, indent=1) + "\n", encoding="utf-8")


# ---- claims ----------------------------------------------------------------------------------------------------
@dataclasses.dataclass
class _Claim:
    path: Path
    what: str  # "file" | "folder" | "resumable"
    names: tuple | None = None  # folder: globs of the names the output writes
    existed: bool = False
    snapshot: dict = dataclasses.field(default_factory=dict)  # folder: name -> (size, mtime_ns, ino) before
    location: object = None  # resumable: the Location
    layout: tuple = ()
    #: resumable: names (all present), or a function (location, names) -> bool
    legacy: Sequence[str] | Callable[..., bool] = ()
    #: resumable, local: the top-level names before the run and whether the manifest was there
    before: tuple | None = None
    had_manifest: bool = False


def _same_file(a: Path, b: Path) -> bool:
    try:
        return os.path.samefile(a, b)
    except OSError:
        return os.path.abspath(a) == os.path.abspath(b)


#: the folder of derived data (garment precompute, contacts) a run keeps in its output folder
DERIVED_CACHE = "cache"


def _listing(folder: Path) -> list[str]:
    return sorted(n for n in os.listdir(folder) if n != MANIFEST_NAME and not _is_temporary(n))


def _names(items: Sequence[str], more: int = 0) -> str:
    s = ", ".join(items[:3])
    return s + (f" and {len(items) - 3 + more} more" if len(items) + more > 3 else "")


class OutputGuard:
    """The output rule for one command run (see the module docstring).

    Args:
        kind: the command (``"run"``, ``"simulate"``, ``"garment fit"`` ...); files are replaced only by a
            later run of the same kind.
        force: the user's ``--force``: write into a folder that holds other files, beside them (what an earlier
            run of this kind wrote is replaced with or without it).
        inputs: files and folders the command reads; never an output, never replaced or removed.
        replaces: False for a command whose outputs are never replaced, even its own (``dataset pack``).
    """

    def __init__(self, kind: str, *, force: bool = False, inputs: Iterable = (), replaces: bool = True) -> None:
        if not kind or not isinstance(kind, str):
            raise InputError("an output guard needs the command's name", got=kind)
        self.kind, self.force, self.replaces = kind, bool(force) and replaces, replaces
        self.inputs = tuple(Path(p) for p in inputs if p is not None and not _is_url(p))
        self.claims: list[_Claim] = []

    def __repr__(self) -> str:
        return f"OutputGuard({self.kind!r}, force={self.force}, {len(self.claims)} claims)"

    # -- helpers -----------------------------------------------------------------------------------------------
    @property
    def _cmd(self) -> str:
        return _label(self.kind)

    def _input_at(self, p: Path) -> Path | None:
        return next((i for i in self.inputs if _same_file(i, p)), None)

    def _check_parent(self, p: Path) -> None:
        for a in [p.parent, *p.parent.parents]:
            st = _stat(a)
            if st is None:
                continue
            if not os.path.isdir(a):
                raise OutputRefused(
                    f"{a} is a file, so nothing can be written inside it",
                    path=p,
                    expected="a path in a folder",
                    got=f"{a.name} (a file)",
                )
            return

    # -- file outputs ------------------------------------------------------------------------------------------
    def _check_file(self, p: Path) -> bool:
        """Raise unless ``p`` may be written; whether it exists."""
        self._check_parent(p)
        inp = self._input_at(p)
        if inp is not None:
            raise OutputRefused(
                f"is an input of this command, and {self._cmd} never writes over its inputs",
                path=p,
                expected="an output path that is not an input",
                got=str(inp),
            )
        files = read_manifest(p.parent)["files"]  # (a manifest that is not one is refused before any work)
        st = _stat(p)
        if st is None:
            return False
        if os.path.isdir(p):
            raise OutputRefused("is a folder", path=p, expected="a file path for this output", got="a folder")
        entry = files.get(p.name)
        if entry is None or not _unchanged(entry, st):
            # its size or time: the manifest holds no hash (a `touch` of the same bytes is refused too: said)
            why = (
                "segadeform did not write it"
                if entry is None
                else "it changed since segadeform wrote it (its size or modification time: edited, or touched)"
            )
            raise OutputRefused(
                f"exists and {why}; segadeform never overwrites such a file",
                path=p,
                expected="a new path, or remove the file yourself",
                got="an existing file",
            )
        if entry["kind"] != self.kind:
            raise OutputRefused(
                f"exists, written by `{_label(entry['kind'])}`; {self._cmd} does not replace another command's output",
                path=p,
                expected="another path",
                got=f"an output of {_label(entry['kind'])}",
            )
        if not self.replaces:
            raise OutputRefused(
                f"exists (the output of an earlier `{self._cmd}`), and its outputs are never overwritten",
                path=p,
                expected="a new path",
                got="an existing output",
            )
        return True  # an earlier run's output of this command: replaced

    def file(self, path: str | os.PathLike) -> Path:
        """Claim file output ``path`` (see the module docstring); returns it."""
        p = Path(path)
        existed = self._check_file(p)
        self.claims.append(_Claim(p, "file", existed=existed))
        return p

    # -- folder outputs ----------------------------------------------------------------------------------------
    def _check_folder(self, p: Path, names: tuple | None) -> tuple[bool, dict]:
        self._check_parent(p)
        inp = self._input_at(p)
        if inp is not None:
            raise OutputRefused(
                f"is an input of this command, and {self._cmd} never writes over its inputs",
                path=p,
                expected="an output folder that is not an input",
                got=str(inp),
            )
        st = _stat(p)
        if st is None:
            return False, {}
        if not os.path.isdir(p):
            raise OutputRefused(
                "is a file", path=p, expected="a folder for this output (a new or empty one)", got="a file"
            )
        listing = _listing(p)
        if not listing:
            return True, {}
        files = read_manifest(p)["files"]
        snap = {}
        ours: list[str] = []
        other: list[str] = []
        taken: list[str] = []
        for n in listing:
            q = p / n
            s = _stat(q)
            snap[n] = None if s is None else (s.st_size, s.st_mtime_ns, s.st_ino)
            e = files.get(n)
            mine = e is not None and e["kind"] == self.kind and _unchanged(e, s) and self._input_at(q) is None
            (ours if mine else other).append(n)
            if not mine and (names is None or any(fnmatch.fnmatchcase(n, g) for g in names)):
                taken.append(n)
        if not other:
            return True, snap  # only an earlier output of this command: replaced
        if not self.force or names is None:
            raise OutputRefused(
                f"the folder holds {len(other)} file(s) {self._cmd} did not write ({_names(other)})",
                path=p,
                expected="a new or empty folder, or --force to write beside them, untouched"
                if names is not None
                else f"a new or empty folder, or one holding only an earlier output of {self._cmd}",
                got="a folder in use",
            )
        if taken:
            raise OutputRefused(
                f"the folder holds {len(taken)} file(s) named like this output's "
                f"({', '.join(names)}) that "
                f"{self._cmd} did not write ({_names(taken)})",
                path=p,
                expected="another folder",
                got="files in the way",
            )
        return True, snap

    def folder(self, path: str | os.PathLike, *, names=None) -> Path:
        """Claim folder output ``path`` whose files are named like glob(s) ``names`` (None: not known in
        advance)."""
        p = Path(path)
        names = (names,) if isinstance(names, str) else None if names is None else tuple(names)
        existed, snap = self._check_folder(p, names)
        self.claims.append(_Claim(p, "folder", names=names, existed=existed, snapshot=snap))
        return p

    # -- resumable folders ---------------------------------------------------------------------------------------
    def resumable(self, where, *, layout: Sequence[str] = (), legacy: Sequence[str] = ()):
        """Claim a resumable output folder (a path, URL or :class:`~segadeform.io.location.Location`); returns
        the Location.  ``layout``: the top-level names (globs) the command writes (files or folders); ``legacy``:
        names whose presence marks a folder this command made before it had a manifest (all must be there; a
        trailing ``/`` names a folder), or a function ``legacy(location, top-level names) -> bool``.
        """
        from .location import LocalLocation, open_location

        loc = open_location(where)
        if isinstance(loc, LocalLocation):
            p = loc.root
            self._check_parent(p)
            if self._input_at(p) is not None:
                raise OutputRefused(
                    f"is an input of this command, and {self._cmd} never writes over its inputs",
                    path=p,
                    expected="an output folder that is not an input",
                    got=str(p),
                )
            if _stat(p) is not None and not os.path.isdir(p):
                raise OutputRefused("is a file", path=p, expected="a folder for this output", got="a file")
        names = self._top_names(loc)
        c = _Claim(
            Path(str(loc)),
            "resumable",
            location=loc,
            layout=tuple(layout),
            legacy=legacy if callable(legacy) else tuple(legacy),
            existed=names is not None,
        )
        if isinstance(loc, LocalLocation) and names is not None:
            c.before, c.had_manifest = tuple(names), (loc.root / MANIFEST_NAME).is_file()
        self._check_resumable(c, names or [])
        self.claims.append(c)
        return loc

    @staticmethod
    def _top_names(loc) -> list[str] | None:
        """Top-level names in the location (files and folders, manifest and temporaries left out); None when it
        does not exist."""
        from .location import LocalLocation

        if isinstance(loc, LocalLocation):
            if not loc.root.is_dir():
                return None
            return _listing(loc.root)
        try:
            entries = loc.fs.ls(loc.root, detail=False)
        except (FileNotFoundError, NotADirectoryError):
            return None
        names = [str(e).rstrip("/").rsplit("/", 1)[-1] for e in entries]
        return sorted(n for n in names if n and n != MANIFEST_NAME and not _is_temporary(n))

    def _folder_owner(self, loc) -> str | None:
        if not loc.exists(MANIFEST_NAME):
            return None
        from .location import LocalLocation

        if isinstance(loc, LocalLocation):
            return read_manifest(loc.root).get("folder")
        try:
            m = json.loads(loc.read_text(MANIFEST_NAME))
            return m.get("folder") if isinstance(m, dict) else None
        except ValueError:
            return None

    @staticmethod
    def _has(loc, name: str, names: list[str]) -> bool:
        """Whether the location holds ``name`` (``"jobs/"``: a folder of that name)."""
        if not name.endswith("/"):
            return name in names
        from .location import LocalLocation

        n = name.rstrip("/")
        if n not in names:
            return False
        if isinstance(loc, LocalLocation):
            return (loc.root / n).is_dir()
        return bool(loc.fs.isdir(f"{loc.root}/{n}"))

    def _check_resumable(self, c: _Claim, names: list[str]) -> None:
        loc = c.location
        if not names:
            return
        owner = self._folder_owner(loc)
        if owner == self.kind:
            return
        where = Path(str(loc))
        if owner is not None:
            raise OutputRefused(
                f"the folder is the output of `{_label(owner)}`",
                path=where,
                expected=f"a new or empty folder for {self._cmd}",
                got=f"a {owner} folder",
            )
        if (
            callable(c.legacy)
            and c.legacy(loc, names)
            or not callable(c.legacy)
            and c.legacy
            and all(self._has(loc, n, names) for n in c.legacy)
        ):
            return  # made by this command before folders had manifests
        other = [n for n in names]
        if not self.force:
            raise OutputRefused(
                f"the folder holds {len(other)} item(s) {self._cmd} did not write ({_names(other)})",
                path=where,
                expected="a new or empty folder, or --force to write beside them, untouched"
                if self.replaces
                else f"a folder made by {self._cmd}",
                got="a folder in use",
            )
        taken = [n for n in names if any(fnmatch.fnmatchcase(n, pat) for pat in c.layout)]
        if taken:
            raise OutputRefused(
                f"the folder holds {len(taken)} item(s) where {self._cmd} writes ({_names(taken)})",
                path=where,
                expected="another folder",
                got="files in the way",
            )

    def start(self) -> None:
        """Mark claimed resumable folders as this kind's now (before the first task commits), so a stopped run
        is resumed; the folder is created.  A folder that cannot be written (read-only, full) is named."""
        from .atomic import WriteError, write_error

        for c in self.claims:
            if c.what == "resumable":
                try:
                    self._mark(c.location)
                except WriteError as e:
                    raise WriteError(c.path, e.reason, e.errno) from None
                except OSError as e:
                    raise write_error(e, c.path) from None

    def _mark(self, loc) -> None:
        from .location import LocalLocation

        if isinstance(loc, LocalLocation):
            from .atomic import make_folders

            make_folders(loc.root)  # (noted: a command that fails removes it again where it is empty)
            _update_manifest(loc.root, {}, mark=self.kind)
        elif not loc.exists(MANIFEST_NAME):
            body = {"segadeform_outputs": _MANIFEST_VERSION, "folder": self.kind, "files": {}}
            loc.put_bytes(MANIFEST_NAME, (json.dumps(body, indent=1) + "\n").encode("utf-8"))

    def abandon(self) -> None:
        """After a run that made nothing: remove the resumable folders this run created that hold nothing but
        its manifest, and the manifest it added to a folder that was there (a failed run leaves no trace)."""
        from .location import LocalLocation

        for c in self.claims:
            if c.what != "resumable" or not isinstance(c.location, LocalLocation):
                continue
            root = c.location.root
            if c.existed:  # the user's folder: only the manifest this run added goes, if it added nothing else
                with contextlib.suppress(OSError):
                    if not c.had_manifest and c.before is not None and tuple(_listing(root)) == c.before:
                        (root / MANIFEST_NAME).unlink(missing_ok=True)
                continue
            with contextlib.suppress(OSError):
                if _listing(root) == [DERIVED_CACHE] and (root / DERIVED_CACHE).is_dir():
                    # the folder is this run's, so is the cache of derived data it began (a run that could not
                    # read its dataset left it behind)
                    shutil.rmtree(root / DERIVED_CACHE)
                if not _listing(root):
                    for sub in [MANIFEST_NAME]:
                        with contextlib.suppress(FileNotFoundError):
                            (root / sub).unlink()
                    root.rmdir()

    def check_files_in(self, folder, names: Sequence[str]) -> None:
        """Refuse when a file of ``names`` in resumable ``folder`` that its manifest lists as this kind's was edited
        since (the run would write it again: ``train``'s model.pt, train.json, loss.png ...).  Files the manifest
        does not list (runs made before it recorded them) are the run's by the folder's mark."""
        files = read_manifest(folder)["files"]
        for n in names:
            e, q = files.get(n), Path(folder) / n
            st = _stat(q)
            if e is not None and e.get("kind") == self.kind and st is not None and not _unchanged(e, st):
                raise OutputRefused(
                    f"changed since {self._cmd} wrote it, and this run would write it again; segadeform never "
                    "overwrites such a file",
                    path=q,
                    expected="the run's own file (move yours out of the run folder to go on)",
                    got="a file edited since",
                )

    def record_files_in(self, folder, names: Sequence[str]) -> list[Path]:
        """After a run: list the files of ``names`` now in resumable ``folder`` in its manifest as this kind's (what
        :meth:`check_files_in` holds the next run to).  Returns the files recorded."""
        add, out = {}, []
        for n in names:
            q = Path(folder) / n
            st = _stat(q)
            if st is not None and os.path.isfile(q):
                add[n] = _entry(self.kind, st)
                out.append(q)
        if add:
            _update_manifest(Path(folder), add)
        return out

    # -- before the commit, and after ----------------------------------------------------------------------------
    def recheck(self) -> None:
        """Check every file and folder claim again (just before committing: something may have appeared)."""
        for c in self.claims:
            if c.what == "file":
                self._check_file(c.path)
            elif c.what == "folder" and not (c.existed and c.snapshot):
                self._check_folder(c.path, c.names)

    def record(self) -> list[Path]:
        """After a successful commit: list what was written in the manifests, and remove the files an earlier run
        of this kind wrote into a claimed folder that this run did not write again.  Returns the files recorded."""
        out: list[Path] = []
        for c in self.claims:
            if c.what == "file":
                st = _stat(c.path)
                if st is not None and os.path.isfile(c.path):
                    _update_manifest(c.path.parent, {c.path.name: _entry(self.kind, st)})
                    out.append(c.path)
            elif c.what == "folder" and c.path.is_dir():
                out.extend(self._record_folder(c))
        return out

    def _record_folder(self, c: _Claim) -> list[Path]:
        p = c.path
        with _locked(p):
            files = read_manifest(p)["files"]
            add, drop, stale = {}, [], []
            for n in _listing(p):
                q = p / n
                s = _stat(q)
                if s is None or not os.path.isfile(q):
                    continue
                before = c.snapshot.get(n)
                if before is None or before != (s.st_size, s.st_mtime_ns, s.st_ino):
                    add[n] = _entry(self.kind, s)  # written by this run
                    continue
                e = files.get(n)
                if e is not None and e["kind"] == self.kind:
                    if _unchanged(e, s) and self._input_at(q) is None:
                        stale.append(n)  # an earlier run's, not written again: replaced means removed
                    else:
                        drop.append(n)  # edited since: no longer ours, kept
            for n in stale:
                with contextlib.suppress(FileNotFoundError):
                    (p / n).unlink()
            drop.extend(stale)
            drop.extend(n for n in files if not (p / n).exists())
        _update_manifest(p, add, drop)
        return [p / n for n in sorted(add)]

    @contextlib.contextmanager
    def writing(self) -> Iterator[OutputGuard]:
        """``with guard.writing():`` -- :meth:`record` when the block succeeds (what it claimed and wrote)."""
        yield self
        self.record()


#: kinds shared by several commands, as messages name them
_KIND_LABELS = {"package": "segadeform export/repack/quantize/export-body"}


def _label(kind: str) -> str:
    return _KIND_LABELS.get(kind, f"segadeform {kind}")


def _is_url(p) -> bool:
    return isinstance(p, str) and "://" in p and not p.startswith("/")
