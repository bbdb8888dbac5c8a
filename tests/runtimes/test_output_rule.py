"""The Node and C++ command lines keep `segadeform run`'s output rule (src/segadeform/io/output_guard.py): they
wrote over any path they were given -- a user's file, their own motion input, the garment's output with the body's
-- and a run that failed on its second output left the first (a user's trial).  Now: a file segadeform did not
write, an input, one path twice, a folder, a path inside a file or another extension are refused before any work,
untouched; outputs go in all at once; the folder's manifest is the one Python keeps, so each runtime replaces the
other's output of a run and nothing else."""

from __future__ import annotations

import shutil
import subprocess

import pytest

from segadeform.cli.main import main
from segadeform.io.output_guard import MANIFEST_NAME, written_by


def _hashes(folder):
    import hashlib

    return {
        str(p.relative_to(folder)): hashlib.sha256(p.read_bytes()).hexdigest() for p in folder.rglob("*") if p.is_file()
    }


@pytest.mark.parametrize("runtime", ["node", "cpp"])
def test_the_runtime_writes_only_where_segadeform_may(runtime, request, portable_scene, random_package, tmp_path):
    exe = request.getfixturevalue(runtime)
    g, m = tmp_path / "g.sgda", tmp_path / "m.sgdm"
    shutil.copy(portable_scene["garment"], g)
    shutil.copy(portable_scene["motion"], m)
    effects = portable_scene["effects"]
    base = [*exe, "--package", str(random_package), "--garment", str(g), "--motion", str(m), "--effects", effects]

    def go(*extra):
        return subprocess.run([*base, *map(str, extra)], capture_output=True, text=True, timeout=300)

    out = tmp_path / "a.pc2"
    for _ in range(2):  # written, then replaced: an earlier run's output
        r = go("-o", out)
        assert r.returncode == 0, r.stderr
        assert written_by(out) == "run"
    mine = tmp_path / "mine.pc2"
    mine.write_bytes(b"a user's file")
    (tmp_path / "d.pc2").mkdir()
    kept = {p: p.read_bytes() for p in (mine, g, m, out)}
    before = _hashes(tmp_path)  # every file there, the manifest included
    refusals = [
        (("-o", mine), "mine.pc2: exists and segadeform did not write it"),
        (("-o", random_package / "x.pc2"), "is an input of this run"),
        (("-o", tmp_path / "s.pc2", "--body-out", tmp_path / "s.pc2"), "two outputs of this run"),
        (("-o", tmp_path / "x.obj"), "writes PC2 point caches only (expected .pc2, got .obj)"),
        (("-o", tmp_path / "d.pc2"), "is a folder"),
        # the garment's output first, then the body's inside a file: neither is written
        (("-o", tmp_path / "q.pc2", "--body-out", mine / "b.pc2"), "is a path inside a file"),
    ]
    for extra, words in refusals:
        r = go(*extra)
        assert r.returncode == 1 and words in r.stderr, (extra, r.stderr)
        assert r.stderr.count("\n") == 1  # one line
    assert {p: p.read_bytes() for p in kept} == kept
    assert _hashes(tmp_path) == before  # a refused run changes nothing, anywhere in the folder
    assert not (tmp_path / "q.pc2").exists() and not (tmp_path / "s.pc2").exists()
    assert not [p for p in tmp_path.iterdir() if ".tmp-" in p.name]
    # a file edited since a run wrote it is a user's file now
    out.write_bytes(out.read_bytes() + b"\0")
    r = go("-o", out)
    assert r.returncode == 1 and "it changed since segadeform wrote it (its size or modification time: " in r.stderr
    # Python's `run` and this runtime replace each other's output, in the one manifest
    both = tmp_path / "both.pc2"
    args = ["run", "--garment", str(g), "--motion", str(m), "--model", str(random_package), "--effects", effects]
    assert main([*args, "-o", str(both), "--force"]) == 0
    assert go("-o", both).returncode == 0 and written_by(both) == "run"
    assert main([*args, "-o", str(both), "--force"]) == 0
    assert (tmp_path / MANIFEST_NAME).is_file()
    # missing folders are made, as `segadeform run` makes them
    assert go("-o", tmp_path / "new" / "dir" / "o.pc2").returncode == 0
    # a manifest that is not one (text with a line break) is refused in one line (C++ printed the break)
    odd = tmp_path / "odd"
    odd.mkdir()
    (odd / MANIFEST_NAME).write_text("not json {\n")
    r = go("-o", odd / "o.pc2")
    assert r.returncode == 1 and "not a segadeform outputs manifest" in r.stderr, r.stderr
    assert r.stderr.count("\n") == 1, r.stderr
    assert (odd / MANIFEST_NAME).read_text() == "not json {\n" and not (odd / "o.pc2").exists()


