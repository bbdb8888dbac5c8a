"""The same package, garment and motion through the Node and C++ runtimes: parity with `segadeform run` (Python)
on the garment asset and motion file those runtimes read, with the body posed by the package's body graph; and
the scene bundles they also still run."""

from __future__ import annotations

import json
import os
import subprocess
from pathlib import Path

import numpy as np
import pytest

from segadeform.errors import FileFormatError
from segadeform.io import read_pc2
from segadeform.io.sgdb import read_bundle, write_bundle
from tests.conftest import REPO, SAMPLES

RTOL = 1e-5
NODE = REPO / "runtimes" / "node"


def test_bundle_round_trip_and_errors(tmp_path):
    arrays = {
        "a": np.arange(12, dtype=np.float32).reshape(3, 4),
        "b": np.array([1, -2], np.int32),
        "m": np.array([[True, False]]),
        "s": np.float32(2.5),
    }
    write_bundle(tmp_path / "x.sgdb", arrays, {"k": [1, 2]})
    got, meta = read_bundle(tmp_path / "x.sgdb")
    assert meta == {"k": [1, 2]}
    np.testing.assert_array_equal(got["a"], arrays["a"])
    np.testing.assert_array_equal(got["b"], arrays["b"])
    assert got["m"].dtype == np.uint8 and got["m"].tolist() == [[1, 0]] and got["s"].shape == ()
    raw = (tmp_path / "x.sgdb").read_bytes()
    (tmp_path / "t.sgdb").write_bytes(raw[:200])
    with pytest.raises(FileFormatError, match="runs past the end of the file"):
        read_bundle(tmp_path / "t.sgdb")
    (tmp_path / "n.sgdb").write_bytes(b"hello")
    with pytest.raises(FileFormatError, match="not a segadeform bundle"):
        read_bundle(tmp_path / "n.sgdb")


def _parity(output: str) -> dict:
    line = next(ln for ln in output.splitlines() if "PARITY" in ln)
    return json.loads(line.split("PARITY", 1)[1].strip())


def _rel(got, want) -> float:
    got, want = np.asarray(got, np.float64), np.asarray(want, np.float64)
    assert got.shape == want.shape and np.isfinite(got).all()
    return float(np.abs(got - want).max() / np.abs(want).max())


@pytest.mark.parametrize("runtime", ["node", "cpp"])
def test_runtime_animates_the_garment_asset_and_motion_like_segadeform_run(
    runtime, request, portable_scene, random_package, tmp_path
):
    """`segadeform-node` / `segadeform-run --package P --garment G.sgda --motion M.sgdm -o OUT --body-out BODY`:
    the garment's frames and the posed body's equal `segadeform run`'s on the same garment and motion."""
    exe = request.getfixturevalue(runtime)
    s = portable_scene
    p = subprocess.run(
        exe
        + [
            "--package",
            str(random_package),
            "--garment",
            str(s["garment"]),
            "--motion",
            str(s["motion"]),
            "--effects",
            s["effects"],
            "-o",
            str(tmp_path / "g.pc2"),
            "--body-out",
            str(tmp_path / "b.pc2"),
            "--batch",
            "5",
        ],
        capture_output=True,
        text=True,
        timeout=600,
    )
    assert p.returncode == 0, p.stdout + p.stderr
    assert "deformer" in p.stdout or "dqs" in p.stdout
    assert _rel(read_pc2(tmp_path / "g.pc2").frames, s["frames"]) <= RTOL
    assert _rel(read_pc2(tmp_path / "b.pc2").frames, s["body"]) <= RTOL
    # the body's rest mesh beside its point cache: segadeform run's numbers (a user's trial: Python wrote its float64
    # rest, 2.4e-7 m off the body graph's that Node and C++ write)
    from segadeform.io import read_mesh

    mine, theirs = read_mesh(s["dir"] / "python_body.obj"), read_mesh(tmp_path / "b.obj")
    np.testing.assert_array_equal(theirs.faces, mine.faces)
    np.testing.assert_allclose(theirs.vertices, mine.vertices, rtol=0, atol=1e-9)
    # the model's own effects when none are named (LBS, dynamics, wrinkles; and collisions, the package having a
    # body graph): runs, and differs from DQS
    p = subprocess.run(
        exe
        + [
            "--package",
            str(random_package),
            "--garment",
            str(s["garment"]),
            "--motion",
            str(s["motion"]),
            "-o",
            str(tmp_path / "own.pc2"),
        ],
        capture_output=True,
        text=True,
        timeout=600,
    )
    assert p.returncode == 0, p.stderr
    assert "collisions: " in p.stdout, p.stdout
    own = read_pc2(tmp_path / "own.pc2").frames
    assert own.shape == s["frames"].shape and np.isfinite(own).all() and not np.allclose(own, s["frames"])


def test_segadeform_run_refuses_an_asset_of_another_weight_prior_as_the_runtimes_do(
    portable_scene, random_package, tmp_path
):
    """An asset whose body weights were made with another model's weight prior: Node and C++ refuse it (below);
    `segadeform run` recomputed them and played the file (a developer's trial: checked with the Python runtime,
    refused by the embedded library)."""
    import dataclasses

    from click.testing import CliRunner

    from segadeform.cli.main import cli
    from segadeform.geometry import GarmentAsset

    a = GarmentAsset.load(portable_scene["garment"])
    dataclasses.replace(a, body=dict(a.body, weight_prior="inpaint")).save(tmp_path / "inpaint.sgda")
    out = tmp_path / "x.pc2"
    args = ["run", "--model", str(random_package), "--motion", str(portable_scene["motion"]), "-o", str(out)]
    r = CliRunner().invoke(cli, [*args, "--garment", str(tmp_path / "inpaint.sgda")])
    assert r.exit_code == 1 and "made with the inpaint weight prior, the model wants nearest" in r.output, r.output
    assert "segadeform garment export" in r.output and not out.exists()
    assert CliRunner().invoke(cli, [*args, "--garment", str(portable_scene["garment"])]).exit_code == 0


