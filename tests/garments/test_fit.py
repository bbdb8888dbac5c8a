"""Garments made for another body: MakeHuman .mhclo fits, unit/axis fixes, the off-body check, the CLI."""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

from segadeform.body import default_body_path, load_body
from segadeform.body.makehuman import makehuman_vertices, makehuman_weights
from segadeform.body.placement import (
    PlacementError,
    _centre_offset,
    _fits,
    _RestBody,
    _stats,
    check_placement,
    fix_units_and_axes,
    placement_report,
)
from segadeform.cli.main import cli
from segadeform.errors import FileFormatError, InputError
from segadeform.garments.registration import fit_mhclo
from segadeform.io import read_mesh
from segadeform.io.mhclo import read_mhclo
from segadeform.io.obj import rewrite_obj_vertices

ROOT = Path(__file__).resolve().parents[2]
SAMPLES = ROOT / "samples" / "garments" / "makehuman"
SHARED = ROOT.parent / "shared" / "data" / "garments"
SHARED_MHCLO = sorted(SHARED.glob("makehuman*/*/*.mhclo"))


@pytest.fixture(scope="module")
def body():
    return load_body(default_body_path())


def test_binding_reproduces_the_helper_proxies(body):
    """tightshelper/skirthelper bind each vertex exactly to one hm08 vertex: the fit must put them exactly
    where the body file says those hm08 vertices are (here: in the A-pose, before unposing)."""
    mh = body.makehuman
    H = makehuman_vertices(body, mh)
    assert H.shape == (19158, 3) and np.isfinite(H).all()
    W = makehuman_weights(body, mh)
    np.testing.assert_allclose(W.sum(axis=1), 1.0, atol=1e-6)
    # body vertices in the A-pose come from the body itself
    pose_a = mh["rest_pose_a"].reshape(1, 72)
    np.testing.assert_allclose(H[mh["hm08_index"]], body.forward(pose_a).vertices[0], atol=1e-12)


@pytest.mark.parametrize("betas", [[], [2.0, 0.0, 0.0], [-1.5, 1.5]])
@pytest.mark.parametrize("name", ["tshirt_short_sleeve_m", "skirt_short_f"])
def test_mhclo_fit_sits_on_the_body(body, name, betas):
    """The fitted garment hugs the body at three shapes: median distance <= 2 cm, <= 1 % deeper than 1 cm
    inside, and it is where the garment belongs (a T-shirt on the torso, a skirt on the hips)."""
    b = read_mhclo(SAMPLES / f"{name}.mhclo")
    v = fit_mhclo(b, body, betas)
    mesh = read_mesh(SAMPLES / f"{name}.obj")
    assert v.shape == mesh.vertices.shape and np.isfinite(v).all()
    rest = body.shaped_vertices(betas)[0]
    r = placement_report(v, rest, body.faces)
    assert r.median_distance < 0.02 and r.deep_inside_fraction < 0.01, r.line()
    J = body.rest_joints(betas)[0]
    centre = v.mean(axis=0)
    if name.startswith("tshirt"):
        assert J[0, 1] < centre[1] < J[12, 1]  # between pelvis and neck
        assert np.ptp(v[:, 0]) > 0.3  # sleeves out along the T-posed arms
    else:
        assert J[4, 1] < centre[1] < J[3, 1] + 0.1  # between knees and waist
    check_placement(v, rest, body.faces)  # does not raise


@pytest.mark.skipif(not SHARED_MHCLO, reason="../shared/data/garments is not beside the checkout")
@pytest.mark.parametrize("path", SHARED_MHCLO, ids=[p.stem for p in SHARED_MHCLO])
def test_every_shared_makehuman_garment_fits(body, path):
    b = read_mhclo(path)
    v = fit_mhclo(b, body, [0.5, -0.5])
    r = placement_report(v, body.shaped_vertices([0.5, -0.5])[0], body.faces)
    assert r.median_distance < 0.035 and r.deep_inside_fraction < 0.02, r.line()


def test_fit_follows_the_shape(body):
    """A wider body gives a wider garment (the binding follows the shape, not the authoring body)."""
    b = read_mhclo(SAMPLES / "tshirt_short_sleeve_m.mhclo")
    widths = []
    for beta0 in (-2.0, 0.0, 2.0):
        rest = body.shaped_vertices([beta0])[0]
        v = fit_mhclo(b, body, [beta0])
        widths.append((np.ptp(v[:, 2]), np.ptp(rest[(rest[:, 1] > 1.0) & (rest[:, 1] < 1.3), 2])))
    g = [w[0] for w in widths]
    s = [w[1] for w in widths]
    assert (np.diff(g) * np.sign(np.diff(s)) > 0).all()


def test_rewrite_keeps_everything_but_positions(tmp_path):
    src = SAMPLES / "skirt_short_f.obj"
    m = read_mesh(src)
    rewrite_obj_vertices(src, m.vertices + 1.0, tmp_path / "o.obj")
    m2 = read_mesh(tmp_path / "o.obj")
    np.testing.assert_allclose(m2.vertices, m.vertices + 1.0, atol=1e-6)
    np.testing.assert_array_equal(m2.faces, m.faces)
    assert sum(ln.startswith("vt ") for ln in (tmp_path / "o.obj").read_text().splitlines()) == sum(
        ln.startswith("vt ") for ln in src.read_text().splitlines()
    )
    with pytest.raises(InputError, match="vertex count"):
        rewrite_obj_vertices(src, m.vertices[:-1], tmp_path / "p.obj")
    assert not (tmp_path / "p.obj").exists()


def test_units_and_axes():
    v = np.array([[0.0, 1.0, 2.0]])
    np.testing.assert_allclose(fix_units_and_axes(v, units="cm"), [[0, 0.01, 0.02]])
    np.testing.assert_allclose(fix_units_and_axes(v, up="z"), [[0, 2.0, -1.0]])
    np.testing.assert_allclose(fix_units_and_axes(v, scale=2, offset=(1, 0, 0)), [[1, 2, 4]])
    with pytest.raises(InputError, match="unknown units"):
        fix_units_and_axes(v, units="furlong")
    # a number of units or a scale beyond any file's (a QA trial: 1e308 overflowed into "points contain NaN or inf"
    # with numpy's warning, and --units 0 was refused as "scale must be positive")
    for kw, says in (
        ({"units": 1e308}, "units out of range"),
        ({"units": 0.0}, "units out of range"),
        ({"units": float("nan")}, "units out of range"),
        ({"scale": 0.0}, "scale out of range"),
        ({"scale": 1e9}, "scale out of range"),
    ):
        with pytest.raises(InputError, match=says):
            fix_units_and_axes(v, **kw)
    with pytest.raises(InputError, match="overflow"):
        fix_units_and_axes(np.array([[1e305, 0.0, 0.0]]), units=1000.0, scale=1e4)


# ---- the off-body check -------------------------------------------------------------------------------
@pytest.fixture(scope="module")
def dress():
    return read_mesh(ROOT / "samples" / "garments" / "dress.obj")


@pytest.mark.parametrize(
    "transform, words",
    [
        (lambda v: v * 10, "once read in dm"),
        (lambda v: v * 100, "once read in cm"),
        (lambda v: v @ np.array([[1.0, 0, 0], [0, 0, -1.0], [0, 1.0, 0]]).T, r"once read with \+z up"),
        (lambda v: v - [0, 0.95, 0], "0.95 m higher"),
        # moved sideways: sent back onto the body's axis, not down onto the floor by a foot (a user's trial)
        (lambda v: v + [0.4, 0, 0], r"--offset -0\.40,0\.00,0\.00"),
        (lambda v: v + [0.3, -0.5, 0], r"--offset -0\.30,0\.50,0\.00"),
        # 1 m to the side once passed as "read in dm, +z up" (a 10 cm dress on the hips): the move is asked first
        (lambda v: v + [1.0, 0, 0], r"--offset -1\.00,0\.00,0\.00"),
        # 2 m to the side also sits on the skin once read in dm with -z up, a 10 cm dress closer to the skin than the
        # dress moved back: the fixes named are those that leave a garment of a human's size (a review)
        (lambda v: v + [2.0, 0, 0], r"--offset -2\.00,0\.00,0\.00"),
    ],
)
def test_off_body_garments_are_refused_with_the_cause(body, dress, transform, words):
    rest = body.shaped_vertices()[0]
    with pytest.raises(PlacementError, match=words) as ei:
        check_placement(transform(dress.vertices), rest, body.faces, path=Path("g.obj"))
    assert "segadeform garment fit g.obj" in str(ei.value)


