"""What a developer's trial of the Node and C++ command lines found (1 Dec 2026): an option given twice ran the last
one in C++; a signal left the outputs' temporaries behind; Node held the whole clip (and the posed body) in memory
before writing it; a garment split at its seams tore in Node and C++ with no word, as `garment export` and
`garment fit` said nothing of it; a bundle that leaves the scene's collisions out was played as the scene."""

from __future__ import annotations

import signal
import subprocess
import time

import numpy as np
import pytest
from click.testing import CliRunner
from scipy.spatial import cKDTree

from segadeform.cli.main import cli
from segadeform.io import Mesh, read_mesh, read_pc2, write_obj
from tests.conftest import SAMPLES, split_at_a_seam
from tests.runtimes.conftest import play

RTOL = 1e-5  # the parity rule of tests/runtimes/test_engines.py


@pytest.mark.parametrize("runtime", ["node", "cpp"])
@pytest.mark.parametrize("option, values", [("--batch", ["8", "4"]), ("--effects", ["lbs", "dqs"]), ("-o", None)])
def test_an_option_given_twice_is_a_usage_error(runtime, option, values, request, portable_scene, tmp_path):
    exe = request.getfixturevalue(runtime)
    s = portable_scene
    more = [option, values[0], option, values[1]] if values else ["-o", str(tmp_path / "y.pc2")]
    p = play(exe, "pkg", s["garment"], s["motion"], tmp_path / "x.pc2", *more)
    assert p.returncode == 2, p.stdout + p.stderr
    assert f"{option} is given more than once" in p.stderr.splitlines()[0], p.stderr
    assert not list(tmp_path.iterdir())


