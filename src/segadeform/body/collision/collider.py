"""The body collider: one interface (:class:`BodyCollider`: ``query``, ``push_out``) over the compiled and numpy
backends, chosen once when it is built; and :class:`ReferenceCollider`, the same interface over the slow, obvious
:class:`~segadeform.body.collision.reference.BodyProxy` (benchmarks and tests only)."""

from __future__ import annotations

import numpy as np

from ...errors import InputError
from ...geometry._checks import check_mesh
from .compiled import CompiledBVH, load_kernel, warn_fallback
from .numpy_bvh import NumpyBVH
from .reference import BodyProxy, ProximityResult, body_size, carry_correction, push_out, winding_number

__all__ = ["BodyCollider", "ReferenceCollider"]


class BodyCollider:
    """Fast, exact collisions against a body whose triangles stay the same while its vertices move
    every frame (the posed body): everything that depends on the triangles is built once.

    A bounding-volume hierarchy over the triangles is built once (see :func:`_build_bvh`); per frame only
    its axis-aligned boxes are recomputed from the posed vertices, bottom-up (a few vectorised passes,
    no sorting).  A query then walks the tree a few levels at a time for all points together:

    1. *near*: every leaf whose box lies within ``margin`` of the point, then the exact closest point on
       the leaves' triangles.  Every triangle closer than ``margin`` is in a kept leaf, so a closest point
       found closer than ``margin`` is the exact one (:func:`_closest_soa`, with the same feature rule and
       pseudo-normals as :class:`BodyProxy`).
    2. *the others' side*: a point farther than ``margin`` is left alone unless it is inside.  A ray from
       it (pointing away from the body's centre, which only makes it cheaper) is traced through the same
       tree and its crossings with the triangles are summed with their orientation: zero for a point
       outside a closed mesh.  A ray that grazes an edge or a vertex is cast again in another direction.
    3. points whose count is not zero (inside, deep or not) get the exact closest point by branch and
       bound with no radius (the radius shrinking to the farthest corner of the nearest box).
    4. *buried skin* (``push_out`` only; ``query`` keeps the closest surface): where the posed body
       intersects itself (an arm pressed into the torso), a point in the torso can be nearest the arm's skin
       buried in it, whose side says outside.  A point whose closest feature says outside but whose winding
       number (the ray's count) says inside is moved to the nearest point that is not buried instead (a
       surface point is buried when the point just outside it is inside the body): out of the torso, not onto
       the buried arm (:func:`~segadeform.body.collision.reference.unbury`, issue #26) -- when that point is
       within ``PINCH`` times the body's size; a point deeper in the crease keeps its closest surface (pinched:
       the nearest open skin there flips from in front of the arm to behind it between frames).

    So every point closer than ``margin`` or inside gets the brute-force closest point (over every
    triangle), which :class:`BodyProxy` -- the slow, obvious reference beside it -- approximates with its
    ``k`` nearest centroids; ``tests/body/test_collision.py`` compares the two, and both with brute
    force.  A mesh that is not closed (an edge not shared by exactly two opposite faces) gets no ray
    test: every point takes step 3 (exact, slow).  Frames can be batched: the boxes of ``B`` frames are
    stacked so that one walk serves them all.

    That is the ``"numpy"`` backend.  The ``"compiled"`` one (``_collide.c``, the default when it was built)
    follows the same three steps one point at a time, with a binary tree, a ray along the coordinate axis
    that leaves the body's box soonest (a ray through an edge or a vertex takes step 3 instead of a second
    ray) and, for push-out, the passes of each point in a row; see the C file's header.  Both give the
    exhaustive reference's result; they can differ where two triangles are equally near (a point pushed
    onto an edge: either face, the same distance).

    Args:
        vertices: (V, 3) any pose of the body (the tree is built from it); faces: (F, 3) outward triangles.
        leaf_size: triangles per leaf (at most).
        step: tree levels per pass of the walk (a ``2**step``-ary tree; numpy backend only).
        backend: ``"auto"`` (compiled if built, else numpy with one logged warning), ``"compiled"`` (an
            error if it was not built) or ``"numpy"``.
        threads: threads for the compiled backend (points split between them; same results for any
            number).
    """

    def __init__(
        self, vertices, faces, *, leaf_size: int = 4, step: int = 2, backend: str = "auto", threads: int = 1
    ) -> None:
        v, f = check_mesh(vertices, faces)
        if len(f) == 0:
            raise InputError("the body has no faces", expected="F >= 1", got=0)
        for name, x in (("leaf_size", leaf_size), ("step", step), ("threads", threads)):
            if isinstance(x, bool) or not isinstance(x, (int, np.integer)) or x < 1:
                raise InputError(f"{name} must be a positive integer", expected=">= 1", got=x)
        if backend not in ("auto", "compiled", "numpy"):
            raise InputError("unknown collision backend", expected="'auto', 'compiled' or 'numpy'", got=repr(backend))
        self.faces = f
        self.n_vertices = len(v)
        self.threads = int(threads)
        self._args = (
            v,
            f,
            {"leaf_size": int(leaf_size), "step": int(step), "backend": backend, "threads": self.threads},
        )
        kernel = None
        if backend != "numpy":  # the backend is chosen here, once: every call goes to it
            kernel, why = load_kernel()
            if kernel is None and backend == "compiled":
                raise InputError(
                    "the compiled collision kernel is not available (reinstall segadeform with a C "
                    "compiler, or use backend='numpy')",
                    expected="segadeform.body._collide",
                    got=why,
                )
            if kernel is None:
                warn_fallback(why)
        self.backend = "numpy" if kernel is None else "compiled"
        self._impl = (
            CompiledBVH(kernel, v, f, int(leaf_size))
            if kernel is not None
            else NumpyBVH(v, f, int(leaf_size), int(step))
        )
        self.closed, self.depth = self._impl.closed, self._impl.depth

    def __reduce__(self):
        v, f, kw = self._args
        return (_rebuild_collider, (v, f, kw))

    def _check(self, points, posed):
        p = np.asarray(points, np.float64)
        v = np.asarray(posed, np.float64)
        if p.ndim not in (2, 3) or p.shape[-1] != 3:
            raise InputError("points must be (N, 3) or (B, N, 3)", got=p.shape)
        batched = p.ndim == 3
        want = (p.shape[0], self.n_vertices, 3) if batched else (self.n_vertices, 3)
        if v.shape != want:
            raise InputError(
                "the posed body must have the body's vertices, one frame per frame of points",
                expected=want,
                got=v.shape,
            )
        if not np.isfinite(p).all():
            raise InputError("points contain NaN or inf")
        if not np.isfinite(v).all():
            raise InputError("the posed body contains NaN or inf")
        return (p, v) if batched else (p[None], v[None])

    def query(self, points, posed) -> ProximityResult:
        """Exact signed distance (negative inside), closest point, outward normal and face for every point,
        by branch and bound with no radius: the brute-force answer (slower than :meth:`push_out`, which
        only looks for points near or inside).

        Shapes:
            points: (P, 3), posed: (V, 3) -> fields (P,) / (P, 3)
        """
        p, v = self._check(points, posed)
        if p.shape[0] != 1 or np.ndim(points) != 2:
            raise InputError("query takes one frame of points", expected="(P, 3)", got=np.shape(points))
        if isinstance(self._impl, CompiledBVH):  # self.backend == "compiled"
            return self._impl.query(p[0], v[0], self.threads)
        return self._impl.query(p, v)

    def winding(self, points, posed) -> np.ndarray:
        """The body's winding number at every point: 0 outside, 1 inside, 2 where two parts of a posed body that
        intersects itself overlap.  Unlike :meth:`query`'s sign, which the closest surface decides, a point inside
        the torso whose closest surface is the buried skin of an arm pressed into it is inside here.  Compiled: a
        ray's signed crossings (``sdc_winding``); numpy: the reference's generalised winding number, rounded
        (exact, O(P F): slow).

        Shapes:
            points: (P, 3), posed: (V, 3) -> (P,) int64
        """
        p, v = self._check(points, posed)
        if p.shape[0] != 1 or np.ndim(points) != 2:
            raise InputError("winding takes one frame of points", expected="(P, 3)", got=np.shape(points))
        if isinstance(self._impl, CompiledBVH):
            return self._impl.winding(p[0], v[0], self.threads)
        return np.rint(np.abs(winding_number(p[0], v[0], self.faces))).astype(np.int64)

    def push_out(self, points, posed, margin: float = 0.0, *, iterations: int = 3, carry=None):
        """:func:`push_out` against the body at ``posed``: the same rule, moves and passes, with exact
        closest points (see the class docstring).  Frames can be batched.

        With ``carry`` -- a writable (N, 3) float64 array, zeros at the start of a stream, kept by the caller between
        calls -- the frames are consecutive and each point's correction (its place after the push-out minus before)
        is carried from frame to frame: where the closest exit jumps to another side of a limb, the exit nearest the
        frame before's correction is kept (:func:`~segadeform.body.collision.reference.carry_correction`); ``carry``
        is left holding the last frame's corrections, so a stream cut into calls anywhere gives the frames of one
        call.  The number moved then counts the points whose place changed.

        Shapes:
            points: (N, 3), posed: (V, 3) -> (N, 3), and the number of points moved
            points: (B, N, 3), posed: (B, V, 3) -> (B, N, 3), and the number of points moved in all frames
            carry: (N, 3), updated in place
        """
        p, v = self._check(points, posed)
        margin = float(margin)
        if not np.isfinite(margin) or margin < 0:
            raise InputError("margin must be finite and >= 0", got=margin)
        iterations = max(1, int(iterations))
        carry = _check_carry(carry, p.shape[1])
        if isinstance(self._impl, CompiledBVH):  # self.backend == "compiled"
            out, moved = self._impl.push_out(p, v, margin, iterations, self.threads, carry)
        elif carry is None:
            out, moved = self._impl.push_out(p, v, margin, iterations)
        else:  # numpy: the frames pushed out together, then the rule frame by frame
            impl = self._impl
            out = impl.push_out(p, v, margin, iterations)[0].reshape(p.shape)
            for f in range(len(p)):
                out[f] = carry_correction(
                    p[f],
                    out[f],
                    carry,
                    body_size(v[f], self.faces),
                    lambda x, f=f: impl.push_out(x[None], v[f : f + 1], margin, iterations)[0],
                )
            moved = int(np.any(out != p, axis=2).sum())
        return out.reshape(np.shape(points)), moved


