"""Skinning-weight priors: closest point and inpainted (segadeform.body.transfer)."""

import numpy as np
import pytest

from segadeform.body.model import default_body_path, load_body
from segadeform.body.transfer import (
    garment_weights,
    inpaint_transfer_weights,
    inpaint_weights,
    transfer_weights,
)
from segadeform.errors import InputError
from segadeform.garments import make_garment
from segadeform.geometry.primitives import grid_plane


@pytest.fixture(scope="module")
def body():
    return load_body(default_body_path())


def test_inpainting_keeps_the_known_rows_and_is_harmonic_elsewhere():
    v, f = grid_plane(7, 7, (1.0, 1.0))
    w = np.zeros((len(v), 2))
    left, right = v[:, 0] < 1e-9, v[:, 0] > 1 - 1e-9
    w[left, 0] = 1
    w[right, 1] = 1
    w[~(left | right)] = [0.9, 0.1]  # arbitrary: replaced
    out = inpaint_weights(v, f, w, left | right)
    assert np.array_equal(out[left | right], w[left | right])
    # the harmonic interpolation between the two sides is linear in x on a regular grid
    np.testing.assert_allclose(out[:, 1], v[:, 0], atol=1e-9)
    np.testing.assert_allclose(out.sum(1), 1.0)


def test_a_piece_with_nothing_known_keeps_its_weights_and_nothing_known_is_a_copy():
    v1, f1 = grid_plane(3, 3)
    v2, f2 = grid_plane(3, 3)
    v = np.concatenate([v1, v2 + 5.0])
    f = np.concatenate([f1, f2 + len(v1)])
    w = np.random.default_rng(0).dirichlet(np.ones(3), len(v))
    known = np.zeros(len(v), bool)
    known[:2] = True
    out = inpaint_weights(v, f, w, known)
    np.testing.assert_array_equal(out[len(v1) :], w[len(v1) :])
    np.testing.assert_array_equal(inpaint_weights(v, f, w, np.zeros(len(v), bool)), w)
    with pytest.raises(InputError, match="must match"):
        inpaint_weights(v, f, w[:-1], known)


def test_a_tight_garment_keeps_the_body_weights_and_a_skirt_hem_blends_both_legs(body):
    rest = body.shaped_vertices()[0]
    tee = make_garment("tshirt", body)
    near = transfer_weights(tee.vertices, rest, body.faces, body.weights)
    inp = garment_weights(tee.vertices, tee.faces, body, None, "inpaint")
    assert np.abs(inp - near).max(axis=1).mean() < 0.05  # nearly all of a T-shirt lies on the body
    skirt = make_garment("skirt", body)
    near = transfer_weights(skirt.vertices, rest, body.faces, body.weights)
    inp = inpaint_transfer_weights(skirt.vertices, skirt.faces, rest, body.faces, body.weights)
    np.testing.assert_allclose(inp.sum(1), 1.0, atol=1e-12)
    assert (inp >= 0).all()
    hem = skirt.vertices[:, 1] < skirt.vertices[:, 1].min() + 0.02
    # SMPL: 1 left hip, 2 right hip.  Closest-point weights give each hem vertex (nearly) one leg;
    # inpainted ones give every hem vertex some of both
    both = lambda w: np.minimum(w[:, 1], w[:, 2])  # noqa: E731
    assert np.median(both(near[hem])) < 0.05 and np.median(both(inp[hem])) > 0.1


KERNEL_PRIORS = ("idw", "gaussian", "smooth", "smooth-light")


