"""The catalogue of hard cases: small generated inputs, each with a one-line reason it is hard.

Each case builds a garment, a motion and a body shape; ``test_catalogue.py`` runs
it through every stage that exists (precompute -> garment encoder -> deformer,
in torch and in onnxruntime -> the cloth stage, collisions -> writer) and checks the outcome the
case declares: finite and parity-checked output, or a clear error.  :data:`CLOTH_CASES` names the cloth stage's
cases that need more than that runner (``test_cloth_cases.py``).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable

import numpy as np

from segadeform.geometry.primitives import fan, frustum, grid_plane
from segadeform.motion import make_motion


def skirt(n_around=16, n_rings=6):
    return frustum(n_around, n_rings, 0.17, 0.33, 1.02, 0.55)


def walk(frames=8):
    m = make_motion("walk", seconds=frames / 30.0 + 1.0)
    return m.poses[-frames:], m.trans[-frames:]


def still(frames=4):
    return np.zeros((frames, 72)), np.zeros((frames, 3))


@dataclasses.dataclass(frozen=True)
class Case:
    name: str
    reason: str
    mesh: Callable = skirt
    motion: Callable = walk
    betas: tuple = ()
    error: str | None = None  # an invalid input: the message the clear error must contain
    known_failure: str | None = None  # fails today: why (the test is xfail-strict and flips when fixed)
    collisions: bool = True


def _rot(joint, vec):
    def make(frames=4):
        p, t = still(frames)
        p[:, 3 * joint : 3 * joint + 3] = vec
        return p, t

    return make


def _mesh_zero_area():
    v, f = skirt()
    v = np.vstack([v, v[0], (v[0] + v[1]) / 2])
    n = len(v)
    return v, np.vstack([f, [[0, 1, n - 1]], [[0, n - 2, 1]]])  # collinear and repeated-point faces


def _mesh_needles():
    v, f = skirt()
    v = v.copy()
    v[1::2, 1] += 1e-7  # every second ring vertex nudged: many slivers
    extra = np.array([[0.2, 1.0, 0.0], [0.2 + 1e-9, 1.0, 0.3], [0.2, 1.0 + 1e-9, 0.6]])
    n = len(v)
    return np.vstack([v, extra]), np.vstack([f, [[n, n + 1, n + 2]]])


def _mesh_duplicates():
    v, f = skirt()
    # split the mesh along a seam: duplicate the first column of vertices, re-point half the faces
    dup = np.arange(0, len(v), 16)
    v2 = np.vstack([v, v[dup]])
    remap = {int(d): len(v) + i for i, d in enumerate(dup)}
    f2 = f.copy()
    for r in range(len(f2) // 2):
        f2[r] = [remap.get(int(x), int(x)) for x in f2[r]]
    return v2, f2


def _mesh_isolated():
    v, f = skirt()
    return np.vstack([v, [[0.0, 1.5, 0.0], [0.1, 0.2, 0.3]]]), f


def _mesh_parts():
    v, f = skirt(12, 4)
    parts = [v + [dx, 0, 0] for dx in (0.0, 0.8, -0.8)]
    return np.vstack(parts), np.vstack([f + i * len(v) for i in range(3)])


def _mesh_nonmanifold():
    v, f = skirt()
    n = len(v)
    e = f[0, :2]
    return np.vstack([v, [[0.0, 0.8, 0.5]]]), np.vstack([f, [[e[0], e[1], n]]])  # a third face on one edge


def _mesh_single_triangle():
    return np.array([[0.2, 1.0, 0.1], [-0.2, 1.0, 0.1], [0.0, 0.8, 0.15]]), np.array([[0, 1, 2]])


def _mesh_three_vertex_double_sided():
    v, f = _mesh_single_triangle()
    return v, np.array([[0, 1, 2], [0, 2, 1]])


def _mesh_flipped():
    v, f = skirt()
    f = f.copy()
    f[::2] = f[::2, ::-1]
    return v, f


def _mesh_fan():
    v, f = fan(64, 0.3)
    return v + [0.0, 1.0, 0.2], f


def _scaled(s, shift=(0.0, 0.0, 0.0)):
    def make():
        v, f = skirt()
        return v * s + np.asarray(shift), f

    return make


def _mesh_inside_body():
    v, f = frustum(16, 6, 0.05, 0.12, 1.1, 0.7)  # thinner than the hips: partly inside the body
    return v, f


def _mesh_strip():
    v, f = grid_plane(30, 2, size=(0.6, 0.02))
    return v + [-0.3, 1.0, 0.2], f


def _mesh_folded():
    v, f = grid_plane(8, 8, size=(0.4, 0.4))
    v = v + [-0.2, 1.0, 0.15]
    v[32:, 1] -= 0.2  # the second half folds through the first
    v[32:, 2] = 0.3 - (v[32:, 2] - 0.15)
    return v, f


def _mesh_nan():
    v, f = skirt()
    v = v.copy()
    v[5, 1] = np.nan
    return v, f


def _mesh_bad_index():
    v, f = skirt()
    return v, np.vstack([f, [[0, 1, len(v) + 3]]])


def _motion_frozen(frames=6):
    m = make_motion("dance", seconds=1.0, seed=4)
    return np.repeat(m.poses[-1:], frames, 0), np.repeat(m.trans[-1:], frames, 0)


def _motion_jump179(frames=6):
    p, t = still(frames)
    p[3:, 3 * 16 : 3 * 16 + 3] = [0.0, 0.0, np.deg2rad(179.0)]  # the left shoulder snaps 179 degrees in one frame
    p[3:, 3 * 5 : 3 * 5 + 3] = [np.deg2rad(179.0), 0.0, 0.0]
    return p, t


def _motion_antipodal(frames=4):
    p, t = still(frames)
    # parent and child twisted so that their global rotations differ by about 180 degrees
    p[:, 3 * 16 : 3 * 16 + 3] = [np.pi * 0.999, 0.0, 0.0]
    p[:, 3 * 18 : 3 * 18 + 3] = [np.pi * 0.999, 0.0, 0.0]
    p[:, 0:3] = [0.0, np.pi, 0.0]
    return p, t


def _motion_nan(frames=3):
    p, t = still(frames)
    p[1, 10] = np.nan
    return p, t


def _motion_empty():
    return np.zeros((0, 72)), np.zeros((0, 3))


def _motion_huge_trans(frames=3):
    p, t = still(frames)
    return p, t + [1e4, 0.0, -1e4]


def _mesh_deep_inside_body():
    v, f = frustum(16, 6, 0.03, 0.05, 1.05, 0.25)  # a narrow tube inside the hips and belly: every vertex deep inside
    return v, f


def _motion_teleport(frames=8):
    m = make_motion("walk", seconds=frames / 30.0 + 1.0)
    p, t = m.poses[-frames:], m.trans[-frames:].copy()
    t[frames // 2 :] += [3.0, 0.0, 2.0]  # the body jumps 3.6 m between two frames
    return p, t


CASES = [
    Case(
        "zero_area_triangles",
        "collinear and repeated-vertex faces have no normal and infinite cotangents",
        _mesh_zero_area,
    ),
    Case("needle_triangles", "slivers give cotangents of 1e7 and near-singular Laplacians", _mesh_needles),
    Case(
        "duplicate_vertices",
        "a seam split into coincident vertices: zero-length edges, two graph parts that touch",
        _mesh_duplicates,
    ),
    Case(
        "isolated_vertices", "vertices in no face: empty neighbour rows, no normal, infinite geodesics", _mesh_isolated
    ),
    Case("disconnected_parts", "three separate pieces: infinite geodesic distances between them", _mesh_parts),
    Case(
        "non_manifold_edge", "an edge shared by three faces breaks boundary and normal assumptions", _mesh_nonmanifold
    ),
    Case("single_triangle", "the smallest garment: one face, N = 3 (fewer vertices than N*)", _mesh_single_triangle),
    Case(
        "three_vertex_double_sided",
        "two opposite faces on 3 vertices: a closed surface with zero volume",
        _mesh_three_vertex_double_sided,
    ),
    Case("flipped_faces", "inconsistent winding: normals cancel at shared vertices", _mesh_flipped),
    Case("high_valence_fan64", "one vertex with 64 neighbours: K is capped and the rest truncated", _mesh_fan),
    Case(
        "millimetre_units",
        "a garment in millimetres (x1000): positions and joint distances 1000x too large",
        _scaled(1000.0),
    ),
    Case(
        "kilometre_units",
        "a garment in kilometres (x0.001): everything within a millimetre of the origin",
        _scaled(0.001),
    ),
    Case(
        "tiny_garment",
        "a 0.3 mm garment: edge lengths near float32 resolution of the positions",
        _scaled(1e-3, (0.0, 1.0, 0.0)),
    ),
    Case(
        "far_from_body",
        "100 m away from the body: huge joint distances, collisions never touch",
        _scaled(1.0, (100.0, 0.0, -100.0)),
    ),
    Case(
        "partly_inside_body",
        "the garment starts inside the hips: collisions must push hundreds of vertices out",
        _mesh_inside_body,
    ),
    Case("one_face_wide_strip", "a ribbon one triangle wide: every vertex is on the boundary", _mesh_strip),
    Case("self_intersecting", "the garment folds through itself", _mesh_folded),
    Case(
        "joint_180_twist",
        "a 180-degree knee twist: the axis-angle inverse and DQS hemisphere test are ambiguous",
        motion=_rot(5, [np.pi, 0.0, 0.0]),
    ),
    Case(
        "joint_360_equivalent",
        "a 2 pi rotation equals none: Rodrigues must give the identity",
        motion=_rot(16, [0.0, 0.0, 2 * np.pi]),
    ),
    Case(
        "antipodal_quaternions",
        "neighbouring joints' quaternions nearly antipodal: DQS must flip, not cancel",
        motion=_motion_antipodal,
    ),
    Case("frozen_motion", "every frame identical: the LSTM sees no change", motion=_motion_frozen),
    Case("one_frame_179_jump", "a 179-degree snap between two frames: huge window differences", motion=_motion_jump179),
    Case(
        "extreme_beta_plus5",
        "+5 sigma body shape: joints and body far outside the training range",
        betas=(5.0, 5.0, 5.0),
    ),
    Case("extreme_beta_minus5", "-5 sigma body shape", betas=(-5.0, -5.0, -5.0)),
    Case(
        "huge_translation",
        "the body 14 km from the origin: float32 positions lose millimetres",
        motion=_motion_huge_trans,
        collisions=False,
    ),
    Case(
        "garment_deep_inside_body",
        "every vertex centimetres inside the body: contact must push the whole garment out",
        _mesh_deep_inside_body,
    ),
    Case(
        "teleporting_body",
        "the body jumps 3.6 m between two frames: inertia would fling the cloth (it resets)",
        motion=_motion_teleport,
    ),
    Case("nan_vertex", "a NaN coordinate: must be refused before anything runs", _mesh_nan, error="NaN"),
    Case("face_index_out_of_range", "a face pointing past the last vertex", _mesh_bad_index, error="out of range"),
    Case("nan_pose", "a NaN in the motion", motion=_motion_nan, error="NaN"),
    Case("empty_motion", "a motion with no frames", motion=_motion_empty, error="T >= 1"),
    Case(
        "too_many_betas",
        "more shape coefficients than the body has",
        betas=tuple(range(12)),
        error="too many shape coefficients",
    ),
]

#: the cloth stage's hard cases beyond the generic runner's (``test_cloth_cases.py``); the generic runner puts every
#: case above through the stage too (zero-length and duplicate edges: duplicate_vertices, degenerate triangles:
#: zero_area_triangles and needle_triangles, vertices with no neighbours: isolated_vertices)
CLOTH_CASES = {
    "cloth_200k_vertices": "a 200,000-vertex garment: setup and sweeps in time and memory linear in N",
    "cloth_stream_10000_frames": "10,000 frames streamed through the stage: state O(N), memory flat, frames unchanged",
    "cloth_nan_from_upstream": "NaN in the deformer's frames or the posed body: refused, naming the frame",
    "cloth_teleport_resets_once": "a body that teleports: no explosion, the stage resets and says so once",
    "cloth_zero_length_edges": "coincident vertices joined by edges of rest length 0: no division by zero",
}
