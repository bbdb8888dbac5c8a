"""Dataset packs and several dataset roots: round trip within the stated error, size, read-only use,
incompatible packs refused."""

from __future__ import annotations

import hashlib
import json
import zipfile
from pathlib import Path

import numpy as np
import pytest

from segadeform.body.model import default_body_path, load_body
from segadeform.body.transfer import skin_garment, transfer_weights
from segadeform.cli.main import main
from segadeform.dataset.pack import FRAME_STEP, Pack, decode_frames, encode_frames, write_pack
from segadeform.dataset.roots import DatasetRoots
from segadeform.dataset.store import Sample, load_sample, save_sample
from segadeform.errors import InputError
from segadeform.garments import GarmentParams, make_garment
from segadeform.motion import make_motion


@pytest.fixture(scope="module")
def body():
    return load_body(default_body_path())


def _cloth_like(body, n_frames=60, resolution=2000, seed=0):
    """A ~3k-vertex dress skinned to a walk, with a smooth swing on top: the kind of motion a pack stores."""
    g = make_garment("dress", body, None, GarmentParams(resolution=resolution, length=0.6, flare=0.6))
    w = transfer_weights(g.vertices, body.shaped_vertices()[0], body.faces, body.weights)
    m = make_motion("walk", seconds=n_frames / 30.0, fps=30.0, seed=seed)
    x = skin_garment(g.vertices, w, body, m.poses, None, m.trans)
    t = np.arange(len(x))[:, None, None] / 30.0
    swing = 0.03 * np.sin(2 * np.pi * 1.3 * t + g.vertices[None, :, :1] * 7.0) * (1.0 - g.vertices[None, :, 1:2])
    x = x + swing * np.array([1.0, 0.2, 0.6])
    return g, m, x.astype(np.float32)


def _save(root, sid, body, *, folder="samples", split="train", seed=0, spec=None, **meta):
    g, m, x = _cloth_like(body, seed=seed)
    s = Sample(
        id=sid,
        rest=g.vertices,
        faces=g.faces,
        betas=np.zeros(0),
        poses=m.poses,
        trans=m.trans,
        frames=x,
        meta={
            "id": sid,
            "split": split,
            "kind": "skirt",
            "spec": spec or f"spec-{sid}",
            "blender": "5.0.1",
            "sim_bridge": 2,
            **meta,
        },
        cloth_rest=g.vertices + 0.001,
        lead_poses=m.poses[:7] * 0.5,  # the motion simulated before the clip (any 7 frames here)
        lead_trans=m.trans[:7] - 0.1,
    )
    save_sample(root, s, folder=folder)
    return s


def test_frame_codec_is_exact_to_its_step_and_does_not_drift():
    rng = np.random.default_rng(0)
    x = np.cumsum(rng.normal(0, 0.01, (200, 50, 3)), axis=0) + [0.0, 1.0, 0.0]  # a random walk over 200 frames
    y = decode_frames(encode_frames(x))
    err = np.abs(y - x).max()
    assert err <= FRAME_STEP / 2 + 1e-6  # float32 output adds at most ~1e-7 at these magnitudes
    assert np.abs(y[-1] - x[-1]).max() <= FRAME_STEP / 2 + 1e-6  # no drift along the frames
    # non-finite frames (a rejected sample) are kept as they are
    x[3, 2, 1] = np.nan
    z = decode_frames(encode_frames(x))
    assert np.isnan(z[3, 2, 1]) and np.allclose(z[0], x[0], atol=1e-6)
    for t in (1, 2):  # one or two frames
        assert np.abs(decode_frames(encode_frames(x[:t, :3])) - x[:t, :3]).max() <= FRAME_STEP / 2 + 1e-6


