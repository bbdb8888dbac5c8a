"""The training garments a package remembers (``manifest.json`` ``training_garments``), so a runtime can
warn when a garment lies outside them (:data:`segadeform.contracts.model_package.TRAINING_GARMENTS`)."""

from __future__ import annotations

import os
from collections.abc import Sequence

import numpy as np

from segadeform.errors import InputError
from segadeform.geometry.descriptor import garment_descriptor, novelty_threshold

__all__ = ["training_garments_entry", "mesh_descriptors"]


def training_garments_entry(names: Sequence[str], descriptors, openings: Sequence[int] | None = None) -> dict:
    """The manifest entry for garments ``names`` with descriptors ``(R, N*)`` and, optionally, their
    number of openings (boundary loops: a skirt 2, trousers 3, a top 4, a jumpsuit 5).

    Rows with the same name (one garment made on several bodies) count as one garment for the
    threshold (:func:`~segadeform.geometry.descriptor.novelty_threshold`); identical rows are kept once.
    """
    d = np.asarray(descriptors, np.float64)
    names = [str(n) for n in names]
    if d.ndim != 2 or d.shape[0] != len(names) or d.shape[0] == 0 or not np.isfinite(d).all():
        raise InputError("expected finite (R, N*) descriptors, one per name", got=(d.shape, len(names)))
    if openings is not None and len(openings) != len(names):
        raise InputError("expected one openings count per name", expected=len(names), got=len(openings))
    seen, rows = set(), []
    for i, (n, row) in enumerate(zip(names, d, strict=False)):
        key = (n, row.tobytes())
        if key not in seen:
            seen.add(key)
            g = {"name": n, "descriptor": [float(x) for x in row]}
            if openings is not None:
                g["openings"] = int(openings[i])
            rows.append(g)
    thr = novelty_threshold(np.array([g["descriptor"] for g in rows]), [g["name"] for g in rows])
    return {"metric": "eq19", "threshold": None if thr is None else float(thr), "garments": rows}


def mesh_descriptors(paths: Sequence[str | os.PathLike], n_star: int) -> tuple[list[str], np.ndarray, list[int]]:
    """Names (file stems), descriptors ``(R, N*)`` and openings of garment mesh files (any readable format):
    the arguments of :func:`training_garments_entry`."""
    from pathlib import Path

    from segadeform.geometry.mesh_ops import boundary_loops
    from segadeform.io import read_mesh

    names, rows, openings = [], [], []
    for p in paths:
        m = read_mesh(p)
        rows.append(garment_descriptor(m.vertices, m.faces, n_star=n_star).eigenvalues)
        names.append(Path(p).stem)
        openings.append(len(boundary_loops(m.faces, len(m.vertices))))
    if not rows:
        raise InputError("no training garment files given")
    return names, np.stack(rows), openings
