"""Simulation settings: materials, solver quality and the effects a scene asks for (no Blender, no torch;
:func:`segadeform.physics.blender.blender_settings` turns them into Blender's own).

A scene's ``[simulate]`` table names the effects to simulate; every effect it
does not name is off in the solver::

    [simulate]
    effects = ["gravity", "body_collision", "bending", "air_damping", "pinning"]
    material = "cotton"            # cotton | silk | denim | jersey | leather (MATERIALS)
    quality = 10                   # solver steps per frame (5 left edges snagged 100 %+ in tests)
    collision_quality = 2          # collision passes per step
    collision_distance = 0.005     # metres kept between cloth and body
    impulse_clamp = 0.0            # metres: Blender drops (does not shorten) a collision response larger
                                   # than this; 0: none is dropped
    max_step_motion = 0.0          # metres the body may move in one solver step: a clip where it moves
                                   # farther in a frame gets more steps (quality raised, at most 80); 0: off
    self_collision_distance = 0.005
    pin = "waistband"              # which vertices "pinning" holds: waistband, top or top+waist (PIN_GROUPS)
    wind = [0.0, 0.0, 1.0]         # direction of the "wind" effect (y-up, like the garment)
    wind_strength = 2.0
    drape_seconds = 0.5            # settle in the rest pose before the motion
    blend_seconds = 0.5            # blend from the rest pose into the motion's first frame
    collision_inner = 0.02         # the collider's inner thickness (Blender's thickness_inner): Blender reads
                                   # it for soft bodies only, cloth frames do not change with it (measured)
    collision_normals = false      # push cloth out along the body's normals (Blender's "override normals";
                                   # its "single sided" is on either way): cloth that got inside comes out
                                   # the side it came in from, not the nearest side
    untangle_body = false          # the collider is the posed body with the parts that pass into each
                                   # other (arm into torso, thigh into thigh) moved apart, room for cloth
                                   # between them (segadeform.body.untangle); the gate measures the true body;
                                   # kept no more samples in docs/simulator-gate.md's third study
    rest_pose = "t"                # t: the cloth's rest is the garment as given (T-pose); a: the garment
                                   # skinned to an A-pose (arms 45 deg down) is the cloth's rest and the
                                   # drape starts there -- T-posed garments are too short over the shoulders
                                   # for lowered arms, which tore tops (strain 2-4) in the T-pose rest

Effects (:data:`EFFECTS`):

``gravity``          scene gravity (9.81 m/s^2); off: the cloth floats in place
``body_collision``   the body is a collider and the cloth collides with it
``self_collision``   cloth-cloth contact (about 25 % more time in the trial)
``bending``          the material's bending stiffness; off: 0 (cloth folds freely)
``air_damping``      the material's air drag; off: 0
``pinning``          the ``pin`` group follows the body (skinned), e.g. a waistband
``wind``             a wind force field blowing along ``wind``

Stretch (tension, compression, shear) is the cloth itself and always on.

Arms down squeeze cloth: with the arms at the sides an arm is a few millimetres
from the torso (and a forearm from the hips), too little room for cloth kept
``collision_distance`` from both, and Blender resolves the squeeze by shooting
vertices through to the other side of the arm (edges stretched 200-400 %,
measured on a T-shirt under a CMU walk).  What made sleeves pass the gate
there (``samples/datasets/kinds.toml``): ``rest_pose = "a"`` with the garment
made in the A-pose (``make_garment(..., cloth_pose=A_POSE)``), a 2 mm
``collision_distance``, ``impulse_clamp = 0.02`` and a 1 s blend.  Blender
does not shorten a response past the clamp, it drops it (``collision.cc``,
``cloth_collision_impulse_vert``: an impulse longer than the clamp is not
applied), so the clamp stops cloth squeezed between two body parts from being
shot through, and 0.01 left 2 % of vertices inside the body, 0.005 up to 29 %.
The same rule drops the responses a fast limb needs: a thigh moving 3-4 cm per
step in a run goes through a skirt.  ``max_step_motion`` gives such a clip more
steps per frame (each step's motion, and so its responses, smaller) instead of
raising the clamp, which shoots squeezed cloth through again (issue #27,
``docs/simulator-gate.md``).

Why a drape and a blend: garments are modelled in the rest pose, without
gravity; the drape lets the cloth settle on the body before anything moves,
and the blend (joint rotations slerped from the rest pose to the motion's
first frame, translation interpolated) avoids the first-frame jump that would
otherwise shoot the cloth through the body.  Both are simulated and not
recorded; 0.5 s each settles a skirt in the trial to under 1 mm/frame.
"""

from __future__ import annotations

import dataclasses

from ..errors import FileFormatError, InputError
from ..io.toml import key_line, read_table
from .effects import parse_effect_list

__all__ = [
    "EFFECTS",
    "DEFAULT_EFFECTS",
    "MATERIALS",
    "PIN_GROUPS",
    "Material",
    "SimSettings",
    "parse_simulate_table",
    "parse_sim_effects",
]

