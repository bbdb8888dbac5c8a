"""The documented Blender recipe, inside Blender: default OBJ import + Mesh Cache on segadeform's PC2, on
synthetic caches and on a real `segadeform run --body-out` output loaded by tools/blender/segadeform_import.py
(needs the simulator environment; CI has it)."""

from __future__ import annotations

import json
import subprocess
from pathlib import Path

import numpy as np

from segadeform.io import Mesh, write_obj, write_pc2
from segadeform.settings import Y_TO_Z

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
    p = subprocess.run(
        [str(sim_python), "-c", CHECK, str(TOOL), str(obj), str(pc2), json.dumps(frames)],
        capture_output=True,
        text=True,
        timeout=300,
    )
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
    # (a cache converted to z-up would be rotated twice, far off: the script refuses it,
    # test_import_script_refuses_a_cache_written_with_up_z)


# The one-step script's command-line entry (as `blender --python TOOL -- ARGS` runs it), then the evaluated world
# positions of every object that got a Mesh Cache, per scene frame.
CLI_CHECK = r"""
import json, sys, runpy
import numpy as np
import bpy
tool, args, frames = sys.argv[1], json.loads(sys.argv[2]), json.loads(sys.argv[3])
bpy.ops.wm.read_factory_settings(use_empty=True)
sys.argv = ["blender", "--python", tool, "--"] + args
runpy.run_path(tool, run_name="__main__")
scene = bpy.context.scene
out = {"frame_start": scene.frame_start, "frame_end": scene.frame_end, "objects": {}}
for f in frames:
    scene.frame_set(f)
    deps = bpy.context.evaluated_depsgraph_get()
    for ob in scene.objects:
        mods = [m for m in ob.modifiers if m.type == "MESH_CACHE"]
        if not mods:
            continue
        ev = ob.evaluated_get(deps)
        co = np.empty(len(ev.data.vertices) * 3, np.float64)
        ev.data.vertices.foreach_get("co", co)
        mw = np.array(ev.matrix_world, np.float64)
        world = co.reshape(-1, 3) @ mw[:3, :3].T + mw[:3, 3]
        out["objects"].setdefault(bpy.path.abspath(mods[0].filepath), {})[str(f)] = world.tolist()
print("RESULT" + json.dumps(out))
"""


def test_real_run_output_through_the_import_script(sim_python, tmp_path):
    """A real `segadeform run ... --body-out` (garment OBJ + PC2, body rest OBJ + PC2, frames 10:16) loaded by
    tools/blender/segadeform_import.py's command line with Blender's default OBJ importer: at several scene
    frames every garment and body vertex is where segadeform put it (seen Z-up), and the caches start at the
    PC2 header's start frame (10: Blender's frame 10 shows the motion's frame 10).  The worst error is
    written to blender_recipe.json (README's Blender section quotes it)."""
    from click.testing import CliRunner

    from segadeform.cli.main import cli
    from segadeform.io import read_pc2

    from ..conftest import SAMPLES

    garment_obj = SAMPLES / "garments" / "dress.obj"
    r = CliRunner().invoke(
        cli,
        [
            "run",
            str(SAMPLES / "scenes" / "dress_dance.toml"),
            "--frames",
            "10:16",
            "-o",
            str(tmp_path / "dress.pc2"),
            "--body-out",
            str(tmp_path / "body.pc2"),
            "--no-cache",
        ],
    )
    assert r.exit_code == 0, r.output
    assert (tmp_path / "body.obj").is_file()  # the body's rest mesh, written beside its cache
    garment, body = read_pc2(tmp_path / "dress.pc2"), read_pc2(tmp_path / "body.pc2")
    assert garment.header.start_frame == 10 and body.header.start_frame == 10 and len(garment) == 6
    frames = [10, 12, 15]
    args = [
        "--garment",
        str(garment_obj),
        "--cache",
        str(tmp_path / "dress.pc2"),
        "--body",
        str(tmp_path / "body.obj"),
        "--body-cache",
        str(tmp_path / "body.pc2"),
    ]
    p = subprocess.run(
        [str(sim_python), "-c", CLI_CHECK, str(TOOL), json.dumps(args), json.dumps(frames)],
        capture_output=True,
        text=True,
        timeout=600,
    )
    assert p.returncode == 0, p.stderr[-2000:]
    got = json.loads(next(ln for ln in p.stdout.splitlines() if ln.startswith("RESULT"))[6:])
    assert (got["frame_start"], got["frame_end"]) == (10, 15)
    R = np.array(Y_TO_Z)
    report = {
        "run": "segadeform run samples/scenes/dress_dance.toml --frames 10:16 --body-out body.pc2",
        "blender_frames": frames,
        "unit": "m",
    }
    for name, cache in (("garment", garment), ("body", body)):
        world = got["objects"][str(Path(cache.path).resolve())]
        worst = 0.0
        for f in frames:
            want = np.asarray(cache.frames[f - 10], np.float64) @ R.T
            have = np.array(world[str(f)])
            assert have.shape == want.shape
            worst = max(worst, float(np.abs(have - want).max()))
        report[name] = {"vertices": int(cache.header.num_points), "max_error_m": worst}
    out = tmp_path / "blender_recipe.json"
    out.write_text(json.dumps(report, indent=2))
    print(f"Blender recipe on a real run: {out.read_text()}")
    measured = json.loads(out.read_text())
    assert measured["garment"]["max_error_m"] < 1e-6, measured  # float32 caches of a ~1.8 m body: ~1e-7
    assert measured["body"]["max_error_m"] < 1e-6, measured
    # motion is really played (not the rest mesh everywhere): frames differ by far more than the error
    assert np.abs(np.asarray(garment.frames[5]) - np.asarray(garment.frames[0])).max() > 1e-3


