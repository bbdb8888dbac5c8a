"""The one rule for effect lists on the command line (``run --effects``, ``simulate --effects``).

* every item unsigned (``dqs,collisions``, ``gravity,body_collision``): a complete list -- exactly these
  are on, what is not named is off; ``none`` alone is the empty list;
* every item signed (``-wrinkles,+collisions``, ``+wind,-bending``): changes to the set the command
  starts from (the scene's, or the documented default);
* a list that mixes both forms is an error.

Items that are choices rather than on/off effects (the runtime's skinning, ``lbs``/``dqs``) may join
either form; the caller names them as ``choices`` and gets them back in order.
"""

from __future__ import annotations

import dataclasses
from typing import Iterable, Sequence

from .errors import FileFormatError

__all__ = ["EffectList", "parse_effect_list"]


@dataclasses.dataclass(frozen=True)
class EffectList:
    """What an effect list says.

    Attributes:
        on: the effects on after applying it, in ``names`` order.
        choices: the choice items it gave (e.g. ``("dqs",)``), in order.
        complete: True for a complete list, False for signed changes.
    """

    on: tuple
    choices: tuple
    complete: bool


def parse_effect_list(text: str, names: Sequence[str], base: Iterable[str] = (), *,
                      choices: Sequence[str] = ()) -> EffectList:
    """Apply ``text`` (see the module docstring) to ``base``, the effects on before it.

    Args:
        names: every on/off effect, in canonical order.
        base: the effects on before ``text`` (used by signed changes only).
        choices: items that are not on/off effects (e.g. ``lbs``, ``dqs``), allowed in either form.
    """
    items = [t.strip() for t in str(text).split(",") if t.strip()]
    if items == ["none"]:
        return EffectList((), (), True)
    picked = tuple(i for i in items if i in choices)
    named = [i for i in items if i not in choices]
    signed = [i[:1] in ("+", "-") for i in named]
    if named and any(signed) and not all(signed):
        raise FileFormatError("effects mix a complete list with changes", got=text,
                              expected="either names only (a complete list: the rest off) or signed changes "
                                       "only (-name,+name)")
    complete = not any(signed)
    on = set() if complete else set(base)
    for item in named:
        name = item.lstrip("+-")
        if name not in names:
            form = " | ".join(list(choices) + [f"[+-]{n}" for n in names] + ["none"])
            raise FileFormatError("unknown effect", expected=form, got=item)
        if item.startswith("-"):
            on.discard(name)
        else:
            on.add(name)
    return EffectList(tuple(n for n in names if n in on), picked, complete)
