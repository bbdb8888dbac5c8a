import json
import shutil
import subprocess
import sys

import numpy as np
import pytest
from click.testing import CliRunner

from segadeform.body import BodyProxy, load_body
from segadeform.cli.main import cli
from segadeform.errors import InputError
from segadeform.io import read_obj, read_pc2
from segadeform.motion import Motion, make_motion
from segadeform.runtime import Deformer, ModelPackage, PackageError
from segadeform.runtime.pipeline import Run
from segadeform.settings import Effects
from tests.conftest import SAMPLES, leftovers

BODY = SAMPLES / "bodies" / "default_body.npz"
SKIRT = SAMPLES / "garments" / "skirt.obj"


@pytest.fixture(scope="module")
def body():
    return load_body(BODY)


def make_run(tmp_path, package_path, body, effects, *, motion=None, garment=SKIRT, batch=4, **kw):
    pkg = ModelPackage(package_path)
    motion = motion or make_motion("walk", seconds=0.5)
    return Run(
        garment=garment,
        motion=motion,
        package=pkg,
        body=body,
        effects=effects,
        output=tmp_path / "out.pc2",
        batch=batch,
        cache=False,
        **kw,
    )


# ---- effects: only the stages a scene names run -----------------------------------------------
def test_disabled_stages_never_get_a_session(tmp_path, random_package, body):
    run = make_run(tmp_path, random_package, body, Effects(wrinkles=False, dynamics=False, collisions=False))
    s = run.execute()
    assert s.variant == "deformer_lbs_nowrinkles_static"
    assert s.sessions == ["deformer_lbs_nowrinkles_static", "garment_encoder"]
    assert read_pc2(tmp_path / "out.pc2").frames.shape == (15, 1536, 3)


def test_wrinkles_off_means_zero_blend_shapes(tmp_path, random_package, body):
    asset_run = make_run(tmp_path, random_package, body, Effects(collisions=False))
    joints = body.rest_joints()[0]
    asset = asset_run.load_asset(joints)
    win = np.random.default_rng(0).normal(scale=0.3, size=(3, 5, 72)).astype(np.float32)
    trans = np.zeros((3, 3))
    out = {}
    for wr in (True, False):
        d = Deformer(ModelPackage(random_package), Effects(wrinkles=wr))
        P = d.encode(asset, joints)
        out[wr] = d.deform(
            P,
            asset,
            win if wr or d.window == 5 else win[:, :1],
            joints,
            trans,
            outputs=True,
            log_wbody=d.body_log_weights(asset, body),
        )
    v_on, w_on, b_on = out[True]
    v_off, w_off, b_off = out[False]
    assert (b_off == 0).all() and np.abs(b_on).max() > 0
    np.testing.assert_allclose(w_off, w_on, atol=1e-6)  # the weights do not depend on the decoder
    # without blend shapes the output is the skinning of the rest garment with the same weights
    assert not np.allclose(v_on, v_off)


def test_dynamics_off_depends_on_the_current_pose_only(tmp_path, random_package, body):
    d = Deformer(ModelPackage(random_package), Effects(dynamics=False))
    assert d.window == 1
    d_dyn = Deformer(ModelPackage(random_package), Effects(dynamics=True))
    run = make_run(tmp_path, random_package, body, Effects())
    joints = body.rest_joints()[0]
    asset = run.load_asset(joints)
    rng = np.random.default_rng(1)
    cur = rng.normal(scale=0.3, size=(1, 1, 72))
    hist_a = np.concatenate([cur, rng.normal(scale=0.3, size=(1, 4, 72))], 1).astype(np.float32)
    hist_b = np.concatenate([cur, rng.normal(scale=0.3, size=(1, 4, 72))], 1).astype(np.float32)
    P = d.encode(asset, joints)
    z = np.zeros((1, 3))
    lw = d.body_log_weights(asset, body)
    np.testing.assert_array_equal(
        d.deform(P, asset, hist_a[:, :1], joints, z, log_wbody=lw),
        d.deform(P, asset, hist_b[:, :1], joints, z, log_wbody=lw),
    )
    P2 = d_dyn.encode(asset, joints)
    assert not np.allclose(
        d_dyn.deform(P2, asset, hist_a, joints, z, log_wbody=lw),
        d_dyn.deform(P2, asset, hist_b, joints, z, log_wbody=lw),
    )