SAVED_CHECK = r"""
import json, os, sys, runpy
import numpy as np
import bpy
tool, workdir, garment, blend = sys.argv[1:5]
bpy.ops.wm.read_factory_settings()  # the startup scene, with its cube
os.chdir(workdir)
sys.argv = ["blender", "--python", tool, "--", "--garment", garment, "--cache", "out/dress.pc2", "--fps", "30"]
runpy.run_path(tool, run_name="__main__")
out = {"cube": "Cube" in bpy.data.objects, "fps": bpy.context.scene.render.fps / bpy.context.scene.render.fps_base}
bpy.ops.wm.save_as_mainfile(filepath=blend)
os.chdir("/")
bpy.ops.wm.open_mainfile(filepath=blend)
ob = next(o for o in bpy.context.scene.objects if o.modifiers)
out["path"] = ob.modifiers[0].filepath
bpy.context.scene.frame_set(12)
ev = ob.evaluated_get(bpy.context.evaluated_depsgraph_get())
co = np.empty(len(ev.data.vertices) * 3); ev.data.vertices.foreach_get("co", co)
mw = np.array(ev.matrix_world)
out["world"] = (co.reshape(-1, 3) @ mw[:3, :3].T + mw[:3, 3]).tolist()
print("RESULT" + json.dumps(out))
"""


def test_import_script_keeps_a_relative_cache_through_a_saved_blend(sim_python, tmp_path):
    """A Blender user's trial: `--cache out/dress.pc2` (the README's relative style) was stored as given, and the
    .blend saved in another folder lost it (Blender remapped it to '//../../out/dress.pc2': no such file, 5.5 cm
    off); the startup cube stood where the body's legs are; the scene stayed at 24 fps.  Now the cache is found
    after the .blend is saved elsewhere and reopened from another working folder (frame 12 where segadeform put
    it), the untouched cube is gone, and --fps 30 sets the scene's rate."""
    from click.testing import CliRunner

    from segadeform.cli.main import cli
    from segadeform.io import read_pc2

    from ..conftest import SAMPLES

    work = tmp_path / "work"
    r = CliRunner().invoke(
        cli,
        ["run", str(SAMPLES / "scenes" / "dress_dance.toml"), "--frames", "10:16", "-o",
         str(work / "out" / "dress.pc2"), "--no-cache"],
    )  # fmt: skip
    assert r.exit_code == 0, r.output
    (tmp_path / "elsewhere").mkdir()
    p = subprocess.run(
        [str(sim_python), "-c", SAVED_CHECK, str(TOOL), str(work), str(SAMPLES / "garments" / "dress.obj"),
         str(tmp_path / "elsewhere" / "scene.blend")],
        capture_output=True, text=True, timeout=600,
    )  # fmt: skip
    assert p.returncode == 0, p.stderr[-2000:]
    got = json.loads(next(ln for ln in p.stdout.splitlines() if ln.startswith("RESULT"))[6:])
    assert not got["cube"] and got["fps"] == 30
    want = np.asarray(read_pc2(work / "out" / "dress.pc2").frames[2], np.float64) @ np.array(Y_TO_Z).T
    err = float(np.abs(np.array(got["world"]) - want).max())
    assert err < 1e-6, (err, got["path"])


