"""The spectrum-enhanced graph attention block (SEGA, §4.1-4.2) and its PlainGAT ablation.

Everything here gathers neighbour features through a padded ``(N, K)``
index with ``index_select`` (ONNX ``Gather``) and masks the padding; there
is no scatter.  Shapes: ``B`` batch, ``N`` vertices, ``K`` neighbour slots,
``H`` heads.
"""

from __future__ import annotations

import math

import torch
from torch import nn

__all__ = ["TauLinear", "SEGABlock", "gather_neighbours", "masked_softmax", "theorem2_bound"]

_NEG = -1e9


def theorem2_bound(alpha: float, tau: float) -> float:
    """Eq. 14: ``sqrt((tau e^alpha + sqrt(2)(alpha + alpha tau))^2 + tau^2)``."""
    return math.sqrt((tau * math.exp(alpha) + math.sqrt(2.0) * (alpha + alpha * tau)) ** 2 + tau**2)


def _safe_norm(x: torch.Tensor, dim: int) -> torch.Tensor:
    """Euclidean norm as ``m * ||x / m||`` with ``m = max |x|``: no overflow for huge entries
    (a plain sum of squares overflows float32 above ~1.8e19).  The ``1e-24`` under the root
    keeps the derivative finite at x = 0 (sqrt'(0) is infinite: NaN gradients in training);
    the scaled sum is at least 1 whenever x != 0, so it changes nothing else."""
    # m only rescales (the norm does not depend on it), so it needs no gradient: detaching it gives
    # the exact gradient x / ||x|| and spares the max's backward pass
    m = x.abs().amax(dim=dim, keepdim=True).detach()
    safe = torch.where(m > 0, m, torch.ones_like(m))
    return (torch.sqrt(((x / safe) ** 2).sum(dim=dim, keepdim=True) + 1e-24) * m).squeeze(dim)


def gather_neighbours(x: torch.Tensor, nbr: torch.Tensor) -> torch.Tensor:
    """``x[:, nbr]`` via one index_select (ONNX Gather).

    Shapes:
        x: (B, N, C), nbr: (N, K) int64 -> (B, N, K, C)
    """
    n, k = nbr.shape
    return torch.index_select(x, 1, nbr.reshape(-1)).reshape(x.shape[0], n, k, x.shape[-1])


def _gather_slots(x: torch.Tensor, idx: torch.Tensor, k: int) -> torch.Tensor:
    """``x[:, nbr.T]`` slot-major via one index_select; ``idx = nbr.T.reshape(-1)``.

    Shapes:
        x: (B, N, C), idx: (K N,) int64 -> (B, K, N, C)
    """
    return torch.index_select(x, 1, idx).reshape(x.shape[0], k, -1, x.shape[-1])


def _batch_scale(x: torch.Tensor, dims=1) -> torch.Tensor:
    """``max |x|`` over ``dims`` (kept), 1 where that is 0; detached: a rescaling for overflow-safe norms."""
    m = x.abs().amax(dim=dims, keepdim=True).detach()
    return torch.where(m > 0, m, torch.ones_like(m))


def masked_softmax(scores: torch.Tensor, mask: torch.Tensor) -> torch.Tensor:
    """Softmax over the K axis (dim 2) that ignores padded slots; an all-padding row gives zeros.

    Shapes:
        scores: (B, N, K, H), mask: (N, K) bool, or float 1/0 (package schema 3) -> (B, N, K, H)
    """
    m = mask[None, :, :, None] if mask.dtype == torch.bool else mask[None, :, :, None] > 0
    s = torch.where(m, scores, torch.full_like(scores, _NEG))
    s = s - s.amax(dim=2, keepdim=True).detach()  # softmax is shift-invariant: the shift needs no gradient
    e = torch.exp(s) * m.to(scores.dtype)
    return e / e.sum(dim=2, keepdim=True).clamp_min(1e-30)


