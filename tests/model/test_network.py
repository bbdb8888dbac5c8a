import numpy as np
import pytest
import torch

from segadeform.errors import FileFormatError, InputError
from segadeform.export.package import sample_inputs
from segadeform.model import ModelConfig, SEGANet, load_checkpoint, save_checkpoint


def run(net, n=40, k=6, b=3):
    enc_in = sample_inputs(net.cfg, "garment_encoder", n=n, k=k, b=1)
    dec_in = sample_inputs(net.cfg, "deformer", n=n, k=k, b=b)
    t = {k_: torch.as_tensor(v) for k_, v in {**enc_in, **dec_in}.items()}
    with torch.no_grad():
        g = net.garment_encoder(t["features"], t["nbr"], t["mask"], t["descriptor"])
        return g, net.deformer(
            g[0], t["window"], t["betas"], t["rest"], t["nbr"], t["mask"], t["joints"], t["trans"], t.get("log_wbody")
        )


def test_shapes_and_weights_are_a_partition_of_unity():
    torch.manual_seed(0)
    net = SEGANet(ModelConfig()).eval()
    g, (v, w, b) = run(net)
    assert g.shape == (1, 40, 24)
    assert v.shape == (3, 40, 3) and w.shape == (3, 40, 24) and b.shape == (3, 40, 3)
    assert (w >= 0).all() and torch.allclose(w.sum(-1), torch.ones(3, 40), atol=1e-6)


def test_no_blend_shapes_means_b_is_zero_and_skinning_of_rest():
    torch.manual_seed(0)
    net = SEGANet(ModelConfig(use_blend_shapes=False)).eval()
    _, (v, w, b) = run(net)
    assert (b == 0).all()
    assert net.dec is None and net.mo2 is None


def test_weights_follow_eq16():
    """W~ = softmax_j(sum_i P[k, j, i] f^mo1(Theta)_i), with Eq. 15's P formed by hand (the paper's free weights)."""
    torch.manual_seed(0)
    net = SEGANet(ModelConfig(weights="free")).eval()
    dec_in = {k: torch.as_tensor(v) for k, v in sample_inputs(net.cfg, "deformer", n=20, k=5, b=2).items()}
    with torch.no_grad():
        _, w, _ = net.deformer(*(dec_in[k] for k in ("g", "window", "betas", "rest", "nbr", "mask", "joints", "trans")))
        mo1 = net.mo1(dec_in["window"])
        P = net.target_features(dec_in["g"][None].expand(2, -1, -1), dec_in["betas"])  # (B, N, S, F_enc)
        ref = torch.softmax(torch.einsum("bkji,bi->bkj", P, mo1), dim=-1)
    torch.testing.assert_close(w, ref)


def test_identity_pose_with_zero_blend_keeps_rest_up_to_trans():
    torch.manual_seed(0)
    net = SEGANet(ModelConfig(use_blend_shapes=False)).eval()
    d = {k: torch.as_tensor(v) for k, v in sample_inputs(net.cfg, "deformer", n=20, k=5, b=2).items()}
    d["window"] = torch.zeros_like(d["window"])
    with torch.no_grad():
        v, _, _ = net.deformer(
            *(d[k] for k in ("g", "window", "betas", "rest", "nbr", "mask", "joints", "trans", "log_wbody"))
        )
    torch.testing.assert_close(v, d["rest"][None] + d["trans"][:, None], atol=1e-5, rtol=1e-5)


def test_checkpoint_round_trip(tmp_path):
    torch.manual_seed(0)
    net = SEGANet(ModelConfig(skinning="dqs", hidden=16, heads=2))
    save_checkpoint(tmp_path / "c.pt", net, epoch=3)
    back = load_checkpoint(tmp_path / "c.pt").eval()
    assert back.cfg == net.cfg
    torch.testing.assert_close(run(back)[1][0], run(net.eval())[1][0])


def test_bad_checkpoints_and_configs(tmp_path):
    (tmp_path / "x.pt").write_bytes(b"garbage")
    with pytest.raises(FileFormatError, match=r"not a model checkpoint \(\w+\) \(expected a run's model.pt") as e:
        load_checkpoint(tmp_path / "x.pt")
    assert "\n" not in str(e.value)  # one line, not torch's advice to unpickle it anyway
    run = tmp_path / "run"
    run.mkdir()
    torch.save({"optimizer": {}, "rng": np.zeros(2)}, run / "last.pt")  # a resume state: numpy inside
    with pytest.raises(FileFormatError, match="a training run's resume state"):
        load_checkpoint(run / "last.pt")
    torch.save({"config": {"nope": 1}, "state_dict": {}}, tmp_path / "y.pt")
    with pytest.raises(FileFormatError, match="unknown ModelConfig fields"):
        load_checkpoint(tmp_path / "y.pt")
    with pytest.raises(InputError):
        ModelConfig(hidden=30, heads=4)
    with pytest.raises(InputError):
        ModelConfig(alpha=0)


def test_freeze_keeps_outputs():
    torch.manual_seed(0)
    net = SEGANet(ModelConfig()).eval()
    before = run(net)[1][0]
    net.freeze()
    torch.testing.assert_close(run(net)[1][0], before, atol=1e-5, rtol=1e-5)


