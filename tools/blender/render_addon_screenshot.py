"""The add-on's demonstration scene, and docs/blender-addon.png rendered from it headless (Workbench).

``setup_scene`` installs the add-on from its zip, imports an armature animated by a BVH (Blender's BVH
importer) and a garment (the default OBJ importer), selects both and runs *Animate garment*; the add-on's
test (tests/physics/test_blender_addon.py) uses it too.  Run with the simulator's Python to render:

    .venv-sim/bin/python tools/blender/render_addon_screenshot.py tools/blender/segadeform_import.py ADDON.zip \\
        SEGADEFORM_EXE WALK.bvh samples/garments/dress.obj OUT_DIR BODY.obj BODY.pc2 docs/blender-addon.png

(BODY.obj/.pc2 from ``segadeform run ... --body-out BODY.pc2`` on the add-on's exported garment and motion.)
"""

import math
import runpy
import sys

import addon_utils
import bpy


def setup_scene(addon_zip, exe, bvh, garment, out, quality="fast"):
    """Returns (garment object, the operator's result)."""
    bpy.ops.wm.read_factory_settings(use_empty=True)
    bpy.ops.preferences.addon_install(filepath=addon_zip)
    addon_utils.enable("segadeform_addon", default_set=True)
    bpy.context.preferences.addons["segadeform_addon"].preferences.executable = exe
    addon_utils.enable("io_anim_bvh", default_set=True)
    bpy.ops.import_anim.bvh(filepath=bvh, global_scale=0.01, update_scene_fps=True)
    arm = bpy.context.object
    bpy.ops.wm.obj_import(filepath=garment)  # turns the object 90 degrees about X: the cache must be local
    g = next(o for o in bpy.data.objects if o.type == "MESH")
    arm.select_set(True)
    g.select_set(True)
    bpy.context.view_layer.objects.active = g
    s = bpy.context.scene.segadeform
    s.output_dir, s.quality = out, quality
    return g, bpy.ops.segadeform.animate_garment()


def render(tool, addon_zip, exe, bvh, garment, out, body_obj, body_pc2, png):
    g, _ = setup_scene(addon_zip, exe, bvh, garment, out)
    body = runpy.run_path(tool)["import_result"](body_obj, body_pc2, frame_start=1)[0]
    for ob, name, colour in ((g, "cloth", (0.75, 0.2, 0.25, 1)), (body, "skin", (0.8, 0.7, 0.6, 1))):
        mat = bpy.data.materials.new(name)
        mat.diffuse_color = colour
        ob.data.materials.append(mat)
    sc = bpy.context.scene
    sc.frame_set(8)
    cam = bpy.data.objects.new("cam", bpy.data.cameras.new("cam"))
    sc.collection.objects.link(cam)
    cam.location = (2.2, -3.2, 1.4)
    cam.rotation_euler = (math.radians(82), 0, math.radians(35))
    sc.camera = cam
    sc.render.engine = "BLENDER_WORKBENCH"
    sc.display.shading.color_type = "MATERIAL"
    sc.display.shading.light = "STUDIO"
    sc.render.resolution_x, sc.render.resolution_y = 640, 720
    sc.render.filepath = png
    bpy.ops.render.render(write_still=True)
    print("rendered", png)


if __name__ == "__main__":
    render(*sys.argv[1:10])
