"""Blender side of FBX motion reading: run by the simulator environment's Python, never imported.

Usage (by :mod:`segadeform.physics.fbx`)::

    SIM_PYTHON fbx_worker.py SRC.fbx DST.bvh INFO.json [ANIMATION]

Imports ``SRC.fbx`` with Blender's own FBX importer (``io_scene_fbx``), picks an armature and one of its
animations (the module docstring of :mod:`segadeform.physics.fbx` says which) and writes ``DST.bvh`` from the
bones' *world* transforms, sampled at every frame of the animation's range: root motion on the armature object or
on an animated parent (a MotionBuilder ``Reference`` null) is kept, and the file is always +Y up, in metres (the
objects' scales applied), whatever the FBX file's axes, units and bone orientations.  The BVH's rest pose is the
armature's rest placed as the armature stands at the first frame; its joint names are the bones' with white space
turned into ``_`` (BVH names are single words).  A bone whose head moves against its parent (a stretchy or
translated bone) gets position channels.  ``DST.bvh`` is written to ``DST.bvh.part`` and renamed when complete.

``INFO.json`` gets what was read (armatures, animations, the one taken, frames, frame rate) or ``{"error": ...}``
for a file that holds no animated skeleton; the exit status is 0 in both cases and non-zero only when Blender
itself failed.

This file depends on ``bpy`` and ``mathutils`` only (Blender is GPL-3.0; keeping it in its own interpreter keeps
it out of segadeform).
"""

import json
import math
import os
import re
import sys

#: Blender's world (+Z up) to the BVH's (+Y up): (x, y, z) -> (x, z, -y)
_Q = ((1.0, 0.0, 0.0), (0.0, 0.0, 1.0), (0.0, -1.0, 0.0))


def _fail(info_path, message, **extra):
    with open(info_path, "w") as fh:
        json.dump({"error": message, **extra}, fh)


def _curves(act):
    """Every F-curve of ``act``: the layered actions of Blender 4.4+ (layers, strips, channel bags) and the
    flat ones before."""
    out = list(getattr(act, "fcurves", None) or [])
    for layer in getattr(act, "layers", None) or []:
        for strip in layer.strips:
            for bag in getattr(strip, "channelbags", None) or []:
                out.extend(bag.fcurves)
    return out


def _action_bones(act):
    """The bone names ``act`` animates (its ``pose.bones["NAME"]...`` curves)."""
    names = set()
    for fc in _curves(act):
        m = re.match(r'pose\.bones\["((?:[^"\\]|\\.)*)"\]', fc.data_path)
        if m:
            names.add(m.group(1).replace('\\"', '"').replace("\\\\", "\\"))
    return names


def _skinned(bpy, arm):
    return any(
        m.type == "ARMATURE" and m.object is arm
        for ob in bpy.context.scene.objects
        if ob.type == "MESH"
        for m in ob.modifiers
    )


def _assign(arm, act):
    if arm.animation_data is None:
        arm.animation_data_create()
    ad = arm.animation_data
    ad.action = act
    slots = getattr(act, "slots", None)  # Blender 4.4+: an action plays through one of its slots
    if slots and getattr(ad, "action_slot", None) is None:
        ok = [s for s in slots if getattr(s, "target_id_type", "OBJECT") == "OBJECT"] or list(slots)
        ad.action_slot = ok[0]


def _resolve(name, actions):
    """The action ``name`` names: its full name, or the take name after its last ``|`` when one action has it."""
    if name in actions:
        return name
    short = [a for a in actions if a.rsplit("|", 1)[-1] == name]
    return short[0] if len(short) == 1 else None


def _names(bones):
    """BVH joint names: white space turned into ``_``, unique."""
    out, used = [], set()
    for i, b in enumerate(bones):
        n = "_".join(b.name.split()) or f"joint{i}"
        base, k = n, 1
        while n in used:
            k += 1
            n = f"{base}_{k}"
        used.add(n)
        out.append(n)
    return out


def _num(xs):
    return " ".join(f"{x:.6f}" for x in xs)


