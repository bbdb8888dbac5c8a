"""A package remembers the garments it was trained on, and a run warns about a garment far from all of them."""

from __future__ import annotations

import json
import logging

import numpy as np
import pytest

from segadeform.body import load_body
from segadeform.cli.main import main
from segadeform.contracts import model_package as contract
from segadeform.export.training_set import mesh_descriptors, training_garments_entry
from segadeform.garments import make_garment
from segadeform.garments.make import GarmentParams
from segadeform.geometry import precompute_garment
from segadeform.geometry.descriptor import dissimilarities, dissimilarity, novelty_threshold
from segadeform.io import Mesh, write_obj
from segadeform.runtime import Deformer, ModelPackage
from tests.conftest import SAMPLES

SHIPPED = SAMPLES / "models" / "default"


@pytest.fixture(scope="module")
def body():
    return load_body(SAMPLES / "bodies" / "default_body.npz")


def _asset(body, kind, name, **params):
    g = make_garment(kind, body, None, GarmentParams(**params))
    return precompute_garment(g.vertices, g.faces, body.rest_joints()[0], source_name=name)


def test_vectorised_distances_match_eq19():
    rng = np.random.default_rng(0)
    refs = rng.normal(size=(5, 8))
    refs[2, 3:] = 0.0  # 0/0 terms count 0
    lam = rng.normal(size=8)
    np.testing.assert_allclose(dissimilarities(lam, refs), [dissimilarity(lam, r) for r in refs], rtol=1e-12)


def test_threshold_is_the_largest_distance_to_another_garment():
    refs = np.array([[1.0, 0.0], [1.0, 0.01], [0.0, 1.0], [0.5, 0.5]])
    groups = ["a", "a", "b", "c"]  # two rows of "a": one garment on two bodies, never its own neighbour
    expect = max(min(dissimilarity(refs[i], refs[j]) for j in range(4) if groups[j] != groups[i]) for i in range(4))
    assert novelty_threshold(refs, groups) == pytest.approx(expect)
    assert novelty_threshold(refs[:2], ["a", "a"]) is None  # one garment: nothing to measure against


def test_entry_keeps_each_garment_once_and_is_valid():
    d = np.array([[3.0, 1.0], [3.0, 1.0], [2.0, 2.0]])
    e = training_garments_entry(["skirt", "skirt", "top"], d, openings=[2, 2, 4])
    assert [g["name"] for g in e["garments"]] == ["skirt", "top"] and e["garments"][1]["openings"] == 4
    assert e["threshold"] == pytest.approx(dissimilarity(d[0], d[2]))
    contract._check_training_garments(e, 2, None)
    with pytest.raises(contract.PackageError, match="training_garments is malformed"):
        contract._check_training_garments(e, 3, None)  # descriptors of another N*


def test_shipped_package_knows_its_training_garments(body):
    pkg = ModelPackage(SHIPPED)
    t = pkg.manifest[contract.TRAINING_GARMENTS]
    names = {g["name"] for g in t["garments"]}
    # exactly the garments of the samples it was trained on (default.train/train.json, the trainer's record), which
    # samples/datasets/continuum.toml keeps apart from every held-out garment
    record = json.loads((SAMPLES / "models" / "default.train" / "train.json").read_text())
    assert names == {sid.split("__")[0] for sid in record["samples"]}
    kinds = {n.rsplit("-", 1)[0].removesuffix("-fit") for n in names if not n.startswith("mh-")}
    assert kinds <= {"tshirt", "jacket", "dress", "skirt", "trousers", "shorts"} and len(kinds) >= 5
    assert not {n for n in names if n.endswith(("-test", "-val")) or n in ("tank", "sleeved-dress")}
    # a garment of a trained kind, made again from the ranges, lies inside, nearest to one of its kind
    a = _asset(body, "skirt", "skirt-short", length=0.3, resolution=2500)
    fam = pkg.familiarity(a.descriptor, 2)
    assert fam.nearest.startswith("skirt-") and fam.distance < t["threshold"] and not fam.outside
    # a jumpsuit has 5 openings, which no training garment has
    j = _asset(body, "jumpsuit", "jumpsuit", resolution=1200)
    fam = pkg.familiarity(j.descriptor, 5)
    assert fam.new_openings and fam.outside and "5 openings" in str(fam)
    # far in descriptor space: a flat square sheet
    far = np.zeros(pkg.config["n_star"])
    far[0] = 1e3
    assert pkg.familiarity(far, 2).outside


def test_the_readme_dress_is_what_its_command_makes_and_familiar_to_the_shipped_model(body, tmp_path):
    """The README's first command animates samples/garments/dress.obj; a copy made by an older generator lay
    outside the shipped model's training garments (nearest: shorts) and the first thing a user saw was that
    warning.  The file must be what its header's command makes today, and familiar to the shipped model."""
    from segadeform.geometry.mesh_ops import boundary_loops
    from segadeform.io import read_mesh

    sample = SAMPLES / "garments" / "dress.obj"
    assert "resolution=2500" in sample.read_text().splitlines()[2]
    assert main(["garment", "make", "dress", "--resolution", "2500", "-o", str(tmp_path / "dress.obj")]) == 0
    made, shipped = read_mesh(tmp_path / "dress.obj"), read_mesh(sample)
    assert np.array_equal(made.faces, shipped.faces)
    np.testing.assert_allclose(made.vertices, shipped.vertices, atol=1e-6)
    a = precompute_garment(shipped.vertices, shipped.faces, body.rest_joints()[0], source_name="dress")
    fam = ModelPackage(SHIPPED).familiarity(a.descriptor, len(boundary_loops(shipped.faces, len(shipped.vertices))))
    assert not fam.outside and fam.nearest.startswith("dress-"), str(fam)


def test_run_warns_once_about_an_unfamiliar_garment(body, caplog):
    pkg = ModelPackage(SHIPPED)
    dec = Deformer(pkg)
    joints = body.rest_joints()[0]
    with caplog.at_level(logging.WARNING, logger="segadeform.runtime.deformer"):
        dec.encode(_asset(body, "skirt", "short", length=0.3, resolution=2500), joints)
        assert not caplog.records
        jump = _asset(body, "jumpsuit", "my-jumpsuit", resolution=1200)
        dec.encode(jump, joints)
        dec.encode(jump, joints)  # the cached code: no second warning
    assert len(caplog.records) == 1 and "my-jumpsuit lies outside the garments" in caplog.text


def test_packages_without_a_list_stay_silent(random_package):
    assert ModelPackage(random_package).familiarity(np.ones(32), 2) is None


def test_repack_records_training_garments(tmp_path, random_package, body):
    files = []
    for kind in ("skirt", "tank"):
        g = make_garment(kind, body, None, GarmentParams(resolution=800))
        files.append(tmp_path / f"{kind}.obj")
        write_obj(files[-1], Mesh(vertices=g.vertices, faces=g.faces))
    args = [a for f in files for a in ("--training-garments", str(f))]
    assert main(["repack", str(random_package), "-o", str(tmp_path / "pkg"), *args]) == 0
    m = json.loads((tmp_path / "pkg" / "manifest.json").read_text())
    names, d, openings = mesh_descriptors(files, 32)
    assert m[contract.TRAINING_GARMENTS] == training_garments_entry(names, d, openings)
    assert openings == [2, 4] and m[contract.TRAINING_GARMENTS]["threshold"] > 0
