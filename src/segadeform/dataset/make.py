"""``segadeform dataset make``: plan, simulate, gate and store every sample, resumably and in parallel.

Layout of the output folder::

    DIR/config.toml             the config of the latest run (copied)
    DIR/configs/NNN.toml        every config the folder was made with, in order
    DIR/garments/G-bK.obj       garment G made for body K (rest pose) ...
    DIR/garments/G-bK.cloth.obj ... and made in the A-pose (the cloth's rest, with rest_pose = "a")
    DIR/garments/G-bK.json      what the garment was made from
    DIR/samples/ID.npz|.json    kept samples (arrays, metadata)
    DIR/rejected/ID.json        samples the quality gate rejected, with the reasons
    DIR/log.jsonl               one line per finished sample (kept or rejected), appended

A sample is done when its ``samples/ID.json`` or ``rejected/ID.json`` exists;
a killed run simply starts again and skips those.  Sample ids are
``G__bK__M`` (garment, body index, motion).

Where and how: ``DIR`` is a folder or an fsspec URL (:mod:`segadeform.io.location`; every file
committed whole, the ``.json`` that marks a sample done last and once), and the samples are
simulated by an executor (:mod:`segadeform.distributed.executors`: this machine's process pool by default, or
a Ray cluster).  Each sample is one task, a function of its spec alone: it returns the committed
record when its sample is done already, removes what a killed attempt of it left, and commits its
result; so a task retried after its worker died writes its sample once.  On a cluster, the
garments are made by this process into ``DIR`` first and read from there by the workers, the
files a config names (motion files, MakeHuman garments, the body) must be at the same path on
every worker, and a worker without the simulator environment makes one on first use
(:func:`segadeform.physics.setup.ensure_sim_python`).

A dataset grows over many runs: run again with more entries or a larger
``count`` and only the new samples are made.  Each sample records a digest of
everything that defines it (garment, body shape, motion, clip, simulation
settings of the attempt that made it: the ``[simulate]`` table or one of the ``[[fallback]]``
tables tried in turn on a sample the gate rejects); a run whose config gives a finished sample id another meaning
(an entry's parameters changed under the same name, bodies reordered) stops
before simulating anything and names the ids -- rename the entry instead.
"""

from __future__ import annotations

import contextlib
import dataclasses
import fnmatch
import functools
import hashlib
import json
import logging
import os
import tempfile
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np

from ..body.model import BodyModel, default_body_path, load_body
from ..body.skeleton import default_rest_joints
from ..distributed.executors import Executor, LocalExecutor
from ..errors import InputError, SegadeformError
from ..garments import GARMENT_TYPES, make_garment
from ..io import Mesh, read_mesh, write_obj
from ..io.hashing import file_sha256
from ..io.location import LocalLocation, Location, open_location
from ..io.obj import recorded_params
from ..motion import face_forward, load_motion, make_motion, resample
from ..motion.motion import drop_leading_glitches, drop_leading_jumps, drop_leading_tpose, ramp_in, repair_glitches
from ..physics.fbx import FBX_EXTENSIONS, fbx_cached_bvh
from .config import SPLITS, DatasetConfig, GarmentSpec, MotionEntry
from .quality import BodyParts, body_anchors, frame_stats, kept_frames, on_body_at_rest
from .store import Sample, load_sample, save_sample

log = logging.getLogger(__name__)

__all__ = [
    "PlannedSample",
    "sample_plan",
    "make_dataset",
    "DatasetSummary",
    "sample_spec",
    "sample_specs",
    "check_splits",
    "make_order",
    "regate",
    "RegateSummary",
    "config_training_motions",
]


@dataclasses.dataclass(frozen=True)
class PlannedSample:
    id: str
    garment: int
    body: int
    motion: int
    split: str


def sample_plan(cfg: DatasetConfig) -> list[PlannedSample]:
    """Every sample the config asks for, in a stable order (see the config's split rules)."""
    out = []
    bsplit = cfg.body_splits or ("train",) * len(cfg.bodies)
    for gi, g in enumerate(cfg.garments):
        for bi, betas in enumerate(cfg.bodies):
            if not g.sits_on(betas):  # a garment OBJ: only on the shape it was made for
                continue
            for mi, m in enumerate(cfg.motions):
                if g.split == m.split == "test":
                    split = "test"
                elif g.split == m.split == "val" and bsplit[bi] != "test":
                    split = "val"  # validation: its garments and motions, on bodies the test split does not hold
                elif g.split == m.split == bsplit[bi] == "train":
                    split = "train"
                elif not cfg.cross_splits or "val" in (g.split, m.split, bsplit[bi]):
                    continue
                elif g.split == "test":
                    split = "test-garment"
                elif m.split == "test":
                    split = "test-motion"
                else:
                    split = "test-body"
                out.append(PlannedSample(f"{g.name}__b{bi}__{m.name}", gi, bi, mi, split))
    return out


def split_group(split: str) -> str:
    """The split of :data:`.config.SPLITS` (what ``dataset make --split`` chooses among) that a planned sample's
    split belongs to: a ``test-*`` split of ``cross_splits`` is ``test``."""
    return "test" if split.startswith("test") else split


#: with ``order = "spread"``: training samples made between two held-out ones
SPREAD_TRAIN_PER_HELD_OUT = 2


def make_order(cfg: DatasetConfig, plan: list[PlannedSample]) -> list[PlannedSample]:
    """The order ``plan`` is made in, by ``cfg.order``:

    * ``"body-major"``: held-out samples first, then body, motion, garment -- a run stopped early still
      has every garment and motion of the bodies it reached, and a complete test split;
    * ``"spread"``: held-out and training samples each by a hash of the sample's name (fixed,
      pseudo-random), one held-out sample after every ``dataset.spread`` (default
      :data:`SPREAD_TRAIN_PER_HELD_OUT`) training ones
      until the held-out ones are done: any prefix -- a dataset grown by ``--limit`` runs -- covers
      every garment, body and motion about evenly, with test data and training data from the start.
    """
    if cfg.order != "spread":
        return sorted(plan, key=lambda p: (p.split == "train", p.body, p.motion, p.garment))
    h = lambda p: hashlib.sha256(p.id.encode()).hexdigest()  # noqa: E731
    held = sorted((p for p in plan if p.split != "train"), key=h)
    train = sorted((p for p in plan if p.split == "train"), key=h)
    # one held-out sample, then k training ones, until the held-out are done
    out, k = [], cfg.spread or SPREAD_TRAIN_PER_HELD_OUT
    for i, p in enumerate(held):
        out.append(p)
        out.extend(train[i * k : (i + 1) * k])
    return out + train[len(held) * k :]


def _family(m: MotionEntry) -> str:
    return m.family or (m.file.stem if m.file is not None else str(m.kind))