def _write_bvh(path, names, parents, offsets, ends, channels, frames, fps):
    """Write a BVH: joints in ``names`` order (each parent before its children); ``channels[j]`` 6 or 3;
    ``frames``: per frame, per joint ``(position or None, (z, x, y) degrees)``."""
    children = {j: [] for j in range(-1, len(names))}
    for j, p in enumerate(parents):
        children[p].append(j)
    lines = ["HIERARCHY"]
    order = []

    def joint(j, depth):
        ind = "\t" * depth
        lines.append(f"{ind}{'ROOT' if depth == 0 else 'JOINT'} {names[j]}")
        lines.append(ind + "{")
        lines.append(ind + "\tOFFSET " + _num(offsets[j]))
        if channels[j] == 6:
            lines.append(ind + "\tCHANNELS 6 Xposition Yposition Zposition Zrotation Xrotation Yrotation")
        else:
            lines.append(ind + "\tCHANNELS 3 Zrotation Xrotation Yrotation")
        order.append(j)
        if children[j]:
            for c in children[j]:
                joint(c, depth + 1)
        else:
            lines.append(ind + "\tEnd Site")
            lines.append(ind + "\t{")
            lines.append(ind + "\t\tOFFSET " + _num(ends[j]))
            lines.append(ind + "\t}")
        lines.append(ind + "}")

    roots = children[-1]
    if len(roots) == 1:
        joint(roots[0], 0)
    else:  # several root bones: one root above them, at the origin, that never moves
        lines += ["ROOT __root", "{", "\tOFFSET 0.000000 0.000000 0.000000", "\tCHANNELS 0"]
        for r in roots:
            joint(r, 1)
        lines.append("}")
    lines += ["MOTION", f"Frames: {len(frames)}", f"Frame Time: {1.0 / fps:.17g}"]  # 1/x gives the rate back
    for fr in frames:
        vals = []
        for j in order:
            pos, rot = fr[j]
            if channels[j] == 6:
                vals.append(_num(pos))
            vals.append(_num(rot))
        lines.append(" ".join(vals))
    tmp = path + ".part"
    with open(tmp, "w", encoding="utf-8", newline="\n") as fh:
        fh.write("\n".join(lines) + "\n")
    os.replace(tmp, path)


