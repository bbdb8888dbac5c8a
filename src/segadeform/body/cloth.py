"""The cloth stage: a deterministic, stateful contact-and-stretch pass after the network.

It takes the network's frames as targets and returns frames that behave like cloth against the posed body:
edges held within a stretch limit, contact with the body resolved with the neighbours moving along, inertia and
gravity from the previous output frames, and every vertex within a bounded distance of its target (zero where
the garment lies on the body at rest, so there it follows the network exactly).  The method -- position-based
dynamics (Mueller et al. 2007) with strain limiting (Provot 1995), tethers to the nearest attached vertex (long
range attachments, Kim et al. 2012), smoothing of the deviation from the target, max-distance attachments and
contact planes at vertices and edge middles (Bridson et al. 2002), a backstop for deep targets (a free vertex the
network put deeper than ``backstop`` inside the body is traced out along the garment's normal, one side for a
whole panel, and the move spread to its free neighbours), then the collision stage's exact push-out -- and the
meaning of every knob are in the kernel's header, ``src/segadeform/body/_cloth.c``.  Where the posed body intersects
itself (an arm pressed into the torso), a vertex inside the torso whose closest surface is the arm's buried skin is
taken to the skin outside by the collider's rule for buried skin (``_collide.c``) only in the final push-out, which
every vertex in contact goes through.  Cloth deeper in such a pinch is left there, as the simulator leaves it
(Blender's frames of the held-out dresses hold 0.42-0.48 % of their vertices there): taken out one vertex at a time,
across the arm, it made flaps at a dress's armholes (measured and rendered 30 Nov 2026, ``docs/cloth-eval.md``).

A mesh split along a seam (game-engine exports split vertices at UV seams) is one piece of cloth to the stage: the
vertices at exactly one rest position are welded (:attr:`ClothSetup.weld`), the edges join the seam's two sides, and
each frame puts every copy where its group's lowest vertex is (split so, a dress on a walk tore 7 cm at its seam).

Side by side:

* :class:`ClothStage` -- the fast path: the compiled kernel ``_cloth.c`` (built with the collision kernel it
  calls as the extension ``segadeform.body._cloth``; the C++ runtime compiles the same file and
  ``runtimes/node/src/cloth.js`` ports it) through ctypes.  It keeps the state between calls, so batches of any
  size and a stream of any length give the frames of one long call; memory is O(N).
* :func:`garment_setup` -- the per-garment data (edges, rest lengths, neighbours, each vertex's attachment
  radius from its distance to the body at rest, its tether's anchor and rest length), computed once and cached
  on disk with the garment (``C-<hash>.npz`` in the user cache, :mod:`segadeform.io.cache`), as the garment's
  encoding is.
* :func:`cloth_setup_reference` and :func:`cloth_reference` -- the slow, obvious references: the same rule in
  numpy and Python loops, contacts and the final push-out from the numpy :class:`BodyCollider`; tests compare
  them with the kernel.

Without the compiled kernel (no C compiler at install) the stage is not available: :class:`ClothStage` says so
(the reference is far too slow for production).

What the stretch limit does not hold (measured on held-out skirts and dresses, ``bench/cloth_strain.py`` and
``docs/cloth-eval.md``): contact wins over the stretch limit and attached vertices follow the network, so an edge
ends over its limit (1) where the network puts the garment deep inside the body (a thigh 3-7 cm through a skirt):
kept out along its own closest body point, each vertex lands on the side of the limb nearest to it, neighbours on
different sides, and the edges between them stretch by several hundred percent, which no number of sweeps undoes
in one frame -- the backstop takes the free ones out on one side (on held-out skirts under the motion families
where thighs go through, the 99th percentile of stretch 27-81 % -> 14-22 %), but a traced vertex next to an
attached one (which keeps the network's place) still stretches the edge between them; (2)
where both ends are attached and the network's frame is itself stretched (on a dress 12 % of the network's
edge-frames are over a 3 % limit; Blender's own frames reach 149 %).  A third cause, loose vertices sagging a
steady ``gravity dt^2 (1 - follow) / follow`` below the network's frame (1.1 cm at 30 fps) below the attached
ones while four sweeps of edges cannot carry the pull down a hanging chain, is what the tethers remove (issue
#26: the 99th percentile of stretch on held-out skirts 13.1 -> 7.8 % and 26.8 -> 22.1 %, a dress 17.7 -> 16.4 %).
Pops (a vertex stepping more than 3 cm and 3x the network's step between frames; ten garment x CMU-clip pairs,
``docs/cloth-eval.md``): an edge middle found deeper than ``EDGE_DEEP`` (2 cm) inside gets no contact plane -- its
plane, from a closest surface that may be on either side of a limb through the cloth, moved a T-shirt's vertices 7 cm
one frame and not the next (360 -> 107 pops on a dance) -- and a backstop trace longer than ``REACH`` (20 cm) is
dropped -- it went through the torso (a jacket's panel traced 37 cm out of the back; 2,459 -> 1,682 on a karate form).
Most pops left on dresses are the first step out of a capture's leading T-pose frame, which the run warns about
(``--repair-glitches`` holds the first settled pose there: the dress on the jumping jacks 537 -> 4 pops).
Prototypes tried and not kept: contact planes from the previous output, strain limiting measured against the
network's own edge lengths, strain-limit and push-out rounds after the sweeps, gravity 0 (the numbers are in
``docs/cloth-eval.md``).
"""

from __future__ import annotations

import ctypes
import dataclasses
import hashlib
import logging
import threading
import weakref
from pathlib import Path

import numpy as np

from ..errors import InputError
from ..geometry._checks import check_mesh
from ..settings.cloth import ClothSettings

__all__ = [
    "ClothSettings",
    "ClothSetup",
    "ClothStage",
    "cloth_setup",
    "cloth_setup_reference",
    "cloth_reference",
    "garment_setup",
    "rest_signed_distance",
    "compiled_available",
    "settings_array",
    "CONTACT_BAND",
    "EDGE_DEEP",
    "REACH",
]

log = logging.getLogger(__name__)

