"""The SEGA block's fast (slot-major) forward against its slow, obvious reference."""

import numpy as np
import pytest
import torch

from segadeform.geometry import neighbour_graph
from segadeform.geometry.primitives import fan, frustum
from segadeform.model.lipschitz import ADVERSARIAL_CASES, adversarial_features
from segadeform.model.sega import SEGABlock


def _graph(kind):
    v, f = frustum(16, 6, 0.2, 0.35, 1.0, 0.5) if kind == "skirt" else fan(40)
    nbr, mask = neighbour_graph(f, len(v), vertices=v, k=40 if kind == "fan" else None)
    return len(v), torch.as_tensor(nbr), torch.as_tensor(mask)


def _block(use_sega, heads=4, fp=8, fs=16, alpha=2.0, tau=2.0, fin=30):
    torch.manual_seed(0)
    blk = SEGABlock(fin, fp, heads, fs, alpha=alpha, tau=tau, use_sega=use_sega).double().eval()
    with torch.no_grad():
        for p in blk.parameters():
            p.mul_(5.0)
    return blk


@pytest.mark.parametrize("g", ["skirt", "fan"])
@pytest.mark.parametrize("use_sega", [True, False])
@pytest.mark.parametrize("case", ADVERSARIAL_CASES)
def test_fast_forward_equals_reference(g, use_sega, case):
    n, nbr, mask = _graph(g)
    rng = np.random.default_rng(3)
    x = torch.as_tensor(np.stack([adversarial_features(case, n, 30, rng) for _ in range(2)]))
    for heads, fs in ((4, 16), (1, 0)):
        blk = _block(use_sega, heads=heads, fs=fs)
        with torch.no_grad():
            fast, ref = blk(x, nbr, mask), blk.forward_reference(x, nbr, mask)
        assert fast.shape == ref.shape == (2, n, blk.out_features)
        scale = max(1.0, float(ref.abs().max()))
        assert float((fast - ref).abs().max()) <= 1e-9 * scale, (case, heads)


def test_fast_forward_equals_reference_with_a_lifted_input_and_gradients():
    n, nbr, mask = _graph("skirt")
    blk = _block(True)  # eval: the power-iteration state must not change between the two calls
    x = torch.randn(n, 7, dtype=torch.float64, requires_grad=True)
    lift = torch.randn(3, 7, 30, dtype=torch.float64)
    outs, grads = [], []
    for fn in (blk.forward, blk.forward_reference):
        x.grad = None
        y = fn(x, nbr, mask, lift=lift)
        (y * torch.linspace(-1, 1, y.numel(), dtype=y.dtype).reshape(y.shape)).sum().backward()
        outs.append(y.detach())
        grads.append(x.grad.clone())
    assert torch.allclose(outs[0], outs[1], atol=1e-10, rtol=1e-9)
    assert torch.allclose(grads[0], grads[1], atol=1e-9, rtol=1e-7)


def test_a_vertex_without_neighbours_gets_no_attention_term():
    """All-padding rows: the reference's masked softmax gives zeros; so must the fast path."""
    n, nbr, mask = _graph("skirt")
    mask = mask.clone()
    mask[5] = False
    blk = _block(True)
    x = torch.randn(1, n, 30, dtype=torch.float64)
    with torch.no_grad():
        fast, ref = blk(x, nbr, mask), blk.forward_reference(x, nbr, mask)
    assert torch.allclose(fast, ref, atol=1e-12)
    assert torch.all(fast[0, 5, : blk.heads * blk.head_features] == 0)


def test_fast_forward_is_finite_for_huge_and_tiny_float32_features():
    n, nbr, mask = _graph("skirt")
    blk = SEGABlock(30, 8, 4, 16).eval()
    for value in (3e30, 1e-30):
        x = torch.full((1, n, 30), value)
        x[0, ::2] *= -1
        with torch.no_grad():
            fast, ref = blk(x, nbr, mask), blk.forward_reference(x, nbr, mask)
        assert torch.isfinite(fast).all()
        assert torch.allclose(fast, ref, rtol=1e-4, atol=1e-6 * float(ref.abs().max())), value
