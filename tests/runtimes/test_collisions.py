"""Collisions in every runtime: `segadeform run`'s push-out of the garment out of the posed body (the compiled
kernel ``src/segadeform/body/_collide.c``, through :class:`~segadeform.body.collision.BodyCollider`) against the
C++ runtime (the same C file compiled into ``segadeform-run``), the Node runtime and the browser page (its
line-for-line JavaScript port, ``runtimes/node/src/collide.js``).

* A shared vector of the collider alone: points near and inside the posed default body, Python's exact closest
  point, signed distance, normal and push-out, against the JavaScript collider on the same float64 inputs.
* The whole pipeline on the shipped model: the dress, tightened (5 % narrower, so that a third of its
  vertex-frames are pushed out at the default margin), dancing; `segadeform run` on the garment asset and motion
  file the other runtimes read, against each runtime's frames, the number of vertex-frames each moved printed and
  compared.  Given the runtime's own posed body, Python's BodyCollider gives the runtime's frames exactly (to the
  float32 rounding of the output).  Against `segadeform run` itself the frames agree within 1e-5 relative but for a
  few vertex-frames: the runtimes pose the body with the package's body graph (float32) where Python poses it in
  float64 (within 4e-7 m), and the push-out rule is not continuous in the body.  In a concave crease no point is
  the margin away from both faces, so the passes bounce between them and which face the last pass takes -- decided
  by the body's last bits -- moves the vertex by up to about the margin (measured here: 1 vertex-frame of 18,900
  pushed over 1e-5 relative, 3.7e-5 m; on a CMU walk whose arms brush the torso, 243 of 50,677, up to 0.29 mm, and
  Python's own push-out given its body rounded to float32 moves such vertices by up to 2.2 mm).  The bound held is
  therefore: at most one in 1,000 pushed vertex-frames over 1e-5 relative, none by more than the margin.
"""

from __future__ import annotations

import json
import re
import subprocess

import numpy as np
import pytest

from segadeform.bundle import read_bundle, write_bundle
from segadeform.io import read_pc2
from tests.conftest import REPO, SAMPLES
from tests.runtimes.test_engines import _rel
from tests.runtimes.test_web import _page

NODE = REPO / "runtimes" / "node"
RTOL = 1e-5
#: the pipeline tests' margin: segadeform.scene.Effects' default (the runtimes' default too)
MARGIN = 0.004
#: the dress made narrower by this factor about its vertical axis: many vertices inside the body
TIGHTEN = 0.95
FRAMES = 24
EFFECTS = "lbs,dynamics,wrinkles,collisions"


def _report(name: str, **figures) -> None:
    """The figures a run measured, on the test's output (pytest -s shows them; a failure shows them too)."""
    print(f"COLLISIONS {name} " + json.dumps(figures))


@pytest.fixture(scope="module")
def collider_vector(tmp_path_factory):
    """Points near, on and inside the default body in two frames of a dance, and far away, with the compiled
    kernel's answers: the test vector of the JavaScript collider."""
    from segadeform.body import default_body_path, load_body
    from segadeform.body.collision import BodyCollider, compiled_available
    from segadeform.motion import make_motion

    assert compiled_available(), "the compiled collision kernel is not built (pip install -e . builds it)"
    body = load_body(default_body_path())
    m = make_motion("dance", seconds=0.5, seed=1)
    posed = body.forward(m.poses[[4, 12]], None, m.trans[[4, 12]]).vertices
    rng = np.random.default_rng(5)
    v = posed[1]
    near = v[rng.integers(0, len(v), 3000)] + rng.normal(scale=0.015, size=(3000, 3))  # both sides of the skin
    on = v[rng.integers(0, len(v), 200)]  # exactly on vertices
    far = rng.uniform(v.min(0) - 0.2, v.max(0) + 0.2, size=(800, 3))  # inside deep, and outside far
    points = np.concatenate([near, on, far])
    col = BodyCollider(body.v_template, body.faces)
    assert col.backend == "compiled"
    q = col.query(points, v)
    push_in = np.stack([points[:2000], points[2000:]])
    iterations = 3
    push_out, moved = col.push_out(push_in, posed, 0.01, iterations=iterations)
    path = tmp_path_factory.mktemp("collide") / "vec.sgdb"
    write_bundle(path, {"rest": body.v_template, "faces": body.faces.astype(np.int32), "posed": posed,
                        "points": points, "sd": q.signed_distance, "closest": q.closest, "normal": q.normal,
                        "face": q.face.astype(np.int32), "push_in": push_in, "push_out": push_out},
                 {"margin": 0.01, "iterations": iterations, "moved": moved, "query_frame": 1})
    return path, {"moved": moved, "inside": int((q.signed_distance < 0).sum()), "points": len(points)}


