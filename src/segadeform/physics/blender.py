"""The bridge to Blender's cloth solver: build, bake and read back one simulation per call.

Blender (``bpy``) is GPL-3.0, exists only for Python 3.11 and pins numpy<2,
so it never enters segadeform's process: :func:`simulate` writes a job folder
(the garment and body as ``.npy``, the posed body as a PC2 point cache that
Blender plays back through a Mesh Cache modifier, and every solver setting as
JSON) and runs ``blender_worker.py`` with the simulator environment's Python.

The simulator environment is found, in order: the ``sim_python`` argument,
the ``SEGADEFORM_SIM_PYTHON`` environment variable (read at call time), a
``.venv-sim`` folder at the repository root.  ``python -m
segadeform.physics.setup`` creates that folder (``bpy`` pinned in
``requirements-blender.txt``).

Coordinates: segadeform is y-up; Blender is z-up with gravity along -z.  The
bridge converts both ways, so callers see y-up metres only.  The frames come
back in the garment's vertex order.
"""

from __future__ import annotations

import dataclasses
import json
import os
import shutil
import subprocess
import tempfile
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np

from ..body.model import BodyModel
from ..body.rotations import axis_angle_to_quaternion, quaternion_slerp, quaternion_to_axis_angle
from ..body.transfer import skin_garment, transfer_weights
from ..body.untangle import untangle, vertex_parts
from ..errors import InputError, SimulationError
from ..geometry.mesh_ops import adjacency, boundary_loops, connected_components
from ..io.pc2 import PC2Writer
from ..motion.motion import Motion
from ..settings.scene import Y_TO_Z
from ..settings.simulation import EFFECTS, MATERIALS, MAX_QUALITY, PIN_GROUPS, SimSettings

__all__ = [
    "SimResult",
    "simulate",
    "find_sim_python",
    "preroll_poses",
    "pin_weights",
    "waist_height",
    "clip_quality",
    "unpose_lbs",
    "A_POSE",
    "WORKER",
    "SIM_BRIDGE_VERSION",
]

WORKER = Path(__file__).with_name("blender_worker.py")
#: the version of this bridge (how a scene becomes a Blender simulation): recorded by every dataset sample
#: and pack; samples of different versions are not mixed.  1: up to issue #13; 2: collider settings
#: (``collision_inner``, ``collision_normals``) and the per-piece detachment gate (issue #27); 3: leads without
#: a T-pose in front and ramped up from rest where the capture before a clip is short (issue #27)
SIM_BRIDGE_VERSION = 3
_Y_TO_Z = np.array(Y_TO_Z)


def _repo_root() -> Path:
    return Path(__file__).resolve().parents[3]


def find_sim_python(explicit: str | os.PathLike | None = None) -> Path:
    """The simulator environment's Python (see the module docstring); :class:`SimulationError` if none."""
    cands = []
    if explicit:
        cands.append(("argument", Path(explicit)))
    env = os.environ.get("SEGADEFORM_SIM_PYTHON")
    if env:
        cands.append(("SEGADEFORM_SIM_PYTHON", Path(env)))
    if not cands:
        for name in ("bin/python", "Scripts/python.exe"):
            cands.append((".venv-sim", _repo_root() / ".venv-sim" / name))
    for src, p in cands:
        if p.is_file() and os.access(p, os.X_OK):
            return p
        if src != ".venv-sim":
            raise SimulationError(f"the simulator Python given by {src} does not exist: {p}")
    raise SimulationError(
        "no simulator environment: run `python -m segadeform.physics.setup` (creates "
        f"{_repo_root() / '.venv-sim'} with Blender's bpy), or set SEGADEFORM_SIM_PYTHON"
    )


@dataclasses.dataclass
class SimResult:
    """frames (F, N, 3) y-up metres in the garment's vertex order; the rest is provenance."""

    frames: np.ndarray
    fps: float
    settings: dict
    blender: dict
    preroll_frames: int
    wall_seconds: float
    cloth_rest: np.ndarray | None = None  # (N, 3) the shape Blender took the cloth's rest lengths from

    @property
    def seconds_per_frame(self) -> float:
        return float(self.blender["seconds_per_frame"])


