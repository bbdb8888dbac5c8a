"""Which body a file was made for: one hash of a body's arrays, recorded by the body graphs of a model
package (``manifest.json`` ``graphs.body_*.body``), by garment assets prepared for a body shape and by
motion files retargeted onto one, so a runtime can tell that the three belong together."""

from __future__ import annotations

import hashlib

import numpy as np

__all__ = ["body_sha256", "body_label", "body_text", "other_body"]

#: the arrays that decide where a posed body's vertices and joints are (in this order)
_FIELDS = (
    "v_template",
    "faces",
    "shapedirs",
    "weights",
    "parents",
    "J_regressor",
    "joint_template",
    "joint_shapedirs",
    "posedirs",
)


def body_sha256(body) -> str:
    """SHA-256 of a :class:`~segadeform.body.BodyModel`'s arrays (float64 / int64, C-order, little-endian,
    each with its name and shape), so the same body read from ``.npz`` or SMPL ``.pkl`` hashes alike and a
    change to any vertex, weight or joint changes it."""
    h = hashlib.sha256(b"segadeform-body-1")
    for name in _FIELDS:
        a = getattr(body, name)
        if a is None:
            h.update(f"{name}:none;".encode())
            continue
        a = np.asarray(a)
        a = np.ascontiguousarray(a, dtype="<i8" if np.issubdtype(a.dtype, np.integer) else "<f8")
        h.update(f"{name}:{a.shape};".encode())
        h.update(a.tobytes())
    return h.hexdigest()


def body_label(body) -> dict:
    """``{"name", "sha256"}`` of a body: its file's name (``"default_body.npz"``) and :func:`body_sha256`."""
    from pathlib import Path

    return {"name": Path(body.path).name if body.path else "", "sha256": body_sha256(body)}


def body_text(label: dict) -> str:
    """A :func:`body_label` in words, for an error that names two bodies: ``"body2.npz (sha256 0123456789ab)"``."""
    return f"{label.get('name') or 'an unnamed body'} (sha256 {str(label.get('sha256') or '?')[:12]})"


def other_body(recorded, body) -> dict | None:
    """``body``'s :func:`body_label` when ``recorded`` (a label a checkpoint, a run or a package records) names
    another body; None when it names ``body`` or records none (files written before bodies were recorded)."""
    if not isinstance(recorded, dict) or not recorded.get("sha256"):
        return None
    mine = body_label(body)
    return None if mine["sha256"] == str(recorded["sha256"]) else mine