def test_wrong_offset_that_passes_the_lenient_test_is_refused(body, dress):
    """A user's trial: a dress 25 cm in front of the body has its back panel on the belly (the closest fifth within
    5 cm, nothing deep), so the lenient test passed it; it is now refused as off the body's middle, with the
    offset that moves it back."""
    rest = body.shaped_vertices()[0]
    moved = dress.vertices + [0.0, 0.0, 0.25]
    st = _stats(moved, _RestBody(rest, body.faces), float(rest[:, 1].max()), float(rest[:, 1].min()))
    assert _fits(st)  # what the lenient test alone says
    with pytest.raises(PlacementError, match=r"23 cm in front.*--offset 0\.00,0\.00,-0\.23"):
        check_placement(moved, rest, body.faces, path=Path("g.obj"))
    # one side of a garment (a sleeve, a bag) is off the middle by its nature: moved there it would be inside
    side = dress.vertices[dress.vertices[:, 0] > 0.12]
    assert np.abs(_centre_offset(side, rest)).max() > 0.08
    check_placement(side, rest, body.faces)


def test_a_garment_scaled_down_is_named_so(body, dress):
    """A user's trial: a skirt at 1/1000 got the advice of another origin (--offset 0,0.75,0), and the 0.7 mm garment
    that fit wrote then passed.  A garment under 3 cm across never sits; one scaled down is named with --scale."""
    rest = body.shaped_vertices()[0]
    with pytest.raises(PlacementError, match=r"\d\.\d mm across.*once scaled by 1000.*--scale 1000"):
        check_placement(dress.vertices * 0.001, rest, body.faces, path=Path("g.obj"))
    with pytest.raises(PlacementError, match="mm across"):  # moved onto the body, still no garment
        check_placement(dress.vertices * 0.001 + [0.0, 1.0, 0.1], rest, body.faces)
    # a tenth: a move also puts it near the skin (between the thighs, 5 cm from it: a user's trial took that
    # advice and ran a 7 cm "garment"), but scaled back it sits as a garment does: that is the fix named
    skirt = read_mesh(ROOT / "samples" / "garments" / "skirt.obj").vertices
    for v in (dress.vertices, skirt):
        with pytest.raises(PlacementError, match=r"once scaled by 10\b.*--scale 10\b"):
            check_placement(v * 0.1, rest, body.faces, path=Path("g.obj"))
    with pytest.raises(PlacementError, match=r"--offset -1\.00,0\.00,0\.00"):  # not dm (7 cm), nor 0.4 m down
        check_placement(skirt + [1.0, 0, 0], rest, body.faces, path=Path("g.obj"))


def test_a_garment_a_few_per_cent_off_in_size_or_20_cm_off_in_height_gets_that_fix(body):
    """A pipeline TD's trial: a suit scaled by 0.95 was told to move 7 cm up (62 % of it inside the body after, and the
    run took it), and one 20 cm up, between the small moves (10 cm) and another body's origin (25 cm), was told it was
    made for another body.  Now: the scale about the origin, and the move."""
    rest = body.shaped_vertices()[0]
    dress = read_mesh(ROOT / "samples" / "garments" / "dress.obj").vertices
    with pytest.raises(PlacementError, match=r"once scaled by 1\.0[4-6] about the origin.*--scale 1\.0[4-6]`"):
        check_placement(dress * 0.95, rest, body.faces, path=Path("g.obj"))
    with pytest.raises(PlacementError, match=r"once scaled by 1\.(09|1|11) about the origin.*--scale 1\.(09|1|11)`"):
        check_placement(dress * 0.9, rest, body.faces, path=Path("g.obj"))
    with pytest.raises(
        PlacementError, match=r"once moved 0\.20 m lower \(it sits off the body\).*--offset 0\.00,-0\.20"
    ):
        check_placement(dress + [0.0, 0.2, 0.0], rest, body.faces, path=Path("g.obj"))
    check_placement(dress * 1.06, rest, body.faces)  # a little larger still sits (looser)


def test_a_loose_skirt_moved_gets_the_move_back(body):
    """A review: the first height from below that passed the lenient test was named (a skirt 1 m to the side was sent
    back and 0.4 m down, one 0.95 m down was sent 0.55 m up), and the median distance put a loose skirt 10 cm high.
    The move across alone when it fits, else the height whose closest fifth of vertices lies closest to the skin."""
    skirt = read_mesh(ROOT / "samples" / "garments" / "skirt.obj").vertices
    rest = body.shaped_vertices()[0]
    for move, words in (
        ([0.0, -0.95, 0.0], "0.95 m higher"),
        ([0.5, -0.5, 0.0], r"--offset -0\.50,0\.50,0\.00"),
        ([1.5, 0.0, 0.0], r"--offset -1\.50,0\.00,0\.00"),
    ):
        with pytest.raises(PlacementError, match=words):
            check_placement(skirt + move, rest, body.faces, path=Path("g.obj"))


def test_a_garment_a_few_centimetres_off_is_moved_back_not_shrunk(body):
    """A technical artist's trial: the sample dress moved 3 cm sideways was told to be read in dm with +z up and turned
    270 degrees (a 10 cm scrap at the feet, which every command then took); a skirt 2.5 cm back was sent 35 cm down.
    A garment a few centimetres off gets the small move onto the body, and a garment of a human's size is never told
    to shrink below one."""
    rest = body.shaped_vertices()[0]
    dress = read_mesh(ROOT / "samples" / "garments" / "dress.obj").vertices
    skirt = read_mesh(ROOT / "samples" / "garments" / "skirt.obj").vertices
    for v, move, words in (
        (dress, [0.03, 0.0, 0.0], r"3 cm to the body's right .*--offset -0\.03,0\.00,0\.00"),
        (dress, [0.06, 0.0, 0.0], r"--offset -0\.06,0\.00,0\.00"),
        (dress, [0.0, 0.0, -0.025], r"--offset 0\.00,0\.00,0\.04"),
        (skirt, [0.0, 0.0, -0.025], r"--offset 0\.00,0\.0\d,0\.04"),
        (skirt, [0.06, 0.0, 0.0], r"--offset -0\.06,0\.0\d,0\.00"),
    ):
        with pytest.raises(PlacementError, match=words) as ei:
            check_placement(v + move, rest, body.faces, path=Path("g.obj"))
        assert "--units" not in str(ei.value) and "--turn" not in str(ei.value) and "--scale" not in str(ei.value)
        assert "another body's origin" not in str(ei.value)
    # the advice as printed (rounded to cm) puts it on the body: the dress 3 cm off on every axis (a review: the
    # rounded offset once failed the check it came from) -- and no "-0.00"
    with pytest.raises(PlacementError) as ei:
        check_placement(dress + [0.03, 0.03, 0.03], rest, body.faces, path=Path("g.obj"))
    printed = re.search(r"--offset ([-0-9.]+),([-0-9.]+),([-0-9.]+)", str(ei.value))
    assert printed is not None and "-0.00" not in str(ei.value), str(ei.value)
    check_placement(dress + [0.03, 0.03, 0.03] + np.array([float(x) for x in printed.groups()]), rest, body.faces)


def test_vertices_in_no_face_are_left_out(body):
    """A user's trial: 100 stray vertices (in no face) tipped the check and got the advice of another origin."""
    skirt = read_mesh(ROOT / "samples" / "garments" / "skirt.obj")
    rest = body.shaped_vertices()[0]
    pelvis = rest.mean(axis=0)
    v = np.concatenate([skirt.vertices, np.repeat(pelvis[None], 300, axis=0)])  # deep inside the body
    with pytest.raises(PlacementError):
        check_placement(v, rest, body.faces)
    check_placement(v, rest, body.faces, faces=skirt.faces)


def test_garment_for_another_body_is_refused(body):
    from segadeform.garments import GarmentParams, make_garment

    g = make_garment("tshirt", body, [-2.0, 1.0], GarmentParams())
    with pytest.raises(PlacementError, match="another body, pose or body shape"):
        check_placement(g.vertices, body.shaped_vertices()[0], body.faces)


def test_on_body_samples_pass(body, dress):
    rest = body.shaped_vertices()[0]
    for f in ("dress.obj", "skirt.obj"):
        check_placement(read_mesh(ROOT / "samples" / "garments" / f).vertices, rest, body.faces)


