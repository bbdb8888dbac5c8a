"""Which motions are one capture: a fingerprint that survives file formats, frame rates, rigs and body shapes.

A model scored on a motion it was trained on gives numbers that are not held out, and a dataset whose training
and test splits hold one capture in two files (``05_01.fbx`` and ``05_01.bvh``, CMU's ASF/AMC trial and a BVH
conversion of it) leaks the capture.  Names and file hashes do not see either case.  The fingerprint here does:
each joint's angular speed over time,

.. math::

    s_j(t) = \\min\\left(\\frac{1}{\\Delta}\\,\\angle\\!\\left(R_j(t)^\\top R_j(t + \\Delta)\\right),\\ s_{max}\\right),

for the pelvis, hips, knees, shoulders and elbows (:data:`JOINTS`), the motion first resampled to :data:`RATE`
(slerp), over :data:`BASELINE` frames (0.1 s: frame-to-frame angles of a 120 fps capture resampled are mostly its
jitter on a slow motion) and capped at :data:`MAX_SPEED` (what is left of a capture's glitches).  The angle of
a rotation between two frames is the same for ``A R_j(t) B`` whatever the constant rotations ``A`` and ``B``, so
rigs whose rest poses differ (a BVH conversion's T-pose against the ASF's) and retargeting onto different body
shapes leave it almost unchanged; the joints' absolute rotations do not (the same CMU trial
read from its BVH and from its AMC is as far apart in rotations as two different walks of one subject).

Two fingerprints are compared at every time offset where at least half the shorter one overlaps the other
(:func:`capture_distance`): the distance is the relative RMS difference over the overlap, the smallest over the
offsets.  Measured on the CMU files under ``../shared/data/mocap``, read as ``dataset make`` reads them, 2-second
clips against whole files (``tools/fingerprint_separation.py``; ``docs/motion-fingerprint.md``):

* one capture: 148 of 154 pairs at most :data:`SAME_CAPTURE` -- two formats (cgspeed's BVH and CMU's ASF/AMC)
  0.10-0.12, two body shapes median 0.000 (karate up to 0.21: the glitch repair depends on the body), 120 fps
  against 24 fps median 0.05 (dance up to 0.35);
* different captures: 2,745 of 2,746 pairs over it -- median 0.8; the closest, two walks of one subject on one
  day, 0.18.

So the fingerprint tells "this capture, or one nearly like it", not "this file": what a warning needs, not what a
refusal would.  A near-still overlap (RMS speed under :data:`STILL`) tells nothing -- standing still matches any
other standing still -- and is not compared.

* :func:`joint_speeds` -- the fingerprint ``(T', J)`` of a ``(T, 72)`` pose sequence;
* :func:`capture_distance` -- the fast comparison (sliding windows); :func:`capture_distance_reference` -- the
  slow, obvious loop over offsets that tests compare it with;
* :func:`nearest_capture` -- the closest of several fingerprints;
* :func:`encode_speeds` / :func:`decode_speeds` -- the compact text form a model package's manifest keeps
  (one byte a value, square-root steps, base64);
* :func:`motions_record` / :func:`read_motions_record` -- the record of a model's training motions that a
  checkpoint and a package's manifest keep (``training_motions``), and what ``eval`` reads from it.
"""

from __future__ import annotations

import base64
from collections.abc import Sequence

import numpy as np

from ..errors import InputError

__all__ = [
    "RATE",
    "JOINTS",
    "SAME_CAPTURE",
    "STILL",
    "BASELINE",
    "MAX_SPEED",
    "METRIC",
    "joint_speeds",
    "capture_distance",
    "capture_distance_reference",
    "nearest_capture",
    "encode_speeds",
    "decode_speeds",
    "motions_record",
    "read_motions_record",
]

#: frames per second the fingerprint is taken at
RATE = 30.0
#: SMPL joints whose speeds make the fingerprint: pelvis, hips, knees, shoulders, elbows (the hands, feet, spine
#: and neck are left out: rigs split and merge them differently, and captures' ends are noisy)
JOINTS = (0, 1, 2, 4, 5, 16, 17, 18, 19)
#: frames (at RATE) each speed is measured over
BASELINE = 3
#: rad/s: speeds are capped here (a capture's glitches, a frame or two of a limb flipped, are faster)
MAX_SPEED = 12.0
#: the largest distance at which two fingerprints are called one capture (see the module's docstring)
SAME_CAPTURE = 0.2
#: rad/s: an overlap whose RMS joint speed is under this is (nearly) still, and is not compared
STILL = 0.2
#: the name a package records the fingerprint under (a change of JOINTS, RATE or the rule is a new name)
METRIC = "joint-speeds-v1"
_STEPS = 255  # one byte: speed = MAX_SPEED (q / 255)^2


