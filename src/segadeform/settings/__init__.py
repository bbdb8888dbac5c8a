"""What a run asks for, as frozen data read from files and command lines (no numpy maths): scenes
(:mod:`.scene`), the runtime's effects and the effect-list rule (:mod:`.effects`), quality presets
(:mod:`.presets`), the cloth stage's knobs (:mod:`.cloth`) and the simulator's settings (:mod:`.simulation`)."""

from .cloth import CLOTH_KNOBS, ClothSettings
from .effects import DEFAULT_EFFECTS, EffectList, Effects, parse_effect_list, parse_effects
from .presets import QUALITY_PRESETS, Preset, is_change_list, preset_effects
from .scene import Y_TO_Z, MotionSpec, Scene, load_scene, parse_frames
from .simulation import MATERIALS, Material, SimSettings, parse_sim_effects, parse_simulate_table

__all__ = [
    "CLOTH_KNOBS",
    "ClothSettings",
    "DEFAULT_EFFECTS",
    "EffectList",
    "Effects",
    "parse_effect_list",
    "parse_effects",
    "QUALITY_PRESETS",
    "Preset",
    "is_change_list",
    "preset_effects",
    "Y_TO_Z",
    "MotionSpec",
    "Scene",
    "load_scene",
    "parse_frames",
    "MATERIALS",
    "Material",
    "SimSettings",
    "parse_sim_effects",
    "parse_simulate_table",
]
