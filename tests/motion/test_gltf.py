"""glTF/GLB motion (extra 'gltf'): the sampler against its slow reference; GLB files built here (joints with
their own rest orientations, an Armature node scaling centimetres to metres) read like the same motion as a
BVH file; animation choice; bad files; and a GLB that Blender exports from an armature animated by a BVH
(Blender's BVH importer and glTF exporter, in the simulator's environment), whose posed body matches the BVH
path within 1e-5 m."""

from __future__ import annotations

import json
import subprocess

import numpy as np
import pytest
from click.testing import CliRunner

pytest.importorskip("pygltflib", reason="glTF motion needs the 'gltf' extra")

from segadeform.body.skeleton import default_rest_joints
from segadeform.errors import FileFormatError
from segadeform.motion import load_motion, read_bvh
from segadeform.motion.gltf import gltf_animations, sample_channel, sample_channel_reference

from ..conftest import SAMPLES
from .bvh_build import write_skeleton_bvh
from .gltf_build import write_skeleton_glb
from .namings import naming_motion, naming_skeleton


@pytest.mark.parametrize("interp", ["LINEAR", "STEP", "CUBICSPLINE"])
@pytest.mark.parametrize("rotation", [False, True])
def test_sampler_matches_reference(interp, rotation):
    rng = np.random.default_rng(1)
    times = np.cumsum(rng.uniform(0.01, 0.1, size=9))
    d = 4 if rotation else 3
    vals = rng.normal(size=(9 * (3 if interp == "CUBICSPLINE" else 1), d))
    if rotation:
        vals /= np.linalg.norm(vals, axis=1, keepdims=True)
    t = np.concatenate([[times[0] - 0.5], np.linspace(times[0], times[-1], 57), times, [times[-1] + 1]])
    fast = sample_channel(times, vals, t, interp, rotation=rotation)
    ref = sample_channel_reference(times, vals, t, interp, rotation=rotation)
    if rotation:  # q and -q are one rotation
        ref = ref * np.sign(np.sum(fast * ref, axis=1, keepdims=True))
    np.testing.assert_allclose(fast, ref, atol=1e-12)


def _pair(tmp_path, kind="unity", *, rename=False, frames=20, **glb):
    """The same motion of naming ``kind`` as a BVH (metres) and a GLB (centimetres under an Armature node
    scaled 0.01, joints with random rest orientations)."""
    names, parents, rest, expected, twist = naming_skeleton(kind)
    loc, root = naming_motion(parents, rest, names, twist, frames=frames)
    out = [f"j{i}" for i in range(len(names))] if rename else names
    bvh = write_skeleton_bvh(tmp_path / "m.bvh", out, parents, rest, loc, root)
    glb_path = write_skeleton_glb(
        tmp_path / "m.glb", out, parents, rest * 100, loc, root * 100, armature_scale=0.01, **glb
    )
    return bvh, glb_path


@pytest.mark.parametrize("kind, rename", [("unity", False), ("character-creator", False), ("vroid", True)])
def test_glb_reads_like_the_bvh(tmp_path, kind, rename):
    bvh, glb = _pair(tmp_path, kind, rename=rename)
    J = default_rest_joints()
    a, b = read_bvh(bvh, rest_joints=J), load_motion(glb, rest_joints=J)
    assert b.meta["format"] == "gltf" and b.meta["mapped"] == a.meta["mapped"]
    assert b.meta["scheme"] == a.meta["scheme"] and b.meta["animation"] == "take"
    assert b.fps == 30.0 and b.n_frames == a.n_frames
    np.testing.assert_allclose(b.poses, a.poses, atol=2e-5)  # float32 in the GLB
    np.testing.assert_allclose(b.trans, a.trans, atol=2e-6)
    own = load_motion(glb)  # no target body: glTF's metres, not a guessed unit
    assert own.meta["scale"] == 1.0 and own.meta["units_guess"] == "m"


def test_cubic_spline_keys_are_the_values(tmp_path):
    """CUBICSPLINE with zero tangents passes through its keys: the frames (at the keys) are the LINEAR file's."""
    _, lin = _pair(tmp_path)
    cub = write_skeleton_glb(tmp_path / "c.glb", *_args(), armature_scale=0.01, interpolation="CUBICSPLINE")
    a, b = load_motion(lin), load_motion(cub)
    np.testing.assert_allclose(b.poses, a.poses, atol=1e-12)


def _args(kind="unity", frames=20):
    names, parents, rest, _, twist = naming_skeleton(kind)
    loc, root = naming_motion(parents, rest, names, twist, frames=frames)
    return names, parents, rest * 100, loc, root * 100


def test_animation_is_chosen_by_name(tmp_path):
    f = write_skeleton_glb(tmp_path / "two.glb", *_args(), armature_scale=0.01, animations=("walk", "fast"))
    assert gltf_animations(f) == ["walk", "fast"]
    first, fast = load_motion(f), load_motion(f, animation="fast")
    assert first.meta["animation"] == "walk" and fast.meta["animation"] == "fast"
    assert (first.n_frames, fast.n_frames) == (20, 10)
    np.testing.assert_allclose(fast.poses, first.poses[::2], atol=1e-5)
    with pytest.raises(FileFormatError, match=r"two\.glb: no animation named 'run'.*'walk', 'fast'"):
        load_motion(f, animation="run")
    with pytest.raises(FileFormatError, match="animation name applies to glTF files only"):
        load_motion(SAMPLES / "motions" / "walk.npz", animation="walk")


