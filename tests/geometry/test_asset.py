import dataclasses

import numpy as np
import pytest

from segadeform.errors import FileFormatError, InputError
from segadeform.geometry import GarmentAsset, precompute_garment, vertex_features
from segadeform.geometry.primitives import frustum
from segadeform.io.garment_asset import ASSET_SCHEMA_VERSION
from tests.conftest import leftovers


@pytest.fixture
def asset(rest_joints):
    v, f = frustum(20, 8, 0.16, 0.3, 1.0, 0.6)
    return precompute_garment(v, f, rest_joints, n_star=16)


def test_features_are_position_normal_joint_distance(rest_joints):
    v, f = frustum(10, 4, 0.2, 0.3, 1.0, 0.6)
    x = vertex_features(v, f, rest_joints)
    assert x.shape == (40, 30) and x.dtype == np.float32
    np.testing.assert_allclose(x[:, :3], v, atol=1e-6)
    np.testing.assert_allclose(np.linalg.norm(x[:, 3:6], axis=1), 1, atol=1e-5)
    np.testing.assert_allclose(x[7, 6 + 4], np.linalg.norm(v[7] - rest_joints[4]), rtol=1e-6)


def test_round_trip(tmp_path, asset):
    asset.save(tmp_path / "a.npz")
    b = GarmentAsset.load(tmp_path / "a.npz")
    for fld in dataclasses.fields(GarmentAsset):
        x, y = getattr(asset, fld.name), getattr(b, fld.name)
        if isinstance(x, np.ndarray):
            np.testing.assert_array_equal(x, y)
            assert x.dtype == y.dtype
        else:
            assert x == y
    assert leftovers(tmp_path) == []


def test_portable_round_trip_is_exact(tmp_path, asset):
    """The portable form (.sgda, the bundle container: read by the Node and C++ runtimes' bundle readers)."""
    from segadeform.io.sgdb import read_bundle, write_bundle

    asset.save(tmp_path / "a.sgda")
    b = GarmentAsset.load(tmp_path / "a.sgda")
    for fld in dataclasses.fields(GarmentAsset):
        x, y = getattr(asset, fld.name), getattr(b, fld.name)
        if isinstance(x, np.ndarray):
            np.testing.assert_array_equal(x, y)
            assert x.dtype == y.dtype
        else:
            assert x == y
    arrays, meta = read_bundle(tmp_path / "a.sgda")  # what a runtime without Python sees
    assert meta["kind"] == "segadeform-garment-asset" and meta["schema_version"] == ASSET_SCHEMA_VERSION
    assert {k: a.dtype.str for k, a in arrays.items()} == {
        "vertices": "<f8",
        "faces": "<i4",
        "normals": "<f4",
        "features": "<f4",
        "nbr": "<i4",
        "mask": "|u1",
        "joints": "<f8",
        "descriptor": "<f8",
        "fps_samples": "<i4",
    }
    write_bundle(tmp_path / "x.sgda", dict(arrays, nbr=arrays["nbr"] + 10**6), meta)
    with pytest.raises(FileFormatError, match="x.sgda: asset field 'nbr' has an index out of range"):
        GarmentAsset.load(tmp_path / "x.sgda")
    write_bundle(tmp_path / "k.sgda", arrays, dict(meta, kind="scene-bundle"))
    with pytest.raises(FileFormatError, match="not a garment asset"):
        GarmentAsset.load(tmp_path / "k.sgda")
    write_bundle(tmp_path / "d.sgda", dict(arrays, faces=arrays["faces"].astype(np.int64)), meta)
    with pytest.raises(FileFormatError, match="'faces' is missing or has the wrong dtype"):
        GarmentAsset.load(tmp_path / "d.sgda")


def corrupt(tmp_path, asset, **changes):
    z = dict(np.load(tmp_path / "a.npz", allow_pickle=False)) if (tmp_path / "a.npz").exists() else None
    if z is None:
        asset.save(tmp_path / "a.npz")
        z = dict(np.load(tmp_path / "a.npz", allow_pickle=False))
    for k, val in changes.items():
        if val is None:
            z.pop(k)
        else:
            z[k] = val
    p = tmp_path / "bad.npz"
    np.savez(p, **z)
    return p


