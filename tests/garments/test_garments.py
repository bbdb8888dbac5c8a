"""Procedural garments: every kind is a clean, open, one-piece manifold outside the body."""

from __future__ import annotations

import numpy as np
import pytest

from segadeform.body import BodyProxy, load_body
from segadeform.cli.main import main
from segadeform.errors import InputError
from segadeform.garments import GARMENT_KINDS, GARMENT_TYPES, GarmentParams, check_garment, make_garment
from segadeform.io import read_obj

from ..conftest import SAMPLES


@pytest.fixture(scope="module")
def body():
    return load_body(SAMPLES / "bodies" / "default_body.npz")


@pytest.mark.parametrize("kind", GARMENT_KINDS)
def test_every_kind_is_clean_and_outside_the_body(body, kind):
    g = make_garment(kind, body)
    info = check_garment(g.vertices, g.faces, body)
    assert 500 <= info["vertices"] <= 5000 and info["boundary_loops"] >= 1
    assert g.type == GARMENT_TYPES[kind]
    assert info["min_clearance"] > 0.001
    sd = BodyProxy(body.shaped_vertices()[0], body.faces).query(g.vertices).signed_distance
    assert (sd > 0).all()


def test_types_cover_the_issue_list():
    assert {"skirt", "dress", "top", "trousers", "jumpsuit", "open-front"} <= set(GARMENT_TYPES.values())


def test_open_front_is_open_and_long_skirt_is_longer(body):
    j = make_garment("jacket", body)
    t = make_garment("tshirt", body)
    # the jacket's front opening joins neck and hem into one boundary loop: fewer loops than the T-shirt
    assert check_garment(j.vertices, j.faces)["boundary_loops"] < check_garment(t.vertices, t.faces)["boundary_loops"]
    short = make_garment("skirt", body, params=GarmentParams(length=0.3))
    long_ = make_garment("skirt", body, params=GarmentParams(length=0.8, flare=0.5))
    assert long_.vertices[:, 1].min() < short.vertices[:, 1].min() - 0.3
    hem = lambda g: np.ptp(g.vertices[g.vertices[:, 1] < g.vertices[:, 1].min() + 0.01][:, 0])  # noqa: E731
    assert hem(long_) > hem(short)


def test_resolution_picks_the_refinement(body):
    n0 = len(make_garment("skirt", body).vertices)
    n1 = len(make_garment("skirt", body, params=GarmentParams(resolution=4 * n0)).vertices)
    assert 3.5 * n0 < n1 < 4.5 * n0
    check_garment(*(lambda g: (g.vertices, g.faces))(make_garment("skirt", body, params=GarmentParams(subdivisions=1))),
                  body)


def test_garments_follow_the_body_shape(body):
    a = make_garment("trousers", body)
    b = make_garment("trousers", body, betas=[1.0, 0.5])
    assert b.vertices[:, 1].max() > a.vertices[:, 1].max() + 0.05  # a taller body, a higher waist
    check_garment(b.vertices, b.faces, body, [1.0, 0.5])


def test_check_garment_catches_problems(body):
    g = make_garment("skirt", body)
    with pytest.raises(InputError, match="inside the body"):
        check_garment(g.vertices * 0.5 + [0, 0.5, 0], g.faces, body)
    with pytest.raises(InputError, match="consistently oriented"):
        f = g.faces.copy()
        f[0] = f[0, ::-1]
        check_garment(g.vertices, f)
    with pytest.raises(InputError, match="one piece"):
        check_garment(np.concatenate([g.vertices, g.vertices + 3]), np.concatenate([g.faces, g.faces + len(g.vertices)]))
    with pytest.raises(InputError, match="unknown garment kind"):
        make_garment("cape", body)
    with pytest.raises(InputError, match="out of range"):
        GarmentParams(flare=-1)


def test_cli_garment_make(tmp_path, capsys):
    out = tmp_path / "d.obj"
    assert main(["garment", "make", "dress", "--length", "0.6", "-o", str(out)]) == 0
    m = read_obj(out)
    assert len(m.vertices) > 1000
    assert "kind=dress type=dress" in out.read_text()[:300]
    assert main(["garment", "make", "cape", "-o", str(tmp_path / "x.obj")]) == 1
    assert not (tmp_path / "x.obj").exists()
    assert "unknown garment kind" in capsys.readouterr().err