#: metres beyond the margin within which a vertex gets a contact plane (_cloth.c's SCL_CONTACT_BAND)
CONTACT_BAND = 0.005
#: metres: an edge middle found deeper inside than this gets no contact plane (_cloth.c's SCL_EDGE_DEEP): a limb is
#: through the cloth there, and the middle's closest surface may be on either side of it from frame to frame
EDGE_DEEP = 0.02
#: the final push-out's passes (_cloth.c's SCL_PASSES: segadeform.body.collision.push_out's default)
PASSES = 3
#: metres: a final push-out move counted in ``pushed`` (_cloth.c's SCL_MOVED; a vertex already at the margin is not)
MOVED = 1e-6
#: the backstop's sphere-tracing steps (SCL_TRACE), metres past the margin each aims (SCL_OVERSHOOT), Jacobi
#: sweeps spreading the traced moves (SCL_SPREAD) and how far along the garment they spread (SCL_SPREAD_RADIUS, m)
TRACE, OVERSHOOT, SPREAD, SPREAD_RADIUS = 8, 0.001, 40, 0.2
#: metres: a backstop trace longer than this went through the torso, not out of a limb: dropped (SCL_REACH; a
#: jacket's panel in the torso was traced 37 cm out of the back, a pop each frame it was traced and not the next)
REACH = 0.2
#: the backstop traces only vertices whose attachment radius is at least this (SCL_LOOSE, metres): cloth lying on the
#: body at rest (a sleeve's hem on the arm, a few millimetres) keeps the closest-point rule (1 cm up to ABI 13)
LOOSE = 0.007
#: cosine: contact normals within 60 degrees are on the same side of the body (SCL_AGREE); an edge with both ends
#: attached gets a contact plane at its middle only where its ends' and its middle's normals agree so
AGREE = 0.5
#: the per-garment data's version: part of its cache key (a release that changes scl_setup reads no old entry)
SETUP_VERSION = 4
_ABI = 15
#: the order of _cloth.c's settings array
_SETTINGS = (
    "iterations",
    "stiffness",
    "stretch",
    "compress",
    "bending",
    "damping",
    "gravity",
    "dt",
    "margin",
    "reset",
    "follow",
    "backstop",
)


def settings_array(settings: ClothSettings, *, margin: float, dt: float) -> np.ndarray:
    """The kernel's settings array (``_cloth.c``'s ``S_*`` order) for ``settings``, the collision ``margin`` (m)
    and the time step ``dt`` (s per frame).  Shapes: -> (12,)"""
    if not isinstance(settings, ClothSettings):
        raise InputError("cloth settings must be a ClothSettings", got=type(settings).__name__)
    margin, dt = float(margin), float(dt)
    if not (np.isfinite(margin) and 0 <= margin < 1):
        raise InputError("the collision margin must be in [0, 1) metres", got=margin)
    if not (np.isfinite(dt) and 0 < dt <= 10):
        raise InputError("the time step must be in (0, 10] seconds", got=dt)
    vals = dataclasses.asdict(settings) | {"dt": dt, "margin": margin}
    return np.array([float(vals[k]) for k in _SETTINGS], np.float64)


# ---- the compiled kernel ------------------------------------------------------------------------------------
_KERNEL_LOCK = threading.Lock()
_KERNEL: dict = {}  # the loaded library, filled on first use: {"lib": CDLL | None, "why": str}


def _load_kernel():
    """The compiled cloth kernel (a ctypes library) and, when it is missing, why; loaded once per process."""
    from .collision import load_extension

    with _KERNEL_LOCK:
        if not _KERNEL:
            p, i64, f64 = ctypes.c_void_p, ctypes.c_int64, ctypes.c_double
            lib, why = load_extension(
                "_cloth",
                lambda lib: lib.scl_abi() == _ABI and lib.scl_n_settings() == len(_SETTINGS),
                (
                    ("sdc_create", p, (p, i64, p, i64, i64)),
                    ("sdc_free", None, (p,)),
                    ("scl_setup", i64, (p, i64, p, i64, p, f64, f64, p, p, p, p, p, p, p, p)),
                    ("scl_per_sweep", f64, (f64, i64)),
                    ("scl_step", i64, (i64, i64, p, p, p, p, p, p, p, p, i64, p, p, p, i64, p, i64, p, p, p, p)),
                ),
            )
            _KERNEL.update(lib=lib, why=why)
        return _KERNEL["lib"], _KERNEL["why"]


def compiled_available() -> bool:
    """Whether the compiled cloth kernel was built and loads (the stage needs it)."""
    return _load_kernel()[0] is not None


def _kernel():
    lib, why = _load_kernel()
    if lib is None:
        raise InputError(
            "the cloth stage needs its compiled kernel, which is not available (reinstall segadeform "
            "with a C compiler: pip install -e .)",
            expected="segadeform.body._cloth",
            got=why,
        )
    return lib


def _ptr(a: np.ndarray) -> int:
    return a.ctypes.data


