"""`--threads` above the CPUs this process may use is lowered to them and said (1000 threads took about 6 s a frame
in a user's trial); the same frames as asking for that many."""

from __future__ import annotations

import os

import numpy as np
from click.testing import CliRunner

from segadeform.cli.main import cli, usable_threads
from segadeform.io import read_pc2

from ..conftest import SAMPLES


def _cpus() -> int:
    return len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count() or 1


def test_usable_threads_lowers_only_past_the_cpus():
    n = _cpus()
    assert usable_threads(1) == (1, "")
    assert usable_threads(n) == (n, "")
    assert usable_threads(n + 1) == (n, f"threads: {n}, not {n + 1} (the CPUs this process may use)")


def test_run_lowers_threads_to_the_cpus_and_says_so(tmp_path):
    n = _cpus()
    outs = {}
    for asked in (n, 4096):
        out = tmp_path / f"t{asked}.pc2"
        garment, motion = SAMPLES / "garments" / "dress.obj", SAMPLES / "motions" / "walk.npz"
        r = CliRunner().invoke(
            cli,
            ["run", "--garment", str(garment), "--motion", str(motion), "-o", str(out), "--frames", "0:3",
             "--no-cache", "--threads", str(asked)],
        )  # fmt: skip
        assert r.exit_code == 0, r.output
        assert (f"threads: {n}, not 4096 (the CPUs this process may use)" in r.output) == (asked == 4096), r.output
        outs[asked] = np.asarray(read_pc2(out).frames)
    np.testing.assert_array_equal(outs[n], outs[4096])  # the lowered run is a run on that many threads
