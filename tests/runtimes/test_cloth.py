"""The cloth stage in every runtime, held to the rule the collision parity uses (tests/runtimes/test_collisions.py):
`segadeform run --effects=+cloth` (the compiled kernel ``src/segadeform/body/_cloth.c`` through
:class:`~segadeform.body.cloth.ClothStage`) against the C++ runtime (the same C file compiled into ``segadeform-run``),
the Node runtime and the browser page (its line-for-line JavaScript port, ``runtimes/node/src/cloth.js``).

* A shared vector of the stage alone: a skirt through the hips and thighs over a walk with a teleport, Python's
  setup and frames, against the JavaScript stage on the same float64 inputs (three settings, and the skirt split
  along a seam as exports split UV seams): the setup equal, every frame equal (in practice bit for bit), the same
  counts.
* The whole pipeline on the shipped model: the dress, tightened, dancing, as the runtimes without Python read it;
  `segadeform run` with the cloth stage against Node and C++ (the same deformer frames and body graph: within 1e-5
  relative every vertex-frame, in practice bit for bit, the same counts) and the browser (wasm rounds the deformer's
  float32 in another order: at most one in 1,000 vertex-frames in contact over 1e-5 relative, none by more than the
  margin).
"""

from __future__ import annotations

import dataclasses
import json
import re
import subprocess
from pathlib import Path

import numpy as np
import pytest

from segadeform.io import Mesh, read_pc2
from segadeform.io.sgdb import write_bundle
from tests.conftest import SAMPLES, split_at_a_seam
from tests.runtimes.test_collisions import FRAMES, MARGIN, TIGHTEN, _agree, _node_vectors, _site, _web_frames

EFFECTS = "lbs,dynamics,wrinkles,cloth"


def _report(name: str, **figures) -> None:
    print(f"CLOTH {name} " + json.dumps(figures))


def _write_vector(path, v, f, rest_body, body_faces, targets, posed, setup, out, settings, batch) -> None:
    """A test vector of the JavaScript stage (runtimes/node/scripts/cloth_vectors.mjs reads it): the garment and body
    at rest, the targets and posed bodies, Python's setup and frames ``out``, stepped ``batch`` frames at a time."""
    write_bundle(
        path,
        {
            "rest": v,
            "faces": f.astype(np.int32),
            "rest_body": rest_body,
            "body_faces": body_faces.astype(np.int32),
            "targets": targets,
            "posed": posed,
            "edges": setup.edges.astype(np.int32),
            "rest_len": setup.rest_len,
            "nptr": setup.nptr.astype(np.int32),
            "nidx": setup.nidx.astype(np.int32),
            "radius": setup.radius,
            "anchor": setup.anchor.astype(np.int32),
            "tether": setup.tether,
            "weld": setup.weld.astype(np.int32),
            "expected": out,
        },
        {"settings": dataclasses.asdict(settings), "margin": MARGIN, "dt": 1 / 30, "batch": batch},
    )