# ---- per garment ---------------------------------------------------------------------------------------------
@dataclasses.dataclass(frozen=True, eq=False)
class ClothSetup:
    """The per-garment data of the cloth stage (``_cloth.c``'s ``scl_setup``).

    Shapes: edges (E, 2) int64, a < b, sorted; rest_len (E,); nptr (N + 1,) int64 and nidx (2E,) int64: vertex i's
    neighbours ``nidx[nptr[i]:nptr[i + 1]]``, ascending; radius (N,): how far vertex i may leave its target;
    anchor (N,) int64: free vertex i's tether anchor, the attached vertex nearest to it along the edges (-1: none);
    tether (N,): the rest length of that path; faces (F, 3) int64: the garment's faces (the backstop's normals, through
    ``weld``); weld (N,) int64: the lowest index of the vertices at exactly vertex i's rest position (a seam's two
    sides, split as exports split UV seams, are one point of cloth: the edges join them and every frame puts each
    where its group's lowest vertex is)."""

    edges: np.ndarray
    rest_len: np.ndarray
    nptr: np.ndarray
    nidx: np.ndarray
    radius: np.ndarray
    anchor: np.ndarray
    tether: np.ndarray
    faces: np.ndarray
    weld: np.ndarray

    @property
    def n_vertices(self) -> int:
        return len(self.radius)

    def validate(self) -> ClothSetup:
        """Itself when every array has the shape, type and range the kernel reads (a cached or hand-made setup is
        checked before any C code touches it); else :class:`InputError` ("inconsistent cloth setup", with the
        arrays' shapes)."""
        n, e = len(self.radius), len(self.edges)
        ok: bool | np.bool_ = (
            self.edges.dtype == np.int64
            and self.edges.shape == (e, 2)
            and self.rest_len.shape == (e,)
            and self.nptr.dtype == np.int64
            and self.nptr.shape == (n + 1,)
            and self.nidx.dtype == np.int64
            and self.nidx.shape == (2 * e,)
            and self.radius.dtype == np.float64
            and n >= 1
            and self.rest_len.dtype == np.float64
            and self.anchor.dtype == np.int64
            and self.anchor.shape == (n,)
            and self.tether.dtype == np.float64
            and self.tether.shape == (n,)
            and self.faces.dtype == np.int64
            and self.faces.ndim == 2
            and self.faces.shape[1] == 3
        )
        ok = ok and (self.faces.size == 0 or (self.faces.min() >= 0 and self.faces.max() < n))
        ok = ok and (
            e == 0 or (self.edges.min() >= 0 and self.edges.max() < n and (self.edges[:, 0] < self.edges[:, 1]).all())
        )
        ok = ok and self.nptr[0] == 0 and self.nptr[-1] == 2 * e and (np.diff(self.nptr) >= 0).all()
        ok = ok and (2 * e == 0 or (self.nidx.min() >= 0 and self.nidx.max() < n))
        ok = ok and np.isfinite(self.rest_len).all() and np.isfinite(self.radius).all() and (self.radius >= 0).all()
        ok = ok and self.anchor.min() >= -1 and self.anchor.max() < n
        ok = ok and np.isfinite(self.tether).all() and (self.tether >= 0).all()
        ok = ok and (self.radius[self.anchor[self.anchor >= 0]] == 0).all()  # anchors are attached vertices
        ok = ok and self.weld.dtype == np.int64 and self.weld.shape == (n,)
        ok = ok and self.weld.min() >= 0 and (self.weld <= np.arange(n)).all()
        ok = ok and (self.weld[self.weld] == self.weld).all()  # each group's lowest vertex is its own
        if not ok:
            raise InputError(
                "inconsistent cloth setup",
                expected="scl_setup's arrays",
                got=f"edges {self.edges.shape}, nptr {self.nptr.shape}, radius {self.radius.shape}, "
                f"anchor {self.anchor.shape}, tether {self.tether.shape}, weld {self.weld.shape}",
            )
        return self

    def save(self, path) -> Path:
        """Write the setup's arrays to ``path`` (``.npz``, atomically); :meth:`load` reads them back, checked."""
        from ..io.atomic import atomic_path

        p = Path(path)
        with atomic_path(p) as tmp:
            with open(tmp, "wb") as fh:
                np.savez(fh, **{f.name: getattr(self, f.name) for f in dataclasses.fields(self)})
        return p

    @classmethod
    def load(cls, path) -> ClothSetup:
        """A setup :meth:`save` wrote, checked (:meth:`validate`)."""
        with np.load(path, allow_pickle=False) as z:
            return cls(**{f.name: np.asarray(z[f.name]) for f in dataclasses.fields(cls)}).validate()


def _check_setup_inputs(rest, faces, rest_sd, settings):
    v, f = check_mesh(rest, faces)
    sd = np.ascontiguousarray(rest_sd, np.float64)
    if sd.shape != (len(v),) or not np.isfinite(sd).all():
        raise InputError("rest distances must be finite, one per garment vertex", expected=(len(v),), got=sd.shape)
    if not isinstance(settings, ClothSettings):
        raise InputError("cloth settings must be a ClothSettings", got=type(settings).__name__)
    return np.ascontiguousarray(v, np.float64), np.ascontiguousarray(f, np.int64), sd


def cloth_setup(rest, faces, rest_sd, settings: ClothSettings = ClothSettings()) -> ClothSetup:
    """The per-garment data by the compiled kernel (``scl_setup``).

    Shapes:
        rest: (N, 3) the garment at rest; faces: (F, 3); rest_sd: (N,) signed distance of each vertex from the body
        at rest (:func:`rest_signed_distance`) -> :class:`ClothSetup`
    """
    lib = _kernel()
    v, f, sd = _check_setup_inputs(rest, faces, rest_sd, settings)
    n, nf = len(v), len(f)
    edges = np.empty((max(3 * nf, 1), 2), np.int64)
    rest_len = np.empty(max(3 * nf, 1))
    nptr = np.empty(n + 1, np.int64)
    nidx = np.empty(max(6 * nf, 1), np.int64)
    radius = np.empty(n)
    anchor = np.empty(n, np.int64)
    tether = np.empty(n)
    weld = np.empty(n, np.int64)
    ne = lib.scl_setup(
        _ptr(v),
        n,
        _ptr(f),
        nf,
        _ptr(sd),
        float(settings.attachment),
        float(settings.max_distance),
        _ptr(edges),
        _ptr(rest_len),
        _ptr(nptr),
        _ptr(nidx),
        _ptr(radius),
        _ptr(anchor),
        _ptr(tether),
        _ptr(weld),
    )
    if ne == -1:
        raise MemoryError("out of memory in the cloth stage's setup")
    if ne < 0:
        raise InputError("a face index is out of range", expected=f"0..{n - 1}")
    return ClothSetup(
        edges=edges[:ne].copy(),
        rest_len=rest_len[:ne].copy(),
        nptr=nptr,
        nidx=nidx[: 2 * ne].copy(),
        radius=radius,
        anchor=anchor,
        tether=tether,
        faces=f.copy(),
        weld=weld,
    )


