"""Packages whose graphs change inside but keep one network's interface, through the Node, C++ and browser runtimes:
the same frames as `segadeform run` (Python), with no change to any runtime.

* ``ensemble``: two networks averaged (`segadeform ensemble`);
* ``heading``: the motion processors read the root's rotation relative to the heading (``motion_input``)."""

from __future__ import annotations

import subprocess

import numpy as np
import pytest

from segadeform.io import read_pc2

RTOL = 1e-5


@pytest.fixture(scope="module", params=["ensemble", "heading"])
def ensemble_scene(request, tmp_path_factory, portable_scene):
    from segadeform.cli.main import main

    pkg = request.getfixturevalue(f"{request.param}_model")[1]  # tests/conftest.py: made once per run
    d = tmp_path_factory.mktemp(request.param)
    s = portable_scene
    scene = d / "s.toml"
    scene.write_text((s["dir"] / "s.toml").read_text().replace(str(s["dir"] / "python"), str(d / "python")))
    assert main(["run", str(scene), "--model", str(pkg), "--force", "--no-cache"]) == 0
    frames = read_pc2(d / "python.pc2").frames
    # the variant's frames are not the portable scene's network's (else the test could not tell them apart)
    assert np.abs(frames - s["frames"]).max() > 1e-3
    from segadeform.io.sgdb import write_bundle

    body = read_pc2(d / "python_body.pc2").frames
    write_bundle(d / "check.sgdb", {"expected": frames, "body": body}, {"effects": s["effects"]})
    return {"pkg": pkg, "frames": frames, "check": d / "check.sgdb"}


@pytest.mark.parametrize("runtime", ["node", "cpp"])
def test_an_ensemble_package_runs_in_node_and_cpp_as_in_python(
    runtime, request, portable_scene, ensemble_scene, tmp_path
):
    exe = request.getfixturevalue(runtime)
    s = portable_scene
    p = subprocess.run(
        exe
        + ["--package", str(ensemble_scene["pkg"]), "--garment", str(s["garment"]), "--motion", str(s["motion"])]
        + ["--effects", s["effects"], "-o", str(tmp_path / "g.pc2")],
        capture_output=True,
        text=True,
        timeout=600,
    )
    assert p.returncode == 0, p.stderr
    got, want = read_pc2(tmp_path / "g.pc2").frames, ensemble_scene["frames"]
    assert got.shape == want.shape and np.isfinite(got).all()
    assert np.abs(got - want).max() / np.abs(want).max() <= RTOL


def test_an_ensemble_package_runs_in_the_browser_page_as_in_python(portable_scene, ensemble_scene, tmp_path):
    """The viewer page (headless Chromium, onnxruntime-web on wasm) on the ensemble package."""
    from tests.conftest import REPO
    from tests.runtimes.test_web import _assert_matches, _asset_args, _page

    site = tmp_path / "site"
    site.mkdir()
    (site / "runtimes").symlink_to(REPO / "runtimes")
    (site / "pkg").symlink_to(ensemble_scene["pkg"])
    (site / "check.sgdb").symlink_to(ensemble_scene["check"])
    for k in ("garment", "motion"):
        (site / portable_scene[k].name).symlink_to(portable_scene[k])
    r = _page(site, "wasm", tmp_path, *_asset_args("check.sgdb", portable_scene["effects"]), shot=False)
    _assert_matches(r, len(ensemble_scene["frames"]), "wasm")
