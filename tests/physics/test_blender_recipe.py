"""The documented Blender recipe, inside Blender: default OBJ import + Mesh Cache on segadeform's PC2
(needs the simulator environment; CI has it)."""

from __future__ import annotations

import json
import subprocess
from pathlib import Path

import numpy as np
import pytest

from segadeform.io import Mesh, write_obj, write_pc2
from segadeform.scene import Y_TO_Z

TOOL = Path(__file__).resolve().parents[2] / "tools" / "blender" / "segadeform_import.py"

CHECK = r"""
import json, sys, runpy
ns = runpy.run_path(sys.argv[1])
import bpy
bpy.ops.wm.read_factory_settings(use_empty=True)
objs = ns["import_result"](sys.argv[2], sys.argv[3], frame_start=1)
out = {}
deps = bpy.context.evaluated_depsgraph_get()
for f in json.loads(sys.argv[4]):
    bpy.context.scene.frame_set(f)
    deps = bpy.context.evaluated_depsgraph_get()
    ob = objs[0].evaluated_get(deps)
    mw = ob.matrix_world
    out[f] = [list(mw @ v.co) for v in ob.data.vertices]
out["frame_end"] = bpy.context.scene.frame_end
print("RESULT" + json.dumps(out))
"""


def _blender_world(sim_python, obj, pc2, frames):
    p = subprocess.run([str(sim_python), "-c", CHECK, str(TOOL), str(obj), str(pc2), json.dumps(frames)],
                       capture_output=True, text=True, timeout=300)
    assert p.returncode == 0, p.stderr[-2000:]
    line = next(ln for ln in p.stdout.splitlines() if ln.startswith("RESULT"))
    return json.loads(line[6:])


def test_default_cache_lines_up_with_the_imported_mesh(sim_python, tmp_path):
    """PC2 in segadeform's default convention (+Y up, as the OBJ): in Blender, every vertex at every frame is
    where segadeform put it (seen in Blender's Z-up world: (x, -z, y)), cache frame k at scene frame 1 + k."""
    rng = np.random.default_rng(0)
    v = rng.normal(size=(50, 3))
    f = np.array([[i, i + 1, i + 2] for i in range(48)])
    frames = np.stack([v + [0.1 * k, 0.05 * k, -0.02 * k] + 0.01 * rng.normal(size=v.shape) for k in range(6)])
    write_obj(tmp_path / "g.obj", Mesh(vertices=v, faces=f))
    write_pc2(tmp_path / "g.pc2", frames.astype(np.float32))
    got = _blender_world(sim_python, tmp_path / "g.obj", tmp_path / "g.pc2", [1, 3, 6])
    R = np.array(Y_TO_Z)
    worst = 0.0
    for scene_frame in (1, 3, 6):
        want = frames[scene_frame - 1] @ R.T
        worst = max(worst, float(np.abs(np.array(got[str(scene_frame)]) - want).max()))
    assert worst < 1e-5, worst
    assert got["frame_end"] == 6
    # a cache converted to z-up is rotated twice: far off (why the README says not to use --up z for this)
    write_pc2(tmp_path / "z.pc2", (frames @ R.T).astype(np.float32))
    gz = _blender_world(sim_python, tmp_path / "g.obj", tmp_path / "z.pc2", [1])
    assert np.abs(np.array(gz["1"]) - frames[0] @ R.T).max() > 0.5
