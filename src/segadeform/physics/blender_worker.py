"""Blender side of the simulator bridge: run by the simulator environment's Python, never imported.

Usage (by :mod:`segadeform.physics.blender`)::

    SIM_PYTHON blender_worker.py JOB_DIR

``JOB_DIR/job.json`` names the inputs (``.npy`` files and a PC2 body cache in
Blender's Z-up frame) and every solver setting; nothing is read from Blender's
own defaults except where the job leaves a setting out.  The worker writes
``frames.npy`` (F, N, 3) float32, the recorded garment frames in the garment's
vertex order, and ``result.json`` (timings, Blender version, a check of the
body playback).  Progress goes to stdout as ``FRAME i n`` lines.

This file depends on ``bpy`` and numpy only (Blender is GPL-3.0 and pins
numpy<2; keeping it in its own interpreter keeps both out of segadeform).
"""

import json
import os
import sys
import time


def _mesh_object(bpy, name, verts, faces):
    me = bpy.data.meshes.new(name)
    me.from_pydata([tuple(map(float, v)) for v in verts], [], [tuple(map(int, f)) for f in faces])
    me.validate(clean_customdata=False)
    me.update()
    if len(me.vertices) != len(verts):
        raise RuntimeError(f"{name}: Blender changed the vertex count ({len(verts)} -> {len(me.vertices)})")
    ob = bpy.data.objects.new(name, me)
    bpy.context.scene.collection.objects.link(ob)
    return ob


def _mesh_cache(obj, path):
    """Play a PC2 point cache (frame 1 = the cache's first sample) on ``obj``'s vertices."""
    mc = obj.modifiers.new("cache", "MESH_CACHE")
    mc.cache_format = "PC2"
    mc.filepath = path
    mc.play_mode = "SCENE"
    mc.time_mode = "FRAME"
    mc.frame_start = 1.0
    return mc


def _set(obj, name, value):
    if not hasattr(obj, name):
        raise RuntimeError(f"this Blender has no setting {type(obj).__name__}.{name}")
    setattr(obj, name, value)


