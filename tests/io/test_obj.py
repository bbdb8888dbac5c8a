import numpy as np
import pytest

from segadeform.errors import FileFormatError, InputError
from segadeform.geometry.primitives import frustum
from segadeform.io import Mesh, read_mesh, read_obj, write_obj
from segadeform.io.mesh import validate_mesh_arrays
from tests.conftest import leftovers


def write(tmp_path, text, name="m.obj"):
    p = tmp_path / name
    p.write_text(text)
    return p


def test_sample_skirt_keeps_vertex_order_and_count(samples):
    m = read_obj(samples / "garments" / "skirt.obj")
    v, _ = frustum(64, 24, 0.16, 0.34, 1.02, 0.50)
    assert m.n_vertices == 64 * 24
    np.testing.assert_allclose(m.vertices, v, atol=1e-6)
    assert m.n_faces == 2 * 64 * 23  # quads triangulated
    # faces written with absolute and with relative indices describe the same grid
    assert m.faces.min() == 0 and m.faces.max() == m.n_vertices - 1


def test_sample_garments_name_no_missing_file(samples):
    """A Blender user's trial: skirt.obj named `mtllib skirt.mtl`, a file that is not there (Blender's OBJ importer
    logs an error on every import).  No sample OBJ names a material library it does not ship."""
    for obj in sorted((samples / "garments").rglob("*.obj")):
        for line in obj.read_text(encoding="utf-8").splitlines():
            if line.startswith("mtllib "):
                assert (obj.parent / line.split(maxsplit=1)[1]).is_file(), (obj, line)


def test_meshio_cannot_read_the_sample_but_we_can(samples):
    import meshio

    with pytest.raises(ValueError):
        meshio.read(samples / "garments" / "skirt.obj")
    assert read_mesh(samples / "garments" / "skirt.obj").n_vertices == 1536


def test_negative_indices_equal_positive(tmp_path):
    pos = "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nf 1 2 3 4\n"
    neg = "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nf -4 -3 -2 -1\n"
    a, b = read_obj(write(tmp_path, pos, "a.obj")), read_obj(write(tmp_path, neg, "b.obj"))
    np.testing.assert_array_equal(a.faces, b.faces)
    np.testing.assert_array_equal(a.faces, [[0, 1, 2], [0, 2, 3]])


def test_relative_index_is_relative_to_the_line(tmp_path):
    text = "v 0 0 0\nv 1 0 0\nv 0 1 0\nf -3 -2 -1\nv 5 5 5\nv 6 5 5\nv 5 6 5\nf -3 -2 -1\n"
    m = read_obj(write(tmp_path, text))
    np.testing.assert_array_equal(m.faces, [[0, 1, 2], [3, 4, 5]])


def test_all_corner_forms_groups_comments_and_continuations(tmp_path):
    text = """# comment
mtllib x.mtl
o thing
v 0 0 0
v 1 0 0
v 1 1 0
v 0 1 \\
  0
v 2 2 0
vt 0 0
vt 1 0
vn 0 0 1
g front
usemtl red
s off
f 1/1/1 2/2/1 3//1
f 1//1 3/1 4
l 1 2
p 5
"""
    m = read_obj(write(tmp_path, text))
    assert m.n_vertices == 5  # unused vertex 5 is kept
    np.testing.assert_array_equal(m.faces, [[0, 1, 2], [0, 2, 3]])


def test_vertex_colours_and_ngon_triangulation(tmp_path):
    text = "".join(
        f"v {np.cos(a):.6f} {np.sin(a):.6f} 0 0.5 0.25 1\n" for a in np.linspace(0, 2 * np.pi, 6, endpoint=False)
    )
    text += "f 1 2 3 4 5 6\n"
    m = read_obj(write(tmp_path, text))
    assert m.colors.shape == (6, 3)
    np.testing.assert_allclose(m.colors[0], [0.5, 0.25, 1])
    np.testing.assert_array_equal(m.faces, [[0, 1, 2], [0, 2, 3], [0, 3, 4], [0, 4, 5]])
    np.testing.assert_array_equal(m.face_origin, [0, 0, 0, 0])


def test_homogeneous_w_divides(tmp_path):
    m = read_obj(write(tmp_path, "v 2 4 6 2\nv 1 0 0\nv 0 1 0\nf 1 2 3\n"))
    np.testing.assert_allclose(m.vertices[0], [1, 2, 3])


