"""A new user's trial (trial 6) of the sequence writers: a BVH's ``Frame Time: 0.00833333`` was written as
120.0000480000192 fps; `--up z` into Alembic or OBJ frames (no up-axis field) said nothing; an output named only an
extension (`nm/.usda`) became a hidden folder, and `--format obj-seq -o d.obj` a folder called d.obj; `inspect` counted
a quad mesh's triangles as its faces; USD prim names dropped a leading digit and non-ASCII letters."""

from __future__ import annotations

import logging

import numpy as np
import pytest
from click.testing import CliRunner

from segadeform.cli.main import cli
from segadeform.errors import InputError
from segadeform.io import open_sequence_writer
from segadeform.io.formats import inspect_sequence
from segadeform.io.outputs import SceneOutput, body_output_format, output_format_for
from segadeform.io.surface import Surface
from segadeform.io.writer import nominal_fps

BVH_120 = 1.0 / 0.00833333  # 120.0000480000192


@pytest.mark.parametrize(
    ("fps", "want"),
    [
        (BVH_120, 120.0),
        (1.0 / 0.0333333, 30.0),
        (1.0 / 0.041667, 24.0),
        (1.0 / 0.008333, 120.0),
        (24000 / 1001, 24000 / 1001),
        (23.976, 24000 / 1001),
        (29.97, 30000 / 1001),
        (60000 / 1001, 60000 / 1001),
        (25.0, 25.0),
        (119.99, 119.99),  # asked for on purpose: kept (a review)
        (25.002, 25.002),
        (12.5, 12.5),  # no common rate near: kept
        (23.9, 23.9),
        (1000.0, 1000.0),
    ],
)
def test_nominal_fps(fps, want):
    assert nominal_fps(fps) == want


def _quads():
    """A strip of 3 quads (8 vertices) and its frames."""
    v = np.array([[x, y, 0.0] for x in range(4) for y in (0, 1)], float)
    counts = np.full(3, 4)
    idx = np.concatenate([[2 * i, 2 * i + 2, 2 * i + 3, 2 * i + 1] for i in range(3)])
    s = Surface(counts=counts, indices=idx)
    return s, v, np.stack([v + [0.01 * k, 0, 0] for k in range(3)])


def _write_quads(path, fmt):
    """The strip's frames written as ``fmt`` at a BVH's 120 fps (Frame Time 0.00833333), from frame 2."""
    s, v, frames = _quads()
    with open_sequence_writer(path, fmt, faces=s.triangles(), num_points=len(v), fps=BVH_120, start_frame=2) as w:
        w.write(frames)


def test_usd_writes_the_nominal_rate_and_its_time_codes(tmp_path):
    pytest.importorskip("pxr", reason="USD output needs the 'usd' extra")
    from segadeform.io.usd import read_usd_sequence

    _write_quads(tmp_path / "a.usda", "usd")
    text = (tmp_path / "a.usda").read_text()
    assert "framesPerSecond = 120\n" in text and "timeCodesPerSecond = 120\n" in text, text[:400]
    _, _, times, info = read_usd_sequence(tmp_path / "a.usda")
    assert info["fps"] == 120.0 and times.tolist() == [2.0, 3.0, 4.0]


def test_alembic_time_sampling_is_the_nominal_rate(tmp_path):
    pytest.importorskip("alembic3d", reason="Alembic output needs the 'alembic' extra")
    from segadeform.io.alembic import alembic_start_frame, read_alembic_sequence

    _write_quads(tmp_path / "b.abc", "abc")
    times = read_alembic_sequence(tmp_path / "b.abc")[2]
    np.testing.assert_array_equal(times, np.array([2.0, 3.0, 4.0]) / 120.0)
    assert alembic_start_frame(tmp_path / "b.abc") == 2.0


def test_xdmf_times_are_at_the_nominal_rate(tmp_path):
    from segadeform.io.sequence import XDMF_RATE, read_xdmf_sequence

    s, v, frames = _quads()
    with open_sequence_writer(
        tmp_path / "c.xdmf", "xdmf", faces=s.triangles(), num_points=len(v), fps=BVH_120, rest=v
    ) as w:
        w.write(frames)
    assert f'Name="{XDMF_RATE}" Value="120.0"' in (tmp_path / "c.xdmf").read_text()
    np.testing.assert_array_equal(read_xdmf_sequence(tmp_path / "c.xdmf")[2], np.arange(3) / 120.0)


def _scene_output(path, fmt, up, body_path=None):
    s, v, frames = _quads()
    kw = {}
    if body_path is not None:
        kw = {"body_path": body_path, "body_faces": s.triangles(), "body_rest": v}
    return SceneOutput(path=path, fmt=fmt, up=up, garment_faces=s.triangles(), garment_rest=v, **kw)


@pytest.mark.parametrize(("name", "fmt"), [("g.abc", "abc"), ("g_frames", "obj-seq")])
def test_up_z_into_a_format_without_an_up_axis_is_warned_of(tmp_path, caplog, name, fmt):
    pytest.importorskip("alembic3d", reason="Alembic output needs the 'alembic' extra")  # (the body's below)
    with caplog.at_level(logging.WARNING, logger="segadeform.io.outputs"):
        _scene_output(tmp_path / name, fmt, "z").abort()
    said = [r.getMessage() for r in caplog.records]
    assert len(said) == 1 and str(tmp_path / name) in said[0] and "up axis z" in said[0], said
    caplog.clear()
    with caplog.at_level(logging.WARNING, logger="segadeform.io.outputs"):  # Y up, and USD/PC2: nothing said
        _scene_output(tmp_path / name, fmt, "y").abort()
        _scene_output(tmp_path / "g.pc2", "pc2", "z", body_path=tmp_path / "b.pc2").abort()
    assert caplog.records == []
    with caplog.at_level(logging.WARNING, logger="segadeform.io.outputs"):  # a body output is named too
        _scene_output(tmp_path / "g.pc2", "pc2", "z", body_path=tmp_path / "b.abc").abort()
    assert [str(tmp_path / "b.abc") in r.getMessage() for r in caplog.records] == [True]
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize("name", [".usda", ".pc2", ".abc", ".USD", ".obj"])
def test_an_output_named_only_an_extension_is_refused(tmp_path, name):
    with pytest.raises(InputError, match="only an extension") as e:
        output_format_for(tmp_path / "nm" / name)
    assert f"expected e.g. {tmp_path / 'nm' / ('out' + name)}" in str(e.value)
    with pytest.raises(InputError, match="only an extension"):
        body_output_format(tmp_path / "nm" / name, "pc2")
    assert output_format_for(tmp_path / "nm" / ".frames") == "obj-seq"  # a hidden folder of another name is one


