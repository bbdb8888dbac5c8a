"""The cloth stage's knobs (``[effects] cloth_*`` in a scene, ``segadeform run --cloth``, ``eval --cloth``).

The stage itself is :mod:`segadeform.body.cloth` (its kernel ``src/segadeform/body/_cloth.c`` says what each
knob does); this module is only the frozen settings, kept free of numpy so that scenes import it cheaply.

Text form (the command line): ``iterations=8,stiffness=0.5`` -- ``NAME=VALUE`` items, the rest as the base
settings (the scene's, else the defaults).
"""

from __future__ import annotations

import dataclasses
import math

from ..errors import InputError

__all__ = ["ClothSettings", "CLOTH_KNOBS"]

#: knob -> (type, lowest, highest, what it is)
CLOTH_KNOBS = {
    "iterations": (int, 1, 64, "constraint sweeps per frame"),
    "stiffness": (float, 0.0, 1.0, "how much of the stretch limit's correction a frame's sweeps apply"),
    "stretch": (float, 0.0, 1.0, "stretch limit: an edge stays under (1 + stretch) x its rest length"),
    "compress": (float, 0.0, 1.0, "and over (1 - compress) x its rest length"),
    "bending": (float, 0.0, 1.0, "how strongly a vertex's deviation from the network follows its neighbours'"),
    "damping": (float, 0.0, 1.0, "fraction of the velocity lost per frame"),
    "follow": (float, 0.0, 1.0, "fraction of the deviation from the network's frame removed per frame"),
    "gravity": (float, 0.0, 100.0, "m/s^2, along -y"),
    "attachment": (float, 0.0, 1.0, "metres: vertices this close to the body at rest follow the network exactly"),
    "max_distance": (float, 0.0, 1.0, "metres: the farthest a loose vertex may leave the network's frame"),
    "reset": (float, 1e-6, 1e3, "metres of mean garment motion in one frame that reset the stage (a teleport)"),
    "backstop": (
        float,
        0.0,
        1.0,
        "metres: a target deeper than this inside the body is traced out along the garment's normal (0: off)",
    ),
}


@dataclasses.dataclass(frozen=True)
class ClothSettings:
    """The cloth stage's knobs (see :data:`CLOTH_KNOBS`; ``_cloth.c`` for their use).  Defaults: the measured
    setting ``segadeform run --effects=+cloth`` uses.  ``compress`` 0.3 (0.03 until 2 Dec 2026): held to 97 % of their
    rest lengths, the edges the network compresses (a skirt gathered over a raised knee) stood out as stacked
    horizontal ridges in a technical artist's renders; at 0.3 the renders are smooth, and on the 26 held-out samples
    vertex error 4.995 -> 4.991 cm, normal error 23.516 -> 23.439 degrees, edge error 1.262 -> 1.312 mm, the same
    penetration and faces across a limb (``samples/models/default.train/eval/cloth_compress_test26.md``)."""

    iterations: int = 4
    stiffness: float = 1.0
    stretch: float = 0.03
    compress: float = 0.3
    bending: float = 0.9
    damping: float = 0.1
    follow: float = 0.5
    gravity: float = 9.81
    attachment: float = 0.02
    max_distance: float = 0.05
    reset: float = 0.25
    backstop: float = 0.03

    def __post_init__(self):
        for name, (typ, lo, hi, what) in CLOTH_KNOBS.items():
            v = getattr(self, name)
            ok = isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v) and lo <= v <= hi
            if typ is int:
                ok = ok and float(v) == int(v)
            if not ok:
                raise InputError(
                    f"cloth {name} must be {'an integer' if typ is int else 'a number'} in [{lo:g}, {hi:g}] ({what})",
                    got=repr(v),
                )
            object.__setattr__(self, name, typ(v))

    def label(self) -> str:
        """The knobs that differ from the defaults, as the text form (``""``: the defaults)."""
        d = ClothSettings.__new__(ClothSettings)  # the defaults without validating twice
        for f in dataclasses.fields(self):
            object.__setattr__(d, f.name, f.default)
        return ",".join(
            f"{f.name}={getattr(self, f.name):g}"
            for f in dataclasses.fields(self)
            if getattr(self, f.name) != getattr(d, f.name)
        )

    @classmethod
    def parse(cls, text: str, base: ClothSettings | None = None) -> ClothSettings:
        """``NAME=VALUE,...`` applied to ``base`` (the defaults when None).  Raises ValueError with
        "expected X, got Y"."""
        base = base if base is not None else cls()
        changes = {}
        for item in (t.strip() for t in str(text).split(",")):
            if not item:
                continue
            name, eq, value = item.partition("=")
            name = name.strip()
            if not eq or name not in CLOTH_KNOBS:
                raise ValueError(
                    f"unknown cloth setting (expected NAME=VALUE with NAME one of "
                    f"{', '.join(CLOTH_KNOBS)}, got {item!r})"
                )
            try:
                changes[name] = float(value)  # integers are checked and converted by __post_init__
            except ValueError:
                raise ValueError(f"cloth {name} must be a number (got {value.strip()!r})") from None
        return dataclasses.replace(base, **changes)
