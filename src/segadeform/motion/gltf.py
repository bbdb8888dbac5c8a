"""glTF 2.0 motion (``.glb``, ``.gltf``): the skeleton and one animation of a skinned character, through
``pygltflib`` (extra ``gltf``), mapped onto SMPL and retargeted by the same code as a BVH file.

Reading (:func:`read_gltf_skeleton`, :func:`read_gltf`):

* **the skeleton** is the first skin's joints (of several skins, the one the animation moves most), their
  parents the nearest ancestor node that is a joint; joints with no joint above them hang from their common
  ancestor node (an ``Armature`` node), which then becomes the root.  Node names are the joint names (the
  name tables, namespaces like ``Armature|`` and the shape rule of
  :mod:`segadeform.body.skeleton_map` apply as for BVH).
* **the rest pose** is the bind pose, the inverse of each joint's ``inverseBindMatrices`` entry (world
  space: glTF ignores the skinned mesh's own transform); a skin without them uses the nodes' own
  translation/rotation/scale.
* **the motion**: every node's world transform per frame, from the animation's channels (``translation``,
  ``rotation``, ``scale``; ``weights`` are morph targets and ignored) over the nodes' own TRS, through the
  whole node tree (an animated or scaled ``Armature`` node included).  Samplers are evaluated as glTF
  defines them: ``LINEAR`` (slerp for rotations), ``STEP`` and ``CUBICSPLINE`` (Hermite, tangents scaled by
  the key interval); before the first key the first value holds, after the last the last.  Rotations are
  taken from the world matrices without their scale; a joint's rotation relative to the rest pose is
  ``R(t) R_rest^T``, as a BVH joint's is with its rest frame the identity.
* **frames**: glTF has no frame rate; the keys give it (:func:`_frame_times`): a sampled export's frames are
  its key times, otherwise frames run from the first key to the last at the keys' rate.
* **units and axes**: glTF's own, metres and +Y up; ``units`` or a number overrides the unit
  (``scale="auto"`` fits the legs to the target body, as for BVH files).

Errors name the file: no skin, no animation, an animation name that is not there (the names are listed),
NaN or infinite keys, times that do not increase, accessors outside their buffers.
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np

from ..body.rotations import quaternion_slerp, quaternion_to_matrix
from ..errors import InputError
from ..io.gltf import MAX_DEPTH, unit_quaternion
from ..io.gltf import GltfFile as _File
from .bvh import BVHSkeleton, skeleton_motion, to_y_up
from .motion import Motion

__all__ = [
    "read_gltf",
    "read_gltf_skeleton",
    "gltf_animations",
    "sample_channel",
    "sample_channel_reference",
    "GLTF_EXTENSIONS",
]

GLTF_EXTENSIONS = (".glb", ".gltf")
_PATH_WIDTH = {"translation": 3, "rotation": 4, "scale": 3}


def gltf_animations(path: str | os.PathLike) -> list[str]:
    """The names of a glTF file's animations (``animationN`` for unnamed ones), in file order."""
    f = _File(Path(path))
    return [a.name or f"animation{k}" for k, a in enumerate(f.g.animations)]