def test_an_obj_sequence_named_as_a_mesh_file_is_refused(tmp_path):
    with pytest.raises(InputError) as e:
        output_format_for(tmp_path / "d.obj", "obj-seq")
    assert str(e.value).endswith("an OBJ sequence is a folder (expected a folder name without .obj, got d.obj)")
    assert output_format_for(tmp_path / "d", "obj-seq") == "obj-seq"
    assert output_format_for(tmp_path / "d.v2", "obj-seq") == "obj-seq"  # a dotted folder name of no file type


@pytest.mark.parametrize(("out", "fmt"), [("nm/.usda", None), ("ext/d.obj", "obj-seq")])
def test_run_refuses_those_names_in_one_line_and_writes_nothing(tmp_path, out, fmt):
    from ..conftest import SAMPLES

    args = ["run", "--garment", str(SAMPLES / "garments" / "dress.obj"), "--motion"]
    args += [str(SAMPLES / "motions" / "walk.npz"), "--frames", "0:2", "--no-cache", "-o", str(tmp_path / out)]
    r = CliRunner().invoke(cli, args + (["--format", fmt] if fmt else []))
    lines = [ln for ln in r.output.splitlines() if ln.strip()]
    assert r.exit_code == 1 and len(lines) == 1 and lines[0].startswith("Error: "), r.output
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize(("fmt", "name"), [("usd", "q.usda"), ("obj-seq", "q_frames")])
def test_inspect_counts_the_faces_the_file_holds(tmp_path, fmt, name):
    if fmt == "usd":
        pytest.importorskip("pxr", reason="USD output needs the 'usd' extra")
    s, v, frames = _quads()
    with open_sequence_writer(tmp_path / name, fmt, faces=s.triangles(), num_points=len(v), surface=s) as w:
        w.write(frames)
    summary = inspect_sequence(tmp_path / name)[1]
    assert "3 faces (6 triangles)" in summary, summary
    with open_sequence_writer(tmp_path / f"t{name}", fmt, faces=s.triangles(), num_points=len(v)) as w:
        w.write(frames)  # triangles: said once
    summary = inspect_sequence(tmp_path / f"t{name}")[1]
    assert "6 faces" in summary and "triangles" not in summary, summary


@pytest.mark.parametrize(
    ("stem", "prim"),
    [
        ("07-walk crop", "/_07_walk_crop"),
        ("ümlaut", "/umlaut"),
        ("Straße Ærø", "/Strasse_AEro"),
        ("dress_walk", "/dress_walk"),
        ("外套", "/mesh"),
    ],
)
def test_usd_prim_names_keep_the_file_name(tmp_path, stem, prim):
    pytest.importorskip("pxr", reason="USD output needs the 'usd' extra")
    from segadeform.io.usd import read_usd_sequence

    s, v, frames = _quads()
    path = tmp_path / f"{stem}.usda"
    with open_sequence_writer(path, "usd", faces=s.triangles(), num_points=len(v)) as w:
        w.write(frames)
    assert read_usd_sequence(path)[3]["prim"] == prim


def test_motion_info_and_inspect_say_the_rate_the_writers_write(tmp_path):
    """A BVH at ``Frame Time: 0.016683`` (59.9412 fps) is NTSC's 60000 / 1001 (59.9401) in `motion info`, `inspect`
    and the written file."""
    from ..conftest import SAMPLES

    lines = (SAMPLES / "motions" / "cmu" / "02_01_walk.bvh").read_text().splitlines()
    k = next(i for i, ln in enumerate(lines) if ln.startswith("Frames:"))
    lines[k : k + 2] = ["Frames: 20", "Frame Time: 0.016683"]
    bvh = tmp_path / "w.bvh"
    bvh.write_text("\n".join(lines[: k + 2 + 20]) + "\n")
    r = CliRunner().invoke(cli, ["motion", "info", str(bvh)])
    assert r.exit_code == 0 and f"{bvh}: 20 frames, 59.9401 fps," in r.output, r.output
    r = CliRunner().invoke(cli, ["inspect", str(bvh)])
    assert r.exit_code == 0 and "20 frames at 59.9401 fps" in r.output, r.output
    assert nominal_fps(1 / 0.016683) == 60000 / 1001


def test_alembic_object_names_keep_the_file_name(tmp_path):
    """Alembic's object named as USD's prim is: ``ümlaut.abc`` holds ``umlaut`` (it held ``_mlaut``)."""
    pytest.importorskip("alembic3d", reason="Alembic output needs the 'alembic' extra")
    from alembic3d import Abc

    _write_quads(tmp_path / "ümlaut.abc", "abc")
    top = Abc.IArchive(str(tmp_path / "ümlaut.abc")).getTop()
    assert [top.getChild(i).getName() for i in range(top.getNumChildren())] == ["umlaut"]
