"""Physical bounds on the numbers users give: one table, and the checks every reader and command shares.

A value past a *hard* bound cannot be right (a frame rate of 1e-30 fps, a root 1e30 m away, a shape
coefficient of 1e300) and is refused wherever it enters; a value past a *usual* bound might be meant (a
3-metre giant) and is refused unless the command was given ``--force``.

==================  ===================  ==========================================================
value               bound                why
==================  ===================  ==========================================================
frame rate          1 .. 1000 fps        motion capture runs at 24..480 fps; BVH ``Frame Time``
                                         1 ms .. 1 s
root translation    |t| <= 10 km         float32 outputs keep 1 mm steps up to 16 km; a clip
                                         further away is in the wrong units
mesh positions      |x| <= 10 km         the same: a garment or body vertex further out is in the
                                         wrong units (a vertex at 1e30 came out of the encoder as
                                         NaN, the file unnamed)
shape (betas)       |beta| <= 10 (hard)  the shape space is linear: past about 10 standard
                                         deviations the body folds through itself (beta0 = -20
                                         turns it inside out)
body height         0.9 .. 2.5 m         a human; on the default body beta0 alone reaches it from
                    (usual, --force)     about -3.8 to +2.57 (the others barely change the height);
                                         a refusal says how far the betas given may go
body surface        <= 0.1 % of faces    a shape whose skin folds through itself: within |beta| <= 10
                    turned over, at      a shape can (betas 0,8: 67 of the default body's 27,420
                    least 8 (usual,      faces turned over; 0,5,...,5: 590); shapes drawn from the
                    --force)             shape space's normal distribution turn at most 9, and 4 in
                                         400 drawn uniformly within +-3 are refused (up to 114)
procedural seed     0 .. 2**32 - 1       numpy's seeds
pose angles         |value| <= 1e6 rad   axis-angle components; the BVH reader's bound is 1e8 degrees
                                         (1.7e6 rad); past about 1e154 the angle's norm overflowed
                                         and the motion turned to NaN (a fuzzer's 1e300 poses)
==================  ===================  ==========================================================
"""

from __future__ import annotations

import contextlib
import contextvars

import numpy as np

from .errors import InputError

__all__ = [
    "FPS_RANGE",
    "MAX_TRANSLATION",
    "MAX_POSITION",
    "MAX_POSE_ANGLE",
    "check_pose_angles",
    "BETA_LIMIT",
    "HEIGHT_RANGE",
    "FOLDED_FACES",
    "FOLDED_FACES_MIN",
    "folded_faces",
    "SEED_RANGE",
    "check_fps",
    "check_translation",
    "played_at",
    "resample_positions",
    "sample_translations",
    "frames_between",
    "check_betas",
    "check_body_height",
    "height_reach",
    "check_seed",
]

FPS_RANGE = (1.0, 1000.0)
MAX_TRANSLATION = 1.0e4
MAX_POSITION = 1.0e4
MAX_POSE_ANGLE = 1.0e6
BETA_LIMIT = 10.0
HEIGHT_RANGE = (0.9, 2.5)
#: the share of the body's faces a shape may turn over (their normal against the template's) before it is refused,
#: and the fewest faces that share allows (a body of few faces is not refused for one)
FOLDED_FACES = 0.001
FOLDED_FACES_MIN = 8
SEED_RANGE = (0, 2**32 - 1)


def _real(a, what: str, path, line=None) -> np.ndarray:
    x = np.asarray(a)
    if x.dtype.kind not in "biuf":
        raise InputError(f"{what} must be real numbers", path=path, line=line, got=str(x.dtype))
    return x.astype(np.float64)


def check_fps(fps, *, path=None, what: str = "frame rate") -> float:
    """``fps`` as a float inside :data:`FPS_RANGE`; :class:`InputError` naming ``path`` otherwise."""
    try:
        f = float(fps)
    except (TypeError, ValueError):
        raise InputError(f"{what} must be a number", path=path, got=repr(fps)[:40]) from None
    lo, hi = FPS_RANGE
    if not (np.isfinite(f) and lo <= f <= hi):
        raise InputError(
            f"{what} is outside what motion is recorded at",
            path=path,
            expected=f"{lo:g}..{hi:g} frames per second",
            got=f"{f:g}",
        )
    return f


#: the frame rate the motion being read will be played at (:func:`played_at`), None: its own
_PLAYED_FPS: contextvars.ContextVar[float | None] = contextvars.ContextVar("played_fps", default=None)