#: the A-pose of ``rest_pose = "a"``: both upper arms 45 degrees down from the T-pose (SMPL axes)
A_POSE = np.zeros(72)
A_POSE[3 * 16 + 2] = -np.pi / 4
A_POSE[3 * 17 + 2] = np.pi / 4


def preroll_poses(
    motion: Motion, drape_frames: int, blend_frames: int, start_pose: np.ndarray | None = None
) -> tuple[np.ndarray, np.ndarray]:
    """Drape in ``start_pose`` (default: the rest pose), then a slerp into the first frame, then the motion.

    Shapes: start_pose (72,) -> poses (drape + blend + T, 72), trans (drape + blend + T, 3)
    """
    d, b = max(int(drape_frames), 1), max(int(blend_frames), 0)
    p0 = np.zeros(72) if start_pose is None else np.asarray(start_pose, np.float64).reshape(72)
    q1 = axis_angle_to_quaternion(motion.poses[0].reshape(24, 3))
    q0 = axis_angle_to_quaternion(p0.reshape(24, 3))
    t = np.arange(1, b + 1) / (b + 1)
    s = 0.5 - 0.5 * np.cos(np.pi * t)  # ease in and out: no velocity jump at either end
    blend = (
        np.stack([quaternion_to_axis_angle(quaternion_slerp(q0, q1, si)).reshape(72) for si in s])
        if b
        else np.zeros((0, 72))
    )
    poses = np.concatenate([np.repeat(p0[None], d, axis=0), blend, motion.poses])
    trans = np.concatenate([np.zeros((d, 3)), s[:, None] * motion.trans[:1], motion.trans])
    return poses, trans


def unpose_lbs(points, weights, transforms) -> np.ndarray:
    """Inverse linear blend skinning: the rest positions that ``transforms`` skin onto ``points``.

    Shapes: points (N, 3), weights (N, S), transforms (S, 4, 4) -> (N, 3)
    """
    m = np.einsum("ns,sij->nij", np.asarray(weights, np.float64), np.asarray(transforms, np.float64)[:, :3, :])
    return np.linalg.solve(m[:, :, :3], (np.asarray(points, np.float64) - m[:, :, 3])[..., None])[..., 0]


def clip_quality(body_frames, quality: int, max_step_motion: float, cap: int = MAX_QUALITY) -> int:
    """Solver steps per frame for a whole clip: ``quality``, raised to ``ceil(motion / max_step_motion)`` (at
    most ``cap``) where ``motion`` is the farthest any body vertex moves from one frame to the next, so that no
    step moves the body more than ``max_step_motion`` metres where the cap allows.

    One number for the clip, not one per frame: Blender reads its steps per frame once -- keyed per frame
    (``keyframe_insert("quality")``), the evaluated setting changes but the solver's frames stay bit-identical
    to the unkeyed ones (measured on Blender 5.0.1).

    Shapes:
        body_frames (T, V, 3) -> int
    """
    b = np.asarray(body_frames, np.float64)
    if b.ndim != 3 or b.shape[2] != 3 or len(b) == 0:
        raise InputError("body frames must be (T, V, 3) with T >= 1", got=b.shape)
    if not (isinstance(quality, (int, np.integer)) and 1 <= quality <= cap):
        raise InputError(f"quality must be an integer in 1..{cap}", got=quality)
    step = float(max_step_motion)
    if not (np.isfinite(step) and step > 0):
        raise InputError("max_step_motion must be a positive number of metres", got=max_step_motion)
    moved = float(np.linalg.norm(np.diff(b, axis=0), axis=2).max()) if len(b) > 1 else 0.0
    if not np.isfinite(moved):
        raise InputError("body frames must be finite", got="non-finite motion")
    return int(min(cap, max(quality, int(np.ceil(moved / step - 1e-9)))))