@pytest.fixture(
    scope="module",
    params=["default", "iterations=3,stiffness=0.6,bending=0,follow=0,gravity=20", "backstop=0", "split"],
)
def cloth_vector(request, tmp_path_factory):
    from segadeform.body import default_body_path, load_body
    from segadeform.body.cloth import ClothSettings, ClothStage, compiled_available, garment_setup
    from segadeform.body.transfer import garment_weights, skin_garment
    from segadeform.geometry.primitives import frustum
    from segadeform.motion import make_motion

    assert compiled_available(), "the compiled cloth kernel is not built (pip install -e . builds it)"
    body = load_body(default_body_path())
    settings = ClothSettings.parse("" if request.param in ("default", "split") else request.param)
    v, f = frustum(24, 9, 0.13, 0.2, 1.0, 0.5)  # partly inside the hips, the thighs swinging through it
    if request.param == "split":  # split along a seam, as exports split UV seams: the sides welded, moving as one
        v, f, _ = split_at_a_seam(Mesh(v, f))
    m = make_motion("walk", seconds=0.8, seed=1)
    trans = m.trans.copy()
    trans[14:] += [2.0, 0.0, 1.0]  # a teleport: the stage resets
    posed = body.forward(m.poses, None, trans).vertices
    # skinned to the nearest body vertex above the hem, carried by the root alone below (the swinging thighs go
    # deep through the free hem there: the backstop's work)
    skinned = skin_garment(v, garment_weights(v, f, body, None, "nearest"), body, m.poses, None, trans)
    rigid = v[None] + trans[:, None]
    targets = np.where((v[:, 1] < 0.75)[None, :, None], rigid, skinned)
    rest_body = body.shaped_vertices()[0]
    setup = garment_setup(v, f, rest_body, body.faces, settings)
    stage = ClothStage(setup, body.v_template, body.faces, settings, margin=MARGIN, dt=1 / 30)
    batch = 5
    out = np.concatenate(
        [stage.step(targets[lo : lo + batch], posed[lo : lo + batch]) for lo in range(0, len(targets), batch)]
    )
    assert stage.resets == 1 and stage.contacts > 200  # the vector means something: contact, a reset,
    assert stage.pushed > 0 if settings.backstop == 0 else stage.traced > 0  # the push-out or the backstop at work
    path = tmp_path_factory.mktemp("cloth") / "vec.sgdb"
    _write_vector(path, v, f, rest_body, body.faces, targets, posed, setup, out, settings, batch)
    counts = {"contacts": stage.contacts, "pushed": stage.pushed, "resets": stage.resets, "traced": stage.traced}
    return path, counts | {"settings": request.param}


def test_javascript_cloth_is_the_compiled_kernel(cloth_vector, node):
    """Same float64 inputs, same setup and frames: every coordinate equal (the port uses only + - * / and sqrt, as the
    C file), the same counts."""
    path, py = cloth_vector
    r = _node_vectors("cloth_vectors.mjs", path, "CLOTH")
    _report("javascript stage vs ClothStage", **r, python=py)
    assert r["edges"] == r["nptr"] == r["nidx"] == r["anchor"] == 0 and r["restLen"] == r["radius"] == 0, r
    assert r["tether"] == 0 and r["weld"] == 0, r
    assert r["frames"] <= 1e-12 and r["identical"] == r["coordinates"], r
    names = ("contacts", "pushed", "resets", "traced")
    assert [r[k] for k in names] == [py[k] for k in names], (r, py)


def test_javascript_cloth_drops_a_trace_through_the_body_as_the_kernel(node, tmp_path):
    """The backstop's reach (``REACH``: a trace longer than 20 cm went through the torso and is dropped) in the port: a
    loose panel across a box arm whose end moves from 13 to 32 cm beyond it along the panel's normal, so that the
    traces out of the end are kept in the first frames and dropped in the last; the JavaScript stage's frames are the
    kernel's bit for bit (a port without the rule differs in the last frames)."""
    from segadeform.body.cloth import REACH, ClothSettings, ClothStage, garment_setup
    from tests.body.test_cloth import _box, _quad

    g = np.arange(-0.04, 0.04001, 0.01)
    v = np.array([[0.2, y + 0.0037, z - 0.0021] for z in g for y in g])
    n = len(g)
    f = np.array([[a, b, c] for j in range(n - 1) for i in range(n - 1) for a, b, c in _quad(j * n + i, n)])
    ends = np.linspace(0.33, 0.52, 10)
    arm_v, arm_f = _box((-0.3, -0.06, -0.06), (0.0, 0.06, 0.06))  # at rest 20 cm short of the panel: it hangs loose
    posed = np.repeat(arm_v[None], len(ends), 0)
    posed[:, arm_v[:, 0] > -0.1, 0] = ends[:, None]
    assert (ends[:3] - 0.2 < REACH).all() and (ends[-3:] - 0.2 > REACH).all()
    settings = ClothSettings(gravity=0.0)
    setup = garment_setup(v, f, arm_v, arm_f, settings)  # as the port makes it, from the body at rest
    assert (setup.radius == settings.max_distance).all()
    targets = np.repeat(v[None], len(ends), 0)
    traced = []
    stage = ClothStage(setup, arm_v, arm_f, settings, margin=MARGIN, dt=1 / 30)
    out = []
    for t in range(len(ends)):
        before = stage.traced
        out.append(stage.step(targets[t : t + 1], posed[t : t + 1]))
        traced.append(stage.traced - before)
    out = np.concatenate(out)
    assert traced[0] > 0 and traced[-1] == 0, traced  # kept, then dropped
    path = tmp_path / "reach.sgdb"
    _write_vector(path, v, f, arm_v, arm_f, targets, posed, setup, out, settings, 1)
    r = _node_vectors("cloth_vectors.mjs", path, "CLOTH")
    _report("javascript stage, the backstop's reach", **r, python_traced=traced)
    assert r["frames"] <= 1e-12 and r["identical"] == r["coordinates"] and r["traced"] == sum(traced), r


