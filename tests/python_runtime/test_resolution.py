"""`run --resolution R`: the model runs on the garment decimated to R of its vertices and its frames are carried
back to every vertex of the garment as given (the accuracy/time table's "garment 1/2 res" row, on its frontier, which
only the bench could run: a new user's trial).  Collisions, the cloth stage and the outputs stay at full resolution."""

from __future__ import annotations

import numpy as np
import pytest
from click.testing import CliRunner

from segadeform.body.resample import SurfaceMap, decimate
from segadeform.cli.main import cli
from segadeform.io import read_mesh, read_pc2, write_obj

from ..conftest import SAMPLES

DRESS = SAMPLES / "garments" / "dress.obj"
WALK = SAMPLES / "motions" / "walk.npz"


def _run(tmp_path, *args):
    r = CliRunner().invoke(cli, ["run", "--motion", str(WALK), "--frames", "0:6", *map(str, args)])
    assert "Traceback" not in r.output, r.output
    return r


def test_the_model_runs_on_the_decimated_garment_and_every_vertex_is_written(tmp_path):
    full = read_mesh(DRESS)
    n = len(full.vertices)
    eff = ["--effects", "lbs,dynamics,wrinkles"]
    r = _run(tmp_path, "--garment", DRESS, "--resolution", "0.5", *eff, "-o", tmp_path / "half.pc2", "--no-cache")
    assert r.exit_code == 0, r.output
    m = int(round(n * 0.5))
    assert f"resolution 0.5: the model ran on {m} of the garment's {n} vertices, carried to all" in r.output
    half = read_pc2(tmp_path / "half.pc2").frames
    assert half.shape == (6, n, 3)
    # the same as running the decimated garment and carrying its frames by hand
    v, f = decimate(full.vertices, full.faces, m)
    write_obj(tmp_path / "small.obj", type(full)(vertices=v, faces=f))
    r = _run(tmp_path, "--garment", tmp_path / "small.obj", *eff, "-o", tmp_path / "small.pc2", "--no-cache")
    assert r.exit_code == 0, r.output
    small = read_pc2(tmp_path / "small.pc2").frames.astype(np.float64)
    by_hand = SurfaceMap.build(full.vertices, v, f).apply(small)
    assert np.abs(by_hand - half).max() < 1e-4  # the small garment's OBJ and frames are float32-rounded
    # not the full-resolution run's frames (the knob does something), but near them
    r = _run(tmp_path, "--garment", DRESS, *eff, "-o", tmp_path / "full.pc2", "--no-cache")
    d = np.linalg.norm(read_pc2(tmp_path / "full.pc2").frames - half, axis=2)
    assert 1e-4 < d.mean() < 0.02, d.mean()


def test_collisions_and_the_outputs_stay_at_full_resolution_and_the_cache_keeps_resolutions_apart(
    tmp_path, monkeypatch
):
    monkeypatch.setenv("SEGADEFORM_CACHE_DIR", str(tmp_path / "cache"))
    full = read_mesh(DRESS)
    for name, res in (("a.pc2", "0.5"), ("b.pc2", "1"), ("c.pc2", "0.5")):
        r = _run(tmp_path, "--garment", DRESS, "--resolution", res, "-o", tmp_path / name)
        assert r.exit_code == 0, r.output
        assert ("resolution 0.5" in r.output) == (res == "0.5")
    a, b, c = (read_pc2(tmp_path / x).frames for x in ("a.pc2", "b.pc2", "c.pc2"))
    assert a.shape == b.shape == (6, len(full.vertices), 3)
    assert np.array_equal(a, c) and not np.array_equal(a, b)  # the cached asset of each resolution its own
    r = _run(tmp_path, "--garment", DRESS, "--resolution", "0.5", "--body-out", tmp_path / "body", "-o", tmp_path / "o")
    assert r.exit_code == 0, r.output
    frame = read_mesh(sorted((tmp_path / "o").glob("*.obj"))[0])
    assert len(frame.vertices) == len(full.vertices) and len(frame.faces) == len(full.faces)


@pytest.mark.parametrize("res", ["0", "1.5", "-0.5"])
def test_a_resolution_outside_0_1_is_a_usage_error(tmp_path, res):
    r = _run(tmp_path, "--garment", DRESS, "--resolution", res, "-o", tmp_path / "x.pc2")
    assert r.exit_code == 2 and "--resolution" in r.output and not (tmp_path / "x.pc2").exists()


def test_a_garment_asset_is_refused_with_a_resolution(tmp_path):
    from segadeform.body import default_body_path

    r = CliRunner().invoke(
        cli, ["precompute", str(DRESS), "--body", str(default_body_path()), "-o", str(tmp_path / "g.npz")]
    )
    assert r.exit_code == 0, r.output
    r = _run(tmp_path, "--garment", tmp_path / "g.npz", "--resolution", "0.5", "-o", tmp_path / "x.pc2")
    assert r.exit_code == 1 and "--resolution takes the garment's mesh" in r.output
    assert not (tmp_path / "x.pc2").exists()