def cloth_setup_reference(rest, faces, rest_sd, settings: ClothSettings = ClothSettings()) -> ClothSetup:
    """:func:`cloth_setup` in numpy, the obvious way (the reference the kernel is tested against)."""
    v, f, sd = _check_setup_inputs(rest, faces, rest_sd, settings)
    n = len(v)
    weld = _weld_reference(v)
    wf = weld[f]  # the faces as if the mesh had never been split
    pairs = np.stack([wf, np.roll(wf, -1, axis=1)], axis=-1).reshape(-1, 2)  # (a, b) of every face side
    pairs = pairs[pairs[:, 0] != pairs[:, 1]]
    pairs = np.unique(np.sort(pairs, axis=1), axis=0)  # sorted by (a, b)
    d = v[pairs[:, 1]] - v[pairs[:, 0]]
    rest_len = np.sqrt(d[:, 0] * d[:, 0] + d[:, 1] * d[:, 1] + d[:, 2] * d[:, 2])
    src = np.concatenate([pairs[:, 0], pairs[:, 1]])
    dst = np.concatenate([pairs[:, 1], pairs[:, 0]])
    order = np.lexsort((dst, src))
    nptr = np.concatenate([[0], np.cumsum(np.bincount(src, minlength=n))]).astype(np.int64)
    over = sd - settings.attachment
    radius = np.where(over > 0, np.minimum(over, settings.max_distance), 0.0).astype(np.float64)
    nidx = dst[order].astype(np.int64)
    anchor, tether = _tethers_reference(v, nptr, nidx, radius)
    return ClothSetup(
        edges=pairs.astype(np.int64).reshape(-1, 2),
        rest_len=rest_len,
        nptr=nptr,
        nidx=nidx,
        radius=radius,
        anchor=anchor,
        tether=tether,
        faces=f.copy(),
        weld=weld,
    )


def _weld_reference(v: np.ndarray) -> np.ndarray:
    """Each vertex's weld (``scl_weld``): the lowest index of the vertices at exactly its position.
    Shapes: (N, 3) -> (N,) int64"""
    _, inverse = np.unique(v + 0.0, axis=0, return_inverse=True)  # (+ 0.0: -0.0 is 0.0, as C's == has it)
    inverse = inverse.reshape(-1)
    lowest = np.full(inverse.max() + 1, len(v), np.int64)
    np.minimum.at(lowest, inverse, np.arange(len(v)))
    return lowest[inverse]


def _tethers_reference(v, nptr, nidx, radius):
    """Each free vertex's tether anchor and rest length (``scl_tethers``): Dijkstra from every attached vertex at
    once (heapq, settled in (distance, index) order), ties between paths of equal length to the smaller anchor."""
    import heapq

    n = len(radius)
    anchor = np.where(radius > 0, -1, np.arange(n)).astype(np.int64)
    dist = np.zeros(n)
    done = np.zeros(n, bool)
    heap = [(0.0, int(i)) for i in np.flatnonzero(anchor >= 0)]
    heapq.heapify(heap)
    while heap:
        d, i = heapq.heappop(heap)
        if done[i] or d > dist[i]:
            continue
        done[i] = True
        for j in nidx[nptr[i] : nptr[i + 1]]:
            if done[j]:
                continue
            e = v[max(i, j)] - v[min(i, j)]
            c = d + np.sqrt(e[0] * e[0] + e[1] * e[1] + e[2] * e[2])
            if anchor[j] < 0 or c < dist[j]:
                dist[j], anchor[j] = c, anchor[i]
                heapq.heappush(heap, (float(c), int(j)))
            elif c == dist[j] and anchor[i] < anchor[j]:
                anchor[j] = anchor[i]
    anchor[~(radius > 0)] = -1
    return anchor, np.where(anchor >= 0, dist, 0.0)


def rest_signed_distance(rest, rest_body, body_faces) -> np.ndarray:
    """Signed distance (negative inside) of each garment vertex from the body at rest (the exact closest point,
    :class:`BodyCollider`): what the attachment radii derive from.

    Shapes:
        rest: (N, 3); rest_body: (V, 3); body_faces: (F, 3) -> (N,)
    """
    from .collision import BodyCollider

    return BodyCollider(rest_body, body_faces).query(np.asarray(rest, np.float64), rest_body).signed_distance


def garment_setup(
    rest, faces, rest_body, body_faces, settings: ClothSettings = ClothSettings(), *, cache_dir=None
) -> ClothSetup:
    """The per-garment data for the garment ``rest``/``faces`` on the body at rest ``rest_body``/``body_faces``,
    read from ``cache_dir`` when it was computed before (``C-<hash>.npz``, keyed by every input and
    :data:`SETUP_VERSION`), else computed (:func:`rest_signed_distance`, :func:`cloth_setup`) and written there.

    Shapes:
        rest: (N, 3); faces: (F, 3); rest_body: (V, 3); body_faces: (F', 3) -> :class:`ClothSetup`
    """
    v = np.ascontiguousarray(rest, np.float64)
    f = np.ascontiguousarray(faces, np.int64)
    b = np.ascontiguousarray(rest_body, np.float64)
    bf = np.ascontiguousarray(body_faces, np.int64)
    h = hashlib.sha256(f"cloth-setup-v{SETUP_VERSION}-{settings.attachment!r}-{settings.max_distance!r}".encode())
    for a in (v, f, b, bf):
        h.update(str(a.shape).encode() + a.tobytes())
    path = Path(cache_dir) / f"C-{h.hexdigest()[:32]}.npz" if cache_dir is not None else None
    if path is not None and path.is_file():
        try:
            s = ClothSetup.load(path)
            if s.n_vertices == len(v):
                return s
        except (OSError, ValueError, KeyError):  # a broken entry is computed again
            log.warning("ignoring unreadable cloth setup cache %s", path)
    s = cloth_setup(v, f, rest_signed_distance(v, b, bf), settings)
    if path is not None:
        try:
            s.save(path)
        except OSError as e:
            log.warning("cannot write the cloth setup cache %s (%s)", path, e.strerror or e)
    return s


