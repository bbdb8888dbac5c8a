"""``segadeform simulate``: a scene's garment, body and motion through the cloth solver, written like a run."""

from __future__ import annotations

import dataclasses
from collections.abc import Callable
from pathlib import Path

import numpy as np

from ..body.model import default_body_path, load_body
from ..errors import InputError
from ..io import SceneOutput, read_mesh
from ..io.outputs import claim_scene_outputs, garment_surface
from ..motion import build_motion, select_frames
from ..settings import Scene
from ..settings.simulation import SimSettings
from .blender import SimResult, simulate

__all__ = ["SimSummary", "simulate_scene"]


@dataclasses.dataclass
class SimSummary:
    frames: int
    output: Path
    body_output: Path | None
    settings: SimSettings
    result: SimResult
    written: list = dataclasses.field(default_factory=list)


def simulate_scene(
    scene: Scene,
    *,
    output: Path | None = None,
    settings: SimSettings | None = None,
    sim_python=None,
    progress: Callable[[int, int], None] | None = None,
    guard=None,
    frames_from_scene: bool = True,
) -> SimSummary:
    """Simulate ``scene`` (its ``[simulate]`` table, or ``settings``) and write its output like ``segadeform run``.

    The frames written are the motion's frames (the scene's frame range, if
    any); the drape and blend pre-roll are simulated but not written.  ``guard``: the command's output rule
    (:class:`~segadeform.io.output_guard.OutputGuard`), which claims the outputs before the simulator starts;
    ``frames_from_scene``: the frame range is the scene file's (named when past the motion's end), not a flag's.
    """
    st = settings or scene.simulate or SimSettings()
    body = load_body(scene.body or default_body_path())
    motion = build_motion(scene.motion, body.rest_joints(scene.betas)[0])
    try:  # checked before the simulator starts; a range past the motion's end is the scene's to fix
        motion, start = select_frames(motion, scene.motion.frames)
    except InputError as e:
        raise e.with_path(scene.path) if scene.path is not None and frames_from_scene else e from None
    mesh = read_mesh(scene.garment)
    out = Path(output) if output is not None else scene.output
    if guard is not None:  # refused before minutes of simulation, not after
        claim_scene_outputs(guard, out, scene.output_format, scene.body_output)
    res = simulate(
        mesh.vertices,
        mesh.faces,
        body,
        motion,
        betas=scene.betas or None,
        settings=st,
        sim_python=sim_python,
        progress=progress,
    )
    if not np.isfinite(res.frames).all():
        raise InputError("the simulation produced NaN or inf; try a higher quality")
    posed = (
        body.forward(motion.poses, scene.betas or None, motion.trans).vertices
        if scene.body_output is not None
        else None
    )
    with SceneOutput(
        path=out,
        fmt=scene.output_format,
        up=scene.up,
        unit=scene.units,
        fps=motion.fps,
        start_frame=start + int((motion.meta or {}).get("start_frame", 0)),  # a cut motion file's numbers
        garment_faces=mesh.faces,
        garment_rest=mesh.vertices,
        garment_surface=garment_surface(scene.garment, len(mesh.vertices), scene.output_format),
        body_path=scene.body_output,
        body_faces=body.faces,
        body_rest=body.shaped_vertices(scene.betas or None)[0] if posed is not None else None,
        guard=guard,
    ) as w:
        w.write(res.frames, posed)
        written = w.close()
    return SimSummary(
        frames=motion.n_frames, output=out, body_output=scene.body_output, settings=st, result=res, written=written
    )
