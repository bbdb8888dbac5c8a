"""The Blender bridge, end to end (needs the simulator environment; CI has it)."""

from __future__ import annotations

import numpy as np
import pytest

from segadeform.body import BodyProxy
from segadeform.errors import InputError, SimulationError
from segadeform.motion import make_motion
from segadeform.motion.motion import Motion
from segadeform.physics import SimSettings, pin_weights, preroll_poses, simulate, waist_height


def _still(n=6):
    return Motion(poses=np.zeros((n, 72)), trans=np.zeros((n, 3)), fps=30.0)


def test_no_effects_and_no_motion_keeps_the_rest_shape(sim_python, body, coarse_skirt):
    g = coarse_skirt
    r = simulate(
        g.vertices, g.faces, body, _still(), settings=SimSettings(effects=(), drape_seconds=0.1, blend_seconds=0.0)
    )
    assert r.frames.shape == (6, len(g.vertices), 3)
    assert np.abs(r.frames - g.vertices).max() < 1e-4
    a = r.blender["applied"]
    assert not a["use_gravity"] and a["effector_gravity"] == 0.0 and not a["use_collision"]
    assert not a["use_self_collision"] and a["cloth"]["bending_stiffness"] == 0.0
    # no body_collision: no body at all, neither posed nor played back in Blender (it cost its setup for nothing)
    assert a["body_modifiers"] == [] and a["objects"] == ["garment"]


def test_gravity_pulls_down_and_collision_holds_the_cloth(sim_python, body, coarse_skirt):
    g = coarse_skirt
    kw = dict(drape_seconds=0.1, blend_seconds=0.0, quality=5)
    free = simulate(g.vertices, g.faces, body, _still(10), settings=SimSettings(effects=("gravity",), **kw))
    held = simulate(
        g.vertices, g.faces, body, _still(10), settings=SimSettings(effects=("gravity", "body_collision"), **kw)
    )
    drop_free = (g.vertices[:, 1] - free.frames[-1][:, 1]).mean()
    assert drop_free > 0.05  # falls freely through the body (about 0.5 g t^2)
    assert held.blender["applied"]["use_collision"] and "COLLISION" in held.blender["applied"]["body_modifiers"]
    proxy = BodyProxy(body.shaped_vertices()[0], body.faces)
    inside_free = (proxy.query(free.frames[-1]).signed_distance < -0.005).sum()
    inside_held = (proxy.query(held.frames[-1]).signed_distance < -0.005).sum()
    assert inside_held < inside_free and inside_held <= 0.01 * len(g.vertices)


def test_vertex_order_is_the_garments(sim_python, body, coarse_skirt):
    g = coarse_skirt
    perm = np.random.default_rng(0).permutation(len(g.vertices))
    inv = np.argsort(perm)
    st = SimSettings(effects=("gravity", "body_collision"), drape_seconds=0.1, blend_seconds=0.0, quality=3)
    a = simulate(g.vertices, g.faces, body, _still(4), settings=st)
    b = simulate(g.vertices[perm], inv[g.faces], body, _still(4), settings=st)
    d = np.linalg.norm(a.frames[:, perm] - b.frames, axis=2)
    wrong = np.linalg.norm(a.frames - b.frames, axis=2)  # what a lost vertex order would look like
    # the same cloth: the solver's collision order differs a little (measured: median 0.14 mm, max 6.6 mm)
    assert np.median(d) < 1e-3 and d.max() < 0.02 and np.median(wrong) > 0.1


def test_pinned_waistband_follows_the_body(sim_python, body, coarse_skirt):
    g = coarse_skirt
    mo = make_motion("walk", seconds=0.5, fps=30)
    st = SimSettings(effects=("gravity", "body_collision", "pinning"), drape_seconds=0.1, blend_seconds=0.1, quality=5)
    r = simulate(g.vertices, g.faces, body, mo, settings=st)
    pins = pin_weights(g.vertices, g.faces, "waistband") > 0
    from segadeform.body.transfer import skin_garment, transfer_weights

    w = transfer_weights(g.vertices, body.shaped_vertices()[0], body.faces, body.weights)
    skinned = skin_garment(g.vertices, w, body, mo.poses, None, mo.trans)
    assert pins.sum() > 10 and r.blender["applied"]["vertex_group_mass"] == "pin"
    assert np.abs(r.frames[:, pins] - skinned[:, pins]).max() < 5e-3
    assert r.blender["body_playback_max_error"] < 1e-5


