"""`segadeform garment export --resolution R`: a garment asset whose model garment is the garment decimated to R of
its vertices, with the garment as given and the map that carries the model's frames to it (schema 3).  Python, Node
and C++ write, collide and step the cloth stage on the garment as given, and give `run --resolution R`'s frames."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from click.testing import CliRunner

from segadeform.cli.main import cli
from segadeform.errors import FileFormatError
from segadeform.geometry import GarmentAsset
from segadeform.io import read_mesh, read_pc2
from tests.runtimes.conftest import play

RTOL = 1e-5  # the parity rule of tests/runtimes/test_engines.py


def _rel(got, want) -> float:
    got, want = np.asarray(got, np.float64), np.asarray(want, np.float64)
    assert got.shape == want.shape and np.isfinite(got).all()
    return float(np.abs(got - want).max() / np.abs(want).max())


@pytest.fixture(scope="module")
def carried(portable_scene, random_package, tmp_path_factory):
    """The portable scene's dress exported at resolution 0.5, and Python's frames of it (from the asset, and from
    the mesh with `run --resolution 0.5`) for two effect sets."""
    d = tmp_path_factory.mktemp("carried")
    mesh = portable_scene["dir"] / "dress_b.obj"
    args = ["garment", "export", str(mesh), "--betas", "0.5,-0.3", "--model", str(random_package), "--resolution"]
    r = CliRunner().invoke(cli, [*args, "0.5", "-o", str(d / "half.sgda")])
    assert r.exit_code == 0, r.output
    assert "(the model's, carried to the garment's" in r.output
    out = {"asset": d / "half.sgda", "mesh": mesh, "dir": d, "frames": {}}
    run = ["run", "--model", str(random_package), "--motion", str(portable_scene["motion"]), "--no-cache", "--force"]
    for effects in ("lbs,dynamics,wrinkles,collisions", "lbs,dynamics,wrinkles,cloth"):
        key = effects.rsplit(",", 1)[1]
        r = CliRunner().invoke(
            cli, [*run, "--garment", str(out["asset"]), "--effects", effects, "-o", str(d / f"a-{key}.pc2")]
        )
        assert r.exit_code == 0, r.output
        assert "the model ran on" in r.output and "carried to all" in r.output
        out["frames"][effects] = read_pc2(d / f"a-{key}.pc2").frames
    return out


def test_the_asset_holds_the_decimated_garment_and_the_garment_as_given(carried):
    a = GarmentAsset.load(carried["asset"])
    full = read_mesh(carried["mesh"])
    assert a.carried and a.schema_version == 3
    assert a.n_vertices == int(round(0.5 * len(full.vertices)))
    np.testing.assert_array_equal(a.out_vertices, full.vertices)
    np.testing.assert_array_equal(a.out_faces, full.faces)
    # the map puts the given garment back where it is on the model's garment at rest: most vertices exactly, those
    # whose closest point is on a triangle's edge to within millimetres (they keep only their offset along the
    # normal: 1.2 mm at most on the sample dress, as `run --resolution` carries them)
    tri = a.vertices[a.faces[a.carry_face]]
    n = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    n /= np.linalg.norm(n, axis=1, keepdims=True)
    back = np.einsum("pk,pkd->pd", a.carry_bary, tri) + a.carry_offset[:, None] * n
    d = np.linalg.norm(back - full.vertices, axis=1)
    assert np.median(d) < 1e-9 and d.max() < 3e-3, (np.median(d), d.max())
    # both forms round-trip exactly
    for suffix in (".npz", ".sgda"):
        p = carried["dir"] / f"again{suffix}"
        a.save(p)
        b = GarmentAsset.load(p)
        for k in ("vertices", "out_vertices", "out_faces", "carry_face", "carry_bary", "carry_offset"):
            np.testing.assert_array_equal(getattr(b, k), getattr(a, k))


def test_python_plays_the_asset_as_run_resolution_plays_the_mesh(carried, portable_scene, random_package):
    d = carried["dir"]
    run = ["run", "--model", str(random_package), "--motion", str(portable_scene["motion"]), "--no-cache", "--force"]
    effects = "lbs,dynamics,wrinkles,collisions"
    r = CliRunner().invoke(
        cli,
        [*run, "--garment", str(carried["mesh"]), "--betas", "0.5,-0.3", "--resolution", "0.5"]
        + ["--effects", effects, "-o", str(d / "m.pc2")],
    )
    assert r.exit_code == 0, r.output
    np.testing.assert_array_equal(read_pc2(d / "m.pc2").frames, carried["frames"][effects])
    # a carried asset is one resolution: --resolution on it is refused, as on any asset
    r = CliRunner().invoke(
        cli, [*run, "--garment", str(carried["asset"]), "--resolution", "0.5", "-o", str(d / "x.pc2")]
    )
    assert r.exit_code == 1 and "a garment asset is one resolution" in r.output and not (d / "x.pc2").exists()


@pytest.mark.parametrize("runtime", ["node", "cpp"])
@pytest.mark.parametrize("effects", ["lbs,dynamics,wrinkles,collisions", "lbs,dynamics,wrinkles,cloth"])
def test_runtime_plays_a_carried_asset_like_segadeform_run(
    runtime, effects, request, carried, portable_scene, random_package, tmp_path
):
    exe = request.getfixturevalue(runtime)
    out = tmp_path / "g.pc2"
    p = play(exe, random_package, carried["asset"], portable_scene["motion"], out, "--effects", effects)
    assert p.returncode == 0, p.stdout + p.stderr
    got = read_pc2(out).frames
    assert got.shape[1] == len(read_mesh(carried["mesh"]).vertices)  # every vertex of the garment as given
    assert _rel(got, carried["frames"][effects]) <= RTOL


@pytest.mark.parametrize("runtime", ["python", "node", "cpp"])
@pytest.mark.parametrize(
    "edit, says",
    [
        (lambda a: dataclasses.replace(a, carry_offset=None), "carry"),
        (lambda a: dataclasses.replace(a, carry_face=a.carry_face + len(a.faces)), "carry_face"),
        (lambda a: dataclasses.replace(a, out_faces=a.out_faces + len(a.out_vertices)), "out_faces"),
    ],
)
def test_a_broken_carry_is_refused_naming_the_file(
    runtime, edit, says, request, carried, portable_scene, random_package, tmp_path
):
    """Python refuses to write such an asset; one written anyway (the container alone) is refused when read, by every
    runtime, naming the file and the field, with nothing written."""
    from segadeform.io.garment_asset import _CARRY_PORTABLE, _NP_OF, _PORTABLE, ASSET_KIND
    from segadeform.io.sgdb import read_bundle, write_bundle

    a = GarmentAsset.load(carried["asset"])
    bad = edit(a)
    with pytest.raises(Exception, match=says):
        bad.save(tmp_path / "refused.sgda")
    assert not (tmp_path / "refused.sgda").exists()
    arrays, meta = read_bundle(carried["asset"])
    for k, dt in _CARRY_PORTABLE.items():
        v = getattr(bad, k)
        if v is None:
            arrays.pop(k)
        else:
            arrays[k] = np.asarray(v).astype(_NP_OF[dt])
    assert meta["kind"] == ASSET_KIND and set(_PORTABLE) <= set(arrays)
    path = tmp_path / "bad.sgda"
    write_bundle(path, arrays, meta)
    out = tmp_path / "x.pc2"
    if runtime == "python":
        with pytest.raises(FileFormatError, match=says) as e:
            GarmentAsset.load(path)
        assert str(path) in str(e.value)
        return
    exe = request.getfixturevalue(runtime)
    p = play(exe, random_package, path, portable_scene["motion"], out)
    assert p.returncode == 1 and says in p.stderr and str(path) in p.stderr, p.stdout + p.stderr
    assert len(p.stderr.strip().splitlines()) == 1 and not out.exists()


def test_an_asset_exported_again_keeps_its_garment_as_given(carried, random_package, caplog):
    """Exported again (another shape, the same here): the garment as given is what is checked and said (a review: the
    decimated copy was, and the seams it said were the copy's), and the map is kept."""
    a = GarmentAsset.load(carried["asset"])
    out = carried["dir"] / "reexported.sgda"
    args = ["garment", "export", str(carried["asset"]), "--betas", "0.5,-0.3", "--model", str(random_package)]
    r = CliRunner().invoke(cli, [*args, "-o", str(out)])
    assert r.exit_code == 0, r.output
    assert f"(the model's, carried to the garment's {len(a.out_vertices)})" in r.output
    b = GarmentAsset.load(out)
    for k in ("vertices", "out_vertices", "out_faces", "carry_face", "carry_bary", "carry_offset"):
        np.testing.assert_array_equal(getattr(b, k), getattr(a, k))
    assert "carried to the garment's" in repr(b)


def test_an_npz_asset_of_schema_3_without_its_map_is_refused(carried, tmp_path):
    a = GarmentAsset.load(carried["asset"])
    a.save(tmp_path / "a.npz")
    with np.load(tmp_path / "a.npz", allow_pickle=False) as z:
        kept = {k: z[k] for k in z.files if k != "carry_offset"}
    np.savez(tmp_path / "b.npz", **kept)
    with pytest.raises(FileFormatError, match="lacks fields.*carry_offset"):
        GarmentAsset.load(tmp_path / "b.npz")


def test_a_decimated_model_garment_is_not_bundled(carried, portable_scene, random_package, tmp_path):
    """A bundle holds the garment the model runs on: a carried asset or a scene's resolution below 1 was bundled at
    the model's resolution, its point cache fitting no import of the garment (a review); now refused."""
    for garment, extra, says in (
        (carried["asset"], "", "model garment is decimated"),
        (carried["mesh"], "[model]\nresolution = 0.5\n", "resolution below 1 is not bundled"),
    ):
        scene = tmp_path / "s.toml"
        scene.write_text(
            f'[garment]\nmesh = "{garment}"\n[motion]\nfile = "{portable_scene["motion"]}"\n[body]\n'
            f'betas = [0.5, -0.3]\n{extra}[output]\npath = "{tmp_path / "o.pc2"}"\n'
        )
        r = CliRunner().invoke(
            cli, ["bundle", str(scene), "--model", str(random_package), "--force", "-o", str(tmp_path / "b.sgdb")]
        )
        assert r.exit_code == 1 and says in r.output, r.output
        assert not (tmp_path / "b.sgdb").exists()
