"""Previews: a small software renderer of meshes (:mod:`.render`; the ``plot`` extra)."""
