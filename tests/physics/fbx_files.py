"""FBX files for the tests, made by Blender (the simulator environment) from a BVH file: a character's skeleton with
its animation, as Mixamo, Maya or Unreal export it, and files an FBX reader must refuse."""

from __future__ import annotations

import subprocess
from pathlib import Path

from segadeform.physics.blender import find_sim_python

#: run by Blender's Python: SCRIPT BVH DST MODE...  (modes: skinned, mixamo, spaces, fps30, cm, turned, objroot,
#: two-takes, prop, still, no-armature)
SCRIPT = r"""
import sys, bpy
src, dst, modes = sys.argv[1], sys.argv[2], set(sys.argv[3:])
bpy.ops.wm.read_factory_settings(use_empty=True)
if "no-armature" in modes:
    bpy.ops.mesh.primitive_cube_add()
    bpy.ops.export_scene.fbx(filepath=dst, object_types={"MESH"})
    raise SystemExit(0)
bpy.ops.import_anim.bvh(filepath=src, frame_start=1, update_scene_fps=True, update_scene_duration=True)
arm = [o for o in bpy.context.scene.objects if o.type == "ARMATURE"][0]
arm.name = "Armature"
if "mixamo" in modes:
    for b in arm.data.bones:
        b.name = "mixamorig:" + b.name
if "fps30" in modes:  # a 30 fps scene
    bpy.context.scene.render.fps, bpy.context.scene.render.fps_base = 30, 1.0  # (any rate: 30 is a common one)
if "spaces" in modes:  # 3ds Max Biped's names
    for b in arm.data.bones:
        b.name = "Bip01 " + b.name
if "cm" in modes:
    arm.scale = (2.0, 2.0, 2.0)
if "turned" in modes:  # the character faces +X in the file: the turn applied to the armature's data
    arm.rotation_euler = (0.0, 0.0, 1.5707963267948966)
    bpy.context.view_layer.objects.active = arm
    arm.select_set(True)
    bpy.ops.object.transform_apply(location=False, rotation=True, scale=False)
if "objroot" in modes:  # root motion on the armature object: 2 m along +X over the clip, on top of the bones'
    f0, f1 = (int(round(f)) for f in arm.animation_data.action.frame_range)
    arm.location = (0.0, 0.0, 0.0)
    arm.keyframe_insert("location", frame=f0)
    arm.location = (2.0, 0.0, 0.0)
    arm.keyframe_insert("location", frame=f1)
    for fc in getattr(arm.animation_data.action, "fcurves", None) or []:
        for k in fc.keyframe_points:
            k.interpolation = "LINEAR"
if "two-takes" in modes:
    act = arm.animation_data.action
    act.name = "walk"
    short = act.copy()
    short.name = "walk-start"
    short.frame_range = (1.0, 40.0)
    short.use_frame_range = True
objects = {"ARMATURE"}
if "skinned" in modes:
    me = bpy.data.meshes.new("body")
    me.from_pydata([tuple(b.head_local) for b in arm.data.bones], [], [])
    ob = bpy.data.objects.new("body", me)
    bpy.context.scene.collection.objects.link(ob)
    for i, b in enumerate(arm.data.bones):
        ob.vertex_groups.new(name=b.name).add([i], 1.0, "REPLACE")
    ob.parent = arm
    ob.modifiers.new("skin", "ARMATURE").object = arm
    ob.select_set(True)
    objects.add("MESH")
if "prop" in modes:  # a prop's rig with more bones than the character, animated too, no mesh
    pd = bpy.data.armatures.new("PropRig")
    prop = bpy.data.objects.new("Prop", pd)
    bpy.context.scene.collection.objects.link(prop)
    bpy.context.view_layer.objects.active = prop
    bpy.ops.object.mode_set(mode="EDIT")
    parent = None
    for i in range(60):
        eb = pd.edit_bones.new(f"Prop_{i:02d}")
        eb.head, eb.tail = (3.0, 0.0, 0.1 * i), (3.0, 0.0, 0.1 * i + 0.1)
        eb.parent, eb.use_connect = parent, parent is not None
        parent = eb
    bpy.ops.object.mode_set(mode="OBJECT")
    for f in (1, 20):
        for pb in prop.pose.bones:
            pb.rotation_mode = "XYZ"
            pb.rotation_euler = (0.05 * f, 0.0, 0.0)
            pb.keyframe_insert("rotation_euler", frame=f)
    prop.select_set(True)
bpy.context.view_layer.objects.active = arm
arm.select_set(True)
bpy.ops.export_scene.fbx(
    filepath=dst, use_selection=True, object_types=objects, bake_anim="still" not in modes, add_leaf_bones=False
)
"""


def make_fbx(bvh: Path, dst: Path, *modes: str) -> Path:
    """Write ``dst`` (.fbx) from ``bvh`` in Blender; ``modes`` as :data:`SCRIPT` takes them."""
    exe = find_sim_python()
    script = dst.with_suffix(".make.py")
    script.write_text(SCRIPT)
    r = subprocess.run([str(exe), str(script), str(bvh), str(dst), *modes], capture_output=True, text=True, timeout=300)
    script.unlink()
    if r.returncode != 0 or not dst.is_file():
        raise RuntimeError(f"Blender could not make {dst.name}: {r.stderr[-2000:]}")
    return dst