def test_collisions_off_never_poses_the_body(tmp_path, random_package, body, monkeypatch):
    def boom(*a, **k):
        raise AssertionError("a disabled stage ran")

    monkeypatch.setattr(type(body), "forward", boom)
    # neither the collider is built nor the body posed when collisions are off
    make_run(tmp_path, random_package, body, Effects(collisions=False), collider=boom).execute()
    with pytest.raises(AssertionError, match="disabled stage"):  # the numpy body: its posing is what is watched
        make_run(tmp_path, random_package, body, Effects(collisions=True), body_backend="numpy").execute()
    monkeypatch.undo()
    with pytest.raises(AssertionError, match="disabled stage"):  # and with them on, the collider is built
        make_run(tmp_path, random_package, body, Effects(collisions=True), collider=boom).execute()


def test_collisions_push_every_vertex_out_of_the_body(tmp_path, random_package, body):
    motion = make_motion("dance", seconds=0.4, seed=2)
    make_run(tmp_path, random_package, body, Effects(collision_margin=0.004), motion=motion).execute()
    frames = read_pc2(tmp_path / "out.pc2").frames
    posed = body.forward(motion.poses, None, motion.trans).vertices
    proxy = BodyProxy(posed[0], body.faces)
    within = 0
    for i in range(len(frames)):
        d = proxy.moved(posed[i]).query(np.asarray(frames[i], np.float64)).signed_distance
        assert d.min() > -1e-5  # no vertex inside the body (float32 output rounding)
        within += int((d < 0.004 - 1e-4).sum())
    # the margin is kept except where two body surfaces are closer than twice the margin
    assert within <= 0.01 * frames.shape[0] * frames.shape[1]


def test_skinning_variant_changes_the_output(tmp_path, random_package, body):
    a = make_run(tmp_path, random_package, body, Effects(collisions=False)).execute()
    fa = np.array(read_pc2(tmp_path / "out.pc2").frames)
    b = make_run(tmp_path, random_package, body, Effects(skinning="dqs", collisions=False)).execute()
    fb = np.array(read_pc2(tmp_path / "out.pc2").frames)
    assert a.variant == "deformer_lbs" and b.variant == "deformer_dqs"
    assert np.isfinite(fb).all() and not np.allclose(fa, fb)


# ---- caching, vertex order, streaming ------------------------------------------------------------
def test_body_weights_are_cached_on_disk(tmp_path, body, monkeypatch):
    """The residual model's log_wbody (the inpainted prior, ~0.2 s at 4k vertices) is computed once per garment,
    body and shape: a second deformer reads it from the cache, a new shape computes it again."""
    import segadeform.body.transfer as transfer

    pkg = SAMPLES / "models" / "default"
    joints = body.rest_joints()[0]
    asset = make_run(tmp_path, pkg, body, Effects()).load_asset(joints)
    d = Deformer(ModelPackage(pkg))
    assert d.needs_body_weights
    lw = d.body_log_weights(asset, body, cache_dir=tmp_path / "cache")
    assert [p.name[:2] for p in (tmp_path / "cache").iterdir()] == ["W-"]
    calls = []
    real = transfer.garment_weights
    monkeypatch.setattr(transfer, "garment_weights", lambda *a, **k: calls.append(1) or real(*a, **k))
    d2 = Deformer(ModelPackage(pkg))
    np.testing.assert_array_equal(d2.body_log_weights(asset, body, cache_dir=tmp_path / "cache"), lw)
    assert calls == []  # served from disk
    other = d2.body_log_weights(asset, body, [1.5], cache_dir=tmp_path / "cache")
    assert calls == [1] and not np.array_equal(other, lw)
    assert len(list((tmp_path / "cache").glob("W-*.npy"))) == 2
    # a new version of the priors reads no old entry
    monkeypatch.setattr(transfer, "WEIGHT_PRIOR_VERSION", transfer.WEIGHT_PRIOR_VERSION + 1)
    Deformer(ModelPackage(pkg)).body_log_weights(asset, body, cache_dir=tmp_path / "cache")
    assert calls == [1, 1] and len(list((tmp_path / "cache").glob("W-*.npy"))) == 3
    # a broken entry is recomputed, not trusted
    for p in (tmp_path / "cache").glob("W-*.npy"):
        p.write_bytes(b"broken")
    np.testing.assert_array_equal(
        Deformer(ModelPackage(pkg)).body_log_weights(asset, body, cache_dir=tmp_path / "cache"), lw
    )