def check_splits(cfg: DatasetConfig, plan: list[PlannedSample]) -> None:
    """Raise :class:`InputError` if a sample leaks into a split it must not see:

    * a ``train`` sample uses anything held out for validation or test: such a garment, motion or
      body, a ``held_out_kinds`` / ``val_kinds`` garment kind, a ``held_out_motions`` /
      ``val_motions`` family, a motion family, motion file or MakeHuman garment a held-out entry uses;
    * a ``val`` sample uses anything of the test split (garment, motion, body, kind, family, file).
    """
    bsplit = cfg.body_splits or ("train",) * len(cfg.bodies)
    held = {
        sp: (
            {m.file for m in cfg.motions if m.split == sp and m.file is not None},
            {g.mhclo for g in cfg.garments if g.split == sp and g.mhclo is not None}
            | {g.mesh for g in cfg.garments if g.split == sp and g.mesh is not None},
            {_family(m) for m in cfg.motions if m.split == sp},
        )
        for sp in ("val", "test")
    }
    kinds = {"val": set(cfg.val_kinds), "test": set(cfg.held_out_kinds)}
    families = {"val": set(cfg.val_motions), "test": set(cfg.held_out_motions)}
    for p in plan:
        if p.split not in ("train", "val"):
            continue
        g, m = cfg.garments[p.garment], cfg.motions[p.motion]
        names = {_family(m), *((m.file.stem, m.file.name) if m.file is not None else (m.kind,))}
        for other in ("val", "test") if p.split == "train" else ("test",):
            files, mhclo, fams = held[other]
            what = "held-out" if other == "test" else "validation"
            bad = [
                why
                for why, leak in (
                    (f"a {what} garment", g.split == other),
                    (f"a {what} motion", m.split == other),
                    (f"a {what} body", bsplit[p.body] == other),
                    (f"a {what} garment kind", g.kind in kinds[other]),
                    (f"a {what} motion family", bool(names & (families[other] | fams))),
                    (f"a {what} motion file", m.file is not None and m.file in files),
                    (f"a {what} MakeHuman garment", g.mhclo is not None and g.mhclo in mhclo),
                    (f"a {what} garment mesh", g.mesh is not None and g.mesh in mhclo),
                )
                if leak
            ]
            if bad:
                raise InputError(f"{'training' if p.split == 'train' else 'validation'} sample {p.id} uses {bad[0]}")


def _digest(obj) -> str:
    return hashlib.sha256(json.dumps(obj, sort_keys=True, default=str).encode()).hexdigest()[:16]


@functools.lru_cache(maxsize=4096)
def _content_id(path: str, size: int, mtime_ns: int) -> str:
    return f"{Path(path).name}:{file_sha256(path)[:16]}"


def file_identity(path) -> str:
    """A file as a sample's spec names it: its name and a hash of its bytes, never where it lies, so a dataset
    (and its packs) made beside one checkout is the same dataset beside another (``../shared`` elsewhere)."""
    p = Path(path)
    try:
        st = p.stat()
        if not p.is_file():
            raise IsADirectoryError(21, "not a file")
        return _content_id(str(p), st.st_size, st.st_mtime_ns)
    except OSError as e:
        raise InputError(
            f"a file the dataset config names cannot be read ({e.strerror})", path=p, expected="a readable file"
        ) from None


def _garment_params(g: GarmentSpec) -> dict:
    """The garment's parameters as plain data; ``waist_ease`` (added later) only when set, so the specs of
    samples made before it do not change."""
    d = dataclasses.asdict(g.params)
    if d.get("waist_ease") is None:
        d.pop("waist_ease", None)
    return d


def _garment_key(g: GarmentSpec) -> dict:
    """What makes the garment; ``decimate`` (added later) only when set, so the specs of samples made before it
    do not change."""
    key = {
        "kind": g.kind,
        "params": _garment_params(g),
        "pin": g.pin,
        "mhclo": file_identity(g.mhclo) if g.mhclo else None,
    }
    if g.decimate is not None:
        key["decimate"] = g.decimate
    if g.mesh is not None:
        key["mesh"] = file_identity(g.mesh)
    return key


def _spec_dict(cfg: DatasetConfig, p: PlannedSample, attempt: int = 0) -> dict:
    """What :func:`sample_spec` digests, by part."""
    g, m = cfg.garments[p.garment], cfg.motions[p.motion]
    mo = dataclasses.asdict(m)
    mo.pop("split")
    mo.pop("family")  # a label for splitting, not data
    if m.file is not None:
        mo["file"] = file_identity(m.file)  # what the file holds, not where this machine keeps it
    st = cfg.attempt_settings(g, attempt)
    return {
        "garment": _garment_key(g),
        "betas": list(cfg.bodies[p.body]),
        "motion": mo,
        "fps": cfg.fps,
        "seconds": cfg.seconds,
        "simulate": st.to_dict(),
    }


def sample_spec(cfg: DatasetConfig, p: PlannedSample, attempt: int = 0) -> str:
    """A digest of everything that defines sample ``p``'s data: garment, body shape, motion and clip,
    frame rate and length, the simulation settings of its attempt ``attempt`` (:meth:`DatasetConfig.attempt_settings`;
    not the quality gate, which only keeps or rejects).  Attempt 0's digest does not depend on the fallbacks."""
    return _digest(_spec_dict(cfg, p, attempt))


def sample_spec_parts(cfg: DatasetConfig, p: PlannedSample, attempt: int = 0) -> dict:
    """A digest of each part of :func:`sample_spec` (``garment``, ``betas``, ``motion``, ``fps``, ``seconds``,
    ``simulate``): a sample's record keeps them, so that a run told the config changed says what changed."""
    return {k: _digest(v) for k, v in _spec_dict(cfg, p, attempt).items()}


def sample_specs(cfg: DatasetConfig, p: PlannedSample) -> list[str]:
    """:func:`sample_spec` of each attempt of sample ``p``, in order."""
    return [sample_spec(cfg, p, a) for a in range(cfg.attempts)]


LEAD_SECONDS = 1.0  # of a motion file, simulated before a clip and dropped: the cloth enters it in motion
#: how many entries with clips shorter than [dataset] seconds a run names (the others are counted)
SHORT_SAID = 3
RAMP_MIN_SECONDS = 0.3  # a clip with less capture before it starts this far in, the body ramped up from rest


def _capture(m: MotionEntry, cfg: DatasetConfig, rest_joints=None):
    """Motion file entry ``m`` as its clips are cut from it: retargeted onto ``rest_joints``, the frames in front
    of the capture and its glitches dealt with (:func:`_motion`), at the dataset's frame rate."""
    f = Path(m.file)
    if f.suffix.lower() in FBX_EXTENSIONS:  # read as the BVH Blender makes of it (once: the user cache), +Y up
        with fbx_cached_bvh(f) as bvh:  # (named as the FBX file: the motion's name is its stem)
            try:
                mo = load_motion(bvh, rest_joints=rest_joints, floor=True, up="y")
            except InputError as e:
                if e.path is None or Path(e.path) != bvh:
                    raise
                why = e.problem + " (read from the BVH Blender wrote of it)"
                raise type(e)(why, path=f, expected=e.expected, got=e.got) from None
    else:
        mo = load_motion(f, rest_joints=rest_joints, floor=True)
    joints = default_rest_joints() if rest_joints is None else np.asarray(rest_joints, np.float64)
    mo, _ = drop_leading_jumps(mo)  # a T-pose put in front of the capture (cgspeed's CMU BVH)
    mo, _ = drop_leading_glitches(mo, joints)  # frames the capture's solve settles from
    mo, _ = drop_leading_tpose(mo)  # a calibration T-pose held at the start of the capture
    mo, _ = repair_glitches(mo, joints)  # frames it jumps to and back from (swapped markers)
    if abs(mo.fps - cfg.fps) > 1e-9:
        mo = resample(mo, cfg.fps)
    return mo


