"""Procedural garments dressed on a body in its rest pose (numpy/scipy only).

See :mod:`.make` for the kinds and their parameters.
"""

from .make import (
    GARMENT_KINDS,
    GARMENT_TYPES,
    KIND_PARAMS,
    WAISTBAND_KINDS,
    Garment,
    GarmentParams,
    check_garment,
    make_garment,
)

__all__ = [
    "GARMENT_KINDS",
    "GARMENT_TYPES",
    "KIND_PARAMS",
    "WAISTBAND_KINDS",
    "Garment",
    "GarmentParams",
    "make_garment",
    "check_garment",
]
