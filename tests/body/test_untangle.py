"""The collision body without self-intersection (segadeform.body.untangle)."""

import numpy as np
import pytest

from segadeform.body import load_body
from segadeform.body.collision import BodyCollider
from segadeform.body.untangle import PART_OF_JOINT, untangle, vertex_parts
from segadeform.errors import InputError
from tests.conftest import SAMPLES

from ._shapes import sphere


def two_spheres(part_a, part_b, overlap=0.1, radius=0.2, rest_apart=1.0):
    """Two closed spheres of ``radius`` whose centres are ``2 radius - overlap`` apart (posed) and ``rest_apart``
    apart at rest, parts ``part_a`` and ``part_b``."""
    v, f = sphere(24, 16)
    v = v * radius
    d = 2 * radius - overlap
    posed = np.concatenate([v, v + [d, 0, 0]])
    rest = np.concatenate([v, v + [rest_apart, 0, 0]])
    faces = np.concatenate([f, f + len(v)])
    part = np.repeat([part_a, part_b], len(v))
    return posed, faces, part, rest


def inside_other(x, faces, part, p, q):
    """Signed distance of part ``p``'s vertices to part ``q``'s triangles (negative inside)."""
    fq = faces[(part[faces] == q).all(axis=1)]
    return BodyCollider(x, fq).query(x[part == p], x).signed_distance


def test_two_limbs_meet_in_the_middle_and_nothing_else_moves():
    posed, faces, part, rest = two_spheres(3, 4, overlap=0.1)
    assert (inside_other(posed, faces, part, 3, 4) < -0.01).any()  # the case is a real intersection
    out = untangle(posed, faces, part, rest, gap=0.0, passes=6)
    for p, q in ((3, 4), (4, 3)):
        assert inside_other(out, faces, part, p, q).min() > -2e-3
    moved = np.linalg.norm(out - posed, axis=1)
    # a vertex outside the other sphere stays; each moves by about half the overlap at most (a polygon, not a sphere)
    far = np.abs(posed[:, 0] - 0.15) > 0.12
    assert moved[far].max() == 0.0
    assert 0.02 < moved.max() <= 0.055
    # both move (same rank: legs)
    assert moved[part == 3].max() > 0.02 and moved[part == 4].max() > 0.02


def test_the_torso_stays_and_the_arm_gives_way():
    posed, faces, part, rest = two_spheres(0, 1, overlap=0.06)
    out = untangle(posed, faces, part, rest, gap=0.0)
    assert np.array_equal(out[part == 0], posed[part == 0])
    assert inside_other(out, faces, part, 1, 0).min() > -1e-6
    assert np.linalg.norm(out - posed, axis=1).max() == pytest.approx(0.06, abs=0.005)


def test_a_joint_is_not_two_parts_and_a_deep_point_is_left_alone():
    posed, faces, part, rest = two_spheres(3, 4, overlap=0.1, rest_apart=0.35)  # closest points < 8 cm at rest
    assert np.array_equal(untangle(posed, faces, part, rest, separation=0.2), posed)
    posed, faces, part, rest = two_spheres(3, 4, overlap=0.3)  # 30 cm deep: not a limb against a limb
    out = untangle(posed, faces, part, rest, max_depth=0.05, passes=1)
    depth = -inside_other(posed, faces, part, 3, 4)
    moved = np.linalg.norm(out - posed, axis=1)[part == 3]
    assert (depth > 0.05).sum() > 10 and moved[depth > 0.05].max() == 0.0
    assert moved[(depth > 0.01) & (depth < 0.04)].min() > 0.0


def test_frames_are_independent_and_one_part_is_a_no_op():
    posed, faces, part, rest = two_spheres(3, 4)
    other = posed * [1.0, 1.0, 1.1] + [0.0, 1.0, 0.0]
    both = untangle(np.stack([posed, other]), faces, part, rest)
    assert np.array_equal(both[0], untangle(posed, faces, part, rest))
    assert np.array_equal(both[1], untangle(other, faces, part, rest))
    same = np.zeros_like(part)
    assert np.array_equal(untangle(posed, faces, same, rest), posed)


def test_the_default_body_with_thighs_pressed_into_each_other():
    body = load_body(SAMPLES / "bodies" / "default_body.npz")
    part = vertex_parts(body.weights)
    assert set(np.unique(part)) == {0, 1, 2, 3, 4}
    assert np.array_equal(part, PART_OF_JOINT[np.asarray(body.weights).argmax(axis=1)])
    pose = np.zeros((1, 72))
    pose[0, 1 * 3 + 2], pose[0, 2 * 3 + 2] = -0.25, 0.25  # both hips turned in: the thighs cross
    posed = body.forward(pose).vertices[0]
    rest = body.shaped_vertices()[0]

    def hits(x):  # vertices of one leg more than 3 mm inside the other, away from the crotch
        out = 0
        for a, b in ((3, 4), (4, 3)):
            fb = body.faces[(part[body.faces] == b).all(axis=1)]
            q = BodyCollider(x, fb).query(x[part == a], x)
            apart = np.linalg.norm(rest[fb[q.face]] - rest[part == a][:, None], axis=2).min(axis=1) > 0.08
            out += int(((q.signed_distance < -0.003) & apart).sum())
        return out

    before = hits(posed)
    out = untangle(posed, body.faces, part, rest)
    assert before > 100  # the thighs are in each other ...
    assert hits(out) <= before // 5  # ... and out of each other
    moved = np.linalg.norm(out - posed, axis=1)
    assert moved[part == 3].max() > 0.01 and moved[part == 4].max() > 0.01  # both give way
    assert np.array_equal(out[part <= 2], posed[part <= 2])  # torso and arms stay
    assert np.isfinite(out).all() and moved.max() < 0.1


@pytest.mark.parametrize(
    "kw, msg",
    [
        ({"posed": np.zeros((2, 3))}, "posed body"),
        ({"posed": np.full((4, 3), np.nan)}, "NaN"),
        ({"part": np.zeros(3)}, "rest and part"),
        ({"separation": -1.0}, "separation"),
        ({"max_depth": 0.0}, "max_depth"),
        ({"gap": 0.5}, "gap"),
        ({"passes": 0}, "passes"),
    ],
)
def test_bad_input_is_a_clear_error(kw, msg):
    posed, faces, part, rest = two_spheres(3, 4)
    args = {"posed": posed, "faces": faces, "part": part, "rest": rest} | kw
    with pytest.raises(InputError, match=msg):
        untangle(args.pop("posed"), args.pop("faces"), args.pop("part"), args.pop("rest"), **args)


def test_parts_closer_than_the_gap_are_moved_apart_to_it():
    posed, faces, part, rest = two_spheres(3, 1, overlap=-0.002)  # a hand 2 mm from a thigh, not in it
    out = untangle(posed, faces, part, rest, gap=0.006, passes=4)
    assert np.array_equal(out[part == 3], posed[part == 3])  # the leg ranks higher and stays
    assert inside_other(out, faces, part, 1, 3).min() > 0.0055
    assert 0.001 < np.linalg.norm(out - posed, axis=1).max() < 0.0045  # at most the 4 mm missing