def test_javascript_collider_is_the_compiled_kernel(collider_vector, node):
    """Same float64 inputs, same answers: closest points, signed distances and normals to 1e-12 m (in practice
    identical but for Math.acos's last bit in vertex pseudo-normals), push-out positions to 1e-9 m and the same
    points moved.  Face ids are reported, not compared (a tie may pick another face at the same distance)."""
    path, py = collider_vector
    p = subprocess.run(["node", str(NODE / "scripts" / "collide_vectors.mjs"), str(path)], capture_output=True,
                       text=True, timeout=600)
    assert p.returncode == 0, p.stderr[-3000:]
    r = json.loads(next(ln for ln in p.stdout.splitlines() if ln.startswith("COLLIDE "))[8:])
    _report("javascript collider vs BodyCollider", **r, python=py)
    assert r["closed"] and r["points"] == py["points"] and py["inside"] > 500 and py["moved"] > 1000
    assert r["sd"] <= 1e-12 and r["closest"] <= 1e-12 and r["normal"] <= 1e-12, r
    assert r["pushOut"] <= 1e-9 and r["moved"] == py["moved"], r


@pytest.fixture(scope="module")
def collided(tmp_path_factory):
    """The shipped model's dress, tightened, on a dance, as the runtimes without Python read it (garment asset and
    motion file), and `segadeform run` on those two files with every effect (collisions at the default margin): its
    frames, posed body and moved vertex-frames (RunSummary.pushed_vertices), and the deformer's frames before
    collisions (check.sgdb)."""
    import dataclasses

    from segadeform.cli.main import main
    from segadeform.io import read_mesh
    from segadeform.io.obj import write_obj
    from segadeform.runtime.pipeline import run_scene
    from segadeform.runtime.vectors import scene_vectors
    from segadeform.scene import Effects, load_scene

    d = tmp_path_factory.mktemp("collided")
    pkg = SAMPLES / "models" / "default"
    m = read_mesh(SAMPLES / "garments" / "dress.obj")
    v = m.vertices.copy()
    c = v.mean(axis=0)
    v[:, [0, 2]] = c[[0, 2]] + TIGHTEN * (v[:, [0, 2]] - c[[0, 2]])  # narrower, about its vertical axis
    write_obj(d / "tight_dress.obj", m, vertices=v)
    sc = load_scene(SAMPLES / "scenes" / "dress_dance.toml")
    sc = dataclasses.replace(sc, garment=d / "tight_dress.obj",
                             motion=dataclasses.replace(sc.motion, frames=(0, FRAMES)))
    files = scene_vectors(sc, d, model=pkg, force=True)  # force: a tight garment is inside the body
    scene = d / "collide.toml"
    scene.write_text(f'[garment]\nmesh = "{files["garment"]}"\n[motion]\nfile = "{files["motion"]}"\n'
                     f'[output]\npath = "{d / "py.pc2"}"\nbody = "{d / "py_body.pc2"}"\n')  # every effect
    s = run_scene(load_scene(scene), model=pkg, cache=False, force=True)
    assert s.effects == Effects() and s.effects.collision_margin == MARGIN and s.variant == "deformer_lbs"
    frames, body = read_pc2(d / "py.pc2").frames, read_pc2(d / "py_body.pc2").frames
    # `segadeform run` on the command line, the motion file given as --motion: the same frames
    assert main(["run", "--garment", str(files["garment"]), "--motion", str(files["motion"]), "--model", str(pkg),
                 "--force", "--no-cache", "-o", str(d / "cli.pc2")]) == 0
    np.testing.assert_array_equal(read_pc2(d / "cli.pc2").frames, frames)
    before = read_bundle(files["check"])[0]["expected"]
    assert before.shape == frames.shape == (FRAMES, before.shape[1], 3)
    write_bundle(d / "collided.sgdb", {"expected": frames, "body": body})
    n = frames.shape[0] * frames.shape[1]
    assert s.pushed_vertices > 0.2 * n, (s.pushed_vertices, n)  # the test means something
    return dict(files, package=pkg, dir=d, frames=frames, body=body, before=before, moved=s.pushed_vertices,
                check_collided=d / "collided.sgdb", ms=1e3 * s.stage_seconds["collisions"] / FRAMES)