@pytest.mark.parametrize(
    "changes, words",
    [
        (dict(schema_version=np.int64(99)), "schema version"),
        (dict(nbr=None), "missing fields"),
        (dict(faces=np.array([[0, 1, 999]])), "out of range"),
        (dict(features=np.zeros((3, 30), np.float32)), "wrong shape"),
        (dict(mask=np.zeros((1, 1), np.int8)), "wrong type"),
        (dict(descriptor=np.full(16, np.nan)), "NaN"),
        (dict(geodesic_radius=np.float64(0.0)), "positive"),
    ],
)
def test_load_rejects_corrupt_assets(tmp_path, asset, changes, words):
    p = corrupt(tmp_path, asset, **changes)
    with pytest.raises(FileFormatError, match=words) as ei:
        GarmentAsset.load(p)
    assert str(p) in str(ei.value)


def test_load_rejects_non_npz_and_pickles(tmp_path):
    p = tmp_path / "x.npz"
    p.write_bytes(b"not a zip")
    with pytest.raises(FileFormatError, match="not a readable"):
        GarmentAsset.load(p)
    np.savez(tmp_path / "o.npz", **{"vertices": np.array([object()], dtype=object)})
    with pytest.raises(FileFormatError):
        GarmentAsset.load(tmp_path / "o.npz")
    # a .sgda that is an empty file or a web page (a server's 404 saved): said so, not as a bad zip (a web developer's
    # trial got "not a readable garment asset .npz file (BadZipFile ...)")
    for body, got in ((b"", "got an empty file"), (b"<html>404</html>", "got b'<html>404</html>'")):
        (tmp_path / "g.sgda").write_bytes(body)
        with pytest.raises(FileFormatError, match="not a garment asset") as e:
            GarmentAsset.load(tmp_path / "g.sgda")
        assert got in str(e.value) and "segadeform garment export" in str(e.value) and "zip" not in str(e.value)


def test_precompute_validates_inputs(rest_joints):
    v, f = frustum(10, 4, 0.2, 0.3, 1.0, 0.6)
    with pytest.raises(InputError, match="joints"):
        precompute_garment(v, f, rest_joints[:, :2])
    with pytest.raises(InputError, match="NaN"):
        precompute_garment(np.where(np.arange(40)[:, None] == 3, np.nan, v), f, rest_joints)


def _quad_at_an_opening(f, loops):
    """Two faces of ``f`` that make a quad with an edge on an opening: its corners in order, diagonal 0-2."""
    ring = {frozenset(e) for lp in loops for e in zip(lp.tolist(), np.roll(lp, -1).tolist(), strict=True)}
    for i, x in enumerate(f.tolist()):
        for j, y in enumerate(f.tolist()):
            shared = set(x) & set(y)
            if j <= i or len(shared) != 2:
                continue
            (p1,), (p3,) = set(x) - shared, set(y) - shared
            k = x.index(p1)
            p0, p2 = x[(k + 2) % 3], x[(k + 1) % 3]  # x = p1, p2, p0 in order: the quad p0, p1, p2, p3
            if any(frozenset(e) in ring for e in ((p0, p1), (p1, p2), (p2, p3), (p3, p0))):
                return p0, p1, p2, p3
    raise AssertionError("no quad at an opening")