# ---- the stage -----------------------------------------------------------------------------------------------
class ClothStage:
    """The cloth stage for one garment on one body, keeping its state between calls (:meth:`step`).

    Args:
        setup: the garment's :class:`ClothSetup` (:func:`garment_setup`).
        body_vertices: (V, 3) any pose of the body (its collider's tree is built from it); body_faces: (F, 3).
        settings: the knobs; margin: metres kept from the body (the collision margin); dt: seconds per frame.
        first_frame: the number of the first frame stepped (for messages only).

    Counters (vertex-frames unless said): ``frames``, ``resets`` (frames where the state was reset because the
    garment jumped, :attr:`ClothSettings.reset`; the first is logged), ``contacts`` (given a contact plane),
    ``pushed`` (moved by the final push-out, more than :data:`MOVED`), ``traced`` (deep targets the backstop
    traced out of the body, ``_cloth.c``).

    One stage is one clip's: call :meth:`reset` before stepping another clip through it (or make a new stage).  A
    stage is not for two threads at once (its state and buffers are its own, unlocked); stages on different threads
    are independent (a library user's trial: two stages on two threads gave the frames of one at a time).
    """

    def __init__(
        self,
        setup: ClothSetup,
        body_vertices,
        body_faces,
        settings: ClothSettings = ClothSettings(),
        *,
        margin: float = 0.004,
        dt: float = 1.0 / 30.0,
        first_frame: int = 0,
    ) -> None:
        lib = _kernel()
        setup.validate()
        bv, bf = check_mesh(body_vertices, body_faces)
        if len(bf) == 0:
            raise InputError("the body has no faces", expected="F >= 1", got=0)
        self.setup, self.settings = setup, settings
        self._settings = settings_array(settings, margin=margin, dt=dt)
        self.margin, self.dt = float(margin), float(dt)
        self.n_vertices, self.n_body = setup.n_vertices, len(bv)
        v = np.ascontiguousarray(bv, np.float64)
        f = np.ascontiguousarray(bf, np.int64)
        h = lib.sdc_create(_ptr(v), len(v), _ptr(f), len(f), 4)
        if not h:
            raise MemoryError("out of memory building the cloth stage's body collider")
        self._lib, self._h = lib, h
        self._free = weakref.finalize(self, lib.sdc_free, h)
        self._arrays = [
            np.ascontiguousarray(a)
            for a in (
                setup.edges,
                setup.rest_len,
                setup.nptr,
                setup.nidx,
                setup.radius,
                setup.anchor,
                setup.tether,
                setup.weld,
                setup.faces,
            )
        ]
        self._state = np.zeros((3, self.n_vertices, 3))
        self._info = np.zeros(6, np.int64)  # have, resets, contacts, pushed, first reset of the last call, traced
        self._buffers: list[np.ndarray | None] = [None, None]  # float64 copies of the frames and the body (_float64)
        self.frames = 0
        self.first_frame = int(first_frame)

    @property
    def resets(self) -> int:
        return int(self._info[1])

    @property
    def contacts(self) -> int:
        return int(self._info[2])

    @property
    def pushed(self) -> int:
        return int(self._info[3])

    @property
    def traced(self) -> int:
        return int(self._info[5])

    def reset(self, first_frame: int = 0) -> None:
        """Start a new clip: forget the previous frames (the next one starts from its target with no velocity) and
        start the counters again, the next frame numbered ``first_frame`` in messages.  Call it between clips: a stage
        stepped on into another clip carries the last one's velocity into it (a library user's trial: 2.6 cm off a
        fresh stage's frames on a clip that began within the reset distance), and its counters and frame numbers went
        on from the old clip's."""
        self._info[:] = 0
        self._state[:] = 0.0
        self.frames = 0
        self.first_frame = int(first_frame)

    def _float64(self, a: np.ndarray, k: int) -> np.ndarray:
        """``a`` as C-contiguous float64: itself when it is, else a copy into the stage's own buffer ``k`` (kept
        between calls: the frames of a stream are copied into memory already mapped, not into a new array each
        call, whose pages the system would zero first)."""
        if a.dtype == np.float64 and a.flags.c_contiguous:
            return a
        buf = self._buffers[k]
        if buf is None or buf.shape[0] < len(a) or buf.shape[1:] != a.shape[1:]:
            buf = self._buffers[k] = np.empty(a.shape, np.float64)
        view = buf[: len(a)]
        try:
            np.copyto(view, a)
        except TypeError:  # complex, object, strings
            raise InputError(
                "the cloth stage takes real coordinates", expected="float or integer arrays", got=str(a.dtype)
            ) from None
        return view

    def step(self, targets, posed) -> np.ndarray:
        """The next frames of the garment.

        Shapes:
            targets: (B, N, 3) the network's frames; posed: (B, V, 3) the posed body -> (B, N, 3) float64
        """
        y = np.asarray(targets)
        bv = np.asarray(posed)
        if y.ndim != 3 or y.shape[1:] != (self.n_vertices, 3):
            raise InputError(
                "the cloth stage takes frames of the garment", expected=f"(B, {self.n_vertices}, 3)", got=y.shape
            )
        if bv.shape != (len(y), self.n_body, 3):
            raise InputError(
                "the posed body must have the body's vertices, one frame per garment frame",
                expected=(len(y), self.n_body, 3),
                got=bv.shape,
            )
        y = self._float64(y, 0)
        bv = self._float64(bv, 1)
        out = np.empty_like(y)
        before, last = self.resets, self._state[2].copy()  # the last target, for the reset's message
        e, rl, nptr, nidx, rad, anc, teth, weld, fc = self._arrays
        status = self._lib.scl_step(
            self.n_vertices,
            len(e),
            _ptr(e),
            _ptr(rl),
            _ptr(nptr),
            _ptr(nidx),
            _ptr(rad),
            _ptr(anc),
            _ptr(teth),
            _ptr(weld),
            len(fc),
            _ptr(fc),
            _ptr(self._settings),
            self._h,
            self.n_body,
            _ptr(bv),
            len(y),
            _ptr(y),
            _ptr(out),
            _ptr(self._state),
            _ptr(self._info),
        )
        if status == -1:
            raise MemoryError("out of memory in the cloth stage")
        if status != 0:  # the kernel checked every frame before stepping any: nothing changed
            f = int(status) - 1
            what = "garment frames" if not np.isfinite(y[f]).all() else "posed body"
            raise InputError(
                f"the cloth stage got NaN or inf in the {what} at frame {self.first_frame + self.frames + f}",
                expected="finite coordinates (from the deformer and the body)",
            )
        if self.resets > before and before == 0:  # the first reset is said, once
            f = int(self._info[4])
            jump = float(np.linalg.norm(y[f] - (y[f - 1] if f > 0 else last), axis=1).mean())
            log.warning(
                "cloth: the garment moved %.3g m on average into frame %d (more than reset=%g m): the stage "
                "started again from the network's frame there (said once; later resets are only counted)",
                jump,
                self.first_frame + self.frames + f,
                self.settings.reset,
            )
        self.frames += len(y)
        return out


