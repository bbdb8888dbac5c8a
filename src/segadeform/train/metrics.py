"""The paper's metrics (§5) of one prediction against the simulation (see :mod:`segadeform.train.evaluate` for the
list); :func:`reference` computes once per sample what every prediction is compared with."""

from __future__ import annotations

import dataclasses

import numpy as np

from ..body.collision import BodyCollider
from ..body.model import BodyModel
from ..dataset.store import Sample
from ..geometry.laplacian import SpectralBasis
from ..geometry.mesh_ops import unique_edges, vertex_normals

__all__ = [
    "METRICS",
    "PEAK_METRICS",
    "PEN_DEPTH",
    "THROUGH_DEPTH",
    "Reference",
    "penetrating",
    "reference",
    "sample_metrics",
    "through_faces",
]

METRICS = (
    "vertex_cm",
    "normal_deg",
    "edge_mm",
    "low_cm",
    "mid_cm",
    "high_cm",
    "penetration_pct",
    "pinched_pct",
    "through_pct",
    "jitter_mm",
    "max_strain_pct",
    "p99_strain_pct",
)
#: metrics aggregated over samples by their largest value, not their mean
PEAK_METRICS = ("max_strain_pct",)
PEN_DEPTH = 0.002
#: metres: a face whose centre is deeper than this inside the body while none of its corners penetrates spans a
#: limb (``through_pct``); 5 mm, above the sagitta of a 4 cm edge wrapped round a thigh at the collision margin
THROUGH_DEPTH = 0.005


def _normals(x, faces):
    return np.stack([vertex_normals(f, faces) for f in x])


@dataclasses.dataclass
class Reference:
    """What every prediction of one sample is compared with, computed once per sample.

    Shapes: gt (T, N, 3); n_gt (T, N, 3) vertex normals; l_gt (T, E) edge lengths; acc_gt (T-2, N, 3)
    second differences; posed (T, V, 3): the posed body (what the runtime's collider pushes out of)."""

    gt: np.ndarray
    faces: np.ndarray
    edges: np.ndarray
    basis: SpectralBasis
    n_gt: np.ndarray
    l_gt: np.ndarray
    acc_gt: np.ndarray
    posed: np.ndarray | None = None
    #: the posed body's exact collider (the penetration metric: winding number and distance)
    collider: BodyCollider | None = None
    #: (E,) the edges' lengths on the garment's rest mesh (the strain metrics' reference)
    l_rest: np.ndarray | None = None


def reference(s: Sample, body: BodyModel, basis: SpectralBasis | None = None) -> Reference:
    """The simulated frames of sample ``s`` and what the metrics derive from them (``basis``: the rest
    garment's spectral basis, made here when not given)."""
    gt = s.frames.astype(np.float64)
    edges = unique_edges(s.faces, len(s.rest))
    basis = basis if basis is not None else SpectralBasis.from_mesh(s.rest, s.faces)
    posed = body.forward(s.poses, s.betas if s.betas.size else None, s.trans).vertices
    return Reference(
        gt=gt,
        faces=s.faces,
        edges=edges,
        basis=basis,
        n_gt=_normals(gt, s.faces),
        l_gt=np.linalg.norm(gt[:, edges[:, 0]] - gt[:, edges[:, 1]], axis=2),
        acc_gt=gt[2:] - 2 * gt[1:-1] + gt[:-2],
        posed=posed,
        l_rest=np.linalg.norm(s.rest[edges[:, 0]] - s.rest[edges[:, 1]], axis=1),
        collider=BodyCollider(posed[0], body.faces),
    )


def penetrating(ref: Reference, points: np.ndarray, t: int) -> np.ndarray:
    """Which of ``points`` (N, 3) lie more than :data:`PEN_DEPTH` inside the body posed at frame ``t``: inside by the
    body's winding number (so inside the torso counts where an arm pressed into it is the closest surface -- the
    closest surface's side, used before 30 Nov 2026, called such a point outside), and farther than PEN_DEPTH from
    every surface of the body.  Shapes: points (N, 3) -> (N,) bool."""
    return penetrating_and_pinched(ref, points, t)[0]


