from __future__ import annotations

import pytest


@pytest.fixture(scope="session")
def body():
    from segadeform.body import load_body

    from ..conftest import SAMPLES

    return load_body(SAMPLES / "bodies" / "default_body.npz")


@pytest.fixture(scope="session")
def coarse_skirt(body):
    """A coarse skirt made for the default body (about 660 vertices)."""
    from segadeform.garments import make_garment

    return make_garment("skirt", body)
