"""The effect pipeline: garment + body + motion -> frames -> writer, building only the stages asked for.

Stages, in order, and when they exist:

==============  ==================================================  =====================
precompute      garment mesh -> asset (cached on disk by file hash)  always
encode          garment encoder, once per garment and body shape    always (cached)
deform          the deformer variant for skinning/dynamics/wrinkles  always
pose body       body posed per batch (the package's body graph)      collisions, cloth or body output
collisions      push garment vertices out of the body               ``effects.collisions`` without cloth
cloth           stretch, contact and inertia against the body       ``effects.cloth`` (resolves contact itself)
                (:mod:`segadeform.body.cloth`, state across batches)
write           streaming writer (PC2, OBJ sequence, XDMF)          always
==============  ==================================================  =====================

Frames stream in batches: memory stays flat however long the motion is.  A batch holds at most
:data:`MAX_VERTEX_FRAMES` vertex-frames (``batch`` is then lowered for big garments): the deformer's
per-call intermediates grow with B x N x K.  Measured (``bench/scaling.py --one 16000``, all effects, 30
frames): a 15,931-vertex garment peaked at 1,470 MiB with batch 8 and at 481 MiB with batch 2, at the
same speed (72.0 and 69.1 ms/frame); the frames do not depend on the batch.

The body (for collisions and ``body_output``) is posed by the package's body graph when it poses the run's body,
as in every other runtime, so that all of them push out of the same float32 body; else by numpy
(:mod:`segadeform.runtime.body`, ``Run(body_backend=...)``).
"""

from __future__ import annotations

import dataclasses
import hashlib
import logging
import os
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any, cast

import numpy as np

from segadeform.body import BodyModel, default_body_path, load_body
from segadeform.body.collision import BodyCollider
from segadeform.body.placement import check_placement
from segadeform.bounds import check_body_height
from segadeform.errors import InputError
from segadeform.geometry import GarmentAsset, precompute_garment
from segadeform.geometry.mesh_ops import surface_faces
from segadeform.geometry.precompute import PRECOMPUTE_VERSION
from segadeform.io import SceneOutput, output_unit, read_mesh
from segadeform.io.garment_asset import PORTABLE_SUFFIX
from segadeform.io.hashing import file_sha256
from segadeform.io.mesh import Mesh
from segadeform.io.obj import recorded_betas
from segadeform.io.outputs import claim_scene_outputs, garment_surface, output_format_for
from segadeform.io.toml import key_line
from segadeform.motion import (
    Motion,
    build_motion,
    floor_shift,
    frame_range,
    glitch_words,
    glitches_in_range,
    motion_windows,
    root_cuts,
)
from segadeform.settings import Effects, Scene

from .body import BODY_BACKENDS, BodyPoser, package_body
from .deformer import Deformer
from .package import ModelPackage
from .translation import at_translation

__all__ = [
    "Run",
    "RunSummary",
    "run_scene",
    "default_body_path",
    "default_model_path",
    "MAX_VERTEX_FRAMES",
    "effective_batch",
]

log = logging.getLogger(__name__)

#: a motion whose feet are further than this (m) from the floor in its median frame is warned of
#: (a user's AMASS file re-saved without its 'name' was read in SMPL's convention: 1.26 m below the floor)
FLOOR_WARN_M = 0.5  # (CMU 03_01, a walk over a raised platform, stands 0.33 m up in its median frame)

#: the most vertex-frames (batch x garment vertices) one deformer call takes
MAX_VERTEX_FRAMES = 32_768

#: the fewest vertices ``--resolution`` may leave the model (fewer left a dress unrecognisable: its placement refused
#: as another unit and axis, a review)
MIN_RESOLUTION_VERTICES = 200


def decimated_garment(vertices, faces, resolution: float, *, path=None, option: str = "--resolution"):
    """The garment ``vertices`` (N, 3), ``faces`` (F, 3) decimated to ``resolution`` of its vertices, and the
    :class:`~segadeform.body.resample.SurfaceMap` that carries the decimated garment's frames back to every vertex:
    ``(v (M, 3), f (G, 3), map)``; fewer than :data:`MIN_RESOLUTION_VERTICES` left is an error naming ``path``."""
    from segadeform.body.resample import SurfaceMap, decimate

    n = int(round(len(vertices) * resolution))
    if n < MIN_RESOLUTION_VERTICES:
        raise InputError(
            f"{option} {resolution:g} leaves the model {n} of the garment's {len(vertices)} vertices",
            path=path,
            expected=f"at least {MIN_RESOLUTION_VERTICES} vertices (a higher resolution)",
            got=n,
        )
    v, f = decimate(vertices, faces, n)
    return v, f, SurfaceMap.build(vertices, v, f)


def welded_garment(vertices, faces, surface: np.ndarray | None = None):
    """The garment ``vertices`` (N, 3), ``faces`` (F, 3) welded along its split seams for the model, and the
    :class:`~segadeform.body.resample.SurfaceMap` that carries the welded garment's frames back to every vertex as
    given: ``(v (M, 3), f (F, 3), map)``, each given vertex on its weld (a corner of a face holding it); None when
    nothing is split (:func:`~segadeform.geometry.mesh_ops.coincident_map`), or when a vertex lies in no face (which a
    carried garment cannot keep).  Game-engine exports split vertices at UV seams, and the model deformed the two sides
    apart: a technical artist's garment split at its UV seams tore 17 cm, exit 0, and the fix on offer (weld) changed
    the vertex count their engine's mesh has (a point cache must keep the file's); welded here, the outputs keep the
    file's vertices and the sides move as one."""
    from segadeform.body.resample import SurfaceMap
    from segadeform.geometry.mesh_ops import coincident_map

    v, f = np.asarray(vertices, np.float64), np.asarray(faces, np.int64)
    m = coincident_map(v, surface_faces(v, f) if surface is None else surface)
    if (m == np.arange(len(v))).all() or len(np.unique(f)) < len(v):
        return None
    keep = np.flatnonzero(m == np.arange(len(v)))
    new = np.full(len(v), -1, np.int64)
    new[keep] = np.arange(len(keep))
    idx = new[m]  # each given vertex's welded index
    wf = idx[f]
    m = _corners(len(keep), wf)  # each welded vertex on a corner of a face holding it (every one is held: above)
    return v[keep], wf, SurfaceMap(face=m.face[idx], bary=m.bary[idx], offset=np.zeros(len(v)), faces=wf)


def model_garment(
    vertices, faces, body: BodyModel, betas, surface: np.ndarray | None = None, *, out: dict | None = None
):
    """The garment the model runs on for a garment mesh as given: welded along its split seams
    (:func:`welded_garment`); its faces wound alike where some are wound against their neighbours
    (:func:`~segadeform.geometry.mesh_ops.wound_alike`: each piece as most of its faces; a dress with 150 faces so ran
    up to 6.6 cm off); and, when its faces are then all wound inward (:func:`inward_share` over :data:`INWARD`, on a
    garment that sits on the body), flipped -- the model reads the normals, and a technical artist's garment wound
    inward ran 9.5 cm off the same garment wound outward, exit 0.  Returns ``(v, f, map, welded, rewound)``: the
    :class:`~segadeform.body.resample.SurfaceMap` carries the model's frames to every vertex as given (None, with ``v``
    and ``f`` as given, when none applies); ``rewound``: ``""``, ``"aligned"``, ``"flipped"`` or
    ``"aligned+flipped"``.  ``surface``: the garment's
    :func:`~segadeform.geometry.mesh_ops.surface_faces` (None: computed here).  ``out``: a dict given to be filled
    with ``"surface"``, the model's garment's surface faces (a run computes them once: 1.5 s on a 69k-vertex
    garment)."""
    from segadeform.body.resample import SurfaceMap
    from segadeform.geometry.mesh_ops import misoriented_edges, wound_alike

    v, f = np.asarray(vertices, np.float64), np.asarray(faces, np.int64)
    surface = surface_faces(v, f) if surface is None else surface
    w = welded_garment(v, f, surface)
    mv, mf, smap = (v, f, None) if w is None else w
    held = len(np.unique(f)) == len(v)  # (a carried garment keeps no vertex outside a face)
    how = ""
    surf = surface if w is None else surface_faces(mv, mf)  # (the caller's when nothing was welded)
    bad = misoriented_edges(surf, len(mv)) if held else 0
    if bad:
        alike = wound_alike(mf, len(mv))  # some faces against their neighbours: wound as most of their piece's
        if alike is not None:
            s2 = _rewound(surf, mf, alike)  # the same faces kept, some the other way round
            if misoriented_edges(s2, len(mv)) < bad:  # (said only when it helped)
                mf, how, surf = alike, "aligned", s2
    flip = (
        held
        and misoriented_edges(surf, len(mv)) == 0
        and inward_share(mv, mf, body, betas) > INWARD
        and _on_the_body(v, f, body, betas)
    )
    if flip:
        mf = mf[:, ::-1].copy()  # corners reversed: the same places, the other way round
        surf = surf[:, ::-1].copy()
        how = "aligned+flipped" if how else "flipped"
    if out is not None:
        out["surface"] = surf
    if not how:
        return mv, mf, smap, w is not None, ""
    if smap is None:  # each vertex on itself: the given vertices are the model's
        smap = _corners(len(v), mf)
    else:  # each given vertex on its weld, a corner of the model's face (its corners reordered above)
        at = smap.faces[smap.face, np.argmax(smap.bary, axis=1)]
        smap = _corners(len(mv), mf)
        smap = SurfaceMap(face=smap.face[at], bary=smap.bary[at], offset=np.zeros(len(at)), faces=mf)
    return mv, mf, smap, w is not None, how


