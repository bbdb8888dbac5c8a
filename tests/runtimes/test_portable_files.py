"""What the runtimes without Python read, made and checked in Python: the garment asset prepared for a body shape
(schema 2; schema 1 still read), the motion file (.sgdm), and the package's body graphs (the body posed as ONNX,
held to segadeform.body's numpy body)."""

from __future__ import annotations

import dataclasses
import json

import numpy as np
import onnxruntime as ort
import pytest

from segadeform.body import default_body_path, load_body
from segadeform.body.identity import body_sha256
from segadeform.body.prepare import prepare_for_body
from segadeform.errors import FileFormatError, InputError
from segadeform.geometry import GarmentAsset, precompute_garment
from segadeform.io import read_mesh
from segadeform.io.sgdb import read_bundle, write_bundle
from segadeform.motion import read_motion_file, write_motion_file
from tests.conftest import SAMPLES

RTOL = 1e-5


@pytest.fixture(scope="module")
def body():
    return load_body(default_body_path())


@pytest.fixture(scope="module")
def skirt(body):
    m = read_mesh(SAMPLES / "garments" / "skirt.obj")
    return precompute_garment(m.vertices, m.faces, body.rest_joints()[0], n_star=32, source_name="skirt.obj")


def test_asset_for_a_body_holds_what_segadeform_run_computes(skirt, body, random_package):
    """features, joints and log_wbody of an asset prepared for betas are the Python runtime's own inputs."""
    from segadeform.geometry.features import vertex_features
    from segadeform.runtime import Deformer, ModelPackage
    from segadeform.settings import Effects

    betas = (0.7, -0.4, 0.2)
    a = prepare_for_body(skirt, body, betas)
    assert a.for_a_body and not skirt.for_a_body and a.body["sha256"] == body_sha256(body)
    assert a.body["weight_prior"] == d_prior(random_package) == "nearest"
    assert a.betas.shape == (body.n_betas,) and a.betas[:3].tolist() == list(betas)
    joints = body.rest_joints(betas)[0]
    np.testing.assert_array_equal(a.joints, joints)
    np.testing.assert_array_equal(
        a.features, vertex_features(a.vertices, a.faces, joints, normals=a.normals.astype(np.float64))
    )
    d = Deformer(ModelPackage(random_package), Effects())
    np.testing.assert_array_equal(a.log_wbody, d.body_log_weights(skirt, body, betas).astype(np.float32))
    np.testing.assert_array_equal(a.nbr, skirt.nbr)  # what does not depend on the body is kept
    with pytest.raises(InputError, match="at most the body's count"):
        prepare_for_body(skirt, body, np.zeros(body.n_betas + 1))
    # models trained with the inpainted prior get it (the model's config.weight_prior; garment export --model)
    from segadeform.body.transfer import garment_weights, residual_log_weights

    ip = prepare_for_body(skirt, body, betas, weight_prior="inpaint")
    assert ip.body["weight_prior"] == "inpaint"
    want = residual_log_weights(
        garment_weights(
            skirt.vertices, skirt.faces, body, np.pad(betas, (0, body.n_betas - 3)).astype(np.float32), "inpaint"
        )
    )
    np.testing.assert_array_equal(ip.log_wbody, want.astype(np.float32))


def d_prior(package) -> str:
    from segadeform.runtime import Deformer, ModelPackage

    return Deformer(ModelPackage(package)).weight_prior


@pytest.mark.parametrize("suffix", [".sgda", ".npz"])
def test_asset_schema_2_round_trip_and_schema_1_still_read(skirt, body, tmp_path, suffix):
    a = prepare_for_body(skirt, body, (0.5,))
    b = GarmentAsset.load(a.save(tmp_path / f"a{suffix}"))
    for k in ("vertices", "faces", "features", "nbr", "mask", "joints", "descriptor", "betas", "log_wbody"):
        np.testing.assert_array_equal(getattr(a, k), getattr(b, k), err_msg=k)
    assert b.body == a.body and b.for_a_body
    assert not GarmentAsset.load(skirt.save(tmp_path / f"plain{suffix}")).for_a_body
    # a schema-1 file (written before assets could be prepared for a body) still loads
    if suffix == ".sgda":
        arrays, meta = read_bundle(tmp_path / "plain.sgda")
        write_bundle(tmp_path / "v1.sgda", dict(arrays), dict(meta, schema_version=1))
    else:
        z = dict(np.load(tmp_path / "plain.npz", allow_pickle=False))
        z["schema_version"] = np.int64(1)
        with open(tmp_path / "v1.npz", "wb") as fh:
            np.savez(fh, **z)
    old = GarmentAsset.load(tmp_path / f"v1{suffix}")
    np.testing.assert_array_equal(old.features, skirt.features)
    with pytest.raises(InputError, match="betas, log_wbody and body together"):
        dataclasses.replace(a, log_wbody=None).validate()


