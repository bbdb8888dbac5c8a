"""Export -> parity -> portability, for random-weight models.

Tolerance: for every output, max |torch - onnxruntime| <= 1e-5 x max |torch| (fp32)."""

import json

import numpy as np
import onnx
import onnxruntime as ort
import pytest
import torch
from click.testing import CliRunner

from segadeform.body import default_rest_joints
from segadeform.cli.main import cli
from segadeform.export import check_portability, export_package
from segadeform.export.package import graph_specs, sample_inputs
from segadeform.export.portability import PortabilityError
from segadeform.export.verify import compare
from segadeform.geometry import precompute_garment
from segadeform.geometry.primitives import cylinder, grid_plane
from segadeform.model import ModelConfig, SEGANet
from segadeform.motion import make_motion, motion_windows
from tests.conftest import made_once

RTOL = 1e-5
# the networks whose graphs are checked: the first three are graphs of the session's random package (conftest's
# random_model: its own deformer and two of its variants, each exported from the network with that config), then a
# network with a drape blend shape, exported here, and one with a heading input
SHARED = {
    "lbs": dict(skinning="lbs", wrinkles=True, dynamics=True),
    "dqs": dict(skinning="dqs", wrinkles=True, dynamics=True),
    "lbs-noblend": dict(skinning="lbs", wrinkles=False, dynamics=True),
}
OWN = {"lbs-drape": dict(skinning="lbs", static_blend=True)}  # the motion-independent blend shape
# the root's rotation relative to the heading: conftest's heading_model (DQS, with the body graphs), which
# tests/runtimes runs in every runtime
VARIANTS = [*SHARED, *OWN, "dqs-heading"]


def _sessions(pkg, files):
    return {g: ort.InferenceSession(str(pkg / f), providers=["CPUExecutionProvider"]) for g, f in files.items()}


@pytest.fixture(scope="module")
def packages(tmp_path_factory, random_model, heading_model):
    """variant -> (frozen torch network, package folder, manifest, {graph role: onnxruntime session})."""
    from segadeform.export.package import _variant_model, deformer_variants

    base, path = random_model
    manifest = json.loads((path / "manifest.json").read_text())
    out = {}
    for name, eff in SHARED.items():
        var = next(v for v in deformer_variants(base.cfg).values() if v["effects"] == eff)
        net = base if var["default"] else _variant_model(base, var["config"])
        files = {"garment_encoder": manifest["graphs"]["garment_encoder"]["file"], "deformer": var["file"]}
        out[name] = (net, path, manifest, _sessions(path, files))
    for name, kw in OWN.items():
        torch.manual_seed(7)
        net = SEGANet(ModelConfig(**kw)).eval()
        with torch.no_grad():  # residual corrections on, so the exported graphs run every path
            net.weight_gate.fill_(0.7)
            net.blend_gate.fill_(0.5)
            if net.cfg.static_blend:
                net.static_gate.fill_(0.3)
        # made once per run (made_once: under pytest-xdist this module's tests run on several workers)
        pkg = made_once(
            tmp_path_factory,
            f"export-{name}",
            lambda p, net=net: export_package(net, p, check=False, variants=False, body=None),
        )
        m = json.loads((pkg / "manifest.json").read_text())
        out[name] = (net.freeze(), pkg, m, _sessions(pkg, {g: s["file"] for g, s in graph_specs(net.cfg).items()}))
    net, pkg = heading_model
    m = json.loads((pkg / "manifest.json").read_text())
    out["dqs-heading"] = (net, pkg, m, _sessions(pkg, {g: s["file"] for g, s in graph_specs(net.cfg).items()}))
    return out


def torch_run(net, graph, feeds):
    spec = graph_specs(net.cfg)[graph]
    fn = net.garment_encoder if graph == "garment_encoder" else net.deformer
    with torch.no_grad():
        r = fn(*(torch.as_tensor(feeds[i["name"]]) for i in spec["inputs"]))
    return r if isinstance(r, tuple) else (r,)


def assert_parity(net, sess, graph, feeds):
    feeds = {i["name"]: feeds[i["name"]] for i in graph_specs(net.cfg)[graph]["inputs"]}  # what the graph takes
    ref = torch_run(net, graph, feeds)
    got = sess.run(None, feeds)
    for r, g in zip(ref, got, strict=True):
        assert g.shape == tuple(r.shape)
        assert np.isfinite(g).all()
        err, rel = compare(r.numpy(), g)
        assert rel <= RTOL, (graph, err, rel)