def _pin_group(v: np.ndarray, faces: np.ndarray, group: str, width: float) -> np.ndarray:
    """``pin_weights`` of one connected mesh (local indices), ``top`` or ``waistband``."""
    if group == "top":
        return (v[:, 1] >= v[:, 1].max() - width).astype(np.float64)
    loops = boundary_loops(faces, len(v))
    if not loops:
        raise InputError("pin = 'waistband' needs a garment with an open boundary (this mesh is closed)")
    top = max(loops, key=lambda lp: v[lp, 1].mean())
    from scipy.sparse.csgraph import dijkstra

    d = dijkstra(adjacency(faces, len(v), vertices=v), directed=False, indices=top, limit=width, min_only=True)
    return (d <= width).astype(np.float64)


def pin_weights(
    vertices, faces, group: str, width: float = 0.025, *, piece_size: float = 0.1, waist_height: float | None = None
) -> np.ndarray:
    """Pin weights (N,) in {0, 1}: ``waistband`` = within ``width`` (along edges) of the highest
    boundary loop; ``top`` = within ``width`` of the highest vertex height; ``top+waist`` = ``top`` and
    the ring of vertices within ``width`` of ``waist_height`` (a belt: a jumpsuit's legs then hang from
    the waist, not from the shoulders, and do not drag the seat down onto the hips; ``waist_height``,
    metres, is required for it: :func:`waist_height` of the body).

    A garment of several pieces (connected components: a button, a pocket, a label beside the cloth) has each
    piece held: a piece the rule leaves without a pin is pinned whole when it is smaller than ``piece_size``
    (the diagonal of its bounding box, metres: it is sewn on and follows the garment), else by the same rule
    applied to the piece alone.  Unheld, it falls off the body (a MakeHuman denim shorts' button fell 28 m in
    2 s and the gate rejected every clip as detached)."""
    v = np.asarray(vertices, np.float64)
    f = np.asarray(faces, np.int64)
    if group not in PIN_GROUPS:
        raise InputError("unknown pin group", expected=" | ".join(PIN_GROUPS), got=group)
    belt = None
    if group == "top+waist":
        if waist_height is None or not np.isfinite(waist_height):
            raise InputError("pin = 'top+waist' needs the body's waist height (metres)", got=waist_height)
        belt = np.abs(v[:, 1] - float(waist_height)) <= width
        if not belt.any():
            raise InputError(
                "pin = 'top+waist': no garment vertex lies at the body's waist height",
                expected=f"vertices within {width} m of y = {float(waist_height):.3f}",
                got=f"heights {v[:, 1].min():.3f}..{v[:, 1].max():.3f}",
            )
        group = "top"
    w = _pin_group(v, f, group, width)  # the rule on the whole garment
    n_comp, comp = connected_components(f, len(v))
    for c in range(n_comp) if n_comp > 1 else ():
        idx = np.flatnonzero(comp == c)
        if w[idx].any():
            continue
        if np.linalg.norm(np.ptp(v[idx], axis=0)) < piece_size:
            w[idx] = 1.0
            continue
        local = np.full(len(v), -1)
        local[idx] = np.arange(len(idx))
        fc = f[comp[f[:, 0]] == c]
        try:
            w[idx] = _pin_group(v[idx], local[fc], group, width)
        except InputError:  # a closed piece has no waistband: its top holds it
            w[idx] = _pin_group(v[idx], local[fc], "top", width)
    if belt is not None:
        w[belt] = 1.0
    return w


def waist_height(body: BodyModel, betas=None) -> float:
    """The height (metres, y-up) of the body's waist at rest: 2 cm below the ``spine1`` joint, where
    :mod:`segadeform.garments.make` puts a waistband."""
    if "spine1" not in body.joint_names:
        raise InputError("pin = 'top+waist' needs a body with a 'spine1' joint", got=list(body.joint_names)[:4])
    j = body.rest_joints(None if betas is None else np.asarray(betas, np.float64).reshape(1, -1))[0]
    return float(j[body.joint_names.index("spine1"), 1] - 0.02)