def test_run_refuses_then_force(tmp_path, dress):
    from segadeform.io import Mesh, write_obj

    write_obj(tmp_path / "dm.obj", Mesh(vertices=dress.vertices * 10, faces=dress.faces))
    args = [
        "run",
        "--garment",
        str(tmp_path / "dm.obj"),
        "--motion",
        str(ROOT / "samples/motions/walk.npz"),
        "-o",
        str(tmp_path / "o.pc2"),
        "--frames",
        "0:4",
        "--no-cache",
        "--effects=-wrinkles,-collisions",
    ]
    r = CliRunner().invoke(cli, args)
    assert r.exit_code == 1 and "once read in dm" in r.output and "--units dm" in r.output
    assert not (tmp_path / "o.pc2").exists()
    r = CliRunner().invoke(cli, args + ["--force"])
    assert r.exit_code == 0, r.output


# ---- CLI and malformed files ---------------------------------------------------------------------------
def test_garment_fit_cli(tmp_path):
    r = CliRunner().invoke(
        cli,
        [
            "garment",
            "fit",
            str(SAMPLES / "tshirt_short_sleeve_m.mhclo"),
            "-o",
            str(tmp_path / "t.obj"),
            "--betas",
            "1,0.5",
        ],
    )
    assert r.exit_code == 0, r.output
    assert "MakeHuman binding" in r.output and "0.0 % of vertices inside" in r.output
    m = read_mesh(tmp_path / "t.obj")
    assert len(m.vertices) == 810
    # an OBJ with its .mhclo beside it is found; plain fixes otherwise
    r = CliRunner().invoke(cli, ["garment", "fit", str(SAMPLES / "skirt_short_f.obj"), "-o", str(tmp_path / "s.obj")])
    assert r.exit_code == 0 and "skirt_short_f.mhclo" in r.output
    # a fix that leaves a garment off the body is refused, and written with --force (t.obj is made for betas 1,0.5)
    args = ["garment", "fit", str(tmp_path / "t.obj"), "-o", str(tmp_path / "u.obj"), "--units", "cm"]
    r = CliRunner().invoke(cli, args)
    # (checked on the shape it records, as `run` runs it: there it sits as it is, and not with the fix)
    assert r.exit_code == 1 and "sits on the body as it is, and not with units cm" in r.output, r.output
    assert not (tmp_path / "u.obj").exists()
    r = CliRunner().invoke(cli, [*args, "--force"])
    assert r.exit_code == 0 and "units cm" in r.output
    np.testing.assert_allclose(read_mesh(tmp_path / "u.obj").vertices, m.vertices * 0.01, atol=1e-6)


def test_garment_fit_refuses_a_file_in_other_units_and_names_the_fix(tmp_path, body):
    """A plain `garment fit` of a garment modelled in centimetres wrote it 92 m off the body, exit 0."""
    from segadeform.io import Mesh, write_obj

    faces = read_mesh(SAMPLES / "skirt_short_f.obj").faces
    on_body = fit_mhclo(read_mhclo(SAMPLES / "skirt_short_f.mhclo"), body)
    write_obj(tmp_path / "cm.obj", Mesh(vertices=on_body * 100, faces=faces))
    out = tmp_path / "fixed.obj"

    def fit(*extra):
        return CliRunner().invoke(cli, ["garment", "fit", str(tmp_path / "cm.obj"), "-o", str(out), *extra])

    r = fit()
    assert r.exit_code == 1 and "it does once read in cm" in r.output and "--units cm`" in r.output, r.output
    assert not out.exists()
    r = fit("--units", "mm")  # the wrong fix: the suggestion is still the one for the file as given
    assert r.exit_code == 1 and "with units mm" in r.output and "--units cm`" in r.output, r.output
    assert not out.exists()
    r = fit("--units", "cm")
    assert r.exit_code == 0, r.output
    np.testing.assert_allclose(read_mesh(out).vertices, on_body, atol=1e-6)


@pytest.mark.parametrize(
    "mutate, words",
    [
        (lambda t: t.replace("basemesh hm08", "basemesh hm07"), "only hm08"),
        (lambda t: t.replace("verts 0", "verts 0\n12 13 0.5 0.5"), "1, 6 or 9 numbers"),
        (lambda t: t.replace("verts 0", "verts 0\n12 13 14 0.5 x 0.5 0 0 0"), "expected a number"),
        (lambda t: t.replace("verts 0", "verts 0\n12 13 14 0.5 nan 0.5 0 0 0"), "not finite"),
        (
            lambda t: t.replace("x_scale 5399 11998", "x_scale 5399 11998 0 0").replace(
                "x_scale 5399 11998 0 0 ", "x_scale 5399 11998 0 "
            ),
            "x_scale",
        ),
        (lambda t: t.split("verts 0")[0], "no binding lines"),
        (lambda t: t.replace("delete_verts", "delete_verts\n20 - 10"), "runs backwards"),
    ],
)
def test_malformed_mhclo(tmp_path, mutate, words):
    src = (SAMPLES / "skirt_short_f.mhclo").read_text()
    (tmp_path / "b.mhclo").write_text(mutate(src))
    with pytest.raises(FileFormatError, match=words) as ei:
        read_mhclo(tmp_path / "b.mhclo")
    assert "b.mhclo" in str(ei.value)


def test_binding_out_of_range(tmp_path, body):
    src = (SAMPLES / "skirt_short_f.mhclo").read_text()
    (tmp_path / "b.mhclo").write_text(src.replace("verts 0", "verts 0\n99999 1 2 0.3 0.3 0.4 0 0 0", 1))
    with pytest.raises(FileFormatError, match="does not have"):
        fit_mhclo(read_mhclo(tmp_path / "b.mhclo"), body)


# ---- a garment modelled on another body mesh ----------------------------------------------------------
def _other_body_scene(body, betas_src):
    """A source body of other shape, pose (MakeHuman's A-pose, a twisted spine), topology (every
    triangle split at its centre, vertices shuffled), units (cm) and up axis (z), and a T-shirt made on
    it in T-pose and skinned into that pose."""
    from segadeform.body.skinning import linear_blend_skinning
    from segadeform.body.transfer import transfer_weights
    from segadeform.garments import GarmentParams, make_garment

    rest_src = body.shaped_vertices(betas_src)[0]
    g = make_garment("tshirt", body, betas_src, GarmentParams())
    pose = body.makehuman["rest_pose_a"].copy()
    pose.reshape(24, 3)[3] += [0.1, 0.2, 0.0]
    out = body.forward(pose[None], betas_src)
    w = transfer_weights(g.vertices, rest_src, body.faces, body.weights)
    g_posed = linear_blend_skinning(g.vertices, w, out.transforms)[0]
    v, f = out.vertices[0], body.faces
    mid = v[f].mean(axis=1)
    sv = np.concatenate([v, mid])
    k = np.arange(len(f)) + len(v)
    sf = np.concatenate(
        [np.stack([f[:, 0], f[:, 1], k], 1), np.stack([f[:, 1], f[:, 2], k], 1), np.stack([f[:, 2], f[:, 0], k], 1)]
    )
    perm = np.random.default_rng(0).permutation(len(sv))
    sv, sf = sv[perm], np.argsort(perm)[sf]
    to_zup_cm = lambda x: (x @ np.array([[1.0, 0, 0], [0, 0, -1.0], [0, 1.0, 0]]).T) * 100  # noqa: E731
    return g, to_zup_cm(g_posed), to_zup_cm(sv), sf