def test_motion_file_round_trip_and_errors(tmp_path):
    from segadeform.motion import make_motion

    m = make_motion("walk", seconds=0.3, fps=30, seed=1)
    write_motion_file(tmp_path / "m.sgdm", m, body={"name": "b.npz", "sha256": "a" * 64}, betas=[0.5])
    got, meta = read_motion_file(tmp_path / "m.sgdm")
    arrays, _ = read_bundle(tmp_path / "m.sgdm")
    assert arrays["poses"].shape == (m.n_frames, 24, 3) and arrays["poses"].dtype == np.float32
    np.testing.assert_array_equal(got.poses, m.poses.astype(np.float32))  # what the graphs take
    np.testing.assert_array_equal(got.trans, m.trans.astype(np.float32))
    assert got.fps == 30 and meta["kind"] == "segadeform-motion" and meta["betas"] == [0.5]
    assert meta["joint_names"][0] == "pelvis" and len(meta["joint_names"]) == 24
    write_bundle(tmp_path / "x.sgdm", {"poses": arrays["poses"]}, dict(meta))
    with pytest.raises(FileFormatError, match="trans must be f32"):
        read_motion_file(tmp_path / "x.sgdm")
    write_bundle(tmp_path / "k.sgdm", dict(arrays), dict(meta, kind="segadeform-garment-asset"))
    with pytest.raises(FileFormatError, match="not a motion file"):
        read_motion_file(tmp_path / "k.sgdm")
    for start in (1e300, 2.5, "ten"):  # 1e300 was a traceback in the PC2 writer (a user's trial)
        write_bundle(tmp_path / "s.sgdm", dict(arrays), dict(meta, start_frame=start))
        with pytest.raises(FileFormatError, match=r"s\.sgdm: meta\.start_frame must be a frame number"):
            read_motion_file(tmp_path / "s.sgdm")


def test_motion_export_is_what_run_plays(tmp_path, body):
    """`segadeform motion export` of a BVH onto a body shape: the motion `segadeform run` builds for that body."""
    from segadeform.cli.main import main
    from segadeform.motion import MotionSpec, build_motion

    bvh = SAMPLES / "motions" / "cmu" / "02_01_walk.bvh"
    assert (
        main(
            [
                "motion",
                "export",
                str(bvh),
                "--betas",
                "0.3",
                "--fps",
                "30",
                "--frames",
                "0:40",
                "-o",
                str(tmp_path / "w.sgdm"),
            ]
        )
        == 0
    )
    got, meta = read_motion_file(tmp_path / "w.sgdm")
    want = build_motion(MotionSpec(file=bvh, fps=30.0), body.rest_joints((0.3,))[0])
    np.testing.assert_array_equal(got.poses, want.poses[:40].astype(np.float32))
    np.testing.assert_array_equal(got.trans, want.trans[:40].astype(np.float32))
    assert meta["body"]["sha256"] == body_sha256(body) and meta["betas"][0] == 0.3
    assert main(["motion", "export", "nonsense", "-o", str(tmp_path / "n.sgdm")]) == 1
    assert main(["motion", "export", "walk", "-o", str(tmp_path / "n.npz")]) == 2
    assert not (tmp_path / "n.sgdm").exists()


def _body_feeds(body, b, seed):
    from segadeform.export.body import body_sample_inputs

    x = body_sample_inputs(body, b=b, seed=seed)
    x["poses"][0] = 0.0  # the rest pose: Rodrigues' series branch
    x["poses"][-1, 5] = [np.pi, 0.0, 0.0]  # a half-turn knee, and a joint past it
    x["poses"][-1, 16] = [0.0, 0.0, 4.0]
    return x


