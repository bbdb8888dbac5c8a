"""The cloth stage (segadeform.body.cloth, the compiled kernel _cloth.c): against its slow reference, and what the
rule promises -- attached vertices follow the network exactly, free ones stay within their radius, nothing is left
inside the body, edges are pulled back toward their stretch limit, inertia and gravity act on loose parts, batches and
streams give the frames of one long call, a jump resets the state once with one message, NaN is refused."""

from __future__ import annotations

import dataclasses
import logging

import numpy as np
import pytest

from segadeform.body import default_body_path, load_body
from segadeform.body.cloth import (
    CONTACT_BAND,
    ClothSettings,
    ClothStage,
    cloth_reference,
    cloth_setup,
    cloth_setup_reference,
    compiled_available,
    garment_setup,
    rest_signed_distance,
    settings_array,
)
from segadeform.body.collision import BodyCollider
from segadeform.errors import InputError
from segadeform.geometry.primitives import frustum, grid_plane
from segadeform.motion import make_motion

MARGIN = 0.004


@pytest.fixture(scope="module")
def body():
    return load_body(default_body_path())


@pytest.fixture(scope="module")
def walk(body):
    """A thin skirt partly inside the hips, skinned rigidly to the pelvis over a walk (targets that push through
    the thighs), the posed body, and the skirt's setup."""
    assert compiled_available(), "the compiled cloth kernel is not built (pip install -e . builds it)"
    v, f = frustum(20, 8, 0.13, 0.26, 1.0, 0.5)
    m = make_motion("walk", seconds=0.4, seed=0)
    posed = body.forward(m.poses, None, m.trans).vertices
    # each frame's target: the skirt carried by the root's translation only (the legs swing through it)
    targets = np.stack([v + t for t in m.trans])
    setup = garment_setup(v, f, body.shaped_vertices()[0], body.faces)
    return v, f, targets, posed, setup


def _stage(setup, body, settings=ClothSettings(), **kw):
    return ClothStage(setup, body.v_template, body.faces, settings, margin=MARGIN, **kw)


def test_setup_is_the_reference_on_hard_meshes(body):
    rest_body = body.shaped_vertices()[0]
    v, f = frustum(16, 6, 0.17, 0.33, 1.02, 0.55)
    meshes = {
        "skirt": (v, f),
        # repeated-vertex and collinear faces, a duplicate face, vertices in no face
        "degenerate": (
            np.vstack([v, v[0], (v[0] + v[1]) / 2, [[0.0, 1.5, 0.0]]]),
            np.vstack([f, [[0, 1, len(v) + 1]], [[0, len(v), 1]], f[:3]]),
        ),
        "strip": (grid_plane(30, 2, size=(0.6, 0.02))[0] + [-0.3, 1.0, 0.2], grid_plane(30, 2, size=(0.6, 0.02))[1]),
        # split along a seam (as exports split UV seams), and a vertex at -0.0 where another is at 0.0
        "split": _split(v, f),
        "signed zero": (np.vstack([v, [[0.0, 1.5, 0.0]], [[-0.0, 1.5, 0.0]]]), f),
    }
    for name, (vv, ff) in meshes.items():
        sd = rest_signed_distance(vv, rest_body, body.faces)
        for s in (ClothSettings(), ClothSettings(attachment=0.0, max_distance=0.2)):
            a, b = cloth_setup(vv, ff, sd, s), cloth_setup_reference(vv, ff, sd, s)
            for k in ("edges", "rest_len", "nptr", "nidx", "radius", "anchor", "tether", "weld"):
                np.testing.assert_array_equal(getattr(a, k), getattr(b, k), err_msg=f"{name} {k}")
            a.validate()
            assert (a.edges[:, 0] < a.edges[:, 1]).all() and len(np.unique(a.edges, axis=0)) == len(a.edges)
            assert (a.radius <= s.max_distance).all() and (a.radius[sd <= s.attachment] == 0).all()
    # the isolated vertex has no neighbours; the copy of vertex 0 is welded to it, so the face holding both makes one
    # edge, not a zero-length one
    a = cloth_setup(*meshes["degenerate"], rest_signed_distance(meshes["degenerate"][0], rest_body, body.faces))
    assert a.nptr[-1] - a.nptr[-2] == 0
    assert a.weld[len(v)] == 0 and (a.weld[: len(v)] == np.arange(len(v))).all() and a.weld[len(v) + 1] == len(v) + 1
    assert (a.rest_len > 0).all()
    # the split skirt's setup is the whole skirt's, its copies welded onto the vertices they were copied from
    sv, sf = meshes["split"]
    a = cloth_setup(sv, sf, rest_signed_distance(sv, rest_body, body.faces))
    b = cloth_setup(v, f, rest_signed_distance(v, rest_body, body.faces))
    np.testing.assert_array_equal(a.edges, b.edges)
    np.testing.assert_array_equal(a.weld[len(v) :], _twins(v, sv))
    a = cloth_setup(*meshes["signed zero"], rest_signed_distance(meshes["signed zero"][0], rest_body, body.faces))
    assert a.weld[-1] == len(v)


def _split(v, f):
    """The mesh split along x = 0 (tests.conftest.split_at_a_seam): the copies appended."""
    from segadeform.io import Mesh
    from tests.conftest import split_at_a_seam

    sv, sf, n = split_at_a_seam(Mesh(v, f))
    assert n > 5
    return sv, sf


def _twins(v, sv):
    """The vertex of ``v`` each appended copy in ``sv`` is at."""
    return np.array([int(np.flatnonzero((v == p).all(axis=1))[0]) for p in sv[len(v) :]])


def test_a_mesh_split_at_a_seam_moves_as_the_whole_mesh(walk, body):
    """Split along a seam (game-engine exports split vertices at UV seams), the stage gives the frames of the mesh
    before it was split, each copy where its twin is: a dress split so on a walk tore 7 cm at its seam, the push-out
    beside it 0 mm (2 Dec 2026).  The kernel and the reference agree on it."""
    v, f, targets, posed, setup = walk
    sv, sf = _split(v, f)
    split = garment_setup(sv, sf, body.shaped_vertices()[0], body.faces)
    st_targets = np.concatenate([targets, targets[:, _twins(v, sv)]], axis=1)
    whole = _stage(setup, body).step(targets, posed)
    stage = _stage(split, body)
    out = stage.step(st_targets, posed)
    np.testing.assert_array_equal(out[:, len(v) :], out[:, _twins(v, sv)])
    np.testing.assert_allclose(out[:, : len(v)], whole, atol=1e-12)
    assert np.abs(whole - targets).max() > 0.01 and stage.pushed > 0  # the stage moved the cloth: a test of something
    ref, _ = cloth_reference(st_targets, posed, body.faces, split, margin=MARGIN)
    assert np.abs(ref - out).max() <= 1e-9
    # a copy's own target is not its twin's: the copy still goes where its twin goes (one point of cloth)
    shifted = st_targets.copy()
    shifted[:, len(v) :] += 0.01
    np.testing.assert_array_equal(_stage(split, body).step(shifted, posed)[:, len(v) :], out[:, len(v) :])


