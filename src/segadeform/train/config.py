"""Training configuration (TOML): model dimensions, loss weights, optimisation, data.

Example (``samples/train/continuum/light_prior_seed1.toml`` is the shipped model's recipe: ``full.toml`` on the
``smooth-light`` prior, seed 1; ``samples/train/default.toml`` an early model's)::

    base = "full.toml"             # optional, first: a config (relative to this file) whose tables this one
                                   # changes, table by table and key by key
    [data]
    dataset = "../../data/train"   # relative to this file; or a list of roots: folders and packs
                                   # (`train --dataset` replaces it and `optional`, not [physics] pairs)
    optional = ["../../../shared/data/sim"]  # roots read when they exist (the durable packs)
    split = "train"                # or several joined by "+" ("train+val": a final fit at a step count
                                   # chosen on val before, with no val_split)
    val_split = "val"              # held-out garments and motion families that choose the model ("": none)
                                   # (the checkpoint with the lowest vertex error on them is model.pt)
    exclude = []                   # sample ids matching any of these globs are not trained on
                                   # (e.g. ["*__cmu-*"]: no motion capture)
    fraction = 1.0                 # train on this share of the samples (a fixed subset by sample id)
    mirror = false                 # also train on each sample's left-right mirror image (twice the samples, no
                                   # simulation: segadeform.dataset.mirror; the body must be symmetric)

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
    collision_power = 2            # 2: mean squared depth (as before); 1: mean depth (m), the vertex term's unit
    collision_near = 0.0           # > 0: only vertices whose simulated position lies within this of the body (m),
                                   # where the plane at its closest body point stands for the body; 0: every vertex
    skin_prior = 1.0               # pull the skinning weights towards the body's (nearest point) ...
    skin_prior_until = 0.5         # ... fading out by half-way (NCS notes transferred weights speed convergence)
    terms_from = 0.0               # > 0: every term but vertex and skin_prior, and the physics pairs, counts only
                                   # from this fraction of the steps on (the vertex fit first; 0: from the start)
    collision_types = {}           # a garment type's own collision weight, e.g. { top = 10.0 } (others: collision)

    [optim]
    init = ""                      # a checkpoint (model.pt) to start from: fine-tuning a trained model on your own
                                   # samples (its [model] must be this config's; `train --init` gives it too)
    steps = 3000
    lr = 1e-3
    frames = 8                     # frames per garment per step
    garments = 1                   # garments per step (their losses averaged: one batch)
    seed = 0
    checkpoint_every = 200
    device = "auto"                # auto | cpu | cuda
    warmup = 0                     # linear learning-rate warm-up over this many steps, then the cosine decay
    seconds = 0                    # a time budget for the run, loading included (0: off): the warm-up steps
                                   # time the machine and fix the step count (at most `steps`) so the run ends
                                   # by then; needs warmup >= 20; train.json records the count (rerun it with
                                   # --steps N --seconds 0)
    weight_decay = 0.0             # decoupled weight decay (AdamW; 0: Adam as before): a residual model's
                                   # corrections shrink towards 0, which is its non-learned prior

    [physics]                      # self-supervision on pairs never simulated (segadeform.train.energies)
    pairs = "../datasets/continuum.toml"   # a dataset config: its training garments x bodies x motions
    every = 2                      # add a self-supervised term every `every` steps (0: off: the dataset's
                                   # samples alone)
    weight = 0.002                 # its weight; the energies are in metres of equivalent height
    frames = 5                     # consecutive frames per term (the first two are the history)
    density = 0.2                  # the cloth (segadeform.train.energies.Material)
    prefetch = false               # build the next pair in a background thread (own random stream)
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
import math
from pathlib import Path

import numpy as np

from ..errors import FileFormatError, InputError
from ..garments.make import GARMENT_TYPES
from ..io.toml import read_table, read_toml
from ..model.config import ModelConfig

BUDGET_PROBE_STEPS = 20  # warm-up steps that time the machine under optim.seconds (the first 5 are not counted)

__all__ = ["BUDGET_PROBE_STEPS", "LossWeights", "OptimConfig", "PhysicsConfig", "TrainConfig", "load_train_config"]


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
    collision_power: int = 2  # 2: mean squared depth below the margin; 1: mean depth (m)
    # > 0: the term counts only vertices whose simulated position is within this of the body (m): the tangent
    # plane at a far vertex's closest body point is no stand-in for the body (0: every vertex, as before)
    collision_near: float = 0.0
    skin_prior: float = 1.0  # mean squared distance of the skinning weights to the body's, transferred
    skin_prior_until: float = 0.5  # ... decaying linearly to 0 at this fraction of the steps
    # > 0: every term but ``vertex`` and ``skin_prior``, and the physics self-supervision, is off before this fraction
    # of the steps and at its weight from there on (the vertex fit first, the physical terms late); the validation
    # split chooses among the checkpoints after it (and the untrained model)
    terms_from: float = 0.0
    # garment type (``skirt``, ``dress``, ``top``, ``trousers``, ``jumpsuit``, ``open-front``) -> the collision weight
    # for samples of that type, in place of ``collision`` (types not named keep it): a tight top pays for every
    # millimetre inside the body, a skirt's hem for contact the tangent plane only stands in for
    collision_types: dict[str, float] = dataclasses.field(default_factory=dict)

    def collision_for(self, garment_type) -> float:
        """The collision weight for a sample of ``garment_type`` (``collision`` unless ``collision_types`` names it)."""
        return float(self.collision_types.get(garment_type, self.collision))


@dataclasses.dataclass(frozen=True)
class PhysicsConfig:
    """Self-supervised cloth energies on garment x body x motion pairs that were never simulated
    (:mod:`segadeform.train.energies`); ``every = 0`` (the default) turns them off."""

    pairs: str | None = None  # a dataset config (relative to the training config): its training pairs
    every: int = 0
    weight: float = 0.3
    frames: int = 5
    density: float = 0.2
    stretch: float = 2.0e4
    bending: float = 4.0e-5
    collision: float = 1.0e7
    margin: float = 0.003
    # build the next pair in a background thread while the current step runs (a GPU waits on the CPU's pair
    # otherwise); the pairs are then drawn from a stream of their own (seeded by optim.seed), one ahead
    prefetch: bool = False

    def __post_init__(self):
        if not isinstance(self.every, int) or isinstance(self.every, bool) or self.every < 0:
            raise InputError("physics.every must be an integer >= 0", got=self.every)
        if not isinstance(self.frames, int) or self.frames < 3:
            raise InputError("physics.frames must be an integer >= 3 (two frames of history)", got=self.frames)
        if self.every and not self.pairs:
            raise InputError("physics.every > 0 needs physics.pairs (a dataset config)")
        if not (isinstance(self.weight, (int, float)) and self.weight >= 0):
            raise InputError("physics.weight must be >= 0", got=self.weight)

    def material(self):
        from .energies import Material

        return Material(
            density=self.density,
            stretch=self.stretch,
            bending=self.bending,
            collision=self.collision,
            margin=self.margin,
        )


@dataclasses.dataclass(frozen=True)
class OptimConfig:
    steps: int = 3000
    lr: float = 1e-3
    frames: int = 8
    garments: int = 1  # garments per step
    seed: int = 0
    checkpoint_every: int = 200
    device: str = "auto"
    lr_final: float = 0.1  # cosine decay to lr * lr_final
    grad_clip: float = 1.0
    warmup: int = 0  # linear warm-up steps before the cosine decay (0: none)
    seconds: float = 0.0  # time budget of a run, loading included (0: off); the warm-up steps time the machine
    weight_decay: float = 0.0  # decoupled weight decay (AdamW): pulls the residual towards 0, i.e. the prior
    init: str = ""  # a checkpoint (model.pt) whose weights the run starts from: fine-tuning (relative to the config)

    def __post_init__(self):
        for k in ("steps", "frames", "garments", "checkpoint_every"):  # (checkpoint_every = 0: a modulo by zero)
            v = getattr(self, k)
            if not (isinstance(v, int) and not isinstance(v, bool) and v >= 1):
                raise InputError(f"optim.{k} must be an integer >= 1", got=v)
        for k in ("lr", "grad_clip"):
            v = getattr(self, k)
            if not (isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v) and v > 0):
                raise InputError(f"optim.{k} must be a number > 0", got=v)
        if not (isinstance(self.lr_final, (int, float)) and 0 <= self.lr_final <= 1):
            raise InputError("optim.lr_final must be a number in [0, 1]", got=self.lr_final)
        if not (
            isinstance(self.weight_decay, (int, float))
            and not isinstance(self.weight_decay, bool)
            and math.isfinite(self.weight_decay)
            and 0 <= self.weight_decay < 1
        ):
            raise InputError("optim.weight_decay must be a number in [0, 1)", got=self.weight_decay)
        if not (isinstance(self.warmup, int) and not isinstance(self.warmup, bool) and 0 <= self.warmup):
            raise InputError("optim.warmup must be an integer >= 0", got=self.warmup)
        if self.warmup > self.steps:
            raise InputError("optim.warmup must be at most optim.steps", expected=f"<= {self.steps}", got=self.warmup)
        if not (math.isfinite(self.seconds) and self.seconds >= 0):
            raise InputError("optim.seconds must be a finite number of seconds >= 0", got=self.seconds)
        if self.seconds > 0 and self.warmup < BUDGET_PROBE_STEPS:
            raise InputError(
                "optim.seconds (a time budget) needs the warm-up to time the machine before the step count is fixed",
                expected=f"optim.warmup >= {BUDGET_PROBE_STEPS}",
                got=self.warmup,
            )

    def lr_factor(self, step: int, total: int) -> float:
        """The learning rate at ``step`` as a fraction of ``lr``: a linear ramp over ``warmup`` steps, then a
        cosine decay to ``lr_final`` at ``total`` steps.  With ``warmup = 0`` it is the cosine alone, computed
        as it always was (the same bits: older runs resume and rerun exactly)."""
        if step < self.warmup:
            return (step + 1) / self.warmup
        span = max(total - self.warmup, 1)
        return self.lr_final + (1 - self.lr_final) * 0.5 * (
            1 + np.cos(np.pi * min(max(step - self.warmup, 0), span) / span)
        )

    def prior_fade(self, step: int, total: int, until: float) -> float:
        """The skinning-weight prior's weight at ``step`` as a fraction of its own (``until``: the fraction of
        the ``total`` steps at which it reaches 0).  It holds through the warm-up (whose steps never depend on the
        count), then falls linearly to 0 at ``until * total`` (at once when that comes before the warm-up ends);
        with ``warmup = 0`` it is the fade it always was."""
        end = until * total
        if not end > 0:
            return 0.0
        if step < self.warmup:
            return 1.0
        span = end - self.warmup
        return max(0.0, 1.0 - (step - self.warmup) / span) if span > 0 else 0.0

    def budget_steps(self, done: int, seconds_so_far: float, per_step: float) -> int:
        """The step count that fits :attr:`seconds` when ``done`` steps took ``seconds_so_far`` and one more
        takes ``per_step`` seconds, with 10 % of the time left kept in reserve (steps slow down when other
        processes share the machine; the trainer stops a run that would overrun all the same): at least
        ``done``, at most :attr:`steps`."""
        if not per_step > 0:
            return self.steps
        left = 0.9 * (self.seconds - seconds_so_far)
        return int(min(self.steps, max(done, done + int(left / per_step))))


@dataclasses.dataclass(frozen=True)
class TrainConfig:
    model: ModelConfig
    loss: LossWeights
    optim: OptimConfig
    dataset: tuple  # dataset roots (folders, packs, folders of packs)
    split: str = "train"
    optional: tuple = ()  # roots read where they exist
    val_split: str | None = None  # the split whose vertex error chooses the checkpoint
    physics: PhysicsConfig = PhysicsConfig()
    exclude: tuple = ()  # globs of sample ids left out of training
    fraction: float = 1.0  # share of the (remaining) samples trained on, by a hash of their ids
    mirror: bool = False  # each training sample is also trained on as its left-right mirror image
    pairs: Path | None = None  # physics.pairs resolved against the config's folder
    path: Path | None = None
    text: str = ""

    def digest(self) -> str:
        return hashlib.sha256(self.text.encode()).hexdigest()[:16]

    def select(self, ids) -> list:
        """The sample ids trained on: ``exclude`` globs removed, then the ``fraction`` whose id hashes
        lowest (a fixed subset: a smaller fraction is contained in a larger one)."""
        import fnmatch

        keep = [i for i in ids if not any(fnmatch.fnmatchcase(i, g) for g in self.exclude)]
        if self.fraction < 1.0:
            keep = sorted(keep, key=lambda i: hashlib.sha256(i.encode()).hexdigest())
            keep = sorted(keep[: max(1, int(round(self.fraction * len(keep))))])
        return keep

    def to_dict(self) -> dict:
        return {
            "model": dataclasses.asdict(self.model),
            "loss": dataclasses.asdict(self.loss),
            "optim": dataclasses.asdict(self.optim),
            "dataset": [str(d) for d in self.dataset],
            "optional": [str(d) for d in self.optional],
            "val_split": self.val_split,
            "split": self.split,
            "physics": dataclasses.asdict(self.physics),
            "exclude": list(self.exclude),
            "fraction": self.fraction,
            "mirror": self.mirror,
        }


def _table(data, name, cls, where):
    t = read_table(data.get(name, {}), cls, where=name, path=where)  # keys and types: the fields of cls
    try:
        return cls(**t)
    except (TypeError, InputError) as e:
        raise FileFormatError(f"[{name}]: {e}", path=where) from None


#: the first line of a run folder's copy of its config: relative paths are the original's (a copy reused as a config
#: looked for the dataset beside the run: a user's trial)
COPY_MARK = "# segadeform: relative paths in this copy are from "


def config_copy(path: Path) -> str:
    """The text of training config ``path`` as a run folder keeps it: the file as it is, after a first line naming
    the folder its relative paths are from (so the copy trains as the original does; the digest, of the tables,
    is the same)."""
    text = Path(path).read_text(encoding="utf-8")
    if text.startswith(COPY_MARK):
        return text
    return f"{COPY_MARK}{Path(path).resolve().parent}\n{text}"


def _folder(p: Path) -> Path:
    """The folder ``p``'s relative paths are from: its own, or the original's for a run folder's copy."""
    try:
        with open(p, encoding="utf-8") as fh:
            first = fh.readline().rstrip("\r\n")
    except (OSError, UnicodeDecodeError):
        return p.parent
    return Path(first[len(COPY_MARK) :]) if first.startswith(COPY_MARK) else p.parent