def simulate(
    vertices,
    faces,
    body: BodyModel,
    motion: Motion,
    *,
    betas=None,
    settings: SimSettings = SimSettings(),
    sim_python=None,
    progress: Callable[[int, int], None] | None = None,
    keep_job: Path | None = None,
    timeout: float | None = None,
    cloth_rest=None,
    start_pose=None,
    rest_lengths_from=None,
) -> SimResult:
    """Simulate a rest-pose garment on ``body`` (shape ``betas``) playing ``motion``.

    Args:
        vertices, faces: the garment, (N, 3) y-up metres dressed on the body's rest pose, (F, 3) triangles.
        body, betas: the collider.
        motion: what the body does; every frame of it is recorded.
        settings: effects, material and solver settings (:class:`SimSettings`).
        sim_python: the simulator environment's Python (see :func:`find_sim_python`).
        progress: called as ``progress(done, total)`` with simulated frames (pre-roll included).
        keep_job: copy the job folder there (for debugging in Blender).
        timeout: seconds before the solver is killed.
        cloth_rest, start_pose: with ``rest_pose = "a"``: the garment as designed in an A-pose
            (N, 3), e.g. a MakeHuman garment's fit before it is carried to the T-pose, and that A-pose
            (72,); default: the garment skinned to :data:`A_POSE`.
        rest_lengths_from: (N, 3) another shape of the garment whose edge lengths are the cloth's rest
            lengths (Blender's rest shape key), e.g. a MakeHuman garment as designed; default: the
            shape the cloth starts from.

    Shapes:
        -> SimResult.frames (T, N, 3), T = motion.n_frames
    """
    v = np.asarray(vertices, np.float64)
    f = np.asarray(faces)
    if v.ndim != 2 or v.shape[1] != 3 or len(v) < 3 or not np.isfinite(v).all():
        raise InputError("garment vertices must be finite (N, 3), N >= 3", got=v.shape)
    if f.ndim != 2 or f.shape[1] != 3 or len(f) < 1 or f.min() < 0 or f.max() >= len(v):
        raise InputError("garment faces must be (F, 3) triangle indices into the vertices", got=f.shape)
    exe = find_sim_python(sim_python)
    bs = blender_settings(settings)
    fps = float(motion.fps)
    drape = max(1, int(round(settings.drape_seconds * fps)))
    blend = int(round(settings.blend_seconds * fps))
    a_pose = settings.rest_pose == "a"
    if cloth_rest is not None and (not a_pose or start_pose is None or np.shape(cloth_rest) != v.shape):
        raise InputError(
            "cloth_rest needs rest_pose = 'a', a start_pose and the garment's vertex count",
            got=(settings.rest_pose, start_pose is None, np.shape(cloth_rest)),
        )
    p0 = (A_POSE if start_pose is None else np.asarray(start_pose, np.float64).reshape(72)) if a_pose else None
    poses, trans = preroll_poses(motion, drape, blend, p0)
    z = lambda a: (np.asarray(a) @ _Y_TO_Z.T).astype(np.float32)  # noqa: E731
    rest_body = body.shaped_vertices(betas)[0]
    # the posed body is the collider alone: without body_collision it is neither posed nor given to Blender, and
    # its motion does not raise the solver's steps (it cannot reach the cloth)
    collide = settings.has("body_collision")
    collider = None
    if collide:
        posed = body.forward(poses, betas, trans)
        if settings.max_step_motion > 0:  # a fast clip gets more solver steps per frame
            bs["cloth"]["quality"] = clip_quality(posed.vertices, settings.quality, settings.max_step_motion)
        collider = posed.vertices
        if settings.untangle_body:  # the collider without the body's self-intersection (arm in torso, thigh in thigh)
            # room between two parts for cloth kept the collision distance from both, and a millimetre
            room = 2 * settings.collision_distance + 0.001
            collider = untangle(collider, body.faces, vertex_parts(body.weights), rest_body, gap=room)
    wts = transfer_weights(v, rest_body, body.faces, body.weights) if (a_pose or settings.has("pinning")) else None
    # the cloth's rest: the garment as given (T-pose), as designed in an A-pose, or skinned into one
    if cloth_rest is not None:
        cloth_rest = np.asarray(cloth_rest, np.float64)
    elif a_pose:
        cloth_rest = skin_garment(v, wts, body, p0[None], betas, np.zeros((1, 3)))[0]
    else:
        cloth_rest = v
    t0 = time.perf_counter()
    with tempfile.TemporaryDirectory(prefix="segadeform-sim-") as tmp:
        job_dir = Path(tmp)
        np.save(job_dir / "garment_rest.npy", z(cloth_rest))
        if rest_lengths_from is not None:
            rl = np.asarray(rest_lengths_from, np.float64)
            if rl.shape != v.shape or not np.isfinite(rl).all():
                raise InputError(
                    "rest_lengths_from must be finite and shaped like the garment", expected=v.shape, got=rl.shape
                )
            np.save(job_dir / "garment_rest_shape.npy", z(rl))
        np.save(job_dir / "garment_faces.npy", f.astype(np.int64))
        check = []
        if collider is not None:
            np.save(job_dir / "body_rest.npy", z(rest_body))
            np.save(job_dir / "body_faces.npy", body.faces.astype(np.int64))
            with PC2Writer(job_dir / "body.pc2", body.n_vertices, start_frame=1, sample_rate=1) as w:
                w.write(z(collider))
            check = sorted({1, drape + blend + 1, len(poses)})
            np.save(job_dir / "body_check.npy", z(collider[[c - 1 for c in check]]))
        job = {
            "fps": fps,
            "total_frames": len(poses),
            "record_start": drape + blend + 1,
            "garment_rest": "garment_rest.npy",
            "garment_faces": "garment_faces.npy",
            "body_rest": "body_rest.npy" if collide else None,
            "body_faces": "body_faces.npy" if collide else None,
            "body_cache": "body.pc2" if collide else None,
            "garment_rest_shape": "garment_rest_shape.npy" if rest_lengths_from is not None else None,
            "check_body_frames": check,
            "body_check": "body_check.npy" if collide else None,
            **bs,
        }
        if bs["wind"]:
            job["wind"]["direction"] = list(map(float, np.asarray(settings.wind) @ _Y_TO_Z.T))
        if settings.has("pinning"):
            wh = waist_height(body, betas) if settings.pin == "top+waist" else None
            pins = pin_weights(v, f, settings.pin, waist_height=wh)
            if not pins.any():
                raise InputError(f"pin group {settings.pin!r} selects no vertex of this garment")
            np.save(job_dir / "pins.npy", pins.astype(np.float32))
            job["pins"] = "pins.npy"
            # pinned vertices follow the body: the garment's own input is the skinned garment, from
            # the cloth's own start on (unposed from there, so pins and cloth agree on frame 1)
            skin_rest = v if not a_pose else unpose_lbs(cloth_rest, wts, body.forward(p0[None], betas).transforms[0])
            skinned = skin_garment(skin_rest, wts, body, poses, betas, trans)
            with PC2Writer(job_dir / "garment.pc2", len(v), start_frame=1, sample_rate=1) as w:
                w.write(z(skinned))
            job["garment_cache"] = "garment.pc2"
        (job_dir / "job.json").write_text(json.dumps(job, indent=1))
        _run_worker(exe, job_dir, len(poses), progress, timeout)
        frames = np.load(job_dir / "frames.npy").astype(np.float64) @ _Y_TO_Z
        info = json.loads((job_dir / "result.json").read_text())
        if keep_job is not None:
            shutil.copytree(job_dir, keep_job, dirs_exist_ok=True)
    if frames.shape != (motion.n_frames, len(v), 3):
        raise SimulationError(
            f"the simulator returned frames of shape {frames.shape}, expected {(motion.n_frames, len(v), 3)}"
        )
    if info.get("body_playback_max_error", 0.0) > 1e-4:
        raise SimulationError(
            "Blender played the body back wrongly (max error "
            f"{info['body_playback_max_error']:.3g} m): check the Mesh Cache settings"
        )
    return SimResult(
        frames=frames,
        fps=fps,
        settings={"segadeform": settings.to_dict(), "blender": bs},
        blender=info,
        preroll_frames=drape + blend,
        wall_seconds=time.perf_counter() - t0,
        cloth_rest=cloth_rest if rest_lengths_from is None else np.asarray(rest_lengths_from, np.float64),
    )