@pytest.fixture(scope="module")
def clothed(tmp_path_factory):
    """The shipped model's dress, tightened, on a dance, as the runtimes without Python read it, and `segadeform run`
    on those two files with the cloth stage: its frames, counts and posed body."""
    from segadeform.io import read_mesh
    from segadeform.io.obj import write_obj
    from segadeform.runtime.pipeline import run_scene
    from segadeform.runtime.vectors import scene_vectors
    from segadeform.settings import load_scene

    d = tmp_path_factory.mktemp("clothed")
    pkg = SAMPLES / "models" / "default"
    m = read_mesh(SAMPLES / "garments" / "dress.obj")
    v = m.vertices.copy()
    c = v.mean(axis=0)
    v[:, [0, 2]] = c[[0, 2]] + TIGHTEN * (v[:, [0, 2]] - c[[0, 2]])
    write_obj(d / "tight_dress.obj", m, vertices=v)
    sc = load_scene(SAMPLES / "scenes" / "dress_dance.toml")
    sc = dataclasses.replace(
        sc, garment=d / "tight_dress.obj", motion=dataclasses.replace(sc.motion, frames=(0, FRAMES))
    )
    files = scene_vectors(sc, d, model=pkg, force=True)
    scene = d / "cloth.toml"
    scene.write_text(
        f'[garment]\nmesh = "{files["garment"]}"\n[motion]\nfile = "{files["motion"]}"\n'
        f'[output]\npath = "{d / "py.pc2"}"\nbody = "{d / "py_body.pc2"}"\n'
        '[effects]\nskinning = "lbs"\ndynamics = true\nwrinkles = true\ncloth = true\n'
    )
    s = run_scene(load_scene(scene), model=pkg, cache=False, force=True)
    assert s.body_backend == "graph" and s.cloth["contacts"] > 0.2 * FRAMES * len(v)
    frames = read_pc2(d / "py.pc2").frames
    write_bundle(d / "clothed.sgdb", {"expected": frames})
    return dict(
        files,
        package=pkg,
        dir=d,
        frames=frames,
        cloth=s.cloth,
        check_clothed=d / "clothed.sgdb",
        ms=1e3 * s.stage_seconds["cloth"] / FRAMES,
    )


@pytest.mark.parametrize("runtime", ["node", "cpp"])
def test_runtime_cloth_matches_segadeform_run(runtime, request, clothed, tmp_path):
    exe = request.getfixturevalue(runtime)
    c = clothed
    p = subprocess.run(
        exe
        + [
            "--package",
            str(c["package"]),
            "--garment",
            str(c["garment"]),
            "--motion",
            str(c["motion"]),
            "--effects",
            EFFECTS,
            "-o",
            str(tmp_path / "g.pc2"),
            "--batch",
            "8",
        ],
        capture_output=True,
        text=True,
        timeout=600,
    )
    assert p.returncode == 0, p.stdout + p.stderr
    m = re.search(
        r"cloth: (\d+) vertex-frames in contact, (\d+) pushed out after the sweeps, (\d+) traced out by the "
        r"backstop, (\d+) reset\(s\), ([\d.]+) ms/frame",
        p.stdout,
    )
    assert m, p.stdout
    counts = {k: int(m.group(i + 1)) for i, k in enumerate(("contacts", "pushed", "traced", "resets"))}
    got = read_pc2(tmp_path / "g.pc2").frames
    a = _agree(got, c["frames"], c["cloth"]["contacts"])
    _report(runtime, **a, **counts, python=c["cloth"], ms_per_frame=float(m.group(5)), python_ms_per_frame=c["ms"])
    assert a["exact"] and a["max_rel"] <= 1e-5, a
    assert counts == c["cloth"], (counts, c["cloth"])