def _check_carry(carry, n: int):
    """``carry`` for :meth:`BodyCollider.push_out`: None, or a writable C-contiguous (n, 3) float64 array of finite
    values (it is updated in place, so it is not converted)."""
    if carry is None:
        return None
    if not isinstance(carry, np.ndarray) or carry.dtype != np.float64 or carry.shape != (n, 3):
        raise InputError(
            "carry must be a float64 numpy array with a row per point",
            expected=f"({n}, 3) float64",
            got=f"{getattr(carry, 'shape', type(carry).__name__)} {getattr(carry, 'dtype', '')}".strip(),
        )
    if not (carry.flags.c_contiguous and carry.flags.writeable):
        raise InputError("carry must be C-contiguous and writable (it is updated in place)", got=carry.flags)
    if not np.isfinite(carry).all():
        raise InputError("carry contains NaN or inf")
    return carry


def _rebuild_collider(vertices, faces, kwargs):
    """Unpickle a :class:`BodyCollider` (the compiled one holds a C pointer: it is built again)."""
    return BodyCollider(vertices, faces, **kwargs)


class ReferenceCollider:
    """:class:`BodyCollider`'s ``push_out`` and ``query`` by the reference, frame by frame: a
    :class:`~segadeform.body.collision.reference.BodyProxy` per posed frame (the topology built once) and
    :func:`~segadeform.body.collision.reference.push_out`.  Slow; for benchmarks and tests that compare the fast
    path with it (``bench/effects.py``, ``bench/collisions.py``), never the runtime's choice."""

    backend = "reference"

    def __init__(self, vertices, faces, *, threads: int = 1) -> None:
        self._proxy = BodyProxy(vertices, faces)
        self.faces, self.n_vertices, self.threads = self._proxy.faces, len(self._proxy.vertices), int(threads)

    def query(self, points, posed) -> ProximityResult:
        """Shapes: points (P, 3), posed (V, 3) -> fields (P,) / (P, 3)."""
        return self._proxy.moved(posed).query(points)

    def push_out(self, points, posed, margin: float = 0.0, *, iterations: int = 3, carry=None):
        """Shapes: points (B, N, 3), posed (B, V, 3) -> (B, N, 3) float64, and the number of points moved; ``carry``
        (N, 3) as :meth:`BodyCollider.push_out`'s."""
        p = np.asarray(points, np.float64)
        if p.ndim == 2:
            out, n = self.push_out(p[None], np.asarray(posed)[None], margin, iterations=iterations, carry=carry)
            return out[0], n
        fixed, moved = np.empty_like(p), 0
        for i in range(len(p)):
            proxy = self._proxy.moved(posed[i])
            fixed[i], n = push_out(p[i], proxy, margin, iterations=iterations)
            if carry is not None:

                def push(x, proxy=proxy):
                    return push_out(x, proxy, margin, iterations=iterations)[0]

                fixed[i] = carry_correction(p[i], fixed[i], carry, body_size(proxy.vertices, proxy.faces), push)
                n = int(np.any(fixed[i] != p[i], axis=1).sum())
            moved += n
        return fixed, moved
