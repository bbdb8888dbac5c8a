"""The shared test vectors of the runtimes without Python: one scene as the portable files those runtimes
read -- the garment asset prepared for the scene's body shape (``.sgda``) and the motion file (``.sgdm``) --
and what ``segadeform run`` makes of them here (the garment's frames and the posed body's), in one
``check.sgdb`` (arrays ``expected (T, N, 3)``, ``body (T, V, 3)``; :mod:`segadeform.io.sgdb`).

``tests/runtimes`` and ``bench/runtimes.py`` hold the Node, browser and C++ runtimes to these."""

from __future__ import annotations

import dataclasses
from pathlib import Path

from segadeform.body import default_body_path, load_body
from segadeform.body.identity import body_label
from segadeform.body.prepare import prepare_for_body
from segadeform.geometry import GarmentAsset, precompute_garment
from segadeform.io import read_mesh, read_pc2
from segadeform.io.garment_asset import PORTABLE_SUFFIX
from segadeform.io.hashing import file_sha256
from segadeform.io.sgdb import write_bundle
from segadeform.motion import build_motion, select_frames, write_motion_file
from segadeform.settings import Scene

from .package import ModelPackage
from .pipeline import Run, default_model_path

__all__ = ["scene_vectors"]


def scene_vectors(
    scene: Scene, out_dir: str | Path, *, model: Path | None = None, batch: int = 8, force: bool = False
) -> dict[str, Path]:
    """Write ``garment.sgda``, ``motion.sgdm`` and ``check.sgdb`` for ``scene`` into ``out_dir``; returns their
    paths by name (``garment``, ``motion``, ``check``).  The frames are ``segadeform run``'s on the asset and the
    motion (the scene's effects without collisions, so these vectors test the network and skinning alone; the
    collision stage has its own cross-runtime parity test, tests/runtimes/test_collisions.py; the frame range is
    cut into the motion file)."""
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    package = ModelPackage(model or scene.model or default_model_path())
    body = load_body(scene.body or default_body_path())
    joints = body.rest_joints(scene.betas)[0]
    motion, _ = select_frames(build_motion(scene.motion, joints), scene.motion.frames)
    g = Path(scene.garment)
    if g.suffix.lower() in (".npz", PORTABLE_SUFFIX):
        asset = GarmentAsset.load(g)
    else:
        mesh = read_mesh(g)
        asset = precompute_garment(
            mesh.vertices,
            mesh.faces,
            body.rest_joints()[0],
            n_star=int(package.config["n_star"]),
            source_name=g.name,
            source_sha256=file_sha256(g),
        )
    paths = {"garment": out / "garment.sgda", "motion": out / "motion.sgdm", "check": out / "check.sgdb"}
    prepare_for_body(asset, body, scene.betas, weight_prior=str(package.config.get("weight_prior", "nearest"))).save(
        paths["garment"]
    )
    full = [0.0] * body.n_betas
    full[: len(scene.betas)] = scene.betas
    write_motion_file(paths["motion"], motion, body=body_label(body), betas=full, source=motion.name)
    effects = dataclasses.replace(scene.effects, collisions=False)
    run = Run(
        garment=paths["garment"],
        motion=motion,
        package=package,
        body=body,
        betas=scene.betas,
        effects=effects,
        output=out / "python.pc2",
        body_output=out / "python_body.pc2",
        batch=batch,
        cache=False,
        force=force,
    )
    run.execute()
    write_bundle(
        paths["check"],
        {"expected": read_pc2(out / "python.pc2").frames, "body": read_pc2(out / "python_body.pc2").frames},
        {
            "effects": {"skinning": effects.skinning, "dynamics": effects.dynamics, "wrinkles": effects.wrinkles},
            "graph": run.deformer.variant,
            "fps": float(motion.fps),
        },
    )
    return paths
