"""A textured garment comes back textured: OBJ frames, USD and Alembic keep the garment file's quads and texture
coordinates (they wrote triangles and no UVs: a new user's trial, 28 Nov 2026); point caches are unchanged."""

from __future__ import annotations

import numpy as np
import pytest
from click.testing import CliRunner

from segadeform.cli.main import cli
from segadeform.errors import FileFormatError
from segadeform.io import read_mesh, read_pc2, read_sequence
from segadeform.io.surface import Surface, fan_triangles, obj_surface

from ..conftest import SAMPLES

TSHIRT = SAMPLES / "garments" / "makehuman" / "tshirt_short_sleeve_m.mhclo"


def test_obj_surface_reads_polygons_uvs_and_relative_indices(tmp_path):
    p = tmp_path / "q.obj"
    p.write_text(
        "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nv 2 0 0\n"
        "vt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\nvt 0.5 0.5\n"
        "f 1/1 2/2 3/3 4/4\nf -4/-4 -1/-1 -3/-3\n"
    )
    s = obj_surface(p)
    np.testing.assert_array_equal(s.counts, [4, 3])
    np.testing.assert_array_equal(s.indices, [0, 1, 2, 3, 1, 4, 2])
    np.testing.assert_array_equal(s.uv_indices, [0, 1, 2, 3, 1, 4, 2])
    np.testing.assert_array_equal(s.triangles(), [[0, 1, 2], [0, 2, 3], [1, 4, 2]])
    # a corner without a texture coordinate: the surface keeps the polygons, not the UVs
    p.write_text(p.read_text().replace("-1/-1", "-1"))
    assert obj_surface(p).uvs is None and obj_surface(p).counts.tolist() == [4, 3]
    p.write_text("v 0 0 0\nv 1 0 0\nf 1 2\n")
    with pytest.raises(FileFormatError, match="3 corners or more"):
        obj_surface(p)
    p.write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 4\n")
    with pytest.raises(FileFormatError, match="out of range"):
        obj_surface(p)


def test_fan_triangles_of_mixed_polygons():
    np.testing.assert_array_equal(
        fan_triangles([3, 5], [0, 1, 2, 3, 4, 5, 6, 7]), [[0, 1, 2], [3, 4, 5], [3, 5, 6], [3, 6, 7]]
    )
    with pytest.raises(ValueError):
        Surface(counts=np.array([3, 2]), indices=np.arange(5))


@pytest.fixture(scope="module")
def textured_run(tmp_path_factory):
    """The MakeHuman T-shirt (quads, UVs) fitted and run for 3 frames into every format."""
    d = tmp_path_factory.mktemp("uv")
    r = CliRunner().invoke(cli, ["garment", "fit", str(TSHIRT), "-o", str(d / "t.obj")])
    assert r.exit_code == 0, r.output
    outs = {"pc2": d / "t.pc2", "obj-seq": d / "seq", "usd": d / "t.usda", "abc": d / "t.abc"}
    for fmt, out in outs.items():
        args = ["run", "--garment", str(d / "t.obj"), "--motion", str(SAMPLES / "motions" / "walk.npz")]
        r = CliRunner().invoke(cli, [*args, "--frames", "0:3", "--no-cache", "-o", str(out), "--format", fmt])
        assert r.exit_code == 0, r.output
    return d, outs


def test_every_format_gives_the_same_frames_and_its_own_faces(textured_run):
    d, outs = textured_run
    src = obj_surface(d / "t.obj")
    assert (src.counts == 4).all() and src.uvs is not None  # the T-shirt is textured quads
    frames = read_pc2(outs["pc2"]).frames.astype(np.float64)
    for fmt in ("obj-seq", "usd", "abc"):
        np.testing.assert_allclose(read_sequence(outs[fmt]), frames, atol=1e-6, err_msg=fmt)
    # the readers give the quads as fan triangles, as read_obj gives the garment file's
    tri = read_mesh(d / "t.obj").faces
    from segadeform.io.usd import read_usd_sequence

    np.testing.assert_array_equal(read_usd_sequence(outs["usd"])[0], tri)
    from segadeform.io.alembic import read_alembic_sequence

    np.testing.assert_array_equal(read_alembic_sequence(outs["abc"])[0], tri)