# The script's command line, once per case, each on Blender's startup scene (its cube, light and camera): the exit
# status, what it wrote to stderr, and the scene's objects (with their modifiers) and meshes afterwards.
CASES_CHECK = r"""
import contextlib, io, json, sys, runpy
import bpy
tool, cases = sys.argv[1], json.loads(sys.argv[2])
out = []
for args in cases:
    bpy.ops.wm.read_factory_settings()
    sys.argv = ["blender", "--background", "--python", tool, "--"] + args
    err, code = io.StringIO(), 0
    with contextlib.redirect_stderr(err):
        try:
            runpy.run_path(tool, run_name="__main__")
        except SystemExit as e:
            code = e.code
    out.append({"exit": code, "stderr": err.getvalue(), "meshes": len(bpy.data.meshes),
                "objects": sorted([o.name, [m.type for m in o.modifiers]] for o in bpy.data.objects)})
print("RESULT" + json.dumps(out))
"""


def _import_cases(sim_python, cases):
    p = subprocess.run(
        [str(sim_python), "-c", CASES_CHECK, str(TOOL), json.dumps([[str(a) for a in c] for c in cases])],
        capture_output=True,
        text=True,
        timeout=600,
    )
    assert p.returncode == 0, p.stderr[-2000:]
    return json.loads(next(ln for ln in p.stdout.splitlines() if ln.startswith("RESULT"))[6:])


def _strip(tmp_path, name="g", n=50, frames=4, loose=False):
    """A strip of ``n`` vertices (``loose``: one more, in no face) as NAME.obj and its cache NAME.pc2."""
    rng = np.random.default_rng(1)
    v = rng.normal(size=(n + loose, 3))
    f = np.array([[i, i + 1, i + 2] for i in range(n - 2)])
    write_obj(tmp_path / f"{name}.obj", Mesh(vertices=v, faces=f))
    write_pc2(tmp_path / f"{name}.pc2", np.stack([v + 0.01 * k for k in range(frames)]).astype(np.float32))
    return tmp_path / f"{name}.obj", tmp_path / f"{name}.pc2"


STARTUP = [["Camera", []], ["Cube", []], ["Light", []]]


def test_import_script_checks_every_input_before_the_scene_changes(sim_python, tmp_path):
    """A Blender user's trial: a missing cache gave a FileNotFoundError traceback; a cache of another garment's point
    count, or a missing body cache, left the scene half changed (the default cube deleted, the garment imported
    without its cache).  Now each is one line naming the file, exit status 1, and Blender's startup scene as it was --
    also for a cut-short cache and for an OBJ whose vertex in no face Blender's importer drops (the import undone)."""
    g, gc = _strip(tmp_path)
    b, bc = _strip(tmp_path, "b", n=30)
    loose, loose_pc2 = _strip(tmp_path, "loose", loose=True)
    cut = tmp_path / "cut.pc2"
    cut.write_bytes(gc.read_bytes()[:-5])
    cases = {
        "no cache": (["--garment", g, "--cache", tmp_path / "nope.pc2"], "nope.pc2: no such file"),
        "no garment": (["--garment", tmp_path / "nope.obj", "--cache", gc], "nope.obj: no such file"),
        "other count": (["--garment", g, "--cache", bc], "point count does not match"),
        "no body cache": (
            ["--garment", g, "--cache", gc, "--body", b, "--body-cache", tmp_path / "nobody.pc2"],
            "nobody.pc2: no such file",
        ),
        "body count": (["--garment", g, "--cache", gc, "--body", b, "--body-cache", gc], "expected 30, got 50"),
        "cut short": (["--garment", g, "--cache", cut], "PC2 cut short"),
        "obj as cache": (["--garment", g, "--cache", g], "not a PC2 file"),
        "loose vertex": (["--garment", loose, "--cache", loose_pc2], "Blender drops vertices that are in no face"),
    }
    got = _import_cases(sim_python, [args for args, _ in cases.values()])
    for (name, (_, want)), res in zip(cases.items(), got, strict=True):
        lines = res["stderr"].strip().splitlines()
        assert res["exit"] == 1 and len(lines) == 1 and lines[0].startswith("Error: ") and want in lines[0], (name, res)
        assert res["objects"] == STARTUP and res["meshes"] == 1, (name, res)  # the cube's mesh alone
    ok = _import_cases(sim_python, [["--garment", g, "--cache", gc, "--body", b, "--body-cache", bc]])[0]
    assert ok["exit"] == 0
    assert ok["objects"] == [["Camera", []], ["Light", []], ["b", ["MESH_CACHE"]], ["g", ["MESH_CACHE"]]]