def test_pack_round_trip_within_its_stated_error_and_size(tmp_path, body):
    root = tmp_path / "ds"
    a = _save(root, "skirt__b0__walk", body)
    _save(root, "skirt__b0__run", body, folder="rejected", seed=1)
    (root / "configs").mkdir()
    (root / "configs" / "001.toml").write_text("# a config\n")
    out = tmp_path / "p.sgdpack"
    s = write_pack(root, out, body=body)
    assert (s.samples, s.rejected, s.skipped) == (1, 1, 0)
    n, t = a.rest.shape[0], a.frames.shape[0]
    assert n >= 2000 and t == 60
    per_2k = out.stat().st_size / 2 * 2000 / n  # the stated bound: 0.5 MB per 2,000 vertices x 60 frames
    assert per_2k <= 0.5e6, f"{per_2k / 1e6:.2f} MB per 2,000 vertices x {t} frames"
    p = Pack(out)
    assert p.ids() == ["skirt__b0__walk"] and p.ids("rejected") == ["skirt__b0__run"]
    assert p.body_sha256 and p.simulator == {"blender": "5.0.1", "bridge": 2} and p.configs() == ["configs/001.toml"]
    b = p.load("skirt__b0__walk")
    assert np.abs(b.frames - a.frames).max() <= FRAME_STEP / 2 + 1e-6
    assert np.abs(b.rest - a.rest).max() < 1e-6 and np.array_equal(b.faces, a.faces)
    assert np.abs(b.cloth_rest - a.cloth_rest).max() < 1e-6 and np.allclose(b.poses, a.poses, atol=1e-6)
    assert np.allclose(b.lead_poses, a.lead_poses, atol=1e-6) and np.allclose(b.lead_trans, a.lead_trans, atol=1e-6)
    assert b.meta == a.meta
    f = load_sample(root, "skirt__b0__walk")  # the folder keeps the lead too
    assert f.lead_poses.shape == (7, 72) and np.allclose(f.lead_trans, a.lead_trans, atol=1e-6)


def test_roots_read_packs_beside_folders_and_never_write_them(tmp_path, body):
    old = tmp_path / "old"
    _save(old, "a", body)
    _save(old, "b", body, split="test", seed=1)
    store = tmp_path / "store"
    store.mkdir()
    pack = store / "one.sgdpack"
    write_pack(old, pack, body=body)
    digest = hashlib.sha256(pack.read_bytes()).hexdigest()
    new = tmp_path / "new"
    _save(new, "c", body, seed=2)
    _save(new, "a", body)  # the same sample in both: the first root serves it
    r = DatasetRoots([new, store])
    assert r.ids() == ["a", "b", "c"] and r.ids(split="test") == ["b"]
    assert r.writable == new and r.cache_dir == new / "cache"
    assert isinstance(r.source("b"), Pack) and r.source("a") == new
    assert np.abs(r.load("b").frames - load_sample(old, "b").frames).max() <= FRAME_STEP / 2 + 1e-6
    assert hashlib.sha256(pack.read_bytes()).hexdigest() == digest
    # a pack made later holds only what is new
    s = write_pack(new, store / "two.sgdpack", body=body, skip=[Pack(pack)])
    assert (s.samples, s.skipped) == (1, 1)
    assert DatasetRoots([store]).ids() == ["a", "b", "c"]
    # an optional root that is not there is skipped; packs are refused as the writable root's files
    r = DatasetRoots([store], optional=[tmp_path / "absent"])
    assert r.writable is None and r.skipped == [tmp_path / "absent"]
    with pytest.raises(InputError, match="never overwritten"):
        write_pack(new, pack, body=body)
    # a file where the writable root keeps its cache: named, before anything is written ("File exists": a trial)
    (new / "cache").mkdir(exist_ok=True)
    (new / "cache").rmdir()
    (new / "cache").write_text("a user's notes\n")
    with pytest.raises(InputError, match="cache: is a file, where train and eval keep"):
        DatasetRoots([new, store])
    assert (new / "cache").read_text() == "a user's notes\n"


def test_a_sample_that_differs_between_roots_is_an_error(tmp_path, body):
    one, two = tmp_path / "one", tmp_path / "two"
    _save(one, "a", body, spec="x")
    _save(two, "a", body, spec="y")
    with pytest.raises(InputError, match="differs between two dataset roots"):
        DatasetRoots([one, two])