def test_encoder_runs_once_and_is_cached_on_disk(tmp_path, random_package, body):
    joints = body.rest_joints()[0]
    run = make_run(tmp_path, random_package, body, Effects())
    asset = run.load_asset(joints)
    d = Deformer(ModelPackage(random_package))
    P1 = d.encode(asset, joints, cache_dir=tmp_path / "cache")
    P2 = d.encode(asset, joints, cache_dir=tmp_path / "cache")
    assert d.encoder_runs == 1 and P1 is P2
    assert len(list((tmp_path / "cache").glob("P-*.npy"))) == 1
    fresh_pkg = ModelPackage(random_package)
    d2 = Deformer(fresh_pkg)
    np.testing.assert_array_equal(d2.encode(asset, joints, cache_dir=tmp_path / "cache"), P1)
    assert d2.encoder_runs == 0 and "garment_encoder" not in fresh_pkg.created  # served from disk
    d2.encode(asset, joints, betas=[1.0], cache_dir=tmp_path / "cache")  # a new body shape re-encodes
    assert d2.encoder_runs == 1


def test_output_keeps_the_files_vertex_order(tmp_path, random_package, body):
    """An OBJ with vt/vn, quads and negative indices: the output addresses the file's vertices in order."""
    g = tmp_path / "quads.obj"
    shutil.copy(SKIRT, g)
    still = Motion(poses=np.zeros((3, 72)), trans=np.zeros((3, 3)), fps=30)
    make_run(
        tmp_path, random_package, body, Effects(wrinkles=False, collisions=False), motion=still, garment=g
    ).execute()
    frames = read_pc2(tmp_path / "out.pc2").frames
    rest = read_obj(g).vertices
    assert frames.shape == (3, len(rest), 3)
    # rest pose, no blend shapes, no translation: skinning reproduces the rest garment vertex by vertex
    np.testing.assert_allclose(frames[0], rest, atol=1e-5)


def test_failure_midway_leaves_no_output(tmp_path, random_package, body, monkeypatch):
    run = make_run(tmp_path, random_package, body, Effects(collisions=False), batch=2)
    calls = {"n": 0}
    real = run.deformer.deform

    def flaky(*a, **k):
        calls["n"] += 1
        if calls["n"] == 3:
            raise RuntimeError("killed")
        return real(*a, **k)

    monkeypatch.setattr(run.deformer, "deform", flaky)
    with pytest.raises(RuntimeError):
        run.execute()
    assert not (tmp_path / "out.pc2").exists() and leftovers(tmp_path) == []


def test_inputs_are_validated_before_running(tmp_path, random_package, body):
    d = Deformer(ModelPackage(random_package))
    with pytest.raises(InputError, match="too many shape coefficients"):
        d._betas(np.zeros(11))
    run = make_run(tmp_path, random_package, body, Effects())
    asset = run.load_asset(body.rest_joints()[0])
    with pytest.raises(InputError, match="windows have the wrong shape"):
        d.deform(np.zeros((1536, 24, 8)), asset, np.zeros((2, 3, 72)), body.rest_joints()[0], np.zeros((2, 3)))
    with pytest.raises(InputError, match="joints"):
        d.encode(asset, np.full((24, 3), np.nan))
    assert d.package.created == {}


# ---- packages ---------------------------------------------------------------------------------
def corrupt(tmp_path, random_package, edit):
    p = tmp_path / "pkg"
    shutil.copytree(random_package, p)
    edit(p)
    return p


@pytest.mark.parametrize(
    "edit, words",
    [
        (lambda p: (p / "manifest.json").unlink(), "no manifest.json"),
        (lambda p: (p / "manifest.json").write_text("{not json"), "not valid JSON"),
        (lambda p: _manifest(p, schema_version=99), "schema version"),
        (lambda p: _manifest(p, opset=7), "opset"),
        (lambda p: (p / "deformer_dqs.onnx").unlink(), "file is missing"),
        (lambda p: (p / "deformer_lbs.onnx").write_bytes(b"junk"), "does not match its manifest hash"),
        (lambda p: (p / "weights.bin").write_bytes(b"junk"), "weights file does not match its manifest hash"),
        (lambda p: (p / "weights.bin").unlink(), "the weights file is missing"),
        (
            lambda p: _manifest(p, graphs=dict(_m(p)["graphs"], deformer_lbs_static=_m(p)["graphs"]["deformer_lbs"])),
            "name the same file",
        ),
        (lambda p: _manifest(p, default_deformer="deformer"), "default_deformer is not a deformer graph"),
        (lambda p: _manifest(p, format="something-else"), "not a segadeform model package"),
        (lambda p: _rename_input(p), "disagree with the manifest"),
    ],
)
def test_broken_packages_are_refused(tmp_path, random_package, edit, words):
    p = corrupt(tmp_path, random_package, edit)
    with pytest.raises(PackageError, match=words):
        pkg = ModelPackage(p)
        pkg.session("deformer")


