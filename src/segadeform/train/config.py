"""Training configuration (TOML): model dimensions, loss weights, optimisation, data.

Example (``samples/train/default.toml`` is the shipped model's)::

    [data]
    dataset = "../../data/train"   # relative to this file
    split = "train"

    [model]                        # any ModelConfig field; alpha = tau = 2 is Table 1's best
    hidden = 32
    alpha = 2.0
    tau = 2.0

    [loss]                         # weights; 0 turns a term off
    vertex = 1.0                   # mean vertex distance to the simulation (m)
    normal = 0.1                   # 1 - cos between vertex normals
    edge = 1.0                     # |edge length - simulated edge length| (m)
    stretch = 0.1                  # edge strain against the rest garment (physics)
    shear = 0.05                   # change of triangle corner angles (physics)
    gravity = 0.0                  # gravitational potential (physics; see LossWeights)
    collision = 1.0                # depth inside the body plus a margin (physics)
    collision_margin = 0.002
    skin_prior = 1.0               # pull the skinning weights towards the body's (nearest point) ...
    skin_prior_until = 0.5         # ... fading out by half-way (NCS notes transferred weights speed convergence)

    [optim]
    steps = 3000
    lr = 1e-3
    frames = 8                     # frames per step (one garment per step)
    seed = 0
    checkpoint_every = 200
    device = "auto"                # auto | cpu | cuda
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
from pathlib import Path
from typing import Optional

from .._toml import read_toml
from ..errors import FileFormatError, InputError
from ..model.config import ModelConfig


__all__ = ["LossWeights", "OptimConfig", "TrainConfig", "load_train_config"]


@dataclasses.dataclass(frozen=True)
class LossWeights:
    """Loss weights.  ``gravity`` defaults to 0: with simulated targets the data term already holds
    gravity's effect, and the potential alone only pulls every vertex down (it is for training
    without targets, as PBNS/SNUG do)."""

    vertex: float = 1.0
    normal: float = 0.1
    edge: float = 1.0
    stretch: float = 0.1
    shear: float = 0.05
    gravity: float = 0.0
    collision: float = 1.0
    collision_margin: float = 0.002
    skin_prior: float = 1.0         # mean squared distance of the skinning weights to the body's, transferred
    skin_prior_until: float = 0.5   # ... decaying linearly to 0 at this fraction of the steps


@dataclasses.dataclass(frozen=True)
class OptimConfig:
    steps: int = 3000
    lr: float = 1e-3
    frames: int = 8
    seed: int = 0
    checkpoint_every: int = 200
    device: str = "auto"
    lr_final: float = 0.1       # cosine decay to lr * lr_final
    grad_clip: float = 1.0


@dataclasses.dataclass(frozen=True)
class TrainConfig:
    model: ModelConfig
    loss: LossWeights
    optim: OptimConfig
    dataset: Path
    split: str = "train"
    path: Optional[Path] = None
    text: str = ""

    def digest(self) -> str:
        return hashlib.sha256(self.text.encode()).hexdigest()[:16]

    def to_dict(self) -> dict:
        return {"model": dataclasses.asdict(self.model), "loss": dataclasses.asdict(self.loss),
                "optim": dataclasses.asdict(self.optim), "dataset": str(self.dataset), "split": self.split}


def _table(data, name, cls, where):
    t = data.get(name, {})
    known = {f.name for f in dataclasses.fields(cls)}
    bad = sorted(set(t) - known)
    if bad:
        raise FileFormatError(f"unknown key {name}.{bad[0]}", path=where, expected=", ".join(sorted(known)))
    try:
        return cls(**t)
    except (TypeError, InputError) as e:
        raise FileFormatError(f"[{name}]: {e}", path=where) from None


def load_train_config(path, *, dataset: Optional[Path] = None, overrides: Optional[dict] = None) -> TrainConfig:
    """Read a training config; ``dataset`` overrides ``[data] dataset``; ``overrides`` maps
    ``"table.key"`` to values (e.g. ``{"optim.steps": 10}``)."""
    p = Path(path)
    data, text = read_toml(p, "training config")
    for k, v in (overrides or {}).items():
        t, _, key = k.partition(".")
        data.setdefault(t, {})[key] = v
    bad = sorted(set(data) - {"data", "model", "loss", "optim"})
    if bad:
        raise FileFormatError(f"unknown table [{bad[0]}]", path=p, expected="data, model, loss, optim")
    d = data.get("data", {})
    if dataset is None:
        if "dataset" not in d:
            raise FileFormatError("missing data.dataset (or pass a dataset folder)", path=p)
        dataset = (p.parent / d["dataset"]).resolve()
    model = _table(data, "model", ModelConfig, p)
    loss = _table(data, "loss", LossWeights, p)
    optim = _table(data, "optim", OptimConfig, p)
    if optim.device not in ("auto", "cpu", "cuda"):
        raise FileFormatError("optim.device must be auto, cpu or cuda", path=p, got=optim.device)
    if optim.steps < 1 or optim.frames < 1 or not optim.lr > 0:
        raise FileFormatError("optim.steps, optim.frames and optim.lr must be positive", path=p)
    return TrainConfig(model=model, loss=loss, optim=optim, dataset=Path(dataset), split=d.get("split", "train"),
                       path=p, text=json.dumps(data, sort_keys=True, default=str))