@pytest.mark.parametrize("runtime", ["node", "cpp"])
def test_runtime_refuses_what_it_cannot_run(runtime, request, portable_scene, random_package, tmp_path):
    exe = request.getfixturevalue(runtime)
    s = portable_scene
    from segadeform.geometry import GarmentAsset

    a = GarmentAsset.load(s["garment"])
    import dataclasses

    dataclasses.replace(a, betas=None, log_wbody=None, body=None).save(tmp_path / "plain.sgda")  # not for a body
    dataclasses.replace(a, body={"name": "other.npz", "sha256": "0" * 64}).save(tmp_path / "other.sgda")
    dataclasses.replace(a, body=dict(a.body, weight_prior="inpaint")).save(tmp_path / "inpaint.sgda")
    # exported for another model (a shorter descriptor): onnxruntime's own error named neither file nor fix
    dataclasses.replace(a, descriptor=a.descriptor[:16], fps_samples=a.fps_samples[:16]).save(tmp_path / "m16.sgda")
    (tmp_path / "folder.sgda").mkdir()

    def run(*args):
        return subprocess.run(
            exe + ["--package", str(random_package), "-o", str(tmp_path / "x.pc2")] + list(args),
            capture_output=True,
            text=True,
            timeout=600,
        )

    cases = [
        (["--garment", str(tmp_path / "plain.sgda"), "--motion", str(s["motion"])], "not prepared for a body shape"),
        (["--garment", str(s["motion"]), "--motion", str(s["motion"])], "not a garment asset"),
        (["--garment", str(s["garment"]), "--motion", str(s["garment"])], "not a motion file"),
        (["--garment", str(s["garment"]), "--motion", str(tmp_path / "missing.sgdm")], "missing.sgdm: no such file"),
        (
            ["--garment", str(tmp_path / "m16.sgda"), "--motion", str(s["motion"])],
            "m16.sgda: the garment asset was exported for another model; export it for this one: segadeform garment "
            "export GARMENT --model PACKAGE (expected a garment descriptor of 32 values, got 16)",
        ),
        (["--garment", str(tmp_path / "folder.sgda"), "--motion", str(s["motion"])], "folder.sgda: is a directory"),
        (
            [
                "--garment",
                str(tmp_path / "other.sgda"),
                "--motion",
                str(s["motion"]),
                "--body-out",
                str(tmp_path / "b.pc2"),
            ],
            # the asset is for another body than the package's, and so than the motion's: either refusal names it
            ("prepared for another body", "retargeted onto another body than the garment asset's"),
        ),
        (
            ["--garment", str(tmp_path / "inpaint.sgda"), "--motion", str(s["motion"])],
            "made with the inpaint weight prior, the model wants nearest",
        ),
        # with no stage posing the body (effects none; the motion's mismatch forced): still refused (it played)
        (
            ["--garment", str(tmp_path / "other.sgda"), "--motion", str(s["motion"]), "--effects", "none", "--force"],
            "prepared for another body than the package's",
        ),
    ]
    # damaged or crafted bundles (a C++ integrator's trial: std::invalid_argument from stoi, reads out of bounds
    # under ASan, a stack overflow on deep nesting): one line naming the file, exit 1
    head = b"SEGADEFORM-BUNDLE 1\n"
    hostile = {
        "count.sgda": head + b"abc\nmeta {}\nEND\n",
        "bigcount.sgda": head + b"99999999999\nmeta {}\nEND\n",
        "negoffset.sgda": head + b"1\nvertices f64 2 2 3 -5000 48\nmeta {}\nEND\n" + b"\0" * 80,
        "negdim.sgda": head + b"1\nvertices f64 2 -1 3 0 -24\nmeta {}\nEND\n",
        "hugedim.sgda": head + b"1\nvertices f64 2 4611686018427387904 4 0 0\nmeta {}\nEND\n",
        "deep.sgda": head + b"0\nmeta " + b"[" * 200_000 + b"\nEND\n",
    }
    for name, data in hostile.items():
        (tmp_path / name).write_bytes(data)
        cases.append((["--garment", str(tmp_path / name), "--motion", str(s["motion"])], name))
    # an --effects list's own mistake is a command-line one: exit 2, with the usage, as `segadeform run` (a QA trial)
    p = run("--garment", str(s["garment"]), "--motion", str(s["motion"]), "--effects", "lbs,wind")
    assert p.returncode == 2 and "--effects: unknown effect 'wind'" in p.stderr, p.stderr
    assert not (tmp_path / "x.pc2").exists()
    for args, words in cases:
        p = run(*args)
        either = (words,) if isinstance(words, str) else words
        assert p.returncode == 1 and any(w in p.stderr for w in either), (args, p.stderr)
        assert len([ln for ln in p.stderr.splitlines() if not ln.startswith("warning:")]) == 1, (args, p.stderr)
        assert not (tmp_path / "x.pc2").exists()
    assert run("--garment", str(s["garment"])).returncode == 2  # usage: no motion
    assert not (tmp_path / "b.pc2").exists()


def test_node_api_matches_python_on_a_bundle_and_on_asset_and_motion(
    shared_bundle, portable_scene, random_package, node
):
    """The Node API (`animate(package, garment.sgda, motion.sgdm, {body: true})`, and `animate(package, bundle)`)."""
    s = portable_scene
    env = dict(
        os.environ,
        SEGADEFORM_PACKAGE=str(random_package),
        SEGADEFORM_BUNDLE=str(shared_bundle),
        SEGADEFORM_GARMENT=str(s["garment"]),
        SEGADEFORM_MOTION=str(s["motion"]),
        SEGADEFORM_CHECK=str(s["check"]),
        SEGADEFORM_EFFECTS=s["effects"],
    )
    p = subprocess.run(["npm", "test"], cwd=NODE, env=env, capture_output=True, text=True, timeout=600)
    assert p.returncode == 0, (p.stdout + p.stderr)[-3000:]
    r = _parity(p.stdout)
    assert r["rel"] <= RTOL, r
    assert "# skipped 0" in p.stdout and "# fail 0" in p.stdout  # the parity tests ran
    line = next(ln for ln in p.stdout.splitlines() if "PARITY_ASSET" in ln)
    a = json.loads(line.split("PARITY_ASSET", 1)[1])
    assert a["garment"]["rel"] <= RTOL and a["body"]["rel"] <= RTOL, a


def test_cpp_runtime_matches_python_on_a_bundle(shared_bundle, random_package, cpp, tmp_path):
    exe = cpp[0]
    p = subprocess.run(
        [exe, str(random_package), str(shared_bundle), "-o", str(tmp_path / "o.pc2"), "--check", "--batch", "3"],
        capture_output=True,
        text=True,
        timeout=600,
    )
    assert p.returncode == 0, p.stderr
    assert _parity(p.stdout)["rel"] <= RTOL
    arrays, _ = read_bundle(shared_bundle)
    np.testing.assert_allclose(read_pc2(tmp_path / "o.pc2").frames, arrays["expected"], rtol=0, atol=1e-5)
    bad = subprocess.run(
        [exe, str(random_package), str(tmp_path / "missing.sgdb"), "-o", str(tmp_path / "x.pc2")],
        capture_output=True,
        text=True,
    )
    assert bad.returncode == 1 and "missing.sgdb: no such file" in bad.stderr and not (tmp_path / "x.pc2").exists()
    # --check on a bundle made with --no-expected said "bundle has no array 'expected'", naming no file, after the
    # sessions were built (a technical artist's trial): the file, the cause and the fix, first
    from segadeform.io.sgdb import write_bundle

    meta = read_bundle(shared_bundle)[1]
    write_bundle(tmp_path / "ne.sgdb", {k: v for k, v in arrays.items() if k != "expected"}, meta)
    ne = subprocess.run(
        [exe, str(random_package), str(tmp_path / "ne.sgdb"), "-o", str(tmp_path / "y.pc2"), "--check"],
        capture_output=True,
        text=True,
    )
    said = f"Error: {tmp_path / 'ne.sgdb'}: the bundle holds no expected frames to --check against"
    assert ne.returncode == 1 and ne.stderr.startswith(said) and ne.stderr.count("\n") == 1, ne.stderr
    assert not (tmp_path / "y.pc2").exists()