def _rewrite_head(src: Path, dst: Path, **change):
    with zipfile.ZipFile(src) as zi, zipfile.ZipFile(dst, "w") as zo:
        for n in zi.namelist():
            data = zi.read(n)
            if n == "pack.json":
                head = json.loads(data)
                for k, v in change.items():
                    head[k] = v
                data = json.dumps(head).encode()
            zo.writestr(n, data)


def test_incompatible_packs_are_refused(tmp_path, body):
    ds = tmp_path / "ds"
    _save(ds, "a", body)
    one = tmp_path / "s1" / "one.sgdpack"
    one.parent.mkdir()
    write_pack(ds, one, body=body)
    other_body = tmp_path / "s2" / "other.sgdpack"
    other_body.parent.mkdir()
    _rewrite_head(one, other_body, body={"name": "x.npz", "sha256": "0" * 64})
    with pytest.raises(InputError, match="different bodies"):
        DatasetRoots([one, other_body])
    other_sim = tmp_path / "s3" / "sim.sgdpack"
    other_sim.parent.mkdir()
    _rewrite_head(one, other_sim, simulator={"blender": "4.4.0", "bridge": 1})
    with pytest.raises(InputError, match="different simulators"):
        DatasetRoots([one, other_sim])


def test_damaged_pack_is_a_clear_error(tmp_path, body):
    from segadeform.errors import FileFormatError

    ds = tmp_path / "ds"
    _save(ds, "a", body)
    p = tmp_path / "p.sgdpack"
    write_pack(ds, p, body=body)
    bad = tmp_path / "bad.sgdpack"
    with zipfile.ZipFile(p) as zi, zipfile.ZipFile(bad, "w") as zo:
        for n in zi.namelist():
            data = zi.read(n)
            if n.endswith(".npz"):
                data = data[:-10] + b"0123456789"
            zo.writestr(n, data)
    with pytest.raises(FileFormatError, match="SHA-256"):
        Pack(bad).load("a")
    (tmp_path / "junk.sgdpack").write_bytes(b"not a zip")
    with pytest.raises(FileFormatError, match="not a zip"):
        Pack(tmp_path / "junk.sgdpack")
    # a pack cut short (a copy that stopped) is said to be one, not "not a pack" (a researcher's trial)
    for share in (0.5, 0.9, 0.999):
        cut = tmp_path / f"cut{share}.sgdpack"
        cut.write_bytes(p.read_bytes()[: int(share * p.stat().st_size)])
        with pytest.raises(FileFormatError, match="truncated or damaged .*a copy cut short"):
            Pack(cut)
    # a byte flipped inside a member's LZMA stream: lzma's own error was a traceback (a user's trial)
    with zipfile.ZipFile(p) as z:
        info = z.getinfo("samples/a.npz")
    raw = bytearray(p.read_bytes())
    at = info.header_offset + 30 + len(info.filename) + len(info.extra) + info.compress_size // 2
    raw[at] ^= 0xFF
    flipped = tmp_path / "flipped.sgdpack"
    flipped.write_bytes(bytes(raw))
    with pytest.raises(FileFormatError, match="sample a is unreadable") as e:
        Pack(flipped).load("a")
    assert "flipped.sgdpack" in str(e.value)
    r = _run_cli(["inspect", str(flipped)])
    assert r[0] == 1 and "Traceback" not in r[1] and "sample a is unreadable" in r[1], r


def test_dataset_pack_command(tmp_path, body, capsys):
    ds = tmp_path / "ds"
    _save(ds, "a", body)
    out = tmp_path / "p.sgdpack"
    assert main(["dataset", "pack", str(ds), "-o", str(out)]) == 0
    assert "1 kept and 0 rejected" in capsys.readouterr().out
    before = out.read_bytes()
    assert main(["dataset", "pack", str(ds), "-o", str(out)]) == 1  # never over an existing file
    assert "never overwritten" in capsys.readouterr().err and out.read_bytes() == before