@pytest.mark.parametrize("runtime", ["node", "cpp"])
def test_a_signal_leaves_no_temporaries_and_no_output(runtime, request, random_package, portable_scene, tmp_path):
    """Ctrl-C or kill during a run: its outputs' hidden temporaries are removed (C++ left 172 MB of a body cache),
    and nothing is written; the folders it made for them go too, as `segadeform run`'s (they were left empty)."""
    from segadeform.cli.main import main

    exe = request.getfixturevalue(runtime)
    motion = tmp_path / "long.sgdm"
    args = ["motion", "export", "dance", "--seconds", "300", "--betas", "0.5,-0.3", "-o", str(motion)]
    assert main(args) == 0
    out = tmp_path / "out"
    out.mkdir()
    p = subprocess.Popen(
        exe
        + ["--package", str(random_package), "--garment", str(portable_scene["garment"]), "--motion", str(motion)]
        + ["-o", str(out / "new" / "deeper" / "g.pc2"), "--body-out", str(out / "new" / "b.pc2")]
        + ["--effects", "lbs,dynamics,wrinkles"],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    deadline = time.monotonic() + 300
    while not [q for q in out.rglob("*") if ".tmp-" in q.name] and p.poll() is None and time.monotonic() < deadline:
        time.sleep(0.05)
    assert p.poll() is None, "the run ended before it was stopped: " + p.stdout.read() + p.stderr.read()
    time.sleep(0.3)
    p.send_signal(signal.SIGINT)
    p.wait(timeout=60)
    assert p.returncode in (130, -signal.SIGINT), (p.returncode, p.stderr.read())
    assert [q.name for q in out.iterdir()] == []


def test_node_writes_a_long_clip_a_chunk_at_a_time_as_one_push(node, random_package, portable_scene, tmp_path):
    """Node's command line pushes the motion about 256 frames at a time (whole batches) and writes each chunk as it
    comes: the frames and the posed body are those of `segadeform run`, across the chunks' seams."""
    from segadeform.cli.main import main

    motion = tmp_path / "m.sgdm"
    assert main(["motion", "export", "dance", "--seconds", "20", "--betas", "0.5,-0.3", "-o", str(motion)]) == 0
    effects = "dqs,dynamics,wrinkles"
    p = play(
        node,
        random_package,
        portable_scene["garment"],
        motion,
        tmp_path / "n.pc2",
        "--effects",
        effects,
        "--body-out",
        str(tmp_path / "nb.pc2"),
        "--batch",
        "5",
    )
    assert p.returncode == 0, p.stdout + p.stderr
    run = ["run", "--model", str(random_package), "--garment", str(portable_scene["garment"]), "--motion", str(motion)]
    run += ["--effects", effects, "--batch", "5", "--no-cache", "--force", "-o", str(tmp_path / "p.pc2")]
    assert main([*run, "--body-out", str(tmp_path / "pb.pc2")]) == 0
    for mine, theirs in (("n.pc2", "p.pc2"), ("nb.pc2", "pb.pc2")):
        got, want = read_pc2(tmp_path / mine).frames, read_pc2(tmp_path / theirs).frames
        assert got.shape == want.shape and got.shape[0] == 600
        assert np.abs(got - want).max() <= RTOL * np.abs(want).max()
    np.testing.assert_allclose(
        read_mesh(tmp_path / "nb.obj").vertices, read_mesh(tmp_path / "pb.obj").vertices, atol=1e-9
    )


@pytest.mark.parametrize("runtime", ["node", "cpp"])
def test_what_garment_export_says_of_a_split_garment_every_runtime_says(
    runtime, request, random_package, portable_scene, tmp_path, caplog
):
    exe = request.getfixturevalue(runtime)
    m = read_mesh(portable_scene["dir"] / "dress_b.obj")
    v, f, n = split_at_a_seam(m)
    write_obj(tmp_path / "split.obj", Mesh(v, f))
    export = ["garment", "export", str(tmp_path / "split.obj"), "--betas", "0.5,-0.3", "--model", str(random_package)]
    r = CliRunner().invoke(cli, [*export, "-o", str(tmp_path / "split.sgda")])
    assert r.exit_code == 0, r.output
    seam = f"garment split.obj: {n} vertices lie on an open boundary at the place of another vertex"
    assert seam in caplog.text, caplog.text  # (the command line prints its log as "warning: ...")
    r = CliRunner().invoke(cli, ["inspect", str(tmp_path / "split.sgda")])
    assert r.exit_code == 0 and f"  said when exported: {seam}" in r.output, r.output
    p = play(exe, random_package, tmp_path / "split.sgda", portable_scene["motion"], tmp_path / "o.pc2")
    assert p.returncode == 0, p.stdout + p.stderr
    said = [ln for ln in p.stderr.splitlines() if ln.startswith("warning: when the garment asset was exported: ")]
    assert any(seam in ln for ln in said), p.stderr
    # the model's garment is the split one welded, its frames carried to every vertex of the file: no tear
    frames = read_pc2(tmp_path / "o.pc2").frames
    twins = cKDTree(m.vertices).query(v[len(m.vertices) :])[1]
    assert frames.shape[1] == len(v)
    np.testing.assert_array_equal(frames[:, len(m.vertices) :], frames[:, twins])
    # a garment without one says nothing of it
    p = play(exe, random_package, portable_scene["garment"], portable_scene["motion"], tmp_path / "q.pc2")
    assert p.returncode == 0 and "when the garment asset was exported" not in p.stderr, p.stderr


def test_garment_fit_says_a_split_garment_needs_weld(tmp_path):
    m = read_mesh(SAMPLES / "garments" / "dress.obj")
    v, f, n = split_at_a_seam(m)
    write_obj(tmp_path / "split.obj", Mesh(v, f))
    r = CliRunner().invoke(cli, ["garment", "fit", str(tmp_path / "split.obj"), "-o", str(tmp_path / "f.obj")])
    assert r.exit_code == 0, r.output
    assert f"warning: split.obj: {n} vertices lie on an open boundary" in r.output and "add --weld" in r.output
    r = CliRunner().invoke(
        cli, ["garment", "fit", str(SAMPLES / "garments" / "dress.obj"), "-o", str(tmp_path / "g.obj")]
    )
    assert r.exit_code == 0 and "open boundary" not in r.output, r.output


@pytest.mark.parametrize("runtime", ["node", "cpp"])
def test_a_bundle_without_the_scenes_collisions_says_so(runtime, request, random_package, tmp_path):
    exe = request.getfixturevalue(runtime)
    scene = tmp_path / "s.toml"
    scene.write_text(
        f'[garment]\nmesh = "{SAMPLES / "garments" / "dress.obj"}"\n[motion]\nkind = "walk"\nseconds = 0.2\n'
        f'[output]\npath = "{tmp_path / "o.pc2"}"\n[effects]\ndynamics = true\nwrinkles = true\ncollisions = true\n'
    )
    r = CliRunner().invoke(cli, ["bundle", str(scene), "--model", str(random_package), "-o", str(tmp_path / "b.sgdb")])
    assert r.exit_code == 0, r.output
    p = subprocess.run(
        exe + [str(random_package), str(tmp_path / "b.sgdb"), "-o", str(tmp_path / "x.pc2")],
        capture_output=True,
        text=True,
        timeout=600,
    )
    assert p.returncode == 0, p.stdout + p.stderr
    assert "the scene's collisions are not in the bundle: these frames are the network's alone" in p.stderr, p.stderr


@pytest.mark.parametrize("runtime", ["python", "node", "cpp"])
@pytest.mark.parametrize("said", [[1, "x"], "a string", ["two\nlines"]])
def test_asset_warnings_that_are_not_one_line_texts_are_refused(
    runtime, said, request, random_package, portable_scene, tmp_path
):
    from segadeform.errors import FileFormatError
    from segadeform.geometry import GarmentAsset
    from segadeform.io.sgdb import read_bundle, write_bundle

    arrays, meta = read_bundle(portable_scene["garment"])
    path = tmp_path / "w.sgda"
    write_bundle(path, arrays, {**meta, "warnings": said})
    if runtime == "python":
        with pytest.raises(FileFormatError, match="one-line texts"):
            GarmentAsset.load(path)
        return
    p = play(request.getfixturevalue(runtime), random_package, path, portable_scene["motion"], tmp_path / "o.pc2")
    assert p.returncode == 1 and "meta.warnings is not a list of one-line texts" in p.stderr, p.stderr
    assert str(path) in p.stderr and len(p.stderr.strip().splitlines()) == 1 and not (tmp_path / "o.pc2").exists()


def test_an_asset_exported_again_keeps_what_its_first_export_said(random_package, tmp_path):
    """What the file alone tells (a vertex in no face: Blender's import drops it) cannot be told again from an asset:
    exported again for another shape it was dropped (a review); it is kept, and not said twice."""
    from segadeform.geometry import GarmentAsset

    m = read_mesh(SAMPLES / "garments" / "dress.obj")
    write_obj(tmp_path / "loose.obj", Mesh(np.concatenate([m.vertices, [[0.0, 1.0, 0.0]]]), m.faces))
    export = ["garment", "export", "--model", str(random_package), "--force"]
    r = CliRunner().invoke(cli, [*export, str(tmp_path / "loose.obj"), "-o", str(tmp_path / "a.sgda")])
    assert r.exit_code == 0, r.output
    first = GarmentAsset.load(tmp_path / "a.sgda").warnings
    assert any("1 vertices are in no face" in w for w in first), first
    r = CliRunner().invoke(cli, [*export, str(tmp_path / "a.sgda"), "--betas", "0.3", "-o", str(tmp_path / "b.sgda")])
    assert r.exit_code == 0, r.output
    again = GarmentAsset.load(tmp_path / "b.sgda").warnings
    assert [w for w in again if "in no face" in w] == [w for w in first if "in no face" in w]
    assert len(again) == len(set(again))


def test_node_takes_a_flag_given_twice_as_click_does(node, random_package, portable_scene, tmp_path):
    p = play(
        node,
        random_package,
        portable_scene["garment"],
        portable_scene["motion"],
        tmp_path / "o.pc2",
        "--force",
        "--force",
        "--effects",
        "dqs,dynamics,wrinkles",
    )
    assert p.returncode == 0, p.stderr


def test_a_scenes_resolution_is_named_as_its_key(tmp_path):
    scene = tmp_path / "s.toml"
    scene.write_text(
        f'[garment]\nmesh = "{SAMPLES / "garments" / "skirt.obj"}"\n[motion]\nkind = "walk"\nseconds = 0.2\n'
        f'[model]\nresolution = 0.01\n[output]\npath = "{tmp_path / "o.pc2"}"\n'
    )
    r = CliRunner().invoke(cli, ["run", str(scene), "--no-cache"])
    assert r.exit_code == 1 and "s.toml: model.resolution 0.01 leaves the model" in r.output, r.output


@pytest.mark.parametrize("runtime", ["node", "cpp"])
def test_the_runtimes_write_in_the_units_and_axes_run_writes(
    runtime, request, random_package, portable_scene, tmp_path
):
    """`--up z --output-units cm` (Maya, Unreal): the garment's and the body's point caches and the body's rest OBJ
    are `segadeform run`'s, bit for bit and byte for byte."""
    from segadeform.cli.main import main

    exe = request.getfixturevalue(runtime)
    s = portable_scene
    more = ["--effects", "dqs,dynamics,wrinkles", "--up", "z", "--output-units", "cm"]
    p = play(
        exe,
        random_package,
        s["garment"],
        s["motion"],
        tmp_path / "r.pc2",
        *more,
        "--body-out",
        str(tmp_path / "rb.pc2"),
    )
    assert p.returncode == 0, p.stdout + p.stderr
    run = ["run", "--model", str(random_package), "--garment", str(s["garment"]), "--motion", str(s["motion"])]
    assert (
        main(
            [
                *run,
                *more,
                "--no-cache",
                "--force",
                "-o",
                str(tmp_path / "p.pc2"),
                "--body-out",
                str(tmp_path / "pb.pc2"),
            ]
        )
        == 0
    )
    for mine, theirs in (("r.pc2", "p.pc2"), ("rb.pc2", "pb.pc2")):
        got, want = read_pc2(tmp_path / mine).frames, read_pc2(tmp_path / theirs).frames
        assert np.abs(got - want).max() <= RTOL * np.abs(want).max()
    assert (tmp_path / "rb.obj").read_bytes() == (tmp_path / "pb.obj").read_bytes()
    metres = read_pc2(tmp_path / "p.pc2").frames
    assert np.abs(metres).max() > 50  # centimetres
    for bad, says in (
        (["--up", "x"], "--up must be y or z"),
        (["--output-units", "furlong"], "--output-units must be"),
        (["--output-units", "100"], "centimetres are cm or 0.01"),  # 100 m per unit: "x100" meant (a TD's trial)
        (["--effects", "lbs,foo"], "unknown effect"),  # exited 1 (a QA trial): a command-line mistake
    ):
        p = play(exe, random_package, s["garment"], s["motion"], tmp_path / "x.pc2", *bad)
        assert p.returncode == 2 and says in p.stderr and not (tmp_path / "x.pc2").exists(), p.stderr


def test_node_prints_numbers_as_python_prints_them(node):
    """Node's OBJ text printed 7.54e-5 as -0.0000754 and rounded ties away from zero (976885.0625 -> ...063); C's and
    Python's %.9g print -7.54e-05 and round half to even (...062)."""
    import json

    rng = np.random.default_rng(3)
    xs = (rng.choice([-1, 1], 4000) * 10.0 ** rng.uniform(-12, 12, 4000)).tolist()
    xs += rng.normal(size=2000).astype(np.float32).astype(float).tolist()
    xs += [-976885.0625, 0.5, 2.5e-5, 0.0, -0.0, 1e9, 999999999.5, 1.00000000005, 12345.678949999999]
    script = (
        "import(process.argv[1]).then(({formatG9}) => {"
        "const xs = JSON.parse(require('fs').readFileSync(0, 'utf8'));"
        "process.stdout.write(JSON.stringify(xs.map(formatG9)));})"
    )
    core = str(SAMPLES.parent / "runtimes" / "node" / "src" / "core.js")
    p = subprocess.run(["node", "-e", script, core], input=json.dumps(xs), capture_output=True, text=True, timeout=120)
    assert p.returncode == 0, p.stderr
    assert json.loads(p.stdout) == [f"{x:.9g}" for x in xs]


@pytest.mark.parametrize("runtime", ["node", "cpp"])
def test_what_motion_export_said_every_runtime_says(runtime, request, random_package, portable_scene, tmp_path):
    """`motion export` keeps what it says of a capture (its glitches) in the file; Node and C++ said nothing of it
    (a developer's trial).  A list that is not one of one-line texts is refused by every reader."""
    from segadeform.errors import FileFormatError
    from segadeform.io.sgdb import read_bundle, write_bundle
    from segadeform.io.sgdm import read_motion_arrays

    exe = request.getfixturevalue(runtime)
    arrays, meta = read_bundle(portable_scene["motion"])
    said = "the capture has 3 leading frames it settles from and 2 frames it jumps to and back from"
    write_bundle(tmp_path / "m.sgdm", arrays, {**meta, "warnings": [said]})
    p = play(exe, random_package, portable_scene["garment"], tmp_path / "m.sgdm", tmp_path / "o.pc2")
    assert p.returncode == 0, p.stderr
    assert f"warning: when the motion file was exported: {said}" in p.stderr, p.stderr
    write_bundle(tmp_path / "bad.sgdm", arrays, {**meta, "warnings": ["two\nlines"]})
    with pytest.raises(FileFormatError, match="one-line texts"):
        read_motion_arrays(tmp_path / "bad.sgdm")
    p = play(exe, random_package, portable_scene["garment"], tmp_path / "bad.sgdm", tmp_path / "x.pc2")
    assert p.returncode == 1 and "meta.warnings is not a list of one-line texts" in p.stderr, p.stderr
    assert str(tmp_path / "bad.sgdm") in p.stderr and not (tmp_path / "x.pc2").exists()
