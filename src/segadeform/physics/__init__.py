"""Ground truth by cloth simulation (Blender's solver, run out of process) and its settings.

Nothing here imports ``bpy`` or torch: :mod:`.blender` talks to Blender
through a subprocess (see its docstring), :mod:`.settings` turns a scene's
``[simulate]`` table into solver settings.
"""

from ..settings.simulation import DEFAULT_EFFECTS, EFFECTS, MATERIALS, Material, SimSettings, parse_simulate_table
from .blender import (
    A_POSE,
    SimResult,
    blender_settings,
    find_sim_python,
    pin_weights,
    preroll_poses,
    simulate,
    unpose_lbs,
    waist_height,
)

__all__ = [
    "SimResult",
    "simulate",
    "find_sim_python",
    "pin_weights",
    "waist_height",
    "preroll_poses",
    "unpose_lbs",
    "A_POSE",
    "SimSettings",
    "Material",
    "MATERIALS",
    "EFFECTS",
    "DEFAULT_EFFECTS",
    "blender_settings",
    "parse_simulate_table",
]