@pytest.mark.parametrize("skinning", ["lbs", "dqs"])
def test_body_graph_poses_the_body_like_segadeform_body(random_package, body, skinning):
    """The package's body graph (onnxruntime) against BodyModel.forward (numpy, float64): vertices, joints, rest
    joints within 1e-5 relative; the triangles are the body's."""
    m = json.loads((random_package / "manifest.json").read_text())
    spec = m["graphs"][f"body_{skinning}"]
    assert spec["role"] == "body" and spec["skinning"] == skinning and spec["body"]["sha256"] == body_sha256(body)
    sess = ort.InferenceSession(str(random_package / spec["file"]), providers=["CPUExecutionProvider"])
    for b, seed in ((1, 0), (5, 1)):
        x = _body_feeds(body, b, seed)
        v, j, rj, f = sess.run(None, x)
        ref = body.forward(
            x["poses"].reshape(b, -1).astype(np.float64),
            x["betas"].astype(np.float64),
            x["trans"].astype(np.float64),
            skinning=skinning,
        )
        for got, want in ((v, ref.vertices), (j, ref.joints), (rj, body.rest_joints(x["betas"].astype(np.float64))[0])):
            assert got.shape == want.shape and np.abs(got - want).max() <= RTOL * np.abs(want).max()
        np.testing.assert_array_equal(f, body.faces)


def test_export_body_gives_a_package_another_body(random_package, body, tmp_path):
    """`segadeform export-body BODY -o PKG --to NEW`: the body graphs of another body, the rest unchanged."""
    from segadeform.cli.main import main
    from segadeform.runtime import ModelPackage

    other = dataclasses.replace(body, v_template=body.v_template * 1.1, path=str(tmp_path / "tall.npz"))
    other.save(tmp_path / "tall.npz")
    args = ["export-body", str(tmp_path / "tall.npz"), "-o", str(random_package), "--to", str(tmp_path / "pkg")]
    # the body graphs record the model's body: another is refused without --force, nothing written (a review)
    assert ModelPackage(random_package).spec("body_lbs")["body"]["sha256"] == body_sha256(body)
    assert main(args) == 1 and not (tmp_path / "pkg").exists()
    assert main([*args, "--force"]) == 0
    old, new = ModelPackage(random_package), ModelPackage(tmp_path / "pkg")
    tall = load_body(tmp_path / "tall.npz")
    assert new.spec("body_lbs")["body"] == {"name": "tall.npz", "sha256": body_sha256(tall)}
    assert set(new.manifest["graphs"]) == set(old.manifest["graphs"])
    x = _body_feeds(tall, 2, 3)
    v = new.run("body_lbs", x)[0]
    ref = tall.forward(
        x["poses"].reshape(2, -1).astype(np.float64), x["betas"].astype(np.float64), x["trans"].astype(np.float64)
    ).vertices
    assert np.abs(v - ref).max() <= RTOL * np.abs(ref).max()
    from segadeform.export.package import sample_inputs
    from segadeform.model import ModelConfig

    cfg = ModelConfig.from_dict(old.config)
    for name in ("garment_encoder", "deformer_dqs_static"):  # the model's graphs compute what they did
        x = sample_inputs(cfg.replace(window=old.spec(name).get("window", cfg.window)), name, n=40, k=5, b=2)
        assert all(a.tobytes() == b.tobytes() for a, b in zip(old.run(name, x), new.run(name, x), strict=True)), name
    assert main(["export-body", "-o", str(tmp_path)]) == 1  # not a package


