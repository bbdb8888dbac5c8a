"""The SEGA deformation network (Eqs. 1-2, 15-18) and checkpoints.

Two halves, exported as two graphs:

* :meth:`SEGANet.garment_encoder` -- once per garment -- computes the
  garment's per-joint code ``g`` (Eq. 15 without the body-shape factor)::

      g[k, j] = sum_i' f^gp(lambda)[i'] f^enc(G)[i', j, k]

  stored vertex-major as ``(N, S)``.  The target-aware features of Eq. 15 are
  ``P[k, j, i] = f^bp(beta)[i, j] g[k, j]`` (:meth:`SEGANet.target_features`);
  the deformer never forms them: every use of ``P`` below is linear in it, so
  the body-shape factor is folded into the small per-frame matrices instead,
  and the first decoder block reads ``N x S`` numbers per frame, not ``N x S F_enc``.
* :meth:`SEGANet.deformer` -- per frame, batched over frames -- combines ``g``
  with the body shape and the motion window:

  - temporal weights (Eq. 16) ``W~[k, j] = sum_i P[k, j, i] f^mo1(Theta)[i]
    = g[k, j] sum_i f^bp(beta)[i, j] f^mo1(Theta)[i]``,
    normalised over the joints with a softmax, so every vertex's weights are
    positive and sum to 1 as skinning needs (the paper leaves the
    normalisation open).  With ``cfg.weights == "residual"`` the logits are
    ``log(w_body + eps) + g_w W~`` (``w_body``: the body's weights at the
    garment's closest body point, an input ``log_wbody``; ``g_w``: a learned
    gate starting at 0), so the weights start as the body's and the network
    learns only where the garment should skin differently;
  - blend features (Eq. 17) ``X^mid[k, (j, i)] = P[k, j, i] f^mo2(Theta, beta)[(j, i)] = (g @ L)[k, (j, i)]``
    with ``L[j, (j, i)] = f^bp(beta)[i, j] f^mo2[(j, i)]`` (zero off the block diagonal), and blend
    shapes (Eq. 18) ``B = f^dec(X^mid)`` (times a second gate starting at 0 for
    residual models: an untrained residual model is exactly LBS with the body's weights);
  - deformation (Eq. 2) ``M = skin(T + B, J, theta_t, W~) + trans`` with LBS
    or DQS, forward kinematics inside the graph.

The rest joints ``J`` are an input (computed on the host from the body model
and beta), so the same network drives any SMPL-compatible body.
"""

from __future__ import annotations

import dataclasses
import os
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
import torch
from torch import nn

from ..body.skeleton import SMPL_PARENTS
from ..errors import FileFormatError, InputError
from .config import ModelConfig
from .kinematics import (
    axis_angle_to_matrix,
    dqs,
    forward_kinematics,
    heading_free_window,
    lbs,
    skinning_transforms,
)
from .modules import (
    MLP,
    BodyShapeParser,
    GarmentTypeParser,
    GraphDecoder,
    GraphEncoder,
    HistoryEncoder,
    MotionProcessor,
)
from .sega import SEGABlock, TauLinear

if TYPE_CHECKING:
    from .ensemble import SEGAEnsemble

__all__ = ["SEGANet", "save_checkpoint", "load_checkpoint"]


