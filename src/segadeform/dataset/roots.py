"""Several dataset roots read as one: dataset folders and read-only packs.

``dataset make``, ``train``, ``eval`` and ``regate`` take more than one root::

    segadeform train CONFIG -o RUN --dataset data/continuum --dataset ../shared/data/sim

A root is

* a dataset folder (``samples/``, ``rejected/``: what ``dataset make`` writes),
* a pack (``*.sgdpack``, :mod:`.pack`), or
* a folder of packs (every ``*.sgdpack`` in it, in name order), such as ``../shared/data/sim``.

Packs are only ever read.  A sample found in several roots must be the same sample (the same ``spec``
digest): the first root that holds it serves it; two roots that give one id different contents are an
error, and so are packs simulated on different bodies or by different simulators (their samples cannot
be trained on together).  Derived data -- garment precomputes, contact caches -- goes to
:attr:`DatasetRoots.cache_dir`: the first dataset folder's ``cache/`` (the writable root), else a
folder the caller names.
"""

from __future__ import annotations

import json
from collections.abc import Iterable, Sequence
from pathlib import Path

from ..errors import FileFormatError, InputError
from .pack import PACK_SUFFIX, Pack
from .store import SAMPLE_FOLDERS, Sample, load_sample

__all__ = ["DatasetRoots", "as_roots", "expand_root"]


def expand_root(path) -> list:
    """A root -> ``[Path]`` (a dataset folder) or ``[Pack, ...]`` (a pack, or every pack in a folder)."""
    p = Path(path)
    if p.is_file():
        return [Pack(p)]
    if not p.is_dir():
        raise InputError(
            "dataset root does not exist", path=p, expected="a dataset folder, a .sgdpack file or a folder of packs"
        )
    if (p / "samples").is_dir() or (p / "rejected").is_dir():
        return [p]
    packs = sorted(p.glob(f"*{PACK_SUFFIX}"))
    if packs:
        return [Pack(q) for q in packs]
    if not any(p.iterdir()):  # an empty folder: a dataset not begun yet, or a store with no packs yet
        return []
    raise InputError(
        "not a dataset root", path=p, expected="a dataset folder (samples/), a .sgdpack file or a folder of packs"
    )


