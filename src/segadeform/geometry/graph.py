"""The padded neighbour graph the exported model gathers from.

ONNX engines handle fixed-width gathers well and scatter-with-reduction
badly, so the mesh's 1-ring is stored as a dense ``(N, K)`` index array plus
a validity mask; attention gathers ``X[nbr]`` and masks the padding.
"""

from __future__ import annotations

import numpy as np

from ..errors import InputError
from ._checks import check_faces
from .mesh_ops import unique_edges

__all__ = ["DEFAULT_MAX_K", "neighbour_graph", "valence"]

#: Cap on K when it is chosen automatically.  Garment meshes from DCC tools
#: and remeshers have valence 4-8 and rarely above 12; 16 leaves room while
#: bounding the (N, K) gathers that dominate the model's cost.
DEFAULT_MAX_K = 16


def valence(faces: np.ndarray, n_vertices: int) -> np.ndarray:
    """Number of distinct edge neighbours of each vertex ``(N,) int64``."""
    e = unique_edges(faces, n_vertices)
    return np.bincount(e.ravel(), minlength=n_vertices).astype(np.int64)


def neighbour_graph(
    faces: np.ndarray,
    n_vertices: int,
    *,
    k: int | None = None,
    vertices: np.ndarray | None = None,
    max_k: int = DEFAULT_MAX_K,
    self_loops: bool = False,
) -> tuple[np.ndarray, np.ndarray]:
    """Padded 1-ring neighbour lists.

    K is ``k`` when given; otherwise ``min(max valence, max_k)`` (at least 1).
    A vertex with more than K neighbours keeps the K nearest by rest-pose edge
    length when ``vertices`` is given (ties, and the no-``vertices`` case, by
    neighbour index): long edges carry the least local detail.  Unused slots
    hold the vertex's own index with ``mask = False``, so a gather through
    them is always in range; an isolated vertex has an all-False row.  With
    ``self_loops=True`` slot 0 is the vertex itself (mask True) and the
    neighbours fill slots 1..K-1, as in GAT with self-attention.

    Returns:
        nbr: (N, K) int64, neighbour indices, ascending by (length, index)
        mask: (N, K) bool, True where ``nbr`` is a real neighbour
    """
    if not isinstance(n_vertices, (int, np.integer)) or n_vertices < 1:
        raise InputError("n_vertices must be a positive integer", got=n_vertices)
    f = check_faces(faces, int(n_vertices))
    n = int(n_vertices)
    e = unique_edges(f)
    src = np.concatenate([e[:, 0], e[:, 1]])
    dst = np.concatenate([e[:, 1], e[:, 0]])
    if vertices is not None:
        v = np.asarray(vertices, np.float64)
        if v.shape != (n, 3):
            raise InputError("vertices must be (N, 3) for this graph", expected=(n, 3), got=v.shape)
        length = np.linalg.norm(v[dst] - v[src], axis=1)
    else:
        length = np.zeros(len(src))
    order = np.lexsort((dst, length, src))
    src, dst = src[order], dst[order]
    deg = np.bincount(src, minlength=n)
    offset = np.concatenate([[0], np.cumsum(deg)[:-1]])
    rank = np.arange(len(src)) - offset[src]
    extra = 1 if self_loops else 0
    if k is None:
        k = max(1, min(int(deg.max(initial=0)), max_k) + extra)
    k = int(k)
    if k < 1 + extra:
        raise InputError("K is too small", expected=f">= {1 + extra}", got=k)
    nbr = np.repeat(np.arange(n, dtype=np.int64)[:, None], k, axis=1)
    mask = np.zeros((n, k), dtype=bool)
    keep = rank < (k - extra)
    nbr[src[keep], rank[keep] + extra] = dst[keep]
    mask[src[keep], rank[keep] + extra] = True
    if self_loops:
        mask[:, 0] = True
    return nbr, mask
