"""Scenes: a TOML file naming a garment, a body, a motion, the output, and the effects to simulate.

Example (every key shown; only ``garment.mesh``, ``motion`` and ``output.path``
are required; relative paths are relative to the scene file)::

    [garment]
    mesh = "../garments/skirt.obj"

    [body]                         # optional; the shipped default body when absent
    model = "../bodies/default_body.npz"
    betas = [0.0, 0.5]             # up to the body's shape coefficients; the rest are 0

    [motion]                       # a file ...
    file = "../motions/walk.npz"   # .npz (AMASS-style), .bvh, .amc (CMU ASF/AMC), .glb/.gltf, .sgdm; .fbx (run only)
    # ... or a procedural kind:
    # kind = "walk"; seconds = 3.0; speed = 1.0; amplitude = 1.0; seed = 0
    fps = 30.0                     # resample the motion to this rate (default: the motion's own)
    frames = "0:90"                # optional frame range A:B of the (resampled) motion
    up = "auto"                    # the file's up axis: auto | y | z (AMASS is z-up)
    units = "cm"                   # BVH: metres per file unit or m|dm|cm|mm|inch|cmu (default: fit the legs)
    joint_map = "map.toml"         # BVH: SMPL name = "file joint name" for skeletons not recognised
    skeleton = "16.asf"            # AMC: its ASF skeleton (default: the one .asf beside the .amc)
    animation = "Walk"             # glTF (.glb/.gltf) or FBX: which animation (default: the first; FBX: the rig's own)
    floor = false                  # move the motion so the feet touch the floor
    repair_glitches = false        # motion capture: hold the first settled pose over the frames its solve
                                   # settles from, rebuild frames it jumps to and back from (faster than
                                   # 20 m/s); the frame count is kept (segadeform motion info lists them)

    [model]                        # optional; the shipped default model when absent
    package = "../models/default"
    resolution = 1.0               # share of the garment's vertices the model runs on (0 < R <= 1; run --resolution):
                                   # the garment decimated, its frames carried to every vertex of the file

    [output]
    path = "../../out/skirt.pc2"
    format = "pc2"                 # pc2 | obj-seq | xdmf | abc | usd (default: from the extension; abc and
                                   # usd need the 'alembic' and 'usd' extras)
    up = "y"                       # y (as computed; what Blender's Mesh Cache on an imported OBJ wants) | z
    units = "m"                    # m (as computed) | dm | cm (Maya, Unreal) | mm | inch | ft, or metres per unit;
                                   # USD records it (metersPerUnit), the other formats have no field for it
    body = "../../out/body.pc2"    # optional: the posed body too, in the format its extension names (no extension:
                                   # a folder of OBJ frames, or path's format when path has none either)

    [effects]                      # what is not named is off (skinning: lbs); no table: every effect on
    skinning = "lbs"               # lbs | dqs
    dynamics = true                # temporal weights from the motion window (off: current pose only)
    wrinkles = true                # the blend-shape decoder (off: B = 0)
    collisions = true              # push vertices out of the body (post-process)
    collision_margin = 0.004       # metres kept between garment and body skin
    cloth = false                  # the cloth stage (segadeform.body.cloth): stretch, contact, inertia; off
                                   # unless named; it resolves contact itself (at collision_margin)
    cloth_iterations = 4           # its knobs (segadeform.settings.cloth.CLOTH_KNOBS): cloth_stiffness,
                                   # cloth_stretch, cloth_compress, cloth_bending, cloth_damping, cloth_follow,
                                   # cloth_gravity, cloth_attachment, cloth_max_distance, cloth_reset,
                                   # cloth_backstop

    [simulate]                     # for `segadeform simulate` (ground truth); see segadeform.settings.simulation
    effects = ["gravity", "body_collision", "bending", "air_damping"]   # all others are off
    material = "cotton"

Unknown tables or keys are errors, as are wrong types and out-of-range values,
each naming the scene file and the key.

**Effects: what is not named is off.**  The ``[effects]`` table runs the
skinning it names (``lbs`` when it names none) and exactly the effects it sets
to true; ``[simulate]`` works the same way for the simulator.  A scene without
an ``[effects]`` table gets :data:`DEFAULT_EFFECTS`: LBS with dynamics,
wrinkles and collisions (the full model).  On the command line,
``--effects dqs,collisions`` is a complete list in the same sense, while
``--effects=-wrinkles`` or ``+collisions`` (every item signed) changes the
scene's set (:func:`parse_effects`).
"""

