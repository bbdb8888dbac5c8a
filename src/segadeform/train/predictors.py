"""The models ``segadeform eval`` compares, as predictors: ``predict(sample, body, asset) -> (T, N, 3)``.

* :class:`LBSPredictor`: the body's skinning weights carried to the garment by a non-learned prior (baseline (a)),
  optionally on the garment draped at rest (``lbs-drape``);
* :class:`CheckpointPredictor`: a ``.pt`` checkpoint run by torch;
* a model package: the runtime's :class:`segadeform.runtime.predictor.PackagePredictor` (onnxruntime), which the
  caller passes to :func:`make_predictor` (the runtime is a layer this one does not import).
"""

from __future__ import annotations

import abc
import os
from collections.abc import Callable
from pathlib import Path

import numpy as np

from ..body.drape import skinned_rest
from ..body.model import BodyModel
from ..body.transfer import WEIGHT_PRIORS, garment_weights, residual_log_weights, skin_garment
from ..dataset.store import Sample
from ..errors import FileFormatError, InputError
from ..geometry.features import vertex_features
from ..motion.motion import motion_windows

__all__ = [
    "Predictor",
    "LBSPredictor",
    "CheckpointPredictor",
    "SimulationPredictor",
    "make_predictor",
    "make_predictors",
]


class Predictor(abc.ABC):
    """``predict(sample, body, asset) -> (T, N, 3)``; see :func:`make_predictor`.  ``name``: its row in the report;
    ``spec``: what it was made from (``simulation``, ``lbs``, ``lbs-PRIOR``, ``FOLDER[:EFFECTS]``, ``X.pt``).
    Anything with these three members is a predictor (the runtime's
    :class:`segadeform.runtime.predictor.PackagePredictor`, which cannot import this torch layer, is one).
    ``body``: the body a learned model was trained on (:func:`segadeform.body.identity.body_label`), None when it
    does not say or learned nothing; :func:`~segadeform.train.evaluate.evaluate` refuses it on another body."""

    name: str = ""
    spec: str = ""
    body: dict | None = None

    @abc.abstractmethod
    def predict(self, s: Sample, body: BodyModel, asset) -> np.ndarray:
        """Shapes: -> (T, N, 3) vertices for every frame of ``s``."""


class LBSPredictor(Predictor):
    """LBS with the body's weights carried to the garment by ``prior`` (``lbs``: the closest body point,
    baseline (a); ``lbs-<prior>`` for every other prior of :data:`segadeform.body.transfer.WEIGHT_PRIORS`:
    ``lbs-inpaint``, ``lbs-idw``, ``lbs-gaussian``, ``lbs-smooth``, ``lbs-smooth-light``: the non-learned
    priors).  ``drape``: skin the garment moved that far toward its drape on the body at rest
    (:mod:`segadeform.body.drape`; ``lbs-drape`` is ``smooth`` with ``drape = 1``)."""

    def __init__(self, prior: str = "nearest", drape: float = 0.0):
        self.prior, self.drape = prior, float(drape)
        self._drapes: dict = {}  # per garment and shape, as the checkpoint predictor keeps them

    def predict(self, s, body, asset):
        betas = s.betas if s.betas.size else None
        w = garment_weights(s.rest, s.faces, body, betas, self.prior)
        rest = skinned_rest(s.rest, s.faces, body, betas, self.drape, self._drapes)
        return skin_garment(rest, w, body, s.poses, betas, s.trans)


class SimulationPredictor(Predictor):
    """The simulator's own frames (spec ``simulation``): no model, zero error by definition.  In an evaluation it
    puts the ground truth's penetration, pinched cloth and stretch in the same table as the models', so that a
    model's are read against what the simulator itself leaves (the cloth it keeps pinched where the body
    intersects itself, the edges it stretches)."""

    def predict(self, s, body, asset):
        return np.asarray(s.frames, np.float64).copy()