@pytest.mark.parametrize("runtime", ["node", "cpp"])
@pytest.mark.parametrize("schema", [1, 2])
def test_runtimes_still_run_older_packages(runtime, schema, request, portable_scene, random_package, tmp_path):
    """Schema 1 and 2 packages (int64 nbr and bool mask inputs, no body graphs): fed in their manifests' dtypes,
    the same frames; asking them for the body says why not."""
    from tests.export.legacy import as_schema

    exe = request.getfixturevalue(runtime)
    s = portable_scene
    old = as_schema(random_package, tmp_path / f"v{schema}", schema)
    args = exe + [
        "--package",
        str(old),
        "--garment",
        str(s["garment"]),
        "--motion",
        str(s["motion"]),
        "--effects",
        s["effects"],
        "-o",
        str(tmp_path / "g.pc2"),
    ]
    p = subprocess.run(args, capture_output=True, text=True, timeout=600)
    assert p.returncode == 0, p.stderr
    assert _rel(read_pc2(tmp_path / "g.pc2").frames, s["frames"]) <= RTOL
    p = subprocess.run(args + ["--body-out", str(tmp_path / "b.pc2")], capture_output=True, text=True, timeout=600)
    assert p.returncode == 1 and "no body graph" in p.stderr and not (tmp_path / "b.pc2").exists()


@pytest.mark.parametrize("runtime", ["node", "cpp"])
def test_a_motion_made_for_another_body_shape_is_refused_unless_forced(
    runtime, request, portable_scene, random_package, tmp_path
):
    """The garment asset is prepared for betas 0.5,-0.3; a motion exported for the mean shape is refused, as
    `segadeform run` refuses it (the runtimes played it with a warning: a new user's trial), and nothing is
    written; `--force` plays it, with the warning (the C++ runtime once compared only the body files)."""
    from segadeform.cli.main import main

    assert main(["motion", "export", "dance", "--seconds", "0.2", "--seed", "2", "-o", str(tmp_path / "m0.sgdm")]) == 0
    exe = request.getfixturevalue(runtime)
    s = portable_scene
    args = ["--package", str(random_package), "--garment", str(s["garment"]), "-o", str(tmp_path / "g.pc2")]
    p = subprocess.run(
        exe + args + ["--motion", str(tmp_path / "m0.sgdm")], capture_output=True, text=True, timeout=600
    )
    assert p.returncode == 1 and p.stderr.count("\n") == 1, p.stdout + p.stderr
    assert p.stderr.startswith(f"Error: {tmp_path / 'm0.sgdm'}: the motion was retargeted onto another body shape")
    assert "or --force" in p.stderr and not (tmp_path / "g.pc2").exists()
    assert (
        main(
            [
                "run",
                "--garment",
                str(s["garment"]),
                "--motion",
                str(tmp_path / "m0.sgdm"),
                "--model",
                str(random_package),
                "-o",
                str(tmp_path / "py.pc2"),
            ]
        )
        == 1
    )  # as Python refuses it
    for motion, extra, warns in ((tmp_path / "m0.sgdm", ["--force"], True), (s["motion"], [], False)):
        p = subprocess.run(exe + args + ["--motion", str(motion), *extra], capture_output=True, text=True, timeout=600)
        assert p.returncode == 0, p.stdout + p.stderr
        assert ("another body shape (betas)" in p.stderr) == warns, p.stderr


@pytest.mark.parametrize("runtime", ["node", "cpp"])
def test_a_package_whose_body_graph_is_not_its_training_body_is_refused_unless_forced(
    runtime, request, portable_scene, random_package, tmp_path
):
    """`export-body --force` gives a package another body's graphs and keeps `training_body`; Python refused a run on
    it, Node and C++ played it without a word (a review).  Now they refuse it (one line naming the package, nothing
    written) unless `--force`, which plays it with a warning; the Node API likewise unless `force: true`."""
    import shutil

    pkg = tmp_path / "pkg"
    shutil.copytree(random_package, pkg)
    m = json.loads((pkg / "manifest.json").read_text())
    (pkg / "manifest.json").write_text(json.dumps({**m, "training_body": {"name": "tall.npz", "sha256": "ab" * 32}}))
    exe = request.getfixturevalue(runtime)
    s = portable_scene
    args = ["--package", str(pkg), "--garment", str(s["garment"]), "--motion", str(s["motion"])]
    p = subprocess.run(exe + args + ["-o", str(tmp_path / "a.pc2")], capture_output=True, text=True, timeout=600)
    assert p.returncode == 1 and p.stderr.count("\n") == 1, p.stdout + p.stderr
    assert p.stderr.startswith(f"Error: {pkg}: the package's body graph 'body_") and "tall.npz abababababab" in p.stderr
    assert "or --force" in p.stderr and not (tmp_path / "a.pc2").exists()
    p = subprocess.run(
        exe + args + ["-o", str(tmp_path / "b.pc2"), "--force"], capture_output=True, text=True, timeout=600
    )
    assert p.returncode == 0 and "warning: the package's body graph" in p.stderr, p.stdout + p.stderr
    # the scene-bundle form, which takes no --force, refuses it too and says which form forces it
    bundle = request.getfixturevalue("shared_bundle")
    p = subprocess.run(exe + [str(pkg), str(bundle), "-o", str(tmp_path / "d.pc2")], capture_output=True, text=True,
                       timeout=600)  # fmt: skip
    assert p.returncode == 1 and p.stderr.startswith(f"Error: {pkg}: the package's body graph"), p.stderr
    assert "or --package/--garment/--motion with --force" in p.stderr and not (tmp_path / "d.pc2").exists()
    # the same package with its own record: played without a word
    (pkg / "manifest.json").write_text(json.dumps(m))
    p = subprocess.run(exe + args + ["-o", str(tmp_path / "c.pc2")], capture_output=True, text=True, timeout=600)
    assert p.returncode == 0 and "body graph" not in p.stderr, p.stdout + p.stderr
    if runtime == "node":
        (pkg / "manifest.json").write_text(json.dumps({**m, "training_body": {"name": "t", "sha256": "ab" * 32}}))
        got = _node_api_refused_then_forced(pkg, s["garment"], s["motion"])
        assert got["refused"] and "poses another body than its model was trained on" in got["refused"]
        assert "force: true" in got["refused"] and any("trained on" in w for w in got["warnings"]) and got["T"] > 0