def _clip_start(m: MotionEntry, cfg: DatasetConfig, mo, mi: int | None = None) -> int:
    """The frame of capture ``mo`` (:func:`_capture`) where entry ``m``'s clip begins: ``start``, or at least
    RAMP_MIN_SECONDS in.  A start past the end of the file is refused (``mi``: the entry's index in
    ``cfg.motions``, to name its table and line)."""
    what, line = cfg.motion_where(mi) if mi is not None else (f"motion {m.name!r}", None)
    if mi is not None:
        what += f" ({m.name})"
    if int(round(m.start * cfg.fps)) >= mo.n_frames - 1:  # was clamped to the last frame: a 1-frame sample, kept
        raise InputError(
            f"{what}: start is past the end of its file",
            path=cfg.path,
            line=line,
            expected=f"start < {(mo.n_frames - 1) / cfg.fps:.2f} s (the clip {m.file.name} is "
            f"{mo.n_frames / cfg.fps:.2f} s once its settling frames are dropped)",
            got=f"start = {m.start:g}",
        )
    a = int(round(m.start * cfg.fps))
    if a < int(round(LEAD_SECONDS * cfg.fps)):  # the clip starts at least RAMP_MIN_SECONDS in (with or without lead)
        a = max(1, min(max(a, int(round(RAMP_MIN_SECONDS * cfg.fps))), mo.n_frames - 2))
    return a


def check_clips(cfg: DatasetConfig, pairs, body: BodyModel, captures: dict | None = None) -> list[str]:
    """Check, before anything is simulated, the clip of each motion file entry on each body it is planned on
    (``pairs``: ``(motion, body)`` indices of the samples to make; a file is read once per body shape).  A start
    past the end of the file is refused.  A clip shorter than ``[dataset] seconds`` is what the file holds: returned,
    one line per entry, for the caller to say (it went unsaid).  Such a clip is not refused even under ``[quality]
    min_frames``: the gate keeps a clip that passes whole at any length (``min_frames`` bounds only the leading
    frames kept of a clip that fails), and the shipped datasets have such clips (a 19-frame clip of continuum.toml's
    ``cmu-127_02-1``, kept; refusing it refused the whole main job, a review found)."""
    want = int(round(cfg.seconds * cfg.fps))
    captures = {} if captures is None else captures  # (file, betas) -> the capture as read: a caller's to reuse
    short: dict = {}
    for mi, bi in sorted(set(pairs)):
        m = cfg.motions[mi]
        if m.file is None:  # generated to the length
            continue
        betas = cfg.bodies[bi]
        k = (str(m.file), tuple(betas))
        if k not in captures:
            captures[k] = _capture(m, cfg, body.rest_joints(betas or None)[0])
        mo = captures[k]
        a = _clip_start(m, cfg, mo, mi)
        have = mo.n_frames - a
        if have >= want:
            continue
        what, line = cfg.motion_where(mi)
        length = f"{m.file.name} is {mo.n_frames / cfg.fps:.2f} s once its settling frames are dropped"
        short.setdefault(
            mi,
            f"{cfg.path}{'' if line is None else f':{line}'}: {what} ({m.name}): start = {m.start:g} s leaves a clip "
            f"of {have} frames ({have / cfg.fps:.2f} s), not the {want} of [dataset] seconds = {cfg.seconds:g} "
            f"({length}): its samples are that much shorter",
        )
    return list(short.values())


def _motion(m: MotionEntry, cfg: DatasetConfig, rest_joints=None, *, with_lead: bool = False, captured=None):
    """The sample's motion.  ``with_lead``: ``(motion, lead)`` where the motion starts ``lead`` frames
    before the clip (LEAD_SECONDS of the file before ``start``): motion capture starts mid-stride, and
    cloth blended from rest straight into a running body lags and ends up inside it; the lead frames are
    simulated and dropped.  A clip with less capture before it starts at least RAMP_MIN_SECONDS in, and its
    lead is that capture played from rest with the speed ramping up (:func:`~segadeform.motion.motion.ramp_in`).
    A T-pose frame in front of a capture, the frames its solve settles from and a calibration T-pose held at its
    start are dropped first, and frames it jumps to and back from are rebuilt
    (:func:`~segadeform.motion.motion.drop_leading_jumps`, :func:`~segadeform.motion.motion.drop_leading_glitches`,
    :func:`~segadeform.motion.motion.drop_leading_tpose`, :func:`~segadeform.motion.motion.repair_glitches`)."""
    if m.kind is not None:
        # a procedural motion with no ease-in starts at full speed: it gets the same lead, its first
        # LEAD_SECONDS simulated and dropped (one that eases in from rest needs none)
        lead = int(round(LEAD_SECONDS * cfg.fps)) if with_lead and m.ease_in == 0 else 0
        mo = make_motion(
            m.kind,
            seconds=cfg.seconds + lead / cfg.fps,
            fps=cfg.fps,
            speed=m.speed,
            amplitude=m.amplitude,
            seed=m.seed,
            ease_in=m.ease_in,
        )
        if not with_lead:  # the clip itself (what a sample stores), as with the lead dropped
            return dataclasses.replace(mo, poses=mo.poses[lead:], trans=mo.trans[lead:])
        return mo, lead
    mo = _capture(m, cfg, rest_joints) if captured is None else captured  # (check_clips read it already)
    a = _clip_start(m, cfg, mo)
    full = int(round(LEAD_SECONDS * cfg.fps))
    short = int(round(m.start * cfg.fps)) < full  # less capture before the clip than a lead needs
    # (a clip shorter than [dataset] seconds is refused before a run simulates anything: check_clips; a sample made
    # before that has what its file held)
    n = min(mo.n_frames - a, int(round(cfg.seconds * cfg.fps)))
    if with_lead and short:
        # the body sets off from rest instead: the capture up to the clip's start played slowed (ramp_in),
        # over twice its length; the clip starts where the normal speed takes over
        mo = ramp_in(mo, a / cfg.fps)
        a = lead = 2 * a
    else:
        lead = min(a, full) if with_lead else 0
    # the lead's first frame is where the simulation's rest pose stands: facing +Z above x = z = 0
    clip = face_forward(dataclasses.replace(mo, poses=mo.poses[a - lead : a + n], trans=mo.trans[a - lead : a + n]), 0)
    return (clip, lead) if with_lead else clip


def config_training_motions(configs) -> dict:
    """The record of the motions the training split of each dataset config (a path) plays, lead and clip as
    :func:`_motion` cuts them, on the default body (:func:`segadeform.motion.fingerprint.motions_record`; the
    fingerprint barely depends on the body: under 0.001 between body shapes).  What ``export --training-motions``
    records for a model trained on those datasets."""
    from ..motion.fingerprint import joint_speeds, motions_record
    from .config import load_dataset_config

    rest = load_body(default_body_path()).rest_joints(None)[0]
    names, speeds = [], []
    for c in configs:
        cfg = load_dataset_config(c)
        for mi in sorted({p.motion for p in sample_plan(cfg) if p.split == "train"}):
            mo, _ = _motion(cfg.motions[mi], cfg, rest, with_lead=True)
            names.append(cfg.motions[mi].name)
            speeds.append(joint_speeds(mo.poses, mo.fps))
    if not names:
        raise InputError("the dataset configs plan no training samples", got=", ".join(str(c) for c in configs))
    return motions_record(names, speeds)


def _without_lead(motion, lead: int):
    """The clip a sample stores: the motion simulated (:func:`_motion` with its lead) less its lead frames."""
    return dataclasses.replace(motion, poses=motion.poses[lead:], trans=motion.trans[lead:])


