"""Outputs in other units than metres (`run --output-units`, a scene's `output.units`, a jobs file's `batch.units`):
Maya and Unreal work in centimetres and read an Alembic's or a PC2's numbers as they are, so a metre output came in
100 times too small.  Every format writes the same frames divided by the unit (the XDMF's rest and a PC2 body's rest
OBJ too), USD records it as `metersPerUnit`, and `inspect` and `preview` read it back."""

from __future__ import annotations

import numpy as np
import pytest
from click.testing import CliRunner

from segadeform.cli.main import cli
from segadeform.errors import FileFormatError, InputError
from segadeform.io import open_sequence_writer, read_pc2, read_sequence
from segadeform.io.alembic import alembic_available
from segadeform.io.formats import sequence_units
from segadeform.io.obj import read_obj
from segadeform.io.output_guard import MANIFEST_NAME
from segadeform.io.usd import usd_available
from segadeform.io.writer import UNIT_SCALES, output_unit
from segadeform.settings import load_scene

from ..conftest import SAMPLES

DRESS = SAMPLES / "garments" / "dress.obj"
WALK = SAMPLES / "motions" / "walk.npz"


def _mesh(n=30, frames=4, seed=0):
    rng = np.random.default_rng(seed)
    v = rng.normal(size=(n, 3))
    f = np.array([[i, i + 1, i + 2] for i in range(n - 2)])
    return v, f, np.stack([v + 0.05 * k + 0.01 * rng.normal(size=v.shape) for k in range(frames)])


@pytest.mark.parametrize(
    "units, metres",
    [
        ("m", 1.0),
        ("cm", 0.01),
        ("CM", 0.01),
        ("mm", 0.001),
        ("inch", 0.0254),
        ("ft", 0.3048),
        (0.01, 0.01),
        ("0.5", 0.5),
    ],
)
def test_output_unit_takes_a_name_or_metres_per_unit(units, metres):
    assert output_unit(units) == metres


@pytest.mark.parametrize("bad", ["furlong", "", "nan", float("nan"), 0, -0.01, 1e-9, 1e6, 100, "1.5", True, None, [1]])
def test_output_unit_refuses_what_is_no_unit(bad):
    with pytest.raises(InputError) as e:
        output_unit(bad, option="--output-units")
    assert "--output-units" in str(e.value) and "cm" in str(e.value)  # names the option and what it takes
    if bad in (100, "1.5"):  # a unit longer than a metre: "x100, centimetres" meant (a pipeline TD's trial)
        assert "centimetres are cm or 0.01" in str(e.value)


FORMATS = [
    ("pc2", "g.pc2"),
    ("obj-seq", "g"),
    ("xdmf", "g.xdmf"),
    pytest.param("abc", "g.abc", marks=pytest.mark.skipif(not alembic_available(), reason="the 'alembic' extra")),
    pytest.param("usd", "g.usd", marks=pytest.mark.skipif(not usd_available(), reason="the 'usd' extra")),
]


@pytest.mark.parametrize("fmt, name", FORMATS)
@pytest.mark.parametrize("up", ["y", "z"])
def test_every_format_writes_the_frames_in_the_unit(tmp_path, fmt, name, up):
    v, f, frames = _mesh()
    got = {}
    for unit in (1.0, 0.01):
        path = tmp_path / str(unit) / name
        path.parent.mkdir()
        with open_sequence_writer(path, fmt, faces=f, num_points=len(v), rest=v, up=up, unit=unit) as w:
            w.write(frames[:2])
            w.write(frames[2:])
        got[unit] = read_sequence(path, faces=f)
        assert sequence_units(path) == (unit if fmt == "usd" else None)  # only USD has a field for it
    assert got[0.01].shape == frames.shape
    np.testing.assert_allclose(got[0.01], 100.0 * got[1.0], rtol=1e-6, atol=1e-5)
    if fmt == "xdmf":  # its rest, the mesh the displacements are added to, in the same units
        import meshio

        with meshio.xdmf.TimeSeriesReader(tmp_path / "0.01" / name) as r:
            rest, _ = r.read_points_cells()
        with meshio.xdmf.TimeSeriesReader(tmp_path / "1.0" / name) as r:
            rest_m, _ = r.read_points_cells()
        np.testing.assert_allclose(rest, 100.0 * rest_m, rtol=1e-9)


