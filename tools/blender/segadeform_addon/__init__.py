"""segadeform for Blender: animate the selected garment with the selected armature's action.

Select a garment mesh and an armature that carries an action, then press *Animate garment* in the 3D
view's sidebar (tab *segadeform*).  The operator

1. writes the garment as an OBJ in segadeform's convention (world positions, metres, +Y up, the mesh's
   vertex order) and the action as a BVH through Blender's own BVH exporter (the action's frame range);
2. runs ``segadeform run`` as a subprocess -- the executable is set in the add-on's preferences, the
   effects and the quality preset in the panel -- showing its progress in the status bar and any error
   (segadeform's one ``Error: ...`` line) in Blender's interface;
3. attaches the result to the garment: a Mesh Cache modifier playing a PC2 in the garment object's own
   coordinates, its first frame at the action's first frame.

Runs inside Blender (GPL-3.0); a separate program, not part of the segadeform package.  Install the zip made
by ``python tools/blender/build_addon.py`` (Edit > Preferences > Add-ons > Install from Disk).
"""

from __future__ import annotations

import os
import struct
import subprocess
import time

import bpy

bl_info = {
    "name": "segadeform",
    "author": "segadeform",
    "version": (0, 1, 0),
    "blender": (4, 2, 0),
    "location": "View3D > Sidebar > segadeform",
    "description": "Animate a garment with an armature's action through segadeform run",
    "category": "Animation",
}

_PC2 = struct.Struct("<12siiffi")
QUALITY = [
    ("NONE", "Effects only", "use the effects field as it is"),
    ("fast", "fast", "quality preset fast"),
    ("balanced", "balanced", "quality preset balanced"),
    ("best", "best", "quality preset best"),
]


class SegadeformPreferences(bpy.types.AddonPreferences):
    bl_idname = __package__ or __name__

    executable: bpy.props.StringProperty(
        name="segadeform executable",
        subtype="FILE_PATH",
        default="segadeform",
        description="The segadeform command (a path, or a name found on PATH)",
    )

    def draw(self, context):
        self.layout.prop(self, "executable")


def _prefs(context):
    return context.preferences.addons[SegadeformPreferences.bl_idname].preferences


def _selection(context):
    """(garment mesh, armature with an action) from the selection, or an error message."""
    sel = list(context.selected_objects)
    meshes = [o for o in sel if o.type == "MESH"]
    arms = [o for o in sel if o.type == "ARMATURE"]
    if len(meshes) != 1 or len(arms) != 1:
        return (
            None,
            None,
            (f"select one garment mesh and one armature (got {len(meshes)} meshes and {len(arms)} armatures)"),
        )
    arm = arms[0]
    if arm.animation_data is None or arm.animation_data.action is None:
        return None, None, f"the armature {arm.name!r} has no action (expected an animated armature)"
    return meshes[0], arm, None


def write_garment_obj(obj, path):
    """The mesh's vertices in world space turned to +Y up ((x, y, z) -> (x, z, -y)), faces as they are."""
    mw = obj.matrix_world
    lines = ["# segadeform garment from Blender object " + obj.name]
    for v in obj.data.vertices:
        w = mw @ v.co
        lines.append(f"v {w.x:.9g} {w.z:.9g} {-w.y:.9g}")
    for p in obj.data.polygons:
        lines.append("f " + " ".join(str(i + 1) for i in p.vertices))
    tmp = path + ".tmp"
    with open(tmp, "w") as fh:
        fh.write("\n".join(lines) + "\n")
    os.replace(tmp, path)


def read_pc2(path):
    import numpy as np

    with open(path, "rb") as fh:
        magic, _v, n, start, rate, samples = _PC2.unpack(fh.read(_PC2.size))
        if magic != b"POINTCACHE2\0":
            raise RuntimeError(f"{path}: not a PC2 file")
        data = np.frombuffer(fh.read(), np.float32, count=samples * n * 3).reshape(samples, n, 3)
    return data, start, rate


def write_local_pc2(obj, frames, start, path):
    """segadeform's frames (world, +Y up) as positions in ``obj``'s own coordinates, which a Mesh Cache
    modifier replaces: (x, y, z) -> Blender's (x, -z, y), then the inverse of the object's world matrix."""
    import numpy as np

    world = np.stack([frames[..., 0], -frames[..., 2], frames[..., 1]], axis=-1).astype(np.float64)
    inv = np.array(obj.matrix_world.inverted(), np.float64)
    local = world @ inv[:3, :3].T + inv[:3, 3]
    tmp = path + ".tmp"
    with open(tmp, "wb") as fh:
        fh.write(_PC2.pack(b"POINTCACHE2\0", 1, local.shape[1], float(start), 1.0, local.shape[0]))
        fh.write(local.astype("<f4").tobytes())
    os.replace(tmp, path)


