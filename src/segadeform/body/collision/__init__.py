"""Body collisions: signed distance, closest point and outward normal for query points, and the
push-out of garment vertices found inside the body or closer than a margin.

One rule, three implementations side by side:

* :class:`BodyProxy` with :func:`push_out` -- the slow, obvious reference.  Rebuilt for every
  frame: candidate triangles are the ``k`` with the nearest centroids (scipy cKDTree) plus every
  triangle around the nearest body vertex; the exact closest point on each candidate (Ericson,
  *Real-Time Collision Detection*, 5.1.5) is kept; the sign comes from the angle-weighted
  pseudo-normal of the feature the closest point lies on -- face, edge or vertex (Bærentzen &
  Aanæs 2005), which is exact for a closed, consistently oriented mesh once the closest point is.
  The candidate set can miss the true closest triangle for points far from the surface relative
  to the triangle size.  Cost per query O(k log F), plus the trees, built every frame.
* :class:`BodyCollider` -- the fast path used by the runtime: a tree over the triangles built
  once, refitted to each posed frame, and walked only as far as needed to find every point that
  is inside or closer than the margin; for those it gives the exact (brute-force) closest point,
  with the same feature rule and pseudo-normals.  Two backends (``backend=``):

  - ``"compiled"``: ``_collide.c``, a portable C99 kernel (the C++ runtime compiles the same file;
    the JavaScript runtime ports it), built at install as the extension module
    ``segadeform.body._collide`` and called through ctypes, one point at a time: the nearest
    triangle within a radius a little over the margin, else a ray along an axis whose signed
    crossings tell inside from outside, and the exact unbounded query for points inside.  Points
    can be split over ``threads`` threads; results are identical for any number of threads (each
    point's result is the minimum of (distance, face index) over every triangle, whatever the walk).
  - ``"numpy"``: the same algorithm vectorised over all points in numpy (the fallback when the
    kernel was not built, e.g. no C compiler at install: ``"auto"`` then logs one warning).

  Where the posed body intersects itself (an arm pressed into the torso), a point that the closest
  surface's side calls outside but the body's winding number calls inside -- in the torso, nearest the
  arm's buried skin -- is pushed to the nearest skin that is not buried when that skin is within
  :data:`~.reference.PINCH` times the body's size (2.1 cm at 1.75 m), and otherwise left pinched, as the simulator
  leaves cloth there (all three implementations and the JavaScript port; :func:`~.reference.unbury`).
  ``python bench/buried_skin.py data/continuum --old-kernel OLD.so`` (four held-out dresses' Blender frames,
  3,555-3,841 vertices, against the kernel before the rule): the vertex-frames left inside the body after the
  push-out fell to 0.15-0.33 of what they were, for 12-23 % more CPU time (3.0 -> 3.4-4.0 ms/frame: these frames lie
  on the body, so most vertices are within the margin and each costs one more ray).  Against the unbounded rule
  (before ``PINCH``, 959cd68~1) the bound takes 0.96-1.00x the time and leaves 1.8-2.5x the vertex-frames inside:
  the simulator's own cloth pinched deeper than 2 cm, left where it was.

  Measured by ``bench/collisions.py`` (a 3,916-vertex skirt jittered into and out of the
  13,718-vertex default body, a dance, batches of 8 frames, one thread, passes interleaved on a
  shared 2-core machine): compiled 1.8 ms/frame wall (1.2 ms CPU), numpy 11.3 ms (7.3 ms CPU),
  the reference 101 ms; every one leaves 0.000 % of the vertices inside (3.0 % before).

Files: :mod:`.reference` (the reference), :mod:`.numpy_bvh` and :mod:`.compiled` (the two backends),
:mod:`.collider` (:class:`BodyCollider`, which picks its backend once when built, and :class:`ReferenceCollider`,
the reference behind the same interface for benchmarks and tests).

``tests/body/test_collision.py`` compares both backends against brute force (every triangle), the
sign against the generalised winding number, and the fast push-out against the reference;
``tests/body/test_collision_compiled.py`` holds the compiled kernel's own cases (threads, hard
inputs).  Points exactly on the surface get distance 0 and a finite normal (unit unless the
feature's faces cancel out: zero-area triangles), never NaN.
"""

from .collider import BodyCollider, ReferenceCollider
from .compiled import compiled_available, load_extension
from .numpy_bvh import closest_point_fast
from .reference import (
    BodyProxy,
    ProximityResult,
    carry_correction,
    closest_point_on_triangles,
    push_out,
    winding_number,
)

__all__ = [
    "BodyProxy",
    "BodyCollider",
    "ReferenceCollider",
    "ProximityResult",
    "closest_point_on_triangles",
    "closest_point_fast",
    "winding_number",
    "push_out",
    "carry_correction",
    "compiled_available",
    "load_extension",
]
