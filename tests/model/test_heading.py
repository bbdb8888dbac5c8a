"""``ModelConfig.motion_input = "heading"``: the motion processors read the root's rotation relative to the current
heading, so the same motion turned about the vertical axis gives the same frames turned with it."""

import numpy as np
import pytest
import torch

from segadeform.body.rotations import matrix_to_axis_angle
from segadeform.errors import InputError
from segadeform.export.package import sample_inputs
from segadeform.model import ModelConfig, SEGANet
from segadeform.model.kinematics import axis_angle_to_matrix, heading_free_window

ARGS = ("g", "window", "betas", "rest", "nbr", "mask", "joints", "trans", "log_wbody")


def _turn_y(deg: float) -> np.ndarray:
    a = np.radians(deg)
    return np.array([[np.cos(a), 0.0, np.sin(a)], [0.0, 1.0, 0.0], [-np.sin(a), 0.0, np.cos(a)]])


def _turned(window: torch.Tensor, q: np.ndarray) -> torch.Tensor:
    """Every frame's root rotation R -> Q R (the whole motion turned about +Y through the world origin)."""
    r = axis_angle_to_matrix(window[..., :3].double()).numpy()
    out = window.clone()
    out[..., :3] = torch.as_tensor(matrix_to_axis_angle(q @ r.reshape(-1, 3, 3)).reshape(r.shape[:-2] + (3,)))
    return out


def test_the_heading_free_window_does_not_change_when_the_motion_turns():
    torch.manual_seed(0)
    w = 0.6 * torch.randn(5, 4, 72)
    ref = heading_free_window(w)
    assert ref.shape == (5, 4, 78)
    assert torch.equal(ref[..., 9:], w[..., 3:])  # the other joints as given
    rel = ref[..., :9].reshape(5, 4, 3, 3)
    assert torch.allclose(rel @ rel.transpose(-1, -2), torch.eye(3).expand(5, 4, 3, 3), atol=1e-5)  # a rotation
    # the current root is left with no turn about +Y (its swing-twist twist is 0): R'_20 = R'_02, R'_00 + R'_22 > 0
    assert torch.allclose(rel[:, 0, 2, 0], rel[:, 0, 0, 2], atol=1e-5)
    assert (rel[:, 0, 0, 0] + rel[:, 0, 2, 2] > 0).all()
    # a pure turn about +Y is taken away whole
    yaw = torch.zeros(1, 2, 72)
    yaw[..., 1] = 1.1
    assert torch.allclose(heading_free_window(yaw)[0, :, :9], torch.eye(3).reshape(9).expand(2, 9), atol=1e-6)
    for deg in (30.0, 90.0, 180.0, -135.0):
        got = heading_free_window(_turned(w, _turn_y(deg)))
        assert (got - ref).abs().max() < 1e-5, deg
    # the raw window does change: what the invariance is measured against
    assert (_turned(w, _turn_y(90.0)) - w)[..., :3].abs().max() > 0.1


def test_lying_on_the_side_is_smooth_and_upside_down_is_bounded():
    """The heading is defined for a body on its side (a quarter turn about +Z), and the window changes little across
    it; it is undefined only upside down (a half turn about +X), where the result stays finite and bounded instead
    of dividing by zero."""
    w = torch.zeros(2, 3, 72)
    w[0, :, 2] = np.pi / 2 - 1e-3
    w[1, :, 2] = np.pi / 2 + 1e-3
    out = heading_free_window(w)
    assert (out[0] - out[1]).abs().max() < 1e-2
    up = torch.zeros(1, 3, 72)
    up[..., 0] = np.pi
    out = heading_free_window(up)
    assert torch.isfinite(out).all() and out.abs().max() <= 1.0 + 1e-6


def _deformer(net, d, window, trans):
    a = dict(d, window=window, trans=trans)
    with torch.no_grad():
        return net.deformer(*(a[k] for k in ARGS))