def test_the_decimation_is_cached_as_entries_the_cache_prunes(tmp_path, monkeypatch):
    """A second run reads the decimated garment and its map from the cache (it decimated again every run: 14.5 s on a
    39k-vertex garment), and every file a --resolution run caches is an entry `cache clear` and the size bound remove
    (an `asset-...-r0.5.npz` was neither: a review)."""
    import segadeform.body.resample as resample
    from segadeform.io.cache import is_entry

    monkeypatch.setenv("SEGADEFORM_CACHE_DIR", str(tmp_path / "cache"))
    r = _run(tmp_path, "--garment", DRESS, "--resolution", "0.5", "-o", tmp_path / "a.pc2")
    assert r.exit_code == 0, r.output
    names = sorted(p.name for p in (tmp_path / "cache").iterdir())
    assert any(n.startswith("R-") for n in names) and all(is_entry(n) for n in names), names

    def refuse(*a, **k):
        raise AssertionError("decimated again")

    monkeypatch.setattr(resample, "decimate", refuse)
    monkeypatch.setattr(resample.SurfaceMap, "build", refuse)
    r = _run(tmp_path, "--garment", DRESS, "--resolution", "0.5", "-o", tmp_path / "b.pc2")
    assert r.exit_code == 0, r.output
    assert (tmp_path / "a.pc2").read_bytes()[32:] == (tmp_path / "b.pc2").read_bytes()[32:]


def test_the_garment_as_given_is_checked_and_too_few_vertices_refused(tmp_path, caplog):
    """The run's garment checks read the file's mesh, not the model's decimated copy (loose vertices went unsaid at
    0.5: the output still has a point for each), and a resolution that leaves the model under 200 vertices is refused
    naming the counts (0.002 of the dress was refused as a garment in another unit and axis: a review)."""
    text = DRESS.read_text() + "v 0 1 0\nv 0 1.1 0\n"
    (tmp_path / "loose.obj").write_text(text)
    r = _run(
        tmp_path, "--garment", tmp_path / "loose.obj", "--resolution", "0.5", "-o", tmp_path / "a.pc2", "--no-cache"
    )
    assert r.exit_code == 0, r.output
    assert "2 vertices are in no face" in caplog.text and "output's 2493 points" in caplog.text, caplog.text
    r = _run(tmp_path, "--garment", DRESS, "--resolution", "0.002", "-o", tmp_path / "b.pc2", "--no-cache")
    n = len(read_mesh(DRESS).vertices)
    assert r.exit_code == 1 and f"leaves the model {round(n * 0.002)} of the garment's {n} vertices" in r.output
    assert "at least 200 vertices" in r.output and not (tmp_path / "b.pc2").exists()


def test_a_scene_and_a_jobs_file_name_the_resolution_as_run_does(tmp_path):
    """`[model] resolution` in a scene and `resolution` in a jobs file's [batch] are `run --resolution` (the option
    alone set it); the command line's wins over the scene's."""
    from segadeform.cli.main import main
    from segadeform.errors import FileFormatError
    from segadeform.settings import load_scene

    scene = tmp_path / "s.toml"
    body = f'[garment]\nmesh = "{DRESS}"\n[motion]\nfile = "{WALK}"\nframes = "0:6"\n'
    scene.write_text(body + '[model]\nresolution = 0.5\n[output]\npath = "scene.pc2"\n')
    assert load_scene(scene).resolution == 0.5
    r = CliRunner().invoke(cli, ["run", str(scene), "--no-cache"])
    assert r.exit_code == 0 and "resolution 0.5: the model ran on" in r.output, r.output
    r = _run(tmp_path, "--garment", DRESS, "--resolution", "0.5", "--no-cache", "-o", tmp_path / "flag.pc2")
    assert r.exit_code == 0, r.output
    assert (tmp_path / "scene.pc2").read_bytes()[32:] == (tmp_path / "flag.pc2").read_bytes()[32:]
    r = CliRunner().invoke(cli, ["run", str(scene), "--resolution", "1", "--no-cache", "-o", str(tmp_path / "one.pc2")])
    assert r.exit_code == 0 and "resolution" not in r.output, r.output  # the option over the scene's
    scene.write_text(body + '[model]\nresolution = 1.5\n[output]\npath = "x.pc2"\n')
    with pytest.raises(FileFormatError, match=r"s.toml.*model.resolution"):
        load_scene(scene)
    jobs = tmp_path / "jobs.toml"
    jobs.write_text(
        f'[batch]\noutput = "out"\nresolution = 0.5\n[[garments]]\nmesh = "{DRESS}"\n'
        f'[[motions]]\nfile = "{WALK}"\nframes = "0:6"\n'
    )
    assert main(["batch", str(jobs)]) == 0
    assert (tmp_path / "out" / "dress__walk.pc2").read_bytes()[32:] == (tmp_path / "flag.pc2").read_bytes()[32:]
