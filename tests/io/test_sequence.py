import numpy as np
import pytest

from segadeform.errors import FileFormatError
from segadeform.geometry.primitives import grid_plane
from segadeform.io import (
    Mesh,
    open_sequence_writer,
    read_obj_sequence,
    read_sequence,
    read_xdmf_sequence,
    write_obj,
    write_obj_sequence,
    write_xdmf_sequence,
)
from tests.conftest import leftovers


def animated(s=5):
    v, f = grid_plane(4, 5)
    t = np.linspace(0, 1, s)[:, None, None]
    return f, v[None] + t * np.array([0.0, 1.0, 0.5]) + 0.01 * np.sin(7 * v[None])


def test_obj_sequence_round_trip(tmp_path):
    f, fr = animated()
    write_obj_sequence(tmp_path / "seq", f, fr)
    faces, back = read_obj_sequence(tmp_path / "seq")
    np.testing.assert_array_equal(faces, f)
    np.testing.assert_allclose(back, fr, atol=1e-8)
    assert leftovers(tmp_path) == []


def test_obj_sequence_orders_numerically(tmp_path):
    v, f = grid_plane(3, 3)
    d = tmp_path / "seq"
    d.mkdir()
    for i in (10, 2, 1):
        write_obj(d / f"f{i}.obj", Mesh(vertices=v + i, faces=f))
    _, fr = read_obj_sequence(d)
    np.testing.assert_allclose(fr[:, 0, 0], [1, 2, 10])


def test_obj_sequence_topology_mismatch(tmp_path):
    v, f = grid_plane(3, 3)
    d = tmp_path / "seq"
    d.mkdir()
    write_obj(d / "frame_0.obj", Mesh(vertices=v, faces=f))
    write_obj(d / "frame_1.obj", Mesh(vertices=v, faces=f[::-1]))
    with pytest.raises(FileFormatError, match="topology differs") as ei:
        read_obj_sequence(d)
    assert "frame_1.obj" in str(ei.value)


def test_obj_sequence_failure_leaves_no_folder(tmp_path):
    f, fr = animated()
    with pytest.raises(RuntimeError):
        with open_sequence_writer(tmp_path / "seq", "obj-seq", faces=f, num_points=fr.shape[1]) as w:
            w.write(fr[:2])
            raise RuntimeError("boom")
    assert list(tmp_path.iterdir()) == []


def test_xdmf_round_trip(tmp_path):
    f, fr = animated()
    write_xdmf_sequence(tmp_path / "a.xdmf", f, fr, fps=25.0)
    faces, back, times = read_xdmf_sequence(tmp_path / "a.xdmf")
    np.testing.assert_array_equal(faces, f)
    np.testing.assert_allclose(back, fr, atol=1e-5)  # float32 displacements
    np.testing.assert_allclose(times, np.arange(5) / 25.0)
    np.testing.assert_allclose(read_sequence(tmp_path / "a.xdmf"), fr, atol=1e-5)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a.xdmf"]  # no side files


def test_read_sequence_dispatch(tmp_path):
    f, fr = animated()
    with open_sequence_writer(tmp_path / "a.pc2", "pc2", faces=f, num_points=fr.shape[1]) as w:
        w.write(fr)
    np.testing.assert_allclose(read_sequence(tmp_path / "a.pc2"), fr, atol=1e-6)
    with pytest.raises(Exception, match="unknown sequence format"):
        read_sequence(tmp_path / "a.txt")


def test_broken_xdmf(tmp_path):
    p = tmp_path / "b.xdmf"
    p.write_text("<Xdmf><Domain>")
    with pytest.raises(FileFormatError) as ei:
        read_xdmf_sequence(p)
    assert str(p) in str(ei.value)


def test_alembic_round_trip(tmp_path):
    from segadeform.io.alembic import read_alembic_sequence

    f, fr = animated()
    with open_sequence_writer(tmp_path / "a.abc", "abc", faces=f, num_points=fr.shape[1], fps=25.0, start_frame=2) as w:
        w.write(fr[:2])
        w.write(fr[2:])
    faces, back, times = read_alembic_sequence(tmp_path / "a.abc")
    np.testing.assert_array_equal(faces, f)
    np.testing.assert_allclose(back, fr, atol=1e-6)
    np.testing.assert_allclose(times, (2 + np.arange(5)) / 25.0)
    np.testing.assert_allclose(read_sequence(tmp_path / "a.abc"), fr, atol=1e-6)
    assert leftovers(tmp_path) == []