class SEGANet(nn.Module):
    """The full network; see the module docstring.

    Shapes (garment_encoder):
        features (B, N, F), nbr (N, K) int64, mask (N, K) bool, descriptor (B, N*) -> g (B, N, S)
    Shapes (deformer):
        g (N, S), window (B, T, 3 S) with window[:, 0] the current pose, betas (B, |beta|),
        rest (N, 3), nbr (N, K), mask (N, K), joints (B, S, 3), trans (B, 3)
        [, log_wbody (N, S) for residual weights] [, history (B, H): :meth:`history_states` at each frame]
        -> vertices (B, N, 3), weights (B, N, S), blend_shapes (B, N, 3)
    """

    def __init__(self, cfg: ModelConfig) -> None:
        super().__init__()
        if cfg.n_joints != len(SMPL_PARENTS):
            raise InputError("only the 24-joint SMPL skeleton is supported", got=cfg.n_joints)
        if cfg.ensemble != 1:
            raise InputError(
                "one SEGANet is one network (segadeform.model.ensemble builds ensembles)", got=cfg.ensemble
            )
        self.cfg = cfg
        self.parents = [int(p) for p in SMPL_PARENTS]
        self.gp = GarmentTypeParser(cfg)
        self.bp = BodyShapeParser(cfg)
        self.enc = GraphEncoder(cfg)
        self.mo1 = MotionProcessor(cfg, cfg.f_enc, with_betas=False)
        self.mo2 = MotionProcessor(cfg, cfg.f_enc * cfg.n_joints, with_betas=True) if cfg.use_blend_shapes else None
        self.dec = GraphDecoder(cfg) if cfg.use_blend_shapes else None
        self.residual = cfg.weights == "residual"
        #: the clip's motion history (cfg.history > 0): input (pose, root velocity) per frame
        self.hist = HistoryEncoder(3 * cfg.n_joints + 3, cfg.history) if cfg.history else None
        self.static = (
            MLP([cfg.n_joints + 3, cfg.hidden, cfg.hidden, 3], cfg.tau if cfg.use_sega else None)
            if cfg.static_blend
            else None
        )
        if self.residual:  # ReZero-style gates: the corrections start at exactly zero and still learn
            self.weight_gate = nn.Parameter(torch.zeros(()))
            self.blend_gate = nn.Parameter(torch.zeros(()))
            if cfg.static_blend:
                self.static_gate = nn.Parameter(torch.zeros(()))

    def freeze(self) -> SEGANet:
        """Fold every tau scaling into its weight (exact spectral norms); use before export."""
        for m in self.modules():
            if isinstance(m, (TauLinear, SEGABlock)):
                m.freeze()
        return self

    def garment_encoder(self, features, nbr, mask, descriptor) -> torch.Tensor:
        enc = self.enc(features, nbr, mask)  # (B, F_enc, S, N)
        gp = self.gp(descriptor)  # (B, F_enc)
        g = torch.matmul(gp[:, None, None, :], enc.permute(0, 2, 1, 3))[:, :, 0, :]  # (B, S, N)
        return g.permute(0, 2, 1)  # (B, N, S)

    def target_features(self, g, betas) -> torch.Tensor:
        """Eq. 15's ``P (B, N, S, F_enc)`` from the garment code ``g (B, N, S)`` and ``betas (B, |beta|)``
        (for inspection and tests; the deformer uses it only in factored form)."""
        bp = self.bp(betas)  # (B, F_enc, S)
        return g[..., None] * bp.permute(0, 2, 1)[:, None, :, :]

    def history_states(self, x: torch.Tensor) -> torch.Tensor:
        """The motion history ``h_t`` at every frame of ``x (B, L, 3 S + 3)`` (:func:`segadeform.motion.motion.
        history_inputs`, oldest first, from the first frame simulated) -> ``(B, L, H)``."""
        if self.hist is None:
            raise InputError("this model has no motion history (ModelConfig.history = 0)")
        return self.hist(x)

    def deformer(self, g, window, betas, rest, nbr, mask, joints, trans, log_wbody=None, history=None):
        cfg = self.cfg
        b = window.shape[0]
        s, f = cfg.n_joints, cfg.f_enc
        if (history is None) != (self.hist is None):
            raise InputError(
                "the motion history is an input exactly when the model has one",
                expected=f"history (B, {cfg.history})" if cfg.history else "no history",
                got=None if history is None else tuple(history.shape),
            )
        bp = self.bp(betas).permute(0, 2, 1)  # f^bp(beta)[i, j] as (B, S, F_enc)
        mwin = heading_free_window(window) if cfg.motion_input == "heading" else window  # what f^mo reads
        mo1 = self.mo1(mwin, history=history)  # (B, F_enc)
        w_raw = g[None] * torch.matmul(bp, mo1[:, :, None])[:, None, :, 0]  # Eq. 16: (B, N, S)
        if self.residual:
            if log_wbody is None:
                raise InputError("a residual-weights model needs log_wbody (N, S): log of the body's weights")
            w_raw = log_wbody[None] + self.weight_gate * w_raw
        weights = torch.softmax(w_raw, dim=-1)
        if self.dec is not None:
            mo2 = self.mo2(mwin, betas, history)  # (B, S F_enc)
            # X^mid = P * mo2 (Eq. 17) = g @ lift, lift block-diagonal (B, S, S F_enc): never formed as (B, N, S F_enc)
            diag = torch.eye(s, dtype=g.dtype, device=g.device)[None, :, :, None]
            lift = (diag * (bp.reshape(b, 1, s, f) * mo2.reshape(b, 1, s, f))).reshape(b, s, s * f)
            blend = self.dec(g, nbr, mask, lift=lift)  # (B, N, 3)
            if self.residual:
                blend = self.blend_gate * blend
        else:
            blend = torch.zeros(b, g.shape[0], 3, dtype=g.dtype, device=g.device)
        if self.static is not None:  # the drape: one (N, 3) blend shape for every frame
            drape = self.static(torch.cat([g, rest], dim=-1))
            blend = blend + (self.static_gate * drape if self.residual else drape)[None]
        verts = rest[None] + blend
        rot = axis_angle_to_matrix(window[:, 0].reshape(b, s, 3))
        g_fk = forward_kinematics(rot, joints, self.parents, trans)
        a = skinning_transforms(g_fk, joints)
        skin = dqs if cfg.skinning == "dqs" else lbs
        return skin(verts, weights, a), weights, blend

    def forward(
        self, features, nbr, mask, descriptor, betas, window, rest, joints, trans, log_wbody=None, history=None
    ):
        """Encoder and deformer in one call (training); the garment batch must be 1."""
        g = self.garment_encoder(features, nbr, mask, descriptor)[0]
        return self.deformer(g, window, betas, rest, nbr, mask, joints, trans, log_wbody, history)


