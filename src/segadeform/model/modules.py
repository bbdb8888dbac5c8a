"""The network's modules (§3, §4.3): parsers, graph encoder/decoder, motion processors."""

from __future__ import annotations

import torch
from torch import nn

from .config import ModelConfig
from .sega import SEGABlock, TauLinear

__all__ = [
    "elu",
    "MLP",
    "UnrolledLSTM",
    "GarmentTypeParser",
    "BodyShapeParser",
    "GraphEncoder",
    "GraphDecoder",
    "MotionProcessor",
]


def elu(x: torch.Tensor) -> torch.Tensor:
    """ELU (alpha 1) as ``relu(x) + exp(min(x, 0)) - 1``: equal to ``torch.nn.functional.elu``
    (derivative 1 at 0 as well), and exported as Relu/Clip/Exp, which onnxruntime vectorises (its Elu
    kernel is about 1.7x slower on a (8, 4k, 64) tensor, one thread)."""
    return torch.relu(x) + (torch.exp(torch.clamp(x, max=0.0)) - 1.0)


class MLP(nn.Module):
    """Linear layers with ELU between them; tau-bounded (Eq. 8) when ``tau`` is set."""

    def __init__(self, sizes: list[int], tau: float | None) -> None:
        super().__init__()
        self.layers = nn.ModuleList(TauLinear(a, b, tau) for a, b in zip(sizes[:-1], sizes[1:], strict=True))

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        for i, layer in enumerate(self.layers):
            x = layer(x)
            if i < len(self.layers) - 1:
                x = elu(x)
        return x


class UnrolledLSTM(nn.Module):
    """A single-layer LSTM written as MatMul/Sigmoid/Tanh over a fixed window (no ONNX LSTM op:
    Sentis' GPU backends and ORT-web's WebGPU lack it).  Weights follow ``torch.nn.LSTM``'s layout
    (gates i, f, g, o), so :meth:`from_lstm` copies a trained ``nn.LSTM``.

    Shapes:
        x: (B, T, I) with x[:, 0] the current frame -> final hidden state (B, H)
    """

    def __init__(self, input_size: int, hidden_size: int) -> None:
        super().__init__()
        self.input_size, self.hidden_size = input_size, hidden_size
        self.w_ih = nn.Parameter(torch.empty(4 * hidden_size, input_size))
        self.w_hh = nn.Parameter(torch.empty(4 * hidden_size, hidden_size))
        self.bias = nn.Parameter(torch.zeros(4 * hidden_size))
        self.reset_parameters()

    def reset_parameters(self) -> None:
        k = 1.0 / self.hidden_size**0.5
        for p in (self.w_ih, self.w_hh):
            nn.init.uniform_(p, -k, k)
        nn.init.zeros_(self.bias)
        with torch.no_grad():  # forget-gate bias 1: remember by default
            self.bias[self.hidden_size : 2 * self.hidden_size].fill_(1.0)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        b, t, _ = x.shape
        h = x.new_zeros(b, self.hidden_size)
        c = x.new_zeros(b, self.hidden_size)
        gx = torch.matmul(x, self.w_ih.t()) + self.bias  # (B, T, 4H)
        hs = self.hidden_size
        for step in range(t - 1, -1, -1):  # oldest frame first, the current frame last
            g = gx[:, step] + torch.matmul(h, self.w_hh.t())
            i = torch.sigmoid(g[:, :hs])
            f = torch.sigmoid(g[:, hs : 2 * hs])
            gg = torch.tanh(g[:, 2 * hs : 3 * hs])
            o = torch.sigmoid(g[:, 3 * hs :])
            c = f * c + i * gg
            h = o * torch.tanh(c)
        return h