def _run_worker(exe: Path, job_dir: Path, total: int, progress, timeout) -> None:
    cmd = [str(exe), str(WORKER), str(job_dir)]
    env = {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH", "PYTHONHOME")}
    # Blender's own temporary folder inside the job's: removed with it even when Blender is killed (a stopped
    # `dataset make` left Blender's own blender_* folders in the system's temporary folder)
    (job_dir / "tmp").mkdir(exist_ok=True)
    env.update(TMPDIR=str(job_dir / "tmp"), TEMP=str(job_dir / "tmp"), TMP=str(job_dir / "tmp"))
    log_path = job_dir / "worker.log"
    with open(log_path, "wb") as err:
        proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=err, env=env, cwd=job_dir, text=True)
        t0 = time.monotonic()
        done = 0
        try:
            for line in proc.stdout:
                if line.startswith("FRAME "):
                    n = int(line.split()[1])
                    if progress is not None and n > done:
                        progress(n, total)
                    done = n
                if timeout is not None and time.monotonic() - t0 > timeout:
                    proc.kill()
                    raise SimulationError(f"the simulator ran past its {timeout:.0f} s limit at frame {done}/{total}")
            rc = proc.wait()
        except BaseException:
            proc.kill()
            proc.wait()
            raise
    if rc != 0 or not (job_dir / "frames.npy").is_file():
        tail = log_path.read_text(errors="replace").strip().splitlines()[-8:]
        raise SimulationError(
            f"Blender's cloth solver failed (exit {rc}) at frame {done}/{total}:\n  " + "\n  ".join(tail)
        )