@pytest.mark.parametrize(
    "text, line, words",
    [
        ("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 4\n", 4, "out of range"),
        ("v 0 0 0\nv 1 0 0\nv 0 1 0\nf -1 -2 -4\n", 4, "out of range"),
        ("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 0 1 2\n", 4, "index 0"),
        ("v 0 0 0\nv 1 0 0\nf 1 2\n", 3, "fewer than 3"),
        ("v 0 0 0\nv nan 0 0\nv 0 1 0\nf 1 2 3\n", 2, "not finite"),
        ("v 0 0 0\nv inf 0 0\nv 0 1 0\nf 1 2 3\n", 2, "not finite"),
        ("v 0 0 0\nv 0 1e30 0\nv 0 1 0\nf 1 2 3\n", 2, "beyond 10 km"),  # garment fit wrote it, run named no file
        ("v 0 0 0\nv 0 0 -10000.5\nv 0 1 0\nf 1 2 3\n", 2, "beyond 10 km"),
        ("v 0 0 0\nv 1 0 x\nv 0 1 0\nf 1 2 3\n", 2, "non-numeric"),
        ("v 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n", 1, "x y z"),
        ("v 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\nf 1/2 2/1 3/1\n", 5, "texture coordinate index out of range"),
        ("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1//1 2//1 3//1\n", 4, "normal index out of range"),
        ("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 a\n", 4, "bad vertex index"),
        ("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1/1/1/1 2 3\n", 4, "bad face corner"),
        ("v 0 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n", 1, "weight"),
    ],
)
def test_malformed_obj_names_file_and_line(tmp_path, text, line, words):
    p = write(tmp_path, text)
    with pytest.raises(FileFormatError) as ei:
        read_obj(p)
    msg = str(ei.value)
    assert msg.startswith(f"{p}:{line}: "), msg
    assert words in msg


@pytest.mark.parametrize(
    "text, words",
    [
        ("", "no vertices"),
        ("# only a comment\n", "no vertices"),
        ("v 0 0 0\nv 1 0 0\n", "no faces"),
        ("\x00\x01binary", "NUL"),
    ],
)
def test_empty_or_binary_obj(tmp_path, text, words):
    p = write(tmp_path, text)
    with pytest.raises(FileFormatError, match=words):
        read_obj(p)


def test_missing_file_is_a_clear_error(tmp_path):
    """One wording for a missing file, whatever reads it."""
    from segadeform.body import load_body
    from segadeform.io import read_mesh, read_off, read_pc2
    from segadeform.io.mhclo import read_mhclo
    from segadeform.motion import load_motion
    from segadeform.settings import load_scene

    for reader, name in (
        (read_obj, "nope.obj"),
        (read_off, "nope.off"),
        (read_pc2, "nope.pc2"),
        (read_mesh, "nope.ply"),
        (load_motion, "nope.bvh"),
        (load_motion, "nope.npz"),
        (load_body, "nope.npz"),
        (load_scene, "nope.toml"),
        (read_mhclo, "nope.mhclo"),
    ):
        with pytest.raises(FileFormatError, match=r"nope\.\w+: no such file$"):
            reader(tmp_path / name)
    (tmp_path / "d.obj").mkdir()
    with pytest.raises(FileFormatError, match="is a directory"):
        read_obj(tmp_path / "d.obj")


def test_write_read_round_trip(tmp_path):
    rng = np.random.default_rng(0)
    v = rng.normal(size=(50, 3)) * 1000.0  # kilometre-scale values keep 9 significant digits
    f = rng.integers(0, 50, size=(80, 3))
    write_obj(tmp_path / "r.obj", Mesh(vertices=v, faces=f))
    m = read_obj(tmp_path / "r.obj")
    np.testing.assert_allclose(m.vertices, v, rtol=1e-8)
    np.testing.assert_array_equal(m.faces, f)


def test_failed_write_leaves_nothing(tmp_path):
    bad = np.array([[0.0, 0.0, np.nan], [1, 0, 0], [0, 1, 0]])
    with pytest.raises(InputError, match="non-finite"):
        write_obj(tmp_path / "x.obj", Mesh(vertices=bad, faces=np.array([[0, 1, 2]])))
    assert not (tmp_path / "x.obj").exists()
    assert leftovers(tmp_path) == []


