"""A simulated sample's left-right mirror image: a second, equally valid sample at no simulation cost.

Cloth physics has no handedness: the mirror image of a garment simulated on a left-right symmetric body under a
motion is what the same solver gives (up to its chaos, ``docs/gpu-training.md``) for the mirrored garment on that
body under the mirrored motion.  Everything is reflected in the plane x = 0 (:mod:`segadeform.motion.mirror`):
the garment's rest and frames, the root's path, the poses with their left and right joints swapped, the stored
body contacts (points and normals), the lead; faces are wound the other way.  The body shape is kept: a training
run that mirrors checks its body is symmetric (:func:`body_asymmetry`).
"""

from __future__ import annotations

import dataclasses

import numpy as np

from ..motion.mirror import mirror_faces, mirror_joint_order, mirror_points, mirror_poses
from .store import Sample

__all__ = ["MIRROR_SUFFIX", "mirror_sample", "body_asymmetry"]

#: a mirrored sample's id is its original's with this suffix
MIRROR_SUFFIX = "~mirror"


def mirror_sample(s: Sample, joint_names) -> Sample:
    """The mirror image of sample ``s`` (poses in ``joint_names`` order): id ``s.id + MIRROR_SUFFIX``,
    ``meta["mirror_of"] = s.id``."""
    m = lambda x: None if x is None else mirror_points(x)  # noqa: E731
    return dataclasses.replace(
        s,
        id=s.id + MIRROR_SUFFIX,
        rest=mirror_points(s.rest),
        faces=mirror_faces(s.faces),
        poses=mirror_poses(s.poses, joint_names),
        trans=mirror_points(s.trans),
        frames=mirror_points(s.frames),
        meta={**s.meta, "mirror_of": s.id},
        contact_p=m(s.contact_p),
        contact_n=m(s.contact_n),
        cloth_rest=m(s.cloth_rest),
        lead_poses=None if s.lead_poses is None else mirror_poses(s.lead_poses, joint_names),
        lead_trans=m(s.lead_trans),
    )


def body_asymmetry(body, betas=None) -> float:
    """How far (m) the body shaped by ``betas`` (None: the template) is from its own mirror image at rest: the
    largest distance of a mirrored rest joint from its twin (joints decide the skinning a mirrored sample is trained
    with)."""
    j = np.asarray(body.rest_joints(betas)[0], np.float64)
    return float(np.linalg.norm(mirror_points(j)[mirror_joint_order(body.joint_names)] - j, axis=-1).max())
