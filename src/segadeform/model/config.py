"""The one frozen model configuration (whisper ``ModelDimensions`` style).

Checkpoints are ``{"config": dataclasses.asdict(cfg), "state_dict": ...}``
and the same JSON rides in the exported model package's manifest.
"""

from __future__ import annotations

import dataclasses
import json

from ..errors import InputError

__all__ = ["ModelConfig"]


@dataclasses.dataclass(frozen=True)
class ModelConfig:
    """Dimensions and switches of the SEGA network.

    Attributes:
        n_joints: S, skeleton joints (24 for SMPL); also the heads of the encoder's last block.
        n_betas: |beta|, body shape coefficients.
        n_star: N*, length of the garment type descriptor.
        feat_dim: F, per-vertex input features (6 + S: position, normal, joint distances).
        hidden: hidden width of graph blocks, parsers and motion processors.
        heads: attention heads of the hidden graph blocks.
        enc_layers / dec_layers: graph blocks in the encoder / decoder (>= 1).
        f_enc: F_enc, features per joint of the encoder output.
        window: T, motion frames seen by the motion processors.
        lstm_hidden: hidden size of the (unrolled) LSTMs.
        alpha, tau: SEGA bounds (Eqs. 8, 13); the paper's best is 2, 2.
        skinning: "lbs" or "dqs".
        use_sega: False gives the PlainGAT ablation (no bounds).
        use_descriptor: False replaces f^gp(lambda) by a learned constant.
        use_blend_shapes: False removes the decoder (B = 0).
        weights: "residual" (skinning logits = log w_body + gated correction, the correction and the
            blend shapes starting at zero: an untrained model is LBS with the body's weights) or
            "free" (the paper's Eq. 16: softmax of the network's logits alone).  Checkpoints and
            manifests without the field are "free" (made before it existed).
        weight_prior: how the body's weights reach the garment for residual weights (``log_wbody``):
            "nearest" (closest body point) or "inpaint" (closest point where the garment lies on the
            body, harmonic inpainting elsewhere: segadeform.body.transfer).  Checkpoints and manifests
            without the field are "nearest".
        static_blend: add a motion-independent blend shape ``B_s = f^s([g, T])`` (an MLP of each vertex's
            garment code and rest position) to the decoder's ``B``: the garment's drape on the body, which the
            decoder could reach only through the motion processors (its features are products with them).
            Gated from 0 in residual models.  Checkpoints and manifests without the field have none.
        history: H, the size of a recurrent motion state carried over the whole clip (0: none, the paper's
            window alone).  A step ``(x_t, h_{t-1}, c_{t-1}) -> (h_t, c_t)`` of an LSTM over every frame from the
            first simulated one (:class:`~segadeform.model.modules.HistoryEncoder`; ``x_t``: the pose and the
            root's velocity in the root's frame, :func:`segadeform.motion.motion.history_inputs`); ``h_t`` joins
            the window's code in both motion processors.  The window covers 0.17 s, a skirt's swing lags the hips by
            most of a second.  Checkpoints without the field have 0.
        rest_drape: how far the garment's rest that the deformer skins is moved toward its drape on the body at
            rest (``segadeform.body.drape``; computed on the host, as the rest joints are): 0 skins the rest as
            designed, 1 the drape.  The network is unchanged; the model package format has no drape yet, so
            only 0 exports.  Checkpoints without the field have 0.
        motion_input: what the motion processors read of the window: "pose" (the paper: every joint's axis-angle,
            the root's rotation in the world, so the same motion facing another way reads differently) or "heading"
            (the root's rotation relative to the current frame's heading, as its 9 matrix entries, the other joints
            as axis-angle: :func:`~segadeform.model.kinematics.heading_free_window`; the frames then turn with the
            motion exactly).  Skinning uses the world rotation either way, and so does the clip-long ``history``
            (its inputs are made on the host), so only a model without one turns exactly.  Checkpoints without the
            field have "pose".
        ensemble: K, the networks run side by side and averaged (:class:`~segadeform.model.ensemble.SEGAEnsemble`,
            made from trained checkpoints by :func:`~segadeform.model.ensemble.combine`); 1 is one network.  The
            garment code ``g`` is then (N, K S).  Checkpoints and manifests without the field have 1.
    """

    n_joints: int = 24
    n_betas: int = 10
    n_star: int = 32
    feat_dim: int = 30
    hidden: int = 32
    heads: int = 4
    enc_layers: int = 2
    dec_layers: int = 2
    f_enc: int = 8
    window: int = 5
    lstm_hidden: int = 32
    alpha: float = 2.0
    tau: float = 2.0
    skinning: str = "lbs"
    use_sega: bool = True
    use_descriptor: bool = True
    use_blend_shapes: bool = True
    weights: str = "residual"
    weight_prior: str = "nearest"
    static_blend: bool = False
    rest_drape: float = 0.0
    history: int = 0
    motion_input: str = "pose"
    ensemble: int = 1

    def __post_init__(self):
        ints = (
            "n_joints",
            "n_betas",
            "n_star",
            "feat_dim",
            "hidden",
            "heads",
            "enc_layers",
            "dec_layers",
            "f_enc",
            "window",
            "lstm_hidden",
            "ensemble",
        )
        for name in ints:
            v = getattr(self, name)
            if not isinstance(v, int) or isinstance(v, bool) or v < 1:
                raise InputError(f"ModelConfig.{name} must be a positive integer", got=v)
        if self.hidden % self.heads:
            raise InputError("ModelConfig.hidden must be divisible by heads", got=(self.hidden, self.heads))
        for name in ("alpha", "tau"):
            v = getattr(self, name)
            if not (isinstance(v, (int, float)) and v > 0):
                raise InputError(f"ModelConfig.{name} must be positive", got=v)
        if not isinstance(self.static_blend, bool):
            raise InputError("ModelConfig.static_blend must be true or false", got=self.static_blend)
        h = self.history
        if not isinstance(h, int) or isinstance(h, bool) or h < 0:
            raise InputError("ModelConfig.history must be a non-negative integer", got=h)
        d = self.rest_drape
        if not (isinstance(d, (int, float)) and not isinstance(d, bool) and 0.0 <= d <= 1.0):
            raise InputError("ModelConfig.rest_drape must be a number in [0, 1]", got=d)
        if self.skinning not in ("lbs", "dqs"):
            raise InputError("ModelConfig.skinning must be 'lbs' or 'dqs'", got=self.skinning)
        if self.motion_input not in ("pose", "heading"):
            raise InputError("ModelConfig.motion_input must be 'pose' or 'heading'", got=self.motion_input)
        if self.weights not in ("residual", "free"):
            raise InputError("ModelConfig.weights must be 'residual' or 'free'", got=self.weights)
        from ..body.transfer import WEIGHT_PRIORS

        if self.weight_prior not in WEIGHT_PRIORS:
            raise InputError(
                "ModelConfig.weight_prior is not a weight prior",
                expected=" | ".join(WEIGHT_PRIORS),
                got=self.weight_prior,
            )

    def to_json(self) -> str:
        return json.dumps(dataclasses.asdict(self), sort_keys=True)

    @classmethod
    def from_dict(cls, d: dict) -> ModelConfig:
        known = {f.name for f in dataclasses.fields(cls)}
        unknown = sorted(set(d) - known)
        if unknown:
            raise InputError("unknown ModelConfig fields", expected=", ".join(sorted(known)), got=", ".join(unknown))
        d = dict(d)
        d.setdefault("weights", "free")  # saved before residual weights existed
        d.setdefault("weight_prior", "nearest")  # saved before the inpainted prior existed
        return cls(**d)

    def replace(self, **kw) -> ModelConfig:
        return dataclasses.replace(self, **kw)