def _read_with_base(p: Path, seen=()) -> dict:
    """A config's tables with those of its ``base`` (another training config, relative to it) underneath:
    a table the config names replaces the base's keys it names, the rest stays the base's.  Paths in a
    base are resolved against the base's folder (made absolute here)."""
    data, _ = read_toml(p, "training config")
    base = data.pop("base", None)
    if base is None:
        return data
    if not isinstance(base, str):
        raise FileFormatError("base must be the path of another training config", path=p, got=base)
    bp = (_folder(p) / base).resolve()
    if bp in seen or bp == p.resolve():
        raise FileFormatError("training configs name each other as base", path=p, got=str(bp))
    if not bp.is_file():  # ("no such file" named the base, not the config that names it: a user's trial)
        raise FileFormatError("base names no training config", path=p, expected="an existing file", got=str(bp))
    under = _read_with_base(bp, (*seen, p.resolve()))
    # the base's relative paths are the base's: make them absolute before merging
    d = under.get("data", {})
    for key in ("dataset", "optional"):
        if key in d:
            v = d[key]
            d[key] = (
                [str((_folder(bp) / x).resolve()) for x in v]
                if isinstance(v, list)
                else str((_folder(bp) / v).resolve())
                if isinstance(v, str)
                else v
            )
    ph = under.get("physics", {})
    if isinstance(ph.get("pairs"), str):
        ph["pairs"] = str((_folder(bp) / ph["pairs"]).resolve())
    for table, values in data.items():
        if isinstance(values, dict) and isinstance(under.get(table), dict):
            under[table] = {**under[table], **values}
        else:
            under[table] = values
    return under


