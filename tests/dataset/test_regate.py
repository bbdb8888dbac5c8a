"""dataset regate: another quality gate applied to kept and rejected samples without simulating again."""

import json

import numpy as np
import pytest

from segadeform.body.model import default_body_path, load_body
from segadeform.cli.main import main
from segadeform.dataset import load_dataset_config
from segadeform.dataset.make import regate
from segadeform.dataset.store import Sample, list_samples, save_sample
from segadeform.garments import make_garment

_CFG = """
[quality]
max_strain = {strain}
max_penetrating = 0.5
max_jitter = 1.0
[[garments]]
kind = "skirt"
[[motions]]
kind = "walk"
"""


@pytest.fixture(scope="module")
def body():
    return load_body(default_body_path())


def _sample(body, sid, stretch):
    """The skirt standing still on the body at rest, its frames stretched along y by ``stretch``."""
    g = make_garment("skirt", body)
    poses, trans = np.zeros((6, 72)), np.zeros((6, 3))
    frames = np.repeat(g.vertices[None], 6, axis=0)
    top = frames[..., 1].max()
    frames[..., 1] = top - (top - frames[..., 1]) * (1.0 + stretch)  # hem lower: vertical edges strain by ~stretch
    return Sample(
        id=sid,
        rest=g.vertices,
        faces=g.faces,
        betas=np.zeros(0),
        poses=poses,
        trans=trans,
        frames=frames.astype(np.float32),
        meta={"id": sid, "split": "train", "status": "x"},
    )


def test_regate_moves_samples_both_ways_and_keeps_their_arrays(tmp_path, body):
    root = tmp_path / "ds"
    save_sample(root, _sample(body, "calm", 0.0))
    save_sample(root, _sample(body, "stretched", 0.3), folder="rejected")
    (root / "rejected" / "old.json").write_text(json.dumps({"id": "old", "status": "rejected"}))  # no arrays
    strict, lenient = tmp_path / "strict.toml", tmp_path / "lenient.toml"
    strict.write_text(_CFG.format(strain=0.1))
    lenient.write_text(_CFG.format(strain=5.0))
    r = regate(root, load_dataset_config(lenient))
    assert r.moved == [("stretched", "kept")] and r.skipped == ["old"] and (r.kept, r.rejected) == (2, 1)
    assert list_samples(root) == ["calm", "stretched"] and not (root / "rejected" / "stretched.npz").exists()
    assert json.loads((root / "samples" / "stretched.json").read_text())["status"] == "kept"
    r = regate(root, load_dataset_config(strict))
    assert sorted(r.moved) == [("stretched", "rejected")] and list_samples(root) == ["calm"]
    meta = json.loads((root / "rejected" / "stretched.json").read_text())
    assert meta["status"] == "rejected" and any("strain" in x for x in meta["reasons"])
    assert (root / "rejected" / "stretched.npz").is_file()


def test_regate_command(tmp_path, body, capsys):
    root = tmp_path / "ds"
    save_sample(root, _sample(body, "stretched", 0.3), folder="rejected")
    cfg = tmp_path / "lenient.toml"
    cfg.write_text(_CFG.format(strain=5.0))
    assert main(["dataset", "regate", str(cfg), "-o", str(root)]) == 0
    out = capsys.readouterr().out
    assert "stretched: now kept" in out and "1 pass the gate" in out