def _garment_rel(cfg: DatasetConfig, gi: int, bi: int) -> str:
    return f"garments/{cfg.garments[gi].name}-b{bi}.obj"


def _cloth_rel(rel: str) -> str:
    return rel[: -len(".obj")] + ".cloth.obj"


def _garment_file(out, cfg: DatasetConfig, gi: int, bi: int, body: BodyModel) -> str:
    """Make the garment's rest-pose OBJ in ``out`` (once per garment and body; done by the process that
    plans the run, before any task starts); with ``rest_pose = "a"`` a procedural garment is also made
    in the A-pose, ``G-bK.cloth.obj`` beside it (same vertices).  Returns its path inside ``out``."""
    from ..physics.blender import A_POSE

    loc = open_location(out)
    g = cfg.garments[gi]
    rel = _garment_rel(cfg, gi, bi)
    key_rel = rel[: -len(".obj")] + ".json"
    if g.mhclo is not None and not Path(g.mhclo).is_file() and loc.exists(rel) and loc.exists(key_rel):
        # made where the MakeHuman file was (a cache carried to a machine without ../shared): used as it is when
        # its key says the same garment, body and pose, the file named alike (its bytes cannot be checked here)
        old = json.loads(loc.read_text(key_rel))
        want = {"garment": {**_garment_key(dataclasses.replace(g, mhclo=None)), "mhclo": None}}
        want.update(betas=list(cfg.bodies[bi]), cloth_pose=cfg.simulate.rest_pose)
        got = {**old, "garment": {**old.get("garment", {}), "mhclo": None}}
        made_from = str(old.get("garment", {}).get("mhclo") or "")
        if got == json.loads(json.dumps(want)) and made_from.split(":")[0] == Path(g.mhclo).name:
            return rel
        raise InputError(
            f"garment {g.name} (body {bi}) in this cache was made from another garment, body or file, and "
            f"its MakeHuman file is not here to make it again",
            path=f"{loc}/{key_rel}",
            expected=f"{Path(g.mhclo).name}, betas {list(cfg.bodies[bi])}",
            got=f"{made_from or 'no file'}, betas {old.get('betas')}",
        )
    key = {"garment": _garment_key(g), "betas": list(cfg.bodies[bi]), "cloth_pose": cfg.simulate.rest_pose}
    if loc.exists(rel) and loc.exists(key_rel):
        old = json.loads(loc.read_text(key_rel))
        if old != json.loads(json.dumps(key)):
            raise InputError(
                f"garment {g.name} (body {bi}) in this dataset was made from other parameters; "
                f"give the changed entry a new name (or use a new folder)",
                path=f"{loc}/{key_rel}",
                expected=json.dumps(key, sort_keys=True),
                got=json.dumps(old, sort_keys=True),
            )
    if not loc.exists(rel):
        if g.mesh is not None:  # the user's garment OBJ: checked on this body (its shape), 3 mm off the skin
            from ..body.placement import check_placement, push_off_body

            m = read_mesh(g.mesh)
            betas = cfg.bodies[bi] or None
            rest = body.shaped_vertices(betas)[0]
            check_placement(m.vertices, rest, body.faces, path=g.mesh, faces=m.faces, forceable=False)
            v, _ = push_off_body(m.vertices, rest, body.faces, 0.003)
            with loc.writing(rel) as tmp:
                write_obj(tmp, Mesh(vertices=v, faces=m.faces), header=f"garment {Path(g.mesh).name}, by segadeform")
        elif g.mhclo is not None:  # a MakeHuman garment: fitted to this body (decimated), 3 mm off the skin
            from ..body.placement import push_off_body
            from ..body.resample import decimate
            from ..garments.registration import fit_mhclo
            from ..io.mhclo import read_mhclo

            binding = read_mhclo(g.mhclo)
            betas = cfg.bodies[bi] or None
            v = fit_mhclo(binding, body, betas)
            faces = read_mesh(binding.obj_path()).faces
            if g.decimate is not None:  # the shortest edges (the narrow hem rows) collapsed first
                v, faces = decimate(v, faces, max(3, int(round(g.decimate * len(v)))))
            v, _ = push_off_body(v, body.shaped_vertices(betas)[0], body.faces, 0.003)
            with loc.writing(rel) as tmp:
                write_obj(
                    tmp,
                    Mesh(vertices=v, faces=faces),
                    header=f"MakeHuman garment {binding.name} (CC0), fitted by segadeform",
                )
        else:
            a_pose = cfg.simulate.rest_pose == "a"
            gar = make_garment(g.kind, body, cfg.bodies[bi] or None, g.params, cloth_pose=A_POSE if a_pose else None)
            if a_pose:  # the cloth file first: the rest-pose OBJ is what marks the garment done
                with loc.writing(_cloth_rel(rel)) as tmp:
                    write_obj(
                        tmp,
                        Mesh(vertices=gar.cloth_rest, faces=gar.faces),
                        header=gar.header() + "\nthe same garment made in the A-pose (the cloth's rest)",
                    )
            with loc.writing(rel) as tmp:
                write_obj(tmp, Mesh(vertices=gar.vertices, faces=gar.faces), header=gar.header())
        loc.put_bytes(key_rel, json.dumps(key, indent=1, sort_keys=True).encode("utf-8"))
    return rel


#: what a sample's log record holds (its committed ``.json`` holds these and more)
_REC_KEYS = (
    "id",
    "split",
    "garment",
    "kind",
    "type",
    "body",
    "motion",
    "vertices",
    "frames",
    "spec",
    "status",
    "reasons",
    "quality",
    "seconds_per_frame",
    "blender",
    "sim_seconds",
    "preroll_frames",
    "attempt",
    "seconds",
)


def _committed(loc: Location, sid: str) -> dict | None:
    """The log record of sample ``sid`` when it is committed already (kept or rejected), else None."""
    for rel in (f"samples/{sid}.json", f"rejected/{sid}.json"):
        if loc.exists(rel):
            meta = json.loads(loc.read_text(rel))
            return dict({k: meta[k] for k in _REC_KEYS if k in meta}, resumed=True)
    return None


def _trim_record(full) -> dict:
    """What a kept sample records of the whole clip it was cut from (its ``trimmed`` metadata)."""
    return {"clip_frames": full.frames, "reasons": list(full.reasons), "quality": full.to_dict()}


def trim_sample(s: Sample, frames: int) -> Sample:
    """Sample ``s`` cut to its first ``frames`` frames (frames, poses, translations and contacts alike)."""
    cut = {k: getattr(s, k)[:frames] for k in ("poses", "trans", "frames")}
    for k in ("contact_p", "contact_n"):
        if getattr(s, k) is not None:
            cut[k] = getattr(s, k)[:frames]
    return dataclasses.replace(s, **cut)