def test_nothing_to_pack_writes_no_pack_and_an_empty_pack_claims_no_simulator(tmp_path, body, capsys):
    """A user's trial: `dataset pack ds -o store/new.sgdpack --skip store` with nothing new (and packing an empty
    folder) wrote a pack of no samples whose head said "Blender None", and every command reading the store then
    refused it as another simulator's.  Now nothing is written (one line, exit 1); a pack of no samples made before
    is read beside the others."""
    ds, store = tmp_path / "ds", tmp_path / "store"
    _save(ds, "a", body)
    store.mkdir()
    first = store / "my-001.sgdpack"
    assert main(["dataset", "pack", str(ds), "-o", str(first)]) == 0
    capsys.readouterr()
    again = store / "my-002.sgdpack"
    assert main(["dataset", "pack", str(ds), "-o", str(again), "--skip", str(store)]) == 1
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "nothing to pack" in err and "1 samples, all in the packs given" in err, err
    (tmp_path / "empty" / "samples").mkdir(parents=True)
    assert main(["dataset", "pack", str(tmp_path / "empty"), "-o", str(again)]) == 1
    assert "nothing to pack" in capsys.readouterr().err and sorted(p.name for p in store.glob("*.sgdpack")) == [
        first.name
    ]
    # a pack of no samples, as the earlier release wrote it, beside a real one: read, not refused
    _rewrite_head(first, again, samples={}, simulator={"blender": None, "bridge": 3})
    zipfile.ZipFile(again).close()
    roots = DatasetRoots([store])
    assert roots.ids() == ["a"]


def test_dataset_pack_into_a_store_that_is_not_there_yet(tmp_path, body, capsys):
    """The first pack of the durable store: the README's command names the store in --skip before it exists."""
    ds = tmp_path / "ds"
    _save(ds, "a", body)
    store = tmp_path / "shared" / "data" / "sim"
    out = store / "continuum-001.sgdpack"
    assert main(["dataset", "pack", str(ds), "-o", str(out), "--skip", str(store)]) == 0
    printed = capsys.readouterr().out
    assert "1 kept and 0 rejected" in printed and "not there yet" in printed and out.is_file()
    # the second pack skips what the first holds
    _save(ds, "b", body, seed=1)
    assert main(["dataset", "pack", str(ds), "-o", str(store / "continuum-002.sgdpack"), "--skip", str(store)]) == 0
    assert "1 kept and 0 rejected samples (1 already in the packs given)" in capsys.readouterr().out
    # a missing pack named in --skip is a mistake: one line, exit 1, nothing written
    third = store / "continuum-003.sgdpack"
    assert main(["dataset", "pack", str(ds), "-o", str(third), "--skip", str(store / "nope.sgdpack")]) == 1
    err = capsys.readouterr().err
    assert "nope.sgdpack" in err and "does not exist" in err and len(err.strip().splitlines()) == 1
    assert not third.exists()


def test_packing_into_a_store_leaves_a_users_files_alone(tmp_path, body):
    """A user's file beside the packs survives a new pack and a refused one, byte for byte."""
    ds = tmp_path / "ds"
    _save(ds, "a", body)
    store = tmp_path / "store"
    store.mkdir()
    (store / "notes.txt").write_text("mine")
    (store / "continuum-001.sgdpack").write_bytes(b"not ours")  # a file where the pack would go

    def digest():
        return {p.name: hashlib.sha256(p.read_bytes()).hexdigest() for p in sorted(store.iterdir()) if p.is_file()}

    before = digest()
    assert main(["dataset", "pack", str(ds), "-o", str(store / "continuum-001.sgdpack")]) == 1  # never over it
    assert digest() == before
    assert main(["dataset", "pack", str(ds), "-o", str(store / "continuum-002.sgdpack")]) == 0
    after = digest()
    assert {k: after[k] for k in before} == before and "continuum-002.sgdpack" in after