def test_fit_to_another_body_mesh(body, tmp_path, monkeypatch):
    """Registered and carried over, the T-shirt sits on the default body (median <= 2 cm, <= 2 % deeper
    than 1 cm inside) and, carried back onto the shape it was made on, lands within a few cm of where it
    was made (mean <= 5 cm: the shape space and the scale trade off a little, so the surface slides).  The
    command's runs use the test's lighter registration (800 samples, 5 rounds), as the calls above do."""

    from segadeform.garments import registration
    from segadeform.garments.registration import fit_to_body_mesh
    from segadeform.io import Mesh, write_obj

    betas_src = [1.5, -1.0]
    g, g_src, sv, sf = _other_body_scene(body, betas_src)
    gv = fix_units_and_axes(g_src, units="cm", up="z")
    bv = fix_units_and_axes(sv, units="cm", up="z")
    back = fit_to_body_mesh(gv, bv, sf, body, betas_src, samples=800, rounds=5)
    assert back.body_error < 0.006
    err = np.linalg.norm(back.vertices - g.vertices, axis=1)
    assert err.mean() < 0.05, err.mean()
    # onto the default body, through the CLI, files in cm and z-up (the fit of the call above without betas)
    calls = []

    def recorded(*args, **kw):  # the registration's inputs, and its result
        calls.append((args, kw, fit_to_body_mesh(*args, samples=800, rounds=5, **kw)))
        return calls[-1][2]

    monkeypatch.setattr(registration, "fit_to_body_mesh", recorded)
    write_obj(tmp_path / "g.obj", Mesh(vertices=g_src, faces=g.faces))
    write_obj(tmp_path / "b.obj", Mesh(vertices=sv, faces=sf))
    res = CliRunner().invoke(
        cli,
        [
            "garment",
            "fit",
            str(tmp_path / "g.obj"),
            "--from-body",
            str(tmp_path / "b.obj"),
            "--units",
            "cm",
            "--up",
            "z",
            "-o",
            str(tmp_path / "f.obj"),
        ],
    )
    assert res.exit_code == 0, res.output
    assert "registered to b.obj" in res.output
    onto = read_mesh(tmp_path / "f.obj").vertices
    r = placement_report(onto, body.shaped_vertices()[0], body.faces)
    assert r.median_distance < 0.02 and r.deep_inside_fraction < 0.02, r.line()
    check_placement(onto, body.shaped_vertices()[0], body.faces)

    # without --units and --up: both read from the source body's height (it is 1.8 m along z, in cm).  The same
    # inputs reach the registration (which is then not run again: its result is the one above)
    def same(*args, **kw):
        calls.append((args, kw, calls[0][2]))
        return calls[0][2]

    monkeypatch.setattr(registration, "fit_to_body_mesh", same)
    res = CliRunner().invoke(
        cli,
        [
            "garment",
            "fit",
            str(tmp_path / "g.obj"),
            "--from-body",
            str(tmp_path / "b.obj"),
            "-o",
            str(tmp_path / "a.obj"),
        ],
    )
    assert res.exit_code == 0, res.output
    assert "read in cm with +z up" in res.output
    (a1, k1, _), (a2, k2, _) = calls
    assert len(a1) == len(a2) and k1.keys() == k2.keys()
    for x, y in [*zip(a1, a2, strict=True), *((k1[k], k2[k]) for k in k1)]:
        if isinstance(x, np.ndarray):
            np.testing.assert_allclose(x, y, rtol=0, atol=1e-12)
        elif not hasattr(x, "faces"):  # (the body model: the same default body, loaded again)
            assert x == y
    np.testing.assert_allclose(
        read_mesh(tmp_path / "a.obj").vertices, read_mesh(tmp_path / "f.obj").vertices, atol=1e-9
    )
    # the facing is searched for unless --turn is given (0 too: the source faces +Z as it is; a head tilted far back
    # reads as facing backwards)
    assert k1["search_facing"] and k2["search_facing"]
    args = ["garment", "fit", str(tmp_path / "g.obj"), "--from-body", str(tmp_path / "b.obj"), "--turn", "0"]
    res = CliRunner().invoke(cli, [*args, "-o", str(tmp_path / "t.obj")])
    assert res.exit_code == 0 and calls[-1][1]["search_facing"] is False, res.output


def test_a_body_in_a_stride_is_registered(body):
    """A source body in a real walking stride (CMU 02_01, frame 30: the right knee bent 53 degrees, the left arm
    hanging beside the hip) was registered with the leg twisted and the shape at its bounds, and the trousers made on
    it tore (24 % of edges > 2x; `tools/registration_check.py`).  The limbs tried from other directions, pairs that
    face the same way and the scale from the area find it: joints within a few cm, the trousers back where they were
    made, nothing torn past `garment fit`'s 5 %."""
    from segadeform.body.skinning import linear_blend_skinning
    from segadeform.body.transfer import transfer_weights
    from segadeform.garments import GarmentParams, make_garment
    from segadeform.garments.registration import edge_distortion, fit_to_body_mesh
    from segadeform.motion import load_motion

    betas = np.array([1.5, -1.0])
    motion = load_motion(
        ROOT / "samples" / "motions" / "cmu" / "02_01_walk.bvh", rest_joints=body.rest_joints(betas)[0]
    )
    pose = np.asarray(motion.poses[30], np.float64).copy()
    pose[:3] = 0.0
    assert np.linalg.norm(pose[15:18]) > 0.8  # the right knee is bent: not a pose the T- or A-pose start is near
    out = body.forward(pose[None], betas)
    g = make_garment("trousers", body, betas, GarmentParams())
    w = transfer_weights(g.vertices, body.shaped_vertices(betas)[0], body.faces, body.weights)
    posed = linear_blend_skinning(g.vertices, w, out.transforms)[0]
    fit = fit_to_body_mesh(posed, out.vertices[0], body.faces, body, betas, garment_faces=g.faces)
    fo = body.forward(fit.pose[None], fit.betas)
    joints = np.linalg.norm(fo.joints[0] * fit.scale + fit.trans - out.joints[0], axis=1)
    assert joints.mean() < 0.05, joints
    err = np.linalg.norm(fit.vertices - g.vertices, axis=1)
    assert err.mean() < 0.05 and err.max() < 0.2, (err.mean(), err.max())
    torn, _ = edge_distortion(g.vertices, fit.vertices, g.faces)
    assert torn < 0.05, torn


def test_a_mesh_wound_inward_gives_the_same_fit(body):
    """The pairing and the attachment read normals: a source body and a garment whose triangles are all wound the
    other way (normals inward, as some exporters write them) give the same fit."""
    from segadeform.garments.registration import fit_to_body_mesh

    g, g_src, sv, sf = _other_body_scene(body, [1.5, -1.0])
    gv = fix_units_and_axes(g_src, units="cm", up="z")
    bv = fix_units_and_axes(sv, units="cm", up="z")
    a = fit_to_body_mesh(gv, bv, sf, body, None, samples=600, rounds=3, garment_faces=g.faces)
    b = fit_to_body_mesh(gv, bv, sf[:, ::-1], body, None, samples=600, rounds=3, garment_faces=g.faces[:, ::-1])
    np.testing.assert_allclose(b.pose, a.pose, atol=1e-6)  # the same registration
    d = np.linalg.norm(a.vertices - b.vertices, axis=1)
    # the same attachment but where a tie (a normal at right angles to the other's, a point on an edge between two
    # triangles) is decided by rounding: measured 2.3 % of vertices moved more than 1 mm, 0.17 mm on average; the
    # carry's smoothing over the garment (registration._smooth_carry) spreads those few over their neighbours:
    # median 0.025 mm, mean 0.10 mm
    assert np.median(d) < 1e-4 and (d > 1e-3).mean() < 0.05 and d.mean() < 1e-3, (np.median(d), d.mean())


def test_a_source_facing_another_way_is_fitted_as_if_turned(body):
    """A source body and garment facing +X (an Unreal character) or -Z were fitted facing +Z: legs crossed, 46 cm
    off, exit 0 (a technical artist's trial).  Each quarter turn is tried; the fit is the unturned one's."""
    from segadeform.body.placement import turn_about_up
    from segadeform.garments.registration import fit_to_body_mesh

    g, g_src, sv, sf = _other_body_scene(body, [1.5, -1.0])
    gv = fix_units_and_axes(g_src, units="cm", up="z")
    bv = fix_units_and_axes(sv, units="cm", up="z")
    a = fit_to_body_mesh(gv, bv, sf, body, None, samples=600, rounds=3, garment_faces=g.faces)
    for turn in (90.0, 180.0):
        r = turn_about_up(turn)
        b = fit_to_body_mesh(gv @ r.T, bv @ r.T, sf, body, None, samples=600, rounds=3, garment_faces=g.faces)
        d = np.linalg.norm(a.vertices - b.vertices, axis=1)
        assert np.median(d) < 1e-3 and d.max() < 0.01, (turn, np.median(d), d.max())