def test_export_body_force_leaves_the_record_of_the_training_body(random_package, body, tmp_path):
    """The body graphs were the only record of the model's body, and `export-body --force` replaced it: a run on the
    forced body was then taken without a word, and export-body gave the training body back only with --force.  The
    manifest's ``training_body`` (export writes it from the checkpoint) stays: runs on another body are refused
    unless forced, and export-body gives the training body's graphs back without --force."""
    import json
    import shutil

    from segadeform.cli.main import main
    from segadeform.errors import InputError
    from segadeform.runtime import ModelPackage
    from segadeform.runtime.body import package_body
    from segadeform.runtime.pipeline import check_package_body

    pkg = tmp_path / "trained"
    shutil.copytree(random_package, pkg)
    m = json.loads((pkg / "manifest.json").read_text())
    label = {"name": "default_body.npz", "sha256": body_sha256(body)}
    (pkg / "manifest.json").write_text(json.dumps({**m, "training_body": label}, indent=2, sort_keys=True) + "\n")
    other = dataclasses.replace(body, v_template=body.v_template * 1.1, path=str(tmp_path / "tall.npz"))
    other.save(tmp_path / "tall.npz")
    tall = load_body(tmp_path / "tall.npz")
    assert main(["export-body", str(tmp_path / "tall.npz"), "-o", str(pkg), "--to", str(tmp_path / "t")]) == 1
    assert (
        main(["export-body", str(tmp_path / "tall.npz"), "-o", str(pkg), "--to", str(tmp_path / "t"), "--force"]) == 0
    )
    forced = ModelPackage(tmp_path / "t")
    assert forced.spec("body_lbs")["body"]["sha256"] == body_sha256(tall)  # the graphs pose the body given
    assert forced.manifest["training_body"] == label and package_body(forced) == label
    with pytest.raises(InputError, match="made for another body than the run's"):
        check_package_body(forced, tall)
    check_package_body(forced, tall, force=True)
    check_package_body(forced, body)
    back = tmp_path / "back"  # the training body's graphs back, without --force
    assert main(["export-body", str(body.path), "-o", str(tmp_path / "t"), "--to", str(back)]) == 0
    assert ModelPackage(back).spec("body_lbs")["body"]["sha256"] == body_sha256(body)


def test_segadeform_reads_the_motion_file_it_exports(tmp_path, capsys):
    """`segadeform run --motion M.sgdm` (scenes' motion.file too) and `segadeform inspect M.sgdm` read the motion
    file as the runtimes without Python do: its frames as they are (no retargeting, y-up); units, joint maps and a
    z-up axis are refused."""
    from segadeform.cli.main import main
    from segadeform.motion import MotionSpec, build_motion, load_motion

    assert main(["motion", "export", "walk", "--seconds", "0.3", "--betas", "0.4", "-o", str(tmp_path / "w.sgdm")]) == 0
    want, meta = read_motion_file(tmp_path / "w.sgdm")
    for got in (
        load_motion(tmp_path / "w.sgdm"),
        build_motion(MotionSpec(file=tmp_path / "w.sgdm"), np.zeros((24, 3))),
    ):
        np.testing.assert_array_equal(got.poses, want.poses)
        np.testing.assert_array_equal(got.trans, want.trans)
        assert got.fps == want.fps == 30
    for kw, words in (
        ({"units": "cm"}, "units"),
        ({"joint_map": {"pelvis": "Hips"}}, "joint map"),
        ({"up": "z"}, "up z"),
    ):
        with pytest.raises(FileFormatError, match="already retargeted") as e:
            load_motion(tmp_path / "w.sgdm", **kw)
        assert words in str(e.value)
    capsys.readouterr()
    assert main(["inspect", str(tmp_path / "w.sgdm")]) == 0
    out = capsys.readouterr().out
    assert f"motion file, {want.n_frames} frames at 30 fps, 24 joints, made for body {meta['body']['name']}" in out
    assert "betas [0.4]" in out and "root translation" in out
    (tmp_path / "bad.sgdm").write_bytes(b"hello")
    assert main(["inspect", str(tmp_path / "bad.sgdm")]) == 1
    assert "not a segadeform bundle" in capsys.readouterr().err


def test_motion_export_of_a_window_says_it_starts_afresh(tmp_path, capsys):
    """A window cut by `motion export --frames A:B` has nothing before A, so its frames played are not
    `run --frames A:B`'s (which looks back before A): said when the file is made, not when it starts at 0
    (a user's trial took the two for the same)."""
    from segadeform.cli.main import main

    args = ["motion", "export", "walk", "--seconds", "0.5", "-o"]
    assert main([*args, str(tmp_path / "a.sgdm"), "--frames", "5:12"]) == 0
    err = capsys.readouterr().err
    assert "starts at frame 5 with no motion before it" in err and "run --frames 5:" in err, err
    assert main([*args, str(tmp_path / "b.sgdm"), "--frames", "0:12"]) == 0
    assert main([*args, str(tmp_path / "c.sgdm")]) == 0
    assert "no motion before it" not in capsys.readouterr().err
    _, meta = read_motion_file(tmp_path / "a.sgdm")
    assert meta["start_frame"] == 5
