"""Theorem 2 as a test: the SEGA block's Lipschitz constant stays under Eq. 14's bound,
estimated by power iteration on the Jacobian (JVP then VJP), for random and adversarial inputs.
The PlainGAT block exceeds the bound on some input, so the test can fail."""

import numpy as np
import pytest
import torch

from segadeform.geometry import neighbour_graph
from segadeform.geometry.primitives import fan, frustum
from segadeform.model.lipschitz import ADVERSARIAL_CASES, adversarial_features, lipschitz_estimate
from segadeform.model.sega import SEGABlock, theorem2_bound


def graph(kind):
    if kind == "skirt":
        v, f = frustum(16, 6, 0.2, 0.35, 1.0, 0.5)
    else:  # a valence-64 fan: very irregular degrees
        v, f = fan(64)
    nbr, mask = neighbour_graph(f, len(v), vertices=v, k=64 if kind == "fan" else None)
    return v, torch.as_tensor(nbr), torch.as_tensor(mask)


def inputs(kind, v, rng):
    return adversarial_features(kind, len(v), 30, rng)


CASES = ADVERSARIAL_CASES


@pytest.mark.parametrize("alpha, tau", [(2.0, 2.0), (1.0, 1.0), (3.0, 1.0)])
@pytest.mark.parametrize("g", ["skirt", "fan"])
def test_sega_block_respects_theorem2(alpha, tau, g):
    torch.manual_seed(0)
    v, nbr, mask = graph(g)
    rng = np.random.default_rng(1)
    bound = theorem2_bound(alpha, tau)
    for heads, fp, fs in ((1, 16, 16), (4, 8, 32)):
        block = SEGABlock(30, fp, heads, fs, alpha=alpha, tau=tau).double().eval()
        with torch.no_grad():  # large raw weights: only the tau/alpha scalings keep the block bounded
            for p in block.parameters():
                p.mul_(20.0)
        for case in CASES:
            x = torch.as_tensor(inputs(case, v, rng))[None]
            est = lipschitz_estimate(block, x, nbr, mask)
            assert np.isfinite(est)
            assert est <= bound, (case, heads, est, bound)


def test_plain_gat_exceeds_the_bound():
    torch.manual_seed(0)
    v, nbr, mask = graph("skirt")
    block = SEGABlock(30, 16, 1, 16, use_sega=False).double().eval()
    with torch.no_grad():
        for p in block.parameters():
            p.mul_(20.0)
    x = torch.as_tensor(inputs("random", v, np.random.default_rng(1)))[None]
    est = lipschitz_estimate(block, x, nbr, mask)
    assert est > theorem2_bound(2.0, 2.0), est


def test_the_estimator_finds_a_known_norm():
    """On a linear map the power iteration must return its spectral norm."""
    torch.manual_seed(0)
    w = torch.randn(5, 7, dtype=torch.float64)

    class Lin(torch.nn.Module):
        def forward(self, x, nbr, mask):
            return x @ w.t()

    est = lipschitz_estimate(Lin(), torch.randn(1, 3, 7, dtype=torch.float64), None, None, iters=200)
    assert est == pytest.approx(float(torch.linalg.matrix_norm(w, ord=2)), rel=1e-6)


def test_attention_scores_stay_finite_for_huge_features():
    torch.manual_seed(0)
    v, nbr, mask = graph("skirt")
    block = SEGABlock(30, 16, 4, 16).eval()
    x = torch.full((1, len(v), 30), 3e30)
    x[0, ::2] *= -1
    with torch.no_grad():
        out = block(x, nbr, mask)
    assert torch.isfinite(out).all()


def test_gradients_are_finite_at_zero_and_equal_features():
    """Regression (hard-case catalogue): sqrt at exactly 0 gave NaN derivatives for all-zero features."""
    torch.manual_seed(0)
    v, nbr, mask = graph("skirt")
    block = SEGABlock(30, 8, 4, 16).double()
    for x in (torch.zeros(1, len(v), 30, dtype=torch.float64), torch.ones(1, len(v), 30, dtype=torch.float64)):
        x.requires_grad_(True)
        block(x, nbr, mask).sum().backward()
        assert torch.isfinite(x.grad).all()
        assert all(torch.isfinite(p.grad).all() for p in block.parameters() if p.grad is not None)
