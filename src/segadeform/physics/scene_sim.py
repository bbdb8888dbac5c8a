"""``segadeform simulate``: a scene's garment, body and motion through the cloth solver, written like a run."""

from __future__ import annotations

import dataclasses
from pathlib import Path
from typing import Callable, Optional

import numpy as np

from ..body.model import default_body_path, load_body
from ..errors import InputError
from ..io import Mesh, open_sequence_writer, read_mesh, write_obj
from ..scene import Y_TO_Z, Scene, build_motion
from .blender import SimResult, simulate
from .settings import SimSettings

__all__ = ["SimSummary", "simulate_scene"]

_Y_TO_Z = np.array(Y_TO_Z)


@dataclasses.dataclass
class SimSummary:
    frames: int
    output: Path
    body_output: Optional[Path]
    settings: SimSettings
    result: SimResult


def simulate_scene(scene: Scene, *, output: Optional[Path] = None, settings: Optional[SimSettings] = None,
                   sim_python=None, progress: Optional[Callable[[int, int], None]] = None) -> SimSummary:
    """Simulate ``scene`` (its ``[simulate]`` table, or ``settings``) and write its output like ``segadeform run``.

    The frames written are the motion's frames (the scene's frame range, if
    any); the drape and blend pre-roll are simulated but not written.
    """
    st = settings or scene.simulate or SimSettings()
    body = load_body(scene.body or default_body_path())
    motion = build_motion(scene.motion, body.rest_joints(scene.betas)[0])
    if scene.motion.frames:
        a, b = scene.motion.frames
        b = motion.n_frames if b is None else b
        if not 0 <= a < b <= motion.n_frames:
            raise InputError(f"frame range {a}:{b} is outside the motion's {motion.n_frames} frames",
                             expected=f"0 <= A < B <= {motion.n_frames}", got=f"{a}:{b}")
        motion = dataclasses.replace(motion, poses=motion.poses[a:b], trans=motion.trans[a:b])
        start = a
    else:
        start = 0
    mesh = read_mesh(scene.garment)
    res = simulate(mesh.vertices, mesh.faces, body, motion, betas=scene.betas or None, settings=st,
                   sim_python=sim_python, progress=progress)
    if not np.isfinite(res.frames).all():
        raise InputError("the simulation produced NaN or inf; try a higher quality")
    out = Path(output) if output is not None else scene.output
    rot = _Y_TO_Z if scene.up == "z" else None
    w = open_sequence_writer(out, scene.output_format, faces=mesh.faces, num_points=len(mesh.vertices),
                             fps=motion.fps, start_frame=start,
                             rest=mesh.vertices if rot is None else mesh.vertices @ rot.T)
    try:
        w.write(res.frames if rot is None else res.frames @ rot.T)
        w.close()
    except BaseException:
        w.abort()
        raise
    if scene.body_output is not None:
        posed = body.forward(motion.poses, scene.betas or None, motion.trans).vertices
        bw = open_sequence_writer(scene.body_output, scene.output_format, faces=body.faces,
                                  num_points=body.n_vertices, fps=motion.fps, start_frame=start)
        try:
            bw.write(posed if rot is None else posed @ rot.T)
            bw.close()
        except BaseException:
            bw.abort()
            raise
        if scene.output_format == "pc2":
            rest = body.shaped_vertices(scene.betas or None)[0]
            write_obj(scene.body_output.with_suffix(".obj"),
                      Mesh(vertices=rest if rot is None else rest @ rot.T, faces=body.faces))
    return SimSummary(frames=motion.n_frames, output=out, body_output=scene.body_output, settings=st, result=res)
