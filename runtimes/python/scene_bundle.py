"""Scene bundles for other runtimes (:mod:`segadeform.io.sgdb`): a scene's model inputs, and the Python
runtime's output as the shared test vector."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np

from segadeform.body import default_body_path, load_body
from segadeform.errors import InputError
from segadeform.geometry.features import vertex_features
from segadeform.io.sgdb import write_bundle
from segadeform.motion import build_motion, motion_windows, select_frames
from segadeform.settings import Scene

from .package import ModelPackage
from .pipeline import Run, default_model_path

__all__ = ["scene_bundle"]


def scene_bundle(
    scene: Scene,
    out: str | Path,
    *,
    model: Path | None = None,
    expected: bool = True,
    batch: int = 8,
    force: bool = False,
) -> Path:
    """Write the bundle of ``scene`` (its effects without collisions and the cloth stage: those are the host's
    post-processes, named on the host runtime's command line).

    ``expected``: also run the deformer here and store its output (the parity vector)."""
    # a bundle holds the model's garment and its frames: a garment decimated for the model (a scene's [model]
    # resolution, an asset from `garment export --resolution`) would be played at the model's resolution, its point
    # cache fitting no import of the garment (a review): refused, with what to do
    if scene.resolution < 1.0:
        raise InputError(
            "a bundle holds the garment the model runs on: a scene's [model] resolution below 1 is not bundled",
            path=scene.path,
            expected="resolution = 1, or `segadeform garment export GARMENT --resolution R` and the runtimes' "
            "--package/--garment/--motion",
            got=scene.resolution,
        )
    package = ModelPackage(model or scene.model or default_model_path())
    body = load_body(scene.body or default_body_path())
    joints = body.rest_joints(scene.betas)[0]
    # frames A:B: the bundle's motion starts at A (its first window does too: no look-back before A, as a motion
    # file cut with `motion export --frames A:B`), and its point cache is numbered from A (meta start_frame)
    motion, first = select_frames(build_motion(scene.motion, joints), scene.motion.frames)
    effects = dataclasses.replace(scene.effects, collisions=False, cloth=False)
    run = Run(
        garment=scene.garment,
        motion=motion,
        package=package,
        body=body,
        betas=scene.betas,
        effects=effects,
        output=None,  # only its checks and its deformer: nothing is written through it
        cache=False,
        force=force,
    )
    # the run's own checks: the body's height and the garment's placement (with force: played, and said as
    # warnings; the bundle skipped them without a word: a review), and what a DCC's import of the garment would not fit
    asset = run.checked_asset()
    if asset.carried:
        raise InputError(
            "the garment asset's model garment is decimated (garment export --resolution), and a bundle holds the "
            "garment the model runs on",
            path=scene.garment,
            expected="the asset played with the runtimes' --package/--garment/--motion, or a full-resolution garment",
        )
    d = run.deformer
    feats = vertex_features(asset.vertices, asset.faces, joints, normals=asset.normals.astype(np.float64))
    betas = d._betas(scene.betas)
    arrays = {
        "features": feats.astype(np.float32),
        "nbr": asset.nbr.astype(np.int32),
        "mask": asset.mask.astype(np.uint8),
        "descriptor": asset.descriptor.astype(np.float32),
        "betas": betas,
        "rest": asset.vertices.astype(np.float32),
        "faces": asset.faces.astype(np.int32),
        "joints": joints.astype(np.float32),
        "poses": motion.poses.astype(np.float32),
        "trans": motion.trans.astype(np.float32),
    }
    lw = d.body_log_weights(asset, body, scene.betas) if d.needs_body_weights else None
    if lw is not None:
        arrays["log_wbody"] = lw.astype(np.float32)
    if expected:
        P = d.encode(asset, joints, scene.betas)
        frames = []
        for lo in range(0, motion.n_frames, batch):
            hi = min(lo + batch, motion.n_frames)
            win = motion_windows(motion.poses, d.window, start=lo, stop=hi)
            frames.append(d.deform(P, asset, win, joints, motion.trans[lo:hi], scene.betas, log_wbody=lw))
        arrays["expected"] = np.concatenate(frames).astype(np.float32)
    meta = {
        "fps": float(motion.fps),
        "window": int(d.window),
        "graph": d.variant,
        "effects": {"skinning": effects.skinning, "dynamics": effects.dynamics, "wrinkles": effects.wrinkles},
        "garment": Path(scene.garment).name,
        "motion": motion.name,
        "betas": [float(x) for x in betas],
        "package_config": package.config,
        "start_frame": int(first) + int((motion.meta or {}).get("start_frame", 0)),
    }
    # the scene's post-processes a bundle does not play: named, so that a runtime playing it says its frames are the
    # network's alone (a developer's trial: --check said max_abs 0 while the frames were 7.8 cm off the scene's)
    left_out = [n for n, on in (("collisions", scene.effects.collisions), ("cloth", scene.effects.cloth)) if on]
    if left_out:
        meta["left_out"] = left_out
    return write_bundle(out, arrays, meta)