@contextlib.contextmanager
def played_at(fps):
    """Within it, a motion read at another frame rate than ``fps`` (None: its own), which a run then resamples to it
    (``run --fps``), has the frames :func:`check_translation` refuses named as they are played at ``fps``: the frames
    ``run --frames A:B`` and the run's other messages count (the frame as read is named beside it)."""
    token = _PLAYED_FPS.set(None if fps is None else float(fps))
    try:
        yield
    finally:
        _PLAYED_FPS.reset(token)


def _first_far(t: np.ndarray) -> int | None:
    far = ~(np.abs(t.reshape(len(t), -1)) <= MAX_TRANSLATION).all(axis=1)
    return int(np.argmax(far)) if far.any() else None


def _far_frame(t: np.ndarray, fps) -> str:
    """Where the translations ``t (T, 3)`` (at ``fps``, None: unknown) first go past :data:`MAX_TRANSLATION`, in the
    frames they are played at (:func:`played_at`: resampled as :func:`~segadeform.motion.resample` resamples them)."""
    k = _first_far(t)
    played = _PLAYED_FPS.get()
    if fps is None or played is None or not played > 0 or abs(played - float(fps)) <= 1e-9 or t.ndim != 2:
        return f", first at frame {k}"
    j = _first_far(sample_translations(t, resample_positions(len(t), float(fps), played)))
    if j is None:  # past it only between the frames played
        return f", first at frame {k} as read at {float(fps):g} fps, between the frames played at {played:g} fps"
    return f", first at frame {j} at {played:g} fps (frame {k} as read, at {float(fps):g} fps)"


def check_translation(trans, *, path=None, fps=None) -> None:
    """Every root translation ``(T, 3)`` within :data:`MAX_TRANSLATION` metres of the origin; the refusal names the
    first frame past it (it named none, a user's trial): of the motion as read, or -- read at ``fps`` within
    :func:`played_at` another rate -- as it is played at that rate (the frames a run's ``--frames`` counts)."""
    t = _real(trans, "translations", path)
    m = float(np.abs(t).max()) if t.size else 0.0
    if not m <= MAX_TRANSLATION:  # NaN fails too
        at = _far_frame(t, fps) if t.ndim else ""
        raise InputError(
            "the motion's root moves too far: check the file's units",
            path=path,
            expected=f"|translation| <= {MAX_TRANSLATION:g} m",
            got=f"{m:.3g} m{at}",
        )


def check_pose_angles(poses, *, path=None) -> None:
    """Every axis-angle component of ``poses (T, D)`` within :data:`MAX_POSE_ANGLE` radians; the refusal names the
    first frame and value past it."""
    a = np.asarray(poses)
    huge = ~(np.abs(a) <= MAX_POSE_ANGLE)  # NaN fails too
    if huge.any():
        k = int(np.flatnonzero(huge.ravel())[0])
        frame, col = divmod(k, a.shape[-1]) if a.ndim == 2 else (0, k)
        raise InputError(
            "the poses hold an angle no capture holds",
            path=path,
            expected=f"|axis-angle component| <= {MAX_POSE_ANGLE:g} radians",
            got=f"{a.ravel()[k]:.3g} (frame {frame}, joint {col // 3})",
        )


def check_betas(betas, *, path=None, what: str = "betas") -> tuple:
    """Shape coefficients as a tuple of floats, each finite with ``|beta| <= BETA_LIMIT``."""
    b = _real(betas, what, path).ravel()
    if not np.isfinite(b).all():
        raise InputError(f"{what} must be finite", path=path, got=[float(x) for x in b[:10]])
    if b.size and np.abs(b).max() > BETA_LIMIT:
        raise InputError(
            f"{what} out of range: the shape space ends there (a shape within it may still fold through itself, "
            "which is checked where the body is shaped)",
            path=path,
            expected=f"|beta| <= {BETA_LIMIT:g}",
            got=f"{float(b[np.abs(b).argmax()]):g}",
        )
    return tuple(float(x) for x in b)


def folded_faces(body, betas=None) -> int:
    """How many of ``body``'s faces the shape ``betas`` turns over: their normal points against the same face's on
    the template (the skin folded through itself)."""
    f = np.asarray(body.faces)

    def normals(v):
        return np.cross(v[f[:, 1]] - v[f[:, 0]], v[f[:, 2]] - v[f[:, 0]])

    shaped = normals(np.asarray(body.shaped_vertices(betas)[0], np.float64))
    template = normals(np.asarray(body.v_template, np.float64))
    return int((np.einsum("ij,ij->i", shaped, template) < 0).sum())


def _height(body, betas) -> float:
    return float(np.ptp(body.shaped_vertices(betas)[0][:, 1]))