class TauLinear(nn.Module):
    """A linear map whose spectral norm is bounded by ``tau`` (Eq. 8): ``W_eff = tau W / max(tau, ||W||_2)``.

    While training, ``||W||_2`` is estimated by power iteration with a persistent
    vector (one step per forward, as in spectral normalisation).  :meth:`freeze`
    replaces the estimate by the exact value (SVD) and stores the scaled weight,
    so the exported graph holds a constant.  ``tau=None`` gives a plain linear.

    Shapes:
        x: (..., in_features) -> (..., out_features)
    """

    def __init__(
        self, in_features: int, out_features: int, tau: float | None, bias: bool = True, n_blocks: int = 1
    ) -> None:
        super().__init__()
        self.in_features, self.out_features, self.tau, self.n_blocks = in_features, out_features, tau, n_blocks
        self.weight = nn.Parameter(torch.empty(out_features, in_features))
        self.bias = nn.Parameter(torch.zeros(out_features)) if bias else None
        # power-iteration vectors, one per output block (heads)
        self.register_buffer("_u", torch.randn(n_blocks, out_features // n_blocks))
        # a plain attribute, not a buffer: exporters must not see a data-dependent branch
        self.frozen = False
        self.reset_parameters()

    def reset_parameters(self) -> None:
        nn.init.xavier_uniform_(self.weight)
        if self.bias is not None:
            # as nn.Linear: a zero bias would map beta = 0 (the mean body) to exactly 0 through
            # the ELU MLPs, and Eq. 15's product would then zero P for the commonest input
            bound = 1.0 / math.sqrt(self.in_features)
            nn.init.uniform_(self.bias, -bound, bound)
        with torch.no_grad():
            self._u.normal_()

    def _blocks(self, w: torch.Tensor) -> torch.Tensor:
        return w.reshape(self.n_blocks, self.out_features // self.n_blocks, self.in_features)

    def block_norms(self, exact: bool = False) -> torch.Tensor:
        """Spectral norm of each output block ``(n_blocks,)``."""
        wb = self._blocks(self.weight)
        if exact:
            return torch.linalg.matrix_norm(wb.detach().double(), ord=2).to(wb.dtype)
        with torch.no_grad():
            u = self._u
            v = torch.nn.functional.normalize(torch.einsum("hoi,ho->hi", wb, u), dim=-1, eps=1e-12)
            u = torch.nn.functional.normalize(torch.einsum("hoi,hi->ho", wb, v), dim=-1, eps=1e-12)
            if self.training:
                self._u.copy_(u)
        return torch.einsum("ho,hoi,hi->h", u, wb, v).abs()

    def effective_weight(self) -> torch.Tensor:
        if self.tau is None or self.frozen:
            return self.weight
        # each block bounded by tau / sqrt(n_blocks): the stacked map then has norm <= tau
        # however differently the blocks are used (e.g. with per-head attention)
        t = self.tau / math.sqrt(self.n_blocks)
        sigma = self.block_norms(exact=not self.training)
        scale = t / torch.clamp(sigma, min=t)
        return (self._blocks(self.weight) * scale[:, None, None]).reshape(self.out_features, self.in_features)

    @torch.no_grad()
    def freeze(self) -> None:
        """Fold the exact tau scaling into ``weight`` (for export); idempotent."""
        if self.tau is not None and not self.frozen:
            self.weight.copy_(self.effective_weight())
            self.frozen = True

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        return nn.functional.linear(x, self.effective_weight(), self.bias)

    def extra_repr(self) -> str:
        return f"in={self.in_features}, out={self.out_features}, tau={self.tau}, blocks={self.n_blocks}"


class SEGABlock(nn.Module):
    r"""Spectrum-enhanced graph attention block (Eq. 4 with Eqs. 8 and 13).

    .. math::
        \Psi(X) = v(X)\,\sigma(s(X))^\top \,\|\, m(X), \qquad
        s_{ij} = s^{pre}_{ij} / n_i(X)

    * ``v`` (values, ``H x F'``) and ``m`` (self stream, ``F''``) are
      :class:`TauLinear` maps: each head's value map has spectral norm at most
      ``tau / sqrt(H)`` and ``m`` at most ``tau`` (Eq. 8).
    * ``s^pre_ij = LeakyReLU_0.2(a_h . W_s x_i + b_h . W_s x_j)`` per head (GAT
      scores) over the padded neighbours ``j in nbr(i)``; softmax over the real
      neighbours only.
    * Eq. 13 per vertex: ``n_i(X) = max(||s^pre_i||_2, max_{j in nbr(i)} ||v(x_j)|| L_i) / alpha``,
      so ``|s_ij| <= alpha``.  ``L_i = sqrt(K) ||u|| + ||w||`` is the Lipschitz constant
      of ``X -> s^pre_i`` for the linear score ``u . x_i + w . x_j``
      (``u = W_s^T a``, ``w = W_s^T b``; LeakyReLU is 1-Lipschitz), computed from
      the weights.  The paper writes ``n`` with the Frobenius norm of the whole
      ``N x N`` score matrix; that norm grows with ``sqrt(N K)`` and would flatten
      the attention on large garments, against the paper's own point that the
      attention is local and independent of N.  Applied per vertex, the same
      argument bounds each row.
    * ``use_sega=False`` is the PlainGAT ablation: plain linear maps, ``n = 1``.

    Output features: ``H F' + F''``.

    Shapes:
        x: (B, N, F), nbr: (N, K) int64, mask: (N, K) bool -> (B, N, H F' + F'')
    """

    def __init__(
        self,
        in_features: int,
        head_features: int,
        heads: int,
        self_features: int,
        *,
        alpha: float = 2.0,
        tau: float = 2.0,
        use_sega: bool = True,
    ) -> None:
        super().__init__()
        self.in_features, self.head_features, self.heads = in_features, head_features, heads
        self.self_features, self.alpha, self.tau, self.use_sega = self_features, alpha, tau, use_sega
        t = tau if use_sega else None
        self.value = TauLinear(in_features, heads * head_features, t, bias=False, n_blocks=heads)
        self.self_stream = TauLinear(in_features, self_features, t, bias=False) if self_features else None
        self.score = nn.Linear(in_features, head_features, bias=False)  # W_s
        self.att_src = nn.Parameter(torch.empty(heads, head_features))
        self.att_dst = nn.Parameter(torch.empty(heads, head_features))
        self.reset_parameters()

    def reset_parameters(self) -> None:
        self.value.reset_parameters()
        if self.self_stream is not None:
            self.self_stream.reset_parameters()
        nn.init.xavier_uniform_(self.score.weight)
        nn.init.xavier_uniform_(self.att_src)
        nn.init.xavier_uniform_(self.att_dst)

    @property
    def out_features(self) -> int:
        return self.heads * self.head_features + self.self_features

    def freeze(self) -> None:
        self.value.freeze()
        if self.self_stream is not None:
            self.self_stream.freeze()

    def forward(
        self, x: torch.Tensor, nbr: torch.Tensor, mask: torch.Tensor, lift: torch.Tensor | None = None
    ) -> torch.Tensor:
        """``x (B, N, F) -> (B, N, out)``.  With ``lift (B, R, F)``, ``x`` is ``(N, R)`` shared by the
        batch and the block sees ``x @ lift[b]``, never formed: every linear map is applied as
        ``x @ (lift[b] @ W^T)`` (the decoder's blend features, Eq. 17, are ``g @ lift`` with ``R = S``
        joints: see :meth:`SEGANet.deformer`).

        The same maths as :meth:`forward_reference`, laid out for speed in exported graphs:

        * neighbours are gathered slot-major, ``(B, K, N, C)``, so every reduction over the
          neighbours is over a middle axis with a large contiguous inner block, and every broadcast
          covers whole ``(N, H)`` slabs (onnxruntime's fast paths; the ``(B, N, K, H)`` layout hit its
          per-element ones; a vertex-major ``(K, N, B, C)`` layout was measured slower);
        * one linear map computes the score, value and self streams;
        * the overflow guard of the norms is one scale per batch row and head
          (``max |e_src| + max |e_dst|`` bounds every ``|s_pre|``; LeakyReLU is positively
          homogeneous, so the scores are formed already divided by it) instead of a per-row max;
        * padded slots are zeroed before the division by ``n_i``, so ``|s| <= alpha`` everywhere
          and the softmax needs no running max (it is shifted by the constant ``alpha``);
        * the attention is expanded to the value channels with a ``(H, H F')`` 0/1 MatMul and
          normalised after the sum over neighbours.
        """
        h, fp = self.heads, self.head_features
        maps = [self.score.weight, self.value.effective_weight()]
        if self.self_stream is not None:
            maps.append(self.self_stream.effective_weight())
        w_all = torch.cat(maps, 0)  # (O, F), O = F' + H F' [+ F'']
        n, k = nbr.shape
        if lift is None:
            b = x.shape[0]
            y = torch.matmul(x, w_all.t())  # (B, N, O)
        else:
            b = lift.shape[0]
            y = torch.matmul(x, torch.matmul(lift, w_all.t()))  # (N, R) @ (B, R, O)
        z, v = y[..., :fp], y[..., fp : fp + h * fp]  # (B, N, F'), (B, N, H F')
        e = torch.matmul(z, torch.cat([self.att_src, self.att_dst], 0).t())  # (B, N, 2H): e_src | e_dst
        idx = nbr.t().reshape(-1)  # slot-major
        mf = mask.t().to(y.dtype)[:, :, None].expand(k, n, h)[None]  # (1, K, N, H)
        expand = torch.repeat_interleave(torch.eye(h, dtype=y.dtype, device=y.device), fp, dim=1)  # (H, H F')
        if self.use_sega:
            sc = _batch_scale(e, 1)
            sc = sc[..., :h] + sc[..., h:]  # (B, 1, H) >= |e_src_i + e_dst_j| >= |s_pre_ij|
            vs = _batch_scale(v, (1, 2))  # (B, 1, 1)
            vq = (v / vs).reshape(b, n, h, fp)
            vn = torch.sqrt((vq * vq).sum(dim=-1) + 1e-24) * vs  # ||v(x_j)||, (B, N, H)
            # one gather for both per-vertex quantities the neighbours contribute
            nb = _gather_slots(torch.cat([e[..., h:] / sc, vn], dim=-1), idx, k)  # (B, K, N, 2H)
            sp = nn.functional.leaky_relu(e[..., :h][:, None] / sc[:, None] + nb[..., :h], 0.2) * mf  # s_pre / sc
            row = torch.sqrt((sp * sp).sum(dim=1) + 1e-24)  # ||s_pre_i|| / sc, (B, N, H)
            vmax = (nb[..., h:] * mf).amax(dim=1)  # max_j ||v(x_j)||, (B, N, H)
            w_s = self.score.weight
            u = torch.matmul(self.att_src, w_s)  # (H, F)
            w = torch.matmul(self.att_dst, w_s)
            sqrt_k = torch.sqrt(torch.ones_like(mask[0], dtype=y.dtype).sum())  # runtime K (see reference)
            lip = sqrt_k * torch.linalg.vector_norm(u, dim=-1) + torch.linalg.vector_norm(w, dim=-1)  # (H,)
            n_i = torch.maximum(torch.maximum(row, vmax * lip / sc) / self.alpha, 1e-12 / sc)  # n_i / sc
            s = sp / n_i[:, None]  # (B, K, N, H), |s| <= alpha; 0 on padded slots
            shift = self.alpha if self.alpha <= 40.0 else s.amax(dim=1, keepdim=True).detach()
            ex = torch.exp(s - shift) * mf
        else:
            s = nn.functional.leaky_relu(e[..., :h][:, None] + _gather_slots(e[..., h:], idx, k), 0.2)
            s = torch.where(mf > 0, s, torch.full_like(s, _NEG))
            ex = torch.exp(s - s.amax(dim=1, keepdim=True).detach()) * mf
        num = (torch.matmul(ex, expand) * _gather_slots(v, idx, k)).sum(dim=1)  # (B, N, H F')
        phi = num / torch.matmul(ex.sum(dim=1).clamp_min(1e-30), expand)
        if self.self_stream is None:
            return phi
        return torch.cat([phi, y[..., fp + h * fp :]], dim=-1)

    def forward_reference(
        self, x: torch.Tensor, nbr: torch.Tensor, mask: torch.Tensor, lift: torch.Tensor | None = None
    ) -> torch.Tensor:
        """The slow, obvious form of :meth:`forward` (the lifted input formed, vertex-major
        ``(B, N, K, H)`` tensors, a per-row overflow-safe norm, a masked softmax): kept as the
        reference the tests compare with."""
        if lift is not None:
            x = torch.matmul(x, lift)  # (B, N, F)
        b, n = x.shape[0], x.shape[1]
        k = nbr.shape[1]
        h, fp = self.heads, self.head_features
        z = self.score(x)  # (B, N, F')
        e_src = torch.matmul(z, self.att_src.t())  # (B, N, H)
        e_dst = torch.matmul(z, self.att_dst.t())
        s_pre = nn.functional.leaky_relu(e_src[:, :, None, :] + gather_neighbours(e_dst, nbr), 0.2)  # (B,N,K,H)
        v = self.value(x)  # (B, N, H F')
        v_nb = gather_neighbours(v, nbr).reshape(b, n, k, h, fp)
        if self.use_sega:
            mf = mask[None, :, :, None].to(x.dtype)
            row = _safe_norm(s_pre * mf, dim=2)  # ||s_pre_i||_2, (B, N, H)
            # ||v(x_j)|| once per vertex, then gathered: K times cheaper than norming v_nb
            vn = _safe_norm(v.reshape(b, n, h, fp), dim=-1)  # (B, N, H)
            vmax = (gather_neighbours(vn, nbr) * mf).amax(dim=2)  # max_j ||v(x_j)||, (B, N, H)
            w_s = self.score.weight  # (F', F)
            u = torch.matmul(self.att_src, w_s)  # (H, F)
            w = torch.matmul(self.att_dst, w_s)
            # sqrt(K) from a tensor, so exported graphs follow the runtime K (a Python
            # float would be frozen at the export-time K)
            sqrt_k = torch.sqrt(torch.ones_like(mask[0], dtype=x.dtype).sum())
            lip = sqrt_k * torch.linalg.vector_norm(u, dim=-1) + torch.linalg.vector_norm(w, dim=-1)  # (H,)
            n_i = torch.maximum(row, vmax * lip) / self.alpha
            s = s_pre / n_i.clamp_min(1e-12)[:, :, None, :]
        else:
            s = s_pre
        att = masked_softmax(s, mask)  # (B, N, K, H)
        phi = (att[..., None] * v_nb).sum(dim=2).reshape(b, n, h * fp)
        if self.self_stream is None:
            return phi
        m = self.self_stream(x)
        return torch.cat([phi, m], dim=-1)

    def extra_repr(self) -> str:
        kind = f"alpha={self.alpha}, tau={self.tau}" if self.use_sega else "PlainGAT"
        return f"in={self.in_features}, heads={self.heads}x{self.head_features}, self={self.self_features}, {kind}"