from __future__ import annotations

import dataclasses
import os
from pathlib import Path

from ..bounds import SEED_RANGE, check_betas
from ..errors import FileFormatError, InputError
from ..io.toml import config_path, key, key_line, read_table, read_toml
from ..io.writer import UP_AXES, Y_TO_Z, output_unit
from .cloth import CLOTH_KNOBS, ClothSettings
from .effects import DEFAULT_EFFECTS, EFFECT_NAMES, Effects, parse_effects
from .simulation import parse_simulate_table

__all__ = ["Y_TO_Z", "MotionSpec", "Scene", "check_motion_fps", "load_scene", "parse_frames"]


#: the frame rates a motion may be resampled to (``fps``: a scene's [motion] key, ``run --fps``)
FPS_RANGE = (1.0, 1000.0)


def check_motion_fps(fps, option: str | None = None) -> None:
    """A motion's frame rate inside :data:`FPS_RANGE` (NaN fails too); the error names ``option`` (``"--fps"``) when
    the value came from one."""
    lo, hi = FPS_RANGE
    if isinstance(fps, bool) or not isinstance(fps, (int, float)) or not lo <= fps <= hi:
        problem = "the motion's frame rate is out of range"
        raise InputError(f"{option}: {problem}" if option else problem, expected=f"{lo:g}..{hi:g} fps", got=fps)


@dataclasses.dataclass(frozen=True)
class MotionSpec:
    """A motion file or a procedural kind, with how to play it (a scene's ``[motion]``;
    :func:`segadeform.motion.build_motion` builds it).

    ``frames``: ``(A, B)`` of the (resampled) motion, B exclusive, or ``(A, None)`` for "to the end"; None: all.
    """

    file: Path | None = None
    kind: str | None = None
    seconds: float = 3.0
    speed: float = 1.0
    amplitude: float = 1.0
    seed: int = 0
    fps: float | None = None
    frames: tuple[int, int | None] | None = None
    up: str = "auto"
    units: str | None = None
    joint_map: Path | None = None
    floor: bool = False
    skeleton: Path | None = None  # an AMC's ASF (default: the one .asf beside it)
    animation: str | None = None  # a glTF or FBX file's animation (default: the first; FBX: the rig's own)
    repair_glitches: bool = False  # motion capture's settling frames and jumps repaired (frame count kept)

    def __post_init__(self):
        if self.fps is not None:  # NaN compares false with everything: checked here, not left to a resample
            check_motion_fps(self.fps)
        if (self.file is None) == (self.kind is None):  # neither was "unknown motion kind" with no got
            raise InputError(
                "a motion is a file or a procedural kind",
                expected="MotionSpec(file=PATH) or MotionSpec(kind=NAME)",
                got="both" if self.file is not None else "neither",
            )


@dataclasses.dataclass(frozen=True)
class Scene:
    """One run's inputs, outputs and effects (a scene file's tables: :func:`load_scene`).  ``output_format`` None
    (the default): the one ``output``'s extension names, as the command line takes it (a library user's
    ``Scene(output=Path("x.obj"))`` wrote a point cache named .obj); a format the extension contradicts is refused.
    ``effects``: an :class:`Effects` (``parse_effects("+cloth")`` makes one from the command line's words)."""

    garment: Path
    motion: MotionSpec
    output: Path
    output_format: str | None = None
    up: str = "y"
    units: float = 1.0  # metres per written unit (io.writer.output_unit)
    resolution: float = 1.0  # share of the garment's vertices the model runs on (`run --resolution`)
    body: Path | None = None
    betas: tuple = ()
    model: Path | None = None
    body_output: Path | None = None
    effects: Effects = Effects()
    path: Path | None = None
    simulate: object | None = None  # segadeform.physics.SimSettings; None: no [simulate] table

    def __post_init__(self):
        from ..io.outputs import output_format_for

        object.__setattr__(self, "output_format", output_format_for(self.output, self.output_format))
        if not isinstance(self.effects, Effects):  # "+cloth" was said as "effects must name skinning ..."
            raise InputError(
                "effects must be an Effects", expected="Effects(...) or parse_effects(TEXT)", got=type(self.effects)
            )