def _m(p):
    return json.loads((p / "manifest.json").read_text())


def _manifest(p, **kw):
    m = json.loads((p / "manifest.json").read_text())
    m.update(kw)
    (p / "manifest.json").write_text(json.dumps(m))


def _rename_input(p):
    m = json.loads((p / "manifest.json").read_text())
    m["graphs"][m["default_deformer"]]["inputs"][3]["name"] = "rest_positions"  # (was "rest")
    (p / "manifest.json").write_text(json.dumps(m))


# ---- CLI ---------------------------------------------------------------------------------------
def test_run_cli_scene_and_flags(tmp_path, random_package):
    out = tmp_path / "skirt.pc2"
    r = CliRunner().invoke(
        cli,
        [
            "run",
            str(SAMPLES / "scenes" / "skirt_walk.toml"),
            "--model",
            str(random_package),
            "-o",
            str(out),
            "--frames",
            "0:12",
            "--no-cache",
        ],
    )
    assert r.exit_code == 0, r.output
    assert "12 frames" in r.output and "ms/frame" in r.output and str(out) in r.output
    assert read_pc2(out).frames.shape == (12, 1536, 3)
    motion = tmp_path / "m.npz"
    make_motion("jump", seconds=0.5).save(motion)
    r = CliRunner().invoke(
        cli,
        [
            "run",
            "--garment",
            str(SKIRT),
            "--motion",
            str(motion),
            "-o",
            str(tmp_path / "seq"),
            "--format",
            "obj-seq",
            "--model",
            str(random_package),
            "--effects",
            "dqs,-collisions",
            "--up",
            "z",
            "--no-cache",
        ],
    )
    assert r.exit_code == 0, r.output
    assert len(list((tmp_path / "seq").glob("*.obj"))) == 15


@pytest.mark.parametrize(
    "args, words",
    [
        (["--garment", "nope.obj", "--motion", "m.npz", "-o", "x.pc2"], "nope.obj"),
        (["--garment", str(SKIRT), "--motion", "m.npz", "-o", "x.pc2", "--effects", "glitter"], "unknown effect"),
        (["--garment", str(SKIRT), "--motion", "m.npz", "-o", "x.pc2", "--frames", "9:3"], "frame range"),
    ],
)
def test_run_cli_errors(tmp_path, random_package, args, words, monkeypatch):
    monkeypatch.chdir(tmp_path)
    make_motion("idle", seconds=0.2).save(tmp_path / "m.npz")
    r = CliRunner().invoke(cli, ["run", *args, "--model", str(random_package)])
    assert r.exit_code != 0 and words in r.output and "Traceback" not in r.output
    assert not (tmp_path / "x.pc2").exists()


def test_info_cli(random_package):
    r = CliRunner().invoke(cli, ["info", str(random_package)])
    assert r.exit_code == 0 and "deformer_dqs_nowrinkles_static" in r.output and "Gather" in r.output


def test_run_works_without_torch(tmp_path, random_package):
    """The runtime and CLI never import torch: run the sample scene with torch made unimportable."""
    code = (
        "import sys\n"
        "class Block:\n"
        "    def find_spec(self, name, path=None, target=None):\n"
        "        if name == 'torch' or name.startswith('torch.'):\n"
        "            raise ImportError('torch is blocked')\n"
        "sys.meta_path.insert(0, Block())\n"
        "from segadeform.cli.main import main\n"
        f"rc = main(['run', {str(SAMPLES / 'scenes' / 'skirt_walk.toml')!r}, '--model', {str(random_package)!r},"
        f" '-o', {str(tmp_path / 'o.pc2')!r}, '--frames', '0:6', '--no-cache'])\n"
        "assert 'torch' not in sys.modules\n"
        "sys.exit(rc)\n"
    )
    p = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert p.returncode == 0, p.stderr + p.stdout
    assert read_pc2(tmp_path / "o.pc2").frames.shape == (6, 1536, 3)


def test_run_writes_alembic(tmp_path, random_package):
    from segadeform.io.alembic import read_alembic_sequence

    r = CliRunner().invoke(
        cli,
        [
            "run",
            str(SAMPLES / "scenes" / "skirt_walk.toml"),
            "--model",
            str(random_package),
            "-o",
            str(tmp_path / "skirt.abc"),
            "--frames",
            "0:4",
            "--no-cache",
        ],
    )
    assert r.exit_code == 0, r.output
    faces, frames, _ = read_alembic_sequence(tmp_path / "skirt.abc")
    assert frames.shape == (4, 1536, 3) and faces.shape == (2944, 3)


