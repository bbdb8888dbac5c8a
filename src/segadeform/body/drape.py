"""A garment's drape on the body at rest: where its loose parts hang under gravity before any motion.

A garment is designed (or fitted) standing off the body -- a flared skirt's cone, a dress's bell -- and the
simulator lets it fall for half a second before the motion starts, so its loose parts hang lower and closer to
the legs than designed.  :func:`drape_rest` computes that hang without the simulator: the cloth stage
(:class:`segadeform.body.cloth.ClothStage`, position-based dynamics with strain limiting and tethers; its kernel
``_cloth.c`` names the sources) run on the body at rest with the designed garment as a constant target, no drive
toward it (``follow = 0``) and no bound on how far a loose vertex may leave it (``max_distance = 1``), until it
settles.  Vertices within ``attachment`` of the body at rest stay where they are (the waistband, the shoulders),
unless they are inside the body or closer than the contact margin (4 mm): the stage's push-out moves those out.

The result serves as a skinning prior (``lbs-drape``: the smoothed weights on the draped rest, no learning) and
as the rest the network skins when its config asks (``ModelConfig.rest_drape``).  Measured on
``data/continuum`` (``tools/drape_prior.py``): what it does depends on the design -- 21-30 % lower vertex error
than the designed rest on strongly flared skirts and dresses, a few percent higher on straight ones, whose
Blender cloth keeps more of its designed shape than this bending-free drape does (``docs/gpu-training.md``).
"""

from __future__ import annotations

import hashlib

import numpy as np

from ..errors import InputError
from ..geometry._checks import check_mesh
from ..settings.cloth import ClothSettings
from .cloth import ClothStage, garment_setup

__all__ = ["DRAPE_SETTINGS", "DRAPE_FRAMES", "drape_rest", "partial_drape", "skinned_rest"]

#: the cloth stage's settings for a drape: 16 sweeps a frame, no drive toward the designed shape, loose parts free,
#: no backstop (the drapes from before it existed).
#: A checkpoint trained with ``rest_drape`` was trained on drapes made with these: changing them changes its input.
DRAPE_SETTINGS = ClothSettings(iterations=16, damping=0.2, follow=0.0, max_distance=1.0, backstop=0.0)
#: frames of 1/30 s the drape runs (3 s: settled to well under a millimetre a frame on the continuum's garments)
DRAPE_FRAMES = 90


def drape_rest(
    rest, faces, rest_body, body_faces, *, settings: ClothSettings = DRAPE_SETTINGS, frames: int = DRAPE_FRAMES
) -> np.ndarray:
    """The garment ``rest``/``faces`` hung under gravity on the body at rest ``rest_body``/``body_faces``.

    Deterministic (the cloth kernel is).  A garment that lies on the body everywhere (every vertex within
    ``settings.attachment``) comes back unchanged.

    Shapes:
        rest: (N, 3); faces: (F, 3); rest_body: (V, 3); body_faces: (F', 3) -> (N, 3) float64
    """
    v, f = check_mesh(rest, faces)
    if len(f) == 0:
        raise InputError("a garment to drape needs faces", expected="F >= 1", got=0)
    frames = int(frames)
    if frames < 2:
        raise InputError("a drape runs at least 2 frames", got=frames)
    b = np.ascontiguousarray(rest_body, np.float64)
    stage = ClothStage(garment_setup(v, f, b, body_faces, settings), b, body_faces, settings)
    y = np.broadcast_to(np.asarray(v, np.float64), (frames,) + v.shape)
    return stage.step(y, np.broadcast_to(b, (frames,) + b.shape))[-1]


def partial_drape(rest, draped, amount: float) -> np.ndarray:
    """``rest + amount (draped - rest)``: ``amount`` 0 is the designed rest, 1 the drape.

    Shapes: rest, draped: (N, 3) -> (N, 3)"""
    amount = float(amount)
    if not (np.isfinite(amount) and 0.0 <= amount <= 1.0):
        raise InputError("the drape amount must be in [0, 1]", got=amount)
    rest = np.asarray(rest, np.float64)
    draped = np.asarray(draped, np.float64)
    if draped.shape != rest.shape:
        raise InputError("the drape must have the garment's shape", expected=rest.shape, got=draped.shape)
    return rest + amount * (draped - rest)


def skinned_rest(rest, faces, body, betas, amount: float, memo: dict | None = None) -> np.ndarray:
    """The rest a model with ``ModelConfig.rest_drape = amount`` skins: ``rest`` itself when ``amount`` is 0,
    else :func:`partial_drape` toward its drape on ``body`` (a :class:`~segadeform.body.model.BodyModel`) at rest,
    shaped by ``betas`` (None or empty: the template).  ``memo``: a dict that keeps drapes between calls, keyed
    by every input.  Shapes: rest (N, 3), faces (F, 3) -> (N, 3) float64"""
    rest = np.asarray(rest, np.float64)
    if not amount:
        return rest
    b = None if betas is None or not np.size(betas) else np.asarray(betas, np.float64).ravel()
    h = hashlib.sha256()
    for a in (rest, np.asarray(faces, np.int64), np.zeros(0) if b is None else b, np.array([float(amount)])):
        a = np.ascontiguousarray(a)
        h.update(str(a.shape).encode() + a.tobytes())
    key = h.hexdigest()
    if memo is not None and key in memo:
        return memo[key]
    out = partial_drape(rest, drape_rest(rest, faces, body.shaped_vertices(b)[0], body.faces), amount)
    if memo is not None:
        memo[key] = out
    return out
