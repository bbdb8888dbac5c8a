"""One sample per ``.npz`` (arrays) beside a ``.json`` (metadata); both written atomically, the json last."""

from __future__ import annotations

import dataclasses
import json
from pathlib import Path

import numpy as np

from ..errors import FileFormatError, InputError, file_error, unreadable_error
from ..io.location import open_location
from ..io.npz import load_npz

__all__ = ["Sample", "save_sample", "load_sample", "list_samples", "check_sample", "SAMPLE_FOLDERS"]

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


def check_sample(s: Sample, path, label: str = "sample", *, finite_frames: bool = True) -> Sample:
    """``s`` with every array's shape, index range and values checked against the others (a sample file edited or
    damaged by hand gave tracebacks deep in training or evaluation, or errors that named no file); each problem is
    one :class:`FileFormatError` naming ``path``, ``label`` and the array.  Returns ``s``.

    Shapes: rest (N, 3), faces (F, 3) in 0..N-1, betas (B,), poses (T, 3 S), trans (T, 3), frames (T, N, 3), T >= 1;
    the lead (L, 3 S) and (L, 3); every float finite (the frames only with ``finite_frames``: a rejected sample's
    simulation may have blown up, and is kept as it is)."""

    def bad(what, expected, got):
        raise FileFormatError(f"{label} array {what}", path=path, expected=expected, got=got)

    n = s.rest.shape[0] if s.rest.ndim == 2 else -1
    if s.rest.ndim != 2 or s.rest.shape[1] != 3 or n < 3:
        bad("'rest' has the wrong shape", "(N, 3), N >= 3", s.rest.shape)
    if s.faces.ndim != 2 or s.faces.shape[1] != 3 or len(s.faces) < 1:
        bad("'faces' has the wrong shape", "(F, 3), F >= 1", s.faces.shape)
    if not np.issubdtype(s.faces.dtype, np.integer):
        bad("'faces' is not integer", "integer vertex indices", str(s.faces.dtype))
    if s.faces.min() < 0 or s.faces.max() >= n:
        bad(
            "'faces' has an index out of range",
            f"0..{n - 1}",
            int(s.faces.max() if s.faces.max() >= n else s.faces.min()),
        )
    t = s.poses.shape[0] if s.poses.ndim == 2 else -1
    if s.poses.ndim != 2 or t < 1 or s.poses.shape[1] < 3 or s.poses.shape[1] % 3:
        bad("'poses' has the wrong shape", "(T, 3 S), T >= 1", s.poses.shape)
    if s.trans.shape != (t, 3):
        bad("'trans' does not match 'poses'", (t, 3), s.trans.shape)
    if s.frames.shape != (t, n, 3):
        bad("'frames' does not match 'poses' and 'rest'", (t, n, 3), s.frames.shape)
    if s.betas.ndim != 1:
        bad("'betas' has the wrong shape", "(B,)", s.betas.shape)
    if s.lead_poses is not None:
        if s.lead_poses.ndim != 2 or s.lead_poses.shape[1] != s.poses.shape[1]:
            bad(
                "'poses' and 'lead_poses' differ in width (one of them is damaged)",
                s.poses.shape[1:],
                s.lead_poses.shape[1:],
            )
        if s.lead_trans is None or s.lead_trans.shape != (len(s.lead_poses), 3):
            bad(
                "'lead_trans' does not match 'lead_poses'", (len(s.lead_poses), 3), getattr(s.lead_trans, "shape", None)
            )
    checked = ("rest", "betas", "poses", "trans", "cloth_rest", "lead_poses", "lead_trans")
    for k in checked + (("frames",) if finite_frames else ()):
        a = getattr(s, k)
        if a is not None and not np.isfinite(a).all():
            bad(f"{k!r} contains NaN or inf", "finite values", f"{int((~np.isfinite(a)).sum())} non-finite")
    return s


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
        contact["lead_poses"], contact["lead_trans"] = z["lead_poses"], z["lead_trans"]
    s = Sample(id=sid, meta=meta, **{k: z[k] for k in _ARRAYS}, **contact)
    return check_sample(s, d / f"{sid}.npz", finite_frames=folder == "samples")


def list_samples(root: Path, split: str | None = None) -> list[str]:
    """Ids of the kept samples (those with metadata), optionally of one split, sorted."""
    out = []
    for p in sorted((Path(root) / "samples").glob("*.json")):
        if split is None or json.loads(p.read_text()).get("split") == split:
            out.append(p.stem)
    return out