def test_every_piece_of_a_garment_is_held_by_a_pin(coarse_skirt):
    """A button beside the skirt is pinned whole; a second large piece by its own waistband; the skirt as alone."""
    from segadeform.geometry.primitives import grid_plane

    g = coarse_skirt
    alone = pin_weights(g.vertices, g.faces, "waistband")
    bv, bf = grid_plane(4, 4)
    button = np.asarray(bv, np.float64) * 0.02 + g.vertices.mean(0) + [0.0, 0.0, 0.3]  # a 2 cm square, lower down
    low = g.vertices - [0.0, 0.5, 0.0]  # a second skirt 0.5 m lower: its waistband is no longer the highest
    n = len(g.vertices)
    v = np.concatenate([g.vertices, button, low])
    f = np.concatenate([g.faces, np.asarray(bf) + n, g.faces + n + len(bv)])
    w = pin_weights(v, f, "waistband")
    assert np.array_equal(w[:n], alone)  # the piece the rule pins is pinned as when alone
    assert np.all(w[n : n + len(bv)] == 1.0)  # sewn on: follows the garment whole
    np.testing.assert_array_equal(w[n + len(bv) :], alone)  # pinned by the rule on itself
    with pytest.raises(InputError, match="pin group"):
        pin_weights(v, f, "sleeves")


def test_top_and_waist_pins_a_jumpsuit_at_the_shoulders_and_round_the_waist(body):
    """``top+waist``: the top group and a closed ring at the body's waist height, nothing else (the
    jumpsuit's legs hang from a belt, not from the shoulders: docs/simulator-gate.md, fourteenth study)."""
    from segadeform.garments import make_garment

    g = make_garment("jumpsuit", body)
    v = g.vertices
    wh = waist_height(body)
    j = body.rest_joints()[0]
    names = body.joint_names
    assert j[names.index("pelvis"), 1] < wh < j[names.index("spine2"), 1]
    top = pin_weights(v, g.faces, "top") > 0
    both = pin_weights(v, g.faces, "top+waist", waist_height=wh) > 0
    belt = both & ~top
    assert np.all(both[top])  # the top stays pinned
    assert belt.sum() >= 30 and np.all(np.abs(v[belt, 1] - wh) <= 0.025)
    assert np.array_equal(belt, (np.abs(v[:, 1] - wh) <= 0.025) & ~top)  # every vertex at the waist, only those
    # a ring round the body, not a patch: every eighth of the turn about the vertical axis has belt vertices
    c = v[belt].mean(0)
    octant = np.floor((np.arctan2(v[belt, 2] - c[2], v[belt, 0] - c[0]) + np.pi) / (np.pi / 4)).astype(int) % 8
    assert set(octant.tolist()) == set(range(8))
    with pytest.raises(InputError, match="waist height"):
        pin_weights(v, g.faces, "top+waist")
    with pytest.raises(InputError, match=r"no garment vertex lies at the body's waist height.*heights"):
        pin_weights(v, g.faces, "top+waist", waist_height=5.0)


def test_the_simulator_is_given_the_waist_pin(sim_python, body, tmp_path):
    """``simulate`` with ``pin = "top+waist"`` hands Blender the top and the waist ring of the body's own
    waist (its shape's, not the template's), and those vertices follow the skinned garment."""
    from segadeform.body.transfer import skin_garment, transfer_weights
    from segadeform.garments import make_garment

    betas = np.array([1.0, 0.5])
    g = make_garment("jumpsuit", body, betas)
    mo = make_motion("walk", seconds=0.2, fps=30)
    st = SimSettings(effects=("pinning",), pin="top+waist", drape_seconds=0.1, blend_seconds=0.0, quality=2)
    r = simulate(g.vertices, g.faces, body, mo, betas=betas, settings=st, keep_job=tmp_path / "job")
    sent = np.load(tmp_path / "job" / "pins.npy") > 0
    want = pin_weights(g.vertices, g.faces, "top+waist", waist_height=waist_height(body, betas)) > 0
    assert np.array_equal(sent, want)
    assert not np.array_equal(want, pin_weights(g.vertices, g.faces, "top+waist", waist_height=waist_height(body)) > 0)
    w = transfer_weights(g.vertices, body.shaped_vertices(betas[None])[0], body.faces, body.weights)
    skinned = skin_garment(g.vertices, w, body, mo.poses, betas, mo.trans)
    assert np.abs(r.frames[:, want] - skinned[:, want]).max() < 5e-3


def test_preroll_starts_at_rest_and_ends_at_the_first_frame():
    mo = make_motion("dance", seconds=0.3, fps=30, ease_in=0)
    p, t = preroll_poses(mo, 3, 4)
    assert p.shape == (3 + 4 + mo.n_frames, 72)
    assert np.all(p[:3] == 0) and np.allclose(p[7:], mo.poses)
    d = np.abs(np.diff(p[:8], axis=0)).max(axis=1)
    assert d.max() <= np.abs(mo.poses[0]).max() / 2  # no jump: the blend spreads the first pose out


def test_missing_simulator_is_a_clear_error(tmp_path, monkeypatch, body, coarse_skirt):
    monkeypatch.setenv("SEGADEFORM_SIM_PYTHON", str(tmp_path / "nope" / "python"))
    with pytest.raises(SimulationError, match="does not exist"):
        simulate(coarse_skirt.vertices, coarse_skirt.faces, body, _still(2))


def test_a_failing_solver_reports_its_error(tmp_path, body, coarse_skirt):
    fake = tmp_path / "python"
    fake.write_text("#!/bin/sh\necho 'bpy exploded' >&2\nexit 3\n")
    fake.chmod(0o755)
    with pytest.raises(SimulationError, match="bpy exploded"):
        simulate(coarse_skirt.vertices, coarse_skirt.faces, body, _still(2), sim_python=fake)