class CheckpointPredictor(Predictor):
    """A ``.pt`` checkpoint run by torch, as the exported graphs would run it."""

    def __init__(self, path):
        from ..model.network import checkpoint_body, load_checkpoint

        self.model = load_checkpoint(path).eval()
        self.body = checkpoint_body(path)
        self.cfg = self.model.cfg
        self._drapes: dict = {}

    def predict(self, s, body, asset):
        import torch

        c = self.cfg
        betas = s.betas if s.betas.size else None
        joints = body.rest_joints(betas)[0]
        b = np.zeros(c.n_betas, np.float32)
        b[: s.betas.size] = s.betas[: c.n_betas]
        t32 = lambda a: torch.as_tensor(np.asarray(a, np.float32))  # noqa: E731
        nbr, mask = torch.as_tensor(asset.nbr, dtype=torch.int64), torch.as_tensor(asset.mask, dtype=torch.bool)
        feats = vertex_features(asset.vertices, asset.faces, joints, normals=asset.normals.astype(np.float64))
        lw = None
        if self.model.residual:
            lw = t32(
                residual_log_weights(garment_weights(asset.vertices, asset.faces, body, betas, self.cfg.weight_prior))
            )
        with torch.no_grad():
            g = self.model.garment_encoder(t32(feats)[None], nbr, mask, t32(asset.descriptor)[None])[0]
            win = motion_windows(s.poses, c.window)
            hist = None
            if self.model.hist is not None:  # the history runs from the lead's first frame where the sample has one
                from .data import sample_history_inputs

                x, lead = sample_history_inputs(s)
                hist = self.model.history_states(t32(x)[None])[0, lead:]
            out = []
            for lo in range(0, len(s.poses), 16):
                hi = min(lo + 16, len(s.poses))
                n = hi - lo
                v, _, _ = self.model.deformer(
                    g,
                    t32(win[lo:hi]),
                    t32(b)[None].expand(n, -1),
                    t32(skinned_rest(s.rest, s.faces, body, betas, c.rest_drape, self._drapes)),
                    nbr,
                    mask,
                    t32(joints)[None].expand(n, -1, -1),
                    t32(s.trans[lo:hi]),
                    lw,
                    None if hist is None else hist[lo:hi],
                )
                out.append(v.numpy())
        return np.concatenate(out).astype(np.float64)


def make_predictor(name: str, spec: str, *, package: Callable[[str, str], Predictor] | None = None) -> Predictor:
    """``spec``: ``simulation`` (the simulator's own frames: :class:`SimulationPredictor`), ``lbs`` (closest-point
    weights) or ``lbs-<prior>`` (a non-learned weight prior of
    :data:`~segadeform.body.transfer.WEIGHT_PRIORS`: ``lbs-inpaint``, ``lbs-idw`` ...), a model package
    folder (optionally ``FOLDER:EFFECTS`` with effects as for ``segadeform run --effects``, e.g.
    ``pkg:-wrinkles``), or a ``.pt`` checkpoint.

    ``package(folder, effects)`` makes a package's predictor: the runtime's
    :class:`segadeform.runtime.predictor.PackagePredictor`, given by the caller (this layer does not import the
    runtime); without it a package spec is refused."""
    folder = eff = None
    if Path(spec).is_dir():
        folder, eff = spec, ""
    elif ":" in spec and Path(spec.rsplit(":", 1)[0]).is_dir():
        folder, eff = spec.rsplit(":", 1)
    if spec == "lbs":
        p: Predictor = LBSPredictor()
    elif spec == "simulation":
        p = SimulationPredictor()
    elif spec == "lbs-drape":
        p = LBSPredictor("smooth", drape=1.0)
    elif spec.startswith("lbs-") and spec[4:] in WEIGHT_PRIORS and spec[4:] != "nearest":
        p = LBSPredictor(spec[4:])
    elif folder is not None:
        if package is None:
            raise InputError(
                "a model package needs the runtime's predictor",
                expected="make_predictor(..., package=segadeform.runtime.predictor.PackagePredictor)",
                got=spec,
            )
        p = package(folder, eff)
    elif Path(spec).suffix == ".pt":
        p = CheckpointPredictor(spec)
    elif "/" in spec or os.sep in spec or spec.startswith("."):  # a path: one that is not there is named as such
        where = spec.rsplit(":", 1)[0] if ":" in spec and not Path(spec).exists() else spec
        raise FileFormatError(
            "no such model package folder or checkpoint" if not Path(where).exists() else "not a model package folder",
            path=where,
            expected="a model package folder (segadeform export) or a .pt checkpoint (segadeform train)",
        )
    else:
        raise InputError(
            "a model must be 'simulation', 'lbs', 'lbs-PRIOR' ("
            + ", ".join(f"lbs-{w}" for w in WEIGHT_PRIORS[1:])
            + ", lbs-drape), a model package folder or a .pt checkpoint",
            got=spec,
        )
    p.name, p.spec = name, spec
    return p


def make_predictors(specs: dict, *, package: Callable[[str, str], Predictor] | None = None) -> dict:
    """``{name: spec}`` -> ``{name: predictor}`` (:func:`make_predictor` for each, in order)."""
    return {n: make_predictor(n, s, package=package) for n, s in specs.items()}