# ---- the slow, obvious reference -------------------------------------------------------------------------------
def _per_sweep(k: float, sweeps: int) -> float:
    """1 - (1 - k)^(1/sweeps) by bisection with products only (``scl_per_sweep``)."""
    if not k > 0:
        return 0.0
    if k >= 1 or sweeps <= 1:
        return 1.0 if k >= 1 else float(k)
    lo, hi = 0.0, 1.0
    for _ in range(64):
        mid = 0.5 * (lo + hi)
        q = 1.0
        for _ in range(sweeps):
            q *= 1.0 - mid
        if 1.0 - q < k:
            lo = mid
        else:
            hi = mid
    return 0.5 * (lo + hi)


def cloth_reference(
    targets,
    posed,
    body_faces,
    setup: ClothSetup,
    settings: ClothSettings = ClothSettings(),
    *,
    margin: float = 0.004,
    dt: float = 1.0 / 30.0,
    state: dict | None = None,
    settle: bool = True,
):
    """The cloth stage's rule, slowly and obviously: every frame, vertex and edge in Python, in the kernel's order;
    contacts and the final push-out by the numpy :class:`BodyCollider` (exact closest points).  ``state`` (from a
    previous call, or None) is updated in place and returned.  ``settle=False`` leaves out the settling after the
    push-out (what the kernel did before 30 Nov 2026: for tests that show what it changes).

    Shapes:
        targets: (B, N, 3); posed: (B, V, 3); body_faces: (F, 3) -> (B, N, 3), state dict
    """
    from .collision import BodyCollider

    s = dict(zip(_SETTINGS, settings_array(settings, margin=margin, dt=dt), strict=True))
    iters = int(s["iterations"])
    ks, kb = _per_sweep(s["stiffness"], iters), _per_sweep(s["bending"], iters)
    hi_f, lo_f = 1.0 + s["stretch"], 1.0 - s["compress"]
    keep, drop = 1.0 - s["damping"], s["gravity"] * s["dt"] * s["dt"]
    y_all = np.asarray(targets, np.float64)
    b_all = np.asarray(posed, np.float64)
    n = setup.n_vertices
    st = state if state is not None else {}
    st.setdefault("have", 0)
    for k in ("resets", "contacts", "pushed", "traced"):
        st.setdefault(k, 0)
    col = BodyCollider(b_all[0], body_faces, backend="numpy")
    w = (setup.radius > 0).astype(np.float64)
    out = np.empty_like(y_all)
    for f in range(len(y_all)):
        y, bv = y_all[f], b_all[f]
        have = st["have"]
        if have > 0 and not np.linalg.norm(y - st["yp"], axis=1).mean() <= s["reset"]:
            have = 0
            st["resets"] += 1
        # predict
        if have == 0:
            x = y.copy()
        else:
            v = st["x1"] - st["x0"] if have >= 2 else np.zeros_like(y)
            x = st["x1"] + keep * v - np.array([0.0, drop, 0.0])
            x = x + s["follow"] * (y - x)
        for i in range(n):
            _attach(x, y, i, setup.radius[i])
        # contacts; deep targets traced out (the backstop), then the contacts again
        q = _near_reference(col, x, bv)
        yc, nt = _backstop_reference(col, bv, setup, y, x, q.signed_distance, q.normal, margin, s["backstop"])
        if nt:
            st["traced"] += nt
            q = _near_reference(col, x, bv)
        contact = q.signed_distance < margin + CONTACT_BAND
        ea, eb = setup.edges[:, 0], setup.edges[:, 1]
        free = (setup.radius[ea] > 0) | (setup.radius[eb] > 0)
        # both ends attached: both in contact, on the same side of the body, and the body may bulge into the middle
        # by more than the ends' room and a quarter of the margin (the kernel's edge_near)
        c = _dot3(q.normal[ea], q.normal[eb])
        d = x[eb] - x[ea]
        sd = q.signed_distance
        room = 0.5 * (np.where(sd[ea] > margin, sd[ea], margin) + np.where(sd[eb] > margin, sd[eb], margin))
        room = room - margin + 0.25 * margin
        bulge = 0.25 * _dot3(d, d) * (1.0 - c) > room * room * (1.0 + c)
        e_near = np.flatnonzero(
            np.where(free, contact[ea] | contact[eb], contact[ea] & contact[eb] & (c > AGREE) & bulge)
        )
        e_sd, e_cp, e_n = np.full(len(e_near), np.inf), np.zeros((len(e_near), 3)), np.zeros((len(e_near), 3))
        if len(e_near):
            eq = _near_reference(col, 0.5 * (x[ea[e_near]] + x[eb[e_near]]), bv)
            e_sd, e_cp, e_n = eq.signed_distance.copy(), eq.closest, eq.normal
            a_, b_ = ea[e_near], eb[e_near]
            # ... and its middle on that side too (the kernel's edge_agrees)
            off = ~free[e_near] & ~((_dot3(e_n, q.normal[a_]) > AGREE) & (_dot3(e_n, q.normal[b_]) > AGREE))
            e_sd[off] = np.inf
        x_query = x.copy()
        for it in range(iters):
            fwd = it % 2 == 0
            _stretch_sweep(x, setup, w, ks, hi_f, lo_f, fwd)
            if ks > 0:
                for i in np.flatnonzero(setup.anchor >= 0).tolist():
                    o = x[setup.anchor[i]]
                    d = x[i] - o
                    l2 = d[0] * d[0] + d[1] * d[1] + d[2] * d[2]
                    lim = hi_f * setup.tether[i]
                    if l2 > lim * lim:
                        x[i] = x[i] - ks * (1.0 - lim / np.sqrt(l2)) * d
            if kb > 0:
                for i in range(n) if fwd else reversed(range(n)):
                    nb = setup.nidx[setup.nptr[i] : setup.nptr[i + 1]]
                    if len(nb) == 0 or not setup.radius[i] > 0:
                        continue
                    m = np.zeros(3)
                    for j in nb:
                        m = m + (x[j] - yc[j])
                    m = m / float(len(nb))
                    x[i] = x[i] + kb * (m - (x[i] - yc[i]))
            for i in range(n):
                _attach(x, yc, i, setup.radius[i])
                if contact[i]:
                    nrm, cp = q.normal[i], q.closest[i]
                    sep = nrm[0] * (x[i, 0] - cp[0]) + nrm[1] * (x[i, 1] - cp[1]) + nrm[2] * (x[i, 2] - cp[2]) - margin
                    if sep < 0:
                        x[i] = x[i] - sep * nrm
            for slot, ei in enumerate(e_near.tolist()):
                if not e_sd[slot] < margin + CONTACT_BAND or e_sd[slot] < -EDGE_DEEP:
                    continue
                a, b = setup.edges[ei]
                nrm, cp = e_n[slot], e_cp[slot]
                m = 0.5 * (x[a] + x[b])
                sep = nrm[0] * (m[0] - cp[0]) + nrm[1] * (m[1] - cp[1]) + nrm[2] * (m[2] - cp[2]) - margin
                if sep < 0:
                    x[a] = x[a] - sep * nrm
                    x[b] = x[b] - sep * nrm
        clear = np.where(contact, q.signed_distance, margin + CONTACT_BAND) - margin
        moved = np.sum((x - x_query) ** 2, axis=1) >= clear * clear
        pick = np.flatnonzero(~(clear > 0) | contact | moved)  # contact: the rule for buried skin may move it
        st["contacts"] += int(contact.sum())
        held = np.zeros(n, bool)
        if len(pick):
            pushed, _ = col.push_out(x[pick], bv, margin, iterations=PASSES)
            held[pick] = np.sum((pushed - x[pick]) ** 2, axis=1) > MOVED**2
            st["pushed"] += int(held.sum())
            x[pick] = pushed
        if settle and held.any():  # settling: the stretch limits and attachment again, the pushed vertices held
            before = x.copy()
            for it in range(iters):
                _stretch_sweep(x, setup, w * ~held, ks, hi_f, lo_f, it % 2 == 0)
                for i in np.flatnonzero(~held & (setup.radius > 0)).tolist():
                    _settle_attach(x, yc, before, i, setup.radius[i])
            # ... then those they moved that may be inside or within the margin (the final push-out's test) pushed out
            moved = np.sum((x - x_query) ** 2, axis=1) >= clear * clear
            again = np.flatnonzero((np.sum((x - before) ** 2, axis=1) > 0) & (~(clear > 0) | contact | moved))
            if len(again):
                x[again] = col.push_out(x[again], bv, margin, iterations=PASSES)[0]
        x = x[setup.weld]  # a seam's sides where their group's lowest vertex is
        st["x0"] = x.copy() if have == 0 else st["x1"]
        st["x1"], st["yp"], st["have"] = x.copy(), y.copy(), 1 if have == 0 else 2
        out[f] = x
    return out, st


