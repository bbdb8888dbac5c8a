"""The compiled backend of the body collider: ``_collide.c`` (built by setup.py as ``segadeform.body._collide``)
loaded through ctypes, once per process, and its collider for one body topology (:class:`CompiledBVH`).
:func:`load_extension` loads the package's other kernel (``_cloth``) the same way."""

from __future__ import annotations

import concurrent.futures
import ctypes
import functools
import importlib.util
import logging
import threading
import weakref

import numpy as np

from .reference import ProximityResult

__all__ = ["load_extension", "load_kernel", "compiled_available", "warn_fallback", "CompiledBVH"]

log = logging.getLogger("segadeform.body.collision")
#: the package the extension modules are built into
_BODY_PACKAGE = "segadeform.body"

_KERNEL_LOCK = threading.Lock()
_KERNEL: dict = {}  # a cache of the loaded library, filled on first use: {"lib": CDLL | None, "why": str}
_ABI = 6  # sdc_abi() of the kernel this wrapper speaks to


def load_extension(module: str, current, signatures):
    """The extension module ``module`` of this package (``_collide``, ``_cloth``: built by setup.py, C reached through
    ctypes) as a ctypes library with ``signatures`` ((name, restype, argtypes), ...) set, and, when it cannot be
    used, None and why: not built, not loadable, or ``current(lib)`` false (built from another version)."""
    lib, why = None, ""
    try:
        spec = importlib.util.find_spec(_BODY_PACKAGE + "." + module)
        if spec is None or not spec.origin:
            why = "the extension module was not built (no C compiler at install?)"
        else:
            lib = ctypes.CDLL(spec.origin)
            if not current(lib):
                lib, why = None, f"{spec.origin} is from another version (reinstall segadeform)"
    except (OSError, ImportError, AttributeError) as e:
        lib, why = None, f"cannot load it ({e})"
    if lib is not None:
        for name, res, args in signatures:
            fn = getattr(lib, name)
            fn.restype, fn.argtypes = res, args
    return lib, why


def load_kernel():
    """The compiled kernel (a ctypes library) and, when it is missing, why; loaded once per process."""
    with _KERNEL_LOCK:
        if not _KERNEL:
            p, i64 = ctypes.c_void_p, ctypes.c_int64
            lib, why = load_extension(
                "_collide",
                lambda lib: lib.sdc_abi() == _ABI,
                (
                    ("sdc_create", p, (p, i64, p, i64, i64)),
                    ("sdc_free", None, (p,)),
                    ("sdc_n_nodes", i64, (p,)),
                    ("sdc_depth", i64, (p,)),
                    ("sdc_closed", i64, (p,)),
                    ("sdc_refit", None, (p, p, p)),
                    ("sdc_query", None, (p, p, p, p, i64, i64, p, p, p, p)),
                    ("sdc_push_out", i64, (p, p, p, i64, p, i64, i64, i64, ctypes.c_double, i64, p)),
                    ("sdc_push_out_carried", i64, (p, p, p, i64, p, i64, i64, i64, ctypes.c_double, i64, p, p)),
                    ("sdc_acos", ctypes.c_double, (ctypes.c_double,)),
                    ("sdc_winding", i64, (p, p, p, p, i64, i64, p)),
                ),
            )
            _KERNEL.update(lib=lib, why=why)
        return _KERNEL["lib"], _KERNEL["why"]


def compiled_available() -> bool:
    """Whether the compiled collision kernel was built and loads (else the collider runs numpy)."""
    return load_kernel()[0] is not None


def warn_fallback(why: str) -> None:
    """One warning per process that the numpy collider stands in for the compiled one."""
    with _KERNEL_LOCK:
        if _KERNEL.get("warned"):
            return
        _KERNEL["warned"] = True
    log.warning(
        "the compiled collision kernel is not available (%s): using the numpy BodyCollider, several times slower", why
    )