def test_a_format_that_takes_no_unit_is_refused_when_one_is_asked(tmp_path, monkeypatch):
    """A format registered before units existed (its opener takes no ``unit``) cannot quietly write metres."""
    from segadeform.io import formats

    pc2 = formats.SEQUENCE_FORMATS["pc2"]

    def old_open(path, *, faces, num_points, fps, start_frame, rest, up):
        return pc2.open(path, faces=faces, num_points=num_points, fps=fps, start_frame=start_frame, rest=rest, up=up)

    import dataclasses

    monkeypatch.setitem(formats.SEQUENCE_FORMATS, "pc2", dataclasses.replace(pc2, open=old_open))
    v, f, _ = _mesh()
    with pytest.raises(InputError, match="cannot write other units than metres"):
        open_sequence_writer(tmp_path / "g.pc2", "pc2", faces=f, num_points=len(v), unit=0.01)
    assert not list(tmp_path.iterdir())
    open_sequence_writer(tmp_path / "g.pc2", "pc2", faces=f, num_points=len(v)).abort()  # metres: as before


def _run(*args):
    r = CliRunner().invoke(
        cli, ["run", "--garment", str(DRESS), "--motion", str(WALK), "--frames", "0:3", "--no-cache", *map(str, args)]
    )
    assert "Traceback" not in r.output, r.output
    return r


def test_run_writes_the_garment_the_body_and_its_rest_mesh_in_centimetres(tmp_path):
    (tmp_path / "m").mkdir()
    (tmp_path / "cm").mkdir()
    r = _run("-o", tmp_path / "m" / "g.pc2", "--body-out", tmp_path / "m" / "b.pc2")
    assert r.exit_code == 0, r.output
    r = _run("-o", tmp_path / "cm" / "g.pc2", "--body-out", tmp_path / "cm" / "b.pc2", "--output-units", "cm")
    assert r.exit_code == 0, r.output
    for name in ("g.pc2", "b.pc2"):
        m, cm = read_pc2(tmp_path / "m" / name).frames, read_pc2(tmp_path / "cm" / name).frames
        np.testing.assert_allclose(cm, 100.0 * m, rtol=1e-6, atol=1e-4)
        assert 150 < cm[..., 1].max() - cm[..., 1].min() or name == "g.pc2"  # the body stands 1.5-2 m: in cm
    rest_m, rest_cm = read_obj(tmp_path / "m" / "b.obj").vertices, read_obj(tmp_path / "cm" / "b.obj").vertices
    np.testing.assert_allclose(rest_cm, 100.0 * rest_m, rtol=1e-9, atol=1e-9)


def test_run_refuses_an_unknown_unit_before_anything_is_written(tmp_path):
    r = _run("-o", tmp_path / "g.pc2", "--output-units", "furlong")
    assert r.exit_code == 2  # a command-line mistake, as in the C++ and Node runtimes (a technical artist's trial: 1)
    last = r.output.strip().splitlines()[-1]
    assert last.startswith("Error: Invalid value for '--output-units': unknown value (expected m | dm"), r.output
    assert "got furlong" in last, r.output
    assert [p.name for p in tmp_path.iterdir() if p.name != MANIFEST_NAME] == []


def test_inspect_says_a_centimetre_usds_motion_in_metres(tmp_path):
    pytest.importorskip("pxr", reason="USD output needs the 'usd' extra")
    for unit in ("m", "cm"):
        (tmp_path / unit).mkdir()
        assert _run("-o", tmp_path / unit / "g.usd", "--output-units", unit).exit_code == 0
    said = {}
    for unit in ("m", "cm"):
        r = CliRunner().invoke(cli, ["inspect", str(tmp_path / unit / "g.usd")])
        assert r.exit_code == 0, r.output
        said[unit] = r.output.splitlines()
    assert "0.01 m per unit" in said["cm"][0] and "in the file's units of 0.01 m" in said["cm"][1]
    assert said["cm"][2] == said["m"][2]  # "motion per frame: mean ... mm, ..., centroid travels ... m"