def _settle_attach(x, y, x0, i, r):
    """The settling's attachment (``settle_attach``): x[i] within r of y[i], or within the distance from y[i] at which
    the sweeps and the push-out left it (x0[i]) if farther."""
    e, f = x[i] - y[i], x0[i] - y[i]
    l2, m2 = e[0] * e[0] + e[1] * e[1] + e[2] * e[2], f[0] * f[0] + f[1] * f[1] + f[2] * f[2]
    if l2 <= r * r or l2 <= m2:
        return
    x[i] = y[i] + ((r if r * r >= m2 else np.sqrt(m2)) / np.sqrt(l2)) * e


def _stretch_sweep(x, setup: ClothSetup, w, ks: float, hi_f: float, lo_f: float, fwd: bool) -> None:
    """One sweep of the strain limits over the edges (forward or backward), free ends moved (``w``: 1 free, 0
    attached), in place."""
    for e in range(len(setup.edges)) if fwd else reversed(range(len(setup.edges))):
        a, b = setup.edges[e]
        wa, wb = w[a], w[b]
        if wa + wb == 0:
            continue
        d = x[b] - x[a]
        l2 = d[0] * d[0] + d[1] * d[1] + d[2] * d[2]
        hi, lo = hi_f * setup.rest_len[e], lo_f * setup.rest_len[e]
        if lo * lo <= l2 <= hi * hi:
            continue
        length = np.sqrt(l2)
        if length < 1e-300:
            continue
        c = length - hi if l2 > hi * hi else length - lo
        sc = ks * c / (length * (wa + wb))
        x[a] = x[a] + wa * sc * d
        x[b] = x[b] - wb * sc * d