def convert(src, dst, info_path, animation=None):
    import bpy
    from mathutils import Euler, Matrix

    bpy.ops.wm.read_factory_settings(use_empty=True)
    try:
        bpy.ops.import_scene.fbx(filepath=src, use_anim=True)
    except RuntimeError as e:  # the importer's own report: not an FBX file, an ASCII FBX, an FBX too old ...
        lines = [s.strip() for s in str(e).splitlines() if s.strip()]
        why = lines[-1] if lines else str(e)
        why = re.sub(r"Couldn't open file\s*'.*?'\s*", "cannot open it ", why).replace(f"'{src}'", "")
        why = " ".join(why.split())
        why = why[len("Error:") :].strip() if why.startswith("Error:") else why
        return _fail(info_path, f"Blender's FBX importer could not read it ({why})")
    scene = bpy.context.scene
    arms = [ob for ob in scene.objects if ob.type == "ARMATURE"]
    if not arms:
        return _fail(info_path, "it holds no armature (skeleton) to read a motion from")
    bone_names = {ob.name: {b.name for b in ob.data.bones} for ob in arms}
    animates = {}  # action name -> {armature name: bones of it the action animates}
    for act in bpy.data.actions:
        hit = {a: len(_action_bones(act) & bones) for a, bones in bone_names.items()}
        hit = {a: n for a, n in hit.items() if n}
        if hit:
            animates[act.name] = hit
    actions = sorted(animates)
    skinned = {ob.name: _skinned(bpy, ob) for ob in arms}
    if not actions:
        return _fail(info_path, "its armature has no animation", armatures=[a.name for a in arms])
    if animation is not None:
        full = _resolve(animation, actions)
        if full is None:
            return _fail(info_path, f"it has no armature animation {animation!r}", actions=actions)
        act = bpy.data.actions[full]
        arm = max(arms, key=lambda ob: (animates[full].get(ob.name, 0), skinned[ob.name], len(ob.data.bones)))
        if arm.animation_data is None or arm.animation_data.action is not act:
            _assign(arm, act)
    else:
        playing = [
            ob
            for ob in arms
            if ob.animation_data is not None
            and ob.animation_data.action is not None
            and ob.name in animates.get(ob.animation_data.action.name, {})
        ]
        if not playing:  # animations there, none given to an armature by the importer: the one that animates most
            full = max(actions, key=lambda a: max(animates[a].values()))
            arm = max(arms, key=lambda ob: (animates[full].get(ob.name, 0), skinned[ob.name]))
            _assign(arm, bpy.data.actions[full])
            playing = [arm]
        # a character (a mesh skinned to it) before a prop's rig; then the most bones animated
        arm = max(
            playing,
            key=lambda ob: (skinned[ob.name], animates[ob.animation_data.action.name][ob.name], len(ob.data.bones)),
        )
        act = arm.animation_data.action
    start, end = (int(round(f)) for f in act.frame_range)
    if end <= start:
        return _fail(info_path, f"its animation {act.name!r} has one frame", actions=actions)
    fps = scene.render.fps / scene.render.fps_base

    bones = list(arm.data.bones)  # parents before children (Blender keeps them so)
    index = {b.name: i for i, b in enumerate(bones)}
    parents = [index[b.parent.name] if b.parent is not None else -1 for b in bones]
    names = _names(bones)
    Q = Matrix(_Q)
    Qt = Q.transposed()
    scene.frame_set(start)
    mw0 = arm.matrix_world.copy()
    rest_rot, rest_pos, end_off = [], [], []
    for b in bones:
        m = mw0 @ b.matrix_local
        rest_rot.append(Q @ m.to_3x3().normalized() @ Qt)  # normalized(): the columns, i.e. without the scale
        rest_pos.append(Q @ m.translation)
        end_off.append(Q @ ((mw0 @ b.tail_local) - m.translation))
    offsets = [rest_pos[j] if parents[j] < 0 else rest_pos[j] - rest_pos[parents[j]] for j in range(len(bones))]
    # per frame: each bone's world rotation against its rest (G) and head position, +Y up
    globs, heads = [], []
    for f in range(start, end + 1):
        scene.frame_set(f)
        mw = arm.matrix_world
        g_f, h_f = [], []
        for j, b in enumerate(bones):
            m = mw @ arm.pose.bones[b.name].matrix
            g_f.append(Q @ m.to_3x3().normalized() @ Qt @ rest_rot[j].transposed())
            h_f.append(Q @ m.translation)
        globs.append(g_f)
        heads.append(h_f)
    size = max(1e-9, max(abs(x) for p in rest_pos for x in p))
    local_pos = []  # per frame, per joint: the head against the parent, in the parent's rest frame
    channels = []
    for j in range(len(bones)):
        p = parents[j]
        if p < 0:
            local_pos.append([heads[t][j] for t in range(len(heads))])
            channels.append(6)
            continue
        lp = [globs[t][p].transposed() @ (heads[t][j] - heads[t][p]) for t in range(len(heads))]
        moved = max(max(abs(x) for x in (v - offsets[j])) for v in lp)
        local_pos.append(lp)
        channels.append(6 if moved > 1e-5 * size else 3)
    frames = []
    prev = [Euler((0.0, 0.0, 0.0), "YXZ") for _ in bones]
    for t in range(len(globs)):
        fr = []
        for j in range(len(bones)):
            p = parents[j]
            loc = globs[t][j] if p < 0 else globs[t][p].transposed() @ globs[t][j]
            e = loc.to_euler("YXZ", prev[j])  # Rz Rx Ry: BVH's "Zrotation Xrotation Yrotation"
            prev[j] = e
            fr.append((tuple(local_pos[j][t]), (math.degrees(e.z), math.degrees(e.x), math.degrees(e.y))))
        frames.append(fr)
    _write_bvh(dst, names, parents, offsets, end_off, channels, frames, fps)
    with open(info_path, "w") as fh:
        json.dump(
            {
                "armature": arm.name,
                "armatures": [a.name for a in arms],
                "bones": len(bones),
                "animation": act.name,
                "actions": actions,
                "frames": end - start + 1,
                "skinned": skinned[arm.name],
                "fps": fps,
                "renamed": sum(1 for b, n in zip(bones, names, strict=True) if b.name != n),
                "blender": bpy.app.version_string,
            },
            fh,
        )


if __name__ == "__main__":
    args = sys.argv[sys.argv.index("--") + 1 :] if "--" in sys.argv else sys.argv[1:]
    convert(*args[:3], animation=args[3] if len(args) > 3 else None)
