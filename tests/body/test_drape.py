"""The drape at rest (segadeform.body.drape): loose parts hang lower, the parts on the body stay, nothing ends inside
the body, the same inputs give the same bits, a garment on the skin comes back unchanged; the partial drape and the
memo of skinned_rest; bad input is refused with what was expected."""

from __future__ import annotations

import numpy as np
import pytest

from segadeform.body import default_body_path, load_body
from segadeform.body.cloth import compiled_available, rest_signed_distance
from segadeform.body.drape import DRAPE_SETTINGS, drape_rest, partial_drape, skinned_rest
from segadeform.errors import InputError
from segadeform.geometry.mesh_ops import vertex_normals
from segadeform.geometry.primitives import frustum

MARGIN = 0.004  # the cloth stage's default contact margin, which the drape uses


@pytest.fixture(scope="module")
def body():
    assert compiled_available(), "the compiled cloth kernel is not built (pip install -e . builds it)"
    return load_body(default_body_path())


@pytest.fixture(scope="module")
def skirt(body):
    """A flared skirt (a cone from the hips, 15 cm at the waist to 36 cm at the hem) and its drape."""
    rb = body.shaped_vertices()[0]
    v, f = frustum(24, 10, 0.15, 0.36, 1.0, 0.45)
    return v, f, rb, drape_rest(v, f, rb, body.faces)


def test_a_flared_skirt_hangs_lower_and_closer_while_its_waistband_stays(body, skirt):
    v, f, rb, d = skirt
    sd = rest_signed_distance(v, rb, body.faces)
    held = (sd <= DRAPE_SETTINGS.attachment) & (sd > MARGIN)  # attached and clear of the body: never moved
    assert held.sum() >= 10
    np.testing.assert_array_equal(d[held], v[held])
    hem = v[:, 1] < 0.46
    assert d[hem, 1].mean() < v[hem, 1].mean() - 0.01  # the hem falls (2-3 cm here)
    assert np.hypot(d[hem, 0], d[hem, 2]).mean() < np.hypot(v[hem, 0], v[hem, 2]).mean()  # and comes in
    assert rest_signed_distance(d, rb, body.faces).min() >= MARGIN - 1e-9  # nothing inside the body
    assert np.isfinite(d).all() and d.shape == v.shape


def test_the_drape_is_deterministic(body, skirt):
    v, f, rb, d = skirt
    np.testing.assert_array_equal(drape_rest(v, f, rb, body.faces), d)


def test_a_garment_on_the_skin_comes_back_unchanged(body):
    """A patch of the body itself, 1 cm out along its normals: every vertex within the attachment and clear of
    the body, so the drape leaves it as it is."""
    rb = body.shaped_vertices()[0]
    torso = np.flatnonzero((rb[:, 1] > 1.1) & (rb[:, 1] < 1.3))
    keep = np.isin(body.faces, torso).all(axis=1)
    used, faces = np.unique(body.faces[keep], return_inverse=True)
    faces = faces.reshape(-1, 3)
    v = rb[used] + 0.01 * vertex_normals(rb, body.faces)[used]
    sd = rest_signed_distance(v, rb, body.faces)
    assert (sd > MARGIN).all() and (sd <= DRAPE_SETTINGS.attachment).all()
    np.testing.assert_array_equal(drape_rest(v, faces, rb, body.faces), v)


def test_partial_drape_goes_from_the_rest_to_the_drape(skirt):
    v, _, _, d = skirt
    np.testing.assert_array_equal(partial_drape(v, d, 0.0), v)
    np.testing.assert_allclose(partial_drape(v, d, 1.0), d, atol=1e-15)
    np.testing.assert_allclose(partial_drape(v, d, 0.5), (v + d) / 2, atol=1e-15)
    with pytest.raises(InputError, match=r"\[0, 1\]"):
        partial_drape(v, d, 1.5)
    with pytest.raises(InputError, match="shape"):
        partial_drape(v, d[:-1], 0.5)


def test_skinned_rest_is_the_rest_at_zero_and_remembers_drapes(body, skirt):
    v, f, _, d = skirt
    np.testing.assert_array_equal(skinned_rest(v, f, body, None, 0.0), v)
    memo: dict = {}
    half = skinned_rest(v, f, body, np.zeros(0), 0.5, memo)
    np.testing.assert_allclose(half, (v + d) / 2, atol=1e-15)
    assert len(memo) == 1 and skinned_rest(v, f, body, None, 0.5, memo) is half  # empty betas = the template
    other = skinned_rest(v, f, body, np.array([1.0, 0.5]), 0.5, memo)  # another body shape: another drape
    assert len(memo) == 2 and not np.array_equal(other, half)


def test_bad_input_is_refused(body, skirt):
    v, f, rb, _ = skirt
    with pytest.raises(InputError, match="faces"):
        drape_rest(v, np.zeros((0, 3), np.int64), rb, body.faces)
    with pytest.raises(InputError, match="2 frames"):
        drape_rest(v, f, rb, body.faces, frames=1)
    bad = v.copy()
    bad[3] = np.nan
    with pytest.raises(InputError):
        drape_rest(bad, f, rb, body.faces)