def test_cloth_knobs_and_refusals_in_the_runtimes(node, cpp, clothed, tmp_path):
    """--cloth sets the knobs (the same frames as segadeform run --cloth); --cloth without the stage is a usage error;
    a bad knob a clear error; a scene bundle cannot run the stage."""
    from segadeform.cli.main import main

    c = clothed
    knobs = "iterations=2,stiffness=0.5,gravity=0"
    assert (
        main(
            [
                "run",
                "--garment",
                str(c["garment"]),
                "--motion",
                str(c["motion"]),
                "--model",
                str(c["package"]),
                "--effects",
                EFFECTS,
                "--cloth",
                knobs,
                "--no-cache",
                "--force",
                "-o",
                str(tmp_path / "py.pc2"),
            ]
        )
        == 0
    )
    want = read_pc2(tmp_path / "py.pc2").frames
    assert np.abs(np.asarray(want, np.float64) - c["frames"]).max() > 1e-4  # the knobs change the frames
    for name, exe in (("node", node), ("cpp", cpp)):
        base = exe + ["--package", str(c["package"]), "--garment", str(c["garment"]), "--motion", str(c["motion"])]
        p = subprocess.run(
            base + ["--effects", EFFECTS, "--cloth", knobs, "-o", str(tmp_path / f"{name}.pc2")],
            capture_output=True,
            text=True,
            timeout=600,
        )
        assert p.returncode == 0, p.stdout + p.stderr
        assert _agree(read_pc2(tmp_path / f"{name}.pc2").frames, want, 1)["exact"]
        p = subprocess.run(
            base + ["--cloth", "iterations=2", "-o", str(tmp_path / "x.pc2")],
            capture_output=True,
            text=True,
            timeout=600,
        )
        assert p.returncode == 2 and "the stage is off" in p.stderr, p.stderr
        p = subprocess.run(
            base + ["--effects", EFFECTS, "--cloth", "iterations=0", "-o", str(tmp_path / "x.pc2")],
            capture_output=True,
            text=True,
            timeout=600,
        )
        # a command-line mistake, as `segadeform run` says it: one `error:` line and the usage, exit 2
        assert p.returncode == 2 and p.stderr.startswith(
            "error: --cloth: cloth iterations must be an integer in [1, 64]"
        ), p.stderr
        assert not (tmp_path / "x.pc2").exists()
        p = subprocess.run(  # the bounds as Python prints them (C++ printed [1.000000, 64.000000]), the text as typed
            base + ["--effects", EFFECTS, "--cloth", "iterations=2.5", "-o", str(tmp_path / "x.pc2")],
            capture_output=True,
            text=True,
            timeout=600,
        )
        assert p.returncode == 2 and "an integer in [1, 64] (got '2.5')" in p.stderr, p.stderr


@pytest.fixture(scope="module")
def clothed_site(tmp_path_factory, clothed):
    return _site(
        tmp_path_factory.mktemp("site"),
        clothed["package"],
        [clothed[k] for k in ("garment", "motion", "check_clothed")],
    )