def _rewound(surface: np.ndarray, faces: np.ndarray, rewound: np.ndarray) -> np.ndarray:
    """``surface`` (rows of ``faces``: :func:`surface_faces` keeps faces by their corners, whatever their winding) as
    the same rows of ``rewound`` (``faces`` with some rows reversed).  Shapes: (F', 3), (F, 3), (F, 3) -> (F', 3)"""
    f = np.asarray(faces, np.int64)
    n = np.int64(max(int(f.max()) + 1, 1)) if f.size else np.int64(1)
    key = (f[:, 0] * n + f[:, 1]) * n + f[:, 2]
    order = np.argsort(key, kind="stable")
    s = np.asarray(surface, np.int64)
    at = order[np.searchsorted(key[order], (s[:, 0] * n + s[:, 1]) * n + s[:, 2])]
    return np.asarray(rewound, np.int64)[at]


def seam_rest(vertices, smap) -> np.ndarray:
    """The garment ``vertices`` (N, 3) as given with each copy of a welded seam vertex at its twin's place: vertices a
    corner-pick :class:`~segadeform.body.resample.SurfaceMap` (:func:`model_garment`'s; weights one-hot, no offset)
    carries from one model vertex all take the lowest-indexed one's position.  The model welds copies within
    :data:`~segadeform.geometry.mesh_ops.COINCIDENT` of the garment's size; the cloth stage welds only copies at one
    position (``_cloth.c``'s ``scl_weld``), so copies 5 um apart tore 51 mm there (an engine integrator's trial).  The
    cloth stage's rest, and a garment asset's ``out_vertices``.  Any other map (a decimated garment's) or None: the
    vertices as given.  Shapes: (N, 3) -> (N, 3) float64"""
    v = np.array(vertices, np.float64)
    if smap is None or not len(v):
        return v
    bary = np.asarray(smap.bary)
    if bary.shape != (len(v), 3) or np.any(smap.offset != 0) or not np.all(np.sort(bary, axis=1) == [0.0, 0.0, 1.0]):
        return v
    key = np.asarray(smap.faces)[smap.face, np.argmax(bary, axis=1)]  # each vertex's model vertex
    first = np.full(int(key.max()) + 1, len(v), np.int64)
    np.minimum.at(first, key, np.arange(len(v)))
    return v[first[key]]


def _corners(n: int, faces: np.ndarray):
    """The :class:`~segadeform.body.resample.SurfaceMap` that puts each of ``n`` vertices on a corner of a face
    holding it (every vertex is held), its weight 1 on that one corner: a face with a repeated corner (A, A, B) held a
    vertex of a garment split at its seams with weights (1, 1, 0), which wrote it at twice its place, 1.35 m off (an
    engine integrator's trial).  Faces with three distinct corners are taken first.  Shapes: faces (F, 3) -> map of
    (n,)"""
    from segadeform.body.resample import SurfaceMap

    f = np.asarray(faces, np.int64)
    proper = (f[:, 0] != f[:, 1]) & (f[:, 1] != f[:, 2]) & (f[:, 2] != f[:, 0])
    owner = np.full(n, -1, np.int64)  # the last face holding each vertex, of those with three corners if any
    for pick in (~proper, proper):
        at = np.flatnonzero(pick)
        if pick is proper:
            owner[np.unique(f[at])] = -1
        np.maximum.at(owner, f[at].ravel(), np.repeat(at, 3))
    corner = np.argmax(f[owner] == np.arange(n)[:, None], axis=1)
    bary = np.zeros((n, 3))
    bary[np.arange(n), corner] = 1.0
    return SurfaceMap(face=owner, bary=bary, offset=np.zeros(n), faces=f)


def _on_the_body(vertices, faces, body: BodyModel, betas) -> bool:
    """Whether the garment sits on a human's body (:func:`check_body_height`, :func:`check_placement`), which the
    winding test (:func:`inward_share`) takes for granted: under ``--force`` a dress between the legs of a 3.85 m body
    was called wound inward (its normals face the legs) and run flipped."""
    try:
        check_body_height(body, betas)
        check_placement(
            vertices,
            body.shaped_vertices(betas)[0],
            body.faces,
            faces=faces,
            template_vertices=body.v_template,
            betas=betas,
        )
    except InputError:
        return False
    return True


