"""A full disk and a read-only folder (issue 29, item 5): `run`, `batch` and `dataset make` run in a child process
with a file-size limit (``ulimit -f``: writes past it fail with EFBIG, as on a full disk) or against a read-only
output folder.  The error is one line naming the output, nothing partial is left (no output, no temporary), the
user's files are untouched, and a resumable job resumes once space is freed.

Root ignores file permissions; as root the read-only case drops CAP_DAC_OVERRIDE from the child (``setpriv``),
so the folder is read-only for it as for any user.  A real full file system (a 64 KiB tmpfs) is tried where
this process may mount one.
"""

from __future__ import annotations

import os
import resource
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from ..conftest import REPO, SAMPLES

SKIRT = SAMPLES / "garments" / "skirt.obj"
WALK = SAMPLES / "motions" / "walk.npz"
FILE_LIMIT = 48 * 1024  # bytes: a 1,536-vertex frame is 18 KiB, the run writes 9 of them


def segadeform(args, *, cwd, fsize=None, read_only=False):
    """Run the CLI in a child; ``fsize``: RLIMIT_FSIZE in bytes; ``read_only``: without CAP_DAC_OVERRIDE."""
    cmd = [
        sys.executable,
        "-c",
        "import sys; from segadeform.cli.main import main; sys.exit(main(sys.argv[1:]))",
        *map(str, args),
    ]
    if read_only and os.geteuid() == 0:
        if shutil.which("setpriv") is None:
            pytest.skip("running as root without setpriv: a read-only folder is writable")
        caps = "-dac_override,-dac_read_search"
        cmd = ["setpriv", "--bounding-set", caps, "--inh-caps", caps, *cmd]

    def limit():
        if fsize is not None:
            resource.setrlimit(resource.RLIMIT_FSIZE, (fsize, fsize))

    return subprocess.run(
        cmd,
        cwd=cwd,
        capture_output=True,
        text=True,
        timeout=900,
        preexec_fn=limit,
        env=dict(os.environ, PYTHONPATH=str(REPO)),
    )


def temporaries(d: Path) -> list[str]:
    return sorted(str(p) for p in Path(d).rglob("*") if ".tmp-" in p.name)


def one_error(r, *words):
    assert r.returncode == 1, (r.returncode, r.stdout, r.stderr)
    lines = [ln for ln in r.stderr.strip().splitlines() if ln.startswith("Error:")]
    assert len(lines) == 1 and "Traceback" not in r.stderr, r.stderr
    for w in words:
        assert w in lines[0], (w, lines[0])
    return lines[0]


def user_folder(tmp_path) -> Path:
    d = tmp_path / "out"
    d.mkdir()
    (d / "notes.txt").write_text("a user's notes")
    return d


def test_run_on_a_full_disk_names_the_output_and_leaves_nothing(tmp_path):
    d = user_folder(tmp_path)
    args = ["run", "--garment", SKIRT, "--motion", WALK, "--frames", "0:9", "--no-cache"]
    r = segadeform(args + ["-o", d / "x.pc2", "--body-out", d / "body.pc2"], cwd=tmp_path, fsize=FILE_LIMIT)
    one_error(r, f"{d / 'x.pc2'}: cannot write", "file-size limit")
    assert sorted(p.name for p in d.iterdir()) == ["notes.txt"]  # no output, no temporary, no manifest
    r = segadeform(args + ["--format", "obj-seq", "-o", d / "seq"], cwd=tmp_path, fsize=FILE_LIMIT)
    one_error(r, f"{d / 'seq'}: cannot write", "file-size limit")
    assert sorted(p.name for p in d.iterdir()) == ["notes.txt"]
    r = segadeform(args + ["-o", d / "x.pc2"], cwd=tmp_path)  # space again
    assert r.returncode == 0, r.stderr
    assert (d / "notes.txt").read_text() == "a user's notes" and not temporaries(d)


def test_batch_on_a_full_disk_resumes_after_space_is_freed(tmp_path):
    jobs = tmp_path / "jobs.toml"
    jobs.write_text(
        f'[batch]\noutput = "out"\n[[garments]]\nmesh = "{SKIRT}"\n'
        '[[motions]]\nkind = "walk"\nseconds = 0.3\n[[motions]]\nkind = "dance"\nseconds = 0.3\n'
    )
    out = tmp_path / "out"
    r = segadeform(["batch", jobs, "--limit", "1"], cwd=tmp_path)
    assert r.returncode == 0, r.stderr
    done = sorted(p.name for p in (out / "jobs").iterdir())
    assert len(done) == 1
    r = segadeform(["batch", jobs], cwd=tmp_path, fsize=FILE_LIMIT)
    todo = "skirt__walk" if done == ["skirt__dance.json"] else "skirt__dance"
    one_error(r, f"{out / (todo + '.pc2')}: cannot write", "file-size limit")
    assert not temporaries(out) and not (out / f"{todo}.pc2").exists()
    assert sorted(p.name for p in (out / "jobs").iterdir()) == done
    r = segadeform(["batch", jobs], cwd=tmp_path)
    assert r.returncode == 0, r.stderr
    assert "2 jobs, 1 already done, 1 made" in r.stdout
    assert (out / f"{todo}.pc2").is_file() and not temporaries(out)