def main(job_dir):
    import bpy
    import numpy as np

    t0 = time.perf_counter()
    with open(os.path.join(job_dir, "job.json")) as fh:
        job = json.load(fh)
    load = lambda k: np.load(os.path.join(job_dir, job[k]))  # noqa: E731
    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = bpy.context.scene
    fps = float(job["fps"])
    scene.render.fps = max(1, int(round(fps)))
    scene.render.fps_base = scene.render.fps / fps
    total = int(job["total_frames"])
    scene.frame_start, scene.frame_end = 1, total
    eff = job["effects"]
    scene.use_gravity = bool(eff["gravity"])
    scene.gravity = (0.0, 0.0, -9.81)

    body = None  # the collider: only with body_collision (the job names no body otherwise)
    if job.get("body_cache"):
        body = _mesh_object(bpy, "body", load("body_rest"), load("body_faces"))
        _mesh_cache(body, os.path.join(job_dir, job["body_cache"]))
        if eff["body_collision"]:
            body.modifiers.new("collision", "COLLISION")
            for k, v in job["body_collision"].items():
                _set(body.collision, k, v)

    garment = _mesh_object(bpy, "garment", load("garment_rest"), load("garment_faces"))
    pins = job.get("pins")
    if pins:
        vg = garment.vertex_groups.new(name="pin")
        w = load("pins")
        for value in sorted(set(float(x) for x in w[w > 0])):
            idx = [int(i) for i in np.nonzero(w == value)[0]]
            vg.add(idx, value, "REPLACE")
    if job.get("garment_cache"):  # pinned vertices follow this input (the skinned garment)
        _mesh_cache(garment, os.path.join(job_dir, job["garment_cache"]))
    rest_shape = None
    if job.get("garment_rest_shape"):  # rest lengths from another shape than the starting one
        garment.shape_key_add(name="start")
        key = garment.shape_key_add(name="rest", from_mix=False)
        for i, co in enumerate(load("garment_rest_shape")):
            key.data[i].co = (float(co[0]), float(co[1]), float(co[2]))
        key.value = 0.0
        rest_shape = key
    cloth = garment.modifiers.new("cloth", "CLOTH")
    s = cloth.settings
    for k, v in job["cloth"].items():
        _set(s, k, v)
    if rest_shape is not None:
        s.rest_shape_key = rest_shape
    s.effector_weights.gravity = 1.0 if eff["gravity"] else 0.0
    s.effector_weights.wind = 1.0 if eff["wind"] else 0.0
    if pins:
        s.vertex_group_mass = "pin"
    c = cloth.collision_settings
    c.use_collision = bool(eff["body_collision"])
    c.use_self_collision = bool(eff["self_collision"])
    for k, v in job["collision"].items():
        _set(c, k, v)
    cloth.point_cache.frame_start = 1
    cloth.point_cache.frame_end = total
    if eff["wind"]:
        # a force field needs its field settings, which only the operator creates
        bpy.ops.object.effector_add(type="WIND", location=(0.0, 0.0, 0.0))
        wind = bpy.context.view_layer.objects.active
        wind.name = "wind"
        wind.field.strength = float(job["wind"]["strength"])
        wind.field.flow = float(job["wind"].get("flow", 0.0))
        d = np.asarray(job["wind"]["direction"], float)
        d = d / np.linalg.norm(d)
        # a wind field blows along its local +Z: rotate +Z onto d
        wind.rotation_mode = "QUATERNION"
        z = np.array([0.0, 0.0, 1.0])
        axis = np.cross(z, d)
        s_ = np.linalg.norm(axis)
        ang = np.arctan2(s_, float(z @ d))
        axis = axis / s_ if s_ > 1e-12 else np.array([1.0, 0.0, 0.0])
        wind.rotation_quaternion = (np.cos(ang / 2), *(np.sin(ang / 2) * axis))

    record = int(job["record_start"])
    n = len(garment.data.vertices)
    out = np.empty((total - record + 1, n, 3), np.float32)
    buf = np.empty(n * 3, np.float32)
    body_check = [int(f) for f in job.get("check_body_frames", [])]
    body_ref = load("body_check") if body_check else None
    body_err = 0.0
    t_setup = time.perf_counter() - t0
    t1 = time.perf_counter()
    for f in range(1, total + 1):
        scene.frame_set(f)
        dg = bpy.context.evaluated_depsgraph_get()
        if f >= record:
            me = garment.evaluated_get(dg).data
            if len(me.vertices) != n:
                raise RuntimeError("the cloth modifier changed the vertex count")
            me.vertices.foreach_get("co", buf)
            out[f - record] = buf.reshape(n, 3)
        if body is not None and f in body_check:
            bme = body.evaluated_get(dg).data
            bb = np.empty(len(bme.vertices) * 3, np.float32)
            bme.vertices.foreach_get("co", bb)
            ref = body_ref[body_check.index(f)]
            body_err = max(body_err, float(np.abs(bb.reshape(-1, 3) - ref).max()))
        sys.stdout.write(f"FRAME {f} {total}\n")
        sys.stdout.flush()
    t_sim = time.perf_counter() - t1
    tmp = os.path.join(job_dir, "frames.tmp.npy")
    np.save(tmp, out)
    os.replace(tmp, os.path.join(job_dir, "frames.npy"))
    applied = {  # read back from Blender: what the solver actually ran with
        "use_gravity": bool(scene.use_gravity),
        "cloth": {k: getattr(s, k) for k in job["cloth"]},
        "collision": {k: getattr(c, k) for k in job["collision"]},
        "use_collision": bool(c.use_collision),
        "use_self_collision": bool(c.use_self_collision),
        "effector_gravity": float(s.effector_weights.gravity),
        "effector_wind": float(s.effector_weights.wind),
        "vertex_group_mass": s.vertex_group_mass,
        "body_modifiers": [m.type for m in body.modifiers] if body is not None else [],
        "garment_modifiers": [m.type for m in garment.modifiers],
        "objects": sorted(o.name for o in scene.objects),
    }
    res = {
        "blender_version": bpy.app.version_string,
        "applied": applied,
        "setup_seconds": t_setup,
        "simulate_seconds": t_sim,
        "seconds_per_frame": t_sim / total,
        "simulated_frames": total,
        "recorded_frames": int(len(out)),
        "body_playback_max_error": body_err,
    }
    with open(os.path.join(job_dir, "result.json"), "w") as fh:
        json.dump(res, fh)


if __name__ == "__main__":
    if sys.argv[-1] == "--version":
        import bpy

        sys.stdout.write(bpy.app.version_string + "\n")
    else:
        main(sys.argv[-1])