def test_import_script_refuses_a_body_cache_without_a_body(sim_python, tmp_path):
    """A Blender user's trial: `--body-cache B.pc2` without `--body` was ignored without a word.  Refused, one line,
    the scene as it was."""
    g, gc = _strip(tmp_path)
    _, bc = _strip(tmp_path, "b", n=30)
    res = _import_cases(sim_python, [["--garment", g, "--cache", gc, "--body-cache", bc]])[0]
    lines = res["stderr"].strip().splitlines()
    assert res["exit"] == 1 and len(lines) == 1 and "--body-cache needs --body" in lines[0] and "b.pc2" in lines[0]
    assert res["objects"] == STARTUP


def test_import_script_refuses_a_cache_written_with_up_z(sim_python, tmp_path):
    """A Blender user's trial: a cache written with `--up z` was taken and placed the garment metres off (Blender
    turns the imported OBJ itself, then the cache again).  A real `run --body-out` turned to Z up (segadeform's
    --up z: (x, y, z) -> (x, -z, y)), garment or body cache, is refused naming the file and --up z, the scene as it
    was; the same caches +Y up load (as written by run)."""
    from click.testing import CliRunner

    from segadeform.cli.main import cli
    from segadeform.io import read_pc2

    from ..conftest import SAMPLES

    r = CliRunner().invoke(
        cli,
        ["run", str(SAMPLES / "scenes" / "dress_dance.toml"), "--frames", "10:13", "-o", str(tmp_path / "dress.pc2"),
         "--body-out", str(tmp_path / "body.pc2"), "--no-cache"],
    )  # fmt: skip
    assert r.exit_code == 0, r.output
    R = np.array(Y_TO_Z)
    for name in ("dress", "body"):
        c = read_pc2(tmp_path / f"{name}.pc2")
        write_pc2(tmp_path / f"{name}_z.pc2", (np.asarray(c.frames) @ R.T).astype(np.float32), start_frame=10)
    g = SAMPLES / "garments" / "dress.obj"
    cm = [f"v {100 * float(a)} {100 * float(b)} {100 * float(c)}" if ln.startswith("v ") else ln
          for ln in g.read_text().splitlines() for a, b, c in [(ln.split() + ["0"] * 4)[1:4]]]  # fmt: skip
    (tmp_path / "dress_cm.obj").write_text("\n".join(cm) + "\n")
    body = ["--body", tmp_path / "body.obj", "--body-cache"]
    got = _import_cases(
        sim_python,
        [
            ["--garment", g, "--cache", tmp_path / "dress_z.pc2"],
            ["--garment", g, "--cache", tmp_path / "dress.pc2", *body, tmp_path / "body_z.pc2"],
            ["--garment", g, "--cache", tmp_path / "dress.pc2", *body, tmp_path / "body.pc2"],
            # a first frame lying down fits turned too: --no-up-check imports it as it is (a review)
            ["--garment", g, "--cache", tmp_path / "dress_z.pc2", "--no-up-check"],
            # the garment's own file in centimetres beside a cache in metres (a Blender artist's trial: taken)
            ["--garment", tmp_path / "dress_cm.obj", "--cache", tmp_path / "dress.pc2"],
        ],
    )
    lines = got[4]["stderr"].strip().splitlines()
    assert got[4]["exit"] == 1 and len(lines) == 1 and "dress_cm.obj: 99.7 times the size of dress.pc2" in lines[0]
    assert got[4]["objects"] == STARTUP
    for res, bad in zip(got[:2], ("dress_z.pc2", "body_z.pc2"), strict=True):
        lines = res["stderr"].strip().splitlines()
        assert res["exit"] == 1 and len(lines) == 1 and f"{bad}: written with --up z" in lines[0], res
        assert "--up y" in lines[0] and res["objects"] == STARTUP
    assert got[2]["exit"] == 0 and [m for _, m in got[2]["objects"]].count(["MESH_CACHE"]) == 2, got[2]
    assert got[3]["exit"] == 0 and [m for _, m in got[3]["objects"]].count(["MESH_CACHE"]) == 1, got[3]