def test_preview_reads_the_result_in_its_units(tmp_path):
    """A centimetre result and body drawn as the metre ones (same file names, so the same titles)."""
    pytest.importorskip("matplotlib")
    import matplotlib.image as mpimg

    for unit in ("m", "cm"):
        d = tmp_path / unit
        d.mkdir()
        r = _run("-o", d / "g.pc2", "--body-out", d / "b.pc2", "--output-units", unit)
        assert r.exit_code == 0, r.output
        args = ["preview", str(d / "g.pc2"), "--garment", str(DRESS), "--body", str(d / "b.pc2")]
        args += ["-o", str(d / "p.png"), "--frames", "1:2", "--size", "96x128"]
        r = CliRunner().invoke(cli, [*args, "--output-units", unit])
        assert r.exit_code == 0, r.output
    a, b = mpimg.imread(tmp_path / "m" / "p.png"), mpimg.imread(tmp_path / "cm" / "p.png")
    assert np.abs(a - b).max() < 0.02


def test_a_scene_names_its_output_units(tmp_path):
    scene = (SAMPLES / "scenes" / "skirt_walk.toml").read_text()
    base = SAMPLES / "scenes"
    text = scene.replace('"../', f'"{base}/../')
    p = tmp_path / "s.toml"
    p.write_text(text.replace("[output]", '[output]\nunits = "cm"'))
    assert load_scene(p).units == 0.01
    p.write_text(text)
    assert load_scene(p).units == 1.0
    p.write_text(text.replace("[output]", '[output]\nunits = "furlong"'))
    with pytest.raises(FileFormatError, match=r"s.toml:\d+: unknown output.units.*furlong"):
        load_scene(p)


def test_unit_names_are_one_table():
    """Placement reads a garment's units from the same table the writers write them by."""
    from segadeform.body import placement

    assert placement.UNIT_SCALES is UNIT_SCALES


def test_a_millimetre_output_past_10000_units_is_read_in_its_units(tmp_path):
    """A walk 11 m from the origin written in millimetres holds numbers past 10,000: `inspect` and `preview` refused
    it as beyond 10 km (a review); told its units they read it, and `inspect` without them says how."""
    from segadeform.io import Mesh, write_obj

    v, f, frames = _mesh()
    far = frames + np.array([11.0, 0.0, 0.0])  # 11 m along x
    d = tmp_path / "mm"
    with open_sequence_writer(d, "obj-seq", faces=f, num_points=len(v), unit=0.001) as w:
        w.write(far)
    r = CliRunner().invoke(cli, ["inspect", str(d)])
    assert r.exit_code == 1 and "--output-units says the one it was written in" in r.output, r.output
    r = CliRunner().invoke(cli, ["inspect", str(d), "--output-units", "mm"])
    assert r.exit_code == 0 and "in the file's units of 0.001 m" in r.output, r.output
    write_obj(tmp_path / "g.obj", Mesh(vertices=v, faces=f))
    args = ["preview", str(d), "--garment", str(tmp_path / "g.obj"), "-o", str(tmp_path / "p.png"), "--size", "64x64"]
    r = CliRunner().invoke(cli, [*args, "--output-units", "mm"])
    assert r.exit_code == 0, r.output
    # a rest mesh in a tiny unit (0.1 mm): read in its units
    write_obj(tmp_path / "tiny.obj", Mesh(vertices=(v + 11.0) / 1e-4, faces=f))
    r = CliRunner().invoke(cli, ["inspect", str(tmp_path / "tiny.obj"), "--output-units", "0.0001"])
    assert r.exit_code == 0 and "in the file's units of 0.0001 m" in r.output, r.output


def test_preview_reads_a_body_beside_a_centimetre_usd_in_its_units(tmp_path):
    """A USD records its unit and a PC2 body of the same run does not: the body is drawn in the USD's units (it was
    drawn 100 times too big, the garment lost in it: a review)."""
    pytest.importorskip("pxr", reason="USD output needs the 'usd' extra")
    pytest.importorskip("matplotlib")
    import matplotlib.image as mpimg

    for unit in ("m", "cm"):
        d = tmp_path / unit
        d.mkdir()
        assert _run("-o", d / "g.usd", "--body-out", d / "b.pc2", "--output-units", unit).exit_code == 0
        args = ["preview", str(d / "g.usd"), "--garment", str(DRESS), "--body", str(d / "b.pc2")]
        r = CliRunner().invoke(cli, [*args, "-o", str(d / "p.png"), "--frames", "1:2", "--size", "96x128"])
        assert r.exit_code == 0, r.output
    a, b = mpimg.imread(tmp_path / "m" / "p.png"), mpimg.imread(tmp_path / "cm" / "p.png")
    assert np.abs(a - b).max() < 0.02