class DatasetRoots:
    """Read-only view of several roots (see the module docstring).

    Args:
        roots: paths (folders, packs, folders of packs); the first dataset folder is the writable root.
        optional: paths read when they exist and skipped when they do not (e.g. ``../shared/data/sim``).
        cache_dir: where derived data goes when no root is a dataset folder.
    """

    def __init__(self, roots: Sequence, *, optional: Iterable = (), cache_dir=None) -> None:
        self.folders: list[Path] = []
        self.packs: list[Pack] = []
        self.skipped: list[Path] = []  # optional roots that did not exist
        self.given = [Path(r) for r in roots]  # as given (an empty folder is no root, but messages name it)
        order: list = []
        for r in roots:
            order.extend(expand_root(r))
        for r in optional:
            if Path(r).exists():
                order.extend(expand_root(r))
            else:
                self.skipped.append(Path(r))
        if not order and not roots and not self.skipped:
            raise InputError("no dataset root given")
        self._where: dict[tuple, object] = {}  # (folder name, id) -> Path | Pack
        self._spec: dict[str, tuple] = {}  # id -> (spec, source) of the serving root
        self._bodies: dict[str, object] = {}  # body sha256 -> the first root whose samples record it
        for src in order:
            if isinstance(src, Pack):
                self.packs.append(src)
                if src.body_sha256 and src.entries:  # (a pack of no samples claims nothing: a review)
                    self._bodies.setdefault(src.body_sha256, src)
                listing = ((e["folder"], sid, e.get("spec")) for sid, e in src.entries.items())
            else:
                self.folders.append(src)
                listing = (
                    (f, m.stem, None)
                    for f in SAMPLE_FOLDERS
                    for m in sorted((src / f).glob("*.json"))
                    if (src / f / f"{m.stem}.npz").is_file()
                )
            for folder, sid, spec in listing:
                if spec is None and not isinstance(src, Pack):
                    spec, body = _folder_record(src, folder, sid)
                    if body:
                        self._bodies.setdefault(body, src)
                prev = self._spec.get(sid)
                if prev is not None:
                    if prev[0] is not None and spec is not None and prev[0] != spec:
                        raise InputError(
                            f"sample {sid} differs between two dataset roots",
                            path=str(_name(src)),
                            expected=f"the sample of {_name(prev[1])} (spec {prev[0]})",
                            got=spec,
                        )
                    continue
                self._spec[sid] = (spec, src)
                self._where[(folder, sid)] = src
        self._check_compatible()
        first = self.folders[0] / "cache" if self.folders else None
        self.cache_dir: Path | None = first if first is not None else (Path(cache_dir) if cache_dir else None)
        if self.cache_dir is not None and self.cache_dir.exists() and not self.cache_dir.is_dir():
            # (it was "File exists" when the cache was first written: a researcher's trial)
            raise InputError(
                "is a file, where train and eval keep what they derive from the dataset (a folder)",
                path=self.cache_dir,
                expected="a folder named cache, or no file there",
                got="a file",
            )

    def _check_compatible(self) -> None:
        if len(self._bodies) > 1:  # packs by their heads, folders by their samples' records
            raise InputError(
                "these dataset roots were simulated on different bodies and cannot be mixed",
                path=", ".join(str(_name(r)) for r in self._bodies.values()),
                got=", ".join(f"body sha256 {b[:12]}" for b in self._bodies),
            )
        # a pack of no samples (written before `dataset pack` refused to) makes no claim about a simulator
        sims = {(p.simulator.get("blender"), p.simulator.get("bridge")) for p in self.packs if p.entries}
        if len(sims) > 1:
            raise InputError(
                "these packs were made by different simulators and cannot be mixed",
                path=", ".join(str(p.path) for p in self.packs),
                got="; ".join(f"Blender {b}, bridge {v}" for b, v in sorted(sims, key=str)),
            )

    def check_body(self, body) -> None:
        """Refuse a body other than the one the samples were simulated on (their recorded
        :func:`~segadeform.body.identity.body_sha256`; samples that record none are not checked): evaluating or
        training them against another body counts the wrong penetration and poses the wrong skin."""
        if not self._bodies:
            return
        from ..body.identity import body_label

        given = body_label(body)
        for h, src in self._bodies.items():
            if h != given["sha256"]:
                raise InputError(
                    "the dataset was simulated on another body than the one given (--body)",
                    path=str(_name(src)),
                    expected=f"the body of sha256 {h[:12]}",
                    got=f"{given['name'] or 'a body'} (sha256 {given['sha256'][:12]})",
                )

    # ------------------------------------------------------------------------------------------------
    @property
    def writable(self) -> Path | None:
        """The first dataset folder (where new samples and caches go), None when only packs were given."""
        return self.folders[0] if self.folders else None

    def ids(self, split: str | None = None, folder: str = "samples") -> list[str]:
        """Sorted ids of ``folder``'s samples (kept by default), optionally of one split."""
        out = []
        for f, sid in self._where:
            if f != folder:
                continue
            if split is None or self.meta(sid, folder).get("split") == split:
                out.append(sid)
        return sorted(out)

    def has(self, sid: str) -> bool:
        return any((f, sid) in self._where for f in SAMPLE_FOLDERS)

    def record(self, sid: str) -> tuple[dict | None, bool]:
        """The metadata of sample ``sid`` from the first of its folders (kept, then rejected) a root holds it in,
        and whether that is the kept samples' folder; (None, False) when no root holds it."""
        for f in SAMPLE_FOLDERS:
            if (f, sid) in self._where:
                return self.meta(sid, f), f == "samples"
        return None, False

    def spec(self, sid: str) -> str | None:
        """The ``spec`` digest the serving root records for sample ``sid`` (None when it records none)."""
        got = self._spec.get(sid)
        return None if got is None else got[0]

    def source(self, sid: str, folder: str = "samples"):
        src = self._where.get((folder, sid))
        if src is None:
            raise InputError(f"no dataset root holds sample {sid}", path=", ".join(str(_name(s)) for s in self.roots))
        return src

    @property
    def roots(self) -> list:
        return [*self.folders, *self.packs]

    def meta(self, sid: str, folder: str = "samples") -> dict:
        src = self.source(sid, folder)
        if isinstance(src, Pack):
            e = src.entries[sid]
            # the pack's index carries what selecting samples needs; the full metadata is read on demand
            return e if "split" in e and e.get("split") is not None else src.read_meta(sid)
        p = src / folder / f"{sid}.json"
        try:
            return json.loads(p.read_text())
        except (OSError, ValueError) as e:
            raise FileFormatError(f"sample metadata is unreadable ({e})", path=p) from None

    def load(self, sid: str, folder: str = "samples") -> Sample:
        src = self.source(sid, folder)
        return src.load(sid) if isinstance(src, Pack) else load_sample(src, sid, folder)

    def __repr__(self) -> str:
        return f"DatasetRoots({[str(_name(r)) for r in self.roots]})"

    def __str__(self) -> str:  # as messages name the roots: the paths given (an empty folder's too)
        return ", ".join(str(_name(r)) for r in self.roots) or ", ".join(str(r) for r in self.given)


def _name(src):
    return src.path if isinstance(src, Pack) else src


def _folder_record(root: Path, folder: str, sid: str) -> tuple[str | None, str | None]:
    """``(spec, body_sha256)`` a folder's sample records (None for what it does not)."""
    try:
        m = json.loads((root / folder / f"{sid}.json").read_text())
    except (OSError, ValueError):
        return None, None
    return (m.get("spec"), m.get("body_sha256")) if isinstance(m, dict) else (None, None)


def as_roots(dataset, *, cache_dir=None) -> DatasetRoots:
    """A :class:`DatasetRoots` from one path, a list of paths, or a ``DatasetRoots`` (returned as it is)."""
    if isinstance(dataset, DatasetRoots):
        return dataset
    if isinstance(dataset, (str, Path)):
        dataset = [dataset]
    return DatasetRoots(list(dataset), cache_dir=cache_dir)
