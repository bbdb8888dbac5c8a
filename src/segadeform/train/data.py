"""Dataset samples as training tensors: the garment asset (cached), motion windows, targets and body contact.

Samples come from one or several dataset roots (folders and read-only packs:
:class:`~segadeform.dataset.roots.DatasetRoots`).  Per (garment, body) pair the precompute runs once
and is cached in ``CACHE/asset-<hash>.npz``; per sample the closest body point and normal to every
simulated vertex (for the collision loss) are cached in ``CACHE/contact-<id>.npz`` when the sample
does not store them (packs never do).  ``CACHE`` is the roots' cache folder: the writable dataset
folder's ``cache/``, else the folder the caller gives (a run's own).
"""

from __future__ import annotations

import dataclasses
import hashlib
from pathlib import Path

import numpy as np
import torch

from ..body.collision import BodyCollider
from ..body.drape import skinned_rest
from ..body.model import BodyModel
from ..body.transfer import garment_weights
from ..dataset.mirror import mirror_sample
from ..dataset.roots import DatasetRoots, as_roots
from ..dataset.store import Sample
from ..geometry.mesh_ops import unique_edges
from ..geometry.precompute import PRECOMPUTE_VERSION, precompute_garment
from ..io.atomic import atomic_path
from ..io.garment_asset import GarmentAsset
from ..motion.fingerprint import joint_speeds
from ..motion.motion import history_inputs, motion_windows

__all__ = ["TrainItem", "load_items", "sample_asset", "sample_history_inputs"]


def sample_history_inputs(s: Sample) -> tuple[np.ndarray, int]:
    """``(x (L + T, 3 S + 3), L)``: a model's motion-history inputs (:func:`~segadeform.motion.history_inputs`)
    from the first frame of sample ``s``'s lead (L = 0 when it records none); ``x[L + t]`` is frame t."""
    lead_p = np.zeros((0, s.poses.shape[1])) if s.lead_poses is None else s.lead_poses
    lead_t = np.zeros((0, 3)) if s.lead_trans is None else s.lead_trans
    x = history_inputs(np.concatenate([lead_p, s.poses]), np.concatenate([lead_t, s.trans]), s.meta.get("fps", 30.0))
    return x, len(lead_p)


@dataclasses.dataclass
class TrainItem:
    """Everything one sample contributes (torch tensors, float32 unless stated)."""

    id: str
    meta: dict
    features: torch.Tensor  # (1, N, F)
    nbr: torch.Tensor  # (N, K) int64
    mask: torch.Tensor  # (N, K) bool
    descriptor: torch.Tensor  # (1, N*)
    betas: torch.Tensor  # (1, B)
    joints: torch.Tensor  # (S, 3)
    rest: torch.Tensor  # (N, 3) the garment as designed (rest lengths, stretch and shear)
    skin_rest: torch.Tensor  # (N, 3) the rest the deformer skins: ``rest`` moved toward its drape (rest_drape)
    faces: torch.Tensor  # (F, 3) int64
    edges: torch.Tensor  # (E, 2) int64
    windows: torch.Tensor  # (T, W, 3 S)
    history_in: torch.Tensor  # (L + T, 3 S + 3) the motion history's inputs from the lead's first frame
    lead: int  # L, frames simulated before frame 0 (history_in[lead + t] is frame t)
    lead_known: bool  # the sample records its lead (samples made before leads were recorded do not: L = 0)
    trans: torch.Tensor  # (T, 3)
    frames: torch.Tensor  # (T, N, 3)
    contact_p: torch.Tensor  # (T, N, 3) closest body point to the simulated vertex
    contact_n: torch.Tensor  # (T, N, 3) outward body normal there
    body_weights: torch.Tensor  # (N, S) the body's skinning weights carried to the garment (weight_prior)
    asset: GarmentAsset
    #: (T', J) the fingerprint of the sample's motion, lead and clip
    #: (:func:`~segadeform.motion.fingerprint.joint_speeds`): what a checkpoint records of the motions it was trained on
    motion_speeds: np.ndarray | None = None

    @property
    def n_frames(self) -> int:
        return int(self.frames.shape[0])

    def to(self, device) -> TrainItem:
        kw = {
            f.name: (
                getattr(self, f.name).to(device)
                if isinstance(getattr(self, f.name), torch.Tensor)
                else getattr(self, f.name)
            )
            for f in dataclasses.fields(self)
        }
        return TrainItem(**kw)


def _hash(*arrays) -> str:
    h = hashlib.sha256()
    for a in arrays:
        a = np.ascontiguousarray(a)
        h.update(str(a.dtype).encode() + str(a.shape).encode())
        h.update(a.tobytes())
    return h.hexdigest()[:24]


def _cache_dir(root) -> Path | None:
    """Where derived data of ``root`` (a dataset folder, or :class:`DatasetRoots`) is cached."""
    if isinstance(root, DatasetRoots):
        return root.cache_dir
    return Path(root) / "cache"


