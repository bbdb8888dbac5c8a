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
