"""A model package as a predictor of ``segadeform eval`` (:mod:`segadeform.train.predictors`): the package's graphs
run by onnxruntime on a dataset sample, as ``segadeform run`` runs them (collisions and the cloth stage are the
evaluation's own post-processes)."""

from __future__ import annotations

import numpy as np

from segadeform.errors import InputError
from segadeform.motion.motion import motion_windows
from segadeform.settings import Effects, parse_effects

from .body import package_body
from .deformer import Deformer
from .package import ModelPackage

__all__ = ["PackagePredictor"]


class PackagePredictor:
    """``predict(sample, body, asset) -> (T, N, 3)`` of a model package folder with ``effects`` (as for
    ``segadeform run --effects``: changes to the package's default, collisions and cloth excluded); one thread.
    ``body``: the body the package poses, its model's (:func:`~segadeform.runtime.body.package_body`)."""

    name = ""
    spec = ""

    def __init__(self, path, effects: str = ""):
        self.pkg = ModelPackage(path, threads=1)
        self.cfg = self.pkg.config
        self.body = package_body(self.pkg)
        eff = Effects(skinning=self.cfg.get("skinning", "lbs"), collisions=False)
        if effects:
            eff = parse_effects(effects, eff)
            if eff.collisions:
                raise InputError("evaluate collisions with --push-out, not as a package effect", got=effects)
            if eff.cloth:
                raise InputError("evaluate the cloth stage with --cloth, not as a package effect", got=effects)
        self.deformer = Deformer(self.pkg, eff)

    def predict(self, s, body, asset):
        betas = s.betas if s.betas.size else None
        joints = body.rest_joints(betas)[0]
        P = self.deformer.encode(asset, joints, s.betas)
        lw = self.deformer.body_log_weights(asset, body, s.betas) if self.deformer.needs_body_weights else None
        out = []
        for lo in range(0, len(s.poses), 16):
            hi = min(lo + 16, len(s.poses))
            win = motion_windows(s.poses, self.deformer.window, start=lo, stop=hi)
            out.append(self.deformer.deform(P, asset, win, joints, s.trans[lo:hi], s.betas, log_wbody=lw))
        return np.concatenate(out).astype(np.float64)
