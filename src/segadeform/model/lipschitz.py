"""Empirical Lipschitz constants of graph blocks (Theorem 2 checks, diagnostics)."""

from __future__ import annotations

import numpy as np
import torch

__all__ = ["lipschitz_estimate", "ADVERSARIAL_CASES", "adversarial_features"]

ADVERSARIAL_CASES = ("random", "large", "near_duplicate", "all_equal", "tiny")


def lipschitz_estimate(block, x, nbr, mask, iters: int = 50, seed: int = 0) -> float:
    """Largest singular value of ``block``'s Jacobian at ``x``: power iteration on J^T J
    (a JVP then a VJP per step).  A lower bound of the Lipschitz constant.

    Shapes:
        x: (B, N, F); ``block(x, nbr, mask)`` -> (B, N, F')
    """
    fn = lambda z: block(z, nbr, mask)  # noqa: E731
    g = torch.Generator().manual_seed(seed)
    u = torch.randn(x.shape, generator=g, dtype=x.dtype)
    u /= u.norm()
    sigma = 0.0
    for _ in range(iters):
        _, jv = torch.func.jvp(fn, (x,), (u,))
        _, vjp = torch.func.vjp(fn, x)
        w = vjp(jv)[0]
        sigma = float(jv.detach().norm())
        u = w / w.norm().clamp_min(1e-300)
    return sigma


def adversarial_features(case: str, n: int, f: int, rng: np.random.Generator) -> np.ndarray:
    """Inputs ``(N, F)`` that stress attention: huge or tiny norms, near-duplicate or equal rows."""
    if case == "random":
        return rng.normal(size=(n, f))
    if case == "large":
        return 1e4 * rng.normal(size=(n, f))
    if case == "near_duplicate":
        return rng.normal(size=(1, f)) + 1e-7 * rng.normal(size=(n, f))
    if case == "all_equal":
        return np.tile(rng.normal(size=(1, f)), (n, 1))
    if case == "tiny":
        return 1e-6 * rng.normal(size=(n, f))
    raise ValueError(f"unknown case {case!r}; expected one of {ADVERSARIAL_CASES}")
