"""The shared test vectors every runtime is held to, and the runtimes' command lines (Node; C++, built once)."""

from __future__ import annotations

import shutil
import subprocess

import pytest

from tests.conftest import REPO, SAMPLES, made_once

NODE = REPO / "runtimes" / "node"


@pytest.fixture(scope="session")
def node():
    """`segadeform-node` (runtimes/node/src/cli.js) as an argv prefix."""
    if shutil.which("node") is None:
        pytest.fail("node is not on PATH (the project's runtimes need Node.js >= 18)")
    if not (NODE / "node_modules" / "onnxruntime-node").is_dir():
        pytest.fail(
            "runtimes/node has no node_modules: run `ONNXRUNTIME_NODE_INSTALL=skip npm ci` there (.ci/run does)"
        )
    return ["node", str(NODE / "src" / "cli.js")]


@pytest.fixture(scope="session")
def cpp(tmp_path_factory):
    """`segadeform-run` (runtimes/cpp, with the collision kernel src/segadeform/body/_collide.c), built once per
    test run by tools/onnxruntime_cpp.sh (:func:`tests.conftest.made_once`), as an argv prefix."""
    for tool in ("go", "cmake", "g++"):
        if shutil.which(tool) is None:
            pytest.fail(f"{tool} is not on PATH (building the C++ runtime needs go, cmake and g++)")

    def build(path):
        b = subprocess.run(
            [str(REPO / "tools" / "onnxruntime_cpp.sh"), str(path)], capture_output=True, text=True, timeout=900
        )
        assert b.returncode == 0, (b.stdout + b.stderr)[-3000:]

    exe = made_once(tmp_path_factory, "cpp-build", build) / "segadeform-run"  # the script's output
    assert exe.is_file(), exe
    return [str(exe)]


@pytest.fixture(scope="session")
def shared_bundle(tmp_path_factory, random_package):
    """A scene's bundle with the Python runtime's output: the test vector every runtime is held to."""
    from segadeform.runtime.scene_bundle import scene_bundle
    from segadeform.settings import load_scene

    d = tmp_path_factory.mktemp("bundle")
    scene = d / "s.toml"
    scene.write_text(
        f'[garment]\nmesh = "{SAMPLES / "garments" / "dress.obj"}"\n[motion]\nkind = "dance"\n'
        f'seconds = 0.4\nseed = 2\n[body]\nbetas = [0.5, -0.3]\n[output]\npath = "{d / "o.pc2"}"\n'
        '[effects]\nskinning = "dqs"\ndynamics = true\nwrinkles = true\n'
    )
    # force: the sample dress was made on the mean body; here it is only numbers to run, shaped by betas
    return scene_bundle(load_scene(scene), d / "s.sgdb", model=random_package, batch=5, force=True)


@pytest.fixture(scope="session")
def portable_scene(tmp_path_factory, random_package):
    """A garment and a motion as the runtimes without Python read them -- `segadeform garment export` and
    `segadeform motion export` -- and `segadeform run`'s frames of the same (garment and posed body): the test
    vector the Node, browser and C++ runtimes are held to.  Returns a dict of paths and the effects."""
    import numpy as np

    from segadeform.cli.main import main
    from segadeform.io import read_pc2
    from segadeform.io.sgdb import write_bundle

    d = tmp_path_factory.mktemp("portable")
    betas = "0.5,-0.3"
    # a dress made for the shape it is exported for (an asset exported with --force for a body it does not sit on is
    # refused by every runtime unless forced again, as `segadeform run` refuses it)
    assert main(["garment", "make", "dress", "--betas", betas, "-o", str(d / "dress_b.obj")]) == 0
    export = ["garment", "export", str(d / "dress_b.obj"), "--betas", betas, "--model", str(random_package)]
    assert main([*export, "-o", str(d / "garment.sgda")]) == 0
    assert (
        main(
            [
                "motion",
                "export",
                "dance",
                "--seconds",
                "0.4",
                "--seed",
                "2",
                "--betas",
                betas,
                "-o",
                str(d / "motion.sgdm"),
            ]
        )
        == 0
    )
    # the same garment and motion through `segadeform run` (Python): the asset, and the motion it was made from
    scene = d / "s.toml"
    scene.write_text(
        f'[garment]\nmesh = "{d / "garment.sgda"}"\n[motion]\nkind = "dance"\nseconds = 0.4\nseed = 2\n'
        f'[body]\nbetas = [0.5, -0.3]\n[output]\npath = "{d / "python.pc2"}"\n'
        f'body = "{d / "python_body.pc2"}"\n'
        '[effects]\nskinning = "dqs"\ndynamics = true\nwrinkles = true\n'
    )
    assert main(["run", str(scene), "--model", str(random_package), "--force", "--no-cache"]) == 0
    frames, body = read_pc2(d / "python.pc2").frames, read_pc2(d / "python_body.pc2").frames
    assert np.isfinite(frames).all() and np.isfinite(body).all()
    write_bundle(d / "check.sgdb", {"expected": frames, "body": body}, {"effects": "dqs,dynamics,wrinkles"})
    return {
        "dir": d,
        "garment": d / "garment.sgda",
        "motion": d / "motion.sgdm",
        "check": d / "check.sgdb",
        "frames": frames,
        "body": body,
        "effects": "dqs,dynamics,wrinkles",
    }


def play(exe, package, garment, motion, out, *more, timeout=600):
    """A runtime's command line (``exe``: the ``node`` or ``cpp`` fixture's argv) on a garment asset and a motion file,
    writing ``out``: the finished process (stdout and stderr as text)."""
    return subprocess.run(
        exe + ["--package", str(package), "--garment", str(garment), "--motion", str(motion), "-o", str(out), *more],
        capture_output=True,
        text=True,
        timeout=timeout,
    )
