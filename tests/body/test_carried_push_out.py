"""The push-out with the correction carried from frame to frame (``BodyCollider.push_out(..., carry=)``,
``_collide.c``'s sdc_push_out_carried, the reference :func:`~segadeform.body.collision.carry_correction`).

The case is a limb passing through cloth: a sphere moving along z through a sheet of points in the plane z = 0.
The closest exit of a point the sphere has swallowed is ahead of the sphere's centre until the centre passes it,
then behind it: without the carried correction a swallowed point jumps across the sphere in one frame (the pops of
``docs/cloth-eval.md``); with it, it stays on the side it was pushed to while the bounds of the rule allow."""

import numpy as np
import pytest

from segadeform.body.collision import BodyCollider, ReferenceCollider
from segadeform.body.collision.reference import CARRY_GROW, CARRY_LIMB, PINCH, body_size
from segadeform.errors import InputError
from tests.body._shapes import sphere, with_reach

MARGIN = 0.004
RADIUS = 0.3


def _limb_through_a_sheet(frames=25, reach=10.0, jitter=0.0, extent=0.35):
    """The body (a sphere of radius 0.3 and, far away, the small sphere of ``with_reach``: the body's size about
    ``reach``, so that the rule's bound, ``PINCH`` times it, is about 12 cm at 10), its posed frames (the sphere's
    centre moving along z from -0.33 to +0.33, each step under the rule's growth bound; with ``jitter``, instead
    alternating between -jitter and +jitter) and a sheet of points at z = 0 within ``extent`` of the axis."""
    v, f = sphere(32, 24)
    v, f = with_reach(v * RADIUS, f, reach)
    limb = np.arange(len(v)) < 32 * 22 + 2  # the sphere's vertices come first
    z = np.linspace(-0.33, 0.33, frames) if not jitter else jitter * (-1.0) ** np.arange(frames)
    posed = np.repeat(v[None], frames, axis=0)
    posed[:, limb, 2] += z[:, None]
    g = np.linspace(-extent, extent, 15)
    x, y = np.meshgrid(g, g)
    # off the grid a little: no point equally near two faces (where the backends may take either)
    sheet = np.stack([x.ravel(), y.ravel(), np.zeros(x.size)], 1) + np.random.default_rng(3).uniform(
        -0.2, 0.2, (x.size, 3)
    ) * [g[1] - g[0], g[1] - g[0], 0.01]
    points = np.repeat(sheet[None], frames, axis=0)
    return v, f, posed, points


def _run(col, posed, points, *, batch, carry=True):
    c = np.zeros((points.shape[1], 3)) if carry else None
    out = [
        col.push_out(points[lo : lo + batch], posed[lo : lo + batch], MARGIN, carry=c)[0]
        for lo in range(0, len(points), batch)
    ]
    return np.concatenate(out), c


def _jumps(x):
    return np.linalg.norm(np.diff(x, axis=0), axis=2)


def test_the_cases_are_what_the_docstrings_say():
    v, f, posed, points = _limb_through_a_sheet()
    lim = PINCH * body_size(posed[0], f)
    assert 0.1 < lim and np.diff(posed[:, 0, 2]).max() < CARRY_GROW * lim  # each step within the growth bound
    v, f, posed, points = _limb_through_a_sheet(frames=12, jitter=0.01, extent=0.02)
    lim = PINCH * body_size(posed[0], f)
    assert 2 * 0.01 < CARRY_GROW * lim


def test_a_point_deep_in_a_jittering_limb_stays_on_the_side_it_was_pushed_to():
    """The pops of real motion: the closest exit of a point near a limb's middle flips side with every small move
    of the limb; with the carried correction it keeps the side of the frame before."""
    v, f, posed, points = _limb_through_a_sheet(frames=12, jitter=0.01, extent=0.02)
    col = BodyCollider(v, f)
    plain, _ = _run(col, posed, points, batch=12, carry=False)
    carried, carry = _run(col, posed, points, batch=12)
    assert (_jumps(plain) > 0.3).sum() > 100  # across the sphere, frame after frame
    assert not (_jumps(carried) > 0.05).any(), _jumps(carried).max()
    for t in range(len(posed)):  # every point out of the body, as the push-out leaves it
        assert (col.query(carried[t], posed[t]).signed_distance > MARGIN - 1e-9).all()
    np.testing.assert_array_equal(carry, carried[-1] - points[-1])  # the last frame's correction


def test_a_point_a_limb_sweeps_through_is_carried_within_the_bounds():
    """A sphere sweeping through the sheet: a swallowed point near its path stays ahead of it after the centre has
    passed it, until the carried move would exceed ``CARRY_LIMB`` times the closest exit's plus the bound; every
    frame's move is within that."""
    v, f, posed, points = _limb_through_a_sheet()
    col = BodyCollider(v, f)
    plain, _ = _run(col, posed, points, batch=25, carry=False)
    carried, _ = _run(col, posed, points, batch=25)
    lim = PINCH * body_size(posed[0], f)
    mid = np.argmin(np.linalg.norm(points[0], axis=1))  # the point on the sphere's path through its centre
    centre = posed[:, : 32 * 22 + 2, 2].mean(axis=1)
    behind = centre > 1e-9
    assert (carried[behind, mid, 2] > centre[behind]).sum() >= 3  # still ahead of the passed centre
    assert (plain[behind, mid, 2] < centre[behind]).all()  # the closest exit: behind it
    move, closest = (np.linalg.norm(x - points, axis=2) for x in (carried, plain))
    assert (move <= CARRY_LIMB * closest + lim + 1e-12).all()