def _need_simulator():
    from segadeform.errors import SimulationError
    from segadeform.physics import find_sim_python

    try:
        find_sim_python()
    except SimulationError as e:
        pytest.skip(f"no simulator environment here ({e})")


def test_dataset_make_on_a_full_disk_resumes_after_space_is_freed(tmp_path):
    _need_simulator()
    out = tmp_path / "ds"
    tiny = SAMPLES / "datasets" / "tiny.toml"
    r = segadeform(["dataset", "make", tiny, "-o", out, "--limit", "1"], cwd=tmp_path, fsize=16 * 1024)
    line = one_error(r, "cannot write", "file-size limit")
    assert str(out / "garments") in line  # the first large file: a garment mesh
    assert not temporaries(out)
    assert not list((out / "samples").glob("*")) if (out / "samples").is_dir() else True
    r = segadeform(["dataset", "make", tiny, "-o", out, "--limit", "1"], cwd=tmp_path)
    assert r.returncode == 0, r.stderr
    made = list((out / "samples").glob("*.json")) + list((out / "rejected").glob("*.json"))
    assert len(made) == 1 and not temporaries(out)


def read_only_folder(tmp_path) -> Path:
    d = user_folder(tmp_path)
    d.chmod(0o555)
    return d


@pytest.fixture
def restore_modes(tmp_path):
    yield
    for p in [tmp_path, *tmp_path.rglob("*")]:
        if p.is_dir():
            p.chmod(0o755)


def test_a_read_only_output_folder_is_named(tmp_path, restore_modes):
    d = read_only_folder(tmp_path)
    r = segadeform(
        ["run", "--garment", SKIRT, "--motion", WALK, "--frames", "0:2", "--no-cache", "-o", d / "x.pc2"],
        cwd=tmp_path,
        read_only=True,
    )
    one_error(r, f"{d / 'x.pc2'}: cannot write", "permission denied")
    jobs = tmp_path / "jobs.toml"
    jobs.write_text(f'[[garments]]\nmesh = "{SKIRT}"\n[[motions]]\nkind = "walk"\nseconds = 0.2\n')
    r = segadeform(["batch", jobs, "-o", d, "--force"], cwd=tmp_path, read_only=True)
    one_error(r, f"{d}: cannot write", "permission denied")
    r = segadeform(
        ["dataset", "make", SAMPLES / "datasets" / "tiny.toml", "-o", d, "--force"], cwd=tmp_path, read_only=True
    )
    one_error(r, f"{d}: cannot write", "permission denied")
    assert sorted(p.name for p in d.iterdir()) == ["notes.txt"]


@pytest.fixture
def tiny_tmpfs(tmp_path):
    """A 64 KiB tmpfs mounted at tmp_path/disk (skipped where this process may not mount)."""
    d = tmp_path / "disk"
    d.mkdir()
    if os.geteuid() != 0 or shutil.which("mount") is None:
        pytest.skip("mounting a tmpfs needs root")
    r = subprocess.run(["mount", "-t", "tmpfs", "-o", "size=64k", "tmpfs", str(d)], capture_output=True, text=True)
    if r.returncode != 0:
        pytest.skip(f"cannot mount a tmpfs here: {r.stderr.strip()}")
    try:
        yield d
    finally:
        subprocess.run(["umount", str(d)], check=True)


def test_run_on_a_really_full_disk(tiny_tmpfs, tmp_path):
    (tiny_tmpfs / "notes.txt").write_text("notes")
    r = segadeform(
        ["run", "--garment", SKIRT, "--motion", WALK, "--frames", "0:9", "--no-cache", "-o", tiny_tmpfs / "x.pc2"],
        cwd=tmp_path,
    )
    one_error(r, f"{tiny_tmpfs / 'x.pc2'}: cannot write", "no space left on the device")
    assert sorted(p.name for p in tiny_tmpfs.iterdir()) == ["notes.txt"]