def test_alembic_failure_leaves_nothing(tmp_path):
    f, fr = animated()
    with pytest.raises(RuntimeError):
        with open_sequence_writer(tmp_path / "a.abc", "abc", faces=f, num_points=fr.shape[1]) as w:
            w.write(fr[:2])
            raise RuntimeError("boom")
    assert list(tmp_path.iterdir()) == []


def test_alembic_lazy_frames_read_the_samples_asked_for(tmp_path, monkeypatch):
    """`read_alembic_sequence(lazy=True)` reads a sample's positions when it is indexed, as float32 (`inspect` of a
    long .abc held the whole clip as float64, 7.4 GB for a 756 MB body; a user's trial)."""
    pytest.importorskip("alembic3d", reason="Alembic needs the 'alembic' extra")
    from segadeform.io import alembic
    from segadeform.io.sequence import open_sequence_frames

    f, fr = animated(s=11)
    with open_sequence_writer(tmp_path / "a.abc", "abc", faces=f, num_points=fr.shape[1], fps=24.0) as w:
        w.write(fr)
    faces, lazy, times = alembic.read_alembic_sequence(tmp_path / "a.abc", lazy=True)
    np.testing.assert_array_equal(faces, f)
    assert isinstance(lazy, alembic.AlembicFrames) and lazy.shape == fr.shape and lazy.dtype == np.float32
    asked = []
    real = alembic.AlembicFrames._read
    monkeypatch.setattr(alembic.AlembicFrames, "_read", lambda self, idx: asked.append(list(idx)) or real(self, idx))
    np.testing.assert_array_equal(lazy[[3, 9]], fr[[3, 9]].astype(np.float32))
    np.testing.assert_array_equal(open_sequence_frames(tmp_path / "a.abc")[-2:], fr[-2:].astype(np.float32))
    assert asked == [[3, 9], [9, 10]]


def test_obj_frames_read_the_files_of_the_frames_asked_for(tmp_path):
    """An OBJ folder's frames are read file by file when indexed; a frame of another topology is named when read."""
    from segadeform.io.sequence import ObjFrames, open_sequence_frames

    f, fr = animated(s=6)
    write_obj_sequence(tmp_path / "seq", f, fr)
    seq = open_sequence_frames(tmp_path / "seq")
    assert isinstance(seq, ObjFrames) and seq.shape == fr.shape
    np.testing.assert_allclose(seq[[1, 4]], fr[[1, 4]], atol=1e-8)
    write_obj(tmp_path / "seq" / "frame_00003.obj", Mesh(vertices=fr[3][:-1], faces=f[:2]))
    np.testing.assert_allclose(seq[2], fr[2], atol=1e-8)  # the bad file is not read
    with pytest.raises(FileFormatError, match="frame topology differs") as ei:
        seq[2:5]
    assert "frame_00003.obj" in str(ei.value)
    with pytest.raises(FileFormatError, match="frame topology differs"):
        read_obj_sequence(tmp_path / "seq")


def test_frames_of_a_format_read_whole_are_indexed_alike(tmp_path):
    """XDMF (meshio reads it whole) is read whole by open_sequence_frames, and indexed as the lazy ones."""
    from segadeform.io.sequence import ArrayFrames, frame_chunks, open_sequence_frames

    f, fr = animated(s=4)
    write_xdmf_sequence(tmp_path / "a.xdmf", f, fr)
    seq = open_sequence_frames(tmp_path / "a.xdmf")
    assert isinstance(seq, ArrayFrames)
    np.testing.assert_allclose(seq[[0, 3]], fr[[0, 3]], atol=1e-6)
    assert [s for s, _ in frame_chunks(seq, max_values=3 * fr.shape[1])] == [0, 1, 2, 3]