class HistoryEncoder(nn.Module):
    """The clip's motion history: one LSTM stepped over every frame in time order (the same gates and
    weight layout as :class:`UnrolledLSTM`), the state carried from one frame to the next::

        (i, f, g, o) = (sigma, sigma, tanh, sigma)(W_ih x_t + W_hh h_{t-1} + b)
        c_t = f c_{t-1} + i g,   h_t = o tanh(c_t),   h_{-1} = c_{-1} = 0

    :meth:`forward` runs a whole sequence (training, offline); :meth:`step` is one frame (what a
    streaming runtime calls, carrying ``(h, c)``).

    Shapes:
        forward: x (B, L, I), oldest frame first -> h (B, L, H), every frame's state
        step: x (B, I), h (B, H), c (B, H) -> (h (B, H), c (B, H))
    """

    def __init__(self, input_size: int, hidden_size: int) -> None:
        super().__init__()
        self.cell = UnrolledLSTM(input_size, hidden_size)

    def step(self, x: torch.Tensor, h: torch.Tensor, c: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        m, hs = self.cell, self.cell.hidden_size
        g = torch.matmul(x, m.w_ih.t()) + m.bias + torch.matmul(h, m.w_hh.t())
        c = torch.sigmoid(g[:, hs : 2 * hs]) * c + torch.sigmoid(g[:, :hs]) * torch.tanh(g[:, 2 * hs : 3 * hs])
        return torch.sigmoid(g[:, 3 * hs :]) * torch.tanh(c), c

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        b, length, _ = x.shape
        h = x.new_zeros(b, self.cell.hidden_size)
        c = x.new_zeros(b, self.cell.hidden_size)
        out = []
        for t in range(length):
            h, c = self.step(x[:, t], h, c)
            out.append(h)
        return torch.stack(out, dim=1)


class GarmentTypeParser(nn.Module):
    """f^gp: descriptor lambda (B, N*) -> (B, F_enc); a learned constant without the descriptor."""

    def __init__(self, cfg: ModelConfig) -> None:
        super().__init__()
        self.use = cfg.use_descriptor
        tau = cfg.tau if cfg.use_sega else None
        if self.use:
            self.mlp = MLP([cfg.n_star, cfg.hidden, cfg.f_enc], tau)
        else:
            self.const = nn.Parameter(torch.ones(cfg.f_enc))

    def forward(self, lam: torch.Tensor) -> torch.Tensor:
        if self.use:
            # eigenvalues scale with N*: feed them per sample (lambda / N*), sign-preserving sqrt
            x = lam / lam.shape[-1]
            return self.mlp(torch.sign(x) * torch.sqrt(torch.abs(x) + 1e-12))
        return self.const.expand(lam.shape[0], -1)


class BodyShapeParser(nn.Module):
    """f^bp: beta (B, |beta|) -> (B, F_enc, S)."""

    def __init__(self, cfg: ModelConfig) -> None:
        super().__init__()
        self.cfg = cfg
        self.mlp = MLP([cfg.n_betas, cfg.hidden, cfg.f_enc * cfg.n_joints], cfg.tau if cfg.use_sega else None)

    def forward(self, betas: torch.Tensor) -> torch.Tensor:
        return self.mlp(betas).reshape(-1, self.cfg.f_enc, self.cfg.n_joints)


class GraphEncoder(nn.Module):
    """f^enc: SEGA blocks over the garment graph -> (B, F_enc, S, N); the last block has S heads."""

    def __init__(self, cfg: ModelConfig) -> None:
        super().__init__()
        self.cfg = cfg
        hp = cfg.hidden // cfg.heads
        blocks = []
        width = cfg.feat_dim
        for _ in range(cfg.enc_layers - 1):
            blk = SEGABlock(width, hp, cfg.heads, cfg.hidden, alpha=cfg.alpha, tau=cfg.tau, use_sega=cfg.use_sega)
            blocks.append(blk)
            width = blk.out_features
        self.blocks = nn.ModuleList(blocks)
        self.last = SEGABlock(
            width,
            cfg.f_enc,
            cfg.n_joints,
            cfg.f_enc * cfg.n_joints,
            alpha=cfg.alpha,
            tau=cfg.tau,
            use_sega=cfg.use_sega,
        )

    def forward(self, x, nbr, mask):
        for blk in self.blocks:
            x = elu(blk(x, nbr, mask))
        y = self.last(x, nbr, mask)  # (B, N, 2 S F_enc): attention part | self part
        half = self.cfg.f_enc * self.cfg.n_joints
        y = y[..., :half] + y[..., half:]
        b, n = y.shape[:2]
        # heads are joints: (B, N, S, F_enc) -> (B, F_enc, S, N)
        return y.reshape(b, n, self.cfg.n_joints, self.cfg.f_enc).permute(0, 3, 2, 1)


class GraphDecoder(nn.Module):
    """f^dec: SEGA blocks over the blend features X^mid (B, N, F_enc S) -> blend shapes (B, N, 3)."""

    def __init__(self, cfg: ModelConfig) -> None:
        super().__init__()
        hp = cfg.hidden // cfg.heads
        width = cfg.f_enc * cfg.n_joints
        blocks = []
        for _ in range(cfg.dec_layers):
            blk = SEGABlock(width, hp, cfg.heads, cfg.hidden, alpha=cfg.alpha, tau=cfg.tau, use_sega=cfg.use_sega)
            blocks.append(blk)
            width = blk.out_features
        self.blocks = nn.ModuleList(blocks)
        self.out = TauLinear(width, 3, cfg.tau if cfg.use_sega else None)

    def forward(self, x, nbr, mask, lift=None):
        """``x (B, N, C)``; or ``x (N, R)`` shared with ``lift (B, R, C)``: the input is ``x @ lift``
        (see SEGABlock)."""
        for i, blk in enumerate(self.blocks):
            x = elu(blk(x, nbr, mask, lift if i == 0 else None))
        return self.out(x)


class MotionProcessor(nn.Module):
    """f^mo: an unrolled LSTM over the window Theta (and beta for f^mo2) -> (B, out)."""

    def __init__(self, cfg: ModelConfig, out: int, with_betas: bool) -> None:
        super().__init__()
        self.with_betas = with_betas
        # the window as the deformer gives it: axis-angle, or the root's 9 heading-free entries (cfg.motion_input)
        self.lstm = UnrolledLSTM(3 * cfg.n_joints + (6 if cfg.motion_input == "heading" else 0), cfg.lstm_hidden)
        extra = (cfg.n_betas if with_betas else 0) + cfg.history
        self.head = MLP([cfg.lstm_hidden + extra, cfg.hidden, out], cfg.tau if cfg.use_sega else None)

    def forward(
        self, window: torch.Tensor, betas: torch.Tensor | None = None, history: torch.Tensor | None = None
    ) -> torch.Tensor:
        """``window (B, T, 3 S)`` (``(B, T, 3 S + 6)`` for ``motion_input = "heading"``:
        :func:`~segadeform.model.kinematics.heading_free_window`), ``betas (B, |beta|)`` for f^mo2, ``history (B, H)``
        when the config has one."""
        h = self.lstm(window)
        if self.with_betas:
            h = torch.cat([h, betas], dim=-1)
        if history is not None:
            h = torch.cat([h, history], dim=-1)
        return self.head(h)
