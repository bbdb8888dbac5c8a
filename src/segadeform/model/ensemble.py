"""Several trained SEGA networks run as one: the mean of their frames.

The mean of K networks' predictions is never further from the truth, on average, than its members are (the vertex
error is a convex function of the prediction, Jensen's inequality); how much closer depends on how much the
members' errors differ.  For this project's recipe they mostly do not: three seeds averaged are 1.4-1.5 % below
their mean and not below their best (``docs/gpu-training.md``, "Averaging trained networks").  An ensemble
is made from trained checkpoints (``segadeform ensemble A.pt B.pt ... -o E.pt``), evaluated and exported like
one network, and costs its members' time.

The two graphs keep the single network's interface, so every runtime runs an ensemble unchanged:

* ``garment_encoder``: the members' codes side by side, ``g = [g_1 | ... | g_K]`` (B, N, K S);
* ``deformer``: each member on its own slice of ``g``; ``vertices`` is the mean of the members' vertices
  (what the error is measured on), ``weights`` and ``blend_shapes`` the means of theirs (for inspection: with
  K > 1 skinning the mean blend shapes with the mean weights is not exactly the mean of the members' frames).

Shapes: as :class:`~segadeform.model.network.SEGANet`, with ``g (N, K S)``.
"""

from __future__ import annotations

import torch
from torch import nn

from ..errors import InputError
from .config import ModelConfig
from .network import SEGANet

__all__ = ["SEGAEnsemble", "build_model", "combine"]


class SEGAEnsemble(nn.Module):
    """``cfg.ensemble`` networks of one configuration (``cfg`` with ``ensemble = 1``); see the module docstring."""

    def __init__(self, cfg: ModelConfig) -> None:
        super().__init__()
        if cfg.ensemble < 2:
            raise InputError(
                "an ensemble has two or more members", expected="ModelConfig.ensemble >= 2", got=cfg.ensemble
            )
        if cfg.history:
            raise InputError(
                "an ensemble of motion-history models is not supported",
                expected="ModelConfig.history = 0",
                got=cfg.history,
            )
        self.cfg = cfg
        member = cfg.replace(ensemble=1)
        self.members = nn.ModuleList(SEGANet(member) for _ in range(cfg.ensemble))
        self.residual = self.members[0].residual
        self.hist = None
        self.parents = self.members[0].parents

    def freeze(self) -> SEGAEnsemble:
        for m in self.members:
            m.freeze()
        return self

    def garment_encoder(self, features, nbr, mask, descriptor) -> torch.Tensor:
        return torch.cat([m.garment_encoder(features, nbr, mask, descriptor) for m in self.members], dim=-1)

    def history_states(self, x: torch.Tensor) -> torch.Tensor:
        raise InputError(
            "this model has no motion history (an ensemble has none)", expected="ModelConfig.history > 0", got=0
        )

    def deformer(self, g, window, betas, rest, nbr, mask, joints, trans, log_wbody=None, history=None):
        s, k = self.cfg.n_joints, len(self.members)
        if g.shape[-1] != k * s:
            raise InputError(
                "an ensemble's garment code has its members' codes side by side",
                expected=f"(N, {k * s})",
                got=tuple(g.shape),
            )
        outs = [
            m.deformer(g[:, i * s : (i + 1) * s], window, betas, rest, nbr, mask, joints, trans, log_wbody, history)
            for i, m in enumerate(self.members)
        ]
        return tuple(torch.stack(parts).mean(dim=0) for parts in zip(*outs, strict=True))

    def forward(
        self, features, nbr, mask, descriptor, betas, window, rest, joints, trans, log_wbody=None, history=None
    ):
        g = self.garment_encoder(features, nbr, mask, descriptor)[0]
        return self.deformer(g, window, betas, rest, nbr, mask, joints, trans, log_wbody, history)


def build_model(cfg: ModelConfig) -> SEGANet | SEGAEnsemble:
    """The network for ``cfg``: a :class:`SEGANet`, or a :class:`SEGAEnsemble` when ``cfg.ensemble > 1``."""
    return SEGAEnsemble(cfg) if cfg.ensemble > 1 else SEGANet(cfg)


def combine(models) -> SEGAEnsemble:
    """One ensemble of trained ``models`` (SEGANets or ensembles, flattened) that share a configuration.

    The ensemble is in the first network's mode (``training`` or eval).  Raises :class:`InputError` for fewer
    than two networks, differing configurations or motion-history models."""
    nets: list[SEGANet] = []
    for m in models:
        nets.extend(m.members if isinstance(m, SEGAEnsemble) else [m])
    if len(nets) < 2:
        raise InputError("an ensemble needs two or more networks", expected=">= 2 networks", got=len(nets))
    cfg = nets[0].cfg
    for i, n in enumerate(nets[1:], 1):
        if n.cfg != cfg:
            diff = {k: (v, getattr(n.cfg, k)) for k, v in vars(cfg).items() if getattr(n.cfg, k) != v}
            raise InputError(
                f"the ensemble's networks must share one configuration; network {i} (from 0, ensembles' members "
                "counted one by one) differs",
                expected="the first network's configuration",
                got=", ".join(f"{k}: {a!r} vs {b!r}" for k, (a, b) in diff.items()),
            )
    ens = SEGAEnsemble(cfg.replace(ensemble=len(nets)))
    for dst, src in zip(ens.members, nets, strict=True):
        dst.load_state_dict(src.state_dict())
        for a, b in zip(dst.modules(), src.modules(), strict=True):  # a frozen network's weights are already scaled
            if hasattr(b, "frozen"):
                a.frozen = b.frozen
    return ens.train(nets[0].training)
