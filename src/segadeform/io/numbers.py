"""Numbers in text files (OBJ, OFF, MakeHuman ``.mhclo``, BVH, ASF/AMC), read as the file formats write them.

Python's ``float`` and ``int`` take more than a file format's number: digit separators (``0.15_9`` is 0.159),
digits of any script (``"١٢"`` is 12) and white space around the token.  No exporter writes them, C's ``strtod``
and JavaScript's ``Number`` refuse them, and a reader that takes them reads a corrupted file as another mesh (a
fuzzer's trial: an OBJ vertex ``0.15_9`` was read as 0.159).  :func:`number` and :func:`integer` are ``float`` and
``int`` on ASCII tokens without ``_`` and raise ``ValueError`` on the rest, as ``float`` does, so a reader's
``except ValueError`` names the file, the line and the token.  ``nan``, ``inf`` and ``infinity`` are still read:
every reader refuses them with its own words ("not finite").
"""

from __future__ import annotations

__all__ = ["number", "integer", "is_number"]


def number(token: str) -> float:
    """``float(token)`` for a number as a text file writes it (``-1.5``, ``2e-3``, ``.5``, ``nan``).

    Raises:
        ValueError: anything else, ``1_000``, non-ASCII digits and padded tokens too.
    """
    if "_" in token or not token.isascii() or token != token.strip():  # (inline: called per token of big files)
        raise ValueError(f"not a plain number: {token!r}")
    return float(token)


def integer(token: str) -> int:
    """``int(token)`` for an integer as a text file writes it (``12``, ``-3``, ``+4``).

    Raises:
        ValueError: anything else, ``1_000``, non-ASCII digits and padded tokens too.
    """
    if "_" in token or not token.isascii() or token != token.strip():
        raise ValueError(f"not a plain integer: {token!r}")
    return int(token)


def is_number(token: str) -> bool:
    """Whether :func:`number` reads ``token`` (a reader's search for the token that broke a bulk conversion)."""
    try:
        number(token)
    except ValueError:
        return False
    return True
