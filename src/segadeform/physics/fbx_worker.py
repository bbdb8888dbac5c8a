"""Blender side of FBX motion reading: run by the simulator environment's Python, never imported.

Usage (by :mod:`segadeform.physics.fbx`)::

    SIM_PYTHON fbx_worker.py SRC.fbx DST.bvh INFO.json [ANIMATION]

Imports ``SRC.fbx`` with Blender's own FBX importer (``io_scene_fbx``), picks the animated armature and one of
its animations (``ANIMATION`` by name; default: the one the importer put on the armature) and writes it with
Blender's BVH exporter (``io_anim_bvh``) over the animation's own frame range, in metres (the armature object's
scale applied: an FBX in centimetres comes out in metres) and in the armature's axes (Blender's, +Z up: the BVH
reader finds the up axis).  ``INFO.json`` gets what was read (armatures, animations, the one taken, frames,
frame rate) or ``{"error": ...}`` for a file that holds no animated skeleton; the exit status is 0 in both
cases and non-zero only when Blender itself failed.

This file depends on ``bpy`` only (Blender is GPL-3.0; keeping it in its own interpreter keeps it out of
segadeform).
"""

import json
import sys


def _fail(info_path, message, **extra):
    with open(info_path, "w") as fh:
        json.dump({"error": message, **extra}, fh)


def _action_of(ob):
    ad = ob.animation_data
    return ad.action if ad is not None else None


def convert(src, dst, info_path, animation=None):
    import bpy

    bpy.ops.wm.read_factory_settings(use_empty=True)
    try:
        bpy.ops.import_scene.fbx(filepath=src, use_anim=True)
    except RuntimeError as e:  # the importer's own report: not an FBX file, an ASCII FBX, an FBX too old ...
        lines = [s.strip() for s in str(e).splitlines() if s.strip()]
        why = (lines[-1] if lines else str(e)).replace(f"'{src}'", "").strip()
        why = why[len("Error:") :].strip() if why.startswith("Error:") else why
        return _fail(info_path, f"Blender's FBX importer could not read it ({why})")
    arms = [ob for ob in bpy.context.scene.objects if ob.type == "ARMATURE"]
    actions = sorted(a.name for a in bpy.data.actions)
    if not arms:
        return _fail(info_path, "it holds no armature (skeleton) to read a motion from", actions=actions)
    if not actions:
        return _fail(info_path, "its armature has no animation", armatures=[a.name for a in arms])
    if animation is not None:
        if animation not in actions:
            return _fail(info_path, f"it has no animation {animation!r}", actions=actions)
        act = bpy.data.actions[animation]
        animated = [ob for ob in arms if _action_of(ob) is act] or arms
        arm = max(animated, key=lambda ob: len(ob.data.bones))
        if _action_of(arm) is not act:
            if arm.animation_data is None:
                arm.animation_data_create()
            arm.animation_data.action = act
            slots = getattr(act, "slots", None)  # Blender 4.4+: an action plays through one of its slots
            if slots and getattr(arm.animation_data, "action_slot", None) is None:
                arm.animation_data.action_slot = slots[0]
    else:
        animated = [ob for ob in arms if _action_of(ob) is not None]
        if not animated:
            return _fail(info_path, "its armature has no animation", armatures=[a.name for a in arms], actions=actions)
        arm = max(animated, key=lambda ob: len(ob.data.bones))
        act = _action_of(arm)
    start, end = (int(round(f)) for f in act.frame_range)
    if end <= start:
        return _fail(info_path, f"its animation {act.name!r} has one frame", actions=actions)
    scene = bpy.context.scene
    scale = arm.matrix_world.to_scale()
    skinned = any(
        m.type == "ARMATURE" and m.object is arm
        for ob in bpy.context.scene.objects
        if ob.type == "MESH"
        for m in ob.modifiers
    )
    bpy.context.view_layer.objects.active = arm
    arm.select_set(True)
    bpy.ops.export_anim.bvh(
        filepath=dst, frame_start=start, frame_end=end, global_scale=float(sum(scale) / 3.0), rotate_mode="NATIVE"
    )
    with open(info_path, "w") as fh:
        json.dump(
            {
                "armature": arm.name,
                "armatures": [a.name for a in arms],
                "bones": len(arm.data.bones),
                "animation": act.name,
                "actions": actions,
                "frames": end - start + 1,
                "skinned": skinned,
                "fps": scene.render.fps / scene.render.fps_base,
                "scale": [float(s) for s in scale],
                "blender": bpy.app.version_string,
            },
            fh,
        )


if __name__ == "__main__":
    args = sys.argv[sys.argv.index("--") + 1 :] if "--" in sys.argv else sys.argv[1:]
    convert(*args[:3], animation=args[3] if len(args) > 3 else None)