EFFECTS = ("gravity", "body_collision", "self_collision", "bending", "air_damping", "pinning", "wind")
#: what a scene without a [simulate] table gets
DEFAULT_EFFECTS = ("gravity", "body_collision", "bending", "air_damping")
#: waistband: the highest boundary loop; top: the highest vertices; top+waist: those and a ring at the body's waist
PIN_GROUPS = ("waistband", "top", "top+waist")


@dataclasses.dataclass(frozen=True)
class Material:
    """Cloth material in Blender's cloth units (not SI; Blender's own presets where it has one).

    Attributes:
        mass: vertex mass (kg)
        tension / compression / shear / bending: spring stiffness
        tension_damping / compression_damping / shear_damping / bending_damping: spring damping
        air_damping: air drag
        friction: cloth-body friction; self_friction: cloth-cloth
    """

    mass: float
    tension: float
    compression: float
    shear: float
    bending: float
    tension_damping: float
    compression_damping: float
    shear_damping: float
    bending_damping: float
    air_damping: float
    friction: float = 5.0
    self_friction: float = 5.0


#: cotton, silk, denim and leather are Blender's presets; jersey (knit) is ours: light, soft, stretchy
MATERIALS = {
    "cotton": Material(0.3, 15, 15, 15, 0.5, 5, 5, 5, 0.5, 1.0),
    "silk": Material(0.15, 5, 5, 5, 0.05, 0, 0, 0, 0.5, 1.0),
    "denim": Material(1.0, 40, 40, 40, 10, 25, 25, 25, 0.5, 1.0),
    "leather": Material(0.4, 80, 80, 80, 150, 25, 25, 25, 0.5, 1.0),
    "jersey": Material(0.2, 8, 8, 6, 0.2, 3, 3, 3, 0.5, 1.0),
}


#: the most solver steps per frame (Blender's ``quality``) a simulation may ask for
MAX_QUALITY = 80


@dataclasses.dataclass(frozen=True)
class SimSettings:
    """Everything one simulation needs besides the inputs."""

    effects: tuple = DEFAULT_EFFECTS
    material: str = "cotton"
    quality: int = 10
    collision_quality: int = 2
    collision_distance: float = 0.005
    self_collision_distance: float = 0.005
    pin: str = "waistband"
    pin_stiffness: float = 1.0
    wind: tuple = (0.0, 0.0, 1.0)
    wind_strength: float = 2.0
    drape_seconds: float = 0.5
    blend_seconds: float = 0.5
    rest_pose: str = "t"
    impulse_clamp: float = 0.0
    collision_inner: float = 0.02
    collision_normals: bool = False
    max_step_motion: float = 0.0
    untangle_body: bool = False

    def __post_init__(self):
        eff = tuple(self.effects)
        bad = [e for e in eff if e not in EFFECTS]
        if bad:
            raise InputError("unknown simulation effect", expected=" | ".join(EFFECTS), got=bad[0])
        if len(set(eff)) != len(eff):
            raise InputError("an effect is named twice", got=list(eff))
        object.__setattr__(self, "effects", tuple(e for e in EFFECTS if e in eff))  # canonical order
        if self.material not in MATERIALS:
            raise InputError("unknown material", expected=" | ".join(MATERIALS), got=self.material)
        if self.pin not in PIN_GROUPS:
            raise InputError("unknown pin group", expected=" | ".join(PIN_GROUPS), got=self.pin)
        for name, lo, hi in (("quality", 1, MAX_QUALITY), ("collision_quality", 1, 20)):
            v = getattr(self, name)
            if not isinstance(v, int) or isinstance(v, bool) or not lo <= v <= hi:
                raise InputError(f"{name} must be an integer in {lo}..{hi}", got=v)
        for name, lo, hi in (
            ("collision_distance", 1e-4, 0.1),
            ("self_collision_distance", 1e-4, 0.1),
            ("pin_stiffness", 0.0, 50.0),
            ("wind_strength", 0.0, 100.0),
            ("drape_seconds", 0.0, 10.0),
            ("blend_seconds", 0.0, 10.0),
            ("impulse_clamp", 0.0, 1.0),
            ("collision_inner", 1e-3, 1.0),
            ("max_step_motion", 0.0, 1.0),
        ):
            v = getattr(self, name)
            if not (isinstance(v, (int, float)) and not isinstance(v, bool) and lo <= v <= hi):
                raise InputError(f"{name} must be a number in {lo}..{hi}", got=v)
        for name in ("collision_normals", "untangle_body"):
            if not isinstance(getattr(self, name), bool):
                raise InputError(f"{name} must be true or false", got=getattr(self, name))
        if self.rest_pose not in ("t", "a"):
            raise InputError(
                "rest_pose must be 't' (the garment's own T-pose) or 'a' (arms lowered)", got=self.rest_pose
            )
        w = tuple(float(x) for x in self.wind)
        if len(w) != 3 or sum(x * x for x in w) < 1e-12:
            raise InputError("wind must be a non-zero 3-vector", got=self.wind)
        object.__setattr__(self, "wind", w)

    def has(self, effect: str) -> bool:
        if effect not in EFFECTS:
            raise InputError("unknown simulation effect", expected=" | ".join(EFFECTS), got=effect)
        return effect in self.effects

    def replace(self, **kw) -> SimSettings:
        return dataclasses.replace(self, **kw)

    def to_dict(self) -> dict:
        """The settings as plain data; the collider settings added later (:data:`_LATER_DEFAULTS`) only when
        they differ from their defaults, so the digests of datasets made before them do not change."""
        d = dataclasses.asdict(self)
        d["effects"], d["wind"] = list(self.effects), list(self.wind)
        for k, v in _LATER_DEFAULTS.items():
            if d[k] == v:
                del d[k]
        return d


