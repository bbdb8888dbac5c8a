"""The one output rule (segadeform.io.output_guard): what a command may replace, where, and what it records."""

from __future__ import annotations

import json
import os
import time
from pathlib import Path

import pytest

from segadeform.io.atomic import (
    atomic_directory,
    atomic_path,
    make_folders,
    merge_directory,
    removing_made_folders,
)
from segadeform.io.output_guard import (
    MANIFEST_NAME,
    OutputGuard,
    OutputRefused,
    read_manifest,
    written_by,
)


def _write(p: Path, text: str = "x") -> None:
    with atomic_path(p) as tmp:
        Path(tmp).write_text(text)


def _made(kind: str, p: Path, text: str = "made", force: bool = False) -> None:
    g = OutputGuard(kind, force=force)
    g.file(p)
    _write(p, text)
    g.record()


def test_a_new_file_is_written_and_recorded(tmp_path):
    p = tmp_path / "out" / "a.pc2"
    _made("run", p)
    assert written_by(p) == "run"
    m = read_manifest(p.parent)
    assert m["files"]["a.pc2"]["size"] == 4


def test_a_file_segadeform_did_not_write_is_never_replaced_even_with_force(tmp_path):
    p = tmp_path / "mine.obj"
    p.write_text("user data")
    for force in (False, True):
        with pytest.raises(OutputRefused, match="segadeform did not write it") as e:
            OutputGuard("garment make", force=force).file(p)
        assert str(p) in str(e.value)
    assert p.read_text() == "user data"


def test_an_earlier_output_of_the_same_command_is_replaced_another_commands_is_not(tmp_path):
    p = tmp_path / "a.pc2"
    _made("run", p)
    _made("run", p, "again")
    assert p.read_text() == "again" and written_by(p) == "run"
    with pytest.raises(OutputRefused, match="written by `segadeform run`"):
        OutputGuard("simulate", force=True).file(p)
    with pytest.raises(OutputRefused, match="never overwritten"):  # dataset pack: not even its own
        OutputGuard("run", replaces=False).file(p)
    assert p.read_text() == "again"


def test_an_output_edited_since_is_no_longer_segadeforms(tmp_path):
    p = tmp_path / "a.obj"
    _made("garment fit", p)
    time.sleep(0.01)
    p.write_text("edited by hand")
    assert written_by(p) is None
    with pytest.raises(OutputRefused, match=r"changed since segadeform wrote it \(its size or modification time: "):
        OutputGuard("garment fit", force=True).file(p)
    assert p.read_text() == "edited by hand"


def test_an_input_is_never_an_output(tmp_path):
    g = tmp_path / "g.obj"
    _made("garment fit", g)  # even one segadeform wrote
    with pytest.raises(OutputRefused, match="is an input of this command"):
        OutputGuard("garment fit", force=True, inputs=[g]).file(tmp_path / "." / "g.obj")


def test_paths_inside_a_file_and_folders_as_files_are_named(tmp_path):
    f = tmp_path / "file.obj"
    f.write_text("v")
    with pytest.raises(OutputRefused, match="is a file, so nothing can be written inside it"):
        OutputGuard("run").file(f / "x.pc2")
    (tmp_path / "d").mkdir()
    with pytest.raises(OutputRefused, match="is a folder"):
        OutputGuard("run", force=True).file(tmp_path / "d")


def test_folder_output_beside_other_files_only_with_force(tmp_path):
    d = tmp_path / "keep"
    d.mkdir()
    (d / "skirt.obj").write_text("input")
    (d / "notes.txt").write_text("notes")
    with pytest.raises(OutputRefused, match=r"holds 2 file\(s\) segadeform run did not write"):
        OutputGuard("run").folder(d, names="frame_*.obj")
    g = OutputGuard("run", force=True)
    g.folder(d, names="frame_*.obj")
    with atomic_directory(d) as tmp:
        for i in range(3):
            (tmp / f"frame_{i:05d}.obj").write_text(f"f{i}")
    assert [p.name for p in g.record()] == [f"frame_{i:05d}.obj" for i in range(3)]
    assert (d / "skirt.obj").read_text() == "input" and (d / "notes.txt").read_text() == "notes"
    # a second, shorter run with --force: the earlier frames it does not write again go, nothing else
    g = OutputGuard("run", force=True)
    g.folder(d, names="frame_*.obj")
    with atomic_directory(d) as tmp:
        (tmp / "frame_00000.obj").write_text("new")
    g.record()
    assert sorted(p.name for p in d.iterdir()) == [MANIFEST_NAME, "frame_00000.obj", "notes.txt", "skirt.obj"]
    assert set(read_manifest(d)["files"]) == {"frame_00000.obj"}