@pytest.mark.parametrize("reversed_", [True, False])
def test_a_quad_repeated_with_the_other_diagonal_leaves_the_garments_shape_and_openings_as_they_were(
    rest_joints, reversed_
):
    """A quad at an opening given twice, the copy triangulated along the other diagonal (reversed or not): no face
    of the copy repeats an earlier face's corners, so it was surface and closed the opening's edge -- the openings
    changed (a user's trial: their count too).  Now the copy is no surface: the openings, descriptor and features are
    the clean mesh's.  A closed tetrahedron, whose faces also pair up over the same four corners, keeps every face."""
    from segadeform.geometry.mesh_ops import boundary_loops, surface_faces

    v, f = frustum(20, 8, 0.16, 0.3, 1.0, 0.6)
    loops = boundary_loops(f, len(v))
    p0, p1, p2, p3 = _quad_at_an_opening(f, loops)
    copy = [[p1, p2, p3], [p1, p3, p0]]  # the other diagonal
    if reversed_:
        copy = [c[::-1] for c in copy]
    bad = np.concatenate([f, copy])

    def edges(faces):  # the openings' edges: in one face
        e, n = np.unique(np.sort(faces[:, [0, 1, 1, 2, 2, 0]].reshape(-1, 2), axis=1), axis=0, return_counts=True)
        return e[n == 1].tolist()

    assert len(edges(bad)) < len(edges(f))  # what they were before: the quad's edge on the opening closed
    np.testing.assert_array_equal(surface_faces(v, bad), f)
    assert edges(surface_faces(v, bad)) == edges(f)
    assert len(boundary_loops(surface_faces(v, bad), len(v))) == len(loops)
    clean = precompute_garment(v, f, rest_joints, n_star=16)
    got = precompute_garment(v, bad, rest_joints, n_star=16)
    np.testing.assert_allclose(got.descriptor, clean.descriptor, rtol=1e-9, atol=1e-12)
    np.testing.assert_allclose(got.features, clean.features)
    tet = np.array([[0.0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]])
    tf = np.array([[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]])
    np.testing.assert_array_equal(surface_faces(tet, tf), tf)
    # a flat tetrahedron of its own (a bead, a button) keeps its faces too: its pairs pass the flatness test up to a
    # fold of 74 degrees, and it shares no edge with the rest (a review found z <= 1.5 stripped of two faces)
    for z in (0.0, 0.5, 1.0, 1.5):
        flat = np.array([[0.0, 0, 0], [1, 0, 0], [1, 1, z], [0, 1, 0]])
        ff = np.array([[0, 1, 2], [0, 2, 3], [1, 0, 3], [1, 3, 2]])
        np.testing.assert_array_equal(surface_faces(flat, ff), ff)
        beside = np.concatenate([v, flat + 5.0]), np.concatenate([f, ff + len(v)])  # beside a garment, too
        assert len(surface_faces(*beside)) == len(f) + 4
    # `segadeform inspect` counts the copy as duplicated faces (it counted nothing once the copy was no surface)
    from segadeform.geometry.mesh_ops import mesh_defects

    assert mesh_defects(v, bad)["duplicated"] == 2 and mesh_defects(v, f)["duplicated"] == 0


def test_flat_broken_and_repeated_faces_leave_the_garments_shape_as_it_was(rest_joints):
    """A face whose corners are collinear (on an existing edge), a face with a repeated corner and a repeated or
    reversed copy of a face add no surface: the asset's normals, features and descriptor are those of the mesh
    without them, and so is its count of openings (one flat face moved a user's descriptor 0.156, 3x the
    training garments' threshold, and a false "lies outside" warning followed).  The asset keeps the faces it was
    given (outputs are written with them)."""
    from segadeform.geometry.mesh_ops import FLAT, boundary_loops, surface_faces

    v, f = frustum(20, 8, 0.16, 0.3, 1.0, 0.6)
    clean = precompute_garment(v, f, rest_joints, n_star=16)
    a, b = f[5, 0], f[5, 1]
    mid = len(v)
    v2 = np.concatenate([v, 0.5 * (v[a] + v[b])[None]])  # a vertex on the edge a-b, in a flat face a, b, mid
    bad = np.concatenate([f, [[a, b, mid], [a, a, b], f[7], f[9, ::-1]]])
    got = precompute_garment(v2, bad, rest_joints, n_star=16)
    assert got.faces.shape == (len(f) + 4, 3)  # kept as given
    assert got.params["n_components"] == clean.params["n_components"] == 1  # the flat face's vertex is no piece
    np.testing.assert_array_equal(surface_faces(v2, bad), f)
    np.testing.assert_allclose(got.descriptor, clean.descriptor, rtol=1e-9, atol=1e-12)
    np.testing.assert_allclose(got.features[: len(v)], clean.features)
    # the graph is every face's: the flat face's vertex keeps its neighbours, the rest is the clean mesh's
    assert got.mask[mid].any()
    rows = np.setdiff1d(np.arange(len(v)), [a, b])
    np.testing.assert_array_equal(got.nbr[rows][got.mask[rows]], clean.nbr[rows][clean.mask[rows]])
    assert len(boundary_loops(surface_faces(v2, bad), len(v2))) == len(boundary_loops(f, len(v)))
    assert len(boundary_loops(bad, len(v2))) != len(boundary_loops(f, len(v)))  # what the count was before
    # a needle is surface, however thin; only collinear corners are flat
    needle = np.array([[0.0, 0, 0], [1.0, 0, 0], [0.5, 1e-6, 0]])
    assert len(surface_faces(needle, np.array([[0, 1, 2]]))) == 1
    assert len(surface_faces(needle * [1, FLAT / 10, 1], np.array([[0, 1, 2]]))) == 0
    with pytest.raises(InputError, match="no face with an area"):
        precompute_garment(needle * [1, 0, 1], np.array([[0, 1, 2]]), rest_joints)