@pytest.mark.parametrize("skinning", ["lbs", "dqs"])
def test_a_heading_model_turns_its_frames_with_the_motion(skinning):
    """Turning the motion by Q about +Y through the origin (root R -> Q R; the root joint J0 placed at
    Q (J0 + t), i.e. t -> Q (J0 + t) - J0) turns every output vertex by Q: the weights and blend shapes, in the
    garment's rest frame, do not change.  A "pose" model (the paper's input) is not equivariant: the same
    check fails on it."""
    torch.manual_seed(3)
    moved = {}
    for mode in ("heading", "pose"):
        net = SEGANet(ModelConfig(hidden=16, lstm_hidden=16, skinning=skinning, motion_input=mode)).eval()
        with torch.no_grad():  # corrections on, so the motion processors matter
            net.weight_gate.fill_(0.7)
            net.blend_gate.fill_(0.5)
        d = {k: torch.as_tensor(v) for k, v in sample_inputs(net.cfg, "deformer", n=30, k=5, b=4, seed=2).items()}
        v0, w0, b0 = _deformer(net, d, d["window"], d["trans"])
        assert b0.abs().max() > 1e-3  # the blend shapes are on
        worst = 0.0
        for deg in (90.0, 180.0, 37.0):
            q = _turn_y(deg)
            j0 = d["joints"][:, 0].double().numpy()
            t = (d["trans"].double().numpy() + j0) @ q.T - j0
            v1, w1, b1 = _deformer(net, d, _turned(d["window"], q), torch.as_tensor(t, dtype=torch.float32))
            back = v1.double().numpy() @ q  # Q^T v for row vectors
            worst = max(worst, float(np.abs(back - v0.double().numpy()).max()))
            if mode == "heading":
                assert (w1 - w0).abs().max() < 1e-5 and (b1 - b0).abs().max() < 1e-5
        moved[mode] = worst
    assert moved["heading"] < 1e-4 * max(1.0, float(d["rest"].abs().max()))
    assert moved["pose"] > 1e-3


def test_motion_input_is_checked_and_old_configs_read_pose():
    assert ModelConfig.from_dict({"hidden": 32}).motion_input == "pose"
    with pytest.raises(InputError, match="motion_input"):
        ModelConfig(motion_input="world")
    net = SEGANet(ModelConfig(hidden=16, lstm_hidden=16, motion_input="heading"))
    assert net.mo1.lstm.input_size == 78 and net.mo2.lstm.input_size == 78


def test_extreme_root_orientations_give_finite_bounded_frames():
    """The heading is undefined upside down and changes fast near it; a heading model still gives finite frames
    whose weights are a partition of unity and whose vertices stay within the blend-shaped rest's reach of the posed
    joints (no division by a vanishing heading blows up)."""
    torch.manual_seed(4)
    net = SEGANet(ModelConfig(hidden=16, lstm_hidden=16, motion_input="heading")).eval()
    with torch.no_grad():
        net.weight_gate.fill_(0.7)
        net.blend_gate.fill_(0.5)
    d = {k: torch.as_tensor(v) for k, v in sample_inputs(net.cfg, "deformer", n=30, k=5, b=6, seed=5).items()}
    roots = torch.tensor(
        [
            [0.0, 0.0, np.pi / 2],  # on its side
            [0.0, 0.0, -np.pi / 2],
            [np.pi, 0.0, 0.0],  # upside down: no heading
            [np.pi / 2, 0.0, 0.0],  # face down
            [0.0, np.pi, 0.0],  # facing backwards (axis-angle at pi)
            [np.pi - 1e-4, 0.0, 1e-4],  # a hair from upside down
        ],
        dtype=torch.float32,
    )
    w = d["window"].clone()
    w[:, :, :3] = roots[:, None, :]
    w[:, 1::2, :3] = -roots[:, None, :]  # the window flips between frames
    v, weights, blend = _deformer(net, d, w, torch.zeros(6, 3))
    assert torch.isfinite(v).all() and torch.isfinite(weights).all() and torch.isfinite(blend).all()
    assert torch.allclose(weights.sum(-1), torch.ones(6, 30), atol=1e-5) and (weights >= 0).all()
    reach = float((d["rest"] + blend).norm(dim=-1).max() + d["joints"].norm(dim=-1).max() * 4)
    assert float(v.norm(dim=-1).max()) <= reach
