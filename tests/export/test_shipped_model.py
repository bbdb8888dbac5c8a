"""The shipped default model: its ONNX graphs match its torch checkpoint on a real garment and motion; the
package holds only what a runtime reads (the checkpoint and the evaluation report live beside it)."""

from __future__ import annotations

import json

import numpy as np
import onnxruntime as ort
import pytest
import torch

from segadeform.body import load_body
from segadeform.contracts.model_package import read_manifest_text
from segadeform.export.package import _variant_model, deformer_variants
from segadeform.geometry import precompute_garment
from segadeform.geometry.features import vertex_features
from segadeform.io import read_mesh
from segadeform.model.config import ModelConfig
from segadeform.model.network import load_checkpoint
from segadeform.motion import make_motion, motion_windows

from ..conftest import SAMPLES

PKG = SAMPLES / "models" / "default"
TRAIN = SAMPLES / "models" / "default.train"  # model.pt and eval/: beside the package, not in it
RTOL = 1e-5


@pytest.fixture(scope="module")
def shipped():
    net = load_checkpoint(TRAIN / "model.pt").eval().freeze()
    manifest = read_manifest_text((PKG / "manifest.json").read_text())
    return net, manifest


def test_package_is_the_checkpoints_and_small(shipped):
    net, manifest = shipped
    # a field the manifest predates reads as its default (weights "free", static_blend false ...): ModelConfig.from_dict
    assert ModelConfig.from_dict(dict(manifest["config"])) == net.cfg
    assert set(manifest["config"]) <= set(json.loads(net.cfg.to_json()))
    size = sum(p.stat().st_size for p in PKG.iterdir())
    # 6 MB before the graphs shared their weights and lost their debug metadata; 0.9 MB since, plus the body
    # graphs' 13,718-vertex body (3.5 MB of shape blend shapes, skinning weights and triangles)
    assert size < 5.5e6
    body_graphs = [g for g in manifest["graphs"].values() if g["role"] == "body"]
    assert sorted(g["skinning"] for g in body_graphs) == ["dqs", "lbs"]
    assert all((PKG / g["file"]).stat().st_size < 1.5e5 for g in manifest["graphs"].values())  # weights in weights.bin
    assert (PKG / "MODEL_CARD.md").read_text().count("| ") > 10
    # one file per graph, every file a graph, the weights or the card: no checkpoint, no reports
    listed = {g["file"] for g in manifest["graphs"].values()} | {manifest["weights"]["file"]}
    assert len(listed) == len(manifest["graphs"]) + 1
    assert {p.name for p in PKG.iterdir()} == listed | {"manifest.json", "MODEL_CARD.md"}
    assert (TRAIN / "eval" / "eval.md").is_file()


def test_the_shipped_checkpoint_records_the_packages_training_motions(shipped):
    """A model fine-tuned from the shipped checkpoint (`train --init`) records its starting model's training motions
    with its own, so eval warns of a test clip either was trained on; the checkpoint recorded none (the package
    alone did) and a fine-tuned package listed 1 motion against 246 (an ML user's trial)."""
    from segadeform.model.network import checkpoint_training_motions

    _, manifest = shipped
    record = checkpoint_training_motions(TRAIN / "model.pt")
    assert record is not None and record == manifest["training_motions"]
    assert len(record["motions"]) == 246