class CompiledBVH:
    """The compiled kernel's collider for one body topology (``_collide.c``): ctypes calls on numpy arrays.

    Work is split into disjoint ranges of points (frames, for the refit) run on ``threads`` threads;
    every point's result is independent of the split, so the output is the same for any ``threads``."""

    def __init__(self, lib, vertices, faces, leaf_size: int) -> None:
        v = np.ascontiguousarray(vertices, np.float64)
        f = np.ascontiguousarray(faces, np.int64)
        h = lib.sdc_create(v.ctypes.data, len(v), f.ctypes.data, len(f), leaf_size)
        if not h:
            raise MemoryError("out of memory building the body collider")
        self._lib, self._h = lib, h
        self._free = weakref.finalize(self, lib.sdc_free, h)
        self.n_vertices, self.n_nodes = len(v), int(lib.sdc_n_nodes(h))
        self.depth, self.closed = int(lib.sdc_depth(h)), bool(lib.sdc_closed(h))
        self._pool: concurrent.futures.ThreadPoolExecutor | None = None
        self._pool_size = 0

    def _run(self, calls, threads: int) -> list:
        """Call every ``calls`` entry (no arguments), on up to ``threads`` threads; their results in order."""
        if threads <= 1 or len(calls) <= 1:
            return [c() for c in calls]
        if self._pool is None or self._pool_size != threads:
            if self._pool is not None:
                self._pool.shutdown(wait=False)
            self._pool = concurrent.futures.ThreadPoolExecutor(threads, thread_name_prefix="segadeform-collide")
            self._pool_size = threads
            weakref.finalize(self, self._pool.shutdown, wait=False)
        return list(self._pool.map(lambda c: c(), calls))

    @staticmethod
    def _ranges(n: int, threads: int):
        """Disjoint ranges covering ``[0, n)``: one per thread, or several when threads share the work (a
        range near the body costs more than one far from it)."""
        k = 1 if threads <= 1 else min(n, 8 * threads)
        edges = (np.arange(k + 1) * n) // max(k, 1)
        return [(int(a), int(b)) for a, b in zip(edges[:-1], edges[1:], strict=True) if b > a]

    def _refit(self, verts, threads: int):
        """Boxes (B, n_nodes, 6) of the tree at the posed frames ``verts (B, V, 3)`` (C-contiguous float64)."""
        boxes = np.empty((len(verts), self.n_nodes, 6))
        lib, h = self._lib, self._h
        vs, bs = verts.strides[0], boxes.strides[0]
        self._run(
            [
                functools.partial(lib.sdc_refit, h, verts.ctypes.data + i * vs, boxes.ctypes.data + i * bs)
                for i in range(len(verts))
            ],
            threads,
        )
        return boxes

    def query(self, p, v, threads: int) -> ProximityResult:
        """Exact closest point and signed distance of every point ``p (P, 3)`` against ``v (V, 3)``."""
        pts = np.ascontiguousarray(p, np.float64)
        verts = np.ascontiguousarray(v[None], np.float64)
        boxes = self._refit(verts, threads)
        n = len(pts)
        sd, closest, normal, face = np.empty(n), np.empty((n, 3)), np.empty((n, 3)), np.empty(n, np.int64)
        lib, h = self._lib, self._h
        self._run(
            [
                functools.partial(
                    lib.sdc_query,
                    h,
                    verts.ctypes.data,
                    boxes.ctypes.data,
                    pts.ctypes.data,
                    a,
                    b,
                    sd.ctypes.data,
                    closest.ctypes.data,
                    normal.ctypes.data,
                    face.ctypes.data,
                )
                for a, b in self._ranges(n, threads)
            ],
            threads,
        )
        return ProximityResult(signed_distance=sd, closest=closest, normal=normal, face=face)

    def winding(self, p, v, threads: int) -> np.ndarray:
        """The body's winding number (P,) int64 at ``p (P, 3)`` against ``v (V, 3)``: 0 outside, 1 inside, 2 where
        two parts of a self-intersecting body overlap (``sdc_winding``: a ray's signed crossings)."""
        pts = np.ascontiguousarray(p, np.float64)
        verts = np.ascontiguousarray(v[None], np.float64)
        boxes = self._refit(verts, threads)
        wind = np.empty(len(pts), np.int64)
        lib, h = self._lib, self._h
        self._run(
            [
                functools.partial(
                    lib.sdc_winding, h, verts.ctypes.data, boxes.ctypes.data, pts.ctypes.data, a, b, wind.ctypes.data
                )
                for a, b in self._ranges(len(pts), threads)
            ],
            threads,
        )
        return wind

    def push_out(self, p, v, margin: float, iterations: int, threads: int, carry=None):
        """:func:`push_out` of ``p (B, N, 3)`` against ``v (B, V, 3)``: the moved points and how many moved.  With
        ``carry`` (N, 3) C-contiguous float64, updated in place: the frames are consecutive and the correction is
        carried between them (``sdc_push_out_carried``)."""
        out = np.array(p, np.float64, order="C")
        verts = np.ascontiguousarray(v, np.float64)
        boxes = self._refit(verts, threads)
        nb, n = out.shape[:2]
        moved = np.zeros((nb, n), np.uint8)
        lib, h = self._lib, self._h
        fn = lib.sdc_push_out if carry is None else lib.sdc_push_out_carried
        tail = () if carry is None else (carry.ctypes.data,)
        self._run(
            [
                functools.partial(
                    fn,
                    h,
                    verts.ctypes.data,
                    boxes.ctypes.data,
                    nb,
                    out.ctypes.data,
                    n,
                    a,
                    b,
                    float(margin),
                    int(iterations),
                    moved.ctypes.data,
                    *tail,
                )
                for a, b in self._ranges(n, threads)
            ],
            threads,
        )
        return out, int(moved.sum())