@pytest.mark.parametrize(
    "what, kw, message",
    [
        ("noskin", {"skin": False}, "glTF has no skin"),
        ("noanim", {"animations": ()}, "glTF has no animation"),
        ("nan", {"nan_key": True}, "animation 'take' has NaN or infinite keys"),
    ],
)
def test_bad_gltf_gives_one_line_and_no_output(tmp_path, what, kw, message):
    f = write_skeleton_glb(tmp_path / f"{what}.glb", *_args(), armature_scale=0.01, **kw)
    with pytest.raises(FileFormatError, match=f"{what}.glb: {message}"):
        load_motion(f)
    from segadeform.cli.main import cli

    out = tmp_path / "out"
    r = CliRunner().invoke(
        cli,
        [
            "run",
            "--garment",
            str(SAMPLES / "garments" / "dress.obj"),
            "--motion",
            str(f),
            "-o",
            str(out / "dress.pc2"),
            "--no-cache",
        ],
    )
    assert r.exit_code == 1
    lines = [ln for ln in r.output.splitlines() if ln.strip()]
    assert len(lines) == 1 and lines[0].startswith(f"Error: {f}: {message.split(' (')[0]}"), r.output
    assert not out.exists() or not any(out.iterdir())


def test_not_a_gltf(tmp_path):
    (tmp_path / "x.glb").write_bytes(b"glTF\x02\x00\x00\x00garbage")
    with pytest.raises(FileFormatError, match=r"x\.glb: not a readable glTF file"):
        load_motion(tmp_path / "x.glb")
    with pytest.raises(FileFormatError, match=r"y\.gltf: no such file"):
        load_motion(tmp_path / "y.gltf")


# ---- a GLB made by Blender ---------------------------------------------------------------------------------
BLENDER_EXPORT = r"""
import sys, json
import bpy
bvh, glb = sys.argv[1], sys.argv[2]
bpy.ops.wm.read_factory_settings(use_empty=True)
bpy.ops.import_anim.bvh(filepath=bvh, global_scale=float(sys.argv[3]), update_scene_fps=True,
                        update_scene_duration=True, rotate_mode="QUATERNION")
arm = next(o for o in bpy.data.objects if o.type == "ARMATURE")
scene = bpy.context.scene
# glTF writes a skin for a skinned mesh: a triangle bound to the armature
me = bpy.data.meshes.new("body")
me.from_pydata([(0, 0, 0), (0.1, 0, 0), (0, 0.1, 0)], [], [(0, 1, 2)])
ob = bpy.data.objects.new("body", me)
scene.collection.objects.link(ob)
ob.parent = arm
ob.modifiers.new("armature", "ARMATURE").object = arm
for b in arm.data.bones:
    ob.vertex_groups.new(name=b.name)
ob.vertex_groups[arm.data.bones[0].name].add([0, 1, 2], 1.0, "REPLACE")
bpy.ops.export_scene.gltf(filepath=glb, export_format="GLB", export_animations=True, export_yup=True)
print("RESULT" + json.dumps({"fps": scene.render.fps / scene.render.fps_base, "frames": [scene.frame_start,
                                                                                          scene.frame_end]}))
"""


def test_blender_glb_matches_the_bvh_path(sim_python, tmp_path):
    """A real CMU capture imported by Blender's BVH importer (0.45-inch units scaled to metres) and exported by
    its glTF exporter: `run`'s motion from the GLB poses the default body where the BVH path does, every
    vertex of every frame within 1e-5 m (the figure is printed)."""
    from segadeform.body import default_body_path, load_body

    bvh = SAMPLES / "motions" / "cmu" / "02_01_walk.bvh"
    glb = tmp_path / "walk.glb"
    p = subprocess.run(
        [str(sim_python), "-c", BLENDER_EXPORT, str(bvh), str(glb), "0.05644"],
        capture_output=True,
        text=True,
        timeout=600,
    )
    assert p.returncode == 0, p.stderr[-2000:]
    info = json.loads(next(ln for ln in p.stdout.splitlines() if ln.startswith("RESULT"))[6:])
    body = load_body(default_body_path())
    J = body.rest_joints()[0]
    a, b = load_motion(bvh, rest_joints=J), load_motion(glb, rest_joints=J)
    assert b.meta["scheme"] == a.meta["scheme"] == "cmu-motionbuilder" and b.meta["mapped"] == a.meta["mapped"]
    assert b.n_frames == a.n_frames
    # the GLB's key times (Blender's exporter) give its rate: within 1e-4 of the BVH's 1 / Frame Time
    assert b.fps == pytest.approx(a.fps, rel=1e-4) and info["fps"] == pytest.approx(a.fps, rel=1e-6)
    va = body.forward(a.poses, trans=a.trans).vertices
    vb = body.forward(b.poses, trans=b.trans).vertices
    err = float(np.linalg.norm(va - vb, axis=-1).max())
    print(f"GLB from Blender vs BVH: {a.n_frames} frames x {va.shape[1]} body vertices, max {err:.3g} m")
    assert err <= 1e-5
    assert np.abs(va[-1] - va[0]).max() > 0.1  # it walks: the frames are not all one pose
