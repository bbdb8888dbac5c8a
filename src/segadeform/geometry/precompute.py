"""Every precompute step on a garment, in one call: the garment asset
(:class:`segadeform.io.garment_asset.GarmentAsset`, its file format and fields)."""

from __future__ import annotations

import numpy as np

from .. import __version__
from ..errors import InputError
from ..io.garment_asset import GarmentAsset
from ._checks import check_faces, check_mesh, check_vertices
from .descriptor import DEFAULT_N_STAR, garment_descriptor
from .features import vertex_features
from .geodesic import DEFAULT_GEODESIC, GeodesicSolver
from .graph import DEFAULT_MAX_K, neighbour_graph
from .mesh_ops import connected_components, surface_faces, vertex_normals

__all__ = ["precompute_garment", "PRECOMPUTE_VERSION"]

#: the precompute's version: part of every cache key of an asset (2: the shape from the surface's faces only,
#: ``mesh_ops.surface_faces``; a cache keyed by the garment's bytes alone kept a user's assets of the rule before;
#: 3: a quad repeated along its other diagonal is no surface either)
PRECOMPUTE_VERSION = 3


def precompute_garment(
    vertices,
    faces,
    joints,
    *,
    k: int | None = None,
    max_k: int = DEFAULT_MAX_K,
    n_star: int = DEFAULT_N_STAR,
    geodesic: str = DEFAULT_GEODESIC,
    source_name: str = "",
    source_sha256: str = "",
    surface=None,
) -> GarmentAsset:
    """Run every precompute step on a garment and return the asset.

    Memory is O(N K + N* N): no step forms an N x N matrix.  ``surface``: the garment's
    :func:`~segadeform.geometry.mesh_ops.surface_faces`, when the caller has them (a run shares them with its checks:
    1.5 s on a 69k-vertex garment); None: computed here.

    Shapes:
        vertices: (N, 3), faces: (F, 3), joints: (S, 3), surface: (F', 3)
    """
    v, f = check_mesh(vertices, faces)
    j = check_vertices(joints, "joints")
    # the shape from the faces that make the surface (no flat, broken or repeated faces: mesh_ops.surface_faces);
    # the graph from every face (a vertex that only a flat face holds keeps its neighbours: with none, attention has
    # nothing to read); the asset keeps the garment's own faces, which the outputs are written with
    sf = surface_faces(v, f) if surface is None else check_faces(surface, v.shape[0])
    if len(sf) == 0:
        raise InputError("the garment has no face with an area", expected="triangles whose corners are not collinear")
    normals = vertex_normals(v, sf)
    feats = vertex_features(v, sf, j, normals=normals)
    nbr, mask = neighbour_graph(f, v.shape[0], k=k, vertices=v, max_k=max_k)
    solver = GeodesicSolver(v, sf, method=geodesic)
    desc = garment_descriptor(v, sf, n_star=n_star, solver=solver)
    params = {
        "k": int(nbr.shape[1]),
        "max_k": int(max_k),
        "n_star": int(n_star),
        "geodesic": geodesic,
        "segadeform_version": __version__,
        # the garment's pieces by all its faces (a vertex that only a flat face holds is not a piece of its own)
        "n_components": connected_components(f, v.shape[0])[0],
        "precompute": PRECOMPUTE_VERSION,
    }
    return GarmentAsset(
        vertices=v,
        faces=f,
        normals=normals.astype(np.float32),
        features=feats,
        nbr=nbr,
        mask=mask,
        joints=j.astype(np.float64),
        descriptor=desc.eigenvalues.astype(np.float64),
        fps_samples=desc.samples.astype(np.int64),
        geodesic_radius=float(desc.radius),
        params=params,
        source_name=source_name,
        source_sha256=source_sha256,
    )