def test_tethers_anchor_free_vertices_to_the_nearest_attached_one():
    """Each free vertex's anchor is the attached vertex nearest along the edges (ties: the smaller index), its tether
    that path's rest length; attached vertices and those no attached vertex reaches have none."""
    v = np.array([[0.0, 0, 0], [1, 0, 0], [0, 1, 0], [1, 1, 0], [5, 5, 5], [6, 5, 5], [5, 6, 5]])
    f = np.array([[0, 1, 2], [1, 3, 2], [4, 5, 6]])
    sd = np.array([0.0, 0.03, 0.5, -1.0, 0.5, 0.5, 0.5])
    for a in (cloth_setup(v, f, sd), cloth_setup_reference(v, f, sd)):
        np.testing.assert_array_equal(a.anchor, [-1, 0, 0, -1, -1, -1, -1])
        np.testing.assert_array_equal(a.tether, [0, 1, 1, 0, 0, 0, 0])
    # a strip 30 edges long hanging from its attached top row: the tethers run the length of the strip
    v, f = grid_plane(2, 30, size=(0.02, 0.3))
    v = v[:, [0, 2, 1]]  # upright: y from 0 to 0.3
    sd = np.where(v[:, 1] >= v[:, 1].max() - 1e-9, 0.0, 1.0)
    a = cloth_setup(v, f, sd)
    free = sd > 0
    assert (a.anchor[free] >= 0).all() and (sd[a.anchor[free]] == 0).all()
    np.testing.assert_allclose(a.tether[free], v[:, 1].max() - v[free, 1], atol=1e-12)  # straight up the strip


def test_tethers_hold_a_hanging_strip_within_the_stretch_limit():
    """A strip hanging still from its attached top row far from any body: gravity sags the free part every frame;
    four sweeps of edges alone leave it stretched well over the limit, the tethers hold it near the limit."""
    v, f = grid_plane(3, 30, size=(0.04, 0.3))
    v = v[:, [0, 2, 1]]  # upright: y from 0 to 0.3
    body_v = np.array([[10.0, 0, 0], [11.0, 0, 0], [10.0, 1, 0], [10.0, 0, 1]])
    body_f = np.array([[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]])
    sd = np.where(v[:, 1] >= v[:, 1].max() - 1e-9, 0.0, 1.0)
    setup = cloth_setup(v, f, sd)
    T = 30
    still, posed = np.repeat(v[None], T, 0), np.repeat(body_v[None], T, 0)
    untethered = dataclasses.replace(setup, anchor=np.full_like(setup.anchor, -1))

    def strain(s):
        x = ClothStage(s, body_v, body_f).step(still, posed)[-1]
        return (np.linalg.norm(x[s.edges[:, 1]] - x[s.edges[:, 0]], axis=-1) / s.rest_len - 1).max()

    assert strain(setup) < 0.04 < 0.1 < strain(untethered), (strain(setup), strain(untethered))