def test_the_body_s_shape_says_which_way_it_faces_where_the_fit_and_the_feet_cannot(body):
    """The rest pose turned a quarter fitted a body in a stride closer than facing its way (CMU 02_01 frame 0: fitted
    facing +X, joints 39 cm off, 15 % of the T-shirt's edges torn; a docs audit), and the feet point every way in a
    stride (07_03 frame 40: 152 degrees off).  The shoulders' line and the head in front of the neck give the facing
    of the rest body turned any way and of walking frames; only the quarters within 60 degrees of it are fitted."""
    from segadeform.body.placement import turn_about_up
    from segadeform.garments.registration import _body_facing, _facing_candidates, _toes_facing
    from segadeform.motion import load_motion

    betas = np.array([1.5, -1.0])
    rest = body.shaped_vertices(betas)[0]
    for turn in (0.0, 90.0, 180.0, 270.0, 30.0):
        got, sure = _body_facing(rest @ turn_about_up(turn).T)
        assert sure and abs((got - turn + 180.0) % 360.0 - 180.0) < 2.0, (turn, got)
    assert _facing_candidates(rest @ turn_about_up(-90.0).T) == [3]  # an Unreal character facing -X
    assert _facing_candidates(rest @ turn_about_up(45.0).T) == [0, 1]  # between two: both fitted, the closer kept
    for clip, frame in (("02_01_walk", 0), ("07_03_walk", 40)):
        m = load_motion(ROOT / "samples" / "motions" / "cmu" / f"{clip}.bvh", rest_joints=body.rest_joints(betas)[0])
        pose = np.asarray(m.poses[frame], np.float64).copy()
        pose[:3] = 0.0  # facing +Z
        v = body.forward(pose[None], betas).vertices[0]
        got, sure = _body_facing(v)
        assert sure and abs(got) < 20.0, (clip, got)
        assert _facing_candidates(v) == [0]
    assert abs(_toes_facing(v)) > 120.0  # (07_03 frame 40's feet: the cue the facing was taken from before)
    # a review's poses: arms reaching forward (the widest band across them once: the torso's alone now), hands on
    # the head (the top band no head alone: unsure, both ways along the shoulders' normal fitted)
    z = np.zeros((24, 3))
    arms = z.copy()
    arms[16], arms[17] = [0.0, -1.5, -0.3], [0.0, 1.5, 0.3]
    assert _facing_candidates(body.forward(arms.reshape(1, -1), betas).vertices[0]) == [0]
    hands = z.copy()
    hands[16], hands[17], hands[18], hands[19] = [0, 0, 1.0], [0, 0, -1.0], [0, -2.0, 0], [0, 2.0, 0]
    assert _facing_candidates(body.forward(hands.reshape(1, -1), betas).vertices[0]) == [0, 2]
    flat = rest * [1.0, 1.0, 0.0]  # no depth: the head in line with the neck, either way along the normal
    assert _body_facing(flat)[1] is False and _facing_candidates(flat) == [0, 2]


def _walls(spec, n: int = 6, width: float = 0.1):
    """Square walls across x, each n x n vertices ``width`` wide: ``spec`` = [(x, +1 or -1: the way it faces along
    x), ...].  Returns vertices, faces and each face's wall (its index in ``spec``)."""
    s = np.linspace(-width / 2, width / 2, n)
    yy, zz = np.meshgrid(s, s, indexing="ij")
    idx = np.arange(n * n).reshape(n, n)
    a, b, c, d = idx[:-1, :-1].ravel(), idx[1:, :-1].ravel(), idx[1:, 1:].ravel(), idx[:-1, 1:].ravel()
    quads = np.concatenate([np.stack([a, b, c], 1), np.stack([a, c, d], 1)])  # on a (y, z) grid: facing +x
    vs, fs, parts = [], [], []
    for k, (x, facing) in enumerate(spec):
        vs.append(np.stack([np.full(n * n, x), yy.ravel(), zz.ravel()], 1))
        fs.append((quads if facing > 0 else quads[:, [0, 2, 1]]) + k * n * n)
        parts.append(np.full(len(quads), k))
    return np.concatenate(vs), np.concatenate(fs), np.concatenate(parts)


def test_a_garment_attaches_to_the_surface_facing_it():
    """A sleeve's inner side between an arm and the torso, nearer the torso: the closest point is on the torso,
    whose surface faces away from the sleeve there; the sleeve is attached to the arm, which faces the same way as
    it.  Without the garment's faces (no normals) the closest point is taken, as before."""
    from segadeform.garments.registration import _attach
    from segadeform.geometry.mesh_ops import face_cross, vertex_normals

    # the torso's side (x = 0, facing +x), an arm 3 cm thick 2 cm beside it (its inner and outer sides)
    v, f, part = _walls([(0.0, 1), (0.02, -1), (0.05, 1)])
    n_f = face_cross(v, f)
    assert (n_f[part == 0, 0] > 0).all() and (n_f[part == 1, 0] < 0).all()
    # the sleeve: 8 mm off the torso (12 mm off the arm's inner side) facing -x, and 5 mm off its outer side
    gv, gf, gpart = _walls([(0.008, -1), (0.055, 1)], n=5, width=0.06)
    assert (vertex_normals(gv, gf)[:25, 0] < 0).all()
    face, closest = _attach(gv, gf, v, f)
    inner = np.arange(25)
    assert (part[face[inner]] == 1).all()
    np.testing.assert_allclose(closest[inner, 0], 0.02, atol=1e-12)
    assert (part[face[25:]] == 2).all()
    face0, _ = _attach(gv, None, v, f)
    assert (part[face0[inner]] == 0).all()


def test_a_vertex_on_another_part_than_its_neighbours_takes_theirs():
    """A registered elbow that passes through a waistband: one garment vertex's closest triangle facing its way is
    the elbow's while every neighbour's is the hip's.  With the body's parts it is attached to the hip as they are."""
    from segadeform.garments.registration import _attach

    v, f, part = _walls([(0.0, 1)])
    gv, gf, _ = _walls([(0.006, 1)], n=5, width=0.06)
    k = 12  # the patch's middle vertex
    # a small "elbow" triangle facing +x just under vertex k, inside the garment's 6 mm
    e = gv[k] + np.array([[-0.002, -0.003, -0.003], [-0.002, 0.004, 0.0], [-0.002, -0.003, 0.004]])
    v2 = np.concatenate([v, e])
    f2 = np.concatenate([f, [[len(v), len(v) + 1, len(v) + 2]]])
    labels = np.concatenate([part, [1]])
    face, _ = _attach(gv, gf, v2, f2)
    assert labels[face[k]] == 1  # without the parts: the elbow's
    face, closest = _attach(gv, gf, v2, f2, face_labels=labels)
    assert (labels[face] == 0).all()
    np.testing.assert_allclose(closest[:, 0], 0.0, atol=1e-12)


def test_units_and_up_of_a_body_mesh(body):
    from segadeform.garments.registration import guess_units_and_up

    v = body.shaped_vertices()[0]  # T-pose: the arm span along x is about the height
    assert guess_units_and_up(v)[:2] == ("m", "y")
    assert guess_units_and_up(fix_units_and_axes(v, up="-z") * 100)[:2] == ("cm", "z")  # +y -> +z
    assert guess_units_and_up(v * 1000)[:2] == ("mm", "y") and guess_units_and_up(v / 0.0254)[:2] == ("inch", "y")
    assert guess_units_and_up(v * 100, units="m")[0] == "m"  # given units are kept
    # Z-up facing +x: the arm span (1.87 m, longer than the height) along y, the height along z
    zx = np.stack([v[:, 2], v[:, 0] * 1.05, v[:, 1]], axis=1)
    assert np.ptp(zx[:, 1]) > np.ptp(zx[:, 2])
    assert guess_units_and_up(zx * 100)[:2] == ("cm", "z")
    # Y-up facing +x: the span along z
    yx = np.stack([v[:, 2], v[:, 1], v[:, 0] * 1.05], axis=1)
    assert guess_units_and_up(yx)[:2] == ("m", "y")
    with pytest.raises(InputError, match="no human's height"):
        guess_units_and_up(v * 1e5)


