"""Load a segadeform result into Blender in one step: garment and body meshes with their point caches.

Runs inside Blender (GPL-3.0; this script is a separate program, not part of the segadeform package):

    blender --python tools/blender/segadeform_import.py -- --garment out/tshirt.obj --cache out/tshirt_walk.pc2 \\
        [--body out/body_walk.obj --body-cache out/body_walk.pc2] [--frame-start 1]

or from Blender's Python console / another script: ``import_result(...)``.

The recipe (verified in Blender 5.0.1 by ``tests/physics/test_blender_recipe.py``): import the OBJ with
Blender's default OBJ importer (it keeps the file's +Y-up coordinates and turns the *object* 90 degrees
about X), add a Mesh Cache modifier reading the PC2 as segadeform writes it by default (``--up y``: the
cache holds object-local positions, like the OBJ), frame start = the scene frame where the cache's
first sample should show.  Vertex order, count and frames line up exactly.  A cache written with
``--up z`` would be rotated a second time by the object's rotation: do not use it for this.
"""

from __future__ import annotations

import sys

import bpy  # noqa: F401  (Blender's own module: this file only runs inside Blender)


def _import_obj(path: str):
    before = set(bpy.data.objects)
    bpy.ops.wm.obj_import(filepath=path)  # default settings: forward -Z, up Y
    new = [o for o in bpy.data.objects if o not in before]
    if len(new) != 1:
        raise RuntimeError(f"{path}: expected one object from the OBJ import, got {len(new)}")
    return new[0]


def _attach_cache(obj, pc2: str, frame_start: float):
    mod = obj.modifiers.new(name="segadeform cache", type="MESH_CACHE")
    mod.cache_format = "PC2"
    mod.filepath = pc2
    mod.frame_start = frame_start
    mod.frame_scale = 1.0
    return mod


def import_result(garment: str, cache: str, body: str | None = None, body_cache: str | None = None,
                  frame_start: float = 1.0, frames: int | None = None):
    """Import the garment (and body) OBJ, attach the PC2 caches, set the scene's frame range."""
    objs = []
    g = _import_obj(garment)
    _attach_cache(g, cache, frame_start)
    objs.append(g)
    if body:
        b = _import_obj(body)
        if body_cache:
            _attach_cache(b, body_cache, frame_start)
        objs.append(b)
    if frames is None:
        import struct

        with open(cache, "rb") as fh:
            frames = struct.unpack("<12siiffi", fh.read(32))[5]
    scene = bpy.context.scene
    scene.frame_start = int(frame_start)
    scene.frame_end = int(frame_start) + int(frames) - 1
    return objs


def _main(argv):
    import argparse

    ap = argparse.ArgumentParser(prog="segadeform_import.py")
    ap.add_argument("--garment", required=True)
    ap.add_argument("--cache", required=True)
    ap.add_argument("--body")
    ap.add_argument("--body-cache")
    ap.add_argument("--frame-start", type=float, default=1.0)
    a = ap.parse_args(argv)
    import_result(a.garment, a.cache, a.body, a.body_cache, a.frame_start)


if __name__ == "__main__":
    _main(sys.argv[sys.argv.index("--") + 1:] if "--" in sys.argv else sys.argv[1:])
