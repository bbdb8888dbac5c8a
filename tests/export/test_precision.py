"""int8 and fp16-weights packages: same interface, valid hashes, output close to fp32, and the CLI."""

from __future__ import annotations

import json

import numpy as np
import pytest

pytest.importorskip("onnx", reason="needs the 'torch' extra")


@pytest.fixture(scope="module")
def body():
    from segadeform.body import load_body

    from ..conftest import SAMPLES

    return load_body(SAMPLES / "bodies" / "default_body.npz")


@pytest.fixture(scope="module")
def skirt_asset(body):
    from segadeform.geometry.precompute import precompute_garment
    from segadeform.io.obj import read_obj

    from ..conftest import SAMPLES

    g = read_obj(SAMPLES / "garments" / "skirt.obj")
    return precompute_garment(g.vertices, g.faces, body.rest_joints(None)[0])


def _deform(pkg_path, garment_asset, body):
    from segadeform.motion import make_motion
    from segadeform.motion.motion import motion_windows
    from segadeform.runtime import ModelPackage
    from segadeform.runtime.deformer import Deformer
    from segadeform.settings import Effects

    d = Deformer(ModelPackage(pkg_path), Effects(collisions=False))
    joints = body.rest_joints(None)[0]
    P = d.encode(garment_asset, joints, np.zeros(10))
    lw = d.body_log_weights(garment_asset, body, np.zeros(10)) if d.needs_body_weights else None
    m = make_motion("walk", seconds=0.3, fps=30)
    win = motion_windows(m.poses, d.window)
    return d.deform(P, garment_asset, win, joints, m.trans, np.zeros(10), log_wbody=lw)


def test_int8_package_runs_close_to_fp32(tmp_path, random_package, body, skirt_asset):
    from segadeform.export.precision import convert_package
    from segadeform.runtime import ModelPackage

    out = convert_package(random_package, tmp_path / "q", "int8")
    m = json.loads((out / "manifest.json").read_text())
    assert m["precision"] == "int8"
    ModelPackage(out, verify_hashes=True)  # every graph's hash matches the rewritten manifest
    a, b = _deform(random_package, skirt_asset, body), _deform(out, skirt_asset, body)
    assert a.shape == b.shape and np.isfinite(b).all()
    disp = np.abs(a - skirt_asset.vertices[None]).max()
    err = np.abs(a - b).max()
    assert 0 < err < 0.1 * max(disp, 1e-3), (err, disp)  # quantised (not a copy), yet close


def test_fp16_weights_package_is_half_the_weights_and_rounds_them_only(tmp_path, random_package, body, skirt_asset):
    import onnx
    from onnx import TensorProto

    from segadeform.export.precision import FP16_MIN_ELEMENTS, convert_package
    from segadeform.runtime import ModelPackage

    out = convert_package(random_package, tmp_path / "h", "fp16-weights")
    m = json.loads((out / "manifest.json").read_text())
    assert m["precision"] == "fp16-weights"
    ModelPackage(out, verify_hashes=True)
    w0, w1 = (json.loads((p / "manifest.json").read_text())["weights"]["bytes"] for p in (random_package, out))
    assert w1 < w0  # the shared weights file is smaller (the learned graphs' weights: half the bytes)
    learned = 0
    for name, spec in m["graphs"].items():
        g = onnx.load(str(out / spec["file"]), load_external_data=True).graph
        for init in g.initializer:  # every big float weight of a learned graph is fp16 now, read through a Cast
            big = int(np.prod(init.dims)) >= FP16_MIN_ELEMENTS
            if "body" in spec:  # the body's own skinning stays float32 (test_body_graphs_stay_float32)
                assert init.data_type != TensorProto.FLOAT16, (name, init.name)
            else:
                assert init.data_type != TensorProto.FLOAT or not big, (name, init.name)
        learned += "body" not in spec
        if name == "garment_encoder":
            assert sum(n.op_type == "Cast" and n.name.endswith("__to_fp32") for n in g.node) >= 4
    assert learned >= 2
    a, b = _deform(random_package, skirt_asset, body), _deform(out, skirt_asset, body)
    disp = np.abs(a - skirt_asset.vertices[None]).max()
    err = np.abs(a - b).max()
    assert 0 < err < 0.02 * max(disp, 1e-3), (err, disp)  # rounded weights: a small, non-zero change