@pytest.mark.parametrize("variant", VARIANTS)
@pytest.mark.parametrize("n", [3, 37, 1000, 20000])
@pytest.mark.parametrize("b", [1, 2, 5])
def test_parity_random_inputs(packages, variant, n, b):
    net, _, _, sessions = packages[variant]
    k = min(8, n - 1) if n > 3 else 2
    for graph in ("garment_encoder", "deformer"):
        assert_parity(net, sessions[graph], graph, sample_inputs(net.cfg, graph, n=n, k=k, b=b, seed=n * 10 + b))


def garment_inputs(net, v, f, poses, trans):
    joints = default_rest_joints()
    a = precompute_garment(v, f, joints, n_star=net.cfg.n_star)
    nbr, mask = a.nbr.astype(np.int32), a.mask.astype(np.float32)  # the graphs' int32 indices and float mask
    enc = {
        "features": a.features[None],
        "nbr": nbr,
        "mask": mask,
        "descriptor": a.descriptor[None].astype(np.float32),
        "betas": np.zeros((1, 10), np.float32),
    }
    win = motion_windows(poses, net.cfg.window).astype(np.float32)
    b = len(win)
    dec = {
        "window": win,
        "betas": np.zeros((b, 10), np.float32),
        "rest": a.vertices.astype(np.float32),
        "nbr": nbr,
        "mask": mask,
        "joints": np.repeat(joints[None], b, 0).astype(np.float32),
        "trans": trans.astype(np.float32),
    }
    if net.residual:
        w = np.random.default_rng(0).dirichlet(np.full(24, 0.3), size=len(v))
        dec["log_wbody"] = np.log(w + 1e-5).astype(np.float32)
    return enc, dec


def hard_meshes():
    v, f = grid_plane(10, 10)
    degenerate = (np.vstack([v, v[5], [[0.5, 0, 0.5]]]), np.vstack([f, [[5, 100, 6]], [[0, 101, 0]]]))
    v1, f1 = cylinder(12, 6, 0.2, 0.5)
    disconnected = (np.vstack([v1, v1 + [0.6, 0, 0], [[3.0, 3, 3]]]), np.vstack([f1, f1 + len(v1)]))
    return {"degenerate": degenerate, "disconnected": disconnected, "plane": (v + [0, 0.9, 0], f)}


@pytest.mark.parametrize("variant", ["lbs", "dqs"])
@pytest.mark.parametrize("mesh", ["degenerate", "disconnected", "plane"])
def test_parity_on_hard_garments_and_twists(packages, variant, mesh):
    net, _, _, sessions = packages[variant]
    v, f = hard_meshes()[mesh]
    m = make_motion("dance", seconds=0.5, seed=1)
    poses = m.poses[:6].copy()
    poses[2, 3 * 5 : 3 * 5 + 3] = [np.pi, 0, 0]  # 180-degree knee twist
    poses[3, 3 * 16 : 3 * 16 + 3] = [0, 0, np.pi]  # 180-degree shoulder twist
    enc, dec = garment_inputs(net, v, f, poses, m.trans[:6])
    assert_parity(net, sessions["garment_encoder"], "garment_encoder", enc)
    enc_spec = graph_specs(net.cfg)["garment_encoder"]
    code = sessions["garment_encoder"].run(None, {i["name"]: enc[i["name"]] for i in enc_spec["inputs"]})[0][0]
    # the encoder's one output, without its batch axis, is the deformer input of the same name
    assert_parity(net, sessions["deformer"], "deformer", dict(dec, **{enc_spec["outputs"][0]["name"]: code}))


@pytest.mark.parametrize("variant", ["lbs", "dqs-heading"])
def test_manifest_matches_the_graphs(packages, variant):
    """Every graph of a package (the session's random one with every variant; one with a heading input)."""
    net, path, manifest, _ = packages[variant]
    on_disk = json.loads((path / "manifest.json").read_text())
    assert on_disk["schema_version"] == 3 and on_disk["opset"] == 18
    assert ModelConfig.from_dict(on_disk["config"]) == net.cfg
    assert on_disk["units"] == "m" and on_disk["up_axis"] == "y" and len(on_disk["joint_names"]) == 24
    for g, spec in on_disk["graphs"].items():
        proto = onnx.load(str(path / spec["file"]))
        assert [i.name for i in proto.graph.input] == [i["name"] for i in spec["inputs"]]
        assert [o.name for o in proto.graph.output] == [o["name"] for o in spec["outputs"]]
        assert proto.opset_import[0].version == 18
        # N, B and K stay symbolic: nothing was frozen to the export sample sizes (37, 7, 3)
        for i in proto.graph.input:
            shape = [d.dim_param or d.dim_value for d in i.type.tensor_type.shape.dim]
            want = [i2["shape"] for i2 in spec["inputs"] if i2["name"] == i.name][0]
            for got_d, want_d in zip(shape, want, strict=True):
                if isinstance(want_d, str):
                    assert isinstance(got_d, str) and got_d, (g, i.name, shape)
                else:
                    assert got_d == want_d
        check_portability(proto, g)
        assert {i["dtype"] for i in spec["inputs"]} <= {"float32", "int32"}, g
        assert not any(n.op_type in ("Sin", "Cos") for n in proto.graph.node), g  # polynomials (replace_trig)