def height_reach(body, betas) -> tuple | None:
    """The farthest betas along ``betas`` (``t * betas``, ``0 <= t < 1``, each rounded towards 0 to 0.01) whose rest
    height is within :data:`HEIGHT_RANGE`: what a refusal of ``betas`` states as the limit.  None when ``betas`` is
    empty or the unshaped body is outside the range itself.

    A vertex's height is linear in the betas, so the height (highest minus lowest) is convex along ``t``: the shapes
    within the range from ``t = 0`` are one interval, whose end bisection finds.
    """
    b = np.asarray(betas if betas is not None else (), np.float64).ravel()
    lo, hi = HEIGHT_RANGE

    def ok(x) -> bool:
        return lo <= _height(body, x) <= hi

    if not b.size or not ok(np.zeros_like(b)):
        return None
    a, z = 0.0, 1.0
    for _ in range(40):
        m = 0.5 * (a + z)
        a, z = (m, z) if ok(m * b) else (a, m)
    for _ in range(100):  # rounded towards 0 and still within (rounding moves off the ray)
        r = np.trunc(a * b * 100.0) / 100.0
        if ok(r):
            return tuple(float(x) for x in r)
        a *= 0.99
    return None


def _betas_text(betas) -> str:
    return ",".join(f"{float(x):g}" for x in np.ravel(betas))


def check_body_height(body, betas=None, *, force: bool = False, path=None) -> float:
    """The rest height (m) of ``body`` shaped by ``betas``.  Outside :data:`HEIGHT_RANGE`, or with more than
    :data:`FOLDED_FACES` of the body's faces turned over (:func:`folded_faces`: the skin folds through itself, which
    shapes well inside ``|beta| <= 10`` do), the shape is refused unless ``force`` (a shape a user may mean, but no
    human has)."""
    h = _height(body, betas)
    lo, hi = HEIGHT_RANGE
    if not force and not lo <= h <= hi:
        reach = height_reach(body, betas)  # the limit along the betas given (a fixed "+-3" was wrong: 3 is 2.61 m)
        raise InputError(
            "the body shape is not a human's height",
            path=path,
            expected=f"{lo:g}..{hi:g} m"
            + (f" (at most betas {_betas_text(reach)} in the direction given)" if reach is not None else "")
            + ", or --force to use it anyway",
            got=f"{h:.2f} m" + (f" with betas {_betas_text(betas)}" if betas is not None and len(betas) else ""),
        )
    if not force:
        n, total = folded_faces(body, betas), len(body.faces)
        limit = max(FOLDED_FACES * total, FOLDED_FACES_MIN)
        if n > limit:
            raise InputError(
                "the body shape folds through itself",
                path=path,
                expected=f"at most {limit:.0f} of the body's {total} faces turned over (a shape nearer the mean), "
                "or --force to use it anyway",
                got=f"{n} turned over",
            )
    return h


def check_seed(seed, *, path=None) -> int:
    """A procedural motion's seed as an int inside :data:`SEED_RANGE`."""
    if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)):
        raise InputError("seed must be an integer", path=path, got=repr(seed)[:40])
    lo, hi = SEED_RANGE
    if not lo <= int(seed) <= hi:
        raise InputError("seed out of range", path=path, expected=f"{lo}..{hi}", got=int(seed))
    return int(seed)


# ---- where a resampled motion's frames fall (segadeform.motion.resample plays them; here, at the base layer, so that
# a bound's refusal names the frame a run plays: check_translation within played_at)
def sample_translations(trans, t) -> np.ndarray:
    """:func:`sample_frames`' translations alone, of the translations ``trans`` (no :class:`Motion` made of them).

    Shapes:
        trans: (T, 3), t: (M,) -> (M, 3)
    """
    tr = np.asarray(trans, np.float64)
    i0, i1, a = frames_between(t, len(tr))
    return (1 - a) * tr[i0] + a * tr[i1]


def frames_between(t, n_frames: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(i0, i1, a (M, 1))``: the frames each fractional index of ``t`` (clamped to ``n_frames``) lies between, and
    how far from ``i0`` it is."""
    t = np.clip(np.asarray(t, np.float64), 0.0, n_frames - 1)
    i0 = np.clip(np.floor(t).astype(int), 0, n_frames - 1)
    return i0, np.clip(i0 + 1, 0, n_frames - 1), (t - i0)[:, None]


def resample_positions(n_frames: int, fps_from: float, fps_to: float) -> np.ndarray:
    """The fractional frame indices of a motion of ``n_frames`` at ``fps_from`` that :func:`resample` to ``fps_to``
    takes its frames at.

    Shapes:
        -> (M,)
    """
    duration = (n_frames - 1) / fps_from
    n_out = int(np.floor(duration * fps_to + 1e-9)) + 1
    return np.arange(n_out) / fps_to * fps_from