def test_shipped_parity_on_the_sample_dress(shipped):
    net, manifest = shipped
    body = load_body(SAMPLES / "bodies" / "default_body.npz")
    mesh = read_mesh(SAMPLES / "garments" / "dress.obj")
    betas = np.zeros(net.cfg.n_betas, np.float32)
    joints = body.rest_joints()[0]
    a = precompute_garment(mesh.vertices, mesh.faces, joints, n_star=net.cfg.n_star)
    feats = vertex_features(a.vertices, a.faces, joints, normals=a.normals.astype(np.float64)).astype(np.float32)
    nbr, mask = a.nbr.astype(np.int32), a.mask.astype(np.float32)  # schema 3: int32 indices, float32 mask
    enc = {"features": feats[None], "nbr": nbr, "mask": mask, "descriptor": a.descriptor[None].astype(np.float32)}
    sess = ort.InferenceSession(
        str(PKG / manifest["graphs"]["garment_encoder"]["file"]), providers=["CPUExecutionProvider"]
    )
    P = sess.run(None, enc)[0]
    with torch.no_grad():
        Pt = net.garment_encoder(*(torch.as_tensor(enc[k]) for k in ("features", "nbr", "mask", "descriptor"))).numpy()
    assert np.abs(P - Pt).max() <= RTOL * np.abs(Pt).max()
    mo = make_motion("dance", seconds=0.3, fps=30, seed=1)
    log_wbody = None
    if net.residual:
        from segadeform.body.transfer import garment_weights, residual_log_weights

        log_wbody = residual_log_weights(garment_weights(a.vertices, a.faces, body, None, net.cfg.weight_prior))
        log_wbody = np.asarray(log_wbody, np.float32)
    for name, var in deformer_variants(net.cfg).items():
        w = motion_windows(mo.poses, var["config"].window).astype(np.float32)
        b = len(w)
        feeds = {
            "g": Pt[0],
            "window": w,
            "betas": np.repeat(betas[None], b, 0),
            "rest": a.vertices.astype(np.float32),
            "nbr": nbr,
            "mask": mask,
            "joints": np.repeat(joints[None].astype(np.float32), b, 0),
            "trans": mo.trans.astype(np.float32),
        }
        if net.residual:  # residual skinning weights: the body's weights at the garment, as log weights (last input)
            feeds["log_wbody"] = log_wbody
        s = ort.InferenceSession(str(PKG / manifest["graphs"][name]["file"]), providers=["CPUExecutionProvider"])
        got = s.run(None, feeds)
        vnet = net if var["default"] else _variant_model(net, var["config"])
        with torch.no_grad():
            ref = vnet.deformer(*(torch.as_tensor(feeds[k]) for k in feeds))
        for r, g in zip(ref, got, strict=True):
            r = r.numpy()
            assert np.isfinite(g).all() and np.abs(g - r).max() <= RTOL * max(np.abs(r).max(), 1e-6), name


@pytest.mark.parametrize("skinning", ["lbs", "dqs"])
def test_shipped_body_graphs_pose_the_shipped_body(shipped, skinning):
    """The package's body graphs are the default body's: same hash, and they pose it as BodyModel.forward does."""
    from segadeform.body import default_body_path
    from segadeform.body.identity import body_sha256

    _, manifest = shipped
    body = load_body(default_body_path())
    spec = manifest["graphs"][f"body_{skinning}"]
    assert spec["body"] == {"name": "default_body.npz", "sha256": body_sha256(body)}
    mo = make_motion("dance", seconds=0.3, fps=30, seed=1)
    betas = np.array([0.5, -0.3] + [0.0] * 8, np.float32)
    feeds = {
        "betas": betas,
        "poses": mo.poses.reshape(-1, 24, 3).astype(np.float32),
        "trans": mo.trans.astype(np.float32),
    }
    v, j, rj, f = ort.InferenceSession(str(PKG / spec["file"]), providers=["CPUExecutionProvider"]).run(None, feeds)
    ref = body.forward(
        feeds["poses"].reshape(len(v), -1).astype(np.float64),
        betas.astype(np.float64),
        feeds["trans"].astype(np.float64),
        skinning=skinning,
    )
    assert np.abs(v - ref.vertices).max() <= RTOL * np.abs(ref.vertices).max()
    assert np.abs(j - ref.joints).max() <= RTOL * np.abs(ref.joints).max()
    np.testing.assert_array_equal(f, body.faces)


def test_run_uses_the_shipped_model_by_default(tmp_path):
    from segadeform.cli.main import main

    out = tmp_path / "dress.pc2"
    assert main(["run", str(SAMPLES / "scenes" / "dress_dance.toml"), "-o", str(out), "--frames", "0:12"]) == 0
    from segadeform.io.pc2 import read_pc2

    x = read_pc2(out).frames
    assert x.shape == (12, len(read_mesh(SAMPLES / "garments" / "dress.obj").vertices), 3) and np.isfinite(x).all()
