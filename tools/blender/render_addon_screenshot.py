"""Render docs/blender-addon.png headless (Workbench): the add-on run on a walk BVH and the dress, with the body
from `segadeform run ... --body-out`.  Run with the simulator's Python:
    .venv-sim/bin/python tools/blender/render_addon_screenshot.py tools/blender/segadeform_import.py ADDON.zip \
        SEGADEFORM_EXE WALK.bvh samples/garments/dress.obj OUT_DIR BODY.obj BODY.pc2 docs/blender-addon.png
"""
import sys, runpy, math
import bpy, addon_utils
tool, addon_zip, exe, bvh, garment, out, body_obj, body_pc2, png = sys.argv[1:10]
ns = runpy.run_path(tool)
bpy.ops.wm.read_factory_settings(use_empty=True)
bpy.ops.preferences.addon_install(filepath=addon_zip)
addon_utils.enable("segadeform_addon", default_set=True)
bpy.context.preferences.addons["segadeform_addon"].preferences.executable = exe
addon_utils.enable("io_anim_bvh", default_set=True)
bpy.ops.import_anim.bvh(filepath=bvh, global_scale=0.01, update_scene_fps=True)
arm = bpy.context.object
bpy.ops.wm.obj_import(filepath=garment)
g = next(o for o in bpy.data.objects if o.type == "MESH")
arm.select_set(True); g.select_set(True); bpy.context.view_layer.objects.active = g
bpy.context.scene.segadeform.output_dir = out
bpy.context.scene.segadeform.quality = "fast"
bpy.ops.segadeform.animate_garment()
body = ns["import_result"](body_obj, body_pc2, frame_start=1)[0]
mat = bpy.data.materials.new("cloth"); mat.diffuse_color = (0.75, 0.2, 0.25, 1); g.data.materials.append(mat)
mb = bpy.data.materials.new("skin"); mb.diffuse_color = (0.8, 0.7, 0.6, 1); body.data.materials.append(mb)
sc = bpy.context.scene
sc.frame_set(8)
cam = bpy.data.objects.new("cam", bpy.data.cameras.new("cam")); sc.collection.objects.link(cam)
cam.location = (2.2, -3.2, 1.4); cam.rotation_euler = (math.radians(82), 0, math.radians(35)); sc.camera = cam
sc.render.engine = "BLENDER_WORKBENCH"
sc.display.shading.color_type = "MATERIAL"
sc.display.shading.light = "STUDIO"
sc.render.resolution_x, sc.render.resolution_y = 640, 720
sc.render.filepath = png
bpy.ops.render.render(write_still=True)
print("rendered", png)