def blender_settings(s: SimSettings) -> dict:
    """The Blender cloth, collision and body-collider settings that ``s`` turns into.

    Only the named effects are on: gravity and wind through the effector
    weights, body and self collision through their switches, bending and air
    damping through their stiffness/drag (0 when off), pinning through a
    vertex group.  Returns ``{"effects", "cloth", "collision", "body_collision",
    "wind"}``, the keys being Blender's own attribute names.
    """
    m = MATERIALS[s.material]
    cloth = {
        "quality": s.quality,
        "mass": m.mass,
        "air_damping": m.air_damping if s.has("air_damping") else 0.0,
        "tension_stiffness": m.tension,
        "compression_stiffness": m.compression,
        "shear_stiffness": m.shear,
        "bending_stiffness": m.bending if s.has("bending") else 0.0,
        "tension_damping": m.tension_damping,
        "compression_damping": m.compression_damping,
        "shear_damping": m.shear_damping,
        "bending_damping": m.bending_damping if s.has("bending") else 0.0,
    }
    if s.has("pinning"):
        cloth["pin_stiffness"] = s.pin_stiffness
    collision = {
        "collision_quality": s.collision_quality,
        "distance_min": s.collision_distance,
        "friction": m.friction,
        "impulse_clamp": s.impulse_clamp,
    }
    if s.has("self_collision"):
        collision.update(self_distance_min=s.self_collision_distance, self_friction=m.self_friction)
    # "use_culling" (Blender's "single sided") is on either way: Blender's default, with which every dataset sample
    # was made, named here so that another Blender's default cannot change it.  ``collision_inner`` is passed on as
    # ``thickness_inner``, which Blender reads for soft bodies only: the cloth frames are bit-identical at 0.01 and
    # 0.05 (docs/simulator-gate.md, tenth study); the setting stays because sample specs and digests record it.
    body = {
        "thickness_outer": s.collision_distance,
        "thickness_inner": s.collision_inner,
        "cloth_friction": m.friction,
        "damping": 0.0,
        "use_culling": True,
    }
    if s.collision_normals:  # push cloth out along the body's normals (recovers cloth that got inside)
        body.update(use_normal=True)
    effects = {e: s.has(e) for e in EFFECTS}
    return {
        "effects": effects,
        "cloth": cloth,
        "collision": collision,
        "body_collision": body,
        "wind": {"strength": s.wind_strength, "direction": list(s.wind)} if s.has("wind") else None,
    }