def test_dataset_make_skips_what_a_pack_holds_and_never_writes_it(tmp_path, body):
    """A fresh machine with the durable packs beside it: `dataset make` finds every sample done in the
    pack (nothing simulated, so no simulator is needed here) and writes nothing into it; a pack whose
    sample was made from other settings than the config now gives stops the run."""
    from segadeform.dataset import load_dataset_config, sample_plan
    from segadeform.dataset.make import make_dataset, sample_spec, sample_spec_parts

    cfg_p = tmp_path / "c.toml"
    cfg_p.write_text(
        "[dataset]\nseconds = 0.5\n[[garments]]\nkind = 'skirt'\n[[motions]]\nkind = 'walk'\n"
        "[[motions]]\nkind = 'run'\n"
    )
    cfg = load_dataset_config(cfg_p)
    plan = sample_plan(cfg)
    old = tmp_path / "old"
    for ps in plan:
        _save(old, ps.id, body, spec=sample_spec(cfg, ps), spec_parts=sample_spec_parts(cfg, ps))
    store = tmp_path / "sim"
    store.mkdir()
    write_pack(old, store / "a.sgdpack", body=body)
    digest = hashlib.sha256((store / "a.sgdpack").read_bytes()).hexdigest()
    s = make_dataset(cfg, tmp_path / "new", roots=[store])
    assert (s.planned, s.skipped, s.kept + s.rejected) == (len(plan), len(plan), 0)
    assert hashlib.sha256((store / "a.sgdpack").read_bytes()).hexdigest() == digest
    assert list((tmp_path / "new" / "samples").iterdir()) == []
    # the config's own dataset.roots: read where they exist, skipped where they do not
    cfg_p.write_text(cfg_p.read_text().replace("[dataset]\n", "[dataset]\nroots = ['sim', 'absent']\n"))
    s = make_dataset(load_dataset_config(cfg_p), tmp_path / "new")
    assert s.skipped == len(plan)
    # a changed entry under the same name is refused before anything is simulated
    cfg_p.write_text(cfg_p.read_text().replace("kind = 'run'", "kind = 'run'\nspeed = 1.5"))
    with pytest.raises(InputError, match="made from other settings") as e:
        make_dataset(load_dataset_config(cfg_p), tmp_path / "new")
    # the pack that holds it is named, not the output folder, whose "use a new folder" did not help (a user's trial)
    assert "a.sgdpack" in str(e.value) and "leave out the root that holds it" in str(e.value)
    assert "its motion (its entry or file) changed" in str(e.value)  # read from the pack's record (a review)
    # and a new output folder is not left behind by the refusal
    with pytest.raises(InputError, match="made from other settings"):
        make_dataset(load_dataset_config(cfg_p), tmp_path / "newer")
    assert not (tmp_path / "newer").exists()


def test_dataset_info_reads_a_pack(tmp_path, body, capsys):
    """`dataset info PACK` said "Directory ... is a file" (a user's trial): a pack's samples are counted from their
    metadata, as the folder's log counts them."""
    ds = tmp_path / "ds"
    _save(ds, "a", body, garment="g", vertices=10, motion="walk", status="kept")
    _save(
        ds,
        "b",
        body,
        folder="rejected",
        seed=1,
        garment="g",
        vertices=10,
        motion="walk",
        status="rejected",
        quality={"reasons": ["max_strain 1.5 > 1.0"]},
    )
    out = tmp_path / "p.sgdpack"
    assert main(["dataset", "pack", str(ds), "-o", str(out)]) == 0
    capsys.readouterr()
    assert main(["dataset", "info", str(out), "--json"]) == 0
    st = json.loads(capsys.readouterr().out)
    assert (st["kept"], st["rejected"]) == (1, 1) and st["splits"] == {"train": 1}
    assert st["reasons"] == {"max_strain": 1}  # the rejected sample's quality verdict
    assert main(["dataset", "info", str(out)]) == 0
    assert "1 kept" in capsys.readouterr().out
    # a folder of packs, as train and eval read it ("not a dataset folder (no log.jsonl)": a user's trial)
    assert main(["dataset", "info", str(tmp_path), "--json"]) == 0
    st = json.loads(capsys.readouterr().out)
    assert (st["kept"], st["rejected"]) == (1, 1)
    # several roots, as train and eval take them (it was a usage error: a user's trial): each on its own
    assert main(["dataset", "info", str(out), str(tmp_path)]) == 0
    said = capsys.readouterr().out
    assert said.startswith(f"{out}: 1 kept") and f"\n{tmp_path}: 1 kept" in said
    assert main(["dataset", "info", str(out), str(tmp_path), "--json"]) == 0
    both = json.loads(capsys.readouterr().out)
    assert list(both) == [str(out), str(tmp_path)] and both[str(out)]["kept"] == 1
    assert main(["dataset", "info", str(out), str(ds)]) == 1  # a root that cannot be read: said, nothing else
    assert "not a dataset folder" in capsys.readouterr().err
    # `inspect` reads a pack too (a user's trial: "unknown mesh file extension"), every sample checked
    assert main(["inspect", str(out)]) == 0
    said = capsys.readouterr().out
    assert "dataset pack, 1 kept samples (train 1;" in said and "1 rejected" in said, said