def test_a_carried_move_grows_at_most_the_bound_a_frame():
    """A sphere sweeping through the sheet faster than the growth bound allows a carried move to grow (6 cm a frame
    against 3 cm): the rule keeps carrying where it may, and where carrying would grow a vertex's move by more than
    ``CARRY_GROW`` times the bound it takes the closest exit instead (a review: no test failed without that bound)."""
    v, f, posed, points = _limb_through_a_sheet(frames=12)
    col = BodyCollider(v, f)
    plain, _ = _run(col, posed, points, batch=12, carry=False)
    carried, _ = _run(col, posed, points, batch=12)
    lim = PINCH * body_size(posed[0], f)
    assert np.diff(posed[:, 0, 2]).min() > 1.5 * CARRY_GROW * lim
    move = np.linalg.norm(carried - points, axis=2)
    kept = np.any(carried != plain, axis=2)
    assert kept.sum() > 20  # carried somewhere
    assert (move[1:][kept[1:]] <= move[:-1][kept[1:]] + CARRY_GROW * lim + 1e-12).all()
    # ... and the bound decided: exits nearer the carried correction, within the other bound, refused by this one
    refused = 0
    for t in range(1, len(points)):
        k0, k = carried[t - 1] - points[t - 1], plain[t] - points[t]
        active = (np.linalg.norm(k - k0, axis=1) > lim) & np.any(k0 != 0, axis=1) & ~kept[t]
        a = col.push_out(points[t][active] + k0[active], posed[t], MARGIN)[0] - points[t][active]
        near = np.linalg.norm(a - k0[active], axis=1) < np.linalg.norm(k[active] - k0[active], axis=1)
        limb = np.linalg.norm(a, axis=1) <= CARRY_LIMB * np.linalg.norm(k[active], axis=1) + lim
        grow = np.linalg.norm(a, axis=1) > np.linalg.norm(k0[active], axis=1) + CARRY_GROW * lim
        refused += int((near & limb & grow).sum())
    assert refused >= 3, refused


@pytest.mark.parametrize("batch", [1, 4, 25])
@pytest.mark.parametrize("case", ["sweep", "jitter"])
def test_streams_backends_threads_and_the_reference_agree(batch, case):
    kw = {} if case == "sweep" else {"frames": 12, "jitter": 0.01, "extent": 0.02}
    v, f, posed, points = _limb_through_a_sheet(**kw)
    whole, carry = _run(BodyCollider(v, f), posed, points, batch=25)
    cut, carry_cut = _run(BodyCollider(v, f, threads=2), posed, points, batch=batch)
    np.testing.assert_array_equal(cut, whole)  # bit for bit: any cut of the stream, any threads
    np.testing.assert_array_equal(carry_cut, carry)
    # the numpy twin and the exhaustive reference on every third frame (each is ~100x slower than C; a carried
    # stream all the same, the frames further apart)
    mine, _ = _run(BodyCollider(v, f), posed[::3], points[::3], batch=batch)
    numpy, _ = _run(BodyCollider(v, f, backend="numpy"), posed[::3], points[::3], batch=batch)
    np.testing.assert_allclose(numpy, mine, rtol=0, atol=1e-9)
    ref, _ = _run(ReferenceCollider(v, f), posed[::3], points[::3], batch=batch)
    np.testing.assert_allclose(ref, mine, rtol=0, atol=1e-9)


def test_a_zero_carry_starts_as_the_plain_push_out():
    v, f, posed, points = _limb_through_a_sheet()
    col = BodyCollider(v, f)
    plain, n_plain = col.push_out(points[:1], posed[:1], MARGIN)
    carried, n = col.push_out(points[:1], posed[:1], MARGIN, carry=np.zeros((points.shape[1], 3)))
    np.testing.assert_array_equal(carried, plain)  # a zero carry: nothing to keep
    assert n == n_plain


@pytest.mark.parametrize(
    "carry, why",
    [
        (np.zeros((3, 3)), "row per point"),
        (np.zeros((225, 3), np.float32), "float64"),
        (np.zeros((225, 6))[:, ::2], "C-contiguous"),
        (np.full((225, 3), np.nan), "NaN"),
        ([[0.0, 0.0, 0.0]] * 225, "numpy array"),
    ],
)
def test_a_bad_carry_is_refused(carry, why):
    v, f, posed, points = _limb_through_a_sheet(frames=2)
    with pytest.raises(InputError, match=why):
        BodyCollider(v, f).push_out(points, posed, MARGIN, carry=carry)
