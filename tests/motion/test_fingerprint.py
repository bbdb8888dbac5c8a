"""The motion fingerprint (segadeform.motion.fingerprint): the fast comparison against its slow reference, the
invariances it rests on (constant rotations before and after each joint's, frame rate), the text form, bad input;
and on the CMU files in ../shared: one trial read from its BVH and from its ASF/AMC is one capture, another trial
of the same subject is not."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from segadeform.body.rotations import axis_angle_to_matrix, matrix_to_axis_angle
from segadeform.errors import InputError
from segadeform.motion import load_motion
from segadeform.motion.fingerprint import (
    BASELINE,
    JOINTS,
    MAX_SPEED,
    SAME_CAPTURE,
    STILL,
    capture_distance,
    capture_distance_reference,
    decode_speeds,
    encode_speeds,
    joint_speeds,
    nearest_capture,
)

SHARED = Path(__file__).resolve().parents[3] / "shared" / "data" / "mocap"
needs_shared = pytest.mark.skipif(not (SHARED / "cmu_asf_amc").is_dir(), reason=f"the CMU trials are not in {SHARED}")


def _smooth_poses(rng, frames: int, fps: float = 30.0) -> np.ndarray:
    """(frames, 72) poses whose joints swing smoothly (sums of sines with random phases)."""
    t = np.arange(frames)[:, None] / fps
    f, ph, amp = rng.uniform(0.3, 2.0, (3, 72)), rng.uniform(0, 6.3, (3, 72)), rng.uniform(0.05, 0.4, (3, 72))
    return sum(amp[i] * np.sin(2 * np.pi * f[i] * t + ph[i]) for i in range(3))


@pytest.mark.parametrize("n,m", [(40, 90), (90, 40), (30, 30), (1, 5), (7, 1), (61, 300)])
def test_the_fast_distance_equals_the_reference_loop(n, m):
    rng = np.random.default_rng(n * 1000 + m)
    a = rng.uniform(0, 3, (n, len(JOINTS)))
    b = rng.uniform(0, 3, (m, len(JOINTS)))
    b[m // 3 : m // 3 + n // 2] = a[: min(n // 2, m - m // 3)] * 1.01  # one offset near the same capture
    assert capture_distance(a, b) == pytest.approx(capture_distance_reference(a, b), rel=1e-9)
    assert capture_distance(b, a) == pytest.approx(capture_distance_reference(b, a), rel=1e-9)


def test_a_stretch_of_a_motion_is_the_same_capture_and_another_motion_is_not():
    rng = np.random.default_rng(0)
    p = _smooth_poses(rng, 300)
    whole = joint_speeds(p, 30.0)
    assert capture_distance(joint_speeds(p[100:160], 30.0), whole) < 1e-6
    # overhanging the end by less than half the clip still finds it
    assert capture_distance(joint_speeds(p[270:], 30.0), joint_speeds(p[:290], 30.0)) < 1e-6
    other = joint_speeds(_smooth_poses(np.random.default_rng(1), 300), 30.0)
    assert capture_distance(joint_speeds(p[100:160], 30.0), other) > SAME_CAPTURE
    assert nearest_capture(joint_speeds(p[100:160], 30.0), [other, whole]) == (1, pytest.approx(0.0, abs=1e-6))
    assert nearest_capture(whole, []) == (-1, float("inf"))


def test_the_fingerprint_ignores_constant_rotations_before_and_after_each_joint():
    """A rig whose rest pose differs (``A R(t) B`` for constant ``A``, ``B``) has the same joint speeds."""
    rng = np.random.default_rng(2)
    p = _smooth_poses(rng, 120)
    r = axis_angle_to_matrix(p.reshape(-1, 24, 3))
    a = axis_angle_to_matrix(rng.normal(0, 0.8, (24, 3)))
    b = axis_angle_to_matrix(rng.normal(0, 0.8, (24, 3)))
    q = matrix_to_axis_angle(np.einsum("jab,tjbc,jcd->tjad", a, r, b)).reshape(-1, 72)
    np.testing.assert_allclose(joint_speeds(q, 30.0), joint_speeds(p, 30.0), atol=2e-4)
    # while the joints' rotations themselves are far apart
    assert np.abs(q - p).max() > 0.5


def test_the_fingerprint_does_not_depend_on_the_frame_rate():
    t120 = np.arange(480) / 120.0
    p = np.zeros((480, 72))
    p[:, 3 * 4] = 0.6 * np.sin(2 * np.pi * 0.8 * t120)  # a knee bending
    p[:, 3 * 16 + 2] = 0.4 * np.sin(2 * np.pi * 0.5 * t120 + 1.0)  # a shoulder
    p[:, 1] = 0.5 * t120  # the root turning
    at120, at24 = joint_speeds(p, 120.0), joint_speeds(p[::5], 24.0)
    assert capture_distance(at24, at120) < 0.03
    assert at120.shape == (120 - BASELINE, len(JOINTS))  # 4 s at 30 fps, a speed over each BASELINE frames


def test_a_still_motion_is_not_compared():
    still = np.zeros((60, 72))
    s = joint_speeds(still, 30.0)
    assert np.abs(s).max() < 1e-6 and capture_distance(s, s) == float("inf")
    slow = joint_speeds(np.linspace(0, 0.1, 60)[:, None] * np.ones(72), 30.0)  # turning under STILL rad/s
    assert np.sqrt((slow**2).mean()) < STILL and capture_distance(slow, slow) == float("inf")
    assert joint_speeds(np.zeros((1, 72)), 30.0).shape == (0, len(JOINTS))
    assert capture_distance(np.zeros((0, len(JOINTS))), s) == float("inf")


def test_the_text_form_round_trips_in_square_root_steps():
    rng = np.random.default_rng(3)
    s = rng.uniform(0, MAX_SPEED, (57, len(JOINTS))).astype(np.float32)
    back = decode_speeds(encode_speeds(s))
    # half a step of q = 255 sqrt(s / MAX_SPEED): d s = sqrt(MAX_SPEED s) / 255, plus the step's curvature
    assert back.shape == s.shape and (np.abs(back - s) <= np.sqrt(MAX_SPEED * s) / 255 + 2e-4).all()
    assert np.abs(back - s).max() < 0.05  # at MAX_SPEED: sqrt(12 * 12) / 255
    assert decode_speeds(encode_speeds(np.zeros((0, len(JOINTS))))).shape == (0, len(JOINTS))
    assert decode_speeds(encode_speeds(np.full((1, len(JOINTS)), 99.0))).max() == pytest.approx(MAX_SPEED)


@pytest.mark.parametrize(
    "call,match",
    [
        (lambda: joint_speeds(np.zeros((5, 69)), 30), r"expected poses \(T, 72\)"),
        (lambda: joint_speeds(np.zeros((0, 72)), 30), r"expected poses \(T, 72\)"),
        (lambda: joint_speeds(np.full((5, 72), np.nan), 30), "expected finite poses"),
        (lambda: joint_speeds(np.zeros((5, 72)), 0), "expected a positive frame rate"),
        (lambda: capture_distance(np.zeros((5, 4)), np.zeros((5, len(JOINTS)))), "expected a fingerprint"),
        (lambda: encode_speeds(-np.ones((2, len(JOINTS)))), "non-negative"),
        (lambda: decode_speeds("not base64!"), "expected a base64 fingerprint"),
        (lambda: decode_speeds("AAAA"), "whole frames"),
        (lambda: decode_speeds(None), "expected a base64 fingerprint"),
    ],
)
def test_bad_input_says_what_was_expected(call, match):
    with pytest.raises(InputError, match=match):
        call()


@needs_shared
def test_one_cmu_trial_in_two_formats_is_one_capture_and_the_next_trial_is_not():
    """02_01 from cgspeed's BVH and from CMU's own ASF/AMC (different rigs: their joints' rotations are as far apart
    as two walks') are one capture; the subject's next walk, 02_02, is not; and a BVH on another body shape is the
    same capture."""
    from segadeform.body import default_body_path, load_body

    body = load_body(default_body_path())
    rj = body.rest_joints(None)[0]
    bvh = load_motion(SHARED / "cmu" / "02_01_walk.bvh", rest_joints=rj, floor=True)
    amc = load_motion(SHARED / "cmu_asf_amc" / "02" / "02_01.amc", rest_joints=rj, floor=True)
    nxt = load_motion(SHARED / "cmu_asf_amc" / "02" / "02_02.amc", rest_joints=rj, floor=True)
    other_body = load_motion(
        SHARED / "cmu" / "02_01_walk.bvh", rest_joints=body.rest_joints([2.0, 1.0] + [0.0] * 8)[0], floor=True
    )
    clip = slice(60, 300)  # 2 s of the 120 fps capture
    whole_bvh = joint_speeds(bvh.poses, bvh.fps)
    assert capture_distance(joint_speeds(amc.poses[clip], amc.fps), whole_bvh) < SAME_CAPTURE
    assert capture_distance(joint_speeds(bvh.poses[clip], bvh.fps), joint_speeds(amc.poses, amc.fps)) < SAME_CAPTURE
    assert capture_distance(joint_speeds(other_body.poses[clip], other_body.fps), whole_bvh) < 0.01
    assert capture_distance(joint_speeds(nxt.poses[clip], nxt.fps), whole_bvh) > SAME_CAPTURE
    assert capture_distance(joint_speeds(nxt.poses[clip], nxt.fps), joint_speeds(amc.poses, amc.fps)) > SAME_CAPTURE