@pytest.mark.parametrize("runtime", ["node", "cpp"])
def test_threads_past_the_cpus_are_lowered_and_said(runtime, request, portable_scene, random_package, tmp_path):
    """`--threads 4096` ran 4096 threads (1000 took about 6 s a frame: a user's trial); the command lines lower it to
    the CPUs the process may run on and say so, as `segadeform run` does, and the frames are those of that many."""
    import os

    cpus = len(os.sched_getaffinity(0))
    exe = request.getfixturevalue(runtime)
    s = portable_scene
    base = ["--package", str(random_package), "--garment", str(s["garment"]), "--motion", str(s["motion"])]
    got = {}
    for asked in (cpus, 4096):
        out = tmp_path / f"t{asked}.pc2"
        p = subprocess.run(exe + base + ["-o", str(out), "--threads", str(asked)], capture_output=True, text=True,
                           timeout=600)  # fmt: skip
        assert p.returncode == 0, p.stdout + p.stderr
        said = f"threads: {cpus}, not 4096 (the CPUs this process may use)"
        assert (said in p.stdout) == (asked == 4096), p.stdout
        got[asked] = out.read_bytes()
    assert got[cpus] == got[4096]


def _node_api_refused_then_forced(package, garment, motion) -> dict:
    """The Node API's `animate(package, garment, motion)` without and with `force: true`: { refused (the error
    message, or None), warnings and T of the forced run }."""
    index = (REPO / "runtimes" / "node" / "src" / "index.js").as_uri()
    script = (
        f"import {{ animate }} from {json.dumps(index)};\n"
        "const [pkg, g, m] = process.argv.slice(1);\n"
        "let refused = null;\n"
        "try { await animate(pkg, g, m); } catch (e) { refused = e.message; }\n"
        "const r = await animate(pkg, g, m, { force: true });\n"
        "console.log('RESULT' + JSON.stringify({ refused, warnings: r.warnings, T: r.T }));\n"
    )
    return _node_result(script, package, garment, motion)


def _node_result(script: str, *args) -> dict:
    """Run the ES module ``script`` with ``args`` in Node; what it printed after ``RESULT``, read as JSON."""
    p = subprocess.run(["node", "--input-type=module", "-e", script, *map(str, args)],
                       capture_output=True, text=True, timeout=600)  # fmt: skip
    assert p.returncode == 0, p.stdout + p.stderr
    return json.loads(next(ln for ln in p.stdout.splitlines() if ln.startswith("RESULT"))[6:])


def test_the_node_api_refuses_a_motion_made_for_another_shape_unless_forced(
    node, portable_scene, random_package, tmp_path
):
    """The command lines refused it; the API (`animate()`, and the browser's, which shares core.js) played it with a
    warning (left over from a trial).  Now it throws unless `force: true`, which plays it with the warning."""
    from segadeform.cli.main import main

    assert main(["motion", "export", "dance", "--seconds", "0.2", "--seed", "2", "-o", str(tmp_path / "m0.sgdm")]) == 0
    got = _node_api_refused_then_forced(random_package, portable_scene["garment"], tmp_path / "m0.sgdm")
    assert got["refused"] and "another body shape (betas)" in got["refused"] and "force: true" in got["refused"]
    assert got["T"] > 0 and any("another body shape" in w for w in got["warnings"])
    assert got["warnings"].count(next(w for w in got["warnings"] if "another body shape" in w)) == 1  # said once
    # a Player opened with { asset, motion } (the page of one's own, runtimes/web/examples/embed.html) played it
    # without a word (a web developer's trial): refused the same way, played with the warning under force
    index = (REPO / "runtimes" / "node" / "src" / "index.js").as_uri()
    script = (
        f"import {{ open }} from {json.dumps(index)};\n"
        "const [pkg, g, m] = process.argv.slice(1);\n"
        "const opts = { effects: 'lbs', motion: m };\n"
        "let refused = null;\n"
        "try { await open(pkg, g, opts); } catch (e) { refused = e.message; }\n"
        "const p = await open(pkg, g, { ...opts, force: true });\n"
        "const mine = await open(pkg, g, { effects: 'lbs' });\n"
        "console.log('RESULT' + JSON.stringify({ refused, warnings: p.warnings, mine: mine.warnings }));\n"
        "await p.close(); await mine.close();\n"
    )
    got = _node_result(script, random_package, portable_scene["garment"], tmp_path / "m0.sgdm")
    assert got["refused"] and "another body shape (betas)" in got["refused"] and "force: true" in got["refused"]
    assert any("another body shape" in w for w in got["warnings"])
    assert not any("another body shape" in w for w in got["mine"])  # no motion given: the host answers for it


@pytest.mark.parametrize("runtime", ["node", "cpp"])
def test_a_mesh_or_a_motion_file_given_to_a_runtime_names_the_export(
    runtime, request, portable_scene, random_package, tmp_path
):
    """`--garment G.obj` or `--motion M.bvh` said only "not a segadeform bundle"; they now name the export command
    that makes what these runtimes read."""
    exe = request.getfixturevalue(runtime)
    s = portable_scene
    base = ["--package", str(random_package), "-o", str(tmp_path / "o.pc2")]
    for garment, motion, says in (
        (SAMPLES / "garments" / "dress.obj", s["motion"], "segadeform garment export"),
        (s["garment"], SAMPLES / "motions" / "cmu" / "02_01_walk.bvh", "segadeform motion export"),
    ):
        p = subprocess.run(
            exe + base + ["--garment", str(garment), "--motion", str(motion)],
            capture_output=True,
            text=True,
            timeout=600,
        )
        assert p.returncode != 0 and "not a segadeform bundle" in p.stderr and says in p.stderr, p.stderr
        assert not (tmp_path / "o.pc2").exists()


def test_node_says_what_is_wrong_with_its_command_line(node, random_package, tmp_path):
    """A misspelled flag or a missing --motion printed the usage alone."""
    for extra, says in (
        (["--motion", "m.sgdm", "--efects", "lbs"], "unknown option --efects"),
        ([], "--motion is missing"),
        (["--motion", "m.sgdm", "--batch", "2", "--batch", "4"], "--batch is given more than once"),
        (["--motion"], "--motion needs a value"),
        # not read as 8 and 2 (a user's trial: parseInt ran them, exit 0)
        (["--motion", "m.sgdm", "--batch", "8x"], "--batch must be an integer >= 1"),
        (["--motion", "m.sgdm", "--threads", "2.5"], "--threads must be an integer >= 1"),
    ):
        args = ["--package", str(random_package), "--garment", "g.sgda", "-o", str(tmp_path / "o.pc2"), *extra]
        p = subprocess.run(node + args, capture_output=True, text=True, timeout=120)
        assert p.returncode == 2 and p.stderr.startswith(f"error: {says}\nusage: "), p.stderr


