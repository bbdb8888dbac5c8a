"""dataset regate: another quality gate applied to kept and rejected samples without simulating again."""

import json

import numpy as np
import pytest

from segadeform.body.model import default_body_path, load_body
from segadeform.cli.main import main
from segadeform.dataset import load_dataset_config
from segadeform.dataset.make import regate
from segadeform.dataset.report import dataset_stats
from segadeform.dataset.store import Sample, list_samples, load_sample, save_sample
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
    # each sample gated once: the one moved into rejected/ was gated there again and counted twice (a trial)
    assert (r.kept, r.rejected) == (1, 2)
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


def test_regate_keeps_the_leading_frames_that_pass_when_the_config_allows_a_cut_clip(tmp_path, body):
    """[quality] min_frames: a clip that fails from frame 4 on is kept as its first 4 frames (arrays cut alike),
    the log says so, and `dataset info` counts it; with min_frames above 4 it stays rejected."""
    root = tmp_path / "ds"
    calm, stretched = _sample(body, "late", 0.0), _sample(body, "late", 0.3)
    s = Sample(**{**calm.__dict__, "frames": np.concatenate([calm.frames[:4], stretched.frames[4:]])})
    save_sample(root, s, folder="rejected")
    (root / "log.jsonl").write_text(
        json.dumps({"id": "late", "split": "train", "kind": "skirt", "motion": "cmu-1", "status": "rejected"}) + "\n"
    )
    cfg = tmp_path / "cut.toml"
    cfg.write_text(_CFG.format(strain=0.1) + "\n")
    too_long = tmp_path / "too_long.toml"
    too_long.write_text(_CFG.format(strain=0.1).replace("max_jitter = 1.0", "max_jitter = 1.0\nmin_frames = 5"))
    assert regate(root, load_dataset_config(too_long)).moved == [] and list_samples(root) == []
    ok = tmp_path / "ok.toml"
    ok.write_text(_CFG.format(strain=0.1).replace("max_jitter = 1.0", "max_jitter = 1.0\nmin_frames = 3"))
    r = regate(root, load_dataset_config(ok))
    assert r.moved == [("late", "kept, 4 of 6 frames")] and list_samples(root) == ["late"]
    kept = load_sample(root, "late")
    assert kept.frames.shape[0] == kept.poses.shape[0] == kept.trans.shape[0] == 4
    np.testing.assert_array_equal(kept.frames, s.frames[:4])
    assert kept.meta["trimmed"]["clip_frames"] == 6 and any("strain" in x for x in kept.meta["trimmed"]["reasons"])
    assert kept.meta["quality"]["ok"] and kept.meta["frames"] == 4 and not (root / "rejected" / "late.npz").exists()
    st = dataset_stats(root)
    assert (st["kept"], st["trimmed"], st["rejected"]) == (1, 1, 0)
    assert st["by_kind_source"]["skirt / mocap"] == {
        "samples": 1,
        "rejected": 0,
        "rejection_rate": 0.0,
        "trimmed": 1,
        "fallback": 0,
    }
    # the same gate again changes nothing: the 4 frames pass whole
    assert regate(root, load_dataset_config(ok)).moved == [] and load_sample(root, "late").frames.shape[0] == 4


def test_regate_cuts_a_kept_sample_shorter_in_place_when_a_stricter_gate_fails_its_tail(tmp_path, body):
    """A kept clip that a stricter gate fails from frame 4 on is cut to 4 frames where it lies (samples/)."""
    root = tmp_path / "ds"
    calm, stretched = _sample(body, "tail", 0.0), _sample(body, "tail", 0.3)
    s = Sample(**{**calm.__dict__, "frames": np.concatenate([calm.frames[:4], stretched.frames[4:]])})
    save_sample(root, s)
    strict = tmp_path / "strict.toml"
    strict.write_text(_CFG.format(strain=0.1).replace("max_jitter = 1.0", "max_jitter = 1.0\nmin_frames = 3"))
    (root / "notes.txt").write_text("the user's own file")
    r = regate(root, load_dataset_config(strict))
    assert r.moved == [("tail", "kept, 4 of 6 frames")] and list_samples(root) == ["tail"]
    kept = load_sample(root, "tail")
    assert kept.frames.shape[0] == 4 and kept.meta["trimmed"]["clip_frames"] == 6
    assert sorted(p.name for p in (root / "samples").iterdir()) == ["tail.json", "tail.npz"]
    assert (root / "notes.txt").read_text() == "the user's own file"
    # a dataset whose log never had the sample (made before logs) still reads: the regate's record is whole
    st = dataset_stats(root)
    assert (st["kept"], st["trimmed"], st["splits"]) == (1, 1, {"train": 1})