def save_checkpoint(path: str | os.PathLike, model: SEGANet, **extra) -> Path:
    """Write ``{config, state_dict, **extra}`` atomically."""
    from ..io.atomic import atomic_path

    p = Path(path)
    with atomic_path(p) as tmp:
        torch.save({"config": dataclasses.asdict(model.cfg), "state_dict": model.state_dict(), **extra}, tmp)
    return p


def checkpoint_training_garments(path: str | os.PathLike):
    """``(names, descriptors (R, N*), openings)`` of the garments a checkpoint was trained on; None when it
    does not say (checkpoints written before training recorded them)."""
    ck = torch.load(Path(path), map_location="cpu", weights_only=True)
    t = ck.get("training_garments") if isinstance(ck, dict) else None
    if not t:
        return None
    return list(t["names"]), np.asarray(t["descriptors"], np.float64), t.get("openings")


def checkpoint_training_motions(path: str | os.PathLike) -> dict | None:
    """The record of the motions a checkpoint was trained on (:func:`segadeform.motion.fingerprint.motions_record`);
    None when it does not say (checkpoints written before training recorded them)."""
    ck = torch.load(Path(path), map_location="cpu", weights_only=True)
    t = ck.get("training_motions") if isinstance(ck, dict) else None
    return t if isinstance(t, dict) and t.get("motions") else None


def checkpoint_body(path: str | os.PathLike) -> dict | None:
    """``{"name", "sha256"}`` of the body a checkpoint was trained on
    (:func:`segadeform.body.identity.body_label`); None when it does not say (checkpoints written before training
    recorded it, and networks never trained: ``segadeform export --random-init``)."""
    ck = torch.load(Path(path), map_location="cpu", weights_only=True)
    b = ck.get("body") if isinstance(ck, dict) else None
    if not isinstance(b, dict) or not b.get("sha256"):
        return None
    return {"name": str(b.get("name") or ""), "sha256": str(b["sha256"])}


def load_checkpoint(path: str | os.PathLike) -> SEGANet | SEGAEnsemble:
    """Read a checkpoint with ``torch.load(weights_only=True)`` and rebuild the model (a
    :class:`~segadeform.model.ensemble.SEGAEnsemble` when its config has ``ensemble > 1``)."""
    from .ensemble import build_model

    p = Path(path)
    try:
        ck = torch.load(p, map_location="cpu", weights_only=True)
    except FileNotFoundError:
        raise FileFormatError("no such file", path=p) from None
    except Exception as e:
        what = (
            "a training run's resume state (optimiser and random state), not its model"
            if p.name == "last.pt"
            else f"not a model checkpoint ({type(e).__name__})"  # torch's many lines, said in one
        )
        raise FileFormatError(
            what, path=p, expected="a run's model.pt: the model `segadeform train` writes", got=p.name
        ) from None
    if not isinstance(ck, dict) or "config" not in ck or "state_dict" not in ck:
        what = (
            "a run's best checkpoint so far: its weights without their config (`segadeform train` writes the model "
            "chosen from it, model.pt, when the run ends: run the same command again to finish it)"
            if isinstance(ck, dict) and "state_dict" in ck and "val_vertex" in ck
            else "checkpoint must hold 'config' and 'state_dict'"
        )
        raise FileFormatError(what, path=p, expected="a run's model.pt")
    try:
        model = build_model(ModelConfig.from_dict(ck["config"]))
        model.load_state_dict(ck["state_dict"])
    except (InputError, RuntimeError, TypeError) as e:
        # torch lists every tensor that does not fit, a line each: the first and how many, in one line
        lines = [ln.strip() for ln in str(e).splitlines() if ln.strip()]
        detail = (
            lines[1] if len(lines) > 1 and lines[0].startswith("Error(s) in loading") else lines[0] if lines else ""
        )
        more = f"; {len(lines) - 2} more" if len(lines) > 2 and lines[0].startswith("Error(s) in loading") else ""
        raise FileFormatError(f"checkpoint's weights do not fit its config ({detail}{more})", path=p) from None
    return model