def load_train_config(path, *, dataset=None, overrides: dict | None = None) -> TrainConfig:
    """Read a training config; ``dataset`` (a root or a list of roots) replaces ``[data] dataset`` and
    ``optional`` (the roots given are the data);
    ``overrides`` maps ``"table.key"`` to values (e.g. ``{"optim.steps": 10}``).  A config may name a
    ``base`` config whose tables it changes (``base = "full.toml"`` and ``[optim] seed = 1``)."""
    p = Path(path)
    data = _read_with_base(p)
    root = _folder(p)
    for k, v in (overrides or {}).items():
        t, _, key = k.partition(".")
        data.setdefault(t, {})[key] = v
    bad = sorted(set(data) - {"data", "model", "loss", "optim", "physics"})
    if bad:
        raise FileFormatError(f"unknown table [{bad[0]}]", path=p, expected="data, model, loss, optim, physics")
    d = data.get("data", {})
    known = {"dataset", "split", "exclude", "fraction", "optional", "val_split", "mirror"}
    bad = sorted(set(d) - known)
    if bad:
        raise FileFormatError(f"unknown key data.{bad[0]}", path=p, expected=", ".join(sorted(known)))
    exclude = d.get("exclude", [])
    if not isinstance(exclude, list) or not all(isinstance(x, str) for x in exclude):
        raise FileFormatError("data.exclude must be a list of glob patterns", path=p, got=exclude)
    fraction = d.get("fraction", 1.0)
    if not isinstance(fraction, (int, float)) or isinstance(fraction, bool) or not 0 < fraction <= 1:
        raise FileFormatError("data.fraction must be in (0, 1]", path=p, got=fraction)

    mirror = d.get("mirror", False)
    if not isinstance(mirror, bool):
        raise FileFormatError("data.mirror must be true or false", path=p, got=mirror)

    def paths(v, key):
        v = [v] if isinstance(v, str) else v
        if not isinstance(v, list) or not all(isinstance(x, str) for x in v):
            raise FileFormatError(f"data.{key} must be a path or a list of paths", path=p, got=v)
        return tuple((root / x).resolve() for x in v)

    if dataset is None:
        if "dataset" not in d and "optional" not in d:
            raise FileFormatError("missing data.dataset (or pass a dataset folder)", path=p)
        dataset = paths(d.get("dataset", []), "dataset")
        optional = paths(d.get("optional", []), "optional")
    else:  # the roots given are the data: the config's own (required and optional) are not read
        dataset = tuple(Path(x) for x in ([dataset] if isinstance(dataset, (str, Path)) else dataset))
        optional = ()
    split = d.get("split", "train")
    parts = split.split("+") if isinstance(split, str) else []
    if not parts or not all(parts) or len(set(parts)) != len(parts):
        raise FileFormatError(
            "data.split must name a split, or several joined by '+'",
            path=p,
            expected='e.g. "train" or "train+val"',
            got=split,
        )
    val_split = d.get("val_split")
    if val_split == "":  # none: a config over a base that names one (a final fit on train+val)
        val_split = None
    if val_split is not None and (not isinstance(val_split, str) or val_split in parts):
        raise FileFormatError("data.val_split must name a split other than the training ones", path=p, got=val_split)
    model = _table(data, "model", ModelConfig, p)
    if model.ensemble != 1:
        raise FileFormatError(
            "model.ensemble: a run trains one network (segadeform ensemble A.pt B.pt ... averages trained ones)",
            path=p,
            expected=1,
            got=model.ensemble,
        )
    loss = _table(data, "loss", LossWeights, p)
    optim = _table(data, "optim", OptimConfig, p)
    if optim.init:  # resolved against the config's folder (the command line's --init is the caller's to resolve)
        init = (root / optim.init).resolve()
        if not init.is_file():
            raise FileFormatError("optim.init is not a file", path=p, expected="a checkpoint (model.pt)", got=str(init))
        optim = dataclasses.replace(optim, init=str(init))
    physics = _table(data, "physics", PhysicsConfig, p)
    pairs = (root / physics.pairs).resolve() if physics.pairs else None
    if physics.every and not pairs.is_file():
        raise FileFormatError("physics.pairs is not a file", path=p, got=str(pairs))
    if not 0.0 <= loss.terms_from < 1.0:
        raise FileFormatError(
            "loss.terms_from must be a fraction of the steps", path=p, expected="0 <= x < 1", got=loss.terms_from
        )
    if loss.collision_power not in (1, 2):
        raise FileFormatError("loss.collision_power must be 1 or 2", path=p, got=loss.collision_power)
    if not loss.collision_near >= 0:
        raise FileFormatError("loss.collision_near must be >= 0 (m)", path=p, got=loss.collision_near)
    known = sorted(set(GARMENT_TYPES.values()))
    for typ, v in loss.collision_types.items():
        if typ not in known:
            raise FileFormatError(
                "loss.collision_types: unknown garment type", path=p, expected=", ".join(known), got=typ
            )
        if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v) or v < 0:
            raise FileFormatError(f"loss.collision_types.{typ} must be a weight >= 0", path=p, got=v)
    if optim.device not in ("auto", "cpu", "cuda"):
        raise FileFormatError("optim.device must be auto, cpu or cuda", path=p, got=optim.device)
    if optim.steps < 1 or optim.frames < 1 or optim.garments < 1 or not optim.lr > 0:
        raise FileFormatError("optim.steps, optim.frames, optim.garments and optim.lr must be positive", path=p)
    return TrainConfig(
        model=model,
        loss=loss,
        optim=optim,
        dataset=dataset,
        split=split,
        optional=optional,
        val_split=val_split,
        physics=physics,
        pairs=pairs,
        exclude=tuple(exclude),
        fraction=float(fraction),
        mirror=mirror,
        path=p,
        text=json.dumps(data, sort_keys=True, default=str),
    )