_DAMAGE = {
    "trans cut short": (lambda z: z.update(trans=z["trans"][:-5]), "'trans' does not match 'poses'"),
    "a vertex missing from frames": (lambda z: z.update(frames=z["frames"][:, :-1]), "'frames' does not match"),
    "a face index out of range": (
        lambda z: z.update(faces=np.where(z["faces"] == 0, 99999, z["faces"])),
        "'faces' has an index out of range",
    ),
    "NaN in frames": (lambda z: z["frames"].__setitem__((3, 5, 0), np.nan), "'frames' contains NaN or inf"),
    "NaN betas": (lambda z: z.update(betas=np.full(10, np.nan)), "'betas' contains NaN or inf"),
    "poses narrower than the lead": (lambda z: z.update(poses=z["poses"][:, :69]), "differ in width"),
}


@pytest.mark.parametrize("damage", list(_DAMAGE))
def test_a_damaged_sample_is_one_line_naming_its_file_and_array(tmp_path, body, capsys, damage):
    """A sample's arrays edited or damaged by hand: each is one error naming the file and the array (a researcher's
    trial met tracebacks deep in training and evaluation, and messages naming no file or the wrong array), in
    `eval` with exit 1 and no output, and in `dataset pack` (no pack written)."""
    from segadeform.errors import FileFormatError

    edit, words = _DAMAGE[damage]
    root = tmp_path / "d"
    _save(root, "s1", body, split="val")
    p = root / "samples" / "s1.npz"
    z = dict(np.load(p))
    edit(z)
    np.savez(p, **z)
    with pytest.raises(FileFormatError) as e:
        load_sample(root, "s1")
    assert words in str(e.value) and "s1.npz" in str(e.value), str(e.value)
    capsys.readouterr()
    assert main(["eval", str(root), "--split", "val", "-m", "lbs=lbs", "-o", str(tmp_path / "ev")]) == 1
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "s1.npz" in err and words in err, err
    assert not (tmp_path / "ev").exists()
    if damage == "trans cut short":  # not packed either: the same error, and no pack
        with pytest.raises(FileFormatError) as e:
            write_pack(root, tmp_path / "d.sgdpack", body=body)
        assert "s1.npz" in str(e.value) and words in str(e.value), str(e.value)
        assert not (tmp_path / "d.sgdpack").exists()


