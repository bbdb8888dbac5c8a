"""Fault injection for the executor tests: a location whose writer process dies at a chosen commit.

:class:`DyingLocation` is a local folder that ends its process (``os._exit``, as a killed worker:
no cleanup, no exception) the first time it is about to commit one of the paths in ``die_at`` --
after the temporary is written, before the rename.  Whether it died is recorded by a marker file per
path in ``markers``, made just before dying (only the first attempt dies), and every commit that
succeeds is appended to ``markers/journal.txt`` (one line, a single ``write`` with ``O_APPEND``).
"""

from __future__ import annotations

import contextlib
import os
from pathlib import Path

from segadeform.io.location import LocalLocation


class DyingLocation(LocalLocation):
    def __init__(self, root, markers, die_at=()) -> None:
        super().__init__(root)
        self.markers, self.die_at = Path(markers), frozenset(die_at)

    def _maybe_die(self, rel: str) -> None:
        if rel not in self.die_at:
            return
        self.markers.mkdir(parents=True, exist_ok=True)
        try:
            os.close(os.open(self.markers / (rel.replace("/", "_") + ".died"), os.O_CREAT | os.O_EXCL | os.O_WRONLY))
        except FileExistsError:
            return  # died once already: this attempt goes through
        os._exit(3)

    def _journal(self, rel: str) -> None:
        self.markers.mkdir(parents=True, exist_ok=True)
        fd = os.open(self.markers / "journal.txt", os.O_CREAT | os.O_APPEND | os.O_WRONLY)
        try:
            os.write(fd, f"{os.getpid()} {rel}\n".encode())
        finally:
            os.close(fd)

    @contextlib.contextmanager
    def writing(self, rel, *, once=False):
        with super().writing(rel, once=once) as tmp:
            yield tmp
            self._maybe_die(rel)  # the temporary is written; the rename has not happened
        self._journal(rel)

    def _commit_file(self, local, rel):
        self._maybe_die(rel)
        super()._commit_file(local, rel)
        self._journal(rel)

    def died(self) -> list[str]:
        return sorted(p.name for p in self.markers.glob("*.died")) if self.markers.is_dir() else []

    def commits(self) -> list[str]:
        j = self.markers / "journal.txt"
        return [line.split(" ", 1)[1] for line in j.read_text().splitlines()] if j.is_file() else []


def temporaries(root) -> list[str]:
    """Every temporary file or folder (``.NAME.tmp-*``) anywhere under ``root``."""
    return sorted(str(p.relative_to(root)) for p in Path(root).rglob("*") if ".tmp-" in p.name)