# ---- sampling ----------------------------------------------------------------------------------------------
def sample_channel(
    times: np.ndarray, values: np.ndarray, t: np.ndarray, interpolation: str, rotation: bool = False
) -> np.ndarray:
    """A glTF sampler evaluated at times ``t`` (fast path: all times at once).

    Shapes:
        times: (K,) increasing; values: (K, D), or (3K, D) for CUBICSPLINE (in-tangent, value, out-tangent per
        key); t: (T,) -> (T, D).  Rotations (``rotation=True``) are quaternions ``(x, y, z, w)``: LINEAR is a
        slerp, and every result is normalised.
    """
    times = np.asarray(times, np.float64)
    cubic = interpolation == "CUBICSPLINE"
    v = np.asarray(values, np.float64)
    if cubic:
        v = v.reshape(len(times), 3, -1)
        a_tan, vals, b_tan = v[:, 0], v[:, 1], v[:, 2]
    else:
        vals = v
    k = np.clip(np.searchsorted(times, t, side="right") - 1, 0, len(times) - 1)
    k1 = np.minimum(k + 1, len(times) - 1)
    dt = times[k1] - times[k]
    s = np.where(dt > 0, (t - times[k]) / np.where(dt > 0, dt, 1.0), 0.0)
    s = np.clip(s, 0.0, 1.0)[:, None]
    before, after = t <= times[0], t >= times[-1]
    if interpolation == "STEP":
        out = vals[k]
    elif cubic:
        s2, s3 = s * s, s * s * s
        dtc = dt[:, None]
        out = (
            (2 * s3 - 3 * s2 + 1) * vals[k]
            + (s3 - 2 * s2 + s) * dtc * b_tan[k]
            + (-2 * s3 + 3 * s2) * vals[k1]
            + (s3 - s2) * dtc * a_tan[k1]
        )
    elif rotation:
        q = quaternion_slerp(vals[k][:, [3, 0, 1, 2]], vals[k1][:, [3, 0, 1, 2]], s[:, 0])
        out = q[:, [1, 2, 3, 0]]
    else:
        out = (1 - s) * vals[k] + s * vals[k1]
    out = np.where(before[:, None], vals[0], np.where(after[:, None], vals[-1], out))
    if rotation:
        out = out / np.maximum(np.linalg.norm(out, axis=1, keepdims=True), 1e-12)
    return out


def sample_channel_reference(times, values, t, interpolation, rotation=False) -> np.ndarray:
    """The slow, obvious :func:`sample_channel`: one time at a time, the key interval found by a loop, the
    formulas of the glTF specification (tests compare the two)."""
    times = [float(x) for x in times]
    K = len(times)
    v = np.asarray(values, np.float64)
    if interpolation == "CUBICSPLINE":
        v = v.reshape(K, 3, -1)
    out = []
    for tt in np.asarray(t, np.float64):
        val = (lambda i: v[i, 1]) if interpolation == "CUBICSPLINE" else (lambda i: v[i])
        if tt <= times[0]:
            r = val(0)
        elif tt >= times[-1]:
            r = val(K - 1)
        else:
            i = 0
            while times[i + 1] <= tt:
                i += 1
            d = times[i + 1] - times[i]
            s = (tt - times[i]) / d
            if interpolation == "STEP":
                r = val(i)
            elif interpolation == "CUBICSPLINE":
                p0, m0, p1, m1 = v[i, 1], d * v[i, 2], v[i + 1, 1], d * v[i + 1, 0]
                r = (
                    (2 * s**3 - 3 * s**2 + 1) * p0
                    + (s**3 - 2 * s**2 + s) * m0
                    + (-2 * s**3 + 3 * s**2) * p1
                    + (s**3 - s**2) * m1
                )
            elif rotation:
                a, b = val(i), val(i + 1)
                if a @ b < 0:
                    b = -b
                ang = np.arccos(np.clip(a @ b, -1.0, 1.0))
                r = a if ang < 1e-12 else (np.sin((1 - s) * ang) * a + np.sin(s * ang) * b) / np.sin(ang)
            else:
                r = (1 - s) * val(i) + s * val(i + 1)
        if rotation:
            r = r / np.linalg.norm(r)
        out.append(np.asarray(r, np.float64))
    return np.stack(out)


def _frame_times(key_times: list[np.ndarray]) -> tuple[np.ndarray, float]:
    """The frames' times ``(T,)`` and the frame rate of an animation whose channels have keys at ``key_times``.

    The rate is the longest channel's key count over its span (a sampled export keys every frame); within
    1e-6 of a whole number it is that number.  When that channel's keys are evenly spaced and span the whole
    animation, the frames are its key times themselves (no key is interpolated); otherwise frames run from
    the first key to the last at that rate.  One key in all: one frame at 30 fps.
    """
    t0 = min(float(k[0]) for k in key_times)
    t1 = max(float(k[-1]) for k in key_times)
    longest = max(key_times, key=len)
    if len(longest) < 2:
        return np.array([t0]), 30.0
    fps = (len(longest) - 1) / float(longest[-1] - longest[0])
    if abs(fps - round(fps)) < 1e-6 * fps:
        fps = float(round(fps))
    step = np.diff(longest)
    if np.abs(step - step.mean()).max() < 1e-3 * step.mean() and longest[0] <= t0 and longest[-1] >= t1:
        return np.asarray(longest, np.float64), fps
    n = int(np.floor((t1 - t0) * fps + 1e-6)) + 1
    return t0 + np.arange(n) / fps, fps