def sample_asset(root, s: Sample, body: BodyModel, n_star: int) -> GarmentAsset:
    """The garment precompute of sample ``s`` (cached in ``root``'s cache folder when it has one)."""
    joints = body.rest_joints(s.betas if s.betas.size else None)[0]
    key = _hash(s.rest, s.faces, joints, np.array([n_star, PRECOMPUTE_VERSION]))
    cache = _cache_dir(root)
    p = None if cache is None else cache / f"asset-{key}.npz"
    if p is not None and p.is_file():
        return GarmentAsset.load(p)
    a = precompute_garment(s.rest, s.faces, joints, n_star=n_star, source_name=s.meta.get("garment", s.id))
    if p is not None:
        p.parent.mkdir(parents=True, exist_ok=True)
        a.save(p)
    return a


def _contact(root, s: Sample, body: BodyModel, collider=None):
    """Closest body point and outward normal of every simulated vertex, (T, N, 3) twice: stored by
    ``dataset make``, else cached, else computed (exactly, with the compiled collider) and cached."""
    if s.contact_p is not None:  # stored by `dataset make`
        return s.contact_p, s.contact_n
    cache = _cache_dir(root)
    p = None if cache is None else cache / f"contact-{s.id}.npz"
    if p is not None and p.is_file():
        z = np.load(p)
        if z["p"].shape == s.frames.shape:
            return z["p"], z["n"]
    posed = body.forward(s.poses, s.betas if s.betas.size else None, s.trans).vertices
    cp = np.empty(s.frames.shape, np.float32)
    cn = np.empty(s.frames.shape, np.float32)
    collider = collider if collider is not None else BodyCollider(body.v_template, body.faces)
    for t in range(len(posed)):
        q = collider.query(s.frames[t].astype(np.float64), posed[t])
        cp[t], cn[t] = q.closest, q.normal
    if p is not None:
        p.parent.mkdir(parents=True, exist_ok=True)
        with atomic_path(p) as tmp:
            with open(tmp, "wb") as fh:
                np.savez(fh, p=cp, n=cn)
    return cp, cn


def load_items(
    root,
    body: BodyModel,
    *,
    n_star: int,
    window: int,
    n_betas: int,
    split: str | None = "train",
    ids=None,
    weight_prior: str = "nearest",
    rest_drape: float = 0.0,
    mirror: bool = False,
) -> list[TrainItem]:
    """Load every kept sample of ``split`` (or the given ``ids``) of ``root`` (a dataset folder, a pack, a list
    of roots or :class:`DatasetRoots`) as :class:`TrainItem`; ``body_weights`` by ``weight_prior``
    (:func:`~segadeform.body.transfer.garment_weights`), ``skin_rest`` by ``rest_drape``
    (:func:`segadeform.body.drape.skinned_rest`).  ``mirror``: each sample is followed by its left-right mirror
    image (:func:`~segadeform.dataset.mirror.mirror_sample`, id ``<id>~mirror``)."""
    memo: dict = {}
    f32 = lambda a: torch.as_tensor(np.asarray(a, np.float32))  # noqa: E731
    roots = as_roots(root)
    out = []
    collider = None
    for s in _samples(roots, ids if ids is not None else roots.ids(split), body.joint_names if mirror else None):
        sid = s.id
        if s.contact_p is None and collider is None:
            collider = BodyCollider(body.v_template, body.faces)
        a = sample_asset(roots, s, body, n_star)
        cp, cn = _contact(roots, s, body, collider)
        b = np.zeros(n_betas)
        b[: s.betas.size] = s.betas[:n_betas]
        joints = body.rest_joints(s.betas if s.betas.size else None)[0]
        win = motion_windows(s.poses, window)
        hist, lead = sample_history_inputs(s)
        bw = garment_weights(s.rest, s.faces, body, s.betas if s.betas.size else None, weight_prior)
        out.append(
            TrainItem(
                id=sid,
                meta=s.meta,
                features=f32(a.features)[None],
                nbr=torch.as_tensor(a.nbr, dtype=torch.int64),
                mask=torch.as_tensor(a.mask, dtype=torch.bool),
                descriptor=f32(a.descriptor)[None],
                betas=f32(b)[None],
                joints=f32(joints),
                rest=f32(s.rest),
                skin_rest=f32(skinned_rest(s.rest, s.faces, body, s.betas, rest_drape, memo)),
                faces=torch.as_tensor(s.faces, dtype=torch.int64),
                edges=torch.as_tensor(unique_edges(s.faces, len(s.rest)), dtype=torch.int64),
                windows=f32(win),
                history_in=f32(hist),
                lead=lead,
                lead_known=s.lead_poses is not None,
                trans=f32(s.trans),
                frames=f32(s.frames),
                contact_p=f32(cp),
                contact_n=f32(cn),
                body_weights=f32(bw),
                asset=a,
                motion_speeds=_motion_speeds(s),
            )
        )
    return out


def _motion_speeds(s: Sample) -> np.ndarray:
    """The fingerprint of sample ``s``'s motion: its lead (when it records one) and its clip."""
    lead = np.zeros((0, s.poses.shape[1])) if s.lead_poses is None else s.lead_poses
    return joint_speeds(np.concatenate([lead, s.poses]), float(s.meta.get("fps", 30.0)))


def _samples(roots, ids, mirror_joints):
    """The samples ``ids`` of ``roots``, each followed by its mirror image when ``mirror_joints`` names the
    skeleton's joints."""
    for sid in ids:
        s = roots.load(sid)
        yield s
        if mirror_joints is not None:
            yield mirror_sample(s, mirror_joints)