def test_factored_decoder_equals_materialised_blend_features():
    """The deformer's factored X^mid = g @ lift gives what the literal Eq. 17 product P * mo2 gives,
    with P formed from Eq. 15 and the decoder run on the (B, N, S F_enc) features."""
    torch.manual_seed(0)
    net = SEGANet(ModelConfig(weights="free")).eval()
    d = {k: torch.as_tensor(v) for k, v in sample_inputs(net.cfg, "deformer", n=30, k=5, b=3).items()}
    with torch.no_grad():
        _, _, factored = net.deformer(
            *(d[k] for k in ("g", "window", "betas", "rest", "nbr", "mask", "joints", "trans"))
        )
        mo2 = net.mo2(d["window"], d["betas"])
        P = net.target_features(d["g"][None].expand(3, -1, -1), d["betas"]).reshape(3, 30, -1)
        literal = net.dec.out(_decoder_blocks(net, P * mo2[:, None, :], d))
    torch.testing.assert_close(factored, literal, atol=1e-5, rtol=1e-5)


def _decoder_blocks(net, x, d):
    """The decoder's blocks on materialised features, each by its slow reference forward."""
    from segadeform.model.modules import elu

    for blk in net.dec.blocks:
        x = elu(blk.forward_reference(x, d["nbr"], d["mask"]))
    return x


def test_mean_body_shape_does_not_zero_the_features():
    """Regression: zero-initialised biases made f^bp(0) = 0, so P = 0 for the mean body."""
    torch.manual_seed(0)
    net = SEGANet(ModelConfig()).eval()
    enc = {k: torch.as_tensor(v) for k, v in sample_inputs(net.cfg, "garment_encoder", n=20, k=5, b=1).items()}
    with torch.no_grad():
        P = net.target_features(net.garment_encoder(**enc), torch.zeros(1, 10))
    assert P.abs().max() > 1e-3


# ---- residual skinning weights ----------------------------------------------------------------------
def test_untrained_residual_model_is_lbs_with_the_body_weights():
    """With the gates at their initial 0, the weights are the body's (softmax(log(w + eps)) = w up to S eps)
    and the garment is the LBS of its rest shape with them: no blend shapes."""
    from segadeform.body import default_body_path, load_body
    from segadeform.body.transfer import RESIDUAL_EPS, residual_log_weights, skin_garment, transfer_weights
    from segadeform.garments import make_garment
    from segadeform.motion import make_motion, motion_windows

    torch.manual_seed(0)
    body = load_body(default_body_path())
    g = make_garment("tank", body)
    wb = transfer_weights(g.vertices, body.shaped_vertices()[0], body.faces, body.weights)
    net = SEGANet(ModelConfig()).eval()
    assert net.residual and net.weight_gate.item() == 0.0 and net.blend_gate.item() == 0.0
    m = make_motion("dance", seconds=0.3)
    J = body.rest_joints()[0]
    from segadeform.geometry import precompute_garment

    a = precompute_garment(g.vertices, g.faces, J)
    from segadeform.geometry.features import vertex_features

    f32 = lambda x: torch.as_tensor(np.asarray(x, np.float32))  # noqa: E731
    feats = vertex_features(a.vertices, a.faces, J, normals=a.normals.astype(np.float64))
    win = motion_windows(m.poses, net.cfg.window)
    n = len(win)
    with torch.no_grad():
        v, w, b = net(
            f32(feats)[None],
            torch.as_tensor(a.nbr),
            torch.as_tensor(a.mask),
            f32(a.descriptor)[None],
            torch.zeros(n, 10),
            f32(win),
            f32(a.vertices),
            f32(J)[None].expand(n, -1, -1),
            f32(m.trans),
            f32(residual_log_weights(wb)),
        )
    assert (b == 0).all()
    assert np.abs(w.numpy() - wb[None]).max() < 24 * RESIDUAL_EPS
    ref = skin_garment(a.vertices, wb, body, m.poses, None, m.trans)
    assert np.abs(v.numpy() - ref).max() < 1e-4


def test_residual_gates_learn_and_old_configs_load_free():
    net = SEGANet(ModelConfig()).train()
    d = {k: torch.as_tensor(v) for k, v in sample_inputs(net.cfg, "deformer", n=20, k=5, b=2).items()}
    v, w, b = net.deformer(
        *(d[k] for k in ("g", "window", "betas", "rest", "nbr", "mask", "joints", "trans", "log_wbody"))
    )
    (v.sum() + w.pow(2).sum()).backward()
    assert net.weight_gate.grad.abs() > 0 and net.blend_gate.grad.abs() > 0
    assert ModelConfig.from_dict({"hidden": 32}).weights == "free"
    with pytest.raises(InputError, match="needs log_wbody"):
        net.deformer(*(d[k] for k in ("g", "window", "betas", "rest", "nbr", "mask", "joints", "trans")))