def test_wind_blows_the_cloth_along_its_direction(sim_python, body, coarse_skirt):
    g = coarse_skirt
    kw = dict(drape_seconds=0.1, blend_seconds=0.0, quality=3, wind=(1.0, 0.0, 0.0), wind_strength=100.0)
    calm = simulate(g.vertices, g.faces, body, _still(20), settings=SimSettings(effects=(), **kw))
    windy = simulate(g.vertices, g.faces, body, _still(20), settings=SimSettings(effects=("wind",), **kw))
    a = windy.blender["applied"]
    assert "wind" in a["objects"] and a["effector_wind"] == 1.0 and "wind" not in calm.blender["applied"]["objects"]
    shift = (windy.frames[-1] - calm.frames[-1]).mean(axis=0)  # measured: 1.5 cm along +x in 0.7 s
    assert shift[0] > 5e-3 and abs(shift[1]) < 0.2 * shift[0] and abs(shift[2]) < 0.2 * shift[0]


def test_unposing_then_skinning_gives_back_the_a_posed_garment(body):
    """The pinned vertices' input starts from the cloth's own A-posed rest: LBS of the unposed garment
    reproduces it (and the plain LBS of the T-posed garment would not)."""
    from segadeform.body.transfer import skin_garment, transfer_weights
    from segadeform.garments import make_garment
    from segadeform.physics import A_POSE, unpose_lbs

    g = make_garment("tshirt", body, cloth_pose=A_POSE)
    w = transfer_weights(g.vertices, body.shaped_vertices()[0], body.faces, body.weights)
    back = skin_garment(unpose_lbs(g.cloth_rest, w, body.forward(A_POSE[None]).transforms[0]), w, body, A_POSE[None])[0]
    assert np.abs(back - g.cloth_rest).max() < 1e-9
    assert np.abs(skin_garment(g.vertices, w, body, A_POSE[None])[0] - g.cloth_rest).max() > 1e-3


def test_a_fast_clip_gets_more_solver_steps(sim_python, body, coarse_skirt):
    g = coarse_skirt
    n = 6
    trans = np.zeros((n, 3))
    trans[3:, 0] = 0.25  # the body jumps 25 cm between frames 2 and 3 of the motion
    mo = Motion(poses=np.zeros((n, 72)), trans=trans, fps=30.0)
    st = SimSettings(
        effects=("gravity", "body_collision"), drape_seconds=0.1, blend_seconds=0.0, quality=4, max_step_motion=0.06
    )
    fast = simulate(g.vertices, g.faces, body, mo, settings=st)
    plain = simulate(g.vertices, g.faces, body, mo, settings=st.replace(max_step_motion=0.0))
    same = simulate(g.vertices, g.faces, body, mo, settings=st.replace(max_step_motion=0.0, quality=5))
    # ceil(25 cm / 6 cm) = 5 steps per frame for the whole clip, read back from Blender, and the frames are
    # those of quality 5 (not of 4: the steps reach the solver)
    assert fast.blender["applied"]["cloth"]["quality"] == 5 and plain.blender["applied"]["cloth"]["quality"] == 4
    to_same, to_plain = np.abs(fast.frames - same.frames).max(), np.abs(fast.frames - plain.frames).max()
    assert to_same < 1e-5 < to_plain, (to_same, to_plain)
    # without body_collision the body cannot reach the cloth: its motion raises no steps (a scene's trial: 4 -> 38)
    free = simulate(g.vertices, g.faces, body, mo, settings=st.replace(effects=("gravity",)))
    assert free.blender["applied"]["cloth"]["quality"] == 4


def test_an_untangled_body_is_what_blender_collides_with(sim_python, body, coarse_skirt, tmp_path):
    from segadeform.body.untangle import untangle, vertex_parts
    from segadeform.io.pc2 import read_pc2
    from segadeform.settings.scene import Y_TO_Z

    g = coarse_skirt
    n = 3
    poses = np.zeros((n, 72))
    poses[:, 1 * 3 + 2], poses[:, 2 * 3 + 2] = -0.25, 0.25  # the thighs cross each other
    mo = Motion(poses=poses, trans=np.zeros((n, 3)), fps=30.0)
    st = SimSettings(effects=("body_collision",), drape_seconds=0.1, blend_seconds=0.0, quality=2, untangle_body=True)
    simulate(g.vertices, g.faces, body, mo, settings=st, keep_job=tmp_path / "job")
    played = np.asarray(read_pc2(tmp_path / "job" / "body.pc2", mmap=False).frames[-1], np.float64) @ np.array(Y_TO_Z)
    posed = body.forward(poses[-1:]).vertices[0]
    want = untangle(posed, body.faces, vertex_parts(body.weights), body.shaped_vertices()[0], gap=2 * 0.005 + 0.001)
    assert np.abs(played - want).max() < 1e-5 < np.abs(played - posed).max()