def joint_speeds(poses, fps: float) -> np.ndarray:
    """The fingerprint of a motion: the angular speed of each of :data:`JOINTS` at :data:`RATE`.

    Args:
        poses: (T, 72) SMPL axis-angle poses (root first), as :class:`~segadeform.motion.motion.Motion` holds.
        fps: their frame rate.

    Shapes:
        poses (T, 72) -> speeds (max(T' - BASELINE, 0), J) float32, rad/s, where T' is the number of frames at
        :data:`RATE`.
    """
    from ..body.kinematics import poses_to_rotmats
    from .motion import Motion, resample

    p = np.asarray(poses, np.float64)
    if p.ndim != 2 or p.shape[1] != 72 or len(p) == 0:
        raise InputError("expected poses (T, 72) with T >= 1", got=p.shape)
    if not np.isfinite(p).all():
        raise InputError("expected finite poses", got="NaN or infinity")
    if not (np.isfinite(fps) and fps > 0):
        raise InputError("expected a positive frame rate", got=fps)
    m = resample(Motion(p, np.zeros((len(p), 3)), float(fps)), RATE)
    r = poses_to_rotmats(m.poses)[:, list(JOINTS)]
    if len(r) <= BASELINE:
        return np.zeros((0, len(JOINTS)), np.float32)
    step = np.einsum("tjki,tjkl->tjil", r[:-BASELINE], r[BASELINE:])
    cos = np.clip((np.trace(step, axis1=-2, axis2=-1) - 1.0) / 2.0, -1.0, 1.0)
    return np.minimum(np.arccos(cos) * (RATE / BASELINE), MAX_SPEED).astype(np.float32)


def _check(a, what: str) -> np.ndarray:
    x = np.asarray(a, np.float64)
    if x.ndim != 2 or x.shape[1] != len(JOINTS):
        raise InputError(f"expected a fingerprint (T, {len(JOINTS)}) for {what}", got=x.shape)
    return x


