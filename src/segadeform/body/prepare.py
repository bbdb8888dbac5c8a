"""A garment asset prepared for one body shape: every model input that only Python computes, so the Node, browser
and C++ runtimes animate it from a motion file alone (``segadeform garment export``; the fields:
:mod:`segadeform.io.garment_asset`)."""

from __future__ import annotations

import dataclasses

import numpy as np

from ..errors import InputError
from ..geometry.features import vertex_features
from ..io.garment_asset import GarmentAsset
from .identity import body_label
from .transfer import garment_weights, residual_log_weights

__all__ = ["prepare_for_body"]


def prepare_for_body(asset: GarmentAsset, body, betas=(), *, weight_prior: str = "nearest") -> GarmentAsset:
    """``asset`` prepared for ``body`` (a :class:`~segadeform.body.BodyModel`) of shape ``betas``: the
    rest joints, the encoder features for them and the body's log weights at the garment, carried by
    ``weight_prior`` (``nearest`` | ``inpaint``: the model's ``config.weight_prior``), computed as
    ``segadeform run`` computes them (so runtimes without Python reproduce its frames), plus ``betas``
    and the body's name, hash and the prior (``body``).  Neighbours, mask and descriptor do not depend on
    the body and are kept.

    Shapes:
        betas: (B',), B' <= body.n_betas
    """
    b = np.asarray(betas if betas is not None else [], np.float64).ravel()
    if b.size > body.n_betas or not np.isfinite(b).all():
        raise InputError(
            "betas must be finite and at most the body's count",
            expected=f"<= {body.n_betas}",
            got=b.size if b.size > body.n_betas else "NaN or inf",
        )
    full = np.zeros(body.n_betas)
    full[: b.size] = b
    joints = body.rest_joints(full)[0]
    if joints.shape != asset.joints.shape:
        raise InputError(
            "the body's skeleton has another number of joints than the asset's",
            expected=asset.joints.shape,
            got=joints.shape,
        )
    # as the runtime's encoder does: the normals as stored (float32), the joints of the shape
    feats = vertex_features(asset.vertices, asset.faces, joints, normals=asset.normals.astype(np.float64))
    # as Deformer.body_log_weights does: the shape rounded to the float32 the graphs take
    lw = residual_log_weights(garment_weights(asset.vertices, asset.faces, body, full.astype(np.float32), weight_prior))
    return dataclasses.replace(
        asset,
        features=feats.astype(np.float32),
        joints=joints.astype(np.float64),
        betas=full,
        log_wbody=np.asarray(lw, np.float32),
        body=dict(body_label(body), weight_prior=weight_prior),
    )