# The scene's tables (what each key takes: segadeform.io.toml.read_table)
@dataclasses.dataclass(frozen=True)
class _GarmentTable:
    mesh: str


@dataclasses.dataclass(frozen=True)
class _BodyTable:
    model: str | None = None
    betas: tuple = ()


@dataclasses.dataclass(frozen=True)
class MotionTable:
    """The keys of a motion that a scene's ``[motion]`` and a jobs file's ``[[motions]]`` share."""

    file: str | None = None
    kind: str | None = None
    seconds: float = key(3.0, range=(1e-3, 3600))
    speed: float = key(1.0, range=(0.05, 5))
    amplitude: float = key(1.0, range=(0, 2))
    seed: int = key(0, range=SEED_RANGE)
    fps: float | None = key(None, range=FPS_RANGE)
    frames: str | None = None
    up: str = key("auto", choices=("auto", "y", "z"))
    units: str | None = key(None, types=(str, int, float))
    floor: bool = False
    repair_glitches: bool = False


def units_key(table: dict, path, name: str) -> float:
    """Metres per written unit of the ``units`` key of TOML table ``name`` (a scene's ``[output]``, a jobs file's
    ``[batch]``; :func:`segadeform.io.writer.output_unit`), 1 without it; a bad one names the file, line and key."""
    try:
        return output_unit(table.get("units", 1.0), option=f"{name}.units")
    except InputError as e:
        raise FileFormatError(
            e.problem, path=path, line=key_line(path, name, "units"), expected=e.expected, got=e.got
        ) from None


def motion_spec_from_table(m: dict, rel, *, where) -> MotionSpec:
    """The :class:`MotionSpec` of a checked motion table ``m`` (a scene's ``[motion]``, a jobs file's
    ``[[motions]]``); ``rel`` resolves a path against the file's folder, ``where`` names the file in errors.
    Keys the table does not have take their defaults."""
    return MotionSpec(
        file=rel(m["file"]) if "file" in m else None,
        kind=m.get("kind"),
        seconds=float(m.get("seconds", 3.0)),
        speed=float(m.get("speed", 1.0)),
        amplitude=float(m.get("amplitude", 1.0)),
        seed=int(m.get("seed", 0)),
        fps=float(m["fps"]) if "fps" in m else None,
        frames=parse_frames(m["frames"], where=where) if "frames" in m else None,
        up=m.get("up", "auto"),
        units=str(m["units"]) if "units" in m else None,
        joint_map=rel(m["joint_map"]) if "joint_map" in m else None,
        floor=bool(m.get("floor", False)),
        repair_glitches=bool(m.get("repair_glitches", False)),
        skeleton=rel(m["skeleton"]) if "skeleton" in m else None,
        animation=m.get("animation"),
    )


@dataclasses.dataclass(frozen=True)
class _MotionTable(MotionTable):
    joint_map: str | None = None
    skeleton: str | None = None
    animation: str | None = None


@dataclasses.dataclass(frozen=True)
class _ModelTable:
    package: str | None = None
    resolution: float = key(1.0, range=(1e-9, 1.0))  # share of the garment's vertices the model runs on


@dataclasses.dataclass(frozen=True)
class _OutputTable:
    path: str
    format: str | None = None
    up: str = "y"  # one of io.writer.UP_AXES, read when a scene is loaded
    units: str | None = key(None, types=(str, int, float))  # io.writer.output_unit's, read when a scene is loaded
    body: str | None = None