def _run_one(
    root,
    cfg: DatasetConfig,
    ps: PlannedSample,
    body_path: str | None,
    sim_python,
    provision: bool = False,
    first_attempt: int = 0,
) -> dict:
    """Simulate, gate and commit one sample (in a worker); returns its log record.  Idempotent: a
    sample committed already is not made again (its record comes back with ``resumed``).

    Attempts ``first_attempt`` .. ``cfg.attempts - 1`` are simulated in turn (:meth:`DatasetConfig.attempt_settings`)
    until one passes the gate; the kept one, or the last one rejected, is committed with its attempt and spec."""
    from ..body.identity import body_sha256
    from ..physics.blender import SIM_BRIDGE_VERSION

    t0 = time.perf_counter()
    loc = open_location(root)
    done = _committed(loc, ps.id)
    if done is not None:
        return done
    for rel in (f"samples/{ps.id}.npz", f"samples/{ps.id}.json", f"rejected/{ps.id}.npz", f"rejected/{ps.id}.json"):
        loc.remove_temporaries(rel)  # what a killed attempt of this task left
    if provision:
        from ..physics.setup import ensure_sim_python

        sim_python = ensure_sim_python(sim_python)
    body = load_body(body_path or default_body_path())
    g, m = cfg.garments[ps.garment], cfg.motions[ps.motion]
    betas = cfg.bodies[ps.body]
    grel = _garment_rel(cfg, ps.garment, ps.body)
    with tempfile.TemporaryDirectory(prefix="segadeform-garment-") as d:
        mesh = read_mesh(loc.local_copy(grel, Path(d)))
        crel = _cloth_rel(grel)
        cloth = read_mesh(loc.local_copy(crel, Path(d))).vertices if loc.exists(crel) else None
    full_motion, lead = _motion(m, cfg, body.rest_joints(betas or None)[0], with_lead=True)
    motion = _without_lead(full_motion, lead)
    base = {
        "id": ps.id,
        "split": ps.split,
        "garment": g.name,
        "kind": g.kind,
        "type": GARMENT_TYPES[g.kind],
        "body": ps.body,
        "motion": m.name,
        "motion_source": "mocap" if m.file is not None else "procedural",  # what drove the body (dataset info)
        "vertices": len(mesh.vertices),
    }
    for attempt in range(first_attempt, cfg.attempts):
        rec = dict(
            base,
            frames=motion.n_frames,
            spec=sample_spec(cfg, ps, attempt),
            spec_parts=sample_spec_parts(cfg, ps, attempt),
            attempt=attempt,
        )
        sample = _attempt(rec, cfg, ps, body, mesh, cloth, full_motion, motion, lead, attempt, sim_python)
        if sample is None:  # the simulator failed: nothing is committed, a later run tries again
            rec["seconds"] = time.perf_counter() - t0
            return rec
        if rec["status"] == "kept":
            break
    sample.meta.update(sim_bridge=SIM_BRIDGE_VERSION, body_sha256=body_sha256(body))
    committed = save_sample(loc, sample, folder="samples" if rec["status"] == "kept" else "rejected")
    if not committed:  # another attempt of this task committed it first: its record is the one
        return _committed(loc, ps.id)
    rec["seconds"] = time.perf_counter() - t0
    return rec


def _attempt(
    rec: dict,
    cfg: DatasetConfig,
    ps: PlannedSample,
    body,
    mesh,
    cloth,
    full_motion,
    motion,
    lead: int,
    attempt: int,
    sim_python,
) -> Sample | None:
    """Simulate and gate sample ``ps`` with the settings of ``attempt``: fills ``rec`` (status, reasons, quality
    ...) and returns the sample to commit, or None when the simulator failed (``rec``'s reasons say how)."""
    from ..physics.blender import A_POSE, simulate

    g = cfg.garments[ps.garment]
    betas = cfg.bodies[ps.body]
    try:
        st = cfg.attempt_settings(g, attempt)
        kw = {} if cloth is None else {"cloth_rest": cloth, "start_pose": A_POSE}
        res = simulate(
            mesh.vertices, mesh.faces, body, full_motion, betas=betas or None, settings=st, sim_python=sim_python, **kw
        )
        if lead:
            res = dataclasses.replace(res, frames=res.frames[lead:], preroll_frames=res.preroll_frames + lead)
    except SegadeformError as e:
        rec.update(status="rejected", reasons=[f"simulation failed: {e}"])
        return None
    posed = body.forward(motion.poses, betas or None, motion.trans).vertices
    contact: dict = {}
    # strain against the cloth's own rest (the A-posed garment when the simulation rests there)
    strain_rest = res.cloth_rest if res.cloth_rest is not None else mesh.vertices
    parts = BodyParts.of(body, betas or None)
    on_body = on_body_at_rest(mesh.vertices, parts.rest, body.faces)
    fs = frame_stats(
        res.frames,
        strain_rest,
        mesh.faces,
        posed,
        body.faces,
        cfg.quality,
        contact=contact,
        parts=parts,
        on_body=on_body,
        anchors=body_anchors(mesh.vertices, parts.rest, body.faces, on_body),
    )
    q = fs.report(cfg.quality)
    keep = kept_frames(q, cfg.quality)
    trimmed = None
    if 0 < keep < q.frames:  # a clip that fails later on keeps the leading frames that pass
        trimmed = _trim_record(q)
        q = fs.report(cfg.quality, keep)
        rec["frames"] = keep
    rec.update(
        quality=q.to_dict(),
        seconds_per_frame=res.seconds_per_frame,
        blender=res.blender["blender_version"],
        sim_seconds=res.blender["simulate_seconds"],
        preroll_frames=res.preroll_frames,
    )
    # a rejected sample keeps its arrays too: another gate can be applied later without simulating (regate)
    rec.update(status="kept" if q.ok else "rejected", **({} if q.ok else {"reasons": q.reasons}))
    if trimmed is not None:
        rec["trimmed"] = trimmed
    meta = dict(
        rec,
        fps=motion.fps,
        betas=list(betas),
        settings=res.settings,
        # a garment OBJ's own (`garment make` records them), not the config's defaults (a researcher's trial: a
        # flare-0.5 skirt's samples said flare 0.25); {} for one that records none
        garment_params=_garment_params(g) if g.mesh is None else (recorded_params(g.mesh) or {}),
        config_digest=cfg.digest(),
        blender_info=res.blender,
    )
    finite = np.isfinite(res.frames).all()
    sample = Sample(
        id=ps.id,
        rest=mesh.vertices,
        faces=mesh.faces,
        betas=np.asarray(betas, np.float64),
        poses=motion.poses,
        trans=motion.trans,
        frames=res.frames.astype(np.float32),
        meta=meta,
        contact_p=contact["closest"] if finite else None,
        contact_n=contact["normal"] if finite else None,
        cloth_rest=None
        if res.cloth_rest is None or strain_rest is mesh.vertices
        else np.asarray(res.cloth_rest, np.float64),
        lead_poses=np.asarray(full_motion.poses[:lead], np.float32),
        lead_trans=np.asarray(full_motion.trans[:lead], np.float32),
    )
    return trim_sample(sample, keep) if trimmed is not None else sample


@dataclasses.dataclass(frozen=True)
class _SampleTask:
    """Everything a worker needs to make one sample (pickled to it)."""

    out: Location
    cfg: DatasetConfig
    sample: PlannedSample
    body_path: str | None  # None: the shipped body of the worker's own installation
    sim_python: str | None
    provision: bool
    first_attempt: int = 0  # > 0: a rejected sample given the config's later fallbacks


def _run_task(t: _SampleTask) -> dict:
    return _run_one(t.out, t.cfg, t.sample, t.body_path, t.sim_python, t.provision, t.first_attempt)