def test_cpp_says_what_is_wrong_with_its_command_line(cpp, random_package, tmp_path):
    """`--batch 0`, a missing -o or --package printed the usage alone (a user's trial)."""
    o = ["-o", str(tmp_path / "o.pc2")]
    for args, says in (
        (
            ["--package", str(random_package), "--garment", "g.sgda", *o, "--motion", "m.sgdm", "--efects", "lbs"],
            "unknown option --efects",
        ),
        (["--package", str(random_package), "--garment", "g.sgda", *o], "--motion is missing"),
        (["--garment", "g.sgda", "--motion", "m.sgdm", *o], "--package is missing"),
        (["--package", str(random_package), "--garment", "g.sgda", "--motion", "m.sgdm"], "-o OUT.pc2 is missing"),
        (
            ["--package", str(random_package), "--garment", "g.sgda", "--motion", "m.sgdm", *o, "--batch", "0"],
            "--batch must be an integer >= 1",
        ),
        (
            ["--package", str(random_package), "--garment", "g.sgda", "--motion", "m.sgdm", *o, "--batch", "x"],
            "--batch has a bad value",
        ),
        (  # not read as 8 and 2 (a user's trial: std::stoi ran them, exit 0)
            ["--package", str(random_package), "--garment", "g.sgda", "--motion", "m.sgdm", *o, "--batch", "8x"],
            "--batch has a bad value",
        ),
        (
            ["--package", str(random_package), "--garment", "g.sgda", "--motion", "m.sgdm", *o, "--threads", "2.5"],
            "--threads has a bad value",
        ),
        (["--package", str(random_package), "--garment", "g.sgda", *o, "--motion"], "--motion needs a value"),
    ):
        p = subprocess.run(cpp + args, capture_output=True, text=True, timeout=120)
        assert p.returncode == 2 and p.stderr.startswith(f"error: {says}\nusage: "), (args, p.stderr)


@pytest.mark.parametrize("runtime", ["node", "cpp"])
def test_a_bad_margin_or_cloth_knob_is_a_command_line_mistake(
    runtime, request, portable_scene, random_package, tmp_path
):
    """A margin or a cloth knob out of range, an unknown knob, a knob of a stage that is off: one `error:` line and the
    usage, exit 2, as `segadeform run` refuses them (a new user's trial: exit 1 with `Error:`, or no `error:` prefix;
    C++ printed -1 as -1.000000 and 1e30 as 1000000000000000019884624838656.000000)."""
    exe = request.getfixturevalue(runtime)
    s = portable_scene
    base = ["--package", str(random_package), "--garment", str(s["garment"]), "--motion", str(s["motion"])]
    out = tmp_path / "o.pc2"
    for extra, says in (
        (["--collision-margin", "-1"], "--collision-margin must be in [0, 1) metres (got -1)"),
        (["--collision-margin", "5"], "--collision-margin must be in [0, 1) metres (got 5)"),
        (["--collision-margin", "1e30"], "--collision-margin must be in [0, 1) metres (got 1e30)"),
        (["--collision-margin", " -2 "], "--collision-margin must be in [0, 1) metres (got -2)"),  # quoted trimmed
        (
            ["--effects=+cloth", "--cloth", "iterations=100"],
            "--cloth: cloth iterations must be an integer in [1, 64] (got '100')",
        ),
        (["--effects=+cloth", "--cloth", "bogus=1"], "--cloth: unknown cloth setting (expected NAME=VALUE with NAME"),
        (
            ["--effects", "lbs", "--cloth", "iterations=4"],
            "--cloth sets the cloth stage's knobs, but the stage is off (name cloth in --effects)",
        ),
    ):
        p = subprocess.run(exe + base + ["-o", str(out), *extra], capture_output=True, text=True, timeout=120)
        assert p.returncode == 2 and p.stderr.startswith(f"error: {says}"), (extra, p.stderr)
        assert p.stderr.splitlines()[1].startswith("usage: "), (extra, p.stderr)
        assert not out.exists()


@pytest.mark.parametrize("runtime", ["node", "cpp"])
def test_a_collision_margin_without_collisions_or_cloth_is_a_command_line_mistake(
    runtime, request, portable_scene, random_package, tmp_path
):
    """`--effects lbs --collision-margin 0.01` ran, the margin ignored (a new user's trial: exit 0); `segadeform run`
    refuses a knob of an effect that will not run, and so do these command lines.  With collisions or the stage on
    (named, or the package's defaults: it has a body graph) the margin is taken."""
    exe = request.getfixturevalue(runtime)
    s = portable_scene
    base = ["--package", str(random_package), "--garment", str(s["garment"]), "--motion", str(s["motion"])]
    out = tmp_path / "o.pc2"
    says = "error: --collision-margin sets the push-out's margin, but neither collisions nor the cloth stage is on\n"
    for effects in (["--effects", "lbs"], ["--effects", "none"], ["--effects=-collisions"]):
        p = subprocess.run(
            exe + base + ["-o", str(out), *effects, "--collision-margin", "0.01"], capture_output=True, text=True
        )
        assert p.returncode == 2 and p.stderr.startswith(says), (effects, p.stderr)
        assert p.stderr.splitlines()[1].startswith("usage: "), (effects, p.stderr)
        assert not out.exists()
    for effects in (["--effects", "lbs,collisions"], []):
        p = subprocess.run(
            exe + base + ["-o", str(out), *effects, "--collision-margin", "0.01"], capture_output=True, text=True
        )
        assert p.returncode == 0 and "(margin 0.01 m)" in p.stdout, (effects, p.stdout + p.stderr)
        out.unlink()


@pytest.mark.parametrize("runtime", ["node", "cpp"])
def test_a_cut_motion_file_keeps_its_frame_numbers(runtime, request, portable_scene, random_package, tmp_path):
    """`motion export ... --frames 10:14` made a file whose Node and C++ point caches started at frame 0, while `run
    --frames 10:14` writes 10: in Blender the two were 10 frames apart."""
    from segadeform.cli.main import main

    m = tmp_path / "cut.sgdm"
    assert (
        main(
            ["motion", "export", "dance", "--seconds", "0.6", "--betas", "0.5,-0.3", "--frames", "10:14", "-o", str(m)]
        )
        == 0
    )
    exe = request.getfixturevalue(runtime)
    args = ["--package", str(random_package), "--garment", str(portable_scene["garment"]), "--motion", str(m)]
    p = subprocess.run(
        exe + args + ["-o", str(tmp_path / "g.pc2"), "--body-out", str(tmp_path / "b.pc2")],
        capture_output=True,
        text=True,
        timeout=600,
    )
    assert p.returncode == 0, p.stdout + p.stderr
    for f in ("g.pc2", "b.pc2"):
        pc = read_pc2(tmp_path / f)
        assert pc.header.start_frame == 10.0 and pc.frames.shape[0] == 4, (f, pc.header)


@pytest.mark.parametrize("runtime", ["node", "cpp"])
def test_a_bundle_of_a_scene_with_frames_keeps_its_frame_numbers(runtime, request, random_package, tmp_path):
    """A bundle of a scene with `frames = "2:6"` gave point caches starting at frame 0 (a user's trial): the bundle
    now records where its motion starts, and every runtime numbers its frames from there."""
    from segadeform.runtime.scene_bundle import scene_bundle
    from segadeform.settings import load_scene

    scene = tmp_path / "s.toml"
    scene.write_text(
        f'[garment]\nmesh = "{SAMPLES / "garments" / "skirt.obj"}"\n[motion]\nkind = "walk"\nseconds = 0.3\n'
        f'frames = "2:6"\n[output]\npath = "{tmp_path / "py.pc2"}"\n'
    )
    b = scene_bundle(load_scene(scene), tmp_path / "s.sgdb", model=random_package, batch=3)
    exe = request.getfixturevalue(runtime)
    p = subprocess.run(
        exe + [str(random_package), str(b), "-o", str(tmp_path / "o.pc2")], capture_output=True, text=True, timeout=600
    )
    assert p.returncode == 0, p.stdout + p.stderr
    pc = read_pc2(tmp_path / "o.pc2")
    assert pc.header.start_frame == 2.0 and pc.frames.shape[0] == 4, pc.header
    arrays, meta = read_bundle(b)
    assert meta["start_frame"] == 2
    np.testing.assert_allclose(pc.frames, arrays["expected"], rtol=0, atol=1e-5)


