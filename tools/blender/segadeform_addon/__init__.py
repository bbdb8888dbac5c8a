"""segadeform for Blender: animate the selected garment with the selected armature's action.

Select a garment mesh and an armature that carries an action, then press *Animate garment* in the 3D
view's sidebar (tab *segadeform*).  The operator

1. writes the garment as an OBJ in segadeform's convention (metres, +Y up, the mesh's vertex order) in the
   armature's frame (from its origin, in its turn) as it is at the scene's start frame -- where it is placed
   on the body, whatever frame the timeline shows (the timeline is left where it was) -- and the action as a
   BVH through Blender's own BVH exporter (the action's frame range, in the armature's own space);
2. runs ``segadeform run`` as a subprocess with that BVH's units and up axis (``--units``: metres per unit,
   the armature's world scale; ``--motion-up``) -- the executable is set in the add-on's preferences, the
   effects and the quality preset in the panel -- showing its progress in the status bar and any error
   (segadeform's one ``Error: ...`` line) in Blender's interface;
3. attaches the result to the garment: a Mesh Cache modifier playing a PC2 in the garment object's own
   coordinates (per frame, so a garment parented to a bone or animated itself, or an armature moved as an
   object, gets its frames right), its first frame at the action's first frame, placed after the garment's
   leading deform modifiers and before the first that changes its vertices (a Subdivision Surface then
   smooths the result).

What follows what: segadeform poses *its own default body* with the action -- the body's pelvis on the
armature's hips (the BVH's root, in metres at the armature's scale, so it travels as the hips do), its joints
turned as the action turns the bones, on the default body's proportions -- and the garment follows that body.
The user's character mesh is never read: where the character is built otherwise than the default body (longer
legs, another girth) its skin can show through the garment or stand off it.  The garment has to sit on the
default body at rest, standing at the armature's origin, as ``segadeform run`` checks; its refusal shows in
Blender and the panel's *Force* runs it anyway.  An armature whose scale is not uniform, or that lies on its
side (neither its +Z nor its +Y axis up), is refused before anything is written.

Like every segadeform command, the add-on never overwrites a file it did not write: its folder's
``.segadeform-outputs.json`` lists what it and ``segadeform run`` wrote there, and any other file at one of its
names is refused before anything is written.  In a file not saved yet, a relative
output folder (the default ``//segadeform``) lies in Blender's temporary folder, which Blender empties on
exit: save the .blend first to keep the result beside it; the cache's path is stored relative to the .blend
when Blender's *Default to relative paths* is on (so a copied project folder still plays).

Runs inside Blender (GPL-3.0); a separate program, not part of the segadeform package.  Install the zip made
by ``python tools/blender/build_addon.py`` (Edit > Preferences > Add-ons > Install from Disk).
"""

from __future__ import annotations

import json
import os
import shutil
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
#: segadeform's outputs manifest (segadeform.io.output_guard; the Node and C++ runtimes keep the same one)
MANIFEST = ".segadeform-outputs.json"
KIND = "blender add-on"
#: modifiers that move vertices and keep their count: the cache goes after the leading ones (it replaces their
#: positions) and before the first other one (a Subdivision Surface, a Mirror ...), which then gets its vertices
DEFORM_ONLY = {
    "ARMATURE", "CAST", "CLOTH", "CORRECTIVE_SMOOTH", "CURVE", "DISPLACE", "HOOK", "LAPLACIANDEFORM",
    "LAPLACIANSMOOTH", "LATTICE", "MESH_CACHE", "MESH_DEFORM", "MESH_SEQUENCE_CACHE", "SHRINKWRAP",
    "SIMPLE_DEFORM", "SMOOTH", "SOFT_BODY", "SURFACE_DEFORM", "WARP", "WAVE",
}  # fmt: skip
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


def _can_move(obj):
    """Whether anything can move ``obj`` from frame to frame (a parent, animation or a constraint)."""
    return obj.parent is not None or obj.animation_data is not None or bool(obj.constraints)