def test_graph_inputs_are_int32_and_float32_and_older_graphs_are_retyped():
    """Schema 3: no int64 or bool graph input (WebGPU, Sentis); make_inputs_portable retypes an older graph's,
    reading them through a Cast, with the same outputs."""
    from onnx import TensorProto, helper

    from segadeform.export.portability import make_inputs_portable

    nodes = [
        helper.make_node("Gather", ["x", "idx"], ["g"], axis=0),
        helper.make_node("Cast", ["m"], ["mf"], to=TensorProto.FLOAT),
        helper.make_node("Mul", ["g", "mf"], ["y"]),
    ]
    graph = helper.make_graph(
        nodes,
        "g",
        [
            helper.make_tensor_value_info("x", TensorProto.FLOAT, ["n"]),
            helper.make_tensor_value_info("idx", TensorProto.INT64, ["k"]),
            helper.make_tensor_value_info("m", TensorProto.BOOL, ["k"]),
        ],
        [helper.make_tensor_value_info("y", TensorProto.FLOAT, ["k"])],
    )
    model = helper.make_model(graph, opset_imports=[helper.make_opsetid("", 18)])
    with pytest.raises(PortabilityError, match="idx int64, m bool"):
        check_portability(model, "toy")
    x, idx, m = np.arange(5, dtype=np.float32), np.array([4, 0, 2]), np.array([True, False, True])
    ref = ort.InferenceSession(model.SerializeToString()).run(None, {"x": x, "idx": idx, "m": m})[0]
    assert make_inputs_portable(model) == {"idx": "int32", "m": "float32"}
    onnx.checker.check_model(model)
    check_portability(model, "toy")
    got = ort.InferenceSession(model.SerializeToString()).run(
        None, {"x": x, "idx": idx.astype(np.int32), "m": m.astype(np.float32)}
    )[0]
    assert got.tobytes() == ref.tobytes()


def test_sine_and_cosine_polynomials_match_the_builtins():
    """replace_trig: within 2e-7 of float64 sin/cos over many turns and near 0 (WebGPU's builtins: 2^-11)."""
    from onnx import TensorProto, helper

    from segadeform.export.portability import replace_trig

    x = np.concatenate([np.linspace(-40, 40, 400_001), np.linspace(-1e-3, 1e-3, 2001), [0.0, np.pi, -np.pi]])
    for op in ("Sin", "Cos"):
        g = helper.make_graph(
            [helper.make_node(op, ["x"], ["y"])],
            "g",
            [helper.make_tensor_value_info("x", TensorProto.FLOAT, ["n"])],
            [helper.make_tensor_value_info("y", TensorProto.FLOAT, ["n"])],
        )
        model = helper.make_model(g, opset_imports=[helper.make_opsetid("", 18)])
        assert replace_trig(model) == 1 and {n.op_type for n in model.graph.node} <= {"Mul", "Add", "Sub", "Floor"}
        onnx.checker.check_model(model)
        check_portability(model, op)
        y = ort.InferenceSession(model.SerializeToString()).run(None, {"x": x.astype(np.float32)})[0]
        assert np.abs(y - getattr(np, op.lower())(x.astype(np.float32).astype(np.float64))).max() <= 2e-7, op


def test_portability_check_can_fail():
    from onnx import TensorProto, helper

    node = helper.make_node("Einsum", ["a", "b"], ["c"], equation="ij,jk->ik")
    g = helper.make_graph(
        [node],
        "g",
        [
            helper.make_tensor_value_info("a", TensorProto.FLOAT, [2, 2]),
            helper.make_tensor_value_info("b", TensorProto.FLOAT, [2, 2]),
        ],
        [helper.make_tensor_value_info("c", TensorProto.FLOAT, [2, 2])],
    )
    with pytest.raises(PortabilityError, match="Einsum: limited in Unity Sentis"):
        check_portability(helper.make_model(g), "toy")
    lstm = helper.make_node("LSTM", ["x", "w", "r"], ["y"], hidden_size=2)
    g2 = helper.make_graph([lstm], "g", [], [])
    with pytest.raises(PortabilityError, match="LSTM"):
        check_portability(helper.make_model(g2), "toy")
    # a Concat of 24 inputs needs 25 WebGPU storage buffers (the default limit is 8)
    ins = [helper.make_tensor_value_info(f"x{i}", TensorProto.FLOAT, [1]) for i in range(24)]
    cat = helper.make_node("Concat", [f"x{i}" for i in range(24)], ["y"], axis=0)
    g3 = helper.make_graph([cat], "g", ins, [helper.make_tensor_value_info("y", TensorProto.FLOAT, [24])])
    with pytest.raises(PortabilityError, match="more than 8 tensors.*Concat with 25"):
        check_portability(helper.make_model(g3), "toy")


