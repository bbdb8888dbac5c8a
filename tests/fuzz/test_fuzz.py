"""A short coverage-guided fuzz run of each reader (the long runs are documented in fuzz_readers.py)."""

import re
import subprocess
import sys
from pathlib import Path

import pytest

from tests.conftest import REPO
from tests.fuzz.fuzz_readers import TARGETS

HARNESS = Path(__file__).with_name("fuzz_readers.py")
RUNS = 4000

pytest.importorskip("atheris", reason="fuzzing needs the dev extra (atheris)")


@pytest.fixture(scope="module")
def seeds(tmp_path_factory):
    d = tmp_path_factory.mktemp("seeds")
    subprocess.run([sys.executable, str(HARNESS), "--seeds", str(d)], check=True, cwd=REPO)
    return d


@pytest.mark.parametrize("target", TARGETS)
def test_short_fuzz_run(target, seeds, tmp_path):
    corpus = tmp_path / "corpus"
    corpus.mkdir()
    for f in (seeds / target).iterdir():
        (corpus / f.name).write_bytes(f.read_bytes())
    # no -rss_limit_mb: Linux carries ru_maxrss over from the (pytest) parent across fork/exec, so
    # libFuzzer would see the suite's own peak (the 200k-vertex case) and stop at once.  Memory
    # blow-up is tested by the malformed corpus under an address-space limit.
    p = subprocess.run(
        [
            sys.executable,
            str(HARNESS),
            target,
            f"-runs={RUNS}",
            "-rss_limit_mb=0",
            f"-artifact_prefix={tmp_path}/crash-",
            str(corpus),
        ],
        capture_output=True,
        text=True,
        timeout=600,
        cwd=REPO,
    )
    crashes = list(tmp_path.glob("crash-*"))
    assert p.returncode == 0 and not crashes, (p.stdout + p.stderr)[-3000:]
    done = re.search(r"Done (\d+) runs", p.stdout + p.stderr)
    assert done and int(done.group(1)) >= RUNS


REGRESSIONS = sorted((Path(__file__).parent / "regressions").iterdir())


@pytest.mark.parametrize("path", REGRESSIONS, ids=[p.name for p in REGRESSIONS])
def test_fuzz_regressions(path):
    """Inputs that once crashed a reader (libFuzzer crash files): each must now give a clear error."""
    from tests.fuzz.fuzz_readers import make_target

    target = path.name.split("-")[0]
    make_target(target)(path.read_bytes())  # raises on anything but a SegadeformError