def _need(n: int, m: int) -> int:
    """Frames two fingerprints of ``n`` and ``m`` frames must overlap by: half the shorter (at least 1)."""
    return max(1, min(n, m) // 2)


def capture_distance_reference(clip, reference) -> float:
    """:func:`capture_distance` as a plain loop over the offsets (slow, obvious: for tests only)."""
    a, b = _check(clip, "the clip"), _check(reference, "the reference")
    n, m = len(a), len(b)
    if n == 0 or m == 0:
        return float("inf")
    need, best = _need(n, m), float("inf")
    for k in range(-(n - need), m - need + 1):  # clip frame i lies on reference frame i + k
        i0, i1 = max(0, -k), min(n, m - k)
        x, y = a[i0:i1], b[i0 + k : i1 + k]
        scale = np.sqrt(0.5 * (x**2 + y**2).mean())
        if scale < STILL:
            continue
        best = min(best, float(np.sqrt(((x - y) ** 2).mean()) / scale))
    return best


def capture_distance(clip, reference) -> float:
    """How far fingerprint ``clip`` is from being a stretch of the same capture as ``reference``: the smallest,
    over the time offsets where at least half of the shorter overlaps the other, of the relative RMS difference
    ``rms(x - y) / sqrt(mean((x^2 + y^2) / 2))`` over the overlap; ``inf`` when no overlap moves
    (:data:`STILL`) or either is empty.  At most :data:`SAME_CAPTURE`: one capture.

    Shapes:
        clip (n, J), reference (m, J) -> a float (symmetric up to which is slid: the set of offsets is the same)
    """
    a, b = _check(clip, "the clip"), _check(reference, "the reference")
    n, m = len(a), len(b)
    if n == 0 or m == 0:
        return float("inf")
    need = _need(n, m)
    pad = n - need
    j = a.shape[1]
    # the reference with NaN rows around it: every offset is then one window of n rows, NaN where they do not overlap
    padded = np.full((m + 2 * pad, j), np.nan)
    padded[pad : pad + m] = b
    win = np.lib.stride_tricks.sliding_window_view(padded, n, axis=0)  # (K, J, n)
    win = np.moveaxis(win, -1, 1)  # (K, n, J), K = m + n - 2 need + 1
    ok = ~np.isnan(win[..., 0])  # (K, n) rows that overlap
    count = ok.sum(1) * j
    y = np.where(ok[..., None], win, 0.0)
    x = np.where(ok[..., None], a[None], 0.0)
    diff = ((x - y) ** 2).sum((1, 2)) / count
    scale = np.sqrt(0.5 * (x**2 + y**2).sum((1, 2)) / count)
    moving = scale >= STILL
    if not moving.any():
        return float("inf")
    return float((np.sqrt(diff[moving]) / scale[moving]).min())


def nearest_capture(clip, references: Sequence) -> tuple[int, float]:
    """``(index, distance)`` of the reference fingerprint nearest ``clip`` (:func:`capture_distance`);
    ``(-1, inf)`` when there are none."""
    best = (-1, float("inf"))
    for i, r in enumerate(references):
        d = capture_distance(clip, r)
        if d < best[1]:
            best = (i, d)
    return best


def encode_speeds(speeds) -> str:
    """A fingerprint as text: one byte a value, ``q = round(255 sqrt(s / MAX_SPEED))`` (finer steps for slower
    speeds: under 0.014 rad/s at 1 rad/s), base64.  :func:`decode_speeds` reads it back."""
    a = _check(speeds, "encoding")
    if not np.isfinite(a).all() or (a < 0).any():
        raise InputError("expected finite non-negative speeds to encode", got="negative, NaN or infinity")
    q = np.rint(_STEPS * np.sqrt(np.minimum(a, MAX_SPEED) / MAX_SPEED)).astype(np.uint8)
    return base64.b64encode(q.tobytes()).decode("ascii")


def decode_speeds(text: str) -> np.ndarray:
    """The fingerprint ``(T, J)`` float32 that :func:`encode_speeds` wrote."""
    try:
        raw = base64.b64decode(text.encode("ascii"), validate=True)
    except (ValueError, UnicodeEncodeError, AttributeError):
        raise InputError("expected a base64 fingerprint", got=str(text)[:40]) from None
    if len(raw) % len(JOINTS):
        raise InputError(f"expected a fingerprint of whole frames ({len(JOINTS)} bytes each)", got=f"{len(raw)} bytes")
    q = np.frombuffer(raw, np.uint8).reshape(-1, len(JOINTS)) / _STEPS
    return (MAX_SPEED * q * q).astype(np.float32)


def motions_record(names: Sequence[str], speeds: Sequence) -> dict:
    """The record of motions ``names`` with fingerprints ``speeds`` (each ``(T, J)``): ``{"metric": METRIC,
    "rate": RATE, "joints": [...], "motions": [{"name": str, "frames": T, "speeds": base64}, ...]}``.  A name
    given twice is kept once (its first fingerprint: one motion played on several bodies)."""
    if len(names) != len(speeds):
        raise InputError("expected one fingerprint per motion name", expected=len(names), got=len(speeds))
    rows, seen = [], set()
    for n, sp in zip(names, speeds, strict=True):
        if str(n) in seen:
            continue
        seen.add(str(n))
        a = _check(sp, f"motion {n!r}")
        rows.append({"name": str(n), "frames": int(len(a)), "speeds": encode_speeds(a)})
    return {"metric": METRIC, "rate": RATE, "joints": list(JOINTS), "motions": rows}


def read_motions_record(record) -> list[tuple[str, np.ndarray]]:
    """``[(name, speeds (T, J)), ...]`` of a :func:`motions_record`; :class:`InputError` naming what is wrong
    when it is malformed or was taken another way (another ``metric``, ``rate`` or ``joints``: a record from
    another release, which cannot be compared)."""
    want = (
        f'{{"metric": "{METRIC}", "rate": {RATE}, "joints": {list(JOINTS)}, '
        '"motions": [{"name", "frames", "speeds"}]}'
    )
    if not isinstance(record, dict) or not isinstance(record.get("motions"), list):
        raise InputError("expected a training_motions record", expected=want, got=str(record)[:80])
    got = (record.get("metric"), record.get("rate"), record.get("joints"))
    if got != (METRIC, RATE, list(JOINTS)):
        raise InputError("a training_motions record taken another way cannot be compared", expected=want, got=got)
    out = []
    for r in record["motions"]:
        if not isinstance(r, dict) or not isinstance(r.get("name"), str) or not isinstance(r.get("frames"), int):
            raise InputError("expected a motion entry {name, frames, speeds}", got=str(r)[:80])
        sp = decode_speeds(r.get("speeds"))
        if len(sp) != r["frames"]:
            raise InputError(
                f"motion {r['name']!r}'s speeds hold another number of frames", expected=r["frames"], got=len(sp)
            )
        out.append((r["name"], sp))
    return out
