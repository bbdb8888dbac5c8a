"""TOML configuration files: reading one (:func:`read_toml`) and checking its tables against the dataclass that
describes them (:func:`read_table`), with errors that name the file and the key.

:func:`read_table` is the one rule for every table of every configuration file (scenes, jobs files, the
simulator's ``[simulate]``, dataset and training configs): each key must be a field of the dataclass, each value
of the field's type, within its range and among its choices; fields without a default are required.  A field's
type says which TOML values it takes:

========================  ===========================================================
field type                TOML value
========================  ===========================================================
``bool``                  a boolean
``int``                   an integer (a boolean is not a number)
``float``                 an integer or a float (not a boolean)
``str``, ``Path``         a string
``tuple``, ``list``       an array
``Optional[X]``, ``X|Y``  what X (or Y) takes
========================  ===========================================================

Field metadata (:func:`key`) adds what a type cannot say: ``types`` (the TOML values taken, replacing the
type's), ``range`` (``lo <= value <= hi``; NaN fails) and ``choices``.
"""

from __future__ import annotations

import dataclasses
import math
import re
import sys
import types
import typing
from pathlib import Path

from ..errors import FileFormatError, file_error

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover
    import tomli as tomllib

__all__ = ["read_toml", "read_table", "key", "toml_types", "config_path", "key_line"]


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


def config_path(text: str, *, path=None) -> Path:
    """A path as a configuration file gives it, ``~`` expanded (a relative one is the caller's to resolve);
    :class:`FileFormatError` naming the file ``path`` for a NUL character or a ``~`` that cannot be expanded."""
    if "\x00" in text:
        raise FileFormatError("path contains a NUL character", path=path, got=repr(text)[:60])
    try:
        return Path(text).expanduser()
    except RuntimeError:  # "~someone" for an unknown user, or no home directory (found by fuzzing)
        raise FileFormatError("cannot expand '~' in a path", path=path, got=text[:60]) from None


def key(
    default=dataclasses.MISSING,
    *,
    types: tuple | None = None,
    range: tuple | None = None,
    choices: tuple | None = None,
    default_factory=dataclasses.MISSING,
):
    """A dataclass field with what :func:`read_table` checks beyond its type (see the module docstring)."""
    meta = {k: v for k, v in (("types", types), ("range", range), ("choices", choices)) if v is not None}
    return dataclasses.field(default=default, default_factory=default_factory, metadata=meta)


_BY_TYPE = {
    bool: (bool,),
    int: (int,),
    float: (int, float),
    str: (str,),
    Path: (str,),
    tuple: (list,),
    list: (list,),
    dict: (dict,),
}


def toml_types(annotation) -> tuple:
    """The Python types of the TOML values a field of type ``annotation`` takes."""
    if annotation in _BY_TYPE:
        return _BY_TYPE[annotation]
    origin = typing.get_origin(annotation)
    if origin in (typing.Union, types.UnionType):
        out: tuple = ()
        for a in typing.get_args(annotation):
            if a is not type(None):
                out += tuple(t for t in toml_types(a) if t not in out)
        return out
    if origin in _BY_TYPE:
        return _BY_TYPE[origin]
    if annotation is typing.Any or annotation is object:
        return (object,)
    raise TypeError(f"read_table cannot read a field of type {annotation!r}: give it key(types=...)")


def _names(ts: tuple) -> str:
    return " or ".join(
        "float" if t is float else "list" if t is list else "table" if t is dict else t.__name__ for t in ts
    )


_HEADER = re.compile(r"^\s*\[\[?\s*([^\]]+?)\s*\]\]?\s*(#.*)?$")


def key_line(path, where: str, name: str | None = None) -> int | None:
    """The line (1-based) of table ``where`` in TOML file ``path`` -- ``garments[2]``: the third ``[[garments]]``
    -- or of key ``name`` in it, for errors that name ``FILE:LINE``; None where it cannot be found (a key set
    inline or by a dotted name, a path that is not a readable file)."""
    try:
        lines = Path(path).read_text(encoding="utf-8").splitlines()
    except (OSError, UnicodeDecodeError, TypeError, ValueError):
        return None
    m = re.fullmatch(r"(.+?)(?:\[(\d+)\])?", where)
    if m is None:
        return None
    table, index = m.group(1), None if m.group(2) is None else int(m.group(2))
    seen, inside = -1, False
    for i, line in enumerate(lines, 1):
        h = _HEADER.match(line)
        if h:
            if inside:  # the table ended without the key
                return None
            if h.group(1) == table:
                seen += 1
                if index is None or seen == index:
                    if name is None:
                        return i
                    inside = True
            continue
        if inside and re.match(rf"^\s*{re.escape(name or '')}\s*=", line):
            return i
    return None


def read_table(table, cls, *, where: str, path=None, skip: tuple = ()) -> dict:
    """Check ``table`` (a TOML table, as read) against the fields of dataclass ``cls`` and return it.

    Args:
        where: the table's name in errors (``motion``, ``garments[2]``, ``simulate``): keys are named
            ``where.key``.
        path: the file, named in every error.
        skip: fields of ``cls`` that the table may not hold (filled in by the caller).
    Raises:
        FileFormatError: "[where] must be a table", "unknown key where.k", "where.k has the wrong type",
        "where.k out of range", "where.k must be one of ...", "missing where.k" (expected X, got Y).
    """
    if not isinstance(table, dict):
        raise FileFormatError(f"[{where}] must be a table", path=path, got=type(table).__name__)
    hints = typing.get_type_hints(cls)
    fields = {f.name: f for f in dataclasses.fields(cls) if f.name not in skip and f.init}
    bad = sorted(set(table) - set(fields))

    def line(name):
        return None if path is None else key_line(path, where, name)

    if bad:
        raise FileFormatError(
            f"unknown key {where}.{bad[0]}",
            path=path,
            line=line(bad[0]),
            expected=", ".join(sorted(fields)),
            got=", ".join(bad),
        )
    for name, f in fields.items():
        if name not in table:
            if f.default is dataclasses.MISSING and f.default_factory is dataclasses.MISSING:
                raise FileFormatError(f"missing {where}.{name}", path=path)
            continue
        v = table[name]
        accepted = f.metadata.get("types") or toml_types(hints[name])
        if not isinstance(v, accepted) or (isinstance(v, bool) and bool not in accepted):
            raise FileFormatError(
                f"{where}.{name} has the wrong type",
                path=path,
                line=line(name),
                expected=_names(accepted),
                got=f"{type(v).__name__} {v!r}"[:60],
            )
        if "range" in f.metadata:
            lo, hi = f.metadata["range"]
            if not lo <= v <= hi or (isinstance(v, float) and math.isnan(v)):
                raise FileFormatError(
                    f"{where}.{name} out of range", path=path, line=line(name), expected=f"{lo}..{hi}", got=v
                )
        if "choices" in f.metadata and v not in f.metadata["choices"]:
            raise FileFormatError(
                f"{where}.{name} must be one of {', '.join(map(str, f.metadata['choices']))}",
                path=path,
                line=line(name),
                expected=" | ".join(map(str, f.metadata["choices"])),
                got=v,
            )
    return dict(table)