#: settings added after datasets were made with this module: left out of ``to_dict`` at these values
_LATER_DEFAULTS = {
    "collision_inner": 0.02,
    "collision_normals": False,
    "max_step_motion": 0.0,
    "untangle_body": False,
}


#: ``[simulate]`` knobs that only an effect uses: set with that effect off, they are refused
KNOB_EFFECT = {
    "wind": "wind",
    "wind_strength": "wind",
    "pin": "pinning",
    "pin_stiffness": "pinning",
    "self_collision_distance": "self_collision",
    "collision_distance": "body_collision",
    "max_step_motion": "body_collision",
    "untangle_body": "body_collision",
}


def parse_simulate_table(table: dict | None, *, where=None, effects: str | None = None) -> SimSettings:
    """``[simulate]`` (a dict from TOML, or None when the scene has none) -> :class:`SimSettings`.

    ``effects``: ``simulate --effects`` (changes to the table's effects, :func:`parse_sim_effects`): a knob of an effect
    is refused when the effect is off both in the table and after that change (a scene may keep wind's knobs for
    ``--effects=+wind``, and for ``--effects=-wind``, which ignores them).  The settings returned keep the table's own
    effects."""
    if table is None:
        return SimSettings()
    read_table(table, SimSettings, where="simulate", path=where)  # keys and types: the fields of SimSettings
    if "effects" not in table:
        raise FileFormatError(
            "[simulate] must name its effects",
            path=where,
            expected=f"effects = [...] from {', '.join(EFFECTS)} (an empty list is allowed)",
        )
    kw = dict(table)
    if not all(isinstance(e, str) for e in kw["effects"]):
        raise FileFormatError("simulate.effects must be a list of names", path=where, got=kw["effects"])
    kw["effects"] = tuple(kw["effects"])
    for k in (
        "collision_distance",
        "self_collision_distance",
        "pin_stiffness",
        "wind_strength",
        "drape_seconds",
        "blend_seconds",
        "impulse_clamp",
        "collision_inner",
        "max_step_motion",
    ):
        if k in kw:
            kw[k] = float(kw[k])
    try:
        st = SimSettings(**kw)
    except InputError as e:
        line = None  # the refused key's line (each tried alone; a user's trial: only the file was named)
        for k, v in kw.items():
            try:
                SimSettings(**{k: v})
            except InputError:
                line = key_line(where, "simulate", k) if where is not None else None
                break
        if line is None and where is not None:
            line = key_line(where, "simulate")
        raise FileFormatError(f"[simulate]: {e}", path=where, line=line) from None
    on = parse_sim_effects(effects, kw["effects"]) if effects is not None else kw["effects"]  # what will run
    for k, effect in KNOB_EFFECT.items():  # a knob of an effect that is off would do nothing: said, as [effects]
        if k in kw and effect not in on and effect not in kw["effects"]:  # as the cloth stage's knobs (a scene
            # author's trial); a knob of an effect the command line turns off is kept, ignored (--effects=-wind)
            raise FileFormatError(
                f"[simulate] sets {k} but the effect {effect} is off",
                path=where,
                line=key_line(where, "simulate", k) if where is not None else None,
                expected=f"{effect!r} in effects (or --effects=+{effect}), or no {k}",
            )
    return st


def parse_sim_effects(text: str, base=DEFAULT_EFFECTS) -> tuple:
    """``simulate --effects``: the same rule as ``run --effects`` (:mod:`segadeform.settings.effects`).

    Every item unsigned (``"gravity,body_collision"``) is a complete list: exactly these are on, the rest
    off (``"none"``: no effect); every item signed (``"+wind,-bending"``) changes ``base`` (the scene's
    ``[simulate]`` effects, or :data:`DEFAULT_EFFECTS` for a scene without that table).  Returns the
    effects on, in :data:`EFFECTS` order.
    """
    return parse_effect_list(text, EFFECTS, base).on
