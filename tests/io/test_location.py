"""Locations: a local folder and fsspec URLs (memory://, file://) commit every file whole, once when
asked, list no temporaries, and clean up after a killed writer."""

from __future__ import annotations

import os
import pickle
import sys
import uuid

import pytest

from segadeform.errors import InputError, SegadeformError
from segadeform.io.atomic import atomic_path
from segadeform.io.location import FsspecLocation, LocalLocation, open_location


@pytest.fixture(params=["local", "file", "memory"])
def loc(request, tmp_path):
    if request.param == "local":
        return open_location(tmp_path / "out")
    pytest.importorskip("fsspec")
    if request.param == "file":
        return open_location(f"file://{tmp_path}/out")
    return open_location(f"memory://segadeform-test-{uuid.uuid4().hex}/out")


def test_kinds():
    assert isinstance(open_location("a/b"), LocalLocation)
    pytest.importorskip("fsspec")
    assert isinstance(open_location("memory://x/y"), FsspecLocation)
    with pytest.raises(InputError, match="expected a path, or a URL of a protocol fsspec knows"):
        open_location("nosuchprotocol://bucket/x")


def test_commit_read_list(loc):
    assert not loc.exists("samples/a.json") and loc.listdir("samples") == []
    with loc.writing("samples/a.npz") as tmp:
        tmp.write_bytes(b"arrays")
        assert not loc.exists("samples/a.npz")  # nothing is there before the commit
    assert loc.put_bytes("samples/a.json", b"{}", once=True)
    assert loc.read_bytes("samples/a.npz") == b"arrays" and loc.read_text("samples/a.json") == "{}"
    assert loc.listdir("samples") == ["a.json", "a.npz"]


def test_once_keeps_the_first(loc):
    assert loc.put_bytes("jobs/x.json", b"first", once=True)
    assert not loc.put_bytes("jobs/x.json", b"second", once=True)
    assert loc.read_bytes("jobs/x.json") == b"first"
    assert loc.put_bytes("jobs/x.json", b"third")  # without once: replaced
    assert loc.read_bytes("jobs/x.json") == b"third"
    assert loc.listdir("jobs") == ["x.json"]


def test_a_failed_write_leaves_nothing(loc):
    with pytest.raises(RuntimeError):
        with loc.writing("samples/b.npz") as tmp:
            tmp.write_bytes(b"half")
            raise RuntimeError("killed")
    assert not loc.exists("samples/b.npz") and loc.listdir("samples") == []
    assert loc.remove_temporaries("samples/b.npz") == 0


def test_temporaries_of_a_killed_writer_are_removed_and_never_listed(loc, tmp_path):
    loc.put_bytes("samples/c.npz", b"old")
    # what a writer killed between upload and rename leaves: a temporary beside the target
    if isinstance(loc, LocalLocation):
        (loc.root / "samples" / ".c.npz.tmp-0123").write_bytes(b"partial")
    else:
        loc.fs.pipe_file(loc.key("samples/.c.npz.tmp-0123"), b"partial")
    assert loc.listdir("samples") == ["c.npz"]
    assert loc.remove_temporaries("samples/c.npz") == 1
    assert loc.remove_temporaries("samples/c.npz") == 0
    assert loc.read_bytes("samples/c.npz") == b"old"


def test_scratch_and_commit_tree(loc):
    with loc.scratch("job.pc2") as d:
        (d / "job.pc2").write_bytes(b"cache")
        (d / "frames").mkdir()
        (d / "frames" / "f0.obj").write_bytes(b"v 0 0 0\n")
        assert loc.commit_tree(d) == ["frames/f0.obj", "job.pc2"]
    assert loc.read_bytes("job.pc2") == b"cache" and loc.read_bytes("frames/f0.obj") == b"v 0 0 0\n"
    assert loc.listdir() == ["job.pc2"]
    assert loc.remove_temporaries("job.pc2") == 0  # the scratch folder is gone


def test_append_text(loc):
    loc.append_text("log.jsonl", "a\n")
    loc.append_text("log.jsonl", "b\n")
    assert loc.read_text("log.jsonl") == "a\nb\n"


def test_pickles(loc):
    loc.put_bytes("k.txt", b"v")
    back = pickle.loads(pickle.dumps(loc))
    assert type(back) is type(loc) and back.read_bytes("k.txt") == b"v"


@pytest.mark.parametrize("rel", ["", "/abs", "a/../b", "a//b", "./a"])
def test_paths_inside_must_be_plain(loc, rel):
    with pytest.raises(InputError, match="relative and plain"):
        loc.exists(rel) if rel else loc.put_bytes(rel, b"")


def test_exclusive_atomic_path(tmp_path):
    target = tmp_path / "t.json"
    with atomic_path(target, exclusive=True) as tmp:
        tmp.write_text("1")
    with pytest.raises(FileExistsError):
        with atomic_path(target, exclusive=True) as tmp:
            tmp.write_text("2")
    assert target.read_text() == "1" and sorted(os.listdir(tmp_path)) == ["t.json"]


def test_fsspec_missing_says_how_to_install(monkeypatch):
    monkeypatch.setitem(sys.modules, "fsspec", None)
    with pytest.raises(SegadeformError, match=r"expected fsspec installed: pip install segadeform\[ray\]"):
        open_location("s3://bucket/ds")
