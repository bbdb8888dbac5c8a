"""Precompute on garment meshes (numpy/scipy only): normals, graph, Laplacian, bands,
geodesics, sampling, the garment type descriptor, vertex features and the garment asset."""

from ..io.garment_asset import ASSET_SCHEMA_VERSION, GarmentAsset
from .descriptor import (
    DEFAULT_N_STAR,
    Descriptor,
    dissimilarity,
    furthest_point_sampling,
    garment_descriptor,
    gaussian_affinity,
    nystrom_eigen,
)
from .features import feature_dim, vertex_features
from .geodesic import DEFAULT_GEODESIC, GEODESIC_METHODS, GeodesicSolver, geodesic_distances
from .graph import DEFAULT_MAX_K, neighbour_graph, valence
from .laplacian import SpectralBasis, cotangent_laplacian, lumped_mass, spectral_bands
from .mesh_ops import boundary_loops, connected_components, face_areas, mean_edge_length, unique_edges, vertex_normals
from .precompute import precompute_garment

__all__ = [
    "ASSET_SCHEMA_VERSION",
    "GarmentAsset",
    "precompute_garment",
    "DEFAULT_N_STAR",
    "Descriptor",
    "dissimilarity",
    "furthest_point_sampling",
    "gaussian_affinity",
    "garment_descriptor",
    "nystrom_eigen",
    "feature_dim",
    "vertex_features",
    "DEFAULT_GEODESIC",
    "GEODESIC_METHODS",
    "GeodesicSolver",
    "geodesic_distances",
    "DEFAULT_MAX_K",
    "neighbour_graph",
    "valence",
    "SpectralBasis",
    "cotangent_laplacian",
    "lumped_mass",
    "spectral_bands",
    "boundary_loops",
    "connected_components",
    "face_areas",
    "mean_edge_length",
    "unique_edges",
    "vertex_normals",
]
