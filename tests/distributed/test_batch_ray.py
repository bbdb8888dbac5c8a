"""`segadeform batch` on Ray: the same outputs as the local pool, and jobs whose worker is killed
mid-commit run again and commit once."""

from __future__ import annotations

import json

import pytest

from segadeform.cli.main import main
from segadeform.distributed.executors import make_executor
from segadeform.runtime.batch import load_batch, run_batch

from ..python_runtime.test_batch import IDS, JOBS
from .faults import DyingLocation, temporaries

# with --dist loadgroup (.ci/run) one worker runs this folder's tests, one after another, on one local Ray: each
# worker used to wait on another's lock for all of its Ray tests
pytestmark = pytest.mark.xdist_group("ray")


def _outputs(root):
    return {p.relative_to(root).as_posix(): p.read_bytes() for p in sorted(root.rglob("*.pc2"))}


def _records(root):
    keep = ("id", "garment", "motion", "spec", "output", "files", "frames", "effects", "graph")
    return {
        p.stem: {k: v for k, v in json.loads(p.read_text()).items() if k in keep}
        for p in (root / "jobs").glob("*.json")
    }


def test_batch_on_ray_equals_the_local_pool_and_survives_killed_workers(ray_cluster, tmp_path, capsys):
    jf = tmp_path / "jobs.toml"
    jf.write_text(JOBS)
    assert main(["batch", str(jf), "-o", str(tmp_path / "local"), "-j", "2"]) == 0
    assert main(["batch", str(jf), "-o", f"file://{tmp_path / 'ray'}", "--executor", "ray", "-j", "2"]) == 0
    assert "4 jobs, 0 already done, 4 made" in capsys.readouterr().out
    local, ray = tmp_path / "local", tmp_path / "ray"
    assert sorted(_outputs(local)) == [f"{i}.pc2" for i in IDS] and _outputs(ray) == _outputs(local)
    assert _records(ray) == _records(local)
    # killed: one job after its output was committed but before its record, one while committing its output
    loc = DyingLocation(
        tmp_path / "killed", tmp_path / "markers", die_at={"jobs/skirt__walk.json", "big-skirt__dance.pc2"}
    )
    with make_executor("ray", 2, max_retries=2) as ex:
        s = run_batch(load_batch(jf), out=loc, executor=ex)
    assert loc.died() == ["big-skirt__dance.pc2.died", "jobs_skirt__walk.json.died"]
    assert sorted(r["id"] for r in s.records) == IDS and s.made == 4
    records = sorted(c for c in loc.commits() if c.startswith("jobs/") and c.endswith(".json"))
    assert records == [f"jobs/{i}.json" for i in IDS]  # once each
    assert not list((loc.root / "jobs").glob("*.partial"))  # each job's marker removed after its record
    assert _outputs(loc.root) == _outputs(local) and _records(loc.root) == _records(local)
    assert temporaries(loc.root) == []