def _check_done(out, cfg: DatasetConfig, plan: list[PlannedSample], roots=None) -> None:
    """Stop if a finished sample's record (in ``out`` or in the read-only ``roots``, a
    :class:`~segadeform.dataset.roots.DatasetRoots`) differs from what the config now asks of its id: its spec (the
    data), or its split (a garment, motion family or body moved between splits: ``train`` and ``eval`` take a
    sample's split from its record, so a sample made for training whose family the config now holds out would be
    trained on and tested on)."""
    loc = open_location(out)
    bad, moved = [], []  # (id, the root that holds it: this folder or a read-only root), ...
    names = {d: set(loc.listdir(d)) for d in ("samples", "rejected")}
    for p in plan:
        rec, kept, where, src = None, False, str(loc), None
        for d in ("samples", "rejected"):
            if f"{p.id}.json" in names[d]:
                rec, kept = json.loads(loc.read_text(f"{d}/{p.id}.json")), d == "samples"
                break
        if rec is None and roots is not None:
            rec, kept = roots.record(p.id)
            if rec is not None:  # a pack's or another folder's (the message named the new output folder)
                src = roots.source(p.id, "samples" if kept else "rejected")
                where = str(getattr(src, "path", src))
        if rec is None:
            continue
        old = rec.get("spec")
        if old is not None and old not in sample_specs(cfg, p):
            bad.append((p, rec, where, src))
        elif kept and rec.get("split") is not None and rec.get("split") != p.split:  # (a rejected one trains nothing)
            moved.append((p.id, rec.get("split"), p.split, where))
    mine = str(loc)
    if bad:
        p, rec, where, src = bad[0]
        sid = p.id
        if "spec_parts" not in rec and src is not None and hasattr(src, "read_meta"):  # a pack's index: its record
            rec = src.read_meta(sid)
        parts = _changed_parts(cfg, p, rec)
        what = f": its {' and '.join(parts)} changed" if parts else ""
        raise InputError(
            f"{len(bad)} finished samples of this dataset were made from other settings than this "
            f"config gives them (first: {sid}{what}); give changed entries new names, keep bodies in "
            + ("order, or use a new folder" if where == mine else "order, or leave out the root that holds it"),
            path=where,
        )
    if moved:
        sid, was, now, where = moved[0]
        raise InputError(
            f"{len(moved)} finished samples of this dataset were made for another split than this config puts "
            f"them in (first: {sid}, made as '{was}', now '{now}'): a garment, motion family or body moved between "
            f"splits, and a sample keeps the split it was made for; give the moved entries new names or "
            + ("use a new folder" if where == mine else "leave out the root that holds it"),
            path=where,
        )


#: a spec part in words
_PART_WORDS = {
    "garment": "garment (its entry or file)",
    "betas": "body shape",
    "motion": "motion (its entry or file)",
    "fps": "frame rate",
    "seconds": "clip length",
    "simulate": "simulation settings",
}


def _changed_parts(cfg: DatasetConfig, p: PlannedSample, rec: dict) -> list[str]:
    """The parts of sample ``p``'s spec that differ from its record's (``spec_parts``, recorded since samples keep
    them; empty for older records): what a user changed (a user's trial was told only "other settings")."""
    old = rec.get("spec_parts")
    if not isinstance(old, dict):
        return []
    attempt = int(rec.get("attempt", 0) or 0)
    if attempt >= cfg.attempts:  # made on a fallback the config no longer has
        now = sample_spec_parts(cfg, p, 0)
        return [_PART_WORDS.get(k, k) for k in now if k != "simulate" and old.get(k) != now[k]] + [
            f"simulation settings (its attempt {attempt} is no [[fallback]] of the config now)"
        ]
    now = sample_spec_parts(cfg, p, attempt)
    return [_PART_WORDS.get(k, k) for k in now if old.get(k) != now[k]]


def _keep_config(out, cfg: DatasetConfig) -> None:
    """config.toml = this run's config; configs/NNN.toml = every distinct config, in order."""
    if cfg.path is None:
        return
    loc = open_location(out)
    text = Path(cfg.path).read_bytes()
    old = [n for n in loc.listdir("configs") if n.endswith(".toml")]
    if not old or loc.read_bytes(f"configs/{old[-1]}") != text:
        loc.put_bytes(f"configs/{len(old) + 1:03d}.toml", text)
    loc.put_bytes("config.toml", text)


class _Undo:
    """A local dataset folder as it was before a run: :meth:`rollback` removes what the run added (files, then the
    folders it made, if empty) and puts back the ``config.toml`` it replaced.  For the checks that come before any
    sample is simulated (the plan, a conflicting root, the garments on their bodies): a run they stop leaves the
    folder as it found it (it left ``configs/NNN.toml``, ``garments/`` and ``samples/`` behind, and a later run
    into the folder kept the failed config in the dataset's history)."""

    def __init__(self, out) -> None:
        if isinstance(out, LocalLocation):  # (the command line gives its output folder as a Location)
            out = out.root
        local = isinstance(out, Path) or (isinstance(out, str) and "://" not in out)
        self.root = Path(out) if local else None
        self.existed = self.root is not None and self.root.is_dir()
        self.before = set(self.root.rglob("*")) if self.existed else set()  # type: ignore[union-attr]
        c = None if self.root is None else self.root / "config.toml"
        self.config = c.read_bytes() if c is not None and c.is_file() else None

    def rollback(self) -> None:
        if self.root is None or not self.root.is_dir():
            return
        with contextlib.suppress(OSError):
            for q in sorted(set(self.root.rglob("*")) - self.before, key=lambda q: len(q.parts), reverse=True):
                if q.is_dir() and not q.is_symlink():
                    with contextlib.suppress(OSError):
                        q.rmdir()
                else:
                    q.unlink(missing_ok=True)
            if self.config is not None:
                (self.root / "config.toml").write_bytes(self.config)
            if not self.existed:
                self.root.rmdir()


class _Log:
    """``log.jsonl``: a line per finished sample, appended as it finishes (in a local folder); on an
    object store, which cannot append, the file is rewritten at most every ``every`` seconds and at
    the end."""

    def __init__(self, loc: Location, every: float = 30.0) -> None:
        self.loc, self.every = loc, every
        self.buf: list[str] = []
        self.last = time.monotonic()
        self.fh = None
        if isinstance(loc, LocalLocation):
            loc.root.mkdir(parents=True, exist_ok=True)
            self.fh = open(loc.path("log.jsonl"), "a")

    def write(self, rec: dict) -> None:
        line = json.dumps(rec) + "\n"
        if self.fh is not None:
            self.fh.write(line)
            self.fh.flush()
            return
        self.buf.append(line)
        if time.monotonic() - self.last >= self.every:
            self.flush()

    def flush(self) -> None:
        if self.buf:
            self.loc.append_text("log.jsonl", "".join(self.buf))
            self.buf = []
        self.last = time.monotonic()

    def close(self) -> None:
        if self.fh is not None:
            self.fh.close()
        else:
            self.flush()


@dataclasses.dataclass
class DatasetSummary:
    planned: int
    skipped: int
    kept: int
    rejected: int
    records: list
    unplanned: tuple = ()  # ids of kept samples in the folder that this config does not plan (an entry removed)


@dataclasses.dataclass(frozen=True)
class RegateSummary:
    kept: int  # samples that pass the gate now
    rejected: int  # samples that fail it now
    moved: list  # (id, "kept" | "rejected") of the samples whose status changed
    skipped: list  # ids of rejected samples with no arrays (rejected before arrays were kept)


def _rewrite_sample(root: Path, s: Sample, folder: str) -> None:
    """Replace a committed sample of the local dataset ``root`` by ``s`` (regate's trim of a sample it keeps in
    place): its metadata goes first, so that a run stopped in between leaves a sample to make again, never
    metadata that names arrays of another length."""
    (root / folder / f"{s.id}.json").unlink()
    save_sample(root, s, folder=folder)


