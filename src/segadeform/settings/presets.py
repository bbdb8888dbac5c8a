"""Quality presets: ``segadeform run --quality fast|balanced|best``.

Each preset is a point on the accuracy/time frontier measured by ``bench/tradeoffs.py`` on the
held-out split of ``samples/datasets/continuum.toml`` with the shipped model
(``docs/accuracy-vs-time.md``, section "Presets", records each preset's error and frames per second;
the bench measures every preset in the same run as the other knobs).  A preset sets the effects and
the collision margin only; ``--batch``, ``--threads`` and ``--model`` stay separate options.

How presets meet other effect settings (``segadeform run``):

* ``--quality`` replaces a scene's ``[effects]`` table (the command line wins over the file), but for the cloth
  stage's knobs (``cloth_iterations`` ...): when the scene and the preset both run the stage, the scene's knobs are
  kept (a user tuned them; the preset's measured error is at the defaults); ``--cloth K=V`` applies on top;
* ``--effects`` with signed changes only (``+collisions``, ``-dynamics``; ``lbs``/``dqs`` may join
  them) applies on top of the preset;
* ``--effects`` with a complete list (``dqs,collisions``) names every effect itself, so giving it with
  ``--quality`` is an error (:func:`preset_effects` raises, the command exits with a usage error).
"""

from __future__ import annotations

import dataclasses

from ..errors import InputError
from .effects import Effects, parse_effects

__all__ = ["Preset", "QUALITY_PRESETS", "preset_effects", "is_change_list"]


@dataclasses.dataclass(frozen=True)
class Preset:
    """A named point of the frontier: the effects it runs and why it was picked."""

    effects: Effects
    why: str


#: name -> preset, fastest first.  Measured figures: docs/accuracy-vs-time.md ("Presets").  All three are
#: points of the shipped model's measured frontier on the held-out split of samples/datasets/continuum.toml
#: (a product setting read off that table, not a model choice).  With the model shipped in issue #27 the
#: temporal weights (dynamics) pay (all effects 4.272 cm, without dynamics 4.452 on the doc's 4 samples), and the
#: cloth stage after all effects is the lowest error there is (4.168-4.199 cm over 1-16 sweeps and stiffness 0.2-1,
#: against 4.265 with the push-out); its settings differ by about 0.03 cm, so best runs it at its defaults.  Three
#: other values of its knobs measured lower still on those 4 held-out samples (gravity 0: 4.154, damping 0.3: 4.161,
#: attachment 1 cm: 4.164, against 4.173 at the defaults); a default chosen there would be tuned on the test
#: split, so they stay rows of the table.  Fast and balanced are unchanged (the cheapest points without and with
#: the collision stage).  A new model should run the bench again and revise this table.
QUALITY_PRESETS = {
    "fast": Preset(
        Effects(dynamics=False, wrinkles=False, collisions=False),
        "the fastest frontier point of the full-resolution garment: skinning weights from the current "
        "pose, no blend shapes, no collision stage (a few % of the vertices stay more than 2 mm "
        "inside the body)",
    ),
    "balanced": Preset(
        Effects(dynamics=False, wrinkles=False, collisions=True, collision_margin=0.004),
        "the cheapest point with the collision stage: the fast preset plus the push-out at a 4 mm "
        "margin (what stays inside is cloth pinched where the body intersects itself, as the simulator leaves it)",
    ),
    "best": Preset(
        Effects(dynamics=True, wrinkles=True, collisions=True, collision_margin=0.004, cloth=True),
        "the lowest vertex error measured: every effect of the model (blend shapes and temporal "
        "weights) and the cloth stage at its defaults with contact at 4 mm (it replaces the push-out; "
        "--effects=-cloth gives the push-out back; about three times balanced's time)",
    ),
}


def is_change_list(text: str) -> bool:
    """Whether an ``--effects`` text holds signed changes only (``-wrinkles,+collisions``, ``dqs,-dynamics``)
    rather than a complete list (``dqs,collisions``; a skinning name alone is a complete list too)."""
    named = [t.strip() for t in text.split(",") if t.strip() and t.strip() not in ("lbs", "dqs")]
    return bool(named) and all(t[0] in "+-" for t in named)


def preset_effects(name: str, effects: str | None = None) -> Effects:
    """The effects of preset ``name``, with ``effects`` (signed changes only) applied on top."""
    if name not in QUALITY_PRESETS:
        raise InputError("unknown quality preset", expected=" | ".join(QUALITY_PRESETS), got=name)
    base = QUALITY_PRESETS[name].effects
    if not effects:
        return base
    if not is_change_list(effects):
        raise InputError(
            "a quality preset takes effect changes (+name/-name), not a complete effects list",
            expected="e.g. --quality fast --effects=+collisions",
            got=effects,
        )
    return parse_effects(effects, base)