def test_a_fit_that_tears_the_garment_is_refused(tmp_path, monkeypatch):
    """A source body in a walk's pose registered to the wrong pose: 13 % of the jeans' edges 2-55x their length,
    and `garment fit` said it succeeded.  The tear is measured on the edges, and refused unless --force."""
    import dataclasses

    from segadeform.garments import registration
    from segadeform.garments.registration import edge_distortion
    from segadeform.io import Mesh, write_obj
    from tests.cli.test_output_safety import folder_hash

    tri = np.array([[0, 1, 2], [0, 2, 3]])
    sq = np.array([[0.0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]])
    assert edge_distortion(sq, sq * 1.5, tri) == (0.0, 1.5)  # carried to a larger body: kept
    torn, worst = edge_distortion(sq, sq + [[0, 0, 0], [0, 0, 0], [0, 0, 0], [0, 0, 9]], tri)
    assert torn == pytest.approx(2 / 5) and worst > 9  # the two edges of the thrown corner
    body_v = load_body(default_body_path()).shaped_vertices()[0]
    write_obj(tmp_path / "b.obj", Mesh(vertices=body_v, faces=load_body(default_body_path()).faces))
    g = read_mesh(ROOT / "samples" / "garments" / "skirt.obj")
    write_obj(tmp_path / "g.obj", g)
    real = registration.fit_to_body_mesh

    def scrambled(*a, **k):  # a registration that found the wrong pose: a tenth of the vertices thrown
        fit = real(*a, **{**k, "samples": 400, "rounds": 2})  # (a quick one: what is tested is the refusal)
        v = fit.vertices.copy()
        v[::10] += [0.0, 0.0, 0.5]
        return dataclasses.replace(fit, vertices=v)

    monkeypatch.setattr(registration, "fit_to_body_mesh", scrambled)
    args = [
        "garment",
        "fit",
        str(tmp_path / "g.obj"),
        "--from-body",
        str(tmp_path / "b.obj"),
        "-o",
        str(tmp_path / "o.obj"),
    ]
    (tmp_path / "notes.txt").write_text("a user's notes\n")
    (tmp_path / "u.obj").write_text("a user's file\n")
    before = folder_hash(tmp_path)  # the user's garment, body and other files beside the output
    r = CliRunner().invoke(cli, args)
    assert r.exit_code == 1 and "the fit tore the garment" in r.output and "--force" in r.output, r.output
    assert not (tmp_path / "o.obj").exists()
    assert folder_hash(tmp_path) == before  # refused: nothing written, nothing touched
    for force in ([], ["--force"]):  # a user's file at the output path survives either way
        r = CliRunner().invoke(cli, [*args[:-1], str(tmp_path / "u.obj"), *force])
        assert r.exit_code == 1 and "segadeform did not write it" in r.output, r.output
        assert folder_hash(tmp_path) == before
    r = CliRunner().invoke(cli, [*args, "--force"])
    assert r.exit_code == 0 and (tmp_path / "o.obj").exists(), r.output
    after = folder_hash(tmp_path)
    assert {k: v for k, v in after.items() if k in before} == before and set(after) - set(before) == {"o.obj"}


def test_a_makehuman_garment_given_to_run_is_sent_to_garment_fit(tmp_path):
    """`run` took neither a MakeHuman `.mhclo` ("unknown mesh file extension") nor pointed from its raw OBJ to the
    binding beside it (it suggested --from-body): both now name `segadeform garment fit`."""
    walk = ROOT / "samples" / "motions" / "walk.npz"
    for garment, says in (
        (SAMPLES / "skirt_short_f.mhclo", "a MakeHuman binding is not a mesh"),
        (SAMPLES / "skirt_short_f.obj", "it is a MakeHuman garment, placed on a body by the binding beside it"),
    ):
        r = CliRunner().invoke(
            cli,
            ["run", "--garment", str(garment), "--motion", str(walk), "--frames", "0:2", "-o", str(tmp_path / "o.pc2")],
        )
        assert r.exit_code == 1 and says in r.output and "segadeform garment fit" in r.output, r.output
        assert not (tmp_path / "o.pc2").exists()


def test_a_garment_records_the_shape_it_was_fitted_for_and_run_holds_it(tmp_path):
    """A garment fitted for betas (1, 0.5) sat on the default body's chest and `run` took it silently (a new user's
    MakeHuman skirt): `garment fit` and `garment make` now record the shape in the OBJ, and `run` refuses the
    garment on another shape -- both ways -- with the shape to use, unless --force."""
    from segadeform.io.obj import betas_record, recorded_betas

    walk = ROOT / "samples" / "motions" / "walk.npz"
    fitted = tmp_path / "s.obj"
    r = CliRunner().invoke(
        cli, ["garment", "fit", str(SAMPLES / "skirt_short_f.mhclo"), "--betas", "1,0.5", "-o", str(fitted)]
    )
    assert r.exit_code == 0, r.output
    assert recorded_betas(fitted) == (1.0, 0.5)

    def run(garment, *extra):
        out = tmp_path / f"o{len(list(tmp_path.glob('o*.pc2')))}.pc2"
        args = ["run", "--garment", str(garment), "--motion", str(walk), "--frames", "0:2", "-o", str(out), *extra]
        res = CliRunner().invoke(cli, args)
        return res, out

    res, out = run(fitted)
    assert res.exit_code == 1 and "made for body shape betas 1,0.5, not for this body's betas 0" in res.output
    assert "--betas 1,0.5" in res.output and not out.exists()
    for extra in (("--betas", "1,0.5,0"), ("--force",)):
        res, out = run(fitted, *extra)
        assert res.exit_code == 0 and out.is_file(), res.output
    made = tmp_path / "m.obj"
    assert CliRunner().invoke(cli, ["garment", "make", "skirt", "-o", str(made)]).exit_code == 0
    assert recorded_betas(made) == ()
    res, out = run(made, "--betas", "1")
    assert res.exit_code == 1 and "made for body shape betas 0 (the default shape)" in res.output
    assert "no --betas" in res.output and not out.exists()
    # fitted again: the new record replaces the old one, the rest of the file is kept
    again = tmp_path / "again.obj"
    rewrite_obj_vertices(fitted, read_mesh(fitted).vertices, again, header=("segadeform garment fit: x", "betas: 2"))
    text = again.read_text()
    assert recorded_betas(again) == (2.0,) and text.count("betas:") == 1 and "MakeHuman" in text
    assert betas_record((1.5, -1)) == "betas: 1.5 -1" and betas_record(None) == "betas:"


def test_garment_fit_refuses_a_second_binding_and_a_body_no_human_has(tmp_path):
    """`garment fit X.mhclo --mhclo Y.mhclo` used X and ignored Y; `--betas 4` made a 2.9 m body without a word."""
    skirt, shirt = SAMPLES / "skirt_short_f.mhclo", SAMPLES / "tshirt_short_sleeve_m.mhclo"
    r = CliRunner().invoke(cli, ["garment", "fit", str(skirt), "--mhclo", str(shirt), "-o", str(tmp_path / "a.obj")])
    assert r.exit_code == 2 and "is a binding itself" in r.output and not (tmp_path / "a.obj").exists()
    r = CliRunner().invoke(cli, ["garment", "fit", str(skirt), "--mhclo", str(skirt), "-o", str(tmp_path / "b.obj")])
    assert r.exit_code == 0, r.output  # the same binding twice is what was meant
    tall = ["garment", "fit", str(skirt), "--betas", "4", "-o", str(tmp_path / "c.obj")]
    r = CliRunner().invoke(cli, tall)
    assert r.exit_code == 1 and "not a human's height" in r.output and not (tmp_path / "c.obj").exists()
    r = CliRunner().invoke(cli, [*tall, "--force"])
    assert r.exit_code == 0 and (tmp_path / "c.obj").is_file()


def test_garment_fit_names_betas_no_human_has_and_how_far_they_may_go(tmp_path):
    """A user's trial: `garment fit X.mhclo --betas 3` said "betas within about +-3" yet refused 3 (2.61 m), without
    naming the option as `run` does.  The limit stated is the one along the betas given, checked here."""
    from segadeform.bounds import HEIGHT_RANGE, height_reach

    out = tmp_path / "x.obj"
    r = CliRunner().invoke(
        cli, ["garment", "fit", str(SAMPLES / "skirt_short_f.mhclo"), "--betas", "3", "-o", str(out)]
    )
    assert r.exit_code == 1 and not out.exists()
    assert r.output == (
        "Error: --betas: the body shape is not a human's height (expected 0.9..2.5 m (at most betas 2.57 in the "
        "direction given), or --force to use it anyway, got 2.61 m with betas 3)\n"
    ), r.output
    r = CliRunner().invoke(
        cli, ["garment", "fit", str(SAMPLES / "skirt_short_f.mhclo"), "--betas", "nan", "-o", str(out)]
    )
    assert r.exit_code == 1 and r.output.startswith("Error: --betas must be finite"), r.output
    body = load_body(default_body_path())
    height = lambda b: np.ptp(body.shaped_vertices(b)[0][:, 1])  # noqa: E731
    for betas in ((3.0,), (-5.0, 2.0), (6.0, -6.0)):
        reach = np.asarray(height_reach(body, betas))
        assert HEIGHT_RANGE[0] <= height(reach) <= HEIGHT_RANGE[1], betas
        assert not HEIGHT_RANGE[0] <= height(reach + 0.02 * np.sign(betas)) <= HEIGHT_RANGE[1], (betas, reach)
    assert height_reach(body, ()) is None