def test_folder_output_refuses_foreign_files_with_its_names(tmp_path):
    d = tmp_path / "seq"
    d.mkdir()
    (d / "frame_00003.obj").write_text("the user's")
    with pytest.raises(OutputRefused, match="named like this output's"):
        OutputGuard("run", force=True).folder(d, names="frame_*.obj")
    with pytest.raises(OutputRefused, match="one holding only an earlier output"):  # a package: names unknown
        OutputGuard("package", force=True).folder(d)


def test_a_folder_holding_only_an_earlier_output_is_replaced_without_force(tmp_path):
    d = tmp_path / "pkg"
    for files in (("a.onnx", "b.onnx", "manifest.json"), ("a.onnx", "manifest.json")):
        g = OutputGuard("package")
        g.folder(d)
        with atomic_directory(d) as tmp:
            for f in files:
                (tmp / f).write_text(f)
        g.record()
    assert sorted(p.name for p in d.iterdir()) == [MANIFEST_NAME, "a.onnx", "manifest.json"]


def test_stale_removal_spares_inputs_and_edited_files(tmp_path):
    d = tmp_path / "seq"
    g = OutputGuard("run")
    g.folder(d, names="frame_*.obj")
    with atomic_directory(d) as tmp:
        for i in range(3):
            (tmp / f"frame_{i:05d}.obj").write_text(f"f{i}")
    g.record()
    time.sleep(0.01)
    (d / "frame_00002.obj").write_text("edited")  # now the user's
    g = OutputGuard("run", force=True, inputs=[d / "frame_00001.obj"])  # an input: kept, yet it is in the way
    with pytest.raises(OutputRefused, match="frame_00001.obj"):
        g.folder(d, names="frame_*.obj")
    g = OutputGuard("run", force=True)
    with pytest.raises(OutputRefused, match="frame_00002.obj"):  # the edited one is in the way of the names
        g.folder(d, names="frame_*.obj")


def test_resumable_folders_continue_their_own_and_mark_new_ones(tmp_path):
    d = tmp_path / "ds"
    g = OutputGuard("dataset")
    g.resumable(d, layout=("samples", "config.toml"), legacy=("samples/", "garments/"))
    g.start()
    assert read_manifest(d)["folder"] == "dataset"
    (d / "samples").mkdir()
    (d / "samples" / "a.json").write_text("{}")
    OutputGuard("dataset").resumable(d, layout=("samples",))  # continued without --force
    with pytest.raises(OutputRefused, match="output of `segadeform dataset`"):
        OutputGuard("batch", force=True).resumable(d)
    legacy = tmp_path / "old"
    (legacy / "samples").mkdir(parents=True)
    (legacy / "garments").mkdir()
    (legacy / "notes.md").write_text("mine")
    OutputGuard("dataset").resumable(legacy, legacy=("samples/", "garments/"))  # made before manifests


def test_resumable_folder_of_other_files(tmp_path):
    d = tmp_path / "mine"
    d.mkdir()
    (d / "notes.txt").write_text("n")
    with pytest.raises(OutputRefused, match="--force to write beside them"):
        OutputGuard("batch").resumable(d, layout=("jobs", "*__*"))
    (d / "jobs").mkdir()
    with pytest.raises(OutputRefused, match=r"where segadeform batch writes \(jobs\)"):
        OutputGuard("batch", force=True).resumable(d, layout=("jobs", "*__*"))
    (d / "jobs").rmdir()
    g = OutputGuard("batch", force=True)
    g.resumable(d, layout=("jobs", "*__*"))
    g.start()
    assert (d / "notes.txt").read_text() == "n" and read_manifest(d)["folder"] == "batch"


def test_a_run_that_made_nothing_leaves_no_folder(tmp_path):
    d = tmp_path / "new"
    g = OutputGuard("batch")
    g.resumable(d)
    g.start()
    assert d.is_dir()
    g.abandon()
    assert not d.exists()
    old = tmp_path / "old"
    old.mkdir()
    g = OutputGuard("batch")
    g.resumable(old)
    g.start()
    g.abandon()
    assert old.is_dir()  # it was there before
    # a run that began its cache of derived data and then could not read its dataset (a damaged pack): the folder
    # and the cache are both this run's, and go (a user's trial found them left behind)
    d = tmp_path / "train"
    g = OutputGuard("train")
    g.resumable(d)
    g.start()
    (d / "cache").mkdir()
    (d / "cache" / "asset-1.npz").write_bytes(b"x")
    g.abandon()
    assert not d.exists()
    # a folder of the user's keeps its cache: only this run's manifest goes
    (old / "cache").mkdir()
    g = OutputGuard("train", force=True)
    g.resumable(old)
    g.start()
    g.abandon()
    assert (old / "cache").is_dir()