@pytest.mark.parametrize("runtime", ["node", "cpp"])
def test_a_motion_or_asset_holding_nan_is_refused_and_rotations_written_otherwise_play_alike(
    runtime, request, portable_scene, random_package, tmp_path, capsys
):
    """A user's trial: the Node and C++ runtimes checked the shapes of a .sgdm / .sgda, not the values -- a NaN pose, a
    translation of 3e38 m, an fps of 0 or a NaN in the asset's joints gave a cache of NaN with exit 0 -- and fed a
    rotation written with an extra turn about its axis to the network as it was (2 cm from Python, which writes every
    rotation one way).  Now each is refused in one line naming the file and field, and the turned motion plays the
    frames of the plain one, as in Python."""
    from segadeform.cli.main import main

    exe = request.getfixturevalue(runtime)
    s = portable_scene
    arrays, meta = read_bundle(s["motion"])
    asset, ameta = read_bundle(s["garment"])
    bad = []
    for name, change in (
        ("nan_pose", lambda a, m: a["poses"].__setitem__((1, 5, 1), np.nan)),
        ("far", lambda a, m: a["trans"].__setitem__((0, 0), 3e38)),
        ("fps0", lambda a, m: m.__setitem__("fps", 0)),
        ("start", lambda a, m: m.__setitem__("start_frame", 1e300)),
    ):
        a, m = {k: v.copy() for k, v in arrays.items()}, dict(meta)
        change(a, m)
        write_bundle(tmp_path / f"{name}.sgdm", a, m)
        bad.append((s["garment"], tmp_path / f"{name}.sgdm", f"{name}.sgdm"))
    # the first bad value named by its index, in every runtime (Python said "motion contains NaN or inf", Node "at
    # value 3613": a user's trial)
    said = "nan_pose.sgdm: field 'poses' contains NaN or inf (first at index [1, 5, 1])"
    bad[0] = (*bad[0][:2], said)
    assert main(["run", "--garment", str(s["garment"]), "--motion", str(tmp_path / "nan_pose.sgdm"), "-o",
                 str(tmp_path / "x.pc2"), "--model", str(random_package)]) == 1  # fmt: skip
    assert said in capsys.readouterr().err
    a = {k: v.copy() for k, v in asset.items()}
    a["joints"][2, 1] = np.nan
    write_bundle(tmp_path / "nan.sgda", a, ameta)
    bad.append((tmp_path / "nan.sgda", s["motion"], "nan.sgda: field 'joints' contains NaN or inf"))
    a = {k: v.copy() for k, v in asset.items()}
    a["vertices"][0, 0] = 1e30  # finite, and NaN out of the encoder (Python named no file)
    write_bundle(tmp_path / "far.sgda", a, ameta)
    bad.append((tmp_path / "far.sgda", s["motion"], "far.sgda: field 'vertices' lies beyond 10 km"))
    from segadeform.geometry import GarmentAsset

    with pytest.raises(FileFormatError, match=r"far\.sgda.*'vertices' lies beyond 10 km"):
        GarmentAsset.load(tmp_path / "far.sgda")
    base = [*exe, "--package", str(random_package)]
    for garment, motion, says in bad:
        p = subprocess.run(
            [*base, "--garment", str(garment), "--motion", str(motion), "-o", str(tmp_path / "x.pc2")],
            capture_output=True, text=True, timeout=600,
        )  # fmt: skip
        assert p.returncode == 1 and says in p.stderr and p.stderr.count("\n") == 1, (says, p.stderr)
        assert not (tmp_path / "x.pc2").exists()
    # every rotation one more full turn about its own axis: the same motion
    a = {k: v.copy() for k, v in arrays.items()}
    r = a["poses"].astype(np.float64)
    t = np.linalg.norm(r, axis=-1, keepdims=True)
    a["poses"] = (r + np.where(t > 1e-6, r / np.maximum(t, 1e-12), 0.0) * 2 * np.pi).astype(np.float32)
    write_bundle(tmp_path / "turned.sgdm", a, meta)
    outs = {}
    for name, motion in (("plain", s["motion"]), ("turned", tmp_path / "turned.sgdm")):
        p = subprocess.run(
            [*base, "--garment", str(s["garment"]), "--motion", str(motion), "-o", str(tmp_path / f"{name}.pc2")],
            capture_output=True, text=True, timeout=600,
        )  # fmt: skip
        assert p.returncode == 0, p.stderr
        outs[name] = read_pc2(tmp_path / f"{name}.pc2").frames
    py = tmp_path / "py.pc2"
    args = ["--garment", str(s["garment"]), "--motion", str(tmp_path / "turned.sgdm"), "--model", str(random_package)]
    args.append("--force")  # (the portable garment is exported for betas its OBJ was not made for)
    assert main(["run", *args, "-o", str(py)]) == 0
    gap = float(np.abs(outs["turned"] - read_pc2(py).frames).max())
    print(f"{runtime}: turned vs plain {np.abs(outs['turned'] - outs['plain']).max():.3g} m, vs Python {gap:.3g} m")
    assert gap <= 1e-5 * np.abs(outs["turned"]).max()  # the runtime writes every rotation as Python does
    # and the turned motion is the plain one, up to the float32 rounding of the turned angles (1.7 cm before)
    assert np.abs(outs["turned"] - outs["plain"]).max() < 5e-3