def test_check_recorded_shape_pads_with_zeros_and_ignores_a_garment_without_a_record():
    from segadeform.body.placement import check_recorded_shape

    check_recorded_shape(None, (3.0,))  # no record: nothing to hold the garment to
    check_recorded_shape((1.0, 0.0), (1.0,))  # the same shape, written shorter
    check_recorded_shape((), np.zeros(10))
    with pytest.raises(PlacementError, match=r"betas 0\.5, not for this body's betas 0\.5,0\.001"):
        check_recorded_shape((0.5,), (0.5, 0.001), path="g.obj")


def test_a_garment_with_no_face_area_is_named_and_not_fitted(tmp_path):
    """A new user's trial: a garment whose one face is flat (collinear corners) was refused by run, precompute and
    garment export without naming the file, and `garment fit` wrote it, exit 0."""
    g = tmp_path / "colin.obj"
    g.write_text("v 0 1.2 0.15\nv 0.1 1.2 0.15\nv 0.2 1.2 0.15\nf 1 2 3\n")
    motion = str(ROOT / "samples/motions/walk.npz")
    for args, out in (
        (["run", "--garment", str(g), "--motion", motion, "-o", str(tmp_path / "o.pc2"), "--no-cache"], "o.pc2"),
        (["precompute", str(g), "--body", str(default_body_path()), "-o", str(tmp_path / "a.npz")], "a.npz"),
        (["garment", "export", str(g), "-o", str(tmp_path / "a.sgda")], "a.sgda"),
        (["garment", "fit", str(g), "-o", str(tmp_path / "fit.obj")], "fit.obj"),
    ):
        r = CliRunner().invoke(cli, args)
        assert r.exit_code == 1, (args, r.output)
        assert f"{g}: the garment has no face with an area" in r.output, r.output
        assert len(r.output.strip().splitlines()) == 1 and not (tmp_path / out).exists(), r.output


def test_garment_fit_into_another_folder_keeps_its_material_library_found_and_says_it_fitted(tmp_path, dress):
    """A new user's trial: `garment fit` of a Maya OBJ into another folder copied `mtllib garment.mtl` with no such
    file there (Blender's OBJ import logs an error on each import of it) and kept `# Exported from Maya 2024` as its
    first line, nothing saying segadeform had rewritten every vertex.  The library is named as found from the
    output's folder (a relative path to the source's), one found nowhere is left out, and the first line says the
    file was fitted, by which segadeform and how; a record of the body shape is kept by a unit fix."""
    from segadeform import __version__
    from segadeform.io import Mesh, write_obj
    from segadeform.io.obj import recorded_betas

    src, out = tmp_path / "maya", tmp_path / "fitted" / "deep"
    src.mkdir()
    write_obj(src / "plain.obj", Mesh(vertices=dress.vertices * 100, faces=dress.faces))
    body = [ln for ln in (src / "plain.obj").read_text().splitlines() if not ln.startswith("#")]
    head = ["# Exported from Maya 2024", "mtllib garment.mtl", "mtllib gone.mtl", "usemtl cotton"]
    (src / "g.obj").write_text("\n".join(head + body) + "\n")
    (src / "garment.mtl").write_text("newmtl cotton\nKd 0.8 0.8 0.8\n")

    def fit(source, output):
        r = CliRunner().invoke(cli, ["garment", "fit", str(source), "-o", str(output), "--units", "cm"])
        assert r.exit_code == 0, r.output
        return r.output, output.read_text().splitlines()

    said, lines = fit(src / "g.obj", out / "fit.obj")
    libs = [ln.split(maxsplit=1)[1] for ln in lines if ln.startswith("mtllib")]
    assert libs == ["../../maya/garment.mtl"] and all((out / x).is_file() for x in libs), lines[:5]
    assert "mtllib gone.mtl: no such file" in said and "written as ../../maya/garment.mtl" in said, said
    assert lines[0].startswith("# segadeform garment fit: units cm, up y, scale 1 (segadeform ")
    assert __version__ in lines[0] and lines[1] == "# Exported from Maya 2024", lines[:3]
    assert recorded_betas(out / "fit.obj") is None  # a file from elsewhere records no shape, as before
    np.testing.assert_allclose(read_mesh(out / "fit.obj").vertices, dress.vertices, atol=1e-5)
    # beside its source, the library is named as it was; a unit fix keeps the shape the source records
    # (a shape the dress, made for the default body, still sits on: a plain fix is checked on the recorded shape)
    (src / "made.obj").write_text("# segadeform garment: kind=dress\n# betas: 0.1\n" + "\n".join(head + body) + "\n")
    _, lines = fit(src / "made.obj", src / "fit.obj")
    assert [ln for ln in lines if ln.startswith("mtllib")] == ["mtllib garment.mtl"]
    assert recorded_betas(src / "fit.obj") == (0.1,) and sum("betas:" in ln for ln in lines) == 1


def test_a_garment_facing_another_way_is_named_with_the_turn(tmp_path, body):
    """A new user's trial: a shirt turned 180 degrees about the up axis, and a cm, z-up, +x-facing one (Unreal
    Engine's) read in cm with +z up, were said to be made for another body (`--from-body THEIR_BODY.obj`).  The
    check tries the garment turned about the up axis, and names the turn; `garment fit --turn` applies it."""
    from segadeform.garments import GarmentParams, make_garment
    from segadeform.io import Mesh, write_obj

    g = make_garment("tshirt", body, None, GarmentParams())
    rest = body.shaped_vertices()[0]
    check_placement(g.vertices, rest, body.faces)  # it sits as made
    np.testing.assert_allclose(fix_units_and_axes([[0.0, 0.0, 1.0]], turn=90), [[1.0, 0.0, 0.0]], atol=1e-12)
    back = fix_units_and_axes(g.vertices, turn=180)
    with pytest.raises(
        PlacementError, match=r"turned 180 degrees.*faces -z \(backward\).*fit g\.obj -o FIXED\.obj --turn 180`"
    ):
        check_placement(back, rest, body.faces, path=Path("g.obj"))
    # the file in cm, +z up, facing +x: what --units cm --up z --turn 270 brings back
    rot = fix_units_and_axes(np.eye(3), up="z", turn=270).T
    ue = (g.vertices * 100) @ rot
    np.testing.assert_allclose(fix_units_and_axes(ue, units="cm", up="z", turn=270), g.vertices, atol=1e-9)
    with pytest.raises(PlacementError, match=r"read in cm with \+z up, turned 270.*--units cm --up z --turn 270`"):
        check_placement(ue, rest, body.faces, path=Path("g.obj"))
    write_obj(tmp_path / "ue.obj", Mesh(vertices=ue, faces=g.faces))
    out = tmp_path / "fixed.obj"

    def fit(*extra):
        return CliRunner().invoke(cli, ["garment", "fit", str(tmp_path / "ue.obj"), "-o", str(out), *extra])

    r = fit("--units", "cm", "--up", "z")  # read right, facing +x: the turn is named with the options given
    assert r.exit_code == 1 and "faces +x" in r.output and "--units cm --up z --turn 270`" in r.output, r.output
    assert "another body" not in r.output and not out.exists()
    r = fit("--units", "cm", "--up", "z", "--turn", "270")
    assert r.exit_code == 0 and "turn 270" in r.output, r.output
    np.testing.assert_allclose(read_mesh(out).vertices, g.vertices, atol=1e-5)
    r = fit("--mhclo", str(SAMPLES / "skirt_short_f.mhclo"), "--turn", "90")
    assert r.exit_code == 1 and "got --turn" in r.output, r.output


