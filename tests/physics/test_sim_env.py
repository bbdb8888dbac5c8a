"""The simulator environment made on a worker's first use: once per machine, under a lock, and only
where none is found."""

from __future__ import annotations

import multiprocessing as mp
import os
import time
from pathlib import Path

import pytest

from segadeform.errors import SimulationError
from segadeform.physics import blender
from segadeform.physics.setup import ensure_sim_python, worker_env_path


def _fake_setup(target):
    """Stands in for `setup_sim_env` (which installs bpy): slow, counted, makes bin/python."""
    target = Path(target)
    with open(target.parent / "setups.txt", "a") as fh:
        fh.write(f"{os.getpid()}\n")
    time.sleep(0.5)
    (target / "bin").mkdir(parents=True, exist_ok=True)
    exe = target / "bin" / "python"
    exe.write_text("#!/bin/sh\n")
    exe.chmod(0o755)
    return exe


def _broken_setup(target):
    raise OSError("no python3.11 here")


def _ensure(target, checkout, q):
    """In a fresh process: a machine without a simulator environment, asking for one."""
    os.environ.pop("SEGADEFORM_SIM_PYTHON", None)
    blender._repo_root = lambda: checkout
    q.put(str(ensure_sim_python(target=target, setup=_fake_setup)))


@pytest.fixture
def no_sim_env(monkeypatch, tmp_path):
    """A machine without a simulator environment: no variable, no .venv-sim in the checkout."""
    monkeypatch.delenv("SEGADEFORM_SIM_PYTHON", raising=False)
    monkeypatch.setattr(blender, "_repo_root", lambda: tmp_path / "checkout")


def test_made_once_per_machine_by_concurrent_workers(no_sim_env, tmp_path):
    target = tmp_path / "envs" / "sim"
    ctx = mp.get_context("spawn")
    q = ctx.Queue()
    procs = [ctx.Process(target=_ensure, args=(target, tmp_path / "checkout", q)) for _ in range(3)]
    for p in procs:
        p.start()
    for p in procs:
        p.join(60)
    assert [p.exitcode for p in procs] == [0, 0, 0]
    assert sorted(q.get(timeout=5) for _ in procs) == [str(target / "bin" / "python")] * 3
    assert len((tmp_path / "envs" / "setups.txt").read_text().split()) == 1  # one of them made it
    assert ensure_sim_python(target=target, setup=_broken_setup) == target / "bin" / "python"  # made: not again


def test_a_failed_setup_is_an_error_and_tried_again_next_time(no_sim_env, tmp_path):
    target = tmp_path / "envs" / "sim"
    with pytest.raises(SimulationError, match="could not make the simulator environment .* got no python3.11"):
        ensure_sim_python(target=target, setup=_broken_setup)
    assert not (target / ".segadeform-ready").exists()
    assert ensure_sim_python(target=target, setup=_fake_setup).is_file()


def test_an_existing_environment_is_used_and_a_named_missing_one_is_not_made(monkeypatch, tmp_path):
    exe = _fake_setup(tmp_path / "given")
    assert ensure_sim_python(exe, setup=_broken_setup) == exe
    monkeypatch.setenv("SEGADEFORM_SIM_PYTHON", str(tmp_path / "nowhere" / "python"))
    with pytest.raises(SimulationError, match="does not exist"):
        ensure_sim_python(target=tmp_path / "envs" / "sim", setup=_fake_setup)
    assert not (tmp_path / "envs").exists()


def test_the_default_place_is_the_user_cache_named_by_the_pinned_requirements(monkeypatch, tmp_path):
    monkeypatch.setenv("SEGADEFORM_CACHE_DIR", str(tmp_path / "cache"))
    p = worker_env_path()
    assert p.parent == tmp_path / "cache" and p.name.startswith("sim-env-")