def test_import_script_plays_a_cache_of_another_sample_rate_and_start(sim_python, tmp_path):
    """A Blender user's trial: a PC2 with sampleRate 2 and startFrame 10 showed sample 0 at frame 20 (the modifier's
    frame start was the header's start, while Blender subtracts it after scaling).  Now sample k shows at scene frame
    start + k * sampleRate, as the header defines it -- for sampleRate 2 from frame 10, 0.5 from frame 3, and 2 from
    --frame-start 1 -- and the scene's frames cover the samples."""
    rng = np.random.default_rng(2)
    v = rng.normal(size=(40, 3))
    f = np.array([[i, i + 1, i + 2] for i in range(38)])
    frames = np.stack([v + [0.1 * k, 0.0, 0.0] for k in range(6)]).astype(np.float32)
    write_obj(tmp_path / "g.obj", Mesh(vertices=v, faces=f))
    R = np.array(Y_TO_Z)
    for start, rate, frame_start in ((10.0, 2.0, None), (3.0, 0.5, None), (10.0, 2.0, 1.0)):
        pc2 = tmp_path / f"s{start:g}_r{rate:g}.pc2"
        write_pc2(pc2, frames, start_frame=start, sample_rate=rate)
        first = start if frame_start is None else frame_start
        shows = [(int(first + k * rate), k) for k in range(6) if float(first + k * rate).is_integer()]
        args = ["--garment", str(tmp_path / "g.obj"), "--cache", str(pc2)]
        args += [] if frame_start is None else ["--frame-start", str(frame_start)]
        p = subprocess.run(
            [str(sim_python), "-c", CLI_CHECK, str(TOOL), json.dumps(args), json.dumps([s for s, _ in shows])],
            capture_output=True, text=True, timeout=300,
        )  # fmt: skip
        assert p.returncode == 0, p.stderr[-2000:]
        got = json.loads(next(ln for ln in p.stdout.splitlines() if ln.startswith("RESULT"))[6:])
        assert (got["frame_start"], got["frame_end"]) == (int(first), int(np.ceil(first + 5 * rate))), got
        world = got["objects"][str(pc2)]
        for scene_frame, k in shows:
            err = np.abs(np.array(world[str(scene_frame)]) @ R - frames).reshape(6, -1).max(1)
            assert err.argmin() == k and err[k] < 1e-5, (start, rate, frame_start, scene_frame, k, err)


OPEN_CHECK = r"""
import json, sys
import numpy as np
import bpy
bpy.ops.wm.open_mainfile(filepath=sys.argv[1])
sc = bpy.context.scene
ob = next(o for o in sc.objects if o.modifiers)
sc.frame_set(int(sys.argv[2]))
ev = ob.evaluated_get(bpy.context.evaluated_depsgraph_get())
co = np.empty(len(ev.data.vertices) * 3); ev.data.vertices.foreach_get("co", co)
mw = np.array(ev.matrix_world)
print("RESULT" + json.dumps({"frames": [sc.frame_start, sc.frame_end], "fps": sc.render.fps,
                             "world": (co.reshape(-1, 3) @ mw[:3, :3].T + mw[:3, 3]).tolist()}))
"""


def test_import_script_saves_the_scene_headless_never_over_a_file(sim_python, tmp_path):
    """`--save FILE.blend` (a Blender user's trial asked to make the .blend headless): the saved file opens with the
    cache playing (frame 3 is the cache's sample 2) at the run's rate; a second --save to the same name is refused
    (one line, exit 1, the file as it was), --force replaces it, with no .blend1 backup beside it; a name not ending
    .blend, and --force without --save, are refused before the scene changes."""
    from segadeform.io import read_pc2

    g, gc = _strip(tmp_path, frames=5)
    out = tmp_path / "saved"
    out.mkdir()
    blend = out / "scene.blend"
    base = ["--garment", g, "--cache", gc, "--fps", "30", "--frame-start", "1"]
    first, again, forced, not_blend, force_alone = _import_cases(
        sim_python,
        [base + ["--save", blend], base + ["--save", blend], base + ["--save", blend, "--force"],
         base + ["--save", out / "scene.txt"], base + ["--force"]],
    )  # fmt: skip
    assert first["exit"] == 0 and again["exit"] == 1, (first, again)
    lines = again["stderr"].strip().splitlines()
    assert len(lines) == 1 and "scene.blend: exists; --save never overwrites a file" in lines[0]
    assert again["objects"] == STARTUP
    assert forced["exit"] == 0 and sorted(p.name for p in out.iterdir()) == ["scene.blend"]
    for res, want in ((not_blend, "expected a name ending .blend"), (force_alone, "--force only lets --save")):
        assert res["exit"] == 1 and want in res["stderr"] and res["objects"] == STARTUP, res
    p = subprocess.run(
        [str(sim_python), "-c", OPEN_CHECK, str(blend), "3"], capture_output=True, text=True, timeout=300
    )
    assert p.returncode == 0, p.stderr[-2000:]
    got = json.loads(next(ln for ln in p.stdout.splitlines() if ln.startswith("RESULT"))[6:])
    assert got["frames"] == [1, 5] and got["fps"] == 30
    want = np.asarray(read_pc2(gc).frames[2], np.float64) @ np.array(Y_TO_Z).T
    assert np.abs(np.array(got["world"]) - want).max() < 1e-6