def test_samples_of_another_body_are_refused_wherever_they_are_read(tmp_path, body):
    """Samples record the body they were simulated on (``body_sha256``).  A user's trial: a folder made on a body
    scaled by 1.01 was packed with the default body's hash in the pack's head, read beside default-body packs by
    `train`, evaluated against the default body (38.5 % penetrating instead of 12.3 %), and counted as done by
    `dataset make --body`.  Now every reader compares: two roots of different bodies are not mixed, `check_body`
    (train, eval, dataset make) refuses another body, and `dataset pack` refuses a `--body` its samples were not
    made on, or a folder of two bodies."""
    import dataclasses

    from segadeform.body.identity import body_sha256
    from segadeform.train.evaluate import evaluate
    from segadeform.train.predictors import make_predictor

    other = dataclasses.replace(body, v_template=body.v_template * 1.01)
    ours, theirs = body_sha256(body), body_sha256(other)
    _save(tmp_path / "ds", "a", body, split="test", body_sha256=ours)
    _save(tmp_path / "ds2", "b", body, split="test", body_sha256=theirs)
    DatasetRoots([tmp_path / "ds"]).check_body(body)
    with pytest.raises(InputError, match="another body than the one given") as e:
        DatasetRoots([tmp_path / "ds2"]).check_body(body)
    assert theirs[:12] in str(e.value) and ours[:12] in str(e.value) and "ds2" in str(e.value)
    with pytest.raises(InputError, match="different bodies"):
        DatasetRoots([tmp_path / "ds", tmp_path / "ds2"])
    with pytest.raises(InputError, match="another body than the one given"):
        evaluate(tmp_path / "ds2", body, {"lbs": make_predictor("lbs", "lbs")})
    out = tmp_path / "p" / "b.sgdpack"
    out.parent.mkdir()
    with pytest.raises(InputError, match="another body than the one given"):
        write_pack(tmp_path / "ds2", out, body=body)
    assert not out.exists()
    write_pack(tmp_path / "ds2", out, body=other)  # the body it was made on: the head records it
    assert Pack(out).body_sha256 == theirs
    with pytest.raises(InputError, match="different bodies"):
        DatasetRoots([tmp_path / "ds", out])
    # dataset make into a folder of another body's samples, given as the command line gives it (a Location): refused
    # before anything is written (a review: the check looked at str and Path outputs only)
    from segadeform.dataset import load_dataset_config, make_dataset
    from segadeform.io.location import open_location
    from tests.conftest import SAMPLES

    before = sorted(p.name for p in (tmp_path / "ds2").rglob("*"))
    with pytest.raises(InputError, match="another body than the one given"):
        make_dataset(
            load_dataset_config(SAMPLES / "datasets" / "tiny.toml"),
            open_location(tmp_path / "ds2"),
            sim_python=tmp_path / "no-simulator",
        )
    assert sorted(p.name for p in (tmp_path / "ds2").rglob("*")) == before
    _save(tmp_path / "ds2", "c", body, split="test", body_sha256=ours)
    with pytest.raises(InputError, match="mixes samples of several bodies"):
        write_pack(tmp_path / "ds2", tmp_path / "p" / "c.sgdpack", body=body)


def _run_cli(args):
    """(exit code, output) of the command line, as a user sees it."""
    from click.testing import CliRunner

    from segadeform.cli.main import cli

    r = CliRunner().invoke(cli, args)
    return r.exit_code, r.output


def test_a_decompression_bomb_is_refused_in_an_npz_and_in_a_pack(tmp_path):
    """A security review: 3.2 MB of deflated zeros in a motion .npz grew to 24 GB of memory, and a 455 KB pack whose
    pack.json unpacked to 3 GiB ran out of memory; a member that unpacks past 64 MiB to over 200 times its compressed
    size is refused before it is read."""
    import zipfile

    from segadeform.dataset.pack import Pack
    from segadeform.errors import FileFormatError
    from segadeform.io.npz import load_npz

    np.savez_compressed(tmp_path / "bomb.npz", poses=np.zeros((70 * 2**20 // 8,)))  # 70 MiB of zeros, ~70 KB packed
    with pytest.raises(FileFormatError, match="array 'poses' unpacks to far more than its compressed size"):
        load_npz(tmp_path / "bomb.npz")
    with zipfile.ZipFile(tmp_path / "bomb.sgdpack", "w", zipfile.ZIP_DEFLATED) as z:
        z.writestr("pack.json", b'{"format": "x"' + b" " * (70 * 2**20) + b"}")
    with pytest.raises(FileFormatError, match="pack.json unpacks to far more than its compressed size"):
        Pack(tmp_path / "bomb.sgdpack")