@pytest.mark.parametrize("runtime", ["node", "cpp"])
def test_the_body_cache_comes_with_its_rest_mesh(runtime, request, portable_scene, random_package, tmp_path):
    """`--body-out b.pc2` writes the body's rest mesh `b.obj` beside it, as `segadeform run` does (Blender's Mesh
    Cache and 3ds Max animate that mesh; a new user's trial: Node and C++ wrote none); a user's `c.obj` beside `c.pc2`
    is refused, untouched, and nothing is written."""
    from segadeform.io import read_mesh

    exe = request.getfixturevalue(runtime)
    g, m, effects = portable_scene["garment"], portable_scene["motion"], portable_scene["effects"]
    base = [*exe, "--package", str(random_package), "--garment", str(g), "--motion", str(m), "--effects", effects]
    args = ["run", "--garment", str(g), "--motion", str(m), "--model", str(random_package), "--effects", effects]
    assert main([*args, "-o", str(tmp_path / "py.pc2"), "--body-out", str(tmp_path / "pyb.pc2"), "--force"]) == 0
    for _ in range(2):  # written, then replaced: its own output
        r = subprocess.run(
            [*base, "-o", str(tmp_path / "a.pc2"), "--body-out", str(tmp_path / "b.pc2")],
            capture_output=True,
            text=True,
            timeout=300,
        )
        assert r.returncode == 0, r.stderr
    mine, want = read_mesh(tmp_path / "b.obj"), read_mesh(tmp_path / "pyb.obj")
    assert written_by(tmp_path / "b.obj") == "run"
    assert (mine.faces == want.faces).all() and abs(mine.vertices - want.vertices).max() < 1e-5
    (tmp_path / "c.obj").write_text("a user's mesh\n")
    before = _hashes(tmp_path)
    r = subprocess.run(
        [*base, "-o", str(tmp_path / "d.pc2"), "--body-out", str(tmp_path / "c.pc2")],
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert r.returncode == 1 and "c.obj: exists and segadeform did not write it" in r.stderr, r.stderr
    assert r.stderr.count("\n") == 1 and _hashes(tmp_path) == before


def test_segadeform_play_keeps_the_output_rule(cpp, portable_scene, random_package, tmp_path):
    """The C++ example segadeform-play (runtimes/cpp/examples/play.cpp) under segadeform-run's rule and manifest: it
    refused to run again into its own output ("exists (expected a new file)"), recorded nothing, and printed the
    cloth stage's counts with the stage off (a user's trial)."""
    from pathlib import Path

    play = str(Path(cpp[0]).with_name("segadeform-play"))
    g, m = portable_scene["garment"], portable_scene["motion"]

    def go(out, effects=portable_scene["effects"], *extra):
        return subprocess.run(
            [play, str(random_package), str(g), str(m), "--effects", effects, "-o", str(out), *extra],
            capture_output=True,
            text=True,
            timeout=300,
        )

    out = tmp_path / "a.pc2"
    for _ in range(2):  # written and recorded, then replaced: its own earlier output
        r = go(out)
        assert r.returncode == 0, r.stderr
        assert written_by(out) == "run" and "cloth:" not in r.stdout, r.stdout
    r = go(out, "+cloth")
    assert r.returncode == 0 and "; cloth: " in r.stdout and "collisions" not in r.stdout, r.stdout + r.stderr
    mine = tmp_path / "mine.pc2"
    mine.write_bytes(b"a user's file")
    before = _hashes(tmp_path)
    refusals = ((mine, "mine.pc2: exists and segadeform did not write it"), (random_package / "x.pc2", "an input"))
    for bad, words in refusals:
        for extra in ((), ("--force",)):  # --force (a motion made for another shape) never replaces a user's file
            r = go(bad, portable_scene["effects"], *extra)
            assert r.returncode == 1 and words in r.stderr and r.stderr.count("\n") == 1, (extra, r.stderr)
    assert _hashes(tmp_path) == before and not (random_package / "x.pc2").exists()
    # `segadeform run` replaces its output, and it run's, in the one manifest
    args = ["run", "--garment", str(g), "--motion", str(m), "--model", str(random_package), "--force"]
    assert main([*args, "--effects", portable_scene["effects"], "-o", str(out)]) == 0
    assert go(out).returncode == 0 and written_by(out) == "run"


@pytest.mark.parametrize("runtime", ["node", "cpp"])
def test_signed_effects_change_the_runs_defaults_as_in_segadeform_run(
    runtime, request, portable_scene, random_package, tmp_path, capsys
):
    """`--effects=+cloth`, `-wrinkles` and `none` are what `segadeform run` takes; the runtimes took complete lists
    only ("unknown option", "unknown effect '+cloth'", "unknown effect 'none'": a user's trial).  Each names the
    effects that ran as `segadeform run` names them (Node printed "..., collisions, cloth" for +cloth, where the
    cloth stage's contact replaces collisions: a user's trial)."""
    import re

    import numpy as np

    from segadeform.io import read_pc2

    exe = request.getfixturevalue(runtime)
    g, m = portable_scene["garment"], portable_scene["motion"]
    for effects in ("+cloth", "-wrinkles", "dqs,-dynamics", "none"):
        name = effects.replace(",", "_").replace("+", "p").replace("-", "m")
        py, rt = tmp_path / f"py_{name}.pc2", tmp_path / f"rt_{name}.pc2"
        args = ["run", "--garment", str(g), "--motion", str(m), "--model", str(random_package), "--force"]
        capsys.readouterr()
        assert main([*args, f"--effects={effects}", "-o", str(py)]) == 0
        said = re.search(r"effects ([a-z+]+)", capsys.readouterr().out)
        base = [*exe, "--package", str(random_package), "--garment", str(g), "--motion", str(m)]
        r = subprocess.run([*base, f"--effects={effects}", "-o", str(rt)], capture_output=True, text=True, timeout=300)
        assert r.returncode == 0, (effects, r.stderr)
        named = re.search(r"\((?:\w+: )?([a-z, ]+)\) -> ", r.stdout)
        assert said and named and named.group(1).split(", ") == said.group(1).split("+"), (effects, r.stdout)
        a, b = read_pc2(py).frames, read_pc2(rt).frames
        assert a.shape == b.shape and np.abs(a - b).max() <= 1e-5 * np.abs(a).max(), effects
    r = subprocess.run(
        [*base, "--effects", "+cloth,lbs,dynamics", "-o", str(tmp_path / "x.pc2")],
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert r.returncode == 2 and "mix a complete list with changes" in r.stderr  # a command-line mistake
    # refused by every runtime alike; an empty list too ("" kept the scene's effects, " , " turned all off)
    for twice in ("+wrinkles,-wrinkles", "lbs,dqs", "dqs,dqs", "lbs,-cloth,lbs", "", " , "):
        r = subprocess.run(
            [*base, f"--effects={twice}", "-o", str(tmp_path / "x.pc2")], capture_output=True, text=True, timeout=300
        )
        said = ("twice", "one skinning", "an empty effects list")
        assert r.returncode == 2 and any(w in r.stderr for w in said), (twice, r.stderr)
        assert (
            main(["run", "--garment", str(g), "--motion", str(m), f"--effects={twice}", "-o", str(tmp_path / "y.pc2")])
            == 2
        )
    assert not (tmp_path / "x.pc2").exists() and not (tmp_path / "y.pc2").exists()