def _agree(got, want, moved: int) -> dict:
    """Frames against `segadeform run`'s: the largest error (metres, and relative to the largest coordinate), how
    many vertex-frames are over RTOL relative, and whether that is within what the push-out's discontinuity explains
    (at most one in 1,000 pushed vertex-frames, none off by more than the margin)."""
    got, want = np.asarray(got, np.float64), np.asarray(want, np.float64)
    assert got.shape == want.shape and np.isfinite(got).all()
    d = np.abs(got - want).max(axis=-1)
    scale = np.abs(want).max()
    over = int((d > RTOL * scale).sum())
    return {"max_abs": float(d.max()), "max_rel": float(d.max() / scale), "over_1e-5": over,
            "ok": over <= max(1, moved // 1000) and float(d.max()) <= MARGIN}


def _moved_close(got: int, want: int) -> bool:
    """Moved counts agree but for vertices within the body's float32 rounding (4e-7 m) of the margin."""
    return abs(got - want) <= max(3, want // 1000)


@pytest.mark.parametrize("runtime", ["node", "cpp"])
def test_runtime_collisions_match_segadeform_run(runtime, request, collided, tmp_path):
    """`segadeform-node` / `segadeform-run --effects ...,collisions` (the default margin): given the runtime's own
    posed body and the deformer's frames (equal to Python's), Python's BodyCollider gives the runtime's frames to
    float32 rounding; against `segadeform run`'s frames, within 1e-5 relative but for the discontinuity's few, and
    about as many vertex-frames moved."""
    from segadeform.body import default_body_path, load_body
    from segadeform.body.collision import BodyCollider

    exe = request.getfixturevalue(runtime)
    c = collided
    p = subprocess.run(exe + ["--package", str(c["package"]), "--garment", str(c["garment"]), "--motion",
                              str(c["motion"]), "--effects", EFFECTS, "-o", str(tmp_path / "g.pc2"),
                              "--body-out", str(tmp_path / "b.pc2"), "--batch", "8"],
                       capture_output=True, text=True, timeout=600)
    assert p.returncode == 0, p.stdout + p.stderr
    m = re.search(r"collisions: (\d+) vertex-frames pushed out \(margin ([\d.e-]+) m\), ([\d.]+) ms/frame", p.stdout)
    assert m, p.stdout
    moved, ms = int(m.group(1)), float(m.group(3))
    assert float(m.group(2)) == MARGIN  # segadeform.scene.Effects' default
    got, posed = read_pc2(tmp_path / "g.pc2").frames, read_pc2(tmp_path / "b.pc2").frames
    # the runtime's own body through Python's collider: the kernel's result, rounded to float32 as written
    body = load_body(default_body_path())
    mine, n = BodyCollider(body.v_template, body.faces).push_out(c["before"].astype(np.float64),
                                                                 posed.astype(np.float64), MARGIN)
    own = float(np.abs(mine.astype(np.float32).astype(np.float64) - got).max())
    a = _agree(got, c["frames"], c["moved"])
    _report(runtime, **a, moved=moved, python_moved=c["moved"], ms_per_frame=ms, python_ms_per_frame=c["ms"],
            own_body_max_abs=own, own_body_moved=n)
    assert own <= 1.2e-7 and moved == n  # one float32 ulp at the garment's coordinates (< 2 m)
    assert a["ok"], a
    assert _moved_close(moved, c["moved"]), (moved, c["moved"])


def test_collisions_refused_without_a_body_graph_or_with_a_bad_margin(node, cpp, collided, random_package, tmp_path):
    from tests.export.legacy import as_schema

    old = as_schema(random_package, tmp_path / "v2", 2)  # no body graphs
    c = collided
    for exe in (node, cpp):
        base = exe + ["--garment", str(c["garment"]), "--motion", str(c["motion"]), "-o", str(tmp_path / "x.pc2")]
        p = subprocess.run(base + ["--package", str(old), "--effects", "lbs,collisions"], capture_output=True,
                           text=True, timeout=600)
        assert p.returncode == 1 and "collisions need the posed body" in p.stderr, p.stderr
        p = subprocess.run(base + ["--package", str(c["package"]), "--effects", EFFECTS, "--collision-margin", "-1"],
                           capture_output=True, text=True, timeout=600)
        assert p.returncode == 1 and "collision margin must be in [0, 1)" in p.stderr, p.stderr
        p = subprocess.run(base + ["--package", str(c["package"]), "--collision-margin", "x"], capture_output=True,
                           text=True, timeout=600)
        assert p.returncode == 2, p.stderr  # usage
        assert not (tmp_path / "x.pc2").exists()


@pytest.fixture(scope="module")
def collided_site(tmp_path_factory, collided):
    d = tmp_path_factory.mktemp("site")
    (d / "runtimes").symlink_to(REPO / "runtimes")
    (d / "pkg").symlink_to(collided["package"])
    for k in ("garment", "motion", "check_collided"):
        (d / collided[k].name).symlink_to(collided[k])
    return d


def test_page_pushes_out_by_default_like_segadeform_run_on_wasm(collided_site, collided, tmp_path):
    """The browser page (onnxruntime-web on wasm, collide.js) with no effects named: the model's own and collisions
    at the default margin (the package has a body graph), as `segadeform run`; the same frames and moves."""
    r = _page(collided_site, "wasm", tmp_path, "--garment", "garment.sgda", "--motion", "motion.sgdm", "--check",
              "collided.sgdb", shot=False)
    col = r["collisions"]
    assert r["effects"] == {"skinning": "lbs", "dynamics": True, "wrinkles": True, "collisions": True}, r
    assert r["finite"] and r["sameLength"] and r["T"] == FRAMES and col["margin"] == MARGIN, r
    over = r["rel"] > RTOL
    _report("browser wasm", max_abs=r["maxAbs"], max_rel=r["rel"], moved=col["moved"],
            python_moved=collided["moved"], ms_per_frame=col["msPerFrame"])
    # the page reports the largest error only: over 1e-5 relative, it must be one the discontinuity explains
    assert not over or r["maxAbs"] <= MARGIN, r
    assert _moved_close(col["moved"], collided["moved"]), (col, collided["moved"])