def run_segadeform(exe, args, report_progress=None):
    """Run ``exe args``; returns (exit code, the last 'Error: ...' line or the output's tail)."""
    try:
        proc = subprocess.Popen([exe] + args, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    except OSError as e:
        return 127, f"cannot start segadeform ({exe}): {e.strerror or e}"
    out = []
    t0 = time.time()
    for line in proc.stdout:
        out.append(line.rstrip("\n"))
        if report_progress:
            report_progress(time.time() - t0, line.strip())
    rc = proc.wait()
    err = next((ln for ln in reversed(out) if ln.startswith("Error:")), None)
    return rc, err or "\n".join(out[-5:])


class SEGADEFORM_OT_animate_garment(bpy.types.Operator):
    """Animate the selected garment with the selected armature's action (segadeform run)"""

    bl_idname = "segadeform.animate_garment"
    bl_label = "Animate garment"
    bl_options = {"REGISTER", "UNDO"}

    @classmethod
    def poll(cls, context):
        return context.mode == "OBJECT"

    def execute(self, context):
        garment, arm, problem = _selection(context)
        if problem:
            self.report({"ERROR"}, problem)
            return {"CANCELLED"}
        scene = context.scene
        settings = scene.segadeform
        action = arm.animation_data.action
        first, last = (int(round(x)) for x in action.frame_range)
        folder = bpy.path.abspath(settings.output_dir) if settings.output_dir else bpy.app.tempdir
        folder = os.path.join(folder, bpy.path.clean_name(f"{garment.name}_{action.name}"))
        os.makedirs(folder, exist_ok=True)
        obj_path, bvh_path = os.path.join(folder, "garment.obj"), os.path.join(folder, "motion.bvh")
        pc2_path = os.path.join(folder, "garment.pc2")
        write_garment_obj(garment, obj_path)
        # Blender's own BVH exporter, for the armature alone over the action's frames
        for o in context.selected_objects:
            o.select_set(o == arm)
        context.view_layer.objects.active = arm
        bpy.ops.export_anim.bvh(
            filepath=bvh_path,
            frame_start=first,
            frame_end=last,
            global_scale=1.0,
            rotate_mode="NATIVE",
            root_transform_only=False,
        )
        garment.select_set(True)
        args = ["run", "--garment", obj_path, "--motion", bvh_path, "-o", pc2_path, "--force"]
        if settings.quality != "NONE":
            args += ["--quality", settings.quality]
        if settings.effects.strip():
            args += ["--effects=" + settings.effects.strip()]
        wm = context.window_manager
        workspace = getattr(context, "workspace", None)

        def progress(seconds, line):
            wm.progress_update(min(99, int(seconds)))
            if workspace is not None:
                workspace.status_text_set(f"segadeform: {line or 'running'} ({seconds:.0f} s)")

        wm.progress_begin(0, 100)
        try:
            rc, message = run_segadeform(bpy.path.abspath(_prefs(context).executable), args, progress)
        finally:
            wm.progress_end()
            if workspace is not None:
                workspace.status_text_set(None)
        if rc != 0:
            self.report({"ERROR"}, f"segadeform failed: {message}")
            return {"CANCELLED"}
        frames, start, _ = read_pc2(pc2_path)
        if frames.shape[1] != len(garment.data.vertices):
            self.report({"ERROR"}, f"{pc2_path}: {frames.shape[1]} points for {len(garment.data.vertices)} vertices")
            return {"CANCELLED"}
        local_path = os.path.join(folder, "garment_local.pc2")
        write_local_pc2(garment, frames, start, local_path)
        mod = garment.modifiers.get("segadeform") or garment.modifiers.new("segadeform", "MESH_CACHE")
        mod.cache_format = "PC2"
        mod.filepath = local_path
        mod.frame_start = first  # sample k shows at the action's frame first + k
        mod.frame_scale = 1.0
        scene.frame_start, scene.frame_end = first, first + frames.shape[0] - 1
        self.report({"INFO"}, f"segadeform: {frames.shape[0]} frames attached to {garment.name} ({pc2_path})")
        return {"FINISHED"}


class SegadeformSettings(bpy.types.PropertyGroup):
    effects: bpy.props.StringProperty(
        name="Effects", default="", description="segadeform run --effects (e.g. lbs,dynamics,collisions or -wrinkles)"
    )
    quality: bpy.props.EnumProperty(name="Quality", items=QUALITY, default="NONE")
    output_dir: bpy.props.StringProperty(
        name="Output folder",
        subtype="DIR_PATH",
        default="//segadeform",
        description="Where the garment, motion and caches are written",
    )


class SEGADEFORM_PT_panel(bpy.types.Panel):
    bl_label = "segadeform"
    bl_space_type = "VIEW_3D"
    bl_region_type = "UI"
    bl_category = "segadeform"

    def draw(self, context):
        s = context.scene.segadeform
        col = self.layout.column()
        col.prop(s, "quality")
        col.prop(s, "effects")
        col.prop(s, "output_dir")
        col.operator(SEGADEFORM_OT_animate_garment.bl_idname, icon="MOD_CLOTH")


_CLASSES = (SegadeformPreferences, SegadeformSettings, SEGADEFORM_OT_animate_garment, SEGADEFORM_PT_panel)


def register():
    for c in _CLASSES:
        bpy.utils.register_class(c)
    bpy.types.Scene.segadeform = bpy.props.PointerProperty(type=SegadeformSettings)


def unregister():
    del bpy.types.Scene.segadeform
    for c in reversed(_CLASSES):
        bpy.utils.unregister_class(c)