def regate(
    out, cfg: DatasetConfig, *, body_path: Path | None = None, progress: Callable[[str], None] | None = None
) -> RegateSummary:
    """Apply ``cfg``'s quality gate again to every sample of the dataset folder ``out`` that has its
    arrays, kept or rejected, and move those whose status changes (``samples/`` <-> ``rejected/``: the
    arrays and the ``.json`` that marks the sample are committed in the new place, then removed from the
    old).  Nothing is simulated.  Run it while no ``dataset make`` writes to the same dataset."""
    loc = open_location(out)
    if not isinstance(loc, LocalLocation):
        raise InputError("regate works on a dataset folder on this machine", got=str(out))
    root = loc.root
    body = load_body(body_path or default_body_path())
    kept = rejected = 0
    moved, skipped = [], []
    # both folders listed before any sample moves: a sample moved into rejected/ was gated and counted there again
    # (a researcher's trial: "0 pass the gate, 8 do not" of 4 samples)
    listed = {f: sorted((root / f).glob("*.json")) if (root / f).is_dir() else [] for f in ("samples", "rejected")}
    for folder in ("samples", "rejected"):
        d = root / folder
        for meta_p in listed[folder]:
            sid = meta_p.stem
            if not (d / f"{sid}.npz").is_file():
                skipped.append(sid)
                rejected += folder == "rejected"
                continue
            if progress is not None:
                progress(sid)
            s = load_sample(root, sid, folder)
            betas = s.betas if s.betas.size else None
            posed = body.forward(s.poses, betas, s.trans).vertices
            rest = s.cloth_rest if s.cloth_rest is not None else s.rest
            parts = BodyParts.of(body, betas)
            st = frame_stats(
                s.frames,
                rest,
                s.faces,
                posed,
                body.faces,
                cfg.quality,
                parts=parts,
                on_body=(ob := on_body_at_rest(s.rest, parts.rest, body.faces)),
                anchors=body_anchors(s.rest, parts.rest, body.faces, ob),
            )
            q = st.report(cfg.quality)
            keep = kept_frames(q, cfg.quality)
            meta = {k: v for k, v in s.meta.items() if k != "reasons"}
            trim = 0 < keep < q.frames
            if trim:  # kept as its leading frames that pass (the tail that failed is not kept)
                meta["trimmed"] = {
                    **_trim_record(q),
                    "clip_frames": s.meta.get("trimmed", {}).get("clip_frames", q.frames),
                }
                q = st.report(cfg.quality, keep)
                meta["frames"] = keep
            kept += q.ok
            rejected += not q.ok
            now = "samples" if q.ok else "rejected"
            meta.update(quality=q.to_dict(), status="kept" if q.ok else "rejected")
            if not q.ok:
                meta["reasons"] = q.reasons
            if now != folder or trim:  # the log follows (dataset info reads it): what changed, merged by id
                keys = ("id", "split", "garment", "kind", "type", "body", "motion", "vertices", "status", "quality")
                upd = {k: meta[k] for k in (*keys, "frames", "reasons", "trimmed") if k in meta}
                loc.append_text("log.jsonl", json.dumps({**upd, "regated": True}) + "\n")
            if now == folder and not trim:
                loc.put_bytes(f"{folder}/{sid}.json", json.dumps(meta, indent=1, sort_keys=True).encode("utf-8"))
                continue
            s = dataclasses.replace(s, meta=meta)
            if trim:
                s = trim_sample(s, keep)
            if now == folder:  # a kept sample cut shorter, in place
                _rewrite_sample(root, s, folder)
            else:
                save_sample(root, s, folder=now)
                meta_p.unlink()
                (d / f"{sid}.npz").unlink()
            moved.append(
                (sid, meta["status"] + (f", {keep} of {meta['trimmed']['clip_frames']} frames" if trim else ""))
            )
    return RegateSummary(kept=kept, rejected=rejected, moved=moved, skipped=skipped)


def _stale_rejected(loc: Location, cfg: DatasetConfig, order: list[PlannedSample], body: BodyModel) -> list:
    """The planned samples of ``loc``'s ``rejected/`` (in make order) whose stored clip differs from what
    :func:`_motion` now gives their motion entry: simulated with a motion that loading no longer gives."""
    names = set(loc.listdir("rejected"))
    rejected = [p for p in order if f"{p.id}.json" in names and f"{p.id}.npz" in names]
    # their clips checked first, as the run's are: a start past the end of its file is refused in the words that
    # name the entry's line (loading the motion refused it without them); what is short is said by the run
    captures: dict = {}  # the files check_clips reads, read once (they were read again below: a review)
    check_clips(cfg, [(p.motion, p.body) for p in rejected], body, captures)
    clips: dict = {}  # (motion, body) -> the clip as stored: a motion file is read once, not once per garment
    out = []
    for p in rejected:
        if (p.motion, p.body) not in clips:
            m, betas = cfg.motions[p.motion], cfg.bodies[p.body]
            joints = body.rest_joints(betas or None)[0]
            got = captures.get((str(m.file), tuple(betas))) if m.file is not None else None
            clips[p.motion, p.body] = _without_lead(*_motion(m, cfg, joints, with_lead=True, captured=got))
        clip = clips[p.motion, p.body]
        with tempfile.TemporaryDirectory(prefix="segadeform-retry-") as d:
            z = np.load(loc.local_copy(f"rejected/{p.id}.npz", Path(d)))
            poses, trans = z["poses"], z["trans"]
        same = poses.shape == clip.poses.shape and np.allclose(poses, clip.poses, atol=1e-6)
        if not (same and np.allclose(trans, clip.trans, atol=1e-6)):
            out.append(p)
    return out


def _untried_fallbacks(loc: Location, cfg: DatasetConfig, order: list[PlannedSample]) -> dict:
    """{sample id: its next attempt} for the rejected samples of ``loc`` (in make order) whose recorded attempt was
    not the config's last: made before a [[fallback]] was added, they are given the fallbacks they have not had."""
    if cfg.attempts == 1:
        return {}
    names = set(loc.listdir("rejected"))
    out = {}
    for p in order:
        if f"{p.id}.json" not in names or f"{p.id}.npz" not in names:
            continue
        specs = sample_specs(cfg, p)
        old = json.loads(loc.read_text(f"rejected/{p.id}.json")).get("spec")
        if old in specs[:-1]:
            out[p.id] = specs.index(old) + 1
    return out


def _retire_rejected(root: Path, sid: str) -> None:
    """Move rejected sample ``sid``'s files to ``rejected/retried/`` (numbered, never over an earlier one): its
    ``.json`` first, so that an interrupted move leaves a sample that is simply not done."""
    d = root / "rejected" / "retried"
    d.mkdir(parents=True, exist_ok=True)
    n = 1
    while (d / f"{sid}.{n}.json").exists() or (d / f"{sid}.{n}.npz").exists():
        n += 1
    for ext in ("json", "npz"):
        os.replace(root / "rejected" / f"{sid}.{ext}", d / f"{sid}.{n}.{ext}")