# ---- the skeleton and its motion ----------------------------------------------------------------------------
def _trs_matrix(t: np.ndarray, q: np.ndarray, s: np.ndarray) -> np.ndarray:
    """``T R S`` as 4x4 matrices.  Shapes: t (..., 3), q (..., 4) as (x, y, z, w), s (..., 3) -> (..., 4, 4)."""
    R = quaternion_to_matrix(np.asarray(q)[..., [3, 0, 1, 2]])
    M = np.zeros(np.broadcast_shapes(np.shape(t)[:-1], R.shape[:-2]) + (4, 4))
    M[..., :3, :3] = R * np.asarray(s)[..., None, :]
    M[..., :3, 3] = t
    M[..., 3, 3] = 1.0
    return M


def _rotation_part(M: np.ndarray) -> np.ndarray:
    """The rotation nearest each ``M[..., :3, :3]`` (its scale and shear removed).  (..., 4, 4) -> (..., 3, 3)"""
    U, _, Vt = np.linalg.svd(M[..., :3, :3])
    d = np.sign(np.linalg.det(U @ Vt))
    U = U.copy()
    U[..., :, 2] *= d[..., None]
    return U @ Vt


def _node_rest(node, f: _File | None = None, k: int = -1) -> np.ndarray:
    if node.matrix is not None:
        return np.asarray(node.matrix, np.float64).reshape(4, 4).T  # glTF matrices are column-major
    t = np.asarray(node.translation if node.translation is not None else [0, 0, 0], np.float64)
    q = unit_quaternion(
        node.rotation if node.rotation is not None else [0, 0, 0, 1],
        where=f"node {k}'s " if k >= 0 else "",
        error=None if f is None else f.error,
    )
    s = np.asarray(node.scale if node.scale is not None else [1, 1, 1], np.float64)
    return _trs_matrix(t, q, s)


def _pick_animation(f: _File, name: str | None):
    anims = f.g.animations or []
    if not anims:
        raise f.error("glTF has no animation", expected="an animation of the skinned character", got="none")
    names = [a.name or f"animation{k}" for k, a in enumerate(anims)]
    if name is None:
        return anims[0], names[0], names
    if name not in names:
        raise f.error(f"no animation named {name!r}", expected="one of " + ", ".join(repr(n) for n in names), got=name)
    return anims[names.index(name)], name, names


