"""A built wheel works outside the checkout: its default body and model are package data.

Builds the wheel, installs it (with its base dependencies from the package index, as a user would)
into a fresh virtual environment outside the repository, and runs ``segadeform run`` there with
only a garment and a motion file; its frames are the checkout's for the same command."""

from __future__ import annotations

import shutil
import subprocess
import sys

import numpy as np

from tests.conftest import REPO, SAMPLES


def test_wheel_runs_outside_the_checkout(tmp_path):
    wheels = tmp_path / "wheels"
    b = subprocess.run(
        [sys.executable, "-m", "pip", "wheel", str(REPO), "--no-deps", "--no-build-isolation", "-q", "-w", str(wheels)],
        capture_output=True,
        text=True,
        timeout=900,
    )
    assert b.returncode == 0, b.stderr[-2000:]
    whl = next(wheels.glob("segadeform-*.whl"))
    env_dir = tmp_path / "fresh"
    subprocess.run([sys.executable, "-m", "venv", str(env_dir)], check=True, timeout=300)
    py = env_dir / "bin" / "python"
    i = subprocess.run(
        [str(py), "-m", "pip", "install", "-q", "--disable-pip-version-check", str(whl)],
        capture_output=True,
        text=True,
        timeout=900,
    )
    assert i.returncode == 0, i.stderr[-2000:]
    work = tmp_path / "elsewhere"
    work.mkdir()
    shutil.copy(SAMPLES / "garments" / "dress.obj", work / "dress.obj")
    shutil.copy(SAMPLES / "motions" / "walk.npz", work / "walk.npz")
    where = subprocess.run(
        [str(py), "-c", "import segadeform; print(segadeform.__file__)"],
        cwd=work,
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert str(env_dir) in where.stdout and str(REPO) not in where.stdout
    r = subprocess.run(
        [
            str(env_dir / "bin" / "segadeform"),
            "run",
            "--garment",
            "dress.obj",
            "--motion",
            "walk.npz",
            "-o",
            "out.pc2",
            "--frames",
            "0:8",
            "--effects",
            "lbs,dynamics,wrinkles",
            "--no-cache",
        ],
        cwd=work,
        capture_output=True,
        text=True,
        timeout=600,
    )
    assert r.returncode == 0, r.stdout + r.stderr
    here = tmp_path / "checkout"
    here.mkdir()
    c = subprocess.run(
        [
            sys.executable,
            "-c",
            "import sys; from segadeform.cli.main import main; sys.exit(main())",
            "run",
            "--garment",
            str(work / "dress.obj"),
            "--motion",
            str(work / "walk.npz"),
            "-o",
            str(here / "out.pc2"),
            "--frames",
            "0:8",
            "--effects",
            "lbs,dynamics,wrinkles",
            "--no-cache",
        ],
        cwd=REPO,
        capture_output=True,
        text=True,
        timeout=600,
    )
    assert c.returncode == 0, c.stdout + c.stderr
    from segadeform.io import read_mesh, read_pc2

    wheel, checkout = read_pc2(work / "out.pc2"), read_pc2(here / "out.pc2")
    n = len(read_mesh(SAMPLES / "garments" / "dress.obj").vertices)
    assert wheel.frames.shape == checkout.frames.shape == (8, n, 3)
    # the same code and model; the fresh environment may resolve other numpy/onnxruntime builds
    np.testing.assert_allclose(wheel.frames, checkout.frames, rtol=0, atol=1e-5)
    assert np.ptp(checkout.frames, axis=0).max() > 1e-3  # the garment moves: frames that differ are caught


def test_every_python_package_is_listed_for_the_wheel():
    """pyproject's explicit package list names every folder with an ``__init__.py`` (a new subpackage left out
    installs from the checkout but is missing from the wheel: ``segadeform.body.collision`` once was)."""
    import tomllib

    cfg = tomllib.loads((REPO / "pyproject.toml").read_text())["tool"]["setuptools"]
    dirs = {k: REPO / v for k, v in cfg["package-dir"].items()}
    found = set()
    for root_name in ("segadeform", "segadeform.cli", "segadeform.export", "segadeform.runtime"):
        root = dirs[root_name]
        for init in root.rglob("__init__.py"):
            rel = init.parent.relative_to(root)
            found.add(".".join((root_name, *rel.parts)))
    listed = set(cfg["packages"])
    assert found - listed == set(), f"packages missing from pyproject.toml: {sorted(found - listed)}"
    assert listed - found == set(), f"listed packages with no __init__.py: {sorted(listed - found)}"
