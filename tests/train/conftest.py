"""A synthetic dataset (no Blender): skinned garments plus a known wave, stored like the real one."""

from __future__ import annotations

import numpy as np
import pytest

from ..conftest import SAMPLES

torch = pytest.importorskip("torch", reason="training needs the 'torch' extra")


@pytest.fixture(scope="session")
def body():
    from segadeform.body import load_body

    return load_body(SAMPLES / "bodies" / "default_body.npz")


def _write(root, sid, split, body, garment, motion, wave, type_, lead=0):
    from segadeform.body.transfer import skin_garment, transfer_weights
    from segadeform.dataset.store import Sample, save_sample

    w = transfer_weights(garment.vertices, body.shaped_vertices()[0], body.faces, body.weights)
    frames = skin_garment(garment.vertices, w, body, motion.poses, None, motion.trans)
    t = np.arange(motion.n_frames)[:, None]
    frames[..., 2] += wave * np.sin(0.3 * t + 8 * garment.vertices[None, :, 1])
    meta = {"id": sid, "split": split, "garment": sid.split("__")[0], "type": type_, "body": 0, "status": "kept"}
    save_sample(
        root,
        Sample(
            id=sid,
            rest=garment.vertices,
            faces=garment.faces,
            betas=np.zeros(0),
            poses=motion.poses,
            trans=motion.trans,
            frames=frames.astype(np.float32),
            meta=meta,
            # the motion simulated before the clip: here its first pose held, stepping back in x
            lead_poses=np.repeat(motion.poses[:1], lead, axis=0) if lead else None,
            lead_trans=motion.trans[:1] - 0.01 * np.arange(lead, 0, -1)[:, None] * [1.0, 0.0, 0.0] if lead else None,
        ),
    )


@pytest.fixture(scope="session")
def synthetic_dataset(tmp_path_factory, body):
    from segadeform.garments import make_garment
    from segadeform.motion import make_motion

    root = tmp_path_factory.mktemp("synth")
    skirt = make_garment("skirt", body)
    shorts = make_garment("shorts", body)
    walk = make_motion("walk", seconds=0.4, fps=30, ease_in=0)
    swing = make_motion("arm_swing", seconds=0.4, fps=30, ease_in=0, seed=1)
    _write(root, "skirt__b0__walk", "train", body, skirt, walk, 0.01, "skirt", lead=4)
    _write(root, "shorts__b0__walk", "train", body, shorts, walk, 0.01, "trousers")
    _write(root, "skirt__b0__swing", "test", body, skirt, swing, 0.0, "skirt")  # exactly LBS
    return root


@pytest.fixture
def tiny_config(tmp_path):
    p = tmp_path / "train.toml"
    p.write_text(
        "[model]\nhidden = 16\nlstm_hidden = 16\n[optim]\nsteps = 6\nframes = 3\ncheckpoint_every = 3\nlr = 0.003\n"
    )
    return p
