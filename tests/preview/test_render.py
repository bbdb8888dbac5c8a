"""The preview renderer: its depth buffer against a slow per-pixel reference, and what it shows."""

from __future__ import annotations

import numpy as np
import pytest

from segadeform.errors import InputError
from segadeform.preview.render import MeshLayer, rasterize, render


def _rasterize_reference(pix: np.ndarray, width: int, height: int) -> np.ndarray:
    """Every pixel centre against every triangle, one at a time: the nearest covering one, ties to the lower index."""
    best = np.full(height * width, -1, np.int64)
    for j in range(height):
        for i in range(width):
            px, py, top = i + 0.5, j + 0.5, -np.inf
            for t, ((xa, ya, za), (xb, yb, zb), (xc, yc, zc)) in enumerate(pix):
                area = (xb - xa) * (yc - ya) - (xc - xa) * (yb - ya)
                if area == 0:
                    continue
                w0 = ((xb - px) * (yc - py) - (xc - px) * (yb - py)) / area
                w1 = ((xc - px) * (ya - py) - (xa - px) * (yc - py)) / area
                w2 = 1.0 - w0 - w1
                if min(w0, w1, w2) < 0:
                    continue
                d = w0 * za + w1 * zb + w2 * zc
                if d > top:
                    top, best[j * width + i] = d, t
    return best


def test_the_depth_buffer_is_the_reference():
    rng = np.random.default_rng(0)
    w, h = 23, 17
    pix = np.concatenate(
        [
            rng.uniform([-4, -4, -1], [w + 4, h + 4, 1], size=(40, 3, 3)),  # large, overlapping, partly outside
            rng.uniform(0, 1, (30, 1, 3)) * [w, h, 1] + rng.normal(0, 1.5, (30, 3, 3)),  # small ones
            [[[2.0, 2.0, 0.0], [9.0, 9.0, 0.0], [16.0, 16.0, 0.0]]],  # degenerate: covers nothing
        ]
    )
    fast = rasterize(pix, w, h, chunk=97)  # many chunks
    np.testing.assert_array_equal(fast, _rasterize_reference(pix, w, h))
    np.testing.assert_array_equal(fast, rasterize(pix, w, h))
    assert len(np.unique(fast)) > 30  # the test means something: many triangles win pixels


def test_cloth_just_outside_a_large_body_triangle_hides_it():
    """A small cloth patch 3 mm in front of a large tilted body triangle, where the body triangle's centre is nearer
    than the patch's: sorting whole triangles by mean depth draws the skin over the cloth; the depth buffer does
    not."""
    body_v = np.array([[-1.0, -1.0, 0.5], [1.0, -1.0, 0.5], [0.0, 1.0, -0.5]])  # leans back toward +y
    patch = np.array([[-0.05, 0.7, 0.0], [0.05, 0.7, 0.0], [0.0, 0.8, 0.0]])
    patch[:, 2] = 0.5 - (patch[:, 1] + 1.0) / 2.0 + 0.003  # 3 mm in front of the body plane there
    assert patch[:, 2].mean() < body_v[:, 2].mean()  # a painter's algorithm would draw the body last
    img = render(
        [MeshLayer(body_v, [[0, 1, 2]], (1.0, 0.0, 0.0)), MeshLayer(patch, [[0, 1, 2]], (0.0, 0.0, 1.0))],
        elevation=0.0,
        size=(200, 200),
        bounds=((-1.0, 1.0), (-1.0, 1.0)),
    )
    blue = (img[..., 2] > 100) & (img[..., 0] < 50)
    assert blue.sum() > 20  # the patch is seen ...
    # ... and it is whole: every pixel centre inside it is blue
    ys, xs = np.mgrid[0:200, 0:200]
    cx, cy = -1 + (xs + 0.5) / 100, 1 - (ys + 0.5) / 100
    inside = (cy >= 0.7) & (cy <= 0.8 - 2 * np.abs(cx) * 1.0) & (np.abs(cx) <= 0.05)
    assert inside.sum() > 20 and blue[inside].all()


def test_bad_layers_are_refused():
    with pytest.raises(InputError, match="nothing to render"):
        render([])
    with pytest.raises(InputError):
        MeshLayer(np.zeros((3, 2)), [[0, 1, 2]])


def test_hard_triangles_cover_what_they_should():
    """A triangle far larger than the image covers every pixel; one smaller than a pixel covers at most one; a
    degenerate one and one with a non-finite corner cover nothing; huge coordinates do not overflow the pair count."""
    w, h = 16, 12
    huge = [[[-1e9, -1e9, 0.0], [3e9, -1e9, 0.0], [-1e9, 3e9, 0.0]]]
    assert (rasterize(np.array(huge), w, h) == 0).all()
    tiny = [[[5.4, 5.4, 0.0], [5.6, 5.4, 0.0], [5.4, 5.6, 0.0]]]
    assert (rasterize(np.array(tiny), w, h) >= 0).sum() == 1
    bad = [[[1.0, 1.0, 0.0], [1.0, 1.0, 0.0], [9.0, 9.0, 0.0]], [[1.0, 1.0, 0.0], [np.nan, 2.0, 0.0], [9.0, 1.0, 0.0]]]
    assert (rasterize(np.array(bad), w, h) == -1).all()
    assert (rasterize(np.zeros((0, 3, 3)), w, h) == -1).all()


def test_a_subject_of_no_extent_renders_blank_without_warnings():
    """Every point in one place (a cache of zeros): the framing had no size and rendering divided by it (NaN
    warnings from numpy, a user's preview of such a cache)."""
    import warnings

    from segadeform.preview.render import fit_bounds

    v, f = np.zeros((3, 3)), np.array([[0, 1, 2]])
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        img = render([MeshLayer(v, f)], size=(20, 10), bounds=fit_bounds(v, size=(20, 10)))
        assert img.shape == (10, 20, 3) and (img == 255).all()
        assert (render([MeshLayer(v, f)], size=(20, 10)) == 255).all()