def penetrating_and_pinched(ref: Reference, points: np.ndarray, t: int) -> tuple[np.ndarray, np.ndarray]:
    """:func:`penetrating`, and which of those are pinched: in a pinch where the posed body intersects itself (an
    arm pressed into the torso), inside by the winding number while the side of the surface nearest them -- the
    skin of the arm buried in the torso -- says outside.  Cloth there has no outside nearer than across the arm;
    the simulator's own frames hold some (``segadeform eval -m blender=simulation``).
    Shapes: points (N, 3) -> (N,) bool, (N,) bool."""
    inside = ref.collider.winding(points, ref.posed[t]) > 0
    out, pinched = np.zeros(len(points), bool), np.zeros(len(points), bool)
    if inside.any():
        sd = ref.collider.query(points[inside], ref.posed[t]).signed_distance
        k = np.flatnonzero(inside)
        out[k] = np.abs(sd) > PEN_DEPTH
        pinched[k] = sd > PEN_DEPTH
    return out, pinched


def through_faces(ref: Reference, points: np.ndarray, t: int, corners_in: np.ndarray | None = None) -> np.ndarray:
    """Which faces of the garment at ``points`` (N, 3) span the body posed at frame ``t``: the face's centre is inside
    by the body's winding number and deeper than :data:`THROUGH_DEPTH` from every surface, while none of its corners
    is :func:`penetrating` (``corners_in`` (N,) bool, computed when not given).  Every vertex is outside and the
    cloth still shows a limb through it: what a render shows as a hole (a thigh between two vertices taken out on
    opposite sides of it).  Shapes: points (N, 3) -> (F,) bool."""
    faces = ref.faces
    if corners_in is None:
        corners_in = penetrating(ref, points, t)
    free = ~corners_in[faces].any(axis=1)
    out = np.zeros(len(faces), bool)
    if not free.any():
        return out
    k = np.flatnonzero(free)
    centres = points[faces[k]].mean(axis=1)
    inside = ref.collider.winding(centres, ref.posed[t]) > 0
    if inside.any():
        sd = ref.collider.query(centres[inside], ref.posed[t]).signed_distance
        out[k[np.flatnonzero(inside)]] = np.abs(sd) > THROUGH_DEPTH
    return out


def sample_metrics(x: np.ndarray, ref: Reference, frame_step: int = 1) -> dict:
    """The :data:`METRICS` of one prediction ``x`` (T, N, 3) against ``ref`` (bands and penetration on
    every ``frame_step``-th frame)."""
    gt, faces, edges = ref.gt, ref.faces, ref.edges
    d = np.linalg.norm(x - gt, axis=2)
    cosang = np.clip((_normals(x, faces) * ref.n_gt).sum(-1), -1, 1)
    l_x = np.linalg.norm(x[:, edges[:, 0]] - x[:, edges[:, 1]], axis=2)
    frames = range(0, len(gt), frame_step)
    bands = np.zeros(3)
    for t in frames:
        lo, mid, hi = ref.basis.split(x[t] - gt[t])
        bands += [
            np.linalg.norm(lo, axis=1).mean(),
            np.linalg.norm(mid, axis=1).mean(),
            np.linalg.norm(hi, axis=1).mean(),
        ]
    bands /= len(frames)
    rows = []
    for t in frames:
        pen_t, pinch_t = penetrating_and_pinched(ref, x[t], t)
        rows.append(
            (pen_t.mean(), pinch_t.mean(), through_faces(ref, x[t], t, pen_t).mean() if len(ref.faces) else 0.0)
        )
    pen, pinch, through = np.array(rows).mean(axis=0)
    jit = np.linalg.norm((x[2:] - 2 * x[1:-1] + x[:-2]) - ref.acc_gt, axis=2).mean() if len(gt) > 2 else 0.0
    # stretch (compression counts as 0): what a stretch limit bounds
    strain = (
        np.maximum(l_x / np.maximum(ref.l_rest, 1e-12) - 1, 0)
        if ref.l_rest is not None and len(edges)
        else np.zeros((1, 1))
    )
    return {
        "vertex_cm": 100 * d.mean(),
        "normal_deg": np.degrees(np.arccos(cosang)).mean(),
        "edge_mm": 1000 * np.abs(l_x - ref.l_gt).mean(),
        "low_cm": 100 * bands[0],
        "mid_cm": 100 * bands[1],
        "high_cm": 100 * bands[2],
        "penetration_pct": 100 * pen,
        "pinched_pct": 100 * pinch,
        "through_pct": 100 * through,
        "jitter_mm": 1000 * jit,
        "max_strain_pct": 100 * float(strain.max()),
        "p99_strain_pct": 100 * float(np.percentile(strain, 99)),
    }