def test_a_file_cut_short_is_refused_naming_its_last_line(tmp_path, samples):
    """A user's trial: an OBJ cut at 90 % of its bytes (a copy that stopped) ran with a tenth of its faces gone, exit
    0.  A file that ends in an element line with no line break is refused when that line looks cut -- it ends in
    whitespace or '/', it is a face with another corner count than the one before, or it does not parse (the error
    then says so); whole files that end unbroken are read (pytorch3d's save_obj writes its last face so)."""
    whole = (samples / "garments" / "skirt.obj").read_text()
    for cut in (0.9, 0.999, 0.5):
        text = whole[: int(cut * len(whole))]
        p = write(tmp_path, text, f"cut{cut}.obj")
        with pytest.raises(FileFormatError, match=r"cut short") as ei:
            read_mesh(p)
        assert f"{text.count(chr(10)) + 1}" in str(ei.value) and "\n" not in str(ei.value)
    assert read_obj(write(tmp_path, whole, "whole.obj")).n_faces == 2 * 64 * 23
    tri = "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nf 1 2 3\nf 1 3 4"  # as pytorch3d writes it
    assert read_obj(write(tmp_path, tri, "p3d.obj")).n_faces == 2
    for tail in ("\n", "\n# end", "\ng skirt", "\r\n"):
        assert read_obj(write(tmp_path, tri + tail, "t.obj")).n_faces == 2
    quads = "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nv 2 0 0\nv 2 1 0\nf 1 2 3 4\nf 2 5 6 3"
    assert read_obj(write(tmp_path, quads, "q.obj")).n_faces == 4
    for bad, why in (
        (quads[:-2], "'f' line"),
        (tri + " ", "'f' line"),
        (tri + "\nv 0 1", "needs x y z"),
        (tri[:-2] + "/", "'f'"),
    ):
        with pytest.raises(FileFormatError, match=why) as ei:
            read_obj(write(tmp_path, bad, "b.obj"))
        assert "cut short" in str(ei.value), bad


def test_a_file_cut_inside_a_face_corner_is_refused(tmp_path, samples):
    """A user's trial: a garment cut in its faces inside a number ('... 1232/691 17', or '... 1794/6' where the whole
    line is '... 1794/692') read as a whole garment with a third of its triangles, exit 0.  Refused: corners in mixed
    forms on the last, unbroken line, or vertices in no face with the file ending unbroken on a face line.  The same
    mesh with a line break at the end, or whole, is read."""
    uv = "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nv 2 0 0\nvt 0 0\nvt 1 0\nvt 1 1\n"
    for bad, why in (
        (uv + "f 1/1 2/2 3/3\nf 1/1 3/3 4", "'f' line"),  # the last corner lost its '/vt'
        (uv + "f 1/1 2/2 3/3\nf 1/1 3/3 4/2", "1 of its 5 vertices are in no face"),  # 'f 1/1 3/3 4/2 5/1' cut
    ):
        with pytest.raises(FileFormatError, match=why) as ei:
            read_obj(write(tmp_path, bad, "b.obj"))
        assert "cut short" in str(ei.value) and "\n" not in str(ei.value), bad
        assert read_obj(write(tmp_path, bad + "\n", "ok.obj")).n_faces == 2  # a line break: whole, as it says
    whole = (samples / "garments" / "skirt.obj").read_text().rstrip("\n")
    assert read_obj(write(tmp_path, whole, "whole.obj")).n_faces == 2 * 64 * 23
    # a loose vertex is no sign of a cut when the last line is not a face (a review: 'vn' and 'l' last were refused)
    for tail in ("vn 0 0 1", "l 3 4"):
        assert read_obj(write(tmp_path, uv + "f 1/1 2/2 3/3\n" + tail, "loose.obj")).n_faces == 1


def test_mesh_arrays_beyond_10_km_are_refused_by_vertex():
    """Every mesh reader's check (validate_mesh_arrays): a vertex further than 10 km (segadeform.bounds.MAX_POSITION)
    is another unit; one at exactly 10 km is kept."""
    v = np.array([[0.0, 0.0, 0.0], [1e4, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, -2e4, 0.0]])
    with pytest.raises(InputError, match=r"vertex 3 lies beyond 10 km"):
        validate_mesh_arrays(v, np.array([[0, 1, 2], [0, 2, 3]]), path="m.ply", bounded=True)
    validate_mesh_arrays(v[:3], np.array([[0, 1, 2]]), bounded=True)
    validate_mesh_arrays(v, np.array([[0, 1, 2], [0, 2, 3]]))  # a writer's: a run's frames are its own