def test_kernel_is_the_reference(walk, body):
    """The compiled stage and the slow reference agree to 1e-9 m on every frame of a walk through the thighs, in
    contact (the reference's contacts and push-out come from the numpy BodyCollider), for two settings."""
    v, f, targets, posed, setup = walk
    for s in (
        ClothSettings(),
        ClothSettings(iterations=3, stiffness=0.6, bending=0.0, compress=1.0, follow=0.0, gravity=20.0),
    ):
        stage = _stage(setup, body, s)
        fast = stage.step(targets, posed)
        ref, st = cloth_reference(targets, posed, body.faces, setup, s, margin=MARGIN)
        err = np.abs(fast - ref).max()
        assert err <= 1e-9, err
        assert stage.contacts == st["contacts"] > 50  # the test means something: many vertex-frames in contact
        assert stage.traced == st["traced"]  # (the backstop's own case: the limb through a panel, below)
        assert abs(stage.pushed - st["pushed"]) <= max(3, st["pushed"] // 20)  # vertices exactly at the margin
        assert np.abs(fast - targets).max() > 0.01


def test_the_settling_after_the_push_out_is_the_references():
    """A panel through the crease of a body that intersects itself (two spheres, one mesh), attached and loose: the
    final push-out moves over a hundred vertex-frames, so the settling after it runs (the stretch limits and the
    attachment again with the pushed vertices held, then the vertices that may be inside pushed out again), and the
    kernel and the reference agree to 1e-9 m, counters too; no vertex ends within the margin."""
    from tests.body._shapes import pressed_spheres, with_reach

    # a long reach (a small sphere 40 units away): the rule for buried skin takes a point out to open skin within
    # PINCH times the body's size, here 49 cm, which every vertex of the panel has
    body_v, body_f = with_reach(*pressed_spheres(24, 16))
    col = BodyCollider(body_v, body_f)
    ys = np.arange(-0.3, 0.3001, 0.03)
    nx = len(ys)
    f = np.array([t for j in range(nx - 1) for i in range(nx - 1) for t in _quad(j * nx + i, nx)])
    v = np.array([[0.93, y + 0.0031, z + 0.0017] for z in ys for y in ys])  # off the spheres' poles: no ties
    knobs = ClothSettings(gravity=0.0)
    for rest_sd in (0.0, 1.0):  # attached (follows the network), loose
        setup = cloth_setup(v, f, np.full(len(v), rest_sd), knobs)
        stage = ClothStage(setup, body_v, body_f, knobs, margin=MARGIN)
        targets, posed = np.repeat(v[None], 6, 0), np.repeat(body_v[None], 6, 0)
        out = stage.step(targets, posed)
        ref, st = cloth_reference(targets, posed, body_f, setup, knobs, margin=MARGIN)
        assert np.abs(out - ref).max() <= 1e-9
        assert stage.pushed == st["pushed"] > 100 and stage.contacts == st["contacts"]
        if rest_sd > 0:  # loose: the settling carries the free neighbours of the pushed vertices (attached: none)
            unsettled, _ = cloth_reference(targets, posed, body_f, setup, knobs, margin=MARGIN, settle=False)
            assert np.abs(out - unsettled).max() > 1e-3
        for x in out:
            assert (col.query(x, body_v).signed_distance >= MARGIN - 1e-9).all()


def test_the_settling_keeps_an_edge_lifted_off_a_ridge():
    """An attached chord across a ridge, lifted by its edge contact (both ends moved alike, its middle at the margin),
    in one garment with a panel whose vertices the final push-out moves (so the frame settles): the settling does not
    pull the lifted ends back to their targets -- its attachment lets a vertex stay as far from its target as the
    sweeps left it -- so the chord's middle stays outside, as without the panel; kernel = reference.  (A review found
    the first form of the settling put it 7.7 mm inside.)"""
    from tests.body._shapes import pressed_spheres

    w, h = 0.2, 0.04
    rv, rf = _roof(w, h, 0.2)
    off = np.array([0.0, 0.0, 5.0])
    sv, sf = pressed_spheres(24, 16)
    body_v, body_f = np.vstack([sv, rv + off]), np.vstack([sf, rf + len(sv)])
    col = BodyCollider(body_v, body_f)
    lift = 0.006 * np.hypot(h, w) / w
    chord = np.array([[-0.07, h * 0.65 + lift, 0.0], [0.09, h * 0.55 + lift, 0.0], [0.0, h + lift, 0.05]]) + off
    ys = np.arange(-0.3, 0.3001, 0.03)
    nx = len(ys)
    pf = np.array([t for j in range(nx - 1) for i in range(nx - 1) for t in _quad(j * nx + i, nx)])
    pv = np.array([[0.93, y + 0.0031, z + 0.0017] for z in ys for y in ys])
    knobs = ClothSettings(stiffness=0.0, bending=0.0, gravity=0.0)
    for with_panel in (False, True):
        v = np.vstack([chord, pv]) if with_panel else chord
        f = np.vstack([[[0, 1, 2]], pf + 3]) if with_panel else np.array([[0, 1, 2]])
        targets, posed = np.repeat(v[None], 6, 0), np.repeat(body_v[None], 6, 0)
        setup = cloth_setup(v, f, np.zeros(len(v)), knobs)
        stage = ClothStage(setup, body_v, body_f, knobs, margin=MARGIN)
        out = stage.step(targets, posed)
        ref, st = cloth_reference(targets, posed, body_f, setup, knobs, margin=MARGIN)
        assert np.abs(out - ref).max() <= 1e-9 and stage.pushed == st["pushed"]
        assert (stage.pushed > 100) == with_panel
        for x in out:
            assert col.query(0.5 * (x[:1] + x[1:2]), body_v).signed_distance[0] >= MARGIN - 1e-9
            assert np.abs(x[:2] - chord[:2]).max() > 0.005  # lifted


def test_the_backstop_traces_out_of_a_torso_with_an_arm_pressed_in():
    """A loose panel deep in the torso of a body that intersects itself (two spheres, one mesh), its outward normal
    toward the arm, then away from it: the backstop traces it along that normal until it is out of the body -- its
    traces keep the rule for buried skin, so a point in the torso nearest the arm's buried skin is not taken for
    outside (a review found the panel 'traced out' inside the torso when the rule left the stage's lookups).  At a
    human scale (0.13 of the unit shapes: traces of 11-19 cm, within ``REACH``); at the unit scale the traces would be
    50-80 cm, through the torso, and are dropped: the push-out takes the panel out instead.  Kernel = reference."""
    from segadeform.body.cloth import REACH
    from tests.body._shapes import pressed_spheres

    ys = np.arange(-0.05, 0.0501, 0.025)
    nx = len(ys)
    f0 = np.array([t for j in range(nx - 1) for i in range(nx - 1) for t in _quad(j * nx + i, nx)])
    knobs = ClothSettings(gravity=0.0)
    for s, traced in ((0.13, True), (1.0, False)):
        # (the traces' rule has no bound: the torso's open skin is 0.52 s from where they pass the arm's buried tip,
        # past the push-out's PINCH times the body's size, 0.026 s)
        body_v, body_f = pressed_spheres(24, 16)
        body_v = s * body_v
        col = BodyCollider(body_v, body_f)
        v = s * np.array([[-0.25, y + 0.0031, z + 0.0017] for z in ys for y in ys])
        assert (s * (0.9 + 0.3 + 0.25) < REACH) == traced  # out of the arm's far side within the reach
        for f in (f0, f0[:, ::-1]):
            setup = cloth_setup(v, f, np.ones(len(v)), knobs)
            stage = ClothStage(setup, body_v, body_f, knobs, margin=MARGIN)
            targets, posed = v[None], body_v[None]
            out = stage.step(targets, posed)
            ref, st = cloth_reference(targets, posed, body_f, setup, knobs, margin=MARGIN)
            assert np.abs(out - ref).max() <= 1e-9 and stage.traced == st["traced"]
            assert (stage.traced == len(v)) == traced and (stage.traced == 0) != traced, (s, stage.traced)
            assert not (col.winding(out[0], body_v) > 0).any()


def test_batches_and_streams_give_the_frames_of_one_call(walk, body):
    v, f, targets, posed, setup = walk
    one = _stage(setup, body).step(targets, posed)
    for size in (1, 3, 5):
        st = _stage(setup, body)
        parts = [st.step(targets[lo : lo + size], posed[lo : lo + size]) for lo in range(0, len(targets), size)]
        np.testing.assert_array_equal(np.concatenate(parts), one)
        assert st.frames == len(targets)
    # deterministic: a second stage gives the same bits; float32 inputs are taken as their float64 values
    np.testing.assert_array_equal(_stage(setup, body).step(targets, posed), one)
    t32 = targets.astype(np.float32)
    np.testing.assert_array_equal(
        _stage(setup, body).step(t32, posed), _stage(setup, body).step(t32.astype(np.float64), posed)
    )


def test_attachment_contact_and_the_bound(walk, body):
    """Attached vertices (radius 0) follow the target exactly unless the body pushes them or an edge to them; free
    ones stay within their radius of it unless the body pushes them or an edge to them; nothing is left inside the
    body deeper than rounding.  The bound is the target's as the backstop leaves it: in a frame where it traced a
    deep free target out of the body it moved the targets near it, so such frames are checked for contact only."""
    v, f, targets, posed, setup = walk
    stage = _stage(setup, body)
    out, traced = [], []
    for t in range(len(targets)):
        before = stage.traced
        out.append(stage.step(targets[t : t + 1], posed[t : t + 1])[0])
        traced.append(stage.traced > before)
    out = np.stack(out)
    assert sum(traced) <= len(traced) // 2, traced  # most frames have their bound checked
    col = BodyCollider(body.v_template, body.faces)
    dev = np.linalg.norm(out - targets, axis=2)
    att = setup.radius == 0
    assert 0.05 < att.mean() < 0.95
    inside_before = 0
    for t in range(len(out)):
        sd_target = col.query(targets[t], posed[t]).signed_distance
        sd_out = col.query(out[t], posed[t]).signed_distance
        inside_before += int((sd_target < 0).sum())
        # the body cannot have moved these: neither they nor a neighbour (an edge's contact moves both ends) can
        # have been near it
        near = ~(sd_target > MARGIN + CONTACT_BAND + setup.radius)
        e = setup.edges
        reached = near.copy()
        reached[e[near[e[:, 0]], 1]] = True
        reached[e[near[e[:, 1]], 0]] = True
        free_of_body = ~reached
        if not traced[t]:
            assert (dev[t][att & free_of_body] == 0).all()
            assert (dev[t][free_of_body] <= setup.radius[free_of_body] + 1e-12).all()
        assert (sd_out > -1e-6).mean() >= 0.999, (t, (sd_out <= -1e-6).sum())
    assert inside_before > 100  # the targets went through the body


def _cube(half: float):
    """A closed box centred at the origin, faces wound outward: (8, 3), (12, 3)."""
    v = np.array([[x, y, z] for x in (-half, half) for y in (-half, half) for z in (-half, half)], float)
    quads = [(0, 1, 3, 2), (4, 6, 7, 5), (0, 4, 5, 1), (2, 3, 7, 6), (0, 2, 6, 4), (1, 5, 7, 3)]
    f = np.array([t for a, b, c, d in quads for t in ((a, b, c), (a, c, d))])
    return v, f


def test_an_edge_across_the_body_is_pushed_out_with_both_ends():
    """An edge whose two ends are outside the body and whose middle is inside it (a chord across a box's corner, as
    a skirt's edge across a thigh): vertex contacts alone leave it there; the edge's contact moves both (free) ends
    alike until its middle is the margin outside, in the kernel and the reference.  An edge with both ends attached
    across the corner is left to the vertex contacts (it follows the network where the garment lies on the body;
    the ends' normals are 90 degrees apart, so no side is the outside)."""
    body_v, body_f = _cube(0.1)
    col = BodyCollider(body_v, body_f)
    assert (col.query(body_v * 0.5, body_v).signed_distance < 0).all()  # the box is closed and wound outward
    v = np.array([[0.09, 0.106, 0.0], [0.106, 0.09, 0.0], [0.16, 0.16, 0.02]])
    f = np.array([[0, 1, 2]])
    mid = 0.5 * (v[0] + v[1])
    assert (col.query(v[:2], body_v).signed_distance > MARGIN).all()
    assert col.query(mid[None], body_v).signed_distance[0] < -0.001  # the target's chord is inside
    targets = np.repeat(v[None], 3, 0)
    posed = np.repeat(body_v[None], 3, 0)
    # the chord's ends free (radius 5 cm), the far vertex attached; only contact and the drive act
    knobs = ClothSettings(stiffness=0.0, bending=0.0, gravity=0.0)
    setup = cloth_setup(v, f, np.array([1.0, 1.0, 0.0]), knobs)
    assert setup.radius.tolist() == [0.05, 0.05, 0.0]
    out = ClothStage(setup, body_v, body_f, knobs, margin=MARGIN).step(targets, posed)
    ref, _ = cloth_reference(targets, posed, body_f, setup, knobs, margin=MARGIN)
    assert np.abs(out - ref).max() <= 1e-12
    for x in out:
        m = 0.5 * (x[0] + x[1])
        assert col.query(m[None], body_v).signed_distance[0] >= MARGIN - 1e-9
        assert (col.query(x, body_v).signed_distance >= MARGIN - 1e-9).all()
        np.testing.assert_allclose(x[1] - x[0], v[1] - v[0], atol=1e-12)  # both ends moved alike
        assert x[2].tolist() == v[2].tolist()  # the attached far vertex is not moved
    # every vertex attached: the chord stays where the network put it (its ends are outside the margin)
    pinned = cloth_setup(v, f, np.zeros(3), knobs)
    out = ClothStage(pinned, body_v, body_f, knobs, margin=MARGIN).step(targets, posed)
    np.testing.assert_array_equal(out, targets)


def test_an_edge_a_limb_is_deep_through_is_left_to_its_ends():
    """A chord across the box's corner with its ends just outside (in contact) and its middle 1.8 cm inside is pushed
    out with both ends, as above; with its middle 2.8 cm inside (deeper than ``EDGE_DEEP``: a limb through the cloth,
    whose middle's closest surface may be on either side of it from one frame to the next -- its plane moved a
    T-shirt's vertices 7 cm one frame and not the next, 300 of 360 pops on a dance) it gets no plane: its ends stay
    where their own contacts keep them.  Kernel = reference on both."""
    from segadeform.body.cloth import EDGE_DEEP

    body_v, body_f = _cube(0.1)
    col = BodyCollider(body_v, body_f)
    knobs = ClothSettings(stiffness=0.0, bending=0.0, gravity=0.0)
    posed = np.repeat(body_v[None], 2, 0)
    for near, deep in ((0.064, False), (0.044, True)):
        v = np.array([[near, 0.104, 0.0], [0.104, near, 0.0], [0.16, 0.16, 0.02]])
        f = np.array([[0, 1, 2]])
        mid = 0.5 * (v[0] + v[1])
        depth = -col.query(mid[None], body_v).signed_distance[0]
        assert (depth > EDGE_DEEP) == deep and 0.015 < depth < 0.03, depth
        setup = cloth_setup(v, f, np.array([1.0, 1.0, 0.0]), knobs)
        targets = np.repeat(v[None], 2, 0)
        out = ClothStage(setup, body_v, body_f, knobs, margin=MARGIN).step(targets, posed)
        ref, _ = cloth_reference(targets, posed, body_f, setup, knobs, margin=MARGIN)
        assert np.abs(out - ref).max() <= 1e-12
        for x in out:
            m_sd = col.query((0.5 * (x[0] + x[1]))[None], body_v).signed_distance[0]
            moved = np.linalg.norm(x[:2] - v[:2], axis=1).max()
            if deep:  # no plane: the ends where their contacts keep them (at most to the margin), the middle inside
                assert moved < 0.001 and m_sd < -EDGE_DEEP, (moved, m_sd)
            else:  # the plane: both ends moved until the middle is the margin outside
                assert moved > 0.015 and m_sd >= MARGIN - 1e-9, (moved, m_sd)


def _roof(width, height, length):
    """A closed prism whose top is a ridge along z (two roof faces sloping down to y = 0 at x = +-width, a knee's
    front as the cloth sees it), faces wound outward: (6, 3), (8, 3)."""
    v = np.array(
        [
            [-width, 0, -length],
            [width, 0, -length],
            [0, height, -length],
            [-width, 0, length],
            [width, 0, length],
            [0, height, length],
        ],
        float,
    )
    f = np.array([[0, 2, 1], [3, 4, 5], [0, 1, 4], [0, 4, 3], [1, 2, 5], [1, 5, 4], [2, 0, 3], [2, 3, 5]])
    return v, f


def test_an_attached_edge_across_a_ridge_is_lifted_where_both_ends_lie_on_it():
    """A tight garment's long edge across a bent knee: both ends attached and lying on the body (6 mm over the two
    roof faces of a ridge whose normals are 23 degrees apart), the middle 8 mm inside it.  The middle's contact
    lifts both ends alike until it is the margin outside (kernel = reference); the same edge across a box's corner
    (normals 90 degrees apart: a pinch, no side is the outside) is left where the network put it."""
    w, h = 0.2, 0.04
    body_v, body_f = _roof(w, h, 0.2)
    col = BodyCollider(body_v, body_f)
    assert (col.query(np.array([[0.0, 0.01, 0.0]]), body_v).signed_distance < 0).all()  # closed, wound outward
    lift = 0.006 * np.hypot(h, w) / w  # 6 mm along a roof face's normal, as a height
    ends = np.array([-0.07, 0.09])  # the middle off the ridge (x = 1 cm: one face is nearest, no tie)
    v = np.array([[ends[0], h * (1 - 0.35) + lift, 0.0], [ends[1], h * (1 - 0.45) + lift, 0.0], [0.0, h + lift, 0.05]])
    f = np.array([[0, 1, 2]])
    d = col.query(v[:2], body_v)
    assert (d.signed_distance > MARGIN).all() and (d.signed_distance < MARGIN + CONTACT_BAND).all()
    assert d.normal[0] @ d.normal[1] > 0.9  # the same side of the body
    assert col.query(0.5 * (v[:1] + v[1:2]), body_v).signed_distance[0] < -0.001  # the chord's middle is inside
    targets = np.repeat(v[None], 3, 0)
    posed = np.repeat(body_v[None], 3, 0)
    knobs = ClothSettings(stiffness=0.0, bending=0.0, gravity=0.0)
    pinned = cloth_setup(v, f, np.zeros(3), knobs)  # every vertex attached: it lies on the body
    assert pinned.radius.tolist() == [0.0, 0.0, 0.0]
    out = ClothStage(pinned, body_v, body_f, knobs, margin=MARGIN).step(targets, posed)
    ref, _ = cloth_reference(targets, posed, body_f, pinned, knobs, margin=MARGIN)
    assert np.abs(out - ref).max() <= 1e-12
    for x in out:
        assert col.query(0.5 * (x[:1] + x[1:2]), body_v).signed_distance[0] >= MARGIN - 1e-9
        np.testing.assert_allclose(x[1] - x[0], v[1] - v[0], atol=1e-12)  # both ends moved alike
        assert x[2].tolist() == v[2].tolist()  # the third vertex, clear of the body, follows the network
    # across a box's corner the ends' normals are 90 degrees apart: left to the vertex contacts
    cube_v, cube_f = _cube(0.1)
    c = np.array([[0.09, 0.106, 0.0], [0.106, 0.09, 0.0], [0.16, 0.16, 0.02]])
    assert BodyCollider(cube_v, cube_f).query(0.5 * (c[:1] + c[1:2]), cube_v).signed_distance[0] < -0.001
    corner = np.repeat(c[None], 3, 0)
    out = ClothStage(cloth_setup(c, f, np.zeros(3), knobs), cube_v, cube_f, knobs, margin=MARGIN).step(
        corner, np.repeat(cube_v[None], 3, 0)
    )
    np.testing.assert_array_equal(out, corner)


def _box(lo, hi):
    """A closed box from corner lo to hi, faces wound outward: (8, 3), (12, 3)."""
    v, f = _cube(0.5)
    return np.asarray(lo, float) + (v + 0.5) * (np.asarray(hi, float) - np.asarray(lo, float)), f


def _panel_through_a_limb(bottom: float, top: float):
    """A box "limb" (z from ``bottom`` to ``top``) through the middle of a flat panel at z = 0 (the network's skirt
    through a thigh), a second box just under the panel's end at x < -0.15 (the body it lies on).
    Shapes: -> body vertices (16, 3), body faces (24, 3), panel vertices (N, 3), panel faces (F, 3)."""
    sv, sf = _box((-0.45, -0.25, -0.2), (-0.15, 0.25, -0.006))
    lv, lf = _box((0.0, -0.1, bottom), (0.2, 0.1, top))
    xs, ys = np.arange(-0.4, 0.3501, 0.025), np.arange(-0.2, 0.2001, 0.025)
    v = np.array([[x, y, 0.0] for y in ys for x in xs])
    nx = len(xs)
    f = np.array([t for j in range(len(ys) - 1) for i in range(nx - 1) for t in _quad(j * nx + i, nx)])
    return np.concatenate([sv, lv]), np.concatenate([sf, lf + 8]), v, f


def test_the_backstop_takes_a_limb_through_a_panel_out_on_one_side():
    """A box "limb" through the middle of a still, flat panel (the network's skirt through a thigh), a second box
    just under the panel's attached end (the body it lies on).  Without the backstop every vertex is pushed out
    along its own closest point: the middle ones down through the limb's near face, those near its sides sideways,
    and the panel is torn across the limb.  With it every deep target is traced out along the panel's outward
    normal (up: the vertices lying just outside the other box vote so), so the deep vertices all leave over the
    limb's top, and the largest stretch falls (its mean over the frames after the first: in this still scene without
    gravity the panel over the limb's corner does not settle, and its largest stretch moves between 1.0 and 2.1 from
    frame to frame).  Kernel and reference agree."""
    body_v, body_f, v, f = _panel_through_a_limb(-0.06, 0.14)
    col = BodyCollider(body_v, body_f)
    deep = col.query(v, body_v).signed_distance < -ClothSettings().backstop
    assert deep.sum() > 20
    targets, posed = np.repeat(v[None], 6, 0), np.repeat(body_v[None], 6, 0)
    rest_sd = np.where(v[:, 0] < -0.15, 0.0, 1.0)  # attached over the other box, free elsewhere
    res = {}
    on = ClothSettings().backstop
    for backstop in (0.0, on):
        knobs = ClothSettings(gravity=0.0, backstop=backstop)
        setup = cloth_setup(v, f, rest_sd, knobs)
        stage = ClothStage(setup, body_v, body_f, knobs, margin=MARGIN)
        out = stage.step(targets, posed)
        ref, st = cloth_reference(targets, posed, body_f, setup, knobs, margin=MARGIN)
        assert np.abs(out - ref).max() <= 1e-9 and stage.traced == st["traced"]
        x, e = out[-1], setup.edges
        assert (col.query(out.reshape(-1, 3), body_v).signed_distance >= MARGIN - 1e-9).all()
        strain = np.linalg.norm(out[1:, e[:, 0]] - out[1:, e[:, 1]], axis=2) / setup.rest_len - 1
        over, under = int((x[deep, 2] > 0.14).sum()), int((x[deep, 2] < -0.06).sum())
        res[backstop] = (stage.traced, over, under, strain.max(axis=1).mean())
    assert res[0.0][0] == 0 and res[0.0][2] >= 5, res  # off: the panel is torn, part of it under the limb
    assert res[on][0] > 0 and res[on][2] == 0 and res[on][1] >= 0.8 * deep.sum(), res  # on: all over it
    assert res[on][3] < 0.75 * res[0.0][3], res


def test_the_backstop_goes_by_the_targets_depth_not_the_predictions():
    """The backstop traces a loose vertex whose *target* is deeper than ``backstop`` inside (and whose prediction is
    inside), whatever the frame before left.  A panel held over a limb, then put 4-6 cm into it and kept still, the
    body still: the first frame in, the prediction (the frame before's output, halfway to the target) is only about
    2 cm inside.  By the prediction's depth (the rule before) those vertices were traced one frame and left to their
    closest exits the next, over and over: 25-40 mm steps every frame of a still scene, never settling (a jacket's
    panel in a hip under a karate form flipped front to back every other frame).  By the target's depth every deep
    target is traced on every frame it is deep and the panel settles.  Kernel and reference agree."""
    body_v, body_f, v, f = _panel_through_a_limb(-0.1, 0.06)
    col = BodyCollider(body_v, body_f)
    knobs = ClothSettings(gravity=0.0)
    setup = cloth_setup(v, f, np.where(v[:, 0] < -0.15, 0.0, 1.0), knobs)  # attached over the other box
    deep = (col.query(v, body_v).signed_distance < -knobs.backstop) & (setup.radius > 0)
    assert deep.sum() > 10
    over = v + np.where(v[:, :1] >= -0.15, [0.0, 0.0, 0.09], [0.0, 0.0, 0.0])  # the free part held over the limb
    pred = 0.5 * (over + v)  # frame 1's prediction (no velocity yet)
    assert (col.query(pred[deep], body_v).signed_distance > -knobs.backstop).all()
    frames = 10
    targets = np.stack([over] + [v] * (frames - 1))
    posed = np.repeat(body_v[None], frames, 0)
    stage = ClothStage(setup, body_v, body_f, knobs, margin=MARGIN)
    out, traced = [], []
    for t in range(frames):  # a frame at a time: the traced count of each
        before = stage.traced
        out.append(stage.step(targets[t : t + 1], posed[t : t + 1])[0])
        traced.append(stage.traced - before)
    assert traced[0] == 0 and all(n == deep.sum() for n in traced[1:]), (traced, int(deep.sum()))
    step = np.linalg.norm(np.diff(out, axis=0), axis=2).max(axis=1)
    assert (step[-3:] < 0.005).all(), step  # settled (the rule before: 25-40 mm every frame)
    assert (out[-1][deep, 2] > 0.06).all()  # over the limb, the side its outward normal says
    ref, st = cloth_reference(targets, posed, body_f, setup, knobs, margin=MARGIN)
    assert st["traced"] == sum(traced) and np.abs(np.asarray(out) - ref).max() <= 1e-9


def test_cloth_pinched_by_a_buried_arm_stays_unless_in_contact():
    """A body that intersects itself (an arm pressed into the torso: two spheres, one mesh) and a panel inside the
    torso next to the arm's buried skin: by its closest surface every vertex is outside (the arm's), by the winding
    number inside.  Every vertex deeper in that pinch than the contact band stays exactly where the network put it --
    as the simulator leaves cloth there, rather than taken alone across the arm (the flaps at a dress's armholes,
    30 Nov 2026) -- and one in contact (the panel 5 mm from the arm's tip) is taken out of the body by the final
    push-out's rule for buried skin when the torso's open skin is within PINCH times the body's size (a long reach
    makes the body large enough: the torso's skin is 40 cm away, the bound 49 cm); without it, that vertex too stays
    pinched.  Kernel and reference alike."""
    from tests.body._shapes import pressed_spheres, with_reach

    ys = np.arange(-0.2, 0.2001, 0.05)
    nx = len(ys)
    f = np.array([t for j in range(nx - 1) for i in range(nx - 1) for t in _quad(j * nx + i, nx)])
    knobs = ClothSettings(gravity=0.0)
    # 5 cm and 5 mm from the arm's buried tip, the body with and without a long reach
    for x_at, reach, stays in ((0.55, True, True), (0.595, True, False), (0.595, False, True)):
        body_v, body_f = with_reach(*pressed_spheres(24, 16)) if reach else pressed_spheres(24, 16)
        col = BodyCollider(body_v, body_f)
        v = np.array([[x_at, y, z] for z in ys for y in ys])
        q = col.query(v, body_v)
        assert ((col.winding(v, body_v) > 0) & (q.signed_distance > 0)).all()
        near = q.signed_distance < MARGIN + CONTACT_BAND
        assert near.sum() == (1 if x_at > 0.59 else 0)  # 5 mm: the vertex facing the arm's tip
        targets, posed = np.repeat(v[None], 2, 0), np.repeat(body_v[None], 2, 0)
        setup = cloth_setup(v, f, np.ones(len(v)), knobs)
        stage = ClothStage(setup, body_v, body_f, knobs, margin=MARGIN)
        out = stage.step(targets, posed)
        ref, st = cloth_reference(targets, posed, body_f, setup, knobs, margin=MARGIN)
        assert np.abs(out - ref).max() <= 1e-9
        assert stage.contacts == st["contacts"] and stage.pushed == st["pushed"] and stage.traced == st["traced"]
        if stays:  # pinched: left where it is (else the settling sweeps carry the neighbours of the vertex taken out)
            assert stage.pushed == 0 and stage.contacts == 2 * near.sum()
            np.testing.assert_array_equal(out, targets)
        else:
            assert stage.contacts >= 2 and stage.pushed >= 2
            for x in out:
                assert not (col.winding(x[near], body_v) > 0).any()


def test_the_backstop_leaves_cloth_that_lies_on_the_body_to_its_contacts():
    """A sleeve's hem the network put deep inside the arm, its panel across the arm: the garment's normal runs along
    the arm, so the traced ray came out 10-30 cm away and the stage threw those vertices there for a few frames (a
    new user's T-shirt walking: 15-17 cm pops).  The hem lies on the arm at rest (attachment radius 5 mm here), so it
    is no cloth hanging in front of a limb: the backstop traces only loose vertices (radius >= LOOSE, 7 mm), and these
    keep their closest-point contact (out through the arm's side).  The same panel hanging loose is traced -- out of
    the arm's end 15 cm away; not 30 cm away, farther than ``REACH`` (a trace through the torso: dropped, the panel
    left to its contacts).  Kernel and reference agree."""
    from segadeform.body.cloth import LOOSE, REACH

    g = np.arange(-0.04, 0.04001, 0.01)
    # a panel across the arm, its normal along +x (off the arm's axis: no vertex equally near two of its faces)
    v = np.array([[0.2, y + 0.0037, z - 0.0021] for z in g for y in g])
    n = len(g)
    f = np.array([[a, b, c] for j in range(n - 1) for i in range(n - 1) for a, b, c in _quad(j * n + i, n)])
    knobs = ClothSettings(gravity=0.0)
    moved = {}
    for end in (0.35, 0.5):  # the arm's end 15 cm or 30 cm along the panel's normal
        arm_v, arm_f = _box((-0.3, -0.06, -0.06), (end, 0.06, 0.06))
        col = BodyCollider(arm_v, arm_f)
        deep = col.query(v, arm_v).signed_distance < -ClothSettings().backstop
        assert deep.sum() >= 9
        targets, posed = np.repeat(v[None], 3, 0), np.repeat(arm_v[None], 3, 0)
        # on the arm at rest / hanging 8 mm off it (loose since ABI 14, which traced it: 3,450 -> 3,315 pops on ten
        # garment x clip pairs, docs/cloth-eval.md) / hanging away
        for rest_sd, loose in ((knobs.attachment + 0.005, False), (knobs.attachment + 0.008, True), (1.0, True)):
            setup = cloth_setup(v, f, np.full(len(v), rest_sd), knobs)
            assert ((setup.radius >= LOOSE) == loose).all() and (setup.radius > 0).all()
            stage = ClothStage(setup, arm_v, arm_f, knobs, margin=MARGIN)
            out = stage.step(targets, posed)
            ref, st = cloth_reference(targets, posed, arm_f, setup, knobs, margin=MARGIN)
            assert np.abs(out - ref).max() <= 1e-9 and stage.traced == st["traced"]
            assert (stage.traced > 0) == (loose and end - 0.2 < REACH), (end, loose, stage.traced)
            assert (col.query(out[-1], arm_v).signed_distance >= MARGIN - 1e-9).all()
            moved[end, loose] = max(moved.get((end, loose), 0.0), np.abs(out[..., 0] - 0.2).max())  # along the arm
    # out through the arm's side, not along it; loose, out of its near end; not through 30 cm of it
    assert moved[0.35, False] < 0.05 and moved[0.5, False] < 0.05, moved
    assert moved[0.35, True] > 0.14 and moved[0.5, True] < 0.05, moved


def _quad(a, nx):
    """The two triangles of the grid cell with corner a in a grid nx wide, wound so that the normal is +z."""
    b, c, d = a + 1, a + nx + 1, a + nx
    return [(a, b, c), (a, c, d)]


def test_strain_is_limited_and_inertia_and_gravity_act():
    """Far from any body (a tiny body 10 m away): a patch whose target is stretched 30 % along x comes back toward
    its stretch limit; a still target with gravity makes the free part sag within its bound; a target that moves
    and stops leaves the free part moving on (inertia), within its bound."""
    v, f = grid_plane(6, 6, size=(0.1, 0.1))
    v = v + [0.0, 1.0, 0.0]
    body_v = np.array([[10.0, 0, 0], [11.0, 0, 0], [10.0, 1, 0], [10.0, 0, 1]])
    body_f = np.array([[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]])
    free = cloth_setup(v, f, np.full(len(v), 1.0), ClothSettings())  # every vertex loose (radius 5 cm)
    assert (free.radius == 0.05).all()
    T = 30
    posed = np.repeat(body_v[None], T, 0)
    stretched = np.repeat((v * [1.3, 1.0, 1.0])[None], T, 0)
    s = ClothSettings(iterations=16, gravity=0.0)
    out = ClothStage(free, body_v, body_f, s).step(stretched, posed)

    def strain(x):
        d = x[:, free.edges[:, 1]] - x[:, free.edges[:, 0]]
        return np.linalg.norm(d, axis=-1) / free.rest_len - 1

    assert strain(stretched).max() > 0.29
    assert strain(out[-1:]).max() < 0.08 and strain(out[-1:]).max() < 0.3 * strain(stretched).max()
    still = np.repeat(v[None], T, 0)
    sag = ClothStage(free, body_v, body_f, ClothSettings(stretch=1.0, compress=1.0)).step(still, posed)
    drop = still[-1, :, 1] - sag[-1, :, 1]
    assert drop.min() > 0.001 and drop.max() <= 0.05 + 1e-12  # down, within the bound
    np.testing.assert_array_equal(ClothStage(free, body_v, body_f, ClothSettings(gravity=0)).step(still, posed), still)
    # moving at 3 cm/frame for 10 frames, then still: the free patch lags as it starts, goes on past the stop, and
    # settles back on the target, always within its bound
    path = np.concatenate([0.03 * np.arange(10), np.full(20, 0.27)])
    moving = still + np.stack([path, np.zeros(T), np.zeros(T)], -1)[:, None, :]
    go = ClothStage(free, body_v, body_f, ClothSettings(gravity=0, follow=0.2, damping=0.0)).step(moving, posed)
    over = (go[:, :, 0] - moving[:, :, 0]).mean(axis=1)
    assert over[0] == 0 and over[2] < -0.02 and over[10:13].max() > 0.01 and np.abs(over).max() <= 0.05 + 1e-12
    assert abs(over[-1]) < 0.25 * np.abs(over).max()


def test_a_jump_resets_once_and_says_so_once(walk, body, caplog):
    v, f, targets, posed, setup = walk
    jumped = targets.copy()
    jumped[4:] += [5.0, 0.0, 0.0]  # the body teleports 5 m between frames 3 and 4 ...
    jumped[8:] -= [5.0, 0.0, 0.0]  # ... and back between 7 and 8
    pj = posed.copy()
    pj[4:] += [5.0, 0.0, 0.0]
    pj[8:] -= [5.0, 0.0, 0.0]
    stage = _stage(setup, body, first_frame=100)
    with caplog.at_level(logging.WARNING, logger="segadeform.body.cloth"):
        out = np.concatenate([stage.step(jumped[:6], pj[:6]), stage.step(jumped[6:], pj[6:])])
    said = [r for r in caplog.records if "started again" in r.getMessage()]
    assert stage.resets == 2 and len(said) == 1 and "frame 104" in said[0].getMessage(), said
    assert "5 m" in said[0].getMessage()
    assert np.isfinite(out).all() and np.abs(out - jumped).max() < 0.1  # no explosion
    # after a reset the frame starts from its target: the same as a fresh stage there
    fresh = _stage(setup, body).step(jumped[4:8], pj[4:8])
    np.testing.assert_array_equal(out[4:8], fresh)


def test_bad_input_is_refused(walk, body):
    v, f, targets, posed, setup = walk
    stage = _stage(setup, body, first_frame=10)
    bad = targets[:3].copy()
    bad[2, 5, 1] = np.nan
    with pytest.raises(InputError, match="NaN or inf in the garment frames at frame 12"):
        stage.step(bad, posed[:3])
    assert stage.frames == 0  # nothing was taken
    badb = posed[:2].copy()
    badb[1, 0, 0] = np.inf
    with pytest.raises(InputError, match="posed body at frame 11"):
        stage.step(targets[:2], badb)
    with pytest.raises(InputError, match="expected"):
        stage.step(targets[:2, :5], posed[:2])
    with pytest.raises(InputError, match="one frame per garment frame"):
        stage.step(targets[:2], posed[:3])
    with pytest.raises(InputError, match=r"real coordinates \(expected float or integer arrays, got complex128\)"):
        stage.step(targets[:2].astype(np.float32).astype(complex), posed[:2])
    for kw in (
        {"iterations": 0},
        {"iterations": 2.5},
        {"stretch": -0.1},
        {"gravity": float("nan")},
        {"reset": 0.0},
        {"follow": 2},
    ):
        with pytest.raises(ValueError, match="cloth"):
            ClothSettings(**kw)
    with pytest.raises(ValueError, match="unknown cloth setting"):
        ClothSettings.parse("wind=1")
    assert ClothSettings.parse("iterations=8, stiffness=0.5") == ClothSettings(iterations=8, stiffness=0.5)
    assert ClothSettings.parse("iterations=8").label() == "iterations=8" and ClothSettings().label() == ""
    with pytest.raises(InputError, match="time step"):
        settings_array(ClothSettings(), margin=MARGIN, dt=0.0)
    with pytest.raises(InputError, match="inconsistent cloth setup"):
        dataclasses.replace(setup, nptr=setup.nptr[:-1]).validate()
    with pytest.raises(InputError, match="inconsistent cloth setup"):  # a tether anchored at a free vertex
        free = np.flatnonzero(setup.anchor >= 0)
        dataclasses.replace(setup, anchor=np.where(setup.anchor >= 0, free[0], -1)).validate()


def test_setup_is_cached_with_the_garment(tmp_path, body, monkeypatch):
    import segadeform.body.cloth as cloth

    v, f = frustum(12, 4, 0.17, 0.33, 1.02, 0.55)
    rest = body.shaped_vertices()[0]
    a = garment_setup(v, f, rest, body.faces, cache_dir=tmp_path)
    files = list(tmp_path.glob("C-*.npz"))
    assert len(files) == 1

    def boom(*a, **k):
        raise AssertionError("computed again")

    monkeypatch.setattr(cloth, "cloth_setup", boom)
    b = garment_setup(v, f, rest, body.faces, cache_dir=tmp_path)
    for k in ("edges", "rest_len", "nptr", "nidx", "radius", "anchor", "tether"):
        np.testing.assert_array_equal(getattr(a, k), getattr(b, k))
    with pytest.raises(AssertionError, match="computed again"):  # other knobs of the setup: another entry
        garment_setup(v, f, rest, body.faces, ClothSettings(attachment=0.03), cache_dir=tmp_path)
    files[0].write_bytes(b"broken")  # a broken entry is computed again (and said)
    monkeypatch.undo()
    c = garment_setup(v, f, rest, body.faces, cache_dir=tmp_path)
    np.testing.assert_array_equal(c.radius, a.radius)


def test_the_holes_bench_counts_a_chord_across_a_corner():
    """bench/cloth_holes.py's count: a triangle whose corners are outside a box, one edge across the box's corner
    with its middle 5 mm inside and the centre 1.7 mm inside, is one edge middle and one face centre and no vertex;
    lifted clear of the box, none."""
    from bench.cloth_holes import holes
    from segadeform.geometry.mesh_ops import unique_edges

    body_v, body_f = _cube(0.1)
    col = BodyCollider(body_v, body_f)
    v = np.array([[0.07, 0.12, 0.0], [0.12, 0.07, 0.0], [0.105, 0.105, 0.0]])
    assert (col.query(v, body_v).signed_distance > 0).all()
    f = np.array([[0, 1, 2]])
    x = np.stack([v, v + [0.05, 0.05, 0.0]])
    out = holes(x, f, unique_edges(f), np.repeat(body_v[None], 2, 0), col)
    assert out.tolist() == [[0.0, 1.0, 1.0], [0.0, 0.0, 0.0]]


def test_reset_starts_a_new_clip_as_a_fresh_stage_counters_included(walk, body):
    """A library user's trial: a stage stepped into a second clip that began within the reset distance carried the
    first clip's velocity into it (2.6 cm off a fresh stage), and reset() left the counters and frame numbers going
    on from the old clip."""
    v, f, targets, posed, setup = walk
    used = _stage(setup, body, first_frame=7)
    used.step(targets[:10], posed[:10])
    assert used.frames == 10 and used.contacts > 0
    used.reset(first_frame=3)
    assert (used.frames, used.resets, used.contacts, used.pushed, used.traced) == (0, 0, 0, 0, 0)
    assert used.first_frame == 3
    again = used.step(targets[4:12], posed[4:12])
    fresh = _stage(setup, body).step(targets[4:12], posed[4:12])
    np.testing.assert_allclose(again, fresh, rtol=0, atol=1e-6)
    assert used.frames == 8