def test_obj_frames_keep_quads_and_uvs(textured_run):
    d, outs = textured_run
    src = obj_surface(d / "t.obj")
    frame = obj_surface(outs["obj-seq"] / "frame_00000.obj")
    np.testing.assert_array_equal(frame.counts, src.counts)
    np.testing.assert_array_equal(frame.indices, src.indices)
    np.testing.assert_allclose(frame.uvs[frame.uv_indices], src.uvs[src.uv_indices], atol=1e-9)


def test_usd_keeps_quads_and_its_st_primvar(textured_run):
    pytest.importorskip("pxr")
    from pxr import Usd, UsdGeom

    d, outs = textured_run
    src = obj_surface(d / "t.obj")
    stage = Usd.Stage.Open(str(outs["usd"]))  # held: the prims expire with it
    mesh = next(UsdGeom.Mesh(p) for p in stage.Traverse() if p.IsA(UsdGeom.Mesh))
    np.testing.assert_array_equal(np.asarray(mesh.GetFaceVertexCountsAttr().Get()), src.counts)
    np.testing.assert_array_equal(np.asarray(mesh.GetFaceVertexIndicesAttr().Get()), src.indices)
    st = UsdGeom.PrimvarsAPI(mesh.GetPrim()).GetPrimvar("st")
    assert st.GetInterpolation() == UsdGeom.Tokens.faceVarying
    per_corner = np.asarray(st.Get())[np.asarray(st.GetIndices())]
    np.testing.assert_allclose(per_corner, src.uvs[src.uv_indices], atol=1e-6)


def test_alembic_keeps_quads_and_face_varying_uvs(textured_run):
    Abc = pytest.importorskip("alembic3d").Abc
    from alembic3d import AbcGeom

    d, outs = textured_run
    src = obj_surface(d / "t.obj")
    schema = AbcGeom.IPolyMesh(Abc.IArchive(str(outs["abc"])).getTop(), "t").getSchema()
    s0 = schema.getValue()
    counts = np.array(memoryview(s0.getFaceCounts()))
    corners = np.array(memoryview(s0.getFaceIndices()))
    np.testing.assert_array_equal(counts, src.counts)
    # each quad stored reversed (Alembic's clockwise winding), its texture coordinates with it
    rev = np.concatenate([np.arange(4 * k, 4 * k + 4)[::-1] for k in range(len(counts))])
    np.testing.assert_array_equal(corners, src.indices[rev])
    uv = schema.getUVsParam()
    assert uv.getScope() == AbcGeom.GeometryScope.kFacevaryingScope
    vals = np.array(memoryview(uv.getExpandedValue().getVals()))
    np.testing.assert_allclose(vals, src.uvs[src.uv_indices][rev], atol=1e-6)


def test_a_garment_whose_uvs_cannot_be_read_still_runs(tmp_path):
    """The surface is read only for a format that keeps it, and an OBJ whose texture lines `read_obj` tolerates but
    the surface reader cannot use is written as triangles, not refused (a bare `vt` line failed every run)."""
    src = (SAMPLES / "garments" / "skirt.obj").read_text()
    (tmp_path / "g.obj").write_text("vt\n" + src)
    for out in ("o.pc2", "o.usda"):
        args = ["run", "--garment", str(tmp_path / "g.obj"), "--motion", str(SAMPLES / "motions" / "walk.npz")]
        r = CliRunner().invoke(cli, [*args, "--frames", "0:2", "--no-cache", "-o", str(tmp_path / out)])
        assert r.exit_code == 0, r.output


def test_a_texture_coordinate_is_a_number_as_files_write_it(tmp_path):
    """A review: `vt 0.5_5 ١` was read as (0.55, 1.0) and `vt nan 0` as a NaN UV; both are refused, naming the line."""
    for bad, words in (("vt 0.5_5 \u0661", "bad vt line"), ("vt nan 0", "not finite")):
        p = tmp_path / "uv.obj"
        p.write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\n" + bad + "\nvt 0 1\nf 1/1 2/2 3/3\n")
        with pytest.raises(FileFormatError, match=words) as e:
            obj_surface(p)
        assert e.value.line == 5
