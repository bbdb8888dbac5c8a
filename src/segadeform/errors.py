"""Errors raised on bad input.

Every error the package raises for something a user supplied derives from
:class:`SegadeformError`; the CLI turns these into a one-line message and a
non-zero exit, never a traceback.  Messages follow one pattern::

    path/to/file.obj:12: face index out of range (expected 1..8 or -8..-1, got 9)
"""

from __future__ import annotations

import os
import re

__all__ = [
    "SegadeformError",
    "InputError",
    "FileFormatError",
    "SimulationError",
    "file_error",
    "check_readable",
    "unreadable_error",
]


class SegadeformError(Exception):
    """Base class of every error segadeform raises on purpose."""


class InputError(SegadeformError, ValueError):
    """An input (array, argument, file) does not meet its contract.

    Args:
        problem: what is wrong, in a few words.
        path: the file the input came from, if any.
        line: 1-based line number within ``path``, if it applies.
        expected / got: what was expected and what was found; both are
            appended as ``(expected X, got Y)``.
    """

    def __init__(
        self,
        problem: str,
        *,
        path: str | os.PathLike | None = None,
        line: int | None = None,
        expected: object | None = None,
        got: object | None = None,
    ) -> None:
        self.problem = problem
        self.path = None if path is None else os.fspath(path)
        self.line = line
        self.expected = expected
        self.got = got
        super().__init__(self._format())

    def _format(self) -> str:
        where = ""
        if self.path is not None:
            where = self.path + (f":{self.line}" if self.line is not None else "") + ": "
        elif self.line is not None:
            where = f"line {self.line}: "
        detail = ""
        if self.expected is not None or self.got is not None:
            parts = []
            if self.expected is not None:
                parts.append(f"expected {self.expected}")
            if self.got is not None:
                parts.append(f"got {self.got}")
            detail = " (" + ", ".join(parts) + ")"
        return f"{where}{self.problem}{detail}"

    def with_path(self, path: str | os.PathLike) -> InputError:
        """The same error, attributed to ``path`` (if it had no path yet)."""
        if self.path is not None:
            return self
        return type(self)(self.problem, path=path, line=self.line, expected=self.expected, got=self.got)


class FileFormatError(InputError):
    """A file is malformed: wrong magic, truncated, bad counts, bad indices."""


class SimulationError(SegadeformError):
    """The cloth simulator failed or is not installed; the message says which and how to fix it."""


def file_error(e: OSError, path, what: str = "file", *, cls: type = FileFormatError) -> FileFormatError:
    """The one wording for a file that cannot be opened: ``no such file``, ``is a directory, not a file``,
    ``permission denied``, else ``cannot read {what}: {reason}``.

    ``cls``: the error class (a :class:`FileFormatError` subclass, e.g. a model package's ``PackageError``).
    """
    if isinstance(e, FileNotFoundError):
        return cls("no such file", path=path)
    if isinstance(e, IsADirectoryError):
        return cls("is a directory, not a file", path=path)
    if isinstance(e, PermissionError):
        return cls("permission denied", path=path)
    return cls(f"cannot read {what}: {e.strerror or e}", path=path)


def check_readable(path, what: str = "file", *, cls: type = FileFormatError) -> None:
    """Raise :func:`file_error`'s error if ``path`` cannot be opened for reading (for readers whose library
    opens the file itself and words its own failures)."""
    try:
        with open(path, "rb"):
            pass
    except OSError as e:
        raise file_error(e, path, what, cls=cls) from None


def unreadable_error(e: BaseException, path, what: str, *, cls: type = FileFormatError) -> FileFormatError:
    """The one wording for a file that opens but whose contents a library cannot read:
    ``not a readable {what} file ({ExceptionType}: {message})``, on one line: a library's message of several lines
    is joined, and OpenUSD's ``Error in 'pxrInternal_...::UsdStage::Open' at line N in file ...: 'what'`` is cut to
    its ``what`` (a new user's trial: a bad .usd printed 2-4 lines of pxr internals)."""
    return cls(f"not a readable {what} file ({type(e).__name__}: {_library_message(e)})", path=path)


def _library_message(e: BaseException) -> str:
    """A library's message on one line: OpenUSD's ``Error in 'pxrInternal_...' at line N in file F : 'what'``
    reports (one or several) cut to their ``what``, a parser's template names (``matching pxrInternal_...pegtl::...``)
    dropped (a review: two reports ran into one line of pxr internals)."""
    msg = " ".join(str(e).split())
    reports = [r.strip().strip("'").strip() for r in re.split(r"Error in '[^']*' at line \d+ in file \S+ ?: ", msg)]
    reports = [re.sub(r" matching pxrInternal.*$", "", r) for r in reports if r]
    return "; ".join(reports) if reports else msg
