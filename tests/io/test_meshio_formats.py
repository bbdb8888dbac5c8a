import meshio
import numpy as np
import pytest

from segadeform.errors import FileFormatError, InputError
from segadeform.io import Mesh, read_mesh, write_mesh


def quad_mesh():
    v = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0], [2, 0, 0], [2, 1, 0.5]], float)
    return v, np.array([[0, 1, 2, 3], [1, 4, 5, 2]])


@pytest.mark.parametrize("ext", [".ply", ".off", ".vtk"])
def test_quads_triangulated_and_order_kept(tmp_path, ext):
    v, q = quad_mesh()
    p = tmp_path / f"q{ext}"
    if ext == ".off":  # meshio's OFF writer drops quads; write the file by hand
        p.write_text(
            "OFF\n6 2 0\n"
            + "".join(f"{a} {b} {c}\n" for a, b, c in v)
            + "".join("4 " + " ".join(map(str, r)) + "\n" for r in q)
        )
    else:
        meshio.write_points_cells(p, v, [("quad", q)])
    m = read_mesh(p)
    np.testing.assert_allclose(m.vertices, v)
    np.testing.assert_array_equal(m.faces, [[0, 1, 2], [0, 2, 3], [1, 4, 5], [1, 5, 2]])


def test_write_then_read_ply(tmp_path):
    v, q = quad_mesh()
    f = np.array([[0, 1, 2], [0, 2, 3]])
    write_mesh(tmp_path / "t.ply", Mesh(vertices=v, faces=f))
    m = read_mesh(tmp_path / "t.ply")
    np.testing.assert_allclose(m.vertices, v)
    np.testing.assert_array_equal(m.faces, f)


def test_unknown_extension_and_garbage(tmp_path):
    with pytest.raises(InputError, match="unknown mesh file extension"):
        read_mesh(tmp_path / "a.xyz")
    p = tmp_path / "g.ply"
    p.write_bytes(b"ply\nformat nonsense\n")
    with pytest.raises(FileFormatError, match="cannot parse mesh") as ei:
        read_mesh(p)
    assert str(p) in str(ei.value)


@pytest.mark.parametrize(
    "text, words",
    [
        ("OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 3\n", "out of range"),
        ("OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n2 0 1\n", "at least 3"),
        ("OFF\n3 2 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n", "truncated"),
        ("OFF\n3 1 0\n0 0 0\n1 nan 0\n0 1 0\n3 0 1 2\n", "not finite"),
        ("PLY\n", "not an OFF file"),
        ("OFF\nx y\n", "counts"),
        ("OFF\n0 0 0\n", "empty"),
    ],
)
def test_malformed_off(tmp_path, text, words):
    p = tmp_path / "m.off"
    p.write_text(text)
    with pytest.raises(FileFormatError, match=words) as ei:
        read_mesh(p)
    assert str(p) in str(ei.value)


def test_off_counts_on_header_line_and_comments(tmp_path):
    p = tmp_path / "m.off"
    p.write_text("OFF 4 1 0 # counts here\n0 0 0\n1 0 0\n1 1 0\n0 1 0\n4 0 1 2 3 255 0 0\n")
    m = read_mesh(p)
    np.testing.assert_array_equal(m.faces, [[0, 1, 2], [0, 2, 3]])