def _effects_line(p, plain: dict, knobs: dict) -> int | None:
    """The line of the ``[effects]`` key whose value is refused (each tried alone), else the table's."""
    for k, v in knobs.items():
        try:
            ClothSettings(**{k: v})
        except ValueError:
            return key_line(p, "effects", f"cloth_{k}")
    for k, v in plain.items():
        try:
            Effects(**{k: v})
        except ValueError:
            return key_line(p, "effects", k)
    return key_line(p, "effects")


#: ``[effects]``: the fields of Effects but the cloth settings, which are ``cloth_<knob>`` keys
_EffectsTable = dataclasses.make_dataclass(
    "_EffectsTable",
    [
        (f.name, f.type, dataclasses.field(default=f.default))
        for f in dataclasses.fields(Effects)
        if f.name != "cloth_settings"
    ]
    + [(f"cloth_{k}", float, dataclasses.field(default=None)) for k in CLOTH_KNOBS],
    frozen=True,
)

_TABLES = {
    "garment": _GarmentTable,
    "body": _BodyTable,
    "motion": _MotionTable,
    "model": _ModelTable,
    "output": _OutputTable,
    "effects": _EffectsTable,
}


def parse_frames(text: str, *, where=None) -> tuple[int, int | None]:
    """``"A:B"`` (B exclusive; either side may be empty) -> (A, B or None)."""
    parts = text.split(":")
    try:
        if len(parts) != 2:
            raise ValueError
        a = int(parts[0]) if parts[0].strip() else 0
        b = int(parts[1]) if parts[1].strip() else None
    except ValueError:
        raise FileFormatError("frames must look like A:B", path=where, expected="e.g. 0:90 or 10:", got=text) from None
    if a < 0 or (b is not None and b <= a):
        raise FileFormatError("frame range must satisfy 0 <= A < B", path=where, got=text)
    return a, b