def test_folded_edges_counts_faces_folded_onto_each_other():
    """A technical artist's trial: `garment fit --from-body` carried a 20k-vertex dress onto a coarser body's facets
    and folded 544 pairs of neighbouring faces (a zig-zag down the skirt) with no word; the fit now says how many it
    added.  The count: a flat sheet and the sample dress have none; a sheet folded in half along a grid line has one
    per edge of the crease."""
    from segadeform.garments.registration import folded_edges
    from segadeform.geometry.primitives import grid_plane

    v, f = grid_plane(9, 9)  # x in [-0.5, 0.5] or [0, 1]: the crease on its middle grid line
    assert folded_edges(v, f) == 0
    sheet = read_mesh(ROOT / "samples" / "garments" / "dress.obj")
    assert folded_edges(sheet.vertices, sheet.faces) == 0
    mid = np.unique(v[:, 0])[4]
    w = v.copy()
    right = v[:, 0] > mid + 1e-9
    w[right, 0] = 2 * mid - v[right, 0]  # the right half laid back over the left ...
    w[right, 1] += 1e-3 * (v[right, 0] - mid)  # ... just above it
    assert folded_edges(w, f) == 8  # the 8 edges of the crease


def test_the_carry_is_smoothed_over_the_garment_so_a_coarse_body_leaves_no_zig_zag():
    """The carried displacement is smoothed over the garment's own edges (registration._smooth_carry): a dense sheet
    carried by a moved, turned frame plus a zig-zag across it (each vertex's offset turned with a coarse body's
    triangle: a technical artist's 20k-vertex dress came out with 433 folded pairs) keeps the move and the turn and
    loses the zig-zag's folds.  Measured end to end by hand: the sample dress subdivided (9,800 vertices) fitted from
    the default body decimated to 1,498 vertices, 312 folded pairs without the smoothing, 9 with it."""
    from segadeform.garments.registration import _smooth_carry, folded_edges
    from segadeform.geometry.primitives import grid_plane

    v, f = grid_plane(40, 40, (0.5, 0.5))
    turn = np.array([[np.cos(0.3), 0.0, np.sin(0.3)], [0.0, 1.0, 0.0], [-np.sin(0.3), 0.0, np.cos(0.3)]])
    rigid = v @ turn.T + [0.1, 1.0, -0.2]
    ij = np.round(v[:, [0, 2]] / (0.5 / 39)).astype(int)
    zig = rigid + np.array([0.0, 0.02, 0.0]) * ((ij.sum(axis=1) % 2) * 2 - 1)[:, None]  # 2 cm up and down, alternately
    assert folded_edges(zig, f) > 100
    out = _smooth_carry(v, zig, f)
    assert folded_edges(out, f) == 0
    inner = (ij.min(axis=1) >= 5) & (ij.max(axis=1) <= 34)  # away from the sheet's border
    assert np.abs(out - rigid)[inner].max() < 0.01  # the move and the turn kept, the 2 cm zig-zag down to < 1 cm
    # a vertex in no face keeps its own displacement
    v2, z2 = np.concatenate([v, [[9.0, 9.0, 9.0]]]), np.concatenate([zig, [[1.0, 2.0, 3.0]]])
    np.testing.assert_array_equal(_smooth_carry(v2, z2, f)[-1], [1.0, 2.0, 3.0])


def test_garment_fit_warns_when_most_of_what_it_writes_is_inside_the_body(tmp_path, body):
    """A pipeline TD's trial: a suit scaled by 0.95, moved as the advice then said, was written 62 % inside the body
    (2 % deeper than 1 cm, so `run` took it) with nothing but the percentage said.  A second skin 3 mm under the
    torso's surface (all of it inside, none deep) is written with a warning; the fitted sample garment is not."""
    from segadeform.geometry.mesh_ops import vertex_normals
    from segadeform.io import Mesh, write_obj

    rest = body.shaped_vertices()[0]
    faces = np.asarray(body.faces)
    torso = (rest[:, 1] > 1.0) & (rest[:, 1] < 1.4) & (np.abs(rest[:, 0]) < 0.15)
    keep = torso[faces].all(axis=1)
    used = np.unique(faces[keep])
    remap = np.full(len(rest), -1)
    remap[used] = np.arange(len(used))
    skin = rest[used] - 0.003 * vertex_normals(rest, faces)[used]
    write_obj(tmp_path / "skin.obj", Mesh(skin, remap[faces[keep]]))
    r = CliRunner().invoke(cli, ["garment", "fit", str(tmp_path / "skin.obj"), "-o", str(tmp_path / "out.obj")])
    assert r.exit_code == 0, r.output
    assert re.search(r"warning: out\.obj: (9\d|100)\.\d % of the garment lies inside the body", r.output), r.output
    r = CliRunner().invoke(cli, ["garment", "fit", str(SAMPLES / "skirt_short_f.obj"), "-o", str(tmp_path / "s.obj")])
    assert r.exit_code == 0 and "lies inside the body" not in r.output, r.output


def test_a_vertex_in_no_face_far_from_the_body_is_refused_near_ones_pass(body, dress, tmp_path):
    """A fuzzer's trial: the skirt plus `v 9000 9000 9000` in no face ran with exit 0, its stray point swung 3.9 km in
    a frame by the skinning.  Vertices in no face more than LOOSE_FAR from the body are refused (unless --force);
    those near it pass the check as before (they are left out of it)."""
    from segadeform.body.placement import LOOSE_FAR

    rest = body.shaped_vertices()[0]
    for far, ok in (([9000.0, 9000, 9000], False), ([1000.0, 0, 0], False), ([0.0, 1.0, 0.6], True)):
        v = np.vstack([dress.vertices, far])
        if ok:
            check_placement(v, rest, body.faces, faces=dress.faces, path=Path("g.obj"))
            continue
        with pytest.raises(
            PlacementError,
            match=rf"1 vertex in no face more than 1.00 m from the body \(the farthest, vertex {len(dress.vertices)}",
        ):
            check_placement(v, rest, body.faces, faces=dress.faces, path=Path("g.obj"))
    assert LOOSE_FAR == 1.0
    # the command: one line, exit 1, nothing written; --force plays it and says so
    g = tmp_path / "stray.obj"
    g.write_text(
        "".join(f"v {x:.6f} {y:.6f} {z:.6f}\n" for x, y, z in dress.vertices)
        + "v 9000 9000 9000\n"
        + "".join(f"f {a + 1} {b + 1} {c + 1}\n" for a, b, c in dress.faces)
    )
    out = tmp_path / "o.pc2"
    motion = ROOT / "samples" / "motions" / "walk.npz"
    args = ["run", "--garment", str(g), "--motion", str(motion), "--frames", "0:2", "-o", str(out)]
    r = CliRunner().invoke(cli, args)
    assert r.exit_code == 1 and "vertex in no face more than" in r.output and "stray.obj" in r.output
    # a garment in centimetres with a stray vertex among its own: told to be read in cm (the placement's advice), not
    # to delete the vertex (a review)
    cm = np.vstack([dress.vertices, dress.vertices[:1] + 0.01]) * 100
    with pytest.raises(PlacementError, match="once read in cm"):
        check_placement(cm, rest, body.faces, faces=dress.faces, path=Path("g.obj"))
    assert not out.exists()
    r = CliRunner().invoke(cli, [*args, "--force"])
    assert r.exit_code == 0 and out.exists(), r.output


def test_the_batched_jacobian_is_scipys_forward_differences():
    """`garment fit --from-body`'s least squares take the Jacobian from one batched body evaluation
    (registration._forward_differences): the same steps as scipy's '2-point' differences, bit for bit, within bounds
    wide or narrower than the step (a review: the first form left a box narrower than the step)."""
    from scipy.optimize._numdiff import approx_derivative

    from segadeform.garments.registration import _forward_differences

    rng = np.random.default_rng(0)
    a = rng.normal(size=(3, 4))

    def f(x):
        return np.sin(a @ x) + (x**2).sum()

    for _ in range(300):
        x0 = rng.normal(size=4) * rng.choice([1e-3, 1.0, 100.0])
        width = rng.choice([np.inf, 1.0, 3e-8, 1e-9])
        lo, hi = x0 - rng.uniform(0, 1, 4) * width, x0 + rng.uniform(0, 1, 4) * width
        want = approx_derivative(f, x0, method="2-point", bounds=(lo, hi))
        got = _forward_differences(lambda xs: np.array([f(x) for x in xs]), x0, lo, hi)
        assert got.shape == (3, 4) and np.array_equal(got, want), (x0, lo, hi)
