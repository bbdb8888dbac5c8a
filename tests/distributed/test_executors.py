"""Executors: the spec each --executor value gives, the local pool, and Ray (results, errors, retries
of a dead worker, the workers limit)."""

from __future__ import annotations

import os
import sys
import time
from pathlib import Path

import pytest

from segadeform.distributed.executors import ExecutorError, LocalExecutor, RayExecutor, make_executor
from segadeform.errors import InputError

# with --dist loadgroup (.ci/run) one worker runs this folder's tests, one after another, on one local Ray: each
# worker used to wait on another's lock for all of its Ray tests
pytestmark = pytest.mark.xdist_group("ray")


def _square(x):
    return x * x


def _fail_on_three(x):
    if x == 3:
        raise InputError("three is not allowed", expected="not 3", got=x)
    return x


def _die_once(task):
    """Task (marker folder, x): the first attempt for each x ends its worker process (as a kill)."""
    markers, x = task
    try:
        os.close(os.open(Path(markers) / f"{x}.died", os.O_CREAT | os.O_EXCL | os.O_WRONLY))
    except FileExistsError:
        return x * 10
    os._exit(3)


def _die_always(x):
    os._exit(3)


def _timed(task):
    """Task (folder, x): records when it ran, for the workers limit."""
    folder, x = task
    t0 = time.time()
    time.sleep(1.5)  # long against a worker's start on a loaded machine (0.6 s once ran two workers' tasks in turn)
    (Path(folder) / f"{x}.txt").write_text(f"{t0} {time.time()}")
    return x


@pytest.mark.parametrize(
    "spec, kind, address",
    [
        ("local", LocalExecutor, None),
        ("ray", RayExecutor, None),
        ("ray://head:10001", RayExecutor, "ray://head:10001"),
        ("ray:auto", RayExecutor, "auto"),
        ("ray:10.0.0.1:6379", RayExecutor, "10.0.0.1:6379"),
    ],
)
def test_specs(spec, kind, address):
    ex = make_executor(spec, 3)
    assert type(ex) is kind and ex.workers == 3
    if kind is RayExecutor:
        assert ex.address == address and ex.remote
    else:
        assert not ex.remote


@pytest.mark.parametrize("spec", ["", "dask", "ray:", "ray://", "Local", "ray:/x"])
def test_bad_specs_say_what_is_expected(spec):
    with pytest.raises(InputError, match="expected local .* ray://HOST:PORT"):
        make_executor(spec)


def test_bad_worker_counts():
    with pytest.raises(InputError, match="at least 1"):
        make_executor("local", 0)
    with pytest.raises(InputError, match="at least 1"):
        make_executor("ray", 0)


@pytest.mark.parametrize("workers", [1, 2])
def test_local_pool(workers):
    ex = LocalExecutor(workers)
    assert sorted(ex.map_unordered(_square, range(6))) == [0, 1, 4, 9, 16, 25]
    with pytest.raises(InputError, match="three is not allowed"):
        list(ex.map_unordered(_fail_on_three, range(5)))


def test_local_pool_reports_a_killed_worker(tmp_path):
    with pytest.raises(ExecutorError, match="worker process died"):
        list(LocalExecutor(2).map_unordered(_die_once, [(tmp_path, i) for i in range(2)]))


def test_ray_missing_says_how_to_install(monkeypatch):
    monkeypatch.setitem(sys.modules, "ray", None)  # import ray -> ImportError
    with pytest.raises(ExecutorError, match=r"expected ray installed: pip install segadeform\[ray\]"):
        list(make_executor("ray", 2).map_unordered(_square, [1]))


def test_ray_results_and_errors(ray_cluster):
    ex = make_executor("ray", 2)
    assert sorted(ex.map_unordered(_square, range(6))) == [0, 1, 4, 9, 16, 25]
    # no workers limit: as many as the cluster runs (a window of twice its CPUs submitted)
    assert sorted(make_executor("ray").map_unordered(_square, range(10))) == [i * i for i in range(10)]
    assert list(ex.map_unordered(_square, [])) == []
    with pytest.raises(InputError, match="three is not allowed") as e:  # the task's own error, not retried
        list(ex.map_unordered(_fail_on_three, range(5)))
    assert str(e.value) == "three is not allowed (expected not 3, got 3)"
    ex.close()
    assert ray_cluster.is_initialized()  # a connection made by someone else is left open


def test_ray_runs_a_task_again_when_its_worker_dies(ray_cluster, tmp_path):
    ex = make_executor("ray", 2, max_retries=2)
    out = list(ex.map_unordered(_die_once, [(tmp_path, i) for i in range(4)]))
    assert sorted(out) == [0, 10, 20, 30]  # each exactly once
    assert sorted(p.name for p in tmp_path.glob("*.died")) == [f"{i}.died" for i in range(4)]  # each died once


def test_ray_gives_up_after_the_retries(ray_cluster):
    with pytest.raises(ExecutorError, match="did not finish on Ray .* 1 retries"):
        list(make_executor("ray", 2, max_retries=1).map_unordered(_die_always, [0]))


@pytest.mark.parametrize("workers, overlap", [(1, False), (2, True)])
def test_ray_keeps_to_the_workers_limit(ray_cluster, tmp_path, workers, overlap):
    assert sorted(make_executor("ray", workers).map_unordered(_timed, [(tmp_path, i) for i in range(4)])) == [
        0,
        1,
        2,
        3,
    ]
    spans = sorted(tuple(map(float, p.read_text().split())) for p in tmp_path.glob("*.txt"))
    overlapping = any(b[0] < a[1] for a, b in zip(spans, spans[1:], strict=False))
    assert overlapping == overlap