@pytest.mark.parametrize("runtime", ["node", "cpp", "api"])
def test_an_asset_exported_with_force_is_refused_unless_forced_again(runtime, request, random_package, tmp_path):
    """A garment 1 m beside the body, exported with `garment export --force`: `segadeform run` refuses the asset
    (it checks the fit itself), Node and C++ played it silently (a runtimes trial).  The asset now records why it
    needed --force (meta.body.unfit); every runtime refuses it, naming that, unless forced again (then warned)."""
    from segadeform.cli.main import main
    from segadeform.io import Mesh, read_mesh, write_obj

    m = read_mesh(SAMPLES / "garments" / "skirt.obj")
    write_obj(tmp_path / "off.obj", Mesh(m.vertices + np.array([1.0, 0.0, 0.0]), m.faces))
    g, mo = tmp_path / "off.sgda", tmp_path / "m.sgdm"
    export = ["garment", "export", str(tmp_path / "off.obj"), "--model", str(random_package), "-o", str(g)]
    assert main(export) == 1 and not g.exists()
    assert main([*export, "--force"]) == 0
    assert main(["motion", "export", "walk", "--seconds", "0.2", "-o", str(mo)]) == 0
    assert main(["run", "--garment", str(g), "--motion", str(mo), "--model", str(random_package), "-o",
                 str(tmp_path / "py.pc2")]) == 1  # fmt: skip
    out = tmp_path / "o.pc2"
    if runtime == "api":
        got = _node_api_refused_then_forced(random_package, g, mo)
        assert "exported with --force although the garment does not sit on the body" in got["refused"]
        assert "force: true" in got["refused"] and got["T"] > 0 and any("--force" in w for w in got["warnings"])
        return
    exe = request.getfixturevalue(runtime)
    base = [*exe, "--package", str(random_package), "--garment", str(g), "--motion", str(mo), "-o", str(out)]
    p = subprocess.run(base, capture_output=True, text=True, timeout=600)
    assert p.returncode == 1 and not out.exists(), p.stdout + p.stderr
    assert f"{g}: the garment asset was exported with --force although the garment does not sit" in p.stderr
    assert "--force here too" in p.stderr and len(p.stderr.strip().splitlines()) == 1
    p = subprocess.run([*base, "--force"], capture_output=True, text=True, timeout=600)
    assert p.returncode == 0 and out.exists(), p.stdout + p.stderr
    assert "warning: the garment asset was exported with --force" in p.stderr


@pytest.mark.parametrize("runtime", ["node", "cpp"])
def test_collisions_on_a_clip_of_extreme_poses_give_segadeform_runs_frames(
    runtime, request, portable_scene, random_package, tmp_path, capsys
):
    """Node and C++ built the collider's tree from the clip's first posed frame, Python from the body at rest: the
    tree decides between equally near triangles, and on a clip of random joint rotations (limbs through each other)
    a user's trial found frames 2 cm apart (a 2,205-vertex suit, 120 frames: 2 vertex-frames; bit for bit after, by
    hand -- this small clip does not meet such a tie, so here it is parity on extreme poses).  Every runtime builds it
    from the body at rest as the run poses it; a clip whose every frame is a random pose plays Python's frames
    (collisions on).  A garment of many vertices: the runtimes lower the batch as Python does (MAX_VERTEX_FRAMES) and
    say so alike."""
    from segadeform.cli.main import main

    exe = request.getfixturevalue(runtime)
    s = portable_scene
    arrays, meta = read_bundle(s["motion"])
    rng = np.random.default_rng(7)
    a = {k: v.copy() for k, v in arrays.items()}
    axis = rng.normal(size=a["poses"].shape)
    axis /= np.linalg.norm(axis, axis=-1, keepdims=True)
    a["poses"] = (axis * rng.uniform(0.0, np.pi, size=a["poses"].shape[:-1] + (1,))).astype(np.float32)
    write_bundle(tmp_path / "wild.sgdm", a, meta)
    common = ["--garment", str(s["garment"]), "--motion", str(tmp_path / "wild.sgdm"), "--effects", "lbs,collisions"]
    assert main(["run", "--model", str(random_package), *common, "-o", str(tmp_path / "py.pc2"), "--no-cache"]) == 0
    p = subprocess.run(
        [*exe, "--package", str(random_package), *common, "-o", str(tmp_path / "rt.pc2")],
        capture_output=True, text=True, timeout=600,
    )  # fmt: skip
    assert p.returncode == 0, p.stderr
    want, got = read_pc2(tmp_path / "py.pc2").frames, read_pc2(tmp_path / "rt.pc2").frames
    assert _rel(got, want) <= RTOL, np.abs(got - want).max()
    # a garment over MAX_VERTEX_FRAMES / 8 vertices: the runtimes lower --batch 8 as segadeform run does (they ran 8
    # frames a call: 7 GB at 69k vertices, frames 1e-7 m apart, millimetres after a push-out)
    big = tmp_path / "big.obj"
    assert main(["garment", "make", "dress", "--betas", "0.5,-0.3", "--resolution", "8000", "-o", str(big)]) == 0
    export = ["garment", "export", str(big), "--betas", "0.5,-0.3", "--model", str(random_package)]
    assert main([*export, "-o", str(tmp_path / "big.sgda")]) == 0
    from segadeform.geometry import GarmentAsset

    n = GarmentAsset.load(tmp_path / "big.sgda").n_vertices
    assert n > 32768 // 8, n  # so batch 8 is lowered (10,318 vertices: 3 frames a call)
    common = ["--garment", str(tmp_path / "big.sgda"), "--motion", str(s["motion"]), "--effects", "lbs", "--batch", "8"]
    assert main(["run", "--model", str(random_package), *common, "-o", str(tmp_path / "pyb.pc2"), "--no-cache"]) == 0
    said = f"batch: {32768 // n} frames a call, not 8 (at most 32768 vertex-frames a call)"
    assert said in capsys.readouterr().out
    p = subprocess.run(
        [*exe, "--package", str(random_package), *common, "-o", str(tmp_path / "rtb.pc2")],
        capture_output=True, text=True, timeout=600,
    )  # fmt: skip
    assert p.returncode == 0, p.stderr
    assert said in p.stdout, p.stdout  # the same batch: they ran 8 frames a call
    np.testing.assert_array_equal(read_pc2(tmp_path / "rtb.pc2").frames, read_pc2(tmp_path / "pyb.pc2").frames)


def test_the_refusal_of_a_forced_asset_names_the_fit_of_its_mesh(tmp_path, capsys):
    """A skirt in centimetres exported with --force: `segadeform run` refused the asset advising `segadeform garment
    fit X100_FORCED.sgda -o FIXED.obj --units cm`, which fails (garment fit reads meshes, not assets: a new user's
    trial).  The advice names the mesh the asset was exported from, and then its export; followed, it runs."""
    from segadeform.cli.main import main
    from segadeform.io import Mesh, read_mesh, write_obj

    m = read_mesh(SAMPLES / "garments" / "skirt.obj")
    (tmp_path / "g").mkdir()
    mesh, forced = tmp_path / "g" / "x100.obj", tmp_path / "g" / "x100_forced.sgda"
    write_obj(mesh, Mesh(m.vertices * 100, m.faces))
    assert main(["garment", "export", str(mesh), "-o", str(forced), "--force"]) == 0
    motion = SAMPLES / "motions" / "walk.npz"
    capsys.readouterr()
    assert main(["run", "--garment", str(forced), "--motion", str(motion), "-o", str(tmp_path / "o.pc2")]) == 1
    err = capsys.readouterr().err
    assert (
        f"run `segadeform garment fit {mesh} -o FIXED.obj --units cm` on the mesh {forced} was exported from, then "
        "`segadeform garment export FIXED.obj -o ASSET.sgda`, or pass --force" in err
    ), err
    assert f"garment fit {forced}" not in err
    fixed, asset = tmp_path / "FIXED.obj", tmp_path / "ASSET.sgda"
    assert main(["garment", "fit", str(mesh), "-o", str(fixed), "--units", "cm"]) == 0
    assert main(["garment", "export", str(fixed), "-o", str(asset)]) == 0
    assert main(["run", "--garment", str(asset), "--motion", str(motion), "-o", str(tmp_path / "o.pc2")]) == 0