def test_a_run_stopped_midway_leaves_no_empty_folder_and_removes_nothing_else(tmp_path):
    """`run -o new/deeper/out.pc2` stopped (Ctrl-C, SIGTERM) after its writer had made the folders left `new/` behind
    (a user's trial): the folders made inside removing_made_folders go again where they are empty, and only those --
    not a folder the user made after the command claimed its output and before the writer began (a review)."""
    with pytest.raises(KeyboardInterrupt), removing_made_folders():
        g = OutputGuard("run")
        out = g.file(tmp_path / "new" / "deeper" / "out.pc2")
        mine = g.file(tmp_path / "mine" / "out.pc2")
        (tmp_path / "mine").mkdir()  # the user's, made between the claim and the write
        for p in (out, mine):
            with atomic_path(p):  # the writer's temporary beside the output (and its folders): then the stop
                raise KeyboardInterrupt
    assert sorted(p.name for p in tmp_path.iterdir()) == ["mine"]
    # a folder something else wrote into meanwhile is not empty: it stays, with its parents and its file
    with pytest.raises(ValueError), removing_made_folders():
        make_folders(tmp_path / "a" / "b")
        (tmp_path / "a" / "note.txt").write_text("mine")
        raise ValueError("bad input")
    assert not (tmp_path / "a" / "b").exists() and (tmp_path / "a" / "note.txt").read_text() == "mine"
    # a resumable folder the run made and marked holds its manifest: left to abandon(), which removes it
    with pytest.raises(KeyboardInterrupt), removing_made_folders():
        g = OutputGuard("batch")
        g.resumable(tmp_path / "made" / "data")
        g.start()
        try:
            raise KeyboardInterrupt
        finally:
            g.abandon()
    assert not (tmp_path / "made").exists()
    # a command that succeeds keeps its folders, even an empty one
    with removing_made_folders():
        make_folders(tmp_path / "ok")
    assert (tmp_path / "ok").is_dir()


def test_a_manifest_that_is_not_one_is_refused_not_overwritten(tmp_path):
    (tmp_path / MANIFEST_NAME).write_text("my own notes")
    with pytest.raises(OutputRefused, match="not a segadeform outputs manifest"):
        OutputGuard("run").file(tmp_path / "a.pc2")
    assert (tmp_path / MANIFEST_NAME).read_text() == "my own notes"


def test_recheck_refuses_a_file_that_appeared_meanwhile(tmp_path):
    p = tmp_path / "a.pc2"
    g = OutputGuard("run", force=True)
    g.file(p)
    p.write_text("someone else's")
    with pytest.raises(OutputRefused, match="segadeform did not write it"):
        g.recheck()


def test_parallel_records_into_one_folder_keep_every_entry(tmp_path):
    """Workers recording into one folder at once: the manifest is updated under a lock, no entry is lost."""
    from concurrent.futures import ProcessPoolExecutor

    names = [f"f{i}.pc2" for i in range(16)]
    with ProcessPoolExecutor(2) as ex:
        list(ex.map(_record_one, [str(tmp_path / n) for n in names]))
    assert set(read_manifest(tmp_path)["files"]) == set(names)


def _record_one(path: str) -> None:
    _made("run", Path(path))


def test_merge_directory_never_removes_what_is_there(tmp_path):
    d = tmp_path / "d"
    d.mkdir()
    (d / "keep.txt").write_text("k")
    (d / "a.bin").write_text("old")
    src = tmp_path / "src"
    (src / "sub").mkdir(parents=True)
    (src / "a.bin").write_text("new")
    (src / "sub" / "b.bin").write_text("b")
    merge_directory(src, d)
    assert (d / "keep.txt").read_text() == "k" and (d / "a.bin").read_text() == "new"
    assert (d / "sub" / "b.bin").read_text() == "b" and not src.exists()
    cwd = os.getcwd()
    e = tmp_path / "empty"
    e.mkdir()
    try:  # into the working directory (`-o .`): file by file, not a rename of the folder in use
        os.chdir(e)
        src2 = tmp_path / "src2"
        src2.mkdir()
        (src2 / "x").write_text("x")
        merge_directory(src2, Path("."))
    finally:
        os.chdir(cwd)
    assert (e / "x").read_text() == "x"


def test_manifest_is_json_listing_kind_size_and_time(tmp_path):
    p = tmp_path / "a.sgdm"
    _made("motion export", p)
    m = json.loads((tmp_path / MANIFEST_NAME).read_text())
    e = m["files"]["a.sgdm"]
    assert m["segadeform_outputs"] == 1 and e["kind"] == "motion export"
    assert e["size"] == p.stat().st_size and e["mtime_ns"] == p.stat().st_mtime_ns