def test_encoder_cache_does_not_hide_a_broken_manifest(tmp_path, random_package, body):
    """Regression: a cached P skipped the encoder session, so a manifest renamed since went unnoticed."""
    joints = body.rest_joints()[0]
    asset = make_run(tmp_path, random_package, body, Effects()).load_asset(joints)
    Deformer(ModelPackage(random_package)).encode(asset, joints, cache_dir=tmp_path / "cache")
    broken = corrupt(
        tmp_path,
        random_package,
        lambda p: _manifest(
            p,
            graphs={
                **json.loads((p / "manifest.json").read_text())["graphs"],
                "garment_encoder": {
                    **json.loads((p / "manifest.json").read_text())["graphs"]["garment_encoder"],
                    "inputs": [{"name": "feats", "dtype": "float32", "shape": ["B", "N", 30]}]
                    + json.loads((p / "manifest.json").read_text())["graphs"]["garment_encoder"]["inputs"][1:],
                },
            },
        ),
    )
    with pytest.raises(PackageError, match="disagree with the manifest"):
        Deformer(ModelPackage(broken)).encode(asset, joints, cache_dir=tmp_path / "cache")


def test_big_garments_take_fewer_frames_per_call(tmp_path, random_package, body, monkeypatch):
    """The batch is lowered so a deformer call holds <= MAX_VERTEX_FRAMES vertex-frames (memory); frames are
    the same as with any other batch."""
    from segadeform.runtime import pipeline

    assert [pipeline.effective_batch(8, n) for n in (1000, 4096, 4097, 16000, 64000)] == [8, 8, 7, 2, 1]
    monkeypatch.setattr(pipeline, "MAX_VERTEX_FRAMES", 2 * read_obj(SKIRT).vertices.shape[0])
    calls = []
    real = Deformer.deform

    def spy(self, P, asset, windows, *a, **k):
        calls.append(windows.shape[0])
        return real(self, P, asset, windows, *a, **k)

    monkeypatch.setattr(Deformer, "deform", spy)
    motion = make_motion("walk", seconds=0.3)
    make_run(tmp_path, random_package, body, Effects(collisions=False), motion=motion, batch=8).execute()
    assert max(calls) == 2 and sum(calls) == motion.n_frames
    a = read_pc2(tmp_path / "out.pc2").frames
    monkeypatch.setattr(pipeline, "MAX_VERTEX_FRAMES", 10**9)
    make_run(tmp_path, random_package, body, Effects(collisions=False), motion=motion, batch=8).execute()
    np.testing.assert_allclose(read_pc2(tmp_path / "out.pc2").frames, a, atol=1e-5)


def test_a_training_runs_folder_given_as_a_package_names_export(tmp_path):
    """A user's trial: `run --model runs/tiny` said only "model package has no manifest.json"."""
    from segadeform.runtime import ModelPackage
    from segadeform.runtime.package import PackageError

    (tmp_path / "model.pt").write_bytes(b"")
    with pytest.raises(PackageError, match=r"training run's folder.*segadeform export .*model\.pt -o PACKAGE_DIR`"):
        ModelPackage(tmp_path)


def test_deform_refuses_another_garments_code_and_a_nan_translation(tmp_path, random_package, body):
    """A library user's trial: a code with one row too few reached onnxruntime's own error (and its red log line),
    and a NaN translation made every frame NaN."""
    from segadeform.errors import InputError

    d = Deformer(ModelPackage(random_package), Effects(dynamics=False))
    run = make_run(tmp_path, random_package, body, Effects())
    joints = body.rest_joints()[0]
    asset = run.load_asset(joints)
    P = d.encode(asset, joints)
    w = np.zeros((1, 1, 72), np.float32)
    lw = d.body_log_weights(asset, body) if d.needs_body_weights else None
    with pytest.raises(
        InputError, match=rf"garment code P is not this garment's.*expected finite \({asset.n_vertices}"
    ):
        d.deform(P[:-1], asset, w, joints, np.zeros((1, 3)), log_wbody=lw)
    with pytest.raises(InputError, match="trans must be finite"):
        d.deform(P, asset, w, joints, np.full((1, 3), np.nan), log_wbody=lw)
    assert np.isfinite(d.deform(P, asset, w, joints, np.zeros((1, 3)), log_wbody=lw)).all()
