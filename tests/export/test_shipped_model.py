"""The shipped default model: its ONNX graphs match its torch checkpoint on a real garment and motion; the
package holds only what a runtime reads (the checkpoint and the evaluation report live beside it)."""

from __future__ import annotations

import json

import numpy as np
import onnxruntime as ort
import pytest
import torch

from segadeform.body import load_body
from segadeform.export.package import _variant_model, deformer_variants
from segadeform.geometry import precompute_garment
from segadeform.geometry.features import vertex_features
from segadeform.io import read_mesh
from segadeform.model.network import load_checkpoint
from segadeform.motion import make_motion, motion_windows
from segadeform.package_spec import read_manifest_text

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
    assert dict({"weights": "free"}, **manifest["config"]) == json.loads(net.cfg.to_json())  # older manifests: free
    size = sum(p.stat().st_size for p in PKG.iterdir())
    assert size < 1.5e6  # 6 MB before the graphs shared their weights and lost their debug metadata
    assert (PKG / "MODEL_CARD.md").read_text().count("| ") > 10
    # one file per graph, every file a graph, the weights or the card: no checkpoint, no reports
    listed = {g["file"] for g in manifest["graphs"].values()} | {manifest["weights"]["file"]}
    assert len(listed) == len(manifest["graphs"]) + 1
    assert {p.name for p in PKG.iterdir()} == listed | {"manifest.json", "MODEL_CARD.md"}
    assert (TRAIN / "eval" / "eval.md").is_file()


def test_shipped_parity_on_the_sample_dress(shipped):
    net, manifest = shipped
    body = load_body(SAMPLES / "bodies" / "default_body.npz")
    mesh = read_mesh(SAMPLES / "garments" / "dress.obj")
    betas = np.zeros(net.cfg.n_betas, np.float32)
    joints = body.rest_joints()[0]
    a = precompute_garment(mesh.vertices, mesh.faces, joints, n_star=net.cfg.n_star)
    feats = vertex_features(a.vertices, a.faces, joints, normals=a.normals.astype(np.float64)).astype(np.float32)
    enc = {"features": feats[None], "nbr": a.nbr, "mask": a.mask, "descriptor": a.descriptor[None].astype(np.float32)}
    sess = ort.InferenceSession(str(PKG / manifest["graphs"]["garment_encoder"]["file"]),
                                providers=["CPUExecutionProvider"])
    P = sess.run(None, enc)[0]
    with torch.no_grad():
        Pt = net.garment_encoder(*(torch.as_tensor(enc[k]) for k in ("features", "nbr", "mask", "descriptor"))).numpy()
    assert np.abs(P - Pt).max() <= RTOL * np.abs(Pt).max()
    mo = make_motion("dance", seconds=0.3, fps=30, seed=1)
    for name, var in deformer_variants(net.cfg).items():
        w = motion_windows(mo.poses, var["config"].window).astype(np.float32)
        b = len(w)
        feeds = {"g": Pt[0], "window": w, "betas": np.repeat(betas[None], b, 0), "rest": a.vertices.astype(np.float32),
                 "nbr": a.nbr, "mask": a.mask, "joints": np.repeat(joints[None].astype(np.float32), b, 0),
                 "trans": mo.trans.astype(np.float32)}
        s = ort.InferenceSession(str(PKG / manifest["graphs"][name]["file"]), providers=["CPUExecutionProvider"])
        got = s.run(None, feeds)
        vnet = net if var["default"] else _variant_model(net, var["config"])
        with torch.no_grad():
            ref = vnet.deformer(*(torch.as_tensor(feeds[k]) for k in feeds))
        for r, g in zip(ref, got):
            r = r.numpy()
            assert np.isfinite(g).all() and np.abs(g - r).max() <= RTOL * max(np.abs(r).max(), 1e-6), name


def test_run_uses_the_shipped_model_by_default(tmp_path):
    from segadeform.cli.main import main

    out = tmp_path / "dress.pc2"
    assert main(["run", str(SAMPLES / "scenes" / "dress_dance.toml"), "-o", str(out), "--frames", "0:12"]) == 0
    from segadeform.io.pc2 import read_pc2

    x = read_pc2(out).frames
    assert x.shape == (12, len(read_mesh(SAMPLES / "garments" / "dress.obj").vertices), 3) and np.isfinite(x).all()