def test_browser_cloth_every_frame(clothed_site, clothed, tmp_path):
    """The browser (onnxruntime-web on wasm, the page's runtime.js and cloth.js), every vertex-frame, against
    `segadeform run --effects=+cloth`: the collision parity's rule (at most one in 1,000 vertex-frames in contact over
    1e-5 relative, none by more than the margin) and the same counts within that share."""
    c = clothed
    r = _web_frames(clothed_site, tmp_path / "cloth.f32", EFFECTS)
    shape = c["frames"].shape
    assert (r["T"], r["N"]) == shape[:2] and r["cloth"] is not None
    got = np.fromfile(tmp_path / "cloth.f32", "<f4").reshape(shape)
    a = _agree(got, c["frames"], c["cloth"]["contacts"])
    _report(
        "browser wasm",
        **a,
        contacts=r["cloth"]["contacts"],
        pushed=r["cloth"]["pushed"],
        python=c["cloth"],
        ms_per_frame=r["cloth"]["msPerFrame"],
    )
    assert a["ok"], a
    assert abs(r["cloth"]["contacts"] - c["cloth"]["contacts"]) <= max(3, c["cloth"]["contacts"] // 1000)
    assert r["cloth"]["resets"] == c["cloth"]["resets"] == 0


def test_node_cloth_under_extreme_poses_is_segadeform_runs_bit_for_bit(node, tmp_path):
    """A walk with 1e5 degrees added to every joint's channel (the body folds through itself every frame, the stage
    restarts on jumps): the cloth stage carries each contact from frame to frame, so one differing bit in a vertex
    pseudo-normal used to grow into centimetres between Node and Python (a trial measured 3.8 cm, when the port's
    angles came from Math.acos).  With the kernel's own acos the two give the same frames bit for bit."""
    from segadeform.cli.main import main

    d = dict(np.load(SAMPLES / "motions" / "walk.npz"))
    t = 30
    rng = np.random.default_rng(5)
    axis = rng.normal(size=(24, 3))
    axis /= np.linalg.norm(axis, axis=1, keepdims=True)
    poses = d["poses"][:t].reshape(t, 24, 3).astype(np.float64)
    poses[:, 1:] += axis[None, 1:] * np.deg2rad(1e5) * np.linspace(0.9, 1.1, t)[:, None, None]
    d.update(poses=poses.reshape(t, 72).astype(np.float32), trans=d["trans"][:t])
    np.savez(tmp_path / "extreme.npz", **d)
    motion, garment = tmp_path / "extreme.sgdm", tmp_path / "skirt.sgda"
    assert main(["motion", "export", str(tmp_path / "extreme.npz"), "-o", str(motion)]) == 0
    assert main(["garment", "export", str(SAMPLES / "garments" / "skirt.obj"), "-o", str(garment)]) == 0
    pkg = SAMPLES / "models" / "default"
    py = tmp_path / "py.pc2"
    assert (
        main(
            ["run", "--garment", str(garment), "--motion", str(motion), "--model", str(pkg)]
            + ["--effects", EFFECTS + ",collisions", "--no-cache", "-o", str(py)]
        )
        == 0
    )
    p = subprocess.run(
        node
        + ["--package", str(pkg), "--garment", str(garment), "--motion", str(motion)]
        + ["--effects", EFFECTS + ",collisions", "-o", str(tmp_path / "node.pc2")],
        capture_output=True,
        text=True,
        timeout=600,
    )
    assert p.returncode == 0, p.stdout + p.stderr
    m = re.search(r"cloth: (\d+) vertex-frames in contact", p.stdout)
    assert m and int(m.group(1)) > 1000, p.stdout  # the stage is busy: the body folds through the skirt
    a, b = read_pc2(py).frames, read_pc2(tmp_path / "node.pc2").frames
    _report("node under extreme poses", contacts=int(m.group(1)), max_m=float(np.abs(a - b).max()))
    assert np.array_equal(a, b)


def test_cpp_library_player_pushed_in_chunks_gives_segadeform_runs_frames(cpp, clothed, tmp_path):
    """The C++ library (runtimes/cpp/include/segadeform/player.hpp) through its example program segadeform-play,
    built beside segadeform-run: the tightened dress's dance pushed as it would arrive live, with the cloth stage.
    Chunks of `batch` frames (8) give `segadeform run`'s frames (batch 8) bit for bit and its counts; a frame at
    a time with batch 1 (onnxruntime's batch-1 kernels) and chunks of 3 stay within the collision parity rule.  An
    existing output is refused, and a cloth knob without the stage is a one-line error."""
    play = str(Path(cpp[0]).with_name("segadeform-play"))
    c = clothed
    base = [play, str(c["package"]), str(c["garment"]), str(c["motion"]), "--effects", EFFECTS]

    def run(out, *extra):
        p = subprocess.run([*base, "-o", str(out), *extra], capture_output=True, text=True, timeout=600)
        assert p.returncode == 0, p.stdout + p.stderr
        m = re.search(r"cloth: (\d+) in contact, (\d+) reset", p.stdout)
        assert m, p.stdout
        return read_pc2(out).frames, {"contacts": int(m.group(1)), "resets": int(m.group(2))}

    want = {k: c["cloth"][k] for k in ("contacts", "resets")}
    for name, extra in (("chunk8", ["--chunk", "8"]), ("frame_at_a_time", ["--chunk", "1", "--batch", "1"])):
        got, counts = run(tmp_path / f"{name}.pc2", *extra)
        a = _agree(got, c["frames"], c["cloth"]["contacts"])
        _report(f"cpp library {name}", **a, **counts)
        if name == "chunk8":
            assert np.array_equal(got, c["frames"]) and counts == want, (a, counts, want)
        else:  # batch 1: onnxruntime's batch-1 kernels, so Python's batch-8 frames to the parity rule
            assert a["ok"] and counts["resets"] == want["resets"], a
    got, counts = run(tmp_path / "chunk3.pc2", "--chunk", "3")
    a = _agree(got, c["frames"], c["cloth"]["contacts"])
    _report("cpp library chunk3", **a, **counts)
    assert a["ok"], a
    # the --name=value form the docs use (a user's trial: refused as an unknown option); a number with more after it
    # refused, not read as its leading digits
    eq = [play, str(c["package"]), str(c["garment"]), str(c["motion"]), f"--effects={EFFECTS}", "--chunk=8"]
    p = subprocess.run([*eq, "-o", str(tmp_path / "eq.pc2")], capture_output=True, text=True, timeout=600)
    assert p.returncode == 0 and np.array_equal(read_pc2(tmp_path / "eq.pc2").frames, c["frames"]), p.stderr
    p = subprocess.run([*base, "-o", str(tmp_path / "b.pc2"), "--batch", "8x"], capture_output=True, text=True)
    assert p.returncode == 2 and p.stderr.startswith("error: --batch must be an integer (got '8x')\nusage: "), p.stderr
    assert not (tmp_path / "b.pc2").exists()
    # an existing output is refused, untouched; a knob without its stage is one line
    (tmp_path / "mine.pc2").write_bytes(b"mine")
    p = subprocess.run([*base, "-o", str(tmp_path / "mine.pc2")], capture_output=True, text=True, timeout=600)
    assert p.returncode == 1 and "exists" in p.stderr and (tmp_path / "mine.pc2").read_bytes() == b"mine"
    p = subprocess.run(
        [play, str(c["package"]), str(c["garment"]), str(c["motion"]), "--effects", "lbs", "--cloth", "iterations=2"]
        + ["-o", str(tmp_path / "x.pc2")],
        capture_output=True,
        text=True,
        timeout=600,
    )
    assert p.returncode == 1 and p.stderr.count("\n") == 1 and "the stage is off" in p.stderr, p.stderr
    assert not (tmp_path / "x.pc2").exists()
    # the library's own checks (runtimes/cpp/test/player_test.cpp): misuse is one std::runtime_error line (sizes,
    # no frame, 2^60 frames, NaN, a moved-from player, a folder or a motion as the garment ...), reset() and a
    # second player in the process give the same frames, a moved player goes on
    t = subprocess.run(
        [str(Path(cpp[0]).with_name("segadeform-player-test")), str(c["package"]), str(c["garment"]), str(c["motion"])],
        capture_output=True,
        text=True,
        timeout=600,
    )
    checks = t.stdout.splitlines()
    assert t.returncode == 0 and len(checks) >= 19 and all(ln.startswith("ok ") for ln in checks), t.stdout + t.stderr