def test_stacks_in_the_model_stay_within_webgpus_buffers():
    """Forward kinematics' 24 joints and the 3x3 matrices are stacked in narrow Concats, with the same values."""
    torch = pytest.importorskip("torch")
    from segadeform.model.kinematics import _matrix3, stack_narrow

    ts = [torch.randn(2, 3) for _ in range(24)]
    assert torch.equal(stack_narrow(ts, 1), torch.stack(ts, 1))
    rows = [[torch.randn(4) for _ in range(3)] for _ in range(3)]
    assert torch.equal(_matrix3(rows), torch.stack([x for r in rows for x in r], -1).reshape(4, 3, 3))


def test_export_cli_random_init_with_check(tmp_path):
    r = CliRunner().invoke(
        cli,
        ["export", "--random-init", "--config", '{"hidden": 16, "heads": 2}', "-o", str(tmp_path / "pkg"), "--check"]
        + ["--no-variants"],  # the model's own deformer only (the variants' parity: tests/model/test_ensemble.py)
    )
    assert r.exit_code == 0, r.output
    assert "4 graphs (default deformer_lbs)" in r.output  # encoder, deformer, the body's two
    assert sorted(p.name for p in (tmp_path / "pkg").glob("*.onnx")) == [
        "body_dqs.onnx",
        "body_lbs.onnx",
        "deformer_lbs.onnx",
        "garment_encoder.onnx",
    ]
    assert "deformer_lbs.vertices: max abs" in r.output and "max rel" in r.output
    rels = [float(line.rsplit("max rel ", 1)[1].split()[0]) for line in r.output.splitlines() if "max rel" in line]
    assert rels and max(rels) <= RTOL
    # a line on stderr as each graph is exported and checked (an export was silent for minutes: an ML user's trial)
    said = [line for line in r.stderr.splitlines() if line.startswith(("exporting", "checking"))]
    assert said[:3] == [
        "exporting garment_encoder (1 of 2)",
        "exporting deformer_lbs (2 of 2)",
        "exporting the body graphs",
    ], r.stderr
    checked = {f"checking {g} against torch" for g in ("garment_encoder", "deformer_lbs", "body_lbs", "body_dqs")}
    assert set(said[3:]) == checked and len(said) == 7, r.stderr
    r = CliRunner().invoke(cli, ["export", "-o", str(tmp_path / "p2")])
    assert r.exit_code == 2 and "CHECKPOINT or --random-init" in r.output
    r = CliRunner().invoke(cli, ["export", str(tmp_path / "missing.pt"), "-o", str(tmp_path / "p3")])
    assert r.exit_code == 1 and "missing.pt" in r.output and not (tmp_path / "p3").exists()


def test_a_second_export_for_the_same_body_writes_the_graphs_it_made(tmp_path, monkeypatch):
    """The body graphs depend on the body's arrays only: a process that exports several packages for one body (the
    suite, an ensemble, checkpoints) exports them once and writes the same bytes again; a body that differs in one
    vertex is exported anew."""
    import dataclasses

    from segadeform.body import default_body_path, load_body
    from segadeform.export import body as body_export

    body = load_body(default_body_path())
    (tmp_path / "a").mkdir()
    first, ops = body_export.export_body_graphs(body, tmp_path / "a", skinnings=("lbs",))

    def no_export(*a, **k):
        raise AssertionError("exported again")

    monkeypatch.setattr(body_export, "_export", no_export)
    (tmp_path / "b").mkdir()
    again, ops_again = body_export.export_body_graphs(body, tmp_path / "b", skinnings=("lbs",))
    assert again == first and ops_again == ops
    assert (tmp_path / "b" / "body_lbs.onnx").read_bytes() == (tmp_path / "a" / "body_lbs.onnx").read_bytes()
    v = body.v_template.copy()
    v[0, 1] += 1e-3
    moved = dataclasses.replace(body, v_template=v)
    (tmp_path / "c").mkdir()
    with pytest.raises(AssertionError, match="exported again"):
        body_export.export_body_graphs(moved, tmp_path / "c", skinnings=("lbs",))