@pytest.mark.parametrize("prior", ("nearest", "inpaint") + KERNEL_PRIORS)
def test_every_prior_sums_to_one_is_non_negative_and_is_the_body_on_the_skin(body, prior):
    """Each prior: weights >= 0 summing to 1 on a loose garment; on a garment lying on the skin (a patch of the
    body's own surface) exactly the body's weights there, and within 0.01 of them 1 mm out (the closest point is
    then between vertices)."""
    skirt = make_garment("skirt", body)
    w = garment_weights(skirt.vertices, skirt.faces, body, None, prior)
    assert w.shape == (len(skirt.vertices), body.weights.shape[1])
    assert (w >= 0).all() and np.allclose(w.sum(1), 1.0, atol=1e-9)
    from segadeform.geometry.mesh_ops import vertex_normals

    rest = body.shaped_vertices()[0]
    n = vertex_normals(rest, body.faces)
    torso = np.flatnonzero((rest[:, 1] > 1.0) & (rest[:, 1] < 1.3) & (np.abs(rest[:, 0]) < 0.12))
    keep = np.isin(body.faces, torso).all(axis=1)
    faces = body.faces[keep]
    used = np.unique(faces)
    remap = -np.ones(len(rest), np.int64)
    remap[used] = np.arange(len(used))
    w = garment_weights(rest[used], remap[faces], body, None, prior)  # on the skin
    np.testing.assert_allclose(w, body.weights[used], atol=1e-6)
    w = garment_weights(rest[used] + 0.001 * n[used], remap[faces], body, None, prior)  # 1 mm out
    np.testing.assert_allclose(w, body.weights[used], atol=0.01)


def test_kernel_priors_blend_both_legs_at_a_skirt_hem(body):
    """The point of the kernel priors: a hem vertex in front of the legs takes both legs' weights, not one."""
    skirt = make_garment("skirt", body)
    v = skirt.vertices
    hem = v[:, 1] < v[:, 1].min() + 0.03
    front = hem & (np.abs(v[:, 0]) < 0.03) & (v[:, 2] > 0)
    assert front.sum() >= 2
    near = garment_weights(v, skirt.faces, body, None, "nearest")[front]
    for prior in KERNEL_PRIORS:
        w = garment_weights(v, skirt.faces, body, None, prior)[front]
        # left (1, 4) and right (2, 5) hip and knee: closer to an even split than the closest point's
        left, right = w[:, [1, 4]].sum(1), w[:, [2, 5]].sum(1)
        nl, nr = near[:, [1, 4]].sum(1), near[:, [2, 5]].sum(1)
        assert np.abs(left - right).mean() < np.abs(nl - nr).mean(), prior
        assert (np.minimum(left, right) > 0.15).all(), prior


def test_unknown_prior_is_refused(body):
    skirt = make_garment("skirt", body)
    with pytest.raises(InputError, match="unknown skinning-weight prior"):
        garment_weights(skirt.vertices, skirt.faces, body, None, "magic")


def test_smooth_light_is_between_the_closest_point_and_smooth(body):
    """``smooth-light`` smooths with a quarter of ``smooth``'s strength: on a loose skirt its weights move away
    from the closest point's, but less far than ``smooth``'s, vertex by vertex on the hem and in all."""
    skirt = make_garment("skirt", body)
    v, f = skirt.vertices, skirt.faces
    near = garment_weights(v, f, body, None, "nearest")
    light = garment_weights(v, f, body, None, "smooth-light")
    full = garment_weights(v, f, body, None, "smooth")
    d_light, d_full = np.abs(light - near).sum(1), np.abs(full - near).sum(1)
    hem = v[:, 1] < v[:, 1].min() + 0.03
    assert d_light[hem].mean() > 0.1  # it smooths ...
    assert (d_light[hem] <= d_full[hem] + 1e-9).mean() > 0.9 and d_light.sum() < d_full.sum()  # ... less


@pytest.mark.parametrize("bad", (-1.0, float("nan"), float("inf")))
def test_smoothing_strength_must_be_finite_and_non_negative(body, bad):
    from segadeform.body.transfer import smooth_transfer_weights

    skirt = make_garment("skirt", body)
    rest = body.shaped_vertices()[0]
    with pytest.raises(InputError, match="smoothing strength"):
        smooth_transfer_weights(skirt.vertices, skirt.faces, rest, body.faces, body.weights, strength=bad)
