"""The runtime's effects (:class:`Effects`, a scene's ``[effects]`` table) and the one rule for effect lists on the
command line (``run --effects``, ``simulate --effects``).

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
import logging
from collections.abc import Iterable, Sequence

import numpy as np

from ..errors import FileFormatError, InputError
from .cloth import ClothSettings

log = logging.getLogger(__name__)

__all__ = ["Effects", "DEFAULT_EFFECTS", "EFFECT_NAMES", "parse_effects", "EffectList", "parse_effect_list"]


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


def parse_effect_list(
    text: str, names: Sequence[str], base: Iterable[str] = (), *, choices: Sequence[str] = ()
) -> EffectList:
    """Apply ``text`` (see the module docstring) to ``base``, the effects on before it.

    Args:
        names: every on/off effect, in canonical order.
        base: the effects on before ``text`` (used by signed changes only).
        choices: items that are not on/off effects (e.g. ``lbs``, ``dqs``), allowed in either form.
    """
    items = [t.strip() for t in str(text).split(",") if t.strip()]
    if not items:  # "" kept the scene's effects, " , " turned every one off, simulate's "" too (a scene's trial)
        raise FileFormatError(
            "an empty effects list",
            expected="effect names (a complete list), signed changes (+name,-name), or none (every effect off)",
            got=repr(str(text)),
        )
    if items == ["none"]:
        return EffectList((), (), True)
    picked = tuple(i for i in items if i in choices)
    named = [i for i in items if i not in choices]
    signed = [i[:1] in ("+", "-") for i in named]
    if named and any(signed) and not all(signed):
        raise FileFormatError(
            "effects mix a complete list with changes",
            got=text,
            expected="either names only (a complete list: the rest off) or signed changes only (-name,+name)",
        )
    complete = not any(signed)
    if len(set(picked)) > 1:  # as the Node and C++ runtimes refuse it (the last one won here, silently)
        raise FileFormatError("name one skinning", expected=" or ".join(choices), got=text)
    if len(picked) > 1:  # "dqs,dqs" went unsaid (a user's trial), as a repeated effect does not
        raise FileFormatError(f"effects name {picked[0]} twice", expected="each effect once", got=text)
    stripped = [i.lstrip("+-") for i in named]
    twice = sorted({n for n in stripped if stripped.count(n) > 1})
    if twice:  # "+wrinkles,-wrinkles": which one is meant?
        raise FileFormatError(f"effects name {twice[0]} twice", expected="each effect once", got=text)
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


@dataclasses.dataclass(frozen=True)
class Effects:
    """Which stages run.  See the module docstring for their meaning."""

    skinning: str = "lbs"
    dynamics: bool = True
    wrinkles: bool = True
    collisions: bool = True
    collision_margin: float = 0.004
    #: the cloth stage after the deformer (off unless named) and its knobs
    cloth: bool = False
    cloth_settings: ClothSettings = ClothSettings()

    def __post_init__(self):
        # InputError (a ValueError): a library user's trial found "0.004" a TypeError and cloth="no" taken as on
        if self.skinning not in ("lbs", "dqs"):
            raise InputError("skinning must be 'lbs' or 'dqs'", expected="lbs | dqs", got=repr(self.skinning))
        for name in ("dynamics", "wrinkles", "collisions", "cloth"):
            v = getattr(self, name)
            if not isinstance(v, (bool, np.bool_)):
                raise InputError(f"{name} must be True or False", expected="a bool", got=repr(v))
            object.__setattr__(self, name, bool(v))
        m = self.collision_margin
        if isinstance(m, bool) or not isinstance(m, (int, float, np.integer, np.floating)) or not 0 <= m < 1:
            raise InputError("collision_margin must be in [0, 1) metres", expected="0 <= metres < 1", got=repr(m))
        object.__setattr__(self, "collision_margin", float(m))
        if not isinstance(self.cloth_settings, ClothSettings):
            raise InputError(
                "cloth_settings must be a ClothSettings", expected="ClothSettings(...)", got=type(self.cloth_settings)
            )

    def label(self) -> str:
        """What runs: ``lbs+dynamics+collisions``; with the cloth stage, whose contact replaces the push-out,
        ``collisions`` is not named apart (a scene's trial: ``lbs+collisions+cloth`` and ``lbs+cloth`` ran alike)."""
        names = ("dynamics", "wrinkles", "cloth") if self.cloth else ("dynamics", "wrinkles", "collisions")
        on = [self.skinning] + [n for n in names if getattr(self, n)]
        return "+".join(on) + (f"({self.cloth_settings.label()})" if self.cloth and self.cloth_settings.label() else "")

    def off(self) -> list[str]:
        """The effects this set leaves off (the cloth stage, off unless named, is not listed; nor collisions when
        it runs: its contact is the stage's)."""
        return [
            n
            for n in ("dynamics", "wrinkles", "collisions")
            if not getattr(self, n) and not (n == "collisions" and self.cloth)
        ]


#: the effects of a scene without an ``[effects]`` table (and of the command line's flag form)
DEFAULT_EFFECTS = Effects()
EFFECT_NAMES = ("dynamics", "wrinkles", "collisions", "cloth")


def parse_effects(text: str, base: Effects = DEFAULT_EFFECTS, *, warn: bool = True) -> Effects:
    """Parse a CLI effects list (the rule of this module's :func:`parse_effect_list`, shared with
    ``simulate --effects``).

    * every item unsigned (``"dqs,collisions"``): exactly these -- what is not named is off, the
      skinning is the one named (lbs if none); ``none`` alone: LBS skinning alone, every on/off effect off;
    * every item signed (``"-wrinkles,+collisions"``, ``"dqs,-wrinkles"``: ``lbs``/``dqs`` may join
      either form): ``base`` with those effects switched on or off.

    ``collision_margin`` and the cloth stage's knobs are kept from ``base`` in both forms.  ``warn``: say a change
    that does nothing (``-collisions`` with the cloth stage on; a caller that parses the same text again says it
    there).
    """
    lst = parse_effect_list(text, EFFECT_NAMES, [n for n in EFFECT_NAMES if getattr(base, n)], choices=("lbs", "dqs"))
    skinning = lst.choices[-1] if lst.choices else ("lbs" if lst.complete else base.skinning)
    out = dataclasses.replace(base, skinning=skinning, **{n: n in lst.on for n in EFFECT_NAMES})
    if warn and out.cloth and not out.collisions and "-collisions" in [t.strip() for t in str(text).split(",")]:
        # (a user's trial: "+cloth,-collisions" ran as "+cloth", unsaid)
        log.warning(
            "effects %s: -collisions changes nothing while the cloth stage runs (its contact replaces the push-out)",
            text,
        )
    return out
