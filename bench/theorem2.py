"""Theorem 2 figures: Eq. 14's bound against the largest Lipschitz estimate found.

    python bench/theorem2.py

Power iteration on the Jacobian (``segadeform.model.lipschitz``, as in tests/model/test_theorem2.py)
over the same graphs and adversarial inputs as the test, with raw weights
scaled x20, for the SEGA block and the PlainGAT block.
"""

from __future__ import annotations

import numpy as np
import torch

from segadeform.geometry import neighbour_graph
from segadeform.geometry.primitives import fan, frustum
from segadeform.model.lipschitz import ADVERSARIAL_CASES, adversarial_features, lipschitz_estimate
from segadeform.model.sega import SEGABlock, theorem2_bound


def graph(kind):
    v, f = frustum(16, 6, 0.2, 0.35, 1.0, 0.5) if kind == "skirt" else fan(64)
    nbr, mask = neighbour_graph(f, len(v), vertices=v, k=64 if kind == "fan" else None)
    return v, torch.as_tensor(nbr), torch.as_tensor(mask)


def main() -> None:
    print(f"{'block':9s} {'alpha':>5s} {'tau':>4s} {'bound':>8s} {'largest estimate':>17s} {'ratio':>7s}")
    for alpha, tau in ((1.0, 1.0), (2.0, 2.0), (3.0, 1.0)):
        for use_sega in (True, False):
            worst = 0.0
            for g in ("skirt", "fan"):
                v, nbr, mask = graph(g)
                rng = np.random.default_rng(1)
                for heads, fp, fs in ((1, 16, 16), (4, 8, 32)):
                    torch.manual_seed(0)
                    block = SEGABlock(30, fp, heads, fs, alpha=alpha, tau=tau, use_sega=use_sega).double().eval()
                    with torch.no_grad():
                        for p in block.parameters():
                            p.mul_(20.0)
                    for case in ADVERSARIAL_CASES:
                        x = torch.as_tensor(adversarial_features(case, len(v), 30, rng))[None]
                        worst = max(worst, lipschitz_estimate(block, x, nbr, mask))
            b = theorem2_bound(alpha, tau)
            print(
                f"{'SEGA' if use_sega else 'PlainGAT':9s} {alpha:5.1f} {tau:4.1f} {b:8.2f} "
                f"{worst:17.4g} {worst / b:7.3g}"
            )


if __name__ == "__main__":
    main()