def _near_reference(col, pts, bv, radius: float = 0.0, rule: bool = False):
    """The collider's exact query of ``pts`` as the kernel's lookup (``sdc_near``) sees it: every point's closest
    surface (the caller reads the points within the lookup's radius, as the kernel's caller does).  Without
    ``rule`` (the contact lookups) no rule for buried skin: cloth pinched where an arm presses into the torso keeps the
    arm's skin nearest it, whose side says outside.  With it (the backstop's traces) a point farther than ``radius``
    that the winding number calls inside but its closest surface outside takes the nearest skin that is not buried,
    however far (:func:`segadeform.body.collision.reference.unbury` with no bound: a trace asks only whether it is
    still inside; the push-out's bound, ``PINCH``, would call a trace deep in a pinch out)."""
    from .collision import BodyProxy, ProximityResult
    from .collision.reference import unbury

    q = col.query(pts, bv)
    far = np.flatnonzero(q.signed_distance >= radius)
    if not rule or not len(far) or not col.closed:  # (not closed: no winding number, as in the kernel)
        return q
    fr = col._impl._frames(np.asarray(bv, np.float64)[None])  # the numpy collider's tree: its winding number

    def winding(p):
        return col._impl._decided(fr, p, 0)

    k, face, c, bary, dist = unbury(pts[far], q.signed_distance[far], bv, col.faces, winding=winding, bound=np.inf)
    if not len(k):
        return q
    sd, closest, normal = q.signed_distance.copy(), q.closest.copy(), q.normal.copy()
    sd[far[k]], closest[far[k]] = -dist, c
    normal[far[k]] = BodyProxy(bv, col.faces).feature_normals(face, bary)
    return ProximityResult(signed_distance=sd, closest=closest, normal=normal, face=q.face)


def _backstop_reference(col, bv, setup: ClothSetup, y, x, sd, normal, margin: float, deep_at: float):
    """``backstop`` in _cloth.c, obviously: when a loose vertex's target (attachment radius >= :data:`LOOSE`) is
    deeper than ``deep_at`` inside (0: off) and its prediction inside (``sd``), each such vertex's target traced out
    of the body along the target's outward vertex normal (oriented by
    the vote of the vertices just outside), the traced moves held and spread by :data:`SPREAD` Jacobi sweeps over
    the free vertices within :data:`SPREAD_RADIUS` of them along the target's edges (attached ones keep 0); ``x`` is
    moved in place.  Returns the target to use (``y`` when nothing was traced) and how many were traced out."""
    n = len(y)
    loose = [i for i in range(n) if deep_at > 0 and setup.radius[i] >= LOOSE]
    if not loose:
        return y, 0
    # the target's depth decides (its prediction inside too), not the prediction's: that follows the frame before's
    # output, deep one frame, traced out, shallow the next and left to its closest exit on the other side of a limb
    ysd = _near_reference(col, y[loose], bv).signed_distance
    deep = [i for i, t in zip(loose, ysd, strict=True) if t < -deep_at and sd[i] < 0]
    if not deep:
        return y, 0
    from ..geometry.mesh_ops import face_cross

    vn = np.zeros((n, 3))  # area-weighted, unnormalised vertex normals of the target
    wf = setup.weld[setup.faces]  # a seam's two sides one vertex
    fc = face_cross(y, wf)
    for corner in range(3):
        np.add.at(vn, wf[:, corner], fc)
    vote = 0.0
    for i in range(n):
        if 0 <= sd[i] < margin + CONTACT_BAND:
            vote += vn[i, 0] * normal[i, 0] + vn[i, 1] * normal[i, 1] + vn[i, 2] * normal[i, 2]
    sign = -1.0 if vote < 0 else 1.0
    g = np.zeros((len(deep), 3))
    for j, i in enumerate(deep):
        l2 = vn[i, 0] * vn[i, 0] + vn[i, 1] * vn[i, 1] + vn[i, 2] * vn[i, 2]
        g[j] = (sign / np.sqrt(l2) if l2 > 1e-300 else 0.0) * vn[i]
    pts = y[deep].copy()
    out = np.zeros(len(deep), bool)
    for _ in range(TRACE):
        tsd = _near_reference(col, pts, bv, margin, rule=True).signed_distance
        out |= tsd >= margin
        if out.all():
            break
        step = np.where(out, 0.0, margin - tsd + OVERSHOOT)
        pts = pts + step[:, None] * g
    else:
        out |= _near_reference(col, pts, bv, margin, rule=True).signed_distance >= margin
    e = pts - y[deep]  # a trace longer than REACH went through the torso: dropped
    out &= ~(e[:, 0] * e[:, 0] + e[:, 1] * e[:, 1] + e[:, 2] * e[:, 2] > REACH * REACH)
    held = np.zeros(n, bool)
    d = np.zeros((n, 3))
    for j, i in enumerate(deep):
        if out[j] and g[j].any():
            held[i] = True
            d[i] = pts[j] - y[i]
    if not held.any():
        return y, 0
    # the region: within SPREAD_RADIUS of a held vertex along the target's edges (Dijkstra, heapq)
    import heapq

    dist = np.where(held, 0.0, np.inf)
    done = np.zeros(n, bool)
    heap = [(0.0, int(i)) for i in np.flatnonzero(held)]
    heapq.heapify(heap)
    region = []
    while heap:
        dv, v = heapq.heappop(heap)
        if done[v] or dv > dist[v]:
            continue
        done[v] = True
        nb = setup.nidx[setup.nptr[v] : setup.nptr[v + 1]]
        if not held[v] and setup.radius[v] > 0 and len(nb):
            region.append(v)
        for u in nb.tolist():
            e = y[u] - y[v]
            c = dv + np.sqrt(e[0] * e[0] + e[1] * e[1] + e[2] * e[2])
            if done[u] or not c <= SPREAD_RADIUS or not c < dist[u]:
                continue
            dist[u] = c
            heapq.heappush(heap, (float(c), u))
    for _ in range(SPREAD):
        d2 = d.copy()
        for i in region:
            nb = setup.nidx[setup.nptr[i] : setup.nptr[i + 1]]
            m = np.zeros(3)
            for j in nb:
                m = m + d[j]
            d2[i] = m / float(len(nb))
        d = d2
    x += d
    return y + d, int(held.sum())


def _dot3(u, v):
    """Row-wise dot products, summed left to right as the kernel's dot3.  Shapes: (..., 3) twice -> (...)"""
    return u[..., 0] * v[..., 0] + u[..., 1] * v[..., 1] + u[..., 2] * v[..., 2]


def _attach(x, y, i, r):
    """Keep x[i] within r of y[i] (``attach`` in _cloth.c)."""
    e = x[i] - y[i]
    l2 = e[0] * e[0] + e[1] * e[1] + e[2] * e[2]
    if l2 > r * r:
        s = r / np.sqrt(l2) if r > 0 else 0.0
        x[i] = y[i] + s * e