def make_dataset(
    cfg: DatasetConfig,
    out,
    *,
    body_path: Path | None = None,
    jobs: int = 1,
    sim_python=None,
    progress: Callable[[dict], None] | None = None,
    limit: int | None = None,
    executor: Executor | None = None,
    roots=(),
    retry_rejected: bool = False,
    retry: tuple = (),
    splits: tuple = (),
) -> DatasetSummary:
    """Make (or continue) the dataset ``cfg`` in ``out`` (a folder, an fsspec URL or a
    :class:`~segadeform.io.location.Location`); see the module docstring.

    ``executor`` runs the samples (default: a local pool of ``jobs`` processes; one given here is
    left open).  Tasks on a remote executor make the simulator environment where a worker has none.
    ``body_path`` None: the shipped body, found by each worker in its own installation.
    ``roots``: read-only dataset roots (packs, folders; :mod:`segadeform.dataset.roots`), and the
    config's own ``dataset.roots`` where they exist: a sample one of them holds is done and is not
    made again (new samples always go to ``out``).
    ``retry_rejected``: simulate again, before new samples, the rejected samples of ``out`` whose clip the
    motion loader now prepares differently from the one they were simulated with (after a fix to motion
    loading, e.g. :func:`~segadeform.motion.motion.repair_glitches`); each one's old files move to
    ``rejected/retried/`` first (nothing is deleted), and the new attempt is committed as any sample is.
    ``retry``: glob patterns of sample ids: the rejected samples of ``out`` that match are simulated again the
    same way (after a change to the simulator that a sample's spec does not record, e.g. how pins are chosen).
    ``splits``: make only the samples of these splits (``"train"``, ``"val"``, ``"test"``; the ``test-*`` splits
    of ``cross_splits`` count as ``"test"``), in the config's order -- the held-out split of a fresh machine first,
    so that an evaluation can be repeated without the training data; empty: every split.
    A config's ``[[fallback]]`` tables are further attempts: a sample the gate rejects is simulated again with
    each in turn, and the first that passes is kept.  A rejected sample of ``out`` made before a fallback was
    added is given the ones it has not had, before new samples (its old files move to ``rejected/retried/``).
    """
    from .roots import DatasetRoots

    bad = [sp for sp in splits if sp not in SPLITS]
    if bad:
        raise InputError("unknown dataset split", expected=" | ".join(SPLITS), got=bad[0])

    extra = DatasetRoots(list(roots), optional=cfg.roots) if (roots or cfg.roots) else None
    body = load_body(body_path or default_body_path())
    # samples of another body neither count as done nor mix with new ones (checked before anything is written)
    if extra is not None:
        extra.check_body(body)
    mine = out.root if isinstance(out, LocalLocation) else out  # (the command line gives a Location)
    if isinstance(mine, (str, Path)) and any(next(Path(mine, d).glob("*.json"), None) for d in ("samples", "rejected")):
        DatasetRoots([mine]).check_body(body)
    undo = _Undo(out)  # what a run that stops before simulating anything leaves: nothing (a user's trial)
    try:
        loc = open_location(out)
        if isinstance(loc, LocalLocation):  # the folder's layout, even before anything is kept
            (loc.root / "samples").mkdir(parents=True, exist_ok=True)
            (loc.root / "garments").mkdir(exist_ok=True)
        plan = sample_plan(cfg)
        check_splits(cfg, plan)
        _check_done(loc, cfg, plan, extra)
        planned = {p.id for p in plan}  # the whole plan: what a kept sample not in it is told against
        _keep_config(loc, cfg)
        if splits:  # the whole plan was checked and ordered as always; only the chosen splits are made
            have = sorted({split_group(p.split) for p in plan})
            plan = [p for p in plan if split_group(p.split) in splits]
            if not plan:  # it made nothing and said "0 planned" (a user's trial)
                raise InputError(
                    f"the config plans no samples of the split{'s' if len(splits) > 1 else ''} asked for",
                    path=cfg.path,
                    expected=f"--split {' | '.join(have)} (the splits its entries name)" if have else "entries",
                    got=", ".join(splits),
                )
        order = make_order(cfg, plan)
        finished = {n[: -len(".json")] for d in ("samples", "rejected") for n in loc.listdir(d) if n.endswith(".json")}
        if extra is not None:
            finished |= {p.id for p in plan if extra.has(p.id)}
        todo = [p for p in order if p.id not in finished]
        skipped = len(plan) - len(todo)
        if (retry_rejected or retry) and not isinstance(loc, LocalLocation):
            raise InputError("retrying rejected samples works on a dataset folder on this machine", got=str(out))
        again = _stale_rejected(loc, cfg, order, body) if retry_rejected else []
        if retry:
            names = set(loc.listdir("rejected"))
            chosen = {p.id for p in again}
            again += [
                p
                for p in order
                if p.id not in chosen
                and f"{p.id}.json" in names
                and f"{p.id}.npz" in names
                and any(fnmatch.fnmatchcase(p.id, g) for g in retry)
            ]
        first = {}  # the rejected samples given the fallbacks they have not had (on a folder here; read-only roots and
        if isinstance(loc, LocalLocation):  # object stores keep what they hold)
            chosen = {p.id for p in again}
            first = {k: v for k, v in _untried_fallbacks(loc, cfg, order).items() if k not in chosen}
            again += [p for p in order if p.id in first]
        todo = again + todo
        if limit is not None:
            todo = todo[:limit]
        skipped -= min(len(again), len(todo))
        # the clips to simulate: a start past the end of the file was refused by the first sample's worker, the
        # run's folder left behind; a clip shorter than [dataset] seconds was kept without a word (a user's trial)
        short = check_clips(cfg, [(p.motion, p.body) for p in todo], body)
        for words in short[:SHORT_SAID]:
            log.warning("%s", words)
        if len(short) > SHORT_SAID:  # continuum.toml has 56 such entries: a page of them every run said nothing more
            log.warning(
                "... and %d more motion entries whose clips are shorter than [dataset] seconds", len(short) - SHORT_SAID
            )
        for gi, bi in sorted({(p.garment, p.body) for p in todo}):  # garments first, in this process: no races
            _garment_file(loc, cfg, gi, bi, body)
    except BaseException:
        undo.rollback()
        raise
    # the old attempts are put aside, not lost, once nothing before the simulation can stop the run (the rollback
    # above removes what the run added: a retired attempt moved under rejected/retried/ would be among it)
    for p in todo[: len(again)]:  # this run makes the sample anew
        _retire_rejected(loc.root, p.id)  # type: ignore[attr-defined]  (a LocalLocation: checked above)
    own = executor is None
    ex = LocalExecutor(jobs) if own else executor
    tasks = [
        _SampleTask(
            loc,
            cfg,
            p,
            None if body_path is None else str(body_path),
            None if sim_python is None else str(sim_python),
            ex.remote,
            first.get(p.id, 0),
        )
        for p in todo
    ]
    records = []
    run = time.strftime("%Y-%m-%dT%H:%M:%S", time.gmtime())
    run_t0 = time.time()
    sample_log = _Log(loc)
    try:
        for rec in ex.map_unordered(_run_task, tasks):
            # the run it belongs to and when it finished: `dataset info` measures samples per hour
            rec.update(run=run, run_started=run_t0, finished=time.time(), jobs=ex.workers, executor=ex.name)
            records.append(rec)
            sample_log.write(rec)
            if progress is not None:
                progress(rec)
    finally:
        sample_log.close()
        if own:
            ex.close()
    kept = sum(r["status"] == "kept" for r in records)
    unplanned = tuple(sorted(n[:-5] for n in loc.listdir("samples") if n.endswith(".json") and n[:-5] not in planned))
    return DatasetSummary(
        planned=len(plan),
        skipped=skipped,
        kept=kept,
        rejected=len(records) - kept,
        records=records,
        unplanned=unplanned,
    )
