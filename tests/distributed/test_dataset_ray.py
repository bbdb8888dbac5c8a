"""`dataset make` on Ray: the same dataset as the local pool, and a worker killed mid-task loses and
duplicates nothing (its task runs again and commits its sample once).  Needs the simulator."""

from __future__ import annotations

import json

import numpy as np
import pytest

from segadeform.cli.main import main
from segadeform.dataset import load_dataset_config, load_sample, make_dataset
from segadeform.distributed.executors import ExecutorError, LocalExecutor, make_executor

from ..conftest import SAMPLES
from ..dataset.test_dataset import _need_simulator
from .faults import DyingLocation, temporaries

# with --dist loadgroup (.ci/run) one worker runs this folder's tests, one after another, on one local Ray: each
# worker used to wait on another's lock for all of its Ray tests
pytestmark = pytest.mark.xdist_group("ray")

BODY = SAMPLES / "bodies" / "default_body.npz"

# two samples (one coarse skirt, two motions of 0.3 s), a couple of seconds each through Blender
TWO = """
[dataset]
fps = 30.0
seconds = 0.3

[quality]
max_strain = 2.0
max_penetrating = 0.02

[simulate]
effects = ["gravity", "body_collision", "bending", "air_damping"]
material = "cotton"
quality = 5
drape_seconds = 0.1
blend_seconds = 0.1

[[garments]]
kind = "skirt"
resolution = 600

[[bodies]]
betas = []

[[motions]]
kind = "walk"

[[motions]]
kind = "arm_swing"
seed = 1
"""
IDS = ["skirt-0__b0__arm_swing-s1", "skirt-0__b0__walk-s0"]
TIMING = ("seconds", "seconds_per_frame", "sim_seconds", "blender_info")  # wall times: differ between runs


@pytest.fixture(scope="module")
def config(tmp_path_factory):
    _need_simulator()
    p = tmp_path_factory.mktemp("cfg") / "two.toml"
    p.write_text(TWO)
    return p


@pytest.fixture(scope="module")
def local_dataset(config, tmp_path_factory):
    """The reference: the local pool, two processes."""
    out = tmp_path_factory.mktemp("local") / "ds"
    s = make_dataset(load_dataset_config(config), out, body_path=BODY, executor=LocalExecutor(2))
    assert s.planned == 2 and s.kept + s.rejected == 2
    return out


def _finished(root):
    out = {}
    for d in ("samples", "rejected"):
        for p in sorted((root / d).glob("*.json")) if (root / d).is_dir() else []:
            out[p.stem] = d
    return out


def _log_ids(root):
    return sorted(json.loads(line)["id"] for line in (root / "log.jsonl").read_text().splitlines() if line.strip())


def assert_same_dataset(a, b):
    """Every sample committed in one is committed in the other, with the same arrays and metadata (wall
    times aside); the garments and the config are the same files."""
    assert _finished(a) == _finished(b) and sorted(_finished(a)) == IDS
    for sid, d in _finished(a).items():
        ma, mb = (json.loads((r / d / f"{sid}.json").read_text()) for r in (a, b))
        assert {k: v for k, v in ma.items() if k not in TIMING} == {k: v for k, v in mb.items() if k not in TIMING}
        if d == "samples":
            sa, sb = load_sample(a, sid), load_sample(b, sid)
            for k in ("rest", "faces", "betas", "poses", "trans", "frames", "contact_p", "contact_n"):
                assert np.array_equal(getattr(sa, k), getattr(sb, k)), (sid, k)
    ga = sorted(p.name for p in (a / "garments").iterdir())
    assert ga == sorted(p.name for p in (b / "garments").iterdir()) and ga
    assert all((a / "garments" / n).read_bytes() == (b / "garments" / n).read_bytes() for n in ga)
    assert (a / "config.toml").read_bytes() == (b / "config.toml").read_bytes()
    assert temporaries(a) == [] and temporaries(b) == []


def test_ray_makes_the_same_dataset_as_the_local_pool(config, local_dataset, ray_cluster, tmp_path, capsys):
    out = tmp_path / "ray"  # through the fsspec path (file://), as an object store would be written
    assert main(["dataset", "make", str(config), "-o", f"file://{out}", "--executor", "ray", "-j", "2"]) == 0
    assert "2 planned, 0 already done" in capsys.readouterr().out
    assert_same_dataset(local_dataset, out)
    assert _log_ids(out) == IDS
    assert {json.loads(line)["executor"] for line in (out / "log.jsonl").read_text().splitlines()} == {"ray"}
    # resumed: nothing to do, nothing rewritten
    before = {p: p.stat().st_mtime_ns for p in out.rglob("*") if p.is_file() and p.name != "log.jsonl"}
    assert main(["dataset", "make", str(config), "-o", str(out), "--executor", "ray", "-j", "2"]) == 0
    assert "2 planned, 2 already done, 0 kept, 0 rejected" in capsys.readouterr().out
    changed = [p for p, t in before.items() if p.stat().st_mtime_ns != t]
    assert all(p.parent.name == "configs" or p.name == "config.toml" for p in changed), changed


def test_a_worker_killed_mid_task_loses_and_duplicates_nothing(config, local_dataset, ray_cluster, tmp_path):
    """Each sample's first attempt is killed while committing: one with its arrays written to a temporary
    but not renamed, the other with its arrays committed but not its metadata (the half-done state).
    Ray runs both tasks again; each sample is then committed once and the dataset equals the reference."""
    out = tmp_path / "ray-killed"
    loc = DyingLocation(out, tmp_path / "markers", die_at={f"samples/{IDS[0]}.npz", f"samples/{IDS[1]}.json"})
    kept = sorted(p.stem for p in (local_dataset / "samples").glob("*.json"))
    assert kept == IDS  # both kept in the reference, so both attempts reach the commit and die there
    with make_executor("ray", 2, max_retries=2) as ex:
        s = make_dataset(load_dataset_config(config), loc, body_path=BODY, executor=ex)
    assert loc.died() == [f"samples_{IDS[0]}.npz.died", f"samples_{IDS[1]}.json.died"]  # both attempts were killed
    assert sorted(r["id"] for r in s.records) == IDS and s.kept == 2  # nothing lost, nothing twice
    meta_commits = [c for c in loc.commits() if c.startswith("samples/") and c.endswith(".json")]
    assert sorted(meta_commits) == [f"samples/{i}.json" for i in IDS]  # each sample committed once
    assert _log_ids(out) == IDS
    assert_same_dataset(local_dataset, out)  # and no temporaries left


def test_the_local_pool_stops_on_a_killed_worker_and_a_rerun_completes(config, local_dataset, tmp_path, capsys):
    """The local pool has no retries: a killed worker ends the run with an error, and running the command
    again finishes the dataset, equal to the reference, with nothing left behind."""
    out = tmp_path / "local-killed"
    loc = DyingLocation(out, tmp_path / "markers", die_at={f"samples/{i}.json" for i in IDS})
    with pytest.raises(ExecutorError, match="worker process died"):
        make_dataset(load_dataset_config(config), loc, body_path=BODY, executor=LocalExecutor(2))
    assert loc.died()
    assert main(["dataset", "make", str(config), "-o", str(out), "-j", "2"]) == 0
    assert "2 planned, 0 already done, 2 kept" in capsys.readouterr().out
    assert_same_dataset(local_dataset, out)