def effective_batch(batch: int, n_vertices: int) -> int:
    """Frames per deformer call for a garment of ``n_vertices``: ``batch``, lowered (to at least 1) so that
    ``batch x n_vertices <= MAX_VERTEX_FRAMES``."""
    return max(1, min(int(batch), MAX_VERTEX_FRAMES // max(int(n_vertices), 1)))


def default_model_path() -> Path:
    """The shipped default model package (package data; ``samples/models/default`` in the source tree)."""
    from segadeform.io.resources import data_path

    p = data_path("models", "default")
    if not (p / "manifest.json").is_file():
        raise InputError(
            "no model package given and the default model is missing from this installation",
            expected=f"--model PACKAGE_DIR, [model] package in the scene, or {p}",
        )
    return p


@dataclasses.dataclass
class RunSummary:
    frames: int
    seconds: float
    output: Path
    body_output: Path | None
    output_format: str
    written: list
    effects: Effects
    variant: str
    sessions: list
    pushed_vertices: int
    stage_seconds: dict
    #: how the body was posed: "graph" (the package's body graph), "numpy", or None (not posed)
    body_backend: str | None = None
    #: the cloth stage's counts (vertex-frames in ``contacts``, ``pushed`` and ``traced`` by the backstop, ``resets``),
    #: None when it was off
    cloth: dict | None = None
    #: frames per deformer call (``batch``, lowered for a big garment: :func:`effective_batch`)
    batch: int = 0
    #: the number the output gives its first frame: the run's first frame (``--frames A:``) plus a cut motion
    #: file's own start frame
    first_frame: int = 0
    #: the run's first frame counted from the motion's first, 0 (``--frames A:``)
    start: int = 0
    #: with ``resolution < 1``: (the vertices the model ran on, the garment's), else None
    resolution_vertices: tuple | None = None

    @property
    def ms_per_frame(self) -> float:
        return 1e3 * self.seconds / max(self.frames, 1)


class Run:
    """One configured run: :meth:`execute` writes it to ``output``; :meth:`stream` (a batch of frames at a time) and
    :meth:`animate` (every frame) give its frames in memory instead.  Built from a :class:`Scene` by
    :func:`run_scene`, or directly::

        run = Run(garment=Path("skirt.obj"), motion=motion, package=ModelPackage(path), body=load_body(...),
                  effects=Effects(cloth=True))
        frames = run.animate()  # (T, N, 3) float32 metres

    Args:
        garment: the path of a mesh file (OBJ, PLY, glTF, ...) or of a precomputed asset (``.npz`` or portable
            ``.sgda``).
        motion: a :class:`Motion`.
        package: a :class:`ModelPackage`.
        body: a :class:`BodyModel`.
        betas: body shape.
        effects: stages to run.
        output / output_format / up / body_output: where and how :meth:`execute` writes (``output`` None: the run
            is only streamed; ``output_format`` None: the one ``output``'s extension names, else checked against
            it, as the command line takes them).
        units: metres per written unit of the outputs (1: metres; 0.01: centimetres;
            :func:`segadeform.io.writer.output_unit`).
        frames: ``(start, stop)`` of the motion, stop exclusive (None: to the end).
        batch: frames per deformer call, at most: lowered so that a call holds at most
            :data:`MAX_VERTEX_FRAMES` vertex-frames (:func:`effective_batch`).
        cache: keep precompute/encoder results in the user cache (:mod:`segadeform.io.cache`).
        force: animate a garment that does not sit on the body (see
            :func:`segadeform.body.placement.check_placement`) instead of refusing it.
        collider: the collider class, built once per run as ``collider(v_template, faces, threads=)`` and called
            once per batch (``push_out(verts (B, N, 3), posed (B, V, 3), margin, carry=(N, 3))``, the correction
            carried between consecutive frames, zeros at the run's first frame): by default
            :class:`~segadeform.body.collision.BodyCollider` (its compiled backend on the package's threads,
            numpy if it was not built); benchmarks pass :class:`~segadeform.body.collision.ReferenceCollider`.
        guard: the command's output rule (:class:`~segadeform.io.output_guard.OutputGuard`; None: none, library
            use): the outputs are claimed here, before any work, and recorded when written.
        body_backend: how the body is posed for collisions and ``body_output`` (:mod:`segadeform.runtime.body`):
            ``"auto"`` (the package's body graph for the effects' skinning when it poses this body -- the body hash
            its manifest records -- as every other runtime does; else numpy, the reason logged once), ``"graph"``
            (that graph, or an error saying why not) or ``"numpy"`` (:meth:`BodyModel.forward`, float64).
    """

    def __init__(
        self,
        *,
        garment: Path,
        motion: Motion,
        package: ModelPackage,
        body: BodyModel,
        betas=(),
        effects: Effects = Effects(),
        output: Path | None = None,
        output_format: str | None = None,
        up: str = "y",
        units: float = 1.0,
        body_output: Path | None = None,
        frames=None,
        batch: int = 8,
        cache: bool = True,
        force: bool = False,
        collider: Callable = BodyCollider,
        body_backend: str = "auto",
        guard=None,
        resolution: float = 1.0,
        resolution_option: str = "--resolution",
    ) -> None:
        if not callable(collider):
            raise InputError(
                "collider must be a collider class", expected="BodyCollider or ReferenceCollider", got=collider
            )
        if body_backend not in BODY_BACKENDS:
            raise InputError("unknown body backend", expected=" | ".join(BODY_BACKENDS), got=body_backend)
        self.collider = collider
        if batch < 1:
            raise InputError("batch must be at least 1", got=batch)
        self.garment, self.motion, self.package, self.body = Path(garment), motion, package, body
        self.betas = np.asarray(betas, np.float64)
        self.effects, self.output, self.up = effects, output, up
        if output is not None:
            self.output = Path(output)
        # the format the output's extension names unless given (and then checked against it), as the command line
        # and Scene take it (a review: Run(output="out.obj") wrote a point cache named .obj)
        self.output_format = output_format_for(self.output, output_format) if self.output is not None else "pc2"
        self.units = output_unit(units)
        self.body_output = Path(body_output) if body_output else None
        self.batch, self.cache, self.force = int(batch), cache, bool(force)
        self._asset: GarmentAsset | None = None  # checked_asset's
        self._surface: np.ndarray | None = None  # _surface_faces's
        self._file_surface: np.ndarray | None = None  # the file's, when the model's garment is welded or rewound
        self._asset_seconds = 0.0
        r = float(resolution)
        if not (np.isfinite(r) and 0.0 < r <= 1.0):
            raise InputError(
                "resolution is the share of the garment's vertices the model runs on", expected="0 < R <= 1", got=r
            )
        self.resolution = r
        self.resolution_option = resolution_option  # where the resolution came from, for its errors
        #: with resolution < 1: the garment as given (vertices, faces), which the outputs, collisions and the
        #: cloth stage use, and the map from the model's decimated garment back to it (load_asset)
        self._full: tuple[np.ndarray, np.ndarray] | None = None
        self._smap: Any = None  # a segadeform.body.resample.SurfaceMap
        self._welded = False  # the model runs on the garment welded along its split seams (welded_garment)
        self._flipped = ""  # ... and its faces wound alike or flipped, as the file's were not (model_garment)
        self.start, self.stop = frame_range(frames, motion.n_frames, first=self._motion_start())
        self.guard = guard
        if guard is not None and self.output is not None:  # refused before any work: an output over a file
            # segadeform did not write ...
            claim_scene_outputs(guard, self.output, self.output_format, self.body_output)
        self.deformer = Deformer(package, effects)  # picks the variant; creates no session yet
        #: poses the body when collisions, the cloth stage or the body output need it (None otherwise); creates no
        #: session yet
        self.body_poser = (
            BodyPoser(package, body, skinning=effects.skinning, backend=body_backend)
            if effects.collisions or effects.cloth or self.body_output is not None
            else None
        )

    def _cache_dir(self) -> Path | None:
        if not self.cache:
            return None
        from segadeform.io.cache import cache_dir

        return cache_dir()

    def load_asset(self, joints: np.ndarray) -> GarmentAsset:
        """The garment's precomputed asset for the rest ``joints (S, 3)``: read from an asset file, else made from
        the mesh (cached in the user cache with ``cache``), welded or rewound for the model and decimated with
        ``resolution < 1`` as the run needs; unchecked (:meth:`checked_asset` checks how it sits on the body)."""
        n_star = int(self.package.config["n_star"])
        if self.garment.suffix.lower() in (".npz", PORTABLE_SUFFIX):
            if self.resolution < 1.0:
                raise InputError(
                    "a garment asset is one resolution: --resolution takes the garment's mesh",
                    path=self.garment,
                    expected="an .obj (or another mesh file) with --resolution",
                    got=self.garment.suffix,
                )
            asset = GarmentAsset.load(self.garment)
            if asset.descriptor.shape != (n_star,):  # an asset exported for another model (a new user's trial)
                raise InputError(
                    "the garment asset was exported for another model; export it for this one: segadeform garment "
                    f"export {asset.source_name or 'GARMENT'} --model {self.package.path}",
                    path=self.garment,
                    expected=f"a garment descriptor of {n_star} values",
                    got=asset.descriptor.shape[0],
                )
            if asset.carried:  # `garment export --resolution`: the model's garment is decimated, its frames carried
                from segadeform.body.resample import SurfaceMap

                out_v, out_f = cast(np.ndarray, asset.out_vertices), cast(np.ndarray, asset.out_faces)
                self._full = (out_v, out_f)
                self._smap = SurfaceMap(
                    face=cast(np.ndarray, asset.carry_face),
                    bary=cast(np.ndarray, asset.carry_bary),
                    offset=cast(np.ndarray, asset.carry_offset),
                    faces=asset.faces,
                )
            # its body weights made with another model's weight prior: refused, as the Node and C++ runtimes refuse
            # it (this runtime recomputed them and played the file they refuse: a developer's trial)
            if self.deformer.needs_body_weights and asset.log_wbody is not None and isinstance(asset.body, dict):
                want = self.deformer.weight_prior
                got = str(asset.body.get("weight_prior") or "nearest")
                if got != want:
                    raise InputError(
                        f"the garment asset's log_wbody was made with the {got} weight prior, the model wants {want}",
                        path=self.garment,
                        expected=f"an asset from segadeform garment export {asset.source_name or 'GARMENT'} --model "
                        f"{self.package.path}",
                    )
            return asset
        # read (and so checked: its extension, its contents) whether or not the cache has it: a cache entry is
        # keyed by the file's bytes, and must not make a file that fails to read (an OBJ renamed .txt) run
        mesh = read_mesh(self.garment)
        sha = file_sha256(self.garment) if self.garment.is_file() else ""
        cdir = self._cache_dir()
        key = sha[:32]
        if self.resolution < 1.0:  # the model runs on the garment decimated, its frames carried back to every vertex
            mesh, key = self._decimated(mesh, sha, cdir)
        else:  # split at seams, or wound inward: the model runs on it welded and flipped, its frames carried to all
            found: dict = {}
            mv, mf, smap, self._welded, self._flipped = model_garment(
                mesh.vertices,
                mesh.faces,
                self.body,
                self.betas,
                self._surface_faces(mesh.vertices, mesh.faces),
                out=found,
            )
            if smap is not None:  # (the surface computed above is the file's: kept for its checks)
                self._file_surface, self._surface = self._surface, found["surface"]
                self._full = (np.asarray(mesh.vertices, np.float64), np.asarray(mesh.faces, np.int64))
                self._smap = smap
                mesh = type(mesh)(vertices=mv, faces=mf)
                how = f"welded={self._welded}:flipped={self._flipped}"
                key = hashlib.sha256(f"{sha}:{how}".encode()).hexdigest()[:32]
        cpath = cdir / f"asset-{key}-n{n_star}-p{PRECOMPUTE_VERSION}.npz" if cdir is not None and sha else None
        if cpath is not None and cpath.is_file():
            try:
                a = GarmentAsset.load(cpath)
                if a.source_sha256 == sha and a.n_vertices == len(mesh.vertices):
                    if self._full is None or np.array_equal(a.vertices, np.asarray(mesh.vertices, a.vertices.dtype)):
                        return a
            except Exception:  # a stale or broken cache entry is recomputed
                log.warning("ignoring unreadable asset cache %s", cpath)
        try:
            a = precompute_garment(
                mesh.vertices,
                mesh.faces,
                joints,
                n_star=n_star,
                source_name=self.garment.name,
                source_sha256=sha,
                surface=self._surface_faces(mesh.vertices, mesh.faces),
            )
        except InputError as e:  # of the garment's mesh ("no face with an area"): named by its file (it was not)
            raise e.with_path(self.garment) from None
        if cpath is not None:
            try:
                a.save(cpath)
            except OSError as e:
                log.warning("cannot write the asset cache %s (%s)", cpath, e.strerror or e)
        return a

    def _decimated(self, full, sha: str, cdir: Path | None):
        """The garment decimated to ``resolution`` of its vertices and the :class:`SurfaceMap` that carries the
        model's frames back to every vertex (``self._full``, ``self._smap``): the mesh the model runs on and the
        key of its cache entries.  Both are cached (``R-<key>.npz``, with the asset keyed alike), so a run does not
        decimate again (14.5 s on a 39k-vertex garment: a review)."""
        from segadeform.body.resample import SurfaceMap

        n = int(round(len(full.vertices) * self.resolution))
        key = hashlib.sha256(f"{sha}:resolution={self.resolution!r}:{n}".encode()).hexdigest()[:32]
        rpath = cdir / f"R-{key}.npz" if cdir is not None and sha else None
        self._full = (np.asarray(full.vertices, np.float64), np.asarray(full.faces, np.int64))
        if rpath is not None and rpath.is_file():
            try:
                with np.load(rpath, allow_pickle=False) as z:
                    v, f = z["vertices"], z["faces"]
                    smap = SurfaceMap(face=z["face"], bary=z["bary"], offset=z["offset"], faces=f)
                if len(smap.face) == len(full.vertices) and len(f) and int(f.max()) < len(v):
                    self._smap = smap
                    return type(full)(vertices=v, faces=f), key
            except (OSError, ValueError, KeyError):
                log.warning("ignoring unreadable resolution cache %s", rpath)
        v, f, self._smap = decimated_garment(
            full.vertices, full.faces, self.resolution, path=self.garment, option=self.resolution_option
        )
        if rpath is not None:
            try:
                from segadeform.io.atomic import atomic_path

                with atomic_path(rpath) as tmp, open(tmp, "wb") as fh:
                    m = self._smap
                    np.savez(fh, vertices=v, faces=f, face=m.face, bary=m.bary, offset=m.offset)
            except OSError as e:
                log.warning("cannot write the resolution cache %s (%s)", rpath, e.strerror or e)
        return type(full)(vertices=v, faces=f), key

    def _surface_faces(self, vertices, faces) -> np.ndarray:
        """The garment's :func:`~segadeform.geometry.mesh_ops.surface_faces` (``vertices`` and ``faces``: the run's
        garment, its mesh or its asset), computed once a run: the precompute, the winding check and the familiarity
        check share them (each computed its own: 1.5 s apiece on a 69k-vertex garment)."""
        if self._surface is None:
            self._surface = surface_faces(vertices, faces)
        return self._surface

    def _motion_start(self) -> int:
        """The frame number a cut motion file gives its first frame (``motion export --frames 10:40``: 10), which
        the outputs keep; ``--frames`` counts from the motion's first frame, 0, whatever it is."""
        return int((self.motion.meta or {}).get("start_frame", 0))

    def checked_asset(self) -> GarmentAsset:
        """The garment's asset (:meth:`load_asset`), its placement on the body checked (a garment that is not on it --
        units, axes, another body -- and a body shape no human has are refused; ``force``: not checked).  Done once:
        :func:`run_scene` asks before it says anything about the motion, so a bad garment is one line."""
        if self._asset is None:
            t = time.perf_counter()
            asset = self.load_asset(self.body.rest_joints(self.betas)[0])
            # the garment as given is what is checked: with --resolution the model's asset is a decimated copy, and
            # the outputs are the file's (a review: loose vertices went unsaid, seams and windings were undercounted)
            given: GarmentAsset | Mesh = (
                asset if self._full is None else Mesh(vertices=self._full[0], faces=self._full[1])
            )
            surface = (
                self._surface_faces(asset.vertices, asset.faces)
                if self._full is None
                else self._file_surface
                if self._file_surface is not None
                else surface_faces(given.vertices, given.faces)
            )
            # with --force each refusal is played anyway and said (--force left no word of it: a user's trial)
            checks = (
                lambda: check_body_height(self.body, self.betas),
                lambda: check_placement(
                    given.vertices,
                    self.body.shaped_vertices(self.betas)[0],
                    self.body.faces,
                    faces=given.faces,
                    path=self.garment,
                    template_vertices=self.body.v_template,
                    betas=self.betas,
                    recorded_betas=recorded_betas(self.garment),
                    forceable=not self.force,
                ),
            )
            for check in checks:
                try:
                    check()
                except InputError as e:
                    if not self.force:
                        raise
                    log.warning("--force: %s (played anyway)", e)
            _warn_blender_import(self.garment, given)
            _warn_winding(self.garment, given, self.body, self.betas, surface, flipped=self._flipped)
            _warn_seams(self.garment, given, surface, welded=self._welded)
            _warn_small_pieces(self.garment, given)
            _warn_non_manifold(self.garment, given, surface)
            self._asset = asset
            self._asset_seconds = time.perf_counter() - t  # counted in the run's precompute, whoever asked first
        return self._asset

    def _body_rest(self) -> np.ndarray:
        """The body at rest as its frames are posed (the poser's zero pose: the package's float32 body graph, as Node
        and C++ write it beside their body point caches; a user's trial found Python's float64 rest 2.4e-7 m off)."""
        poser = cast(BodyPoser, self.body_poser)
        return poser.pose(np.zeros((1, 3 * self.body.n_joints)), self.betas, np.zeros((1, 3)))[0]

    def _output_mesh(self, asset: GarmentAsset) -> tuple[np.ndarray, np.ndarray]:
        """The garment the run writes, collides and steps the cloth stage on: the asset's, or with
        ``resolution < 1`` the garment as given (the model's frames are carried to it)."""
        return self._full if self._full is not None else (asset.vertices, asset.faces)

    def _cloth_stage(self, asset: GarmentAsset):
        """The cloth stage for this run: the garment's per-garment data on the body at rest (posed as the run poses
        it, zero pose: the same float32 body the other runtimes use with the body graph), cached with the garment,
        and the collider over the body."""
        from segadeform.body.cloth import ClothStage, garment_setup

        rest = self._body_rest()  # the cloth stage needs the body
        gv, gf = self._output_mesh(asset)
        if self._welded:  # a mesh welded for the model: its seam's copies at one place, which the stage welds too (an
            # asset is taken as it is stored, as Node and C++ take it: `garment export` writes the copies so)
            gv = seam_rest(gv, self._smap)
        setup = garment_setup(gv, gf, rest, self.body.faces, self.effects.cloth_settings, cache_dir=self._cache_dir())
        return ClothStage(
            setup,
            rest,
            self.body.faces,
            self.effects.cloth_settings,
            margin=self.effects.collision_margin,
            dt=1.0 / float(self.motion.fps),
            first_frame=0,  # it steps from the motion's first frame (:meth:`execute`: frames A:B warm it up)
        )

    def _prepare(self) -> dict:
        """The garment's asset, code and output mesh, the stage timings so far and the state the frames need (the
        cloth stage built once per run), for :meth:`_frames`."""
        stage = {k: 0.0 for k in ("precompute", "encode", "deform", "pose body", "collisions", "cloth", "write")}
        t = time.perf_counter()
        joints = self.body.rest_joints(self.betas)[0]
        asked = self._asset is not None
        asset = self.checked_asset()
        stage["precompute"] += (self._asset_seconds if asked else 0.0) + time.perf_counter() - t
        t = time.perf_counter()
        P = self.deformer.encode(
            asset,
            joints,
            self.betas,
            cache_dir=self._cache_dir(),
            surface=self._surface_faces(asset.vertices, asset.faces),
        )
        lw = (
            self.deformer.body_log_weights(asset, self.body, self.betas, cache_dir=self._cache_dir())
            if self.deformer.needs_body_weights
            else None
        )
        stage["encode"] += time.perf_counter() - t
        out_v, out_f = self._output_mesh(asset)
        cloth = None
        if self.effects.cloth:  # built once per run (its cost counts here); its state spans the batches
            t = time.perf_counter()
            cloth = self._cloth_stage(asset)
            stage["cloth"] += time.perf_counter() - t
        return {
            "stage": stage,
            "asked": asked,
            "asset": asset,
            "joints": joints,
            "P": P,
            "lw": lw,
            "out_v": out_v,
            "out_f": out_f,
            "batch": effective_batch(self.batch, asset.n_vertices),
            "cloth": cloth,
            "pushed": 0,
            "warm": {"contacts": 0, "pushed": 0, "traced": 0, "resets": 0},
        }

    def _frames(self, st: dict):
        """The run's frames, a batch at a time: yields ``(lo, frames (B, N, 3) float32, body (B, V, 3) float32 or
        None)`` for the frames ``lo .. lo + B - 1`` of the motion in world coordinates (the body when it was posed:
        collisions, the cloth stage or ``body_output``).  Updates ``st``'s timings and counts."""
        stage, asset, cloth, batch = st["stage"], st["asset"], st["cloth"], st["batch"]
        need_body = self.effects.collisions or self.effects.cloth or self.body_output is not None
        collider = None
        # with the cloth stage or collisions (both carry state from frame to frame: the stage's velocities, the
        # push-out's corrections), frames A:B step them over the frames before A first, writing nothing, so that
        # their state at A is a whole run's and so are its frames (a user's trial: a render in chunks popped by
        # up to 7 mm at each chunk's start); it costs those A frames.  Without either every frame stands alone.
        stateful = cloth is not None or self.effects.collisions
        warm_up = range(0, self.start, batch) if stateful else range(0)
        carry = np.zeros((len(st["out_v"]), 3)) if self.effects.collisions else None
        for lo in [*warm_up, *range(self.start, self.stop, batch)]:
            writing = lo >= self.start
            if writing and lo == self.start and cloth is not None:  # the run reports its own frames' counts
                st["warm"] = {k: getattr(cloth, k) for k in st["warm"]}
            hi = min(lo + batch, self.stop if writing else self.start)
            t = time.perf_counter()
            win = motion_windows(self.motion.poses, self.deformer.window, start=lo, stop=hi)
            # the graphs run at the root and collisions are resolved there; the translation is added after them
            # (runtime.translation: the same frames wherever the character stands, as Node and C++ compute them);
            # the cloth stage steps in world coordinates
            trans = self.motion.trans[lo:hi]
            root = np.zeros_like(trans)
            verts = self.deformer.deform(st["P"], asset, win, st["joints"], root, self.betas, log_wbody=st["lw"])
            if self._smap is not None:  # carried to every vertex of the garment as given, in float32 as the
                # deformer gives its frames and the Node and C++ runtimes carry them (the push-out of a float64
                # carry moved a vertex in a crease 0.1 mm off theirs)
                verts = self._smap.apply(verts).astype(np.float32)
            stage["deform"] += time.perf_counter() - t
            if not np.isfinite(verts).all():
                raise InputError(f"the deformer produced NaN or inf at frames {lo}..{hi - 1}")
            if need_body:
                t = time.perf_counter()
                posed = cast(BodyPoser, self.body_poser).pose(self.motion.poses[lo:hi], self.betas, root)
                stage["pose body"] += time.perf_counter() - t
            if self.effects.cloth:  # contact included: no push-out after it
                t = time.perf_counter()
                verts = cast(Any, cloth).step(at_translation(verts, trans), at_translation(posed, trans))
                stage["cloth"] += time.perf_counter() - t
            else:
                if self.effects.collisions:
                    t = time.perf_counter()
                    if collider is None:  # built once per run (its cost counts here), the session's threads
                        # from the body at rest as the run poses it, as Node and C++ build theirs (the tree's
                        # shape decides between equally near triangles: the same tree, the same frames)
                        collider = self.collider(
                            self._body_rest(),
                            self.body.faces,
                            threads=max(1, int(getattr(self.package, "threads", 1))),
                        )
                    # the correction carried from frame to frame (BodyCollider.push_out): a vertex deep in a
                    # limb keeps the side it was pushed to instead of flipping to the nearest one
                    verts, n = collider.push_out(verts, posed, self.effects.collision_margin, carry=carry)
                    st["pushed"] += n if writing else 0
                    stage["collisions"] += time.perf_counter() - t
                # rounded to float32 at the root, as the other runtimes hold their frames, then moved
                verts = at_translation(verts.astype(np.float32), trans)
            if not writing:
                continue
            # float32, as every runtime writes them (an OBJ frame printed the float64 sum's extra digits)
            body = at_translation(posed, trans).astype(np.float32) if need_body else None
            yield lo, verts.astype(np.float32), body

    def stream(self):
        """The run's frames in memory, a batch at a time, without writing a file (``output`` may be None): yields
        ``(lo, frames, body)`` -- ``frames`` (B, N, 3) float32 metres, y up, in world coordinates, the motion's frames
        ``lo .. lo + B - 1`` (``lo`` counted from the motion's first frame), exactly the frames :meth:`execute` writes
        (its effects, cloth stage and collisions included) before its writer converts them to ``units`` and ``up``;
        ``body`` (B, V, 3) float32, the posed body of those frames when the run posed it (collisions, the cloth stage
        or ``body_output``), else None.  N is the garment's vertex count in its file's order.  Each call runs the clip
        from its start (the cloth stage and the push-out start afresh).  Python's counterpart of the Node and C++
        ``Player``: a frame at a time through a game loop is ``for lo, frames, body in run.stream(): ...``."""
        yield from self._frames(self._prepare())

    def animate(self) -> np.ndarray:
        """Every frame of the run in memory: (T, N, 3) float32 metres (:meth:`stream`'s frames, stacked; T the run's
        frame count, N the garment's vertices in its file's order)."""
        chunks = [f for _, f, _ in self.stream()]
        if not chunks:
            return np.zeros((0, 0, 3), np.float32)
        return np.concatenate(chunks, axis=0)

    def execute(self, progress: Callable[[int], None] | None = None) -> RunSummary:
        """Run the clip and write its outputs (``output``, ``body_output``); returns what it did."""
        if self.output is None:
            raise InputError(
                "the run has no output to write",
                expected="Run(output=PATH), or Run.stream() for frames in memory",
                got="output=None",
            )
        t_all = time.perf_counter()
        st = self._prepare()
        stage, asset = st["stage"], st["asset"]
        t_all -= self._asset_seconds if st["asked"] else 0.0  # the run's seconds include it, as when execute loads it
        out = SceneOutput(
            path=self.output,
            fmt=self.output_format,
            up=self.up,
            unit=self.units,
            fps=self.motion.fps,
            start_frame=self.start + self._motion_start(),  # a cut motion file's numbers
            garment_faces=st["out_f"],
            garment_rest=st["out_v"],
            garment_surface=garment_surface(self.garment, len(st["out_v"]), self.output_format),
            body_path=self.body_output,
            body_faces=self.body.faces,
            body_rest=self._body_rest() if self.body_output else None,
            guard=self.guard,
        )
        cloth = st["cloth"]
        need_body = self.effects.collisions or self.effects.cloth or self.body_output is not None
        try:
            for _lo, verts, body in self._frames(st):
                t = time.perf_counter()
                out.write(verts, body if self.body_output is not None else None)
                stage["write"] += time.perf_counter() - t
                if progress is not None:
                    progress(len(verts))
            t = time.perf_counter()
            written = out.close()
            if self.cache:
                from segadeform.io.cache import prune

                prune()
            stage["write"] += time.perf_counter() - t
        except BaseException:
            out.abort()
            raise
        warm = st["warm"]
        return RunSummary(
            first_frame=self.start + self._motion_start(),
            start=self.start,
            # (a decimated model garment's counts: --resolution, or an asset exported with it; not a mesh welded or
            # flipped for the model, which keeps the file's vertex count in all but its seams)
            resolution_vertices=(asset.n_vertices, len(st["out_v"]))
            if self._full is not None and not (self._welded or self._flipped)
            else None,
            frames=self.stop - self.start,
            seconds=time.perf_counter() - t_all,
            output=self.output,
            body_output=self.body_output,
            output_format=self.output_format,
            written=written,
            effects=self.effects,
            variant=self.deformer.variant,
            sessions=sorted(self.package.created),
            pushed_vertices=st["pushed"],
            stage_seconds=stage,
            body_backend=cast(BodyPoser, self.body_poser).backend if need_body else None,
            batch=st["batch"],
            cloth=None
            if cloth is None
            else {
                "contacts": cloth.contacts - warm["contacts"],
                "pushed": cloth.pushed - warm["pushed"],
                "traced": cloth.traced - warm["traced"],
                "resets": cloth.resets - warm["resets"],
            },
        )


def _padded(betas, n: int) -> np.ndarray:
    b = np.zeros(n)
    v = np.asarray(betas if betas is not None else (), np.float64).ravel()[:n]
    b[: len(v)] = v
    return b


def _label(betas) -> str:
    b = np.trim_zeros(np.asarray(betas, np.float64), "b")
    return "[" + ", ".join(f"{x:g}" for x in b) + "]" if b.size else "0 (the default shape)"


def _warn_blender_import(garment, asset: GarmentAsset | Mesh, say: Callable[..., None] | None = None) -> None:
    """Say when the garment's OBJ is not what a DCC's import of it gives: vertices in no face (Blender's OBJ import
    drops them) or several objects (imported apart).  The output has one point per vertex of the file, so a point
    cache then fits no import of it (a user's trial: `Vertex count mismatch`, with no word from the run).  ``say``: what
    says it, with ``log.warning``'s arguments (default: it)."""
    if not isinstance(garment, (str, os.PathLike)) or Path(garment).suffix.lower() != ".obj":
        return
    from segadeform.io.obj import obj_line_vertices, obj_objects

    name = Path(garment).name
    used = np.zeros(len(asset.vertices), bool)
    used[np.asarray(asset.faces).ravel()] = True
    try:  # a vertex of a line element is kept by the import (as an edge): not loose (a review)
        lines = [k for k in obj_line_vertices(garment) if 0 <= k < len(used)]
    except OSError:
        lines = []
    used[lines] = True
    loose = int((~used).sum())
    if loose:
        (say or log.warning)(
            "garment %s: %d vertices are in no face; Blender's OBJ import drops them, so the output's %d points fit "
            "no import of the file (delete them and run again: Mesh > Clean Up > Delete Loose)",
            name,
            loose,
            len(used),
        )
    try:
        objects = obj_objects(garment)
    except OSError:
        return
    if len(objects) > 1:
        shown = ", ".join(repr(o) if o else "(unnamed)" for o in objects[:4]) + (" ..." if len(objects) > 4 else "")
        (say or log.warning)(
            "garment %s: holds %d objects (%s), deformed here as one garment; an import that splits them (Blender's "
            "default) has objects the output's points fit none of: join them (import as one object) or export "
            "the garment alone",
            name,
            len(objects),
            shown,
        )


#: metres: garment vertices this close to the body at rest tell which way its faces are wound (their normals
#: against the body's there)
WINDING_NEAR = 0.03
#: the share of those whose normals point into the body past which the garment is said to be wound inward: a garment
#: wound inward gives 100 %, a two-sided one (an inner shell facing the body) about half (a review: 50-53 %)
INWARD = 0.8


def inward_share(vertices, faces, body: BodyModel, betas) -> float:
    """The share of a garment's vertices near the body at rest (within :data:`WINDING_NEAR`) whose normals point into
    it; 0 when fewer than 10 are near."""
    from segadeform.body.collision import BodyCollider
    from segadeform.geometry.mesh_ops import vertex_normals

    v, f = np.asarray(vertices, np.float64), np.asarray(faces)
    q = BodyCollider(body.v_template, body.faces).query(v, body.shaped_vertices(betas)[0])
    near = np.abs(q.signed_distance) < WINDING_NEAR
    if near.sum() < 10:
        return 0.0
    return float(((vertex_normals(v, f)[near] * q.normal[near]).sum(axis=1) < 0).mean())


def _warn_winding(
    garment,
    asset: GarmentAsset | Mesh,
    body: BodyModel,
    betas,
    surface: np.ndarray | None = None,
    say: Callable[..., None] | None = None,
    *,
    flipped: str = "",
) -> None:
    """Say when the garment's faces are not all wound outward: some against their neighbours
    (:func:`~segadeform.geometry.mesh_ops.mesh_defects`' ``misoriented`` edges) or all of them inward (the normals of
    most vertices near the body point into it).  The model reads the normals: a Blender artist's trial moved a
    dress's frames 1.2 cm on average, 6.6 cm at most, with every face flipped, and nothing said so.  ``flipped``: how
    the model's garment was wound for it (:func:`model_garment`'s ``rewound``: ``"aligned"``, ``"flipped"``, both,
    or ``""``).  ``surface``: the garment's :func:`~segadeform.geometry.mesh_ops.surface_faces` (None: computed here).
    ``say``: what says it, with ``log.warning``'s arguments (default: it)."""
    from segadeform.geometry.mesh_ops import misoriented_edges

    name = Path(str(garment)).name if isinstance(garment, (str, os.PathLike)) else "garment"
    v, f = np.asarray(asset.vertices, np.float64), np.asarray(asset.faces)
    fix = "(Blender: Mesh > Normals > Recalculate Outside)"
    bad = misoriented_edges(surface_faces(v, f) if surface is None else surface, len(v))
    if "aligned" in flipped:  # the model ran on it wound alike (model_garment)
        where = f"{bad} edges lie" if bad else "its split seams lie"  # (across a seam: only once welded)
        (say or log.warning)(
            "garment %s: %s between faces wound against each other (their normals point opposite ways): the model "
            "runs on it with each piece wound as most of its faces%s, and the outputs keep the file's faces; wind "
            "them alike in the file %s for renders that read them",
            name,
            where,
            ", then flipped (most of its normals pointed into the body)" if "flipped" in flipped else "",
            fix,
        )
        return
    if bad:
        (say or log.warning)(
            "garment %s: %d edges lie between faces wound against each other (their normals point opposite ways, "
            "and the model reads them): wind them alike %s",
            name,
            bad,
            fix,
        )
        return
    inward = inward_share(v, f, body, betas)
    if flipped == "flipped":  # the model ran on it flipped (model_garment): said, with what the file's faces still are
        (say or log.warning)(
            "garment %s: its faces are wound inward (the normals of %.0f %% of its vertices near the body point into "
            "it): the model runs on it flipped, and the outputs keep the file's faces; flip them in the file "
            "%s for renders that read them",
            name,
            100 * inward,
            fix,
        )
        return
    if inward > INWARD and _on_the_body(v, f, body, betas):  # (off it, the test says nothing: --force played it)
        (say or log.warning)(
            "garment %s: its faces are wound inward (the normals of %.0f %% of its vertices near the body point into "
            "it), and the model reads them: flip them %s",
            name,
            100 * inward,
            fix,
        )


def _warn_seams(
    garment,
    asset: GarmentAsset | Mesh,
    surface: np.ndarray | None = None,
    say: Callable[..., None] | None = None,
    *,
    welded: bool = False,
) -> None:
    """Say when the garment is split along a seam: vertices of an open boundary at the place of another, with no
    edge between them (:func:`~segadeform.geometry.mesh_ops.coincident_map`; game-engine exports split vertices at
    UV seams).  The model deforms the two sides apart: a user's shirt with 83 centre-line vertices duplicated tore
    (3.8 mm apart on average, 16 mm at most) with no word but that it lay outside the training garments.
    ``surface``: the garment's :func:`~segadeform.geometry.mesh_ops.surface_faces` (None: computed here).  ``say``:
    what says it, with ``log.warning``'s arguments (default: it)."""
    from segadeform.geometry.mesh_ops import coincident_map

    v, f = np.asarray(asset.vertices, np.float64), np.asarray(asset.faces)
    welded_n = int((coincident_map(v, surface_faces(v, f) if surface is None else surface) != np.arange(len(v))).sum())
    if not welded_n:
        return
    path = Path(str(garment)) if isinstance(garment, (str, os.PathLike)) else None
    name = path.name if path is not None else "garment"
    if welded:  # the model ran on it welded (welded_garment): the sides move as one, the file's vertices written
        # (the push-out moves each copy as its twin; the cloth stage welds them, _cloth.c's scl_weld)
        (say or log.warning)(
            "garment %s: %d vertices lie on an open boundary at the place of another vertex (the mesh is split along a "
            "seam, as exports split it at UV seams): the model runs on it welded there and writes every vertex of "
            "the file, the two sides of the seam together",
            name,
            welded_n,
        )
        return
    # an OBJ is welded by `garment fit --weld`; an asset's mesh is welded before it is exported again
    how = f"`segadeform garment fit {path} -o WELDED.obj --weld`, or " if name.lower().endswith(".obj") else ""
    (say or log.warning)(
        "garment %s: %d vertices lie on an open boundary at the place of another vertex, with no edge between them: "
        "the mesh is split along a seam (as exports split it at UV seams), and the model deforms the two sides apart, "
        "so the output tears there; weld them (%sBlender: Mesh > Clean Up > Merge by Distance) and run the welded "
        "garment",
        name,
        welded_n,
        how,
    )


def garment_warnings(
    garment, mesh: GarmentAsset | Mesh, body: BodyModel, betas, *, welded: bool = False, flipped: str = ""
) -> list[str]:
    """What ``segadeform run`` says of a garment (``mesh``: its mesh as given; ``garment`` its file, for the words):
    vertices in no face or several objects, faces wound against each other or inward, a mesh split along seams.
    ``garment export`` says them too and keeps them in the asset, for the runtimes that play it to say (a
    developer's trial: a garment split at its UV seams tore in Node with no word).  ``welded``: the model's garment is
    ``mesh`` welded along its seams (:func:`welded_garment`)."""
    said: list[str] = []

    def say(fmt, *args):
        said.append(fmt % args)

    _warn_blender_import(garment, mesh, say)
    _warn_winding(garment, mesh, body, betas, None, say, flipped=flipped)
    _warn_seams(garment, mesh, None, say, welded=welded)
    _warn_small_pieces(garment, mesh, say)
    _warn_non_manifold(garment, mesh, None, say)
    return said


def _warn_non_manifold(
    garment, mesh: GarmentAsset | Mesh, surface: np.ndarray | None = None, say: Callable[..., None] | None = None
) -> None:
    """Say a garment's edges in more than two faces (``non_manifold`` of
    :func:`~segadeform.geometry.mesh_ops.mesh_defects`: a fin, a pocket or a second layer joined along an edge).
    The model's graph and its spectrum are built from the edges: a QA trial's skirt with two stray faces on one edge
    moved by up to 10 mm everywhere, and `run` said nothing (only `inspect` counted it)."""
    from segadeform.geometry.mesh_ops import non_manifold_edges

    v, f = np.asarray(mesh.vertices, np.float64), np.asarray(mesh.faces)
    n = non_manifold_edges(surface_faces(v, f) if surface is None else surface, len(v))
    if n:
        name = Path(str(garment)).name if isinstance(garment, (str, os.PathLike)) else "garment"
        (say or log.warning)(
            "garment %s: %d edge%s in more than two faces (non-manifold: a fin, a pocket or a layer joined along an "
            "edge); the model's graph reads the garment as one surface joined there, which moves all of it (Blender: "
            "Select > Select All by Trait > Non Manifold)",
            name,
            n,
            "s are" if n > 1 else " is",
        )


#: metres: a small piece whose open boundary lies this close to the rest of the garment is split off along a seam
SEAM_GAP = 0.001


def _warn_small_pieces(garment, mesh: GarmentAsset | Mesh, say: Callable[..., None] | None = None) -> None:
    """Say a garment's small loose pieces (:func:`~segadeform.geometry.mesh_ops.small_pieces`): stray triangles an
    edit left are openings the model's descriptor counts, and change the whole garment's frames (a technical artist's
    four stray triangles moved a dress up to 10.8 cm, with no word)."""
    from segadeform.geometry.mesh_ops import SMALL_PIECE, seam_gaps, small_pieces

    pieces = small_pieces(mesh.vertices, mesh.faces)
    gaps = seam_gaps(mesh.vertices, mesh.faces) if len(pieces) else np.zeros(0)
    if len(pieces) and (gaps <= SEAM_GAP).mean() > 0.5:  # panels split along seams, their copies apart: not strays
        (say or log.warning)(
            "garment %s: %d small pieces whose open boundaries lie within %.2g mm of the rest of the garment (at "
            "most): the mesh is split along seams with the two copies of each seam vertex apart, and the model deforms "
            "the pieces apart; weld them (Blender: Mesh > Clean Up > Merge by Distance, %.2g mm) and run the welded "
            "garment",
            Path(garment).name if isinstance(garment, (str, os.PathLike)) else "garment",
            int((gaps <= SEAM_GAP).sum()),
            1e3 * float(gaps[gaps <= SEAM_GAP].max()),
            1e3 * float(gaps[gaps <= SEAM_GAP].max()) * 1.1,
        )
        return
    if len(pieces):
        (say or log.warning)(
            "garment %s: %d small loose piece%s (%d faces in all, each under %g %% of the garment's), e.g. stray "
            "triangles left by an edit: each is an opening the model reads, and changes how the whole garment moves; "
            "delete them if they are not part of the garment (Blender: select one, Select Linked, Delete)",
            Path(garment).name if isinstance(garment, (str, os.PathLike)) else "garment",
            len(pieces),
            "s" if len(pieces) > 1 else "",
            int(pieces.sum()),
            100 * SMALL_PIECE,
        )


def shape_for_inputs(scene: Scene, body: BodyModel, *, force: bool = False) -> tuple:
    """The body shape a run uses: the scene's ``betas``, or -- for a garment asset prepared for a body shape
    (``segadeform garment export``) -- the asset's, which it was made for.  An asset prepared for another body,
    or for other betas than the scene gives, is refused (``force``: the scene's betas are used anyway)."""
    g = Path(scene.garment)
    if g.suffix.lower() not in (".npz", PORTABLE_SUFFIX) or not g.is_file():
        return tuple(scene.betas)
    asset = GarmentAsset.load(g)
    if not asset.for_a_body:
        return tuple(scene.betas)
    from segadeform.body.identity import body_sha256

    want = (asset.body or {}).get("sha256")
    if want and want != body_sha256(body) and not force:
        raise InputError(
            f"the garment asset was prepared for another body ({(asset.body or {}).get('name')})",
            path=g,
            expected=f"the body it was exported for, or `segadeform garment export` "
            f"for {Path(body.path).name if body.path else 'this body'}",
            got=f"body {Path(body.path).name if body.path else ''} (another hash)",
        )
    ab = _padded(asset.betas, body.n_betas)
    if not scene.betas:
        return tuple(float(x) for x in np.trim_zeros(ab, "b"))
    if not np.allclose(_padded(scene.betas, body.n_betas), ab, atol=1e-6) and not force:
        raise InputError(
            "the garment asset was prepared for another body shape than the run's betas",
            path=g,
            expected=f"betas {_label(ab)}, the asset's: leave --betas out, or export the garment again for these betas",
            got=f"betas {_label(_padded(scene.betas, body.n_betas))}",
        )
    return tuple(scene.betas)


def check_motion_shape(motion: Motion, scene: Scene, body: BodyModel, *, force: bool = False) -> None:
    """A motion file (``.sgdm``) is retargeted onto one body and shape (``segadeform motion export``): refuse it
    for another body or shape, unless ``force`` (then it plays as it is)."""
    meta = motion.meta or {}
    if meta.get("format") != "sgdm" or force:
        return
    from segadeform.body.identity import body_sha256

    f = scene.motion.file
    mb = meta.get("body") or {}
    if isinstance(mb, dict) and mb.get("sha256") and mb["sha256"] != body_sha256(body):
        raise InputError(
            f"the motion file was retargeted onto another body ({mb.get('name')})",
            path=f,
            expected="the body it was exported for, or the motion exported again for this one; --force plays it anyway",
            got="another body",
        )
    mbetas = meta.get("betas")
    if mbetas is not None:
        try:
            mb_full = _padded([float(x) for x in mbetas], body.n_betas)
        except (TypeError, ValueError):
            raise InputError("the motion file's betas are not numbers", path=f, got=repr(mbetas)[:60]) from None
        run_b = _padded(scene.betas, body.n_betas)
        if not np.allclose(mb_full, run_b, atol=1e-6):
            raise InputError(
                f"the motion file was retargeted onto body shape betas {_label(mb_full)}, and this run's body has "
                f"betas {_label(run_b)}",
                path=f,
                expected=f"a run with the motion's betas {_label(mb_full)}, or the motion exported again for the "
                "run's; --force plays it anyway",
                got=f"the run's betas {_label(run_b)}",
            )


def check_package_body(package: ModelPackage, body: BodyModel, *, force: bool = False) -> None:
    """A model package poses the body its model was trained on (its body graphs record it: :func:`package_body`):
    refuse a run on another body, unless ``force`` (then the model runs on a body it never saw, posed with numpy).
    A package whose body graphs record no body (or that has none) is not checked."""
    from segadeform.body.identity import body_text, other_body

    recorded = package_body(package)
    mine = other_body(recorded, body)
    if mine is None or force:
        return
    raise InputError(
        "the model package was made for another body than the run's (--body, or the scene's body)",
        path=package.path,
        expected=f"{body_text(cast(dict, recorded))}, the body it was trained on and poses (a package exported for "
        "this body; --force runs it anyway)",
        got=body_text(mine),
    )


def run_scene(
    scene: Scene,
    *,
    model: Path | None = None,
    output: Path | None = None,
    batch: int = 8,
    threads: int = 1,
    providers=None,
    progress=None,
    cache: bool = True,
    force: bool = False,
    body_backend: str = "auto",
    guard=None,
    frames_from_scene: bool = True,
    resolution: float | None = None,
    resolution_option: str | None = None,
) -> RunSummary:
    """Run a scene (optionally overriding its model package and output path); ``body_backend`` and ``guard``:
    :class:`Run`'s.  ``frames_from_scene``: the frame range is the scene file's (a range past the motion's end
    names the file); False when a command-line flag gave it.  ``resolution``: :class:`Run`'s (None: the scene's
    ``[model] resolution``); ``resolution_option``: what its errors call it (default ``--resolution``, or the scene
    file's key)."""
    package = ModelPackage(model or scene.model or default_model_path(), threads=threads, providers=providers)
    body = load_body(scene.body or default_body_path())
    betas = shape_for_inputs(scene, body, force=force)
    if betas != tuple(scene.betas):
        scene = dataclasses.replace(scene, betas=betas)
    try:
        motion = build_motion(scene.motion, body.rest_joints(scene.betas)[0])
    except InputError as e:  # a value of the scene's [motion] (kind, units): name the file and the key's line
        if scene.path is None or e.path is not None:
            raise
        k = "kind" if "kind" in e.problem else "units" if ("unit" in e.problem or "scale" in e.problem) else None
        line = key_line(scene.path, "motion", k) if k else None
        raise type(e)(
            f"[motion]: {e.problem}",
            path=scene.path,
            line=line or key_line(scene.path, "motion"),
            expected=e.expected,
            got=e.got,
        ) from None
    check_motion_shape(motion, scene, body, force=force)
    check_package_body(package, body, force=force)
    try:  # a range past the motion's end is the scene's to fix: name it
        frame_range(scene.motion.frames, motion.n_frames, first=int((motion.meta or {}).get("start_frame", 0)))
    except InputError as e:
        raise e.with_path(scene.path) if scene.path is not None and frames_from_scene else e from None
    said: list = []  # what the run says of the motion: after the garment is checked (a bad one is then one line)
    if not scene.motion.floor:  # feet far from the floor all clip long: another origin, convention or units
        shift = floor_shift(motion, body.rest_joints(scene.betas)[0], typical=True)
        if abs(shift) > FLOOR_WARN_M:
            said.append(
                (
                    "motion %s: its feet are %.2f m %s the floor in most frames (another origin, translation "
                    "convention or units?); --floor (floor = true in a scene's [motion]) stands it on the floor",
                    Path(scene.motion.file or scene.motion.kind or "motion").name,
                    abs(shift),
                    "below" if shift > 0 else "above",
                )
            )
    settle, jumps = glitches_in_range(motion, scene.motion.frames)  # inside the range the run plays
    if settle or jumps:
        said.append(
            (
                "motion %s: %s (joints faster than 20 m/s) throw the garment about; --repair-glitches "
                "(repair_glitches = true in a scene's [motion]) rebuilds them",
                Path(scene.motion.file or "motion").name,
                glitch_words(settle, jumps),
            )
        )
    cuts = root_cuts(motion, scene.motion.frames)
    if cuts:
        first, metres = cuts[0]
        said.append(
            (
                "motion %s: its root moves %.3g m in one frame, into frame %d: a cut or a teleport, and the garment "
                "jumps with it (%d step%s faster than 20 m/s)",
                Path(scene.motion.file or "motion").name,
                metres,
                first + int((motion.meta or {}).get("start_frame", 0)),  # numbered as the outputs number it
                len(cuts),
                "" if len(cuts) == 1 else "s",
            )
        )
    out = Path(output) if output is not None else scene.output
    run = Run(
        garment=scene.garment,
        motion=motion,
        package=package,
        body=body,
        betas=scene.betas,
        effects=scene.effects,
        output=out,
        # another output than the scene's: the format its extension names (the command line's -o sets both)
        output_format=scene.output_format if output is None or Path(output) == scene.output else None,
        up=scene.up,
        units=scene.units,
        body_output=scene.body_output,
        frames=scene.motion.frames,
        batch=batch,
        cache=cache,
        force=force,
        body_backend=body_backend,
        guard=guard,
        resolution=scene.resolution if resolution is None else resolution,
        resolution_option=resolution_option
        or (
            "--resolution"
            if resolution is not None
            else f"{scene.path.name}: model.resolution"
            if scene.path is not None
            else "model.resolution"
        ),
    )
    run.checked_asset()
    for words in said:
        log.warning(*words)
    return run.execute(progress)