def test_quantize_cli_and_bad_precision(tmp_path, random_package):
    from click.testing import CliRunner

    from segadeform.cli.main import cli
    from segadeform.errors import InputError
    from segadeform.export.precision import convert_package

    r = CliRunner().invoke(cli, ["quantize", str(random_package), "-o", str(tmp_path / "q8")])
    assert r.exit_code == 0, r.output
    assert "int8 package" in r.output and (tmp_path / "q8" / "manifest.json").is_file()
    r = CliRunner().invoke(
        cli, ["quantize", str(random_package), "-o", str(tmp_path / "h"), "--precision", "fp16-weights"]
    )
    assert r.exit_code == 0 and "fp16-weights package" in r.output, r.output
    # a converted package is not converted again (int8 of int8 rounded the rounding): one line, exit 1, nothing written
    from tests.cli.test_output_safety import folder_hash

    before = {src: folder_hash(tmp_path / src) for src in ("q8", "h")}
    for src, precision in (("q8", "int8"), ("q8", "fp16-weights"), ("h", "int8")):
        out = tmp_path / f"again-{src}-{precision}"
        r = CliRunner().invoke(cli, ["quantize", str(tmp_path / src), "-o", str(out), "--precision", precision])
        assert r.exit_code == 1, r.output
        assert f"at precision {'int8' if src == 'q8' else 'fp16-weights'} already" in r.output, r.output
        assert "float32 package it was made from" in r.output and str(tmp_path / src) in r.output
        assert len(r.output.strip().splitlines()) == 1, r.output
        assert not out.exists()
    with pytest.raises(InputError, match="at precision fp16-weights already"):  # fp32 too: not a command's choice
        convert_package(tmp_path / "h", tmp_path / "back", "fp32")
    assert not (tmp_path / "back").exists()
    assert {src: folder_hash(tmp_path / src) for src in ("q8", "h")} == before  # the packages given are untouched
    with pytest.raises(InputError, match="unknown precision"):
        convert_package(random_package, tmp_path / "x", "fp4")
    assert not (tmp_path / "x").exists()


@pytest.mark.parametrize("precision", ["int8", "fp16-weights"])
def test_body_graphs_stay_float32(tmp_path, body, precision):
    """A user's trial: `segadeform quantize` rounded the body graphs too, and the int8 package posed the body up to
    49 mm away from the float package (collisions pushed the garment out of that body).  The body graphs are the
    body's own skinning, not the learned model: they are kept at float32, and pose the body as fp32 does."""
    from segadeform.export.precision import convert_package
    from segadeform.runtime import ModelPackage
    from segadeform.runtime.body import BodyPoser

    from ..conftest import SAMPLES

    src = SAMPLES / "models" / "default"
    out = convert_package(src, tmp_path / precision, precision)
    rng = np.random.default_rng(0)
    poses = rng.normal(0.0, 0.4, (4, 3 * body.n_joints))
    trans = rng.normal(0.0, 0.1, (4, 3))
    betas = np.array([1.0, -0.5])
    for skinning in ("lbs", "dqs"):
        ref = BodyPoser(ModelPackage(src), body, skinning=skinning, backend="graph").pose(poses, betas, trans)
        got = BodyPoser(ModelPackage(out), body, skinning=skinning, backend="graph").pose(poses, betas, trans)
        assert np.abs(got - ref).max() < 1e-6, (skinning, np.abs(got - ref).max())
    # the learned graphs are still converted (int8: quantised nodes; fp16: half-size weights)
    m_src, m_out = (json.loads((p / "manifest.json").read_text()) for p in (src, out))
    assert m_out["precision"] == precision
    assert m_out["graphs"]["deformer_lbs"]["sha256"] != m_src["graphs"]["deformer_lbs"]["sha256"]
