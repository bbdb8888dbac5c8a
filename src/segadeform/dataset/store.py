"""One sample per ``.npz`` (arrays) beside a ``.json`` (metadata); both written atomically, the json last."""

from __future__ import annotations

import dataclasses
import json
from pathlib import Path

import numpy as np

from ..errors import FileFormatError, InputError, file_error, unreadable_error
from ..io.location import open_location
from ..io.npz import load_npz

__all__ = ["Sample", "save_sample", "load_sample", "list_samples", "SAMPLE_FOLDERS"]

#: where a dataset keeps samples that passed its quality gate, and those that did not
SAMPLE_FOLDERS = ("samples", "rejected")

_ARRAYS = {"rest": 2, "faces": 2, "betas": 1, "poses": 2, "trans": 2, "frames": 3}


@dataclasses.dataclass
class Sample:
    """rest (N, 3), faces (F, 3), betas (B,), poses (T, 72), trans (T, 3), frames (T, N, 3) float32, meta;
    optional contact_p, contact_n (T, N, 3), cloth_rest (N, 3) and the lead: lead_poses (L, 72), lead_trans (L, 3),
    the motion simulated before the first stored frame (what a model's motion history starts from)."""

    id: str
    rest: np.ndarray
    faces: np.ndarray
    betas: np.ndarray
    poses: np.ndarray
    trans: np.ndarray
    frames: np.ndarray
    meta: dict
    contact_p: np.ndarray | None = None  # (T, N, 3) closest body point to each simulated vertex
    contact_n: np.ndarray | None = None  # (T, N, 3) outward body normal there
    cloth_rest: np.ndarray | None = None  # (N, 3) the cloth's rest shape when it was not ``rest`` (A-pose)
    lead_poses: np.ndarray | None = None  # (L, 72) the motion simulated before frame 0 (dropped from the clip)
    lead_trans: np.ndarray | None = None  # (L, 3)


def save_sample(root, s: Sample, folder: str = "samples") -> bool:
    """Commit sample ``s`` to ``root`` (a folder, URL or :class:`~segadeform.io.location.Location`): the
    ``.npz`` first, then the ``.json`` that marks it done, once.  False (nothing written) when the
    sample's ``.json`` is there already: a sample is committed once, whichever attempt gets there first.
    ``folder``: ``samples`` (kept) or ``rejected`` (kept too, so that another gate can be applied later
    without simulating again: :func:`segadeform.dataset.make.regate`)."""
    if folder not in SAMPLE_FOLDERS:
        raise InputError("a sample lives in 'samples' or 'rejected'", got=folder)
    loc = open_location(root)
    meta_rel = f"{folder}/{s.id}.json"
    if loc.exists(meta_rel):
        return False
    with loc.writing(f"{folder}/{s.id}.npz") as tmp:
        with open(tmp, "wb") as fh:
            extra = (
                {}
                if s.contact_p is None
                else {"contact_p": s.contact_p.astype(np.float32), "contact_n": s.contact_n.astype(np.float32)}
            )
            if s.cloth_rest is not None:
                extra["cloth_rest"] = np.asarray(s.cloth_rest, np.float64)
            if s.lead_poses is not None and s.lead_trans is not None:
                extra["lead_poses"] = np.asarray(s.lead_poses, np.float32)
                extra["lead_trans"] = np.asarray(s.lead_trans, np.float32)
            np.savez(
                fh,
                rest=s.rest,
                faces=s.faces,
                betas=s.betas,
                poses=s.poses,
                trans=s.trans,
                frames=s.frames.astype(np.float32),
                **extra,
            )
    return loc.put_bytes(meta_rel, json.dumps(s.meta, indent=1, sort_keys=True).encode("utf-8"), once=True)


def load_sample(root: Path, sid: str, folder: str = "samples") -> Sample:
    if folder not in SAMPLE_FOLDERS:
        raise InputError("a sample lives in 'samples' or 'rejected'", got=folder)
    d = Path(root) / folder
    meta_p = d / f"{sid}.json"
    try:
        raw = meta_p.read_bytes()
    except OSError as e:
        raise file_error(e, meta_p, "sample metadata") from None
    try:
        meta = json.loads(raw)
    except json.JSONDecodeError as e:
        raise FileFormatError(f"sample metadata is not valid JSON ({e.msg})", path=meta_p, line=e.lineno) from None
    except ValueError as e:  # not UTF-8
        raise unreadable_error(e, meta_p, "sample metadata") from None
    z = load_npz(d / f"{sid}.npz")
    for k, nd in _ARRAYS.items():
        if k not in z or z[k].ndim != nd:
            raise FileFormatError(f"sample array {k!r} missing or not {nd}-D", path=d / f"{sid}.npz")
    contact = {}
    if "contact_p" in z and "contact_n" in z and z["contact_p"].shape == z["frames"].shape == z["contact_n"].shape:
        contact = {"contact_p": z["contact_p"], "contact_n": z["contact_n"]}
    if "cloth_rest" in z:
        if z["cloth_rest"].shape != z["rest"].shape:
            raise FileFormatError(
                "sample array 'cloth_rest' is not shaped like 'rest'",
                path=d / f"{sid}.npz",
                expected=z["rest"].shape,
                got=z["cloth_rest"].shape,
            )
        contact["cloth_rest"] = z["cloth_rest"]
    if "lead_poses" in z and "lead_trans" in z:
        lp, lt = z["lead_poses"], z["lead_trans"]
        if lp.ndim != 2 or lp.shape[1:] != z["poses"].shape[1:] or lt.shape != (lp.shape[0], 3):
            raise FileFormatError(
                "sample arrays 'lead_poses', 'lead_trans' are not (L, 72), (L, 3)",
                path=d / f"{sid}.npz",
                got=(lp.shape, lt.shape),
            )
        contact["lead_poses"], contact["lead_trans"] = lp, lt
    return Sample(id=sid, meta=meta, **{k: z[k] for k in _ARRAYS}, **contact)


def list_samples(root: Path, split: str | None = None) -> list[str]:
    """Ids of the kept samples (those with metadata), optionally of one split, sorted."""
    out = []
    for p in sorted((Path(root) / "samples").glob("*.json")):
        if split is None or json.loads(p.read_text()).get("split") == split:
            out.append(p.stem)
    return out