def read_gltf_skeleton(
    path: str | os.PathLike, *, animation: str | None = None, up: str = "auto"
) -> tuple[BVHSkeleton, dict]:
    """A glTF file's skinned skeleton and one animation as a :class:`~segadeform.motion.bvh.BVHSkeleton`
    (metres unless the file's nodes scale it, +Y up; see the module docstring), and what was read
    (``{"animation", "animations", "skin", "joints", "keys"}``)."""
    p = Path(path)
    f = _File(p)
    g = f.g
    nodes = g.nodes or []
    if not g.skins:
        raise f.error("glTF has no skin", expected="a skinned character (a skin with joints)", got="no skins")
    anim, anim_name, anim_names = _pick_animation(f, animation)
    n = len(nodes)
    parent = np.full(n, -1, np.int64)
    for i, nd in enumerate(nodes):
        for c in nd.children or []:
            if not 0 <= c < n or parent[c] >= 0 or c == i:
                raise f.error(f"node {i} has a bad child", expected="each node the child of one other node", got=c)
            parent[c] = i
    for i in range(n):  # a cycle would loop for ever below
        seen, k = 0, i
        while k >= 0:
            k, seen = int(parent[k]), seen + 1
            if seen > n:
                raise f.error("the node hierarchy has a cycle", got=f"node {i}")
            if seen > MAX_DEPTH:  # (5,000 nested nodes: a RecursionError traceback, a fuzzer's trial)
                raise f.error("nodes nest too deeply", expected=f"at most {MAX_DEPTH} levels", got=f"node {i}")
    # the channels of the animation, validated
    channels = []
    key_times = []
    for ci, ch in enumerate(anim.channels or []):
        tgt = ch.target
        if tgt is None or tgt.path not in _PATH_WIDTH or tgt.node is None:
            continue  # morph weights, or a channel aimed at nothing
        if not 0 <= tgt.node < n:
            raise f.error(f"animation {anim_name!r} channel {ci} names a node that is not there", got=tgt.node)
        if not 0 <= ch.sampler < len(anim.samplers):
            raise f.error(f"animation {anim_name!r} channel {ci} names a sampler that is not there", got=ch.sampler)
        smp = anim.samplers[ch.sampler]
        interp = smp.interpolation or "LINEAR"
        if interp not in ("LINEAR", "STEP", "CUBICSPLINE"):
            raise f.error(
                f"animation {anim_name!r}: unknown interpolation", expected="LINEAR, STEP or CUBICSPLINE", got=interp
            )
        times = f.accessor(smp.input, f"animation {anim_name!r} sampler {ch.sampler} input")[:, 0]
        vals = f.accessor(smp.output, f"animation {anim_name!r} sampler {ch.sampler} output")
        width = _PATH_WIDTH[tgt.path]
        if vals.shape[1] != width or len(vals) != len(times) * (3 if interp == "CUBICSPLINE" else 1) or not len(times):
            raise f.error(
                f"animation {anim_name!r} sampler {ch.sampler} does not fit its {tgt.path} channel",
                expected=f"{width} values per key, one key per time",
                got=f"{vals.shape} for {len(times)} times",
            )
        if not (np.isfinite(times).all() and np.isfinite(vals).all()):
            raise f.error(
                f"animation {anim_name!r} has NaN or infinite keys (node {nodes[tgt.node].name!r}, {tgt.path})",
                expected="finite numbers",
            )
        if (np.diff(times) <= 0).any():
            raise f.error(f"animation {anim_name!r}: key times do not increase (sampler {ch.sampler})")
        channels.append((tgt.node, tgt.path, times, vals, interp))
        key_times.append(times)
    if not channels:
        raise f.error(f"animation {anim_name!r} moves no node", expected="translation, rotation or scale channels")
    # which skin: the one whose joints the animation moves most
    moved = {c[0] for c in channels}
    skin = max(g.skins, key=lambda s: len(moved & set(s.joints or [])))
    joints = list(skin.joints or [])
    if not joints or any(not 0 <= j < n for j in joints) or len(set(joints)) != len(joints):
        raise f.error("the skin's joints are not distinct nodes", got=joints[:10])
    t, fps = _frame_times(key_times)
    nf, t0, longest = len(t), float(t[0]), max(key_times, key=len)
    # local transforms per frame of every node on the way to the joints
    needed = set()
    for j in joints:
        k = j
        while k >= 0 and k not in needed:
            needed.add(k)
            k = int(parent[k])
    local = {}
    for k in needed:
        nd = nodes[k]
        anim_k = {path: (times, vals, interp) for node, path, times, vals, interp in channels if node == k}
        if not anim_k:
            local[k] = np.broadcast_to(_node_rest(nd, f, k), (nf, 4, 4))
            continue
        if nd.matrix is not None:
            raise f.error(f"node {nd.name!r} is animated but has a matrix", expected="translation/rotation/scale")
        tr = np.asarray(nd.translation if nd.translation is not None else [0, 0, 0], np.float64)
        ro = np.asarray(nd.rotation if nd.rotation is not None else [0, 0, 0, 1], np.float64)
        sc = np.asarray(nd.scale if nd.scale is not None else [1, 1, 1], np.float64)
        cur = {
            "translation": np.broadcast_to(tr, (nf, 3)),
            "rotation": np.broadcast_to(ro, (nf, 4)),
            "scale": np.broadcast_to(sc, (nf, 3)),
        }
        for pth, (times, vals, interp) in anim_k.items():
            cur[pth] = sample_channel(times, vals, t, interp, rotation=pth == "rotation")
        local[k] = _trs_matrix(cur["translation"], cur["rotation"], cur["scale"])
    world: dict[int, np.ndarray] = {}
    rest_world: dict[int, np.ndarray] = {}

    def walk(k):
        if k in world:
            return
        pk = int(parent[k])
        if pk >= 0:
            walk(pk)
            world[k] = world[pk] @ local[k]
            rest_world[k] = rest_world[pk] @ _node_rest(nodes[k], f, k)
        else:
            world[k], rest_world[k] = np.asarray(local[k]), _node_rest(nodes[k], f, k)

    for k in needed:
        walk(k)
    # the joint hierarchy; joints without a joint above hang from their common ancestor node
    jset = set(joints)

    def joint_parent(j):
        k = int(parent[j])
        while k >= 0 and k not in jset:
            k = int(parent[k])
        return k

    roots = [j for j in joints if joint_parent(j) < 0]
    if len(roots) > 1:
        anc = None
        for r in roots:
            chain = []
            k = int(parent[r])
            while k >= 0:
                chain.append(k)
                k = int(parent[k])
            anc = chain if anc is None else [a for a in anc if a in chain]
        if not anc:
            raise f.error(
                "the skin's joints form several separate trees",
                expected="one skeleton",
                got=", ".join(str(nodes[r].name) for r in roots[:6]),
            )
        joints = [anc[0]] + joints
        jset.add(anc[0])
    ibm = None
    if skin.inverseBindMatrices is not None:
        m = f.accessor(skin.inverseBindMatrices, "the skin's inverseBindMatrices")
        if m.shape != (len(skin.joints), 16):
            raise f.error("inverseBindMatrices do not fit the joints", expected=(len(skin.joints), 16), got=m.shape)
        if not np.isfinite(m).all():
            raise f.error("inverseBindMatrices contain NaN or inf")
        ibm = {jn: m[k].reshape(4, 4).T for k, jn in enumerate(skin.joints)}
    rest_m = []
    for j in joints:
        if ibm is not None and j in ibm:
            if abs(np.linalg.det(ibm[j][:3, :3])) < 1e-12:
                raise f.error(f"joint {nodes[j].name!r} has a singular inverse bind matrix")
            rest_m.append(np.linalg.inv(ibm[j]))
        else:
            rest_m.append(rest_world[j])
    rest_m = np.stack(rest_m)  # (J, 4, 4)
    W = np.stack([world[j] for j in joints], axis=1)  # (T, J, 4, 4)
    R0 = _rotation_part(rest_m)
    G = _rotation_part(W) @ np.swapaxes(R0, -1, -2)[None]
    P = W[..., :3, 3]
    rest = rest_m[:, :3, 3]
    names = [nodes[j].name or f"node{j}" for j in joints]
    pos_of = {j: i for i, j in enumerate(joints)}
    parents = np.array([pos_of.get(joint_parent(j), -1) for j in joints], np.int64)
    if up not in ("auto", "y", "z"):
        raise InputError("up must be 'auto', 'y' or 'z'", got=up)
    sk = to_y_up(names, parents, rest, rest.copy(), G, P, fps, "y" if up == "auto" else up)
    info = {
        "animation": anim_name,
        "animations": anim_names,
        "skin": skin.name or f"skin{g.skins.index(skin)}",
        "joints": len(joints),
        "keys": int(len(longest)),
        "start_time": t0,
    }
    return sk, info


def read_gltf(
    path: str | os.PathLike,
    *,
    rest_joints: np.ndarray | None = None,
    scale: float | str = "auto",
    units=None,
    up: str = "auto",
    joint_map=None,
    animation: str | None = None,
) -> Motion:
    """A glTF/GLB character animation on the 24-joint SMPL skeleton (see the module docstring).

    Args as :func:`~segadeform.motion.bvh.read_bvh`; ``animation``: its name when the file has several
    (default: the first).  Without ``rest_joints`` the file's own skeleton is kept in metres (glTF's unit).
    ``Motion.meta`` adds the animation's name and the file's animations to the BVH reader's record.
    """
    p = Path(path)
    sk, info = read_gltf_skeleton(p, animation=animation, up=up)
    if rest_joints is None and units is None and scale == "auto":
        scale = 1.0  # glTF is in metres
    m = skeleton_motion(sk, p, rest_joints=rest_joints, scale=scale, units=units, joint_map=joint_map, fmt="gltf")
    m.meta.update(info)
    return m