def world_matrix_at(scene, obj, frame):
    """``obj``'s world matrix at scene frame ``frame``; the scene's current frame is restored."""
    if not _can_move(obj):
        return obj.matrix_world.copy()
    here, sub = scene.frame_current, scene.frame_subframe
    try:
        scene.frame_set(frame)
        return obj.matrix_world.copy()
    finally:
        scene.frame_set(here, subframe=sub)


def write_garment_obj(obj, path, matrix=None):
    """The mesh's vertices through ``matrix`` (default: the object's world matrix now; the add-on's: into the
    rig's frame, :func:`rig_frame`) turned to +Y up ((x, y, z) -> (x, z, -y)), faces as they are."""
    mw = obj.matrix_world if matrix is None else matrix
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


def rig_units_up(matrix):
    """(metres per unit of the armature's own space -- its world scale --, its up axis for ``segadeform run
    --motion-up``) from the armature's world matrix: Blender's BVH exporter writes the armature's own space,
    without the object's transform.  RuntimeError for a scale that is not uniform or an armature on its side."""
    from mathutils import Vector

    _loc, rot, scale = matrix.decompose()
    big = max(abs(x) for x in scale)
    if not min(scale) > 0 or big - min(scale) > 1e-4 * big:
        got = ", ".join(f"{x:.6g}" for x in scale)
        raise RuntimeError(
            f"the armature's scale is not uniform (expected equal positive X, Y and Z scales, got {got}): apply "
            "its scale (Ctrl+A > Scale) first"
        )
    up = rot.to_matrix().transposed() @ Vector((0.0, 0.0, 1.0))  # the world's up in the armature's axes
    if up.z >= 0.9:
        return big, "z"
    if up.y >= 0.9:
        return big, "y"
    raise RuntimeError(
        f"the armature lies on its side (expected its +Z or +Y axis up in the world, got the world's up along "
        f"({up.x:.2f}, {up.y:.2f}, {up.z:.2f}) of its own axes): stand it up first"
    )


def rig_frame(matrix, up):
    """segadeform's frame in Blender's world, Z up: the armature's origin and turn, without its scale (segadeform
    is told the scale by ``--units``), and for an armature whose own +Y is up (``up`` "y") a quarter turn about X
    (segadeform reads its own +Y as up: the inverse of (x, y, z) -> (x, z, -y))."""
    from mathutils import Matrix

    loc, rot, _scale = matrix.decompose()
    m = Matrix.Translation(loc) @ rot.to_matrix().to_4x4()
    return m @ Matrix(((1, 0, 0, 0), (0, 0, 1, 0), (0, -1, 0, 0), (0, 0, 0, 1))) if up == "y" else m


def local_matrices(scene, obj, arm, up, first, count):
    """(count, 4, 4): the inverse of ``obj``'s world matrix times the rig's frame (:func:`rig_frame` of ``arm``) at
    scene frames first, first + 1, ...: segadeform's coordinates (Z up) to the object's own; one matrix repeated
    when nothing can move the object or the armature (no parent, animation or constraint)."""
    import numpy as np

    def now():
        return np.array(obj.matrix_world.inverted() @ rig_frame(arm.matrix_world, up), np.float64)

    if not (_can_move(obj) or _can_move(arm)):
        return np.repeat(now()[None], count, axis=0)
    here, sub = scene.frame_current, scene.frame_subframe
    out = np.empty((count, 4, 4))
    try:
        for k in range(count):
            scene.frame_set(first + k)
            out[k] = now()
    finally:
        scene.frame_set(here, subframe=sub)
    return out


def write_local_pc2(inverses, frames, start, path):
    """segadeform's frames (+Y up) as positions in the object's own coordinates, which a Mesh Cache modifier
    replaces: (x, y, z) -> Blender's (x, -z, y), then ``inverses[k]`` (segadeform's frame to the object's own at
    the frame sample k shows at; :func:`local_matrices`)."""
    import numpy as np

    world = np.stack([frames[..., 0], -frames[..., 2], frames[..., 1]], axis=-1).astype(np.float64)
    local = np.einsum("kij,knj->kni", inverses[:, :3, :3], world) + inverses[:, None, :3, 3]
    tmp = path + ".tmp"
    with open(tmp, "wb") as fh:
        fh.write(_PC2.pack(b"POINTCACHE2\0", 1, local.shape[1], float(start), 1.0, local.shape[0]))
        fh.write(local.astype("<f4").tobytes())
    os.replace(tmp, path)


