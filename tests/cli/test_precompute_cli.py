import subprocess
import sys

import numpy as np
import pytest
from click.testing import CliRunner

from segadeform.cli.main import cli, main
from segadeform.errors import InputError
from segadeform.geometry import GarmentAsset
from tests.conftest import SAMPLES, leftovers


def run(*args):
    return CliRunner().invoke(cli, list(map(str, args)))


def test_precompute_sample(tmp_path, samples):
    out = tmp_path / "skirt.npz"
    r = run(
        "precompute",
        samples / "garments" / "skirt.obj",
        "--joints",
        samples / "skeletons" / "tpose_joints_24.npy",
        "-o",
        out,
    )
    assert r.exit_code == 0, r.output
    assert "1536 vertices" in r.output
    a = GarmentAsset.load(out)
    assert a.n_vertices == 1536 and a.features.shape == (1536, 30) and a.descriptor.shape == (32,)
    assert len(a.source_sha256) == 64


def test_options_are_applied(tmp_path, samples):
    out = tmp_path / "a.npz"
    r = run(
        "precompute",
        samples / "garments" / "skirt.obj",
        "--joints",
        samples / "skeletons" / "tpose_joints_24.npy",
        "-o",
        out,
        "--k",
        "4",
        "--n-star",
        "8",
        "--geodesic",
        "dijkstra",
    )
    assert r.exit_code == 0, r.output
    a = GarmentAsset.load(out)
    assert a.nbr.shape[1] == 4 and a.descriptor.shape == (8,) and a.params["geodesic"] == "dijkstra"


def test_body_npz_gives_joints(tmp_path, samples):
    j = np.load(samples / "skeletons" / "tpose_joints_24.npy")
    vt = np.random.default_rng(0).normal(size=(50, 3))
    jr = np.linalg.lstsq(vt.T, j.T, rcond=None)[0].T  # (24, 50) with jr @ vt == j
    np.savez(tmp_path / "body.npz", v_template=vt, J_regressor=jr)
    out = tmp_path / "a.npz"
    r = run("precompute", samples / "garments" / "skirt.obj", "--body", tmp_path / "body.npz", "-o", out)
    assert r.exit_code == 0, r.output
    np.testing.assert_allclose(GarmentAsset.load(out).joints, j, atol=1e-8)


@pytest.mark.parametrize(
    "garment_text, words",
    [
        ("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 4\n", "g.obj:4: vertex index out of range"),
        ("", "g.obj: mesh has no vertices"),
        ("v 0 0 0\nv nan 0 0\nv 0 1 0\nf 1 2 3\n", "g.obj:2: vertex coordinate is not finite"),
    ],
)
def test_bad_garment_clear_error_no_output(tmp_path, samples, garment_text, words):
    g = tmp_path / "g.obj"
    g.write_text(garment_text)
    out = tmp_path / "a.npz"
    r = run("precompute", g, "--joints", samples / "skeletons" / "tpose_joints_24.npy", "-o", out)
    assert r.exit_code == 1
    assert words in r.output and "Traceback" not in r.output
    assert not out.exists() and leftovers(tmp_path) == []


def test_bad_joints_and_usage(tmp_path, samples):
    g = samples / "garments" / "skirt.obj"
    np.save(tmp_path / "j.npy", np.zeros((24, 2)))
    r = run("precompute", g, "--joints", tmp_path / "j.npy", "-o", tmp_path / "a.npz")
    assert r.exit_code == 1 and "expected (S, 3), got (24, 2)" in r.output
    r = run("precompute", g, "-o", tmp_path / "a.npz")
    assert r.exit_code == 2 and "exactly one of --joints" in r.output
    r = run(
        "precompute",
        tmp_path / "missing.obj",
        "--joints",
        samples / "skeletons" / "tpose_joints_24.npy",
        "-o",
        tmp_path / "a.npz",
    )
    assert r.exit_code == 1 and "missing.obj" in r.output
    assert not (tmp_path / "a.npz").exists()


def test_console_script_runs_as_a_process(tmp_path, samples):
    """The installed entry point, in a fresh interpreter: exit codes and stderr."""
    p = subprocess.run(
        [
            sys.executable,
            "-c",
            "import sys; from segadeform.cli.main import main; sys.exit(main())",
            "precompute",
            str(tmp_path / "nope.obj"),
            "--joints",
            str(samples / "skeletons" / "tpose_joints_24.npy"),
            "-o",
            str(tmp_path / "a.npz"),
        ],
        capture_output=True,
        text=True,
    )
    assert p.returncode == 1
    assert p.stderr.startswith("Error: ") and "nope.obj" in p.stderr and "Traceback" not in p.stderr


def test_main_returns_status():
    assert main(["--version"]) == 0


def test_an_asset_is_written_only_under_its_own_suffixes(tmp_path):
    """``precompute`` and ``garment export`` wrote an .npz archive under any name (``-o skirt.obj``, ``-o out``): now
    a name other than .npz / .sgda is one line naming it, exit 1, before any work, and nothing is written."""
    body = SAMPLES / "bodies" / "default_body.npz"
    garment = SAMPLES / "garments" / "skirt.obj"
    for args in (
        ["precompute", str(garment), "--body", str(body), "-o"],
        ["garment", "export", str(garment), "-o"],
    ):
        for name in ("skirt.obj", "asset", "asset.npz.txt"):
            out = tmp_path / name
            r = CliRunner().invoke(cli, [*args, str(out)])
            assert r.exit_code == 1, r.output
            assert f"{out}: a garment asset is written as .npz or .sgda" in r.output, r.output
            assert "got " + (out.suffix or "no suffix") in r.output, r.output
            assert not out.exists()
    r = CliRunner().invoke(cli, ["precompute", str(garment), "--body", str(body), "-o", str(tmp_path / "a.NPZ")])
    assert r.exit_code == 0, r.output
    GarmentAsset.load(tmp_path / "a.NPZ")
    with pytest.raises(InputError, match=r"expected \.npz or \.sgda, got \.ply"):
        GarmentAsset.load(tmp_path / "a.NPZ").save(tmp_path / "a.ply")
    assert not (tmp_path / "a.ply").exists()