def test_static_blend_is_one_drape_for_every_frame_gated_from_zero_and_absent_from_old_configs():
    """``static_blend``: B gains f^s([g, T]), the same (N, 3) for every frame and every motion window, added
    before skinning; residual models start with its gate at 0 (exactly the model without it), the gate learns,
    and configs saved before the field have none."""
    torch.manual_seed(0)
    cfg = ModelConfig(hidden=16, lstm_hidden=16, static_blend=True)
    net = SEGANet(cfg).eval()
    assert net.static_gate.item() == 0.0
    plain = SEGANet(cfg.replace(static_blend=False)).eval()
    plain.load_state_dict({k: v for k, v in net.state_dict().items() if not k.startswith("static")})
    _, (v0, _, b0) = run(net)
    _, (v1, _, b1) = run(plain)
    assert torch.equal(b0, b1) and torch.allclose(v0, v1, atol=1e-6)  # gate 0: the model without the drape
    with torch.no_grad():
        net.static_gate.fill_(0.5)
    d = {k: torch.as_tensor(x) for k, x in sample_inputs(cfg, "deformer", n=20, k=5, b=3).items()}
    args = [d[k] for k in ("g", "window", "betas", "rest", "nbr", "mask", "joints", "trans", "log_wbody")]
    with torch.no_grad():
        _, _, b_on = net.deformer(*args)
        net.static_gate.zero_()
        _, _, b_off = net.deformer(*args)
        args[1] = torch.randn_like(args[1])  # another motion window: the drape is the same
        net.static_gate.fill_(0.5)
        _, _, b_on2 = net.deformer(*args)
        net.static_gate.zero_()
        _, _, b_off2 = net.deformer(*args)
        drape = 0.5 * net.static(torch.cat([args[0], args[3]], dim=-1))
    assert drape.abs().max() > 1e-4
    for on, off in ((b_on, b_off), (b_on2, b_off2)):
        assert torch.allclose(on - off, drape.expand_as(on), atol=1e-6)
    net.train()
    v, _, _ = net.deformer(*args)
    v.sum().backward()
    assert net.static_gate.grad.abs() > 0
    assert ModelConfig.from_dict({"hidden": 32}).static_blend is False
    with pytest.raises(InputError, match="static_blend"):
        ModelConfig(static_blend=1)


def test_history_encoder_is_the_window_lstm_stepped_in_time_order():
    """HistoryEncoder.forward's last state over a sequence = UnrolledLSTM (the window's LSTM, current frame
    first) over the same frames reversed, with the same weights; every state = stepping one frame at a time."""
    from segadeform.model.modules import HistoryEncoder, UnrolledLSTM

    torch.manual_seed(0)
    enc = HistoryEncoder(7, 5)
    win = UnrolledLSTM(7, 5)
    win.load_state_dict(enc.cell.state_dict())
    x = torch.randn(3, 11, 7)
    with torch.no_grad():
        hs = enc(x)
        torch.testing.assert_close(hs[:, -1], win(x.flip(1)))
        h = c = torch.zeros(3, 5)
        for t in range(11):
            h, c = enc.step(x[:, t], h, c)
            torch.testing.assert_close(hs[:, t], h)


def test_a_history_model_starts_as_its_prior_and_its_state_changes_the_frames_once_trained():
    """ModelConfig.history: the residual gates at 0 make the state irrelevant (the model is its prior); with
    the gates open another history gives other frames; the history is an input exactly when the model has one,
    and configs saved before the field have none."""
    torch.manual_seed(0)
    cfg = ModelConfig(hidden=16, lstm_hidden=16, history=6)
    net = SEGANet(cfg).eval()
    d = {k: torch.as_tensor(v) for k, v in sample_inputs(cfg, "deformer", n=20, k=5, b=2).items()}
    args = [d[k] for k in ("g", "window", "betas", "rest", "nbr", "mask", "joints", "trans", "log_wbody")]
    h1, h2 = torch.zeros(2, 6), torch.randn(2, 6)
    with torch.no_grad():
        v1, _, _ = net.deformer(*args, h1)
        v2, _, _ = net.deformer(*args, h2)
        assert torch.equal(v1, v2)
        net.weight_gate.fill_(1.0)
        net.blend_gate.fill_(1.0)
        v1, w1, _ = net.deformer(*args, h1)
        v2, w2, _ = net.deformer(*args, h2)
    assert not torch.allclose(v1, v2) and not torch.allclose(w1, w2)
    with pytest.raises(InputError, match="history"):
        net.deformer(*args)
    with pytest.raises(InputError, match="history"):
        SEGANet(cfg.replace(history=0)).deformer(*args, h1)
    with pytest.raises(InputError, match="history"):
        ModelConfig(history=-1)
    assert ModelConfig.from_dict({"hidden": 32}).history == 0
    states = net.history_states(torch.randn(1, 9, 75))
    assert states.shape == (1, 9, 6) and torch.isfinite(states).all()


def test_a_history_model_does_not_export_until_the_package_has_its_graph(tmp_path):
    from segadeform.export.package import export_package

    with pytest.raises(InputError, match="motion-history"):
        export_package(SEGANet(ModelConfig(hidden=16, lstm_hidden=16, history=4)), tmp_path / "pkg")