def _manifest(folder):
    try:
        with open(os.path.join(folder, MANIFEST), encoding="utf-8") as fh:
            m = json.load(fh)
    except FileNotFoundError:
        return {"segadeform_outputs": 1, "files": {}}
    except (OSError, ValueError):
        m = None
    if not isinstance(m, dict) or m.get("segadeform_outputs") != 1 or not isinstance(m.get("files"), dict):
        where = os.path.join(folder, MANIFEST)
        raise RuntimeError(f"{where}: not a segadeform outputs manifest; choose another output folder")
    return m


def refuse_foreign(folder, names):
    """Raise unless every file of ``names`` in ``folder`` is missing or was written there by the add-on or
    ``segadeform run`` (the manifest lists it, unchanged since): nothing else is ever overwritten."""
    files = _manifest(folder)["files"]
    for name in names:
        path = os.path.join(folder, name)
        if not os.path.lexists(path):
            continue
        e, st = files.get(name), os.lstat(path)
        ours = (
            isinstance(e, dict)
            and e.get("kind") in (KIND, "run")
            and os.path.isfile(path)
            and (e.get("size"), e.get("mtime_ns")) == (st.st_size, st.st_mtime_ns)
        )
        if not ours:
            raise RuntimeError(
                f"{path} exists and segadeform did not write it (or it changed since); the add-on never overwrites "
                "such a file: choose another output folder, or move the file"
            )


def record(folder, names):
    """List ``names`` (just written) in the folder's manifest as the add-on's; written atomically."""
    m = _manifest(folder)
    for name in names:
        st = os.stat(os.path.join(folder, name))
        m["files"][name] = {"kind": KIND, "size": int(st.st_size), "mtime_ns": int(st.st_mtime_ns)}
    m["files"] = dict(sorted(m["files"].items()))
    tmp = os.path.join(folder, MANIFEST + ".tmp")
    with open(tmp, "w", encoding="utf-8") as fh:
        fh.write(json.dumps(m, indent=1) + "\n")
    os.replace(tmp, os.path.join(folder, MANIFEST))


def find_executable(exe):
    """The segadeform program to run (a path, or a name on PATH), or None."""
    if os.path.dirname(exe):
        return exe if os.path.isfile(exe) and os.access(exe, os.X_OK) else None
    return shutil.which(exe)


def output_root(output_dir):
    """(folder, warning or None) for the panel's output folder.  A relative one (``//...``) in a file not saved
    yet lies in Blender's temporary folder (Blender's own ``//`` would be the current directory)."""
    if not output_dir:
        return bpy.app.tempdir, "written to Blender's temporary folder, which Blender empties on exit"
    if output_dir.startswith("//") and not bpy.data.filepath:
        return (
            os.path.join(bpy.app.tempdir, output_dir[2:]),
            "the file is not saved, so the result is in Blender's temporary folder, which Blender empties on exit: "
            "save the .blend and animate again to keep it beside it",
        )
    return bpy.path.abspath(output_dir), None


