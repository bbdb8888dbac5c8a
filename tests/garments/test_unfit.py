"""`segadeform garment unfit`: a point cache of a fitted garment put back in the frame of the file it was fitted from
(an engine integrator's trial: `run --up z --output-units cm` undid a cm, Z-up asset's units and axes but not the
`--turn 90` of its fit, and the frames lay turned against the asset)."""

from __future__ import annotations

import numpy as np
from click.testing import CliRunner

from segadeform.body.placement import fix_units_and_axes
from segadeform.cli.main import cli
from segadeform.io import Mesh, read_mesh, read_pc2, write_obj
from segadeform.io.pc2 import write_pc2

from ..conftest import SAMPLES


def _source(tmp_path):
    """The sample dress as an asset in centimetres, +Z up, facing -X (what `fit --units cm --up z --turn 90` undoes)."""
    m = read_mesh(SAMPLES / "garments" / "dress.obj")
    basis = fix_units_and_axes(np.eye(3), units="cm", up="z", turn=90)  # rows: f R e_i
    src = m.vertices @ np.linalg.inv(basis)
    write_obj(tmp_path / "asset.obj", Mesh(src, m.faces))
    return src, m


def test_unfit_puts_a_cache_back_on_the_asset(tmp_path):
    src, m = _source(tmp_path)
    r = CliRunner().invoke(
        cli,
        ["garment", "fit", str(tmp_path / "asset.obj"), "--units", "cm", "--up", "z", "--turn", "90", "-o",
         str(tmp_path / "fit.obj")],
    )  # fmt: skip
    assert r.exit_code == 0, r.output
    fit = read_mesh(tmp_path / "fit.obj").vertices
    np.testing.assert_allclose(fit, m.vertices, atol=1e-5)  # on the body again
    # a cache of two frames: the rest, and the rest moved 10 cm forward (+Z on the body: -X on the asset) and 1 m up
    frames = np.stack([fit, fit + [0.0, 1.0, 0.1]])
    write_pc2(tmp_path / "run.pc2", frames, start_frame=7, sample_rate=1.0)
    r = CliRunner().invoke(
        cli, ["garment", "unfit", str(tmp_path / "run.pc2"), "--garment", str(tmp_path / "fit.obj"), "-o",
              str(tmp_path / "asset.pc2")],
    )  # fmt: skip
    assert r.exit_code == 0, r.output
    back = read_pc2(tmp_path / "asset.pc2")
    np.testing.assert_allclose(back.frames[0], src, atol=1e-3)  # cm: within 10 um of the asset
    np.testing.assert_allclose(back.frames[1] - back.frames[0], np.broadcast_to([-10.0, 0.0, 100.0], src.shape),
                               atol=1e-3)  # fmt: skip
    assert back.header.start_frame == 7 and back.frames.shape == frames.shape
    # never over a file it did not write; refused inputs say why
    (tmp_path / "mine.pc2").write_bytes(b"mine")
    r = CliRunner().invoke(
        cli, ["garment", "unfit", str(tmp_path / "run.pc2"), "--garment", str(tmp_path / "fit.obj"), "-o",
              str(tmp_path / "mine.pc2")],
    )  # fmt: skip
    assert r.exit_code == 1 and (tmp_path / "mine.pc2").read_bytes() == b"mine", r.output
    for garment, words in (
        (tmp_path / "asset.obj", "no record of `segadeform garment fit`"),
        (SAMPLES / "garments" / "skirt.obj", "no record of `segadeform garment fit`"),
    ):
        r = CliRunner().invoke(cli, ["garment", "unfit", str(tmp_path / "run.pc2"), "--garment", str(garment), "-o",
                                     str(tmp_path / "x.pc2")])  # fmt: skip
        assert r.exit_code == 1 and words in r.output and not (tmp_path / "x.pc2").exists(), r.output
    lines = (tmp_path / "fit.obj").read_text().splitlines()
    lines[0] = "# segadeform garment fit: registered to body.npz (body fit 0.3 cm mean)"
    (tmp_path / "reg.obj").write_text("\n".join(lines) + "\n")
    r = CliRunner().invoke(cli, ["garment", "unfit", str(tmp_path / "run.pc2"), "--garment", str(tmp_path / "reg.obj"),
                                 "-o", str(tmp_path / "x.pc2")])  # fmt: skip
    assert r.exit_code == 1 and "fitted by registration" in r.output, r.output
    write_pc2(tmp_path / "other.pc2", frames[:, :10], start_frame=0, sample_rate=1.0)
    other = ["garment", "unfit", str(tmp_path / "other.pc2"), "--garment", str(tmp_path / "fit.obj")]
    r = CliRunner().invoke(cli, [*other, "-o", str(tmp_path / "x.pc2")])
    assert r.exit_code == 1 and "not of this garment" in r.output, r.output