def load_scene(path: str | os.PathLike, *, effects: str | None = None, sim_effects: str | None = None) -> Scene:
    """Read and validate a scene file (see the module docstring).

    ``effects`` / ``sim_effects``: the command line's ``--effects`` of ``run`` / ``simulate``, which change the scene's
    ``[effects]`` / ``[simulate]`` effects.  A knob of an effect that is off is refused; with these, "off" is judged
    both before and after the change, so a scene may keep the knobs of an effect that the command line turns on
    (``--effects=+wind`` with ``wind_strength`` in ``[simulate]``) or, in ``[effects]``, off (``--effects=-cloth``
    with ``cloth_iterations``: ignored, as ``--quality fast`` ignores them).  The returned scene keeps its own
    effects (the command applies its change)."""
    effects_text = effects
    p = Path(path)
    data, _ = read_toml(p, "scene")
    unknown = sorted(set(data) - set(_TABLES) - {"simulate"})
    if unknown:
        raise FileFormatError(
            f"unknown table [{unknown[0]}]",
            path=p,
            line=key_line(p, unknown[0]),
            expected=", ".join(sorted(set(_TABLES) | {"simulate"})),
            got=", ".join(unknown),
        )
    for table, cls in _TABLES.items():
        if table in data or table in ("garment", "output"):
            read_table(data.get(table, {}), cls, where=table, path=p)
    if "motion" not in data:
        raise FileFormatError("missing [motion]", path=p, expected="motion.file or motion.kind")
    base = p.resolve().parent

    def rel(s: str) -> Path:
        q = config_path(s, path=p)
        return Path(os.path.normpath(q if q.is_absolute() else base / q))

    m = data["motion"]
    if ("file" in m) == ("kind" in m):
        raise FileFormatError("[motion] needs exactly one of 'file' or 'kind'", path=p)
    if "file" in m and any(k in m for k in ("seconds", "speed", "amplitude", "seed")):
        raise FileFormatError("motion.seconds/speed/amplitude/seed apply to procedural motions (kind) only", path=p)
    if "kind" in m and any(k in m for k in ("up", "units", "joint_map", "skeleton", "animation")):
        raise FileFormatError("motion.up/units/joint_map/skeleton/animation apply to motion files only", path=p)
    motion = motion_spec_from_table(m, rel, where=p)
    out = data["output"]
    out_path = rel(out["path"])
    from ..io.formats import SEQUENCE_FORMATS
    from ..io.outputs import body_output_format, output_format_for

    if "format" in out and out["format"] not in SEQUENCE_FORMATS:
        raise FileFormatError("output.format must be " + ", ".join(SEQUENCE_FORMATS), path=p, got=out["format"])
    try:
        fmt = output_format_for(out_path, out.get("format"))
    except InputError as e:  # output.format names it where the extension does not
        raise FileFormatError(
            f"output.path: {e.problem} (output.format: {', '.join(SEQUENCE_FORMATS)})", path=p, got=e.got
        ) from None
    if "body" in out:
        try:
            body_output_format(rel(out["body"]), fmt, out_path)
        except InputError as e:
            raise FileFormatError(f"output.body: {e.problem}", path=p, expected=e.expected, got=e.got) from None
    up = out.get("up", "y")
    if up not in UP_AXES:
        raise FileFormatError("unknown output.up axis", path=p, expected=" | ".join(UP_AXES), got=up)
    units = units_key(out, p, "output")
    betas = data.get("body", {}).get("betas", [])
    if not all(isinstance(b, (int, float)) and not isinstance(b, bool) for b in betas):
        raise FileFormatError("body.betas must be a list of numbers", path=p, got=betas)
    try:
        betas = check_betas(betas, what="body.betas")  # finite, within the shape space (segadeform.bounds)
    except InputError as e:
        raise FileFormatError(e.problem, path=p, expected=e.expected, got=e.got) from None
    if "effects" in data:  # what is not named is off
        eff = dict({n: False for n in EFFECT_NAMES}, **data["effects"])
        knobs = {k[len("cloth_") :]: eff.pop(k) for k in list(eff) if k.startswith("cloth_")}
        plain = {k: (float(v) if k == "collision_margin" else v) for k, v in eff.items()}
        try:
            effects = Effects(**plain, cloth_settings=ClothSettings(**knobs))
        except ValueError as e:
            raise FileFormatError(f"[effects]: {e}", path=p, line=_effects_line(p, plain, knobs)) from None
        on = parse_effects(effects_text, effects, warn=False) if effects_text is not None else effects  # what runs
        # a knob is refused only when its stage is off both in the scene and after the command line's change: a
        # scene may keep the knobs of a stage the command line turns on (--effects=+cloth) or off (--effects=-cloth,
        # as --quality fast does: a user's trial found -cloth refused with a hint to set what the file already set)
        if "collision_margin" in plain and not (on.collisions or on.cloth or effects.collisions or effects.cloth):
            raise FileFormatError(
                "[effects] sets collision_margin but neither collisions nor the cloth stage is on",
                path=p,
                line=key_line(p, "effects", "collision_margin"),
                expected="collisions = true or cloth = true in [effects] (or --effects=+collisions), or no "
                "collision_margin",
            )
        if knobs and not (on.cloth or effects.cloth):  # as --cloth K=V with the stage off: they would do nothing
            first = sorted(knobs)[0]
            raise FileFormatError(
                f"[effects] sets cloth_{first} but the cloth stage is off",
                path=p,
                line=key_line(p, "effects", f"cloth_{first}"),
                expected="cloth = true in [effects] (or --effects=+cloth), or no cloth_ keys",
            )
    else:
        effects = DEFAULT_EFFECTS
    sim = parse_simulate_table(data["simulate"], where=p, effects=sim_effects) if "simulate" in data else None
    return Scene(
        simulate=sim,
        garment=rel(data["garment"]["mesh"]),
        motion=motion,
        output=out_path,
        output_format=fmt,
        up=up,
        units=units,
        body=rel(data["body"]["model"]) if "model" in data.get("body", {}) else None,
        betas=tuple(float(b) for b in betas),
        model=rel(data["model"]["package"]) if "package" in data.get("model", {}) else None,
        resolution=float(data.get("model", {}).get("resolution", 1.0)),
        body_output=rel(out["body"]) if "body" in out else None,
        effects=effects,
        path=p,
    )