def place_modifier(obj, mod):
    """Move ``mod`` after ``obj``'s leading deform-only modifiers; returns the names of the modifiers after it
    that move vertices again (they would change segadeform's result)."""
    mods = list(obj.modifiers)
    mods.remove(mod)
    at = 0
    while at < len(mods) and mods[at].type in DEFORM_ONLY:
        at += 1
    obj.modifiers.move(list(obj.modifiers).index(mod), at)
    return [m.name for m in mods[at:] if m.type in DEFORM_ONLY and m.show_viewport]


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
        exe = bpy.path.abspath(_prefs(context).executable)
        if find_executable(exe) is None:  # before anything is written
            self.report(
                {"ERROR"},
                f"cannot start segadeform ({exe}): no such program; set the segadeform executable in the add-on's "
                "preferences (Edit > Preferences > Add-ons > segadeform)",
            )
            return {"CANCELLED"}
        try:  # the armature's scale and up axis, for segadeform run's --units and --motion-up
            rig_at_start = world_matrix_at(scene, arm, scene.frame_start)
            units, up = rig_units_up(rig_at_start)
        except RuntimeError as e:
            self.report({"ERROR"}, str(e))
            return {"CANCELLED"}
        root, warning = output_root(settings.output_dir)
        folder = os.path.join(root, bpy.path.clean_name(f"{garment.name}_{action.name}"))
        names = ("garment.obj", "motion.bvh", "garment.pc2", "garment_local.pc2")
        obj_path, bvh_path, pc2_path, local_path = (os.path.join(folder, n) for n in names)
        try:
            os.makedirs(folder, exist_ok=True)
            refuse_foreign(folder, names)
        except (OSError, RuntimeError) as e:
            self.report({"ERROR"}, str(e))
            return {"CANCELLED"}
        # the garment where it was placed on the body: at the scene's start frame, whatever frame the timeline is
        # on (a garment parented to a bone moves with it; at frame 20 of a walk it was refused, or 0.28 m off), in
        # the rig's frame (segadeform's body stands at the armature's origin)
        place = world_matrix_at(scene, garment, scene.frame_start)
        write_garment_obj(garment, obj_path, rig_frame(rig_at_start, up).inverted() @ place)
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
        record(folder, names[:2])
        # the BVH's root in metres as it stands (segadeform otherwise rescales it by the legs' length, and the
        # garment drifted off the rig: 0.33 m in 2.9 s)
        args = ["run", "--garment", obj_path, "--motion", bvh_path, "-o", pc2_path]
        args += ["--units", f"{units:.9g}", "--motion-up", up]
        if settings.force:
            args.append("--force")
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
            rc, message = run_segadeform(exe, args, progress)
        finally:
            wm.progress_end()
            if workspace is not None:
                workspace.status_text_set(None)
        if rc != 0:
            if "--force" in message and not settings.force:
                message += " (the panel's Force runs it anyway)"
            self.report({"ERROR"}, f"segadeform failed: {message}")
            return {"CANCELLED"}
        frames, start, _ = read_pc2(pc2_path)
        if frames.shape[1] != len(garment.data.vertices):
            self.report({"ERROR"}, f"{pc2_path}: {frames.shape[1]} points for {len(garment.data.vertices)} vertices")
            return {"CANCELLED"}
        to_local = local_matrices(scene, garment, arm, up, first, frames.shape[0])
        write_local_pc2(to_local, frames, start, local_path)
        record(folder, names[3:])
        mod = garment.modifiers.get("segadeform") or garment.modifiers.new("segadeform", "MESH_CACHE")
        mod.cache_format = "PC2"
        relative = bool(bpy.data.filepath) and context.preferences.filepaths.use_relative_paths
        try:
            mod.filepath = bpy.path.relpath(local_path) if relative else local_path
        except ValueError:  # another drive than the .blend's
            mod.filepath = local_path
        mod.frame_start = first  # sample k shows at the action's frame first + k
        mod.frame_scale = 1.0
        after = place_modifier(garment, mod)
        span = (first, first + frames.shape[0] - 1)
        if (scene.frame_start, scene.frame_end) != span:
            self.report({"INFO"}, f"segadeform: the scene's frames set to {span[0]}-{span[1]}, the action's")
            scene.frame_start, scene.frame_end = span
        if after:
            moved = ", ".join(after)
            self.report({"WARNING"}, f"segadeform: the modifiers {moved} after the cache move the garment again")
        if warning:
            self.report({"WARNING"}, f"segadeform: {warning} ({folder})")
        self.report({"INFO"}, f"segadeform: {frames.shape[0]} frames attached to {garment.name} ({pc2_path})")
        return {"FINISHED"}


class SegadeformSettings(bpy.types.PropertyGroup):
    effects: bpy.props.StringProperty(
        name="Effects", default="", description="segadeform run --effects (e.g. lbs,dynamics,collisions or -wrinkles)"
    )
    quality: bpy.props.EnumProperty(name="Quality", items=QUALITY, default="NONE")
    force: bpy.props.BoolProperty(
        name="Force",
        default=False,
        description="segadeform run --force: animate a garment that does not sit on segadeform's body, or a motion "
        "it refuses (the result is then likely wrong)",
    )
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
        col.prop(s, "force")
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
