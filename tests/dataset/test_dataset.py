"""Dataset tool: config, plan and splits, quality gate, and the tiny CI dataset end to end."""

from __future__ import annotations

import json
import shutil

import numpy as np
import pytest

from segadeform.cli.main import main
from segadeform.dataset import load_dataset_config, load_sample, quality_check, sample_plan
from segadeform.dataset.config import QualitySpec
from segadeform.errors import FileFormatError
from segadeform.geometry.primitives import grid_plane

from ..conftest import SAMPLES

TINY = SAMPLES / "datasets" / "tiny.toml"
TRAIN = SAMPLES / "datasets" / "train.toml"


def test_plan_and_held_out_splits():
    cfg = load_dataset_config(TRAIN)
    plan = sample_plan(cfg)
    train_g = {g.name for g in cfg.garments if g.split == "train"}
    train_m = {m.name for m in cfg.motions if m.split == "train"}
    assert len(train_g) >= 8 and len({cfg.garments[i].kind for i in range(len(cfg.garments))}) >= 7
    assert len(cfg.bodies) >= 4 and len(train_m) >= 8
    for p in plan:
        g, m = cfg.garments[p.garment], cfg.motions[p.motion]
        if p.split == "test":  # never seen in training: neither the garment nor the motion
            assert g.name not in train_g and m.name not in train_m
        else:
            assert p.split == "train" and g.name in train_g and m.name in train_m
    assert len({p.id for p in plan}) == len(plan)
    tiny = sample_plan(load_dataset_config(TINY))
    assert sorted(p.split for p in tiny) == ["test", "test-garment", "test-motion", "train"]


@pytest.mark.parametrize("text, msg", [
    ("[[garments]]\nkind = 'cape'\n[[motions]]\nkind = 'walk'\n", "not a garment kind"),
    ("[[garments]]\nkind = 'skirt'\n[[motions]]\nkind = 'moonwalk'\n", "not a motion kind"),
    ("[[garments]]\nkind = 'skirt'\nsplit = 'val'\n[[motions]]\nkind = 'walk'\n", "split"),
    ("[[garments]]\nkind = 'skirt'\n", "at least one"),
    ("[[garments]]\nkind = 'skirt'\n[[motions]]\nkind = 'walk'\n[[motions]]\nkind = 'walk'\n", "used twice"),
    ("[dataset]\nspeed = 1\n[[garments]]\nkind = 'skirt'\n[[motions]]\nkind = 'walk'\n", "unknown key"),
    ("[[garments]]\nkind = 'skirt'\n[[motions]]\nkind = 'walk'\n[simulate]\neffects = ['fire']\n", "unknown simulation"),
])
def test_bad_configs(tmp_path, text, msg):
    p = tmp_path / "c.toml"
    p.write_text(text)
    with pytest.raises(FileFormatError, match=msg) as e:
        load_dataset_config(p)
    assert "c.toml" in str(e.value)


def _cloth(t=5):
    v, f = grid_plane(6, 6, (0.5, 0.5))
    v = np.c_[v[:, 0], v[:, 1] + 3.0, v[:, 2]] if v.shape[1] == 3 else np.c_[v, np.full(len(v), 3.0)]
    frames = np.repeat(v[None], t, axis=0)
    return v, f, frames


def _body_frames(t=5):
    from segadeform.body import load_body

    b = load_body(SAMPLES / "bodies" / "default_body.npz")
    return b, np.repeat(b.shaped_vertices()[0][None], t, axis=0)


def test_quality_gate_accepts_clean_and_names_each_failure():
    b, bf = _body_frames()
    v, f, x = _cloth()
    spec = QualitySpec()
    assert quality_check(x, v, f, bf, b.faces, spec).ok
    y = x.copy()
    y[2, 0] = np.nan
    r = quality_check(y, v, f, bf, b.faces, spec)
    assert not r.ok and r.reasons == ["non-finite positions"]
    y = x.copy()
    y[3, 0] += [0.5, 0, 0]
    r = quality_check(y, v, f, bf, b.faces, spec)
    assert any(s.startswith("strain") for s in r.reasons) and any(s.startswith("jitter") for s in r.reasons)
    inside = x.copy()
    inside[:, :] = b.rest_joints()[0][0]  # every vertex at the pelvis joint, inside the body
    r = quality_check(inside + np.random.default_rng(0).normal(0, 1e-3, inside.shape), v, f, bf, b.faces, spec)
    assert any(s.startswith("penetration") for s in r.reasons)


@pytest.fixture(scope="module")
def tiny_dataset(tmp_path_factory):
    from segadeform.errors import SimulationError
    from segadeform.physics import find_sim_python

    try:
        find_sim_python()
    except SimulationError as e:
        pytest.skip(f"no simulator environment here ({e})")
    out = tmp_path_factory.mktemp("ds") / "tiny"
    assert main(["dataset", "make", str(TINY), "-o", str(out), "-j", "2"]) == 0
    return out


def test_tiny_dataset_end_to_end(tiny_dataset, capsys):
    out = tiny_dataset
    ids = sorted(p.stem for p in (out / "samples").glob("*.json"))
    rejected = sorted(p.stem for p in (out / "rejected").glob("*.json")) if (out / "rejected").is_dir() else []
    assert len(ids) + len(rejected) == 4 and len(ids) >= 3
    s = load_sample(out, ids[0])
    assert s.frames.shape == (15, len(s.rest), 3) and np.isfinite(s.frames).all()
    assert s.meta["blender"].startswith("5.") and s.meta["quality"]["ok"] and s.meta["seconds_per_frame"] > 0
    assert s.meta["settings"]["segadeform"]["effects"] == ["gravity", "body_collision", "bending", "air_damping"]
    assert (out / "config.toml").read_text() == TINY.read_text()
    assert main(["dataset", "info", str(out), "--json"]) == 0
    st = json.loads(capsys.readouterr().out)
    assert st["kept"] == len(ids) and st["by_size"]


def test_resume_skips_done_and_redoes_missing(tiny_dataset, tmp_path, capsys):
    out = tmp_path / "copy"
    shutil.copytree(tiny_dataset, out)
    victim = sorted((out / "samples").glob("*.json"))[0]
    victim.unlink()  # as if killed before the metadata was written
    capsys.readouterr()
    assert main(["dataset", "make", str(TINY), "-o", str(out)]) == 0
    line = capsys.readouterr().out
    assert "4 planned, 3 already done, " in line
    assert victim.is_file()