def test_cpp_library_says_its_numbers_as_written(cpp, portable_scene, random_package):
    """The library's refusals printed numbers with %f (an fps of 20000 as 20000.000000, a margin of 5 as 5.000000: a
    new user's trial): runtimes/cpp/test/player_test.cpp's checks of them, on the portable scene."""
    s = portable_scene
    test = Path(cpp[0]).with_name("segadeform-player-test")
    t = subprocess.run(
        [str(test), str(random_package), str(s["garment"]), str(s["motion"])],
        capture_output=True,
        text=True,
        timeout=600,
    )
    checks = t.stdout.splitlines()
    for name in (
        "trans beyond 10 km said as written",
        "an fps out of range said as written",
        "a margin out of range said as written",
        "a huge margin said as written",
    ):
        assert f"ok {name}" in checks, t.stdout + t.stderr
    assert t.returncode == 0 and all(ln.startswith("ok ") for ln in checks), t.stdout + t.stderr


def test_the_readme_says_what_effects_none_runs():
    """The README said `--effects none` turns every effect off; it runs LBS skinning (`run` prints `effects lbs`)."""
    from segadeform.settings import parse_effects

    e = parse_effects("none")
    assert e.label() == "lbs" and not (e.dynamics or e.wrinkles or e.collisions or e.cloth)
    text = " ".join((REPO / "README.md").read_text(encoding="utf-8").split())
    assert "`none`: every effect off" not in text
    assert "(`none`: LBS skinning alone, with dynamics, wrinkles, collisions and the cloth stage off" in text


def test_node_reads_a_motion_of_no_frames_as_such_and_says_nan_as_nan(node, tmp_path):
    """A web developer's trial: a well-formed motion file of 0 frames read as "bundle array poses does not fit the
    file" (its (0, 24, 3) shape was measured against the file's bytes), and an fps of NaN was said as "got null"."""
    meta = {"kind": "segadeform-motion", "schema_version": 1, "fps": 30.0, "name": "empty"}
    arrays = {"poses": np.zeros((0, 24, 3), np.float32), "trans": np.zeros((0, 3), np.float32)}
    write_bundle(tmp_path / "empty.sgdm", arrays, meta)
    core = (REPO / "runtimes" / "node" / "src").as_uri()
    script = (
        f"import {{ readMotion, checkOptions }} from {json.dumps(core + '/core.js')};\n"
        f"import {{ readBundle }} from {json.dumps(core + '/bundle.js')};\n"
        "const out = {};\n"
        "try { readMotion(readBundle(process.argv[1]), 'empty.sgdm'); } catch (e) { out.motion = e.message; }\n"
        "try { checkOptions({ fps: NaN }, ['fps'], 'Player.open'); } catch (e) { out.fps = e.message; }\n"
        "console.log('RESULT' + JSON.stringify(out));\n"
    )
    got = _node_result(script, tmp_path / "empty.sgdm")
    assert got["motion"] == "empty.sgdm: the motion has no frames (expected T >= 1, got [0,24,3])", got
    assert got["fps"].endswith("(expected 1..1000, got NaN)"), got


def test_a_manifest_naming_a_file_outside_the_package_is_refused_by_node_and_cpp(
    node, cpp, portable_scene, random_package, tmp_path
):
    """A security review: Node and C++ joined a graph's file name from manifest.json to the package folder unchecked:
    `../outside.onnx` ran a graph from outside the package, `../../dev/zero` read until Node aborted, a FIFO hung
    both.  They now hold the name to Python's rule (a plain .onnx name in the folder)."""
    import shutil

    from tests.runtimes.conftest import play

    for bad in ("../outside.onnx", "/dev/zero", "sub/x.onnx", ".hidden.onnx"):
        pkg = tmp_path / "pkg"
        shutil.rmtree(pkg, ignore_errors=True)
        shutil.copytree(random_package, pkg)
        m = json.loads((pkg / "manifest.json").read_text())
        m["graphs"]["garment_encoder"]["file"] = bad
        (pkg / "manifest.json").write_text(json.dumps(m))
        for exe in (node, cpp):
            p = play(exe, pkg, portable_scene["garment"], portable_scene["motion"], tmp_path / "o.pc2", timeout=120)
            assert p.returncode != 0 and "must be a .onnx file name in the package folder" in p.stderr, (exe, p.stderr)
            assert not (tmp_path / "o.pc2").exists()


def test_a_package_of_the_models_own_deformer_alone_says_how_to_get_the_others(
    node, cpp, portable_scene, random_package, tmp_path
):
    """An ML user's package exported --no-variants refused `--quality fast` with "no deformer for these effects" and
    no word of why; every runtime now says it has the model's own alone and how to export the others."""
    import shutil

    from tests.runtimes.conftest import play

    pkg = tmp_path / "pkg"
    shutil.copytree(random_package, pkg)
    m = json.loads((pkg / "manifest.json").read_text())
    m["graphs"] = {k: g for k, g in m["graphs"].items() if g["role"] != "deformer" or k == m["default_deformer"]}
    (pkg / "manifest.json").write_text(json.dumps(m))
    other = "dqs" if "lbs" in m["default_deformer"] else "lbs"
    for exe in (node, cpp):
        p = play(exe, pkg, portable_scene["garment"], portable_scene["motion"], tmp_path / "o.pc2", "--effects", other)
        assert p.returncode == 1 and "without --no-variants writes the others" in p.stderr, (exe, p.stderr)
        assert not (tmp_path / "o.pc2").exists()


def test_cpp_refuses_a_scene_bundle_whose_arrays_do_not_agree(cpp, shared_bundle, random_package, tmp_path):
    """A security review: the C++ bundle path read a 1-D nbr's missing second dimension from the heap and took 1-D
    poses into std::bad_alloc; it now checks a bundle's arrays as an asset's."""
    arrays, meta = read_bundle(shared_bundle)
    for name, bad in (("nbr", arrays["nbr"][:1, 0].copy()), ("poses", arrays["poses"].ravel().copy())):
        broken = dict(arrays, **{name: bad})
        f = tmp_path / f"bad_{name}.sgdb"
        write_bundle(f, broken, meta)
        p = subprocess.run(
            [*cpp, str(random_package), str(f), "-o", str(tmp_path / "o.pc2")],
            capture_output=True,
            text=True,
            timeout=120,
        )
        assert p.returncode != 0 and f"field '{name}' is missing or malformed" in p.stderr, p.stderr
    broken = dict(arrays, nbr=np.full_like(arrays["nbr"], len(arrays["rest"])))
    write_bundle(tmp_path / "far.sgdb", broken, meta)
    p = subprocess.run(
        [*cpp, str(random_package), str(tmp_path / "far.sgdb"), "-o", str(tmp_path / "o.pc2")],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert p.returncode != 0 and "nbr index out of range" in p.stderr, p.stderr
