"""How `segadeform run` poses the body (segadeform.runtime.body): with the package's body graph (float32, as the
Node, browser and C++ runtimes) when the graph poses the run's body, else with numpy, saying why once; the body
output and the collisions use the same posed body."""

from __future__ import annotations

import dataclasses
import logging

import numpy as np
import pytest

from segadeform.body import default_body_path, load_body
from segadeform.errors import InputError
from segadeform.io import read_pc2
from segadeform.motion import make_motion
from segadeform.runtime import ModelPackage
from segadeform.runtime.body import BodyPoser, graph_body_status
from segadeform.runtime.pipeline import Run
from segadeform.runtime.translation import at_translation
from segadeform.settings import Effects
from tests.conftest import SAMPLES

SHIPPED = SAMPLES / "models" / "default"
SKIRT = SAMPLES / "garments" / "skirt.obj"


@pytest.fixture(scope="module")
def body():
    return load_body(default_body_path())


@pytest.fixture(scope="module")
def shipped():
    return ModelPackage(SHIPPED)


@pytest.fixture(scope="module")
def custom_body(tmp_path_factory, body):
    """Another body file: the default body 1 mm taller (not the one the package's body graphs pose)."""
    v = body.v_template.copy()
    v[:, 1] *= 1.001
    path = tmp_path_factory.mktemp("body") / "taller.npz"
    dataclasses.replace(body, v_template=v, path=None).save(path)
    return load_body(path)


def _run(tmp_path, package, body, effects, **kw):
    return Run(
        garment=SKIRT,
        motion=make_motion("dance", seconds=0.4, seed=2),
        package=package,
        body=body,
        effects=effects,
        output=tmp_path / "out.pc2",
        body_output=tmp_path / "body.pc2",
        batch=4,
        cache=False,
        **kw,
    )


@pytest.mark.parametrize("skinning", ["lbs", "dqs"])
def test_graph_body_is_the_numpy_body_within_a_micrometre(shipped, body, skinning):
    """The shipped package's body graphs pose the default body within 1e-6 m of BodyModel.forward, over a dance
    with a body shape; the graph's float32 numbers at the root, the translation added in float64, as the other
    runtimes add it (segadeform.runtime.translation)."""
    m = make_motion("dance", seconds=1.0, seed=4)
    betas = np.array([0.8, -0.5, 0.3])
    graph = BodyPoser(shipped, body, skinning=skinning, backend="graph")
    numpy = BodyPoser(shipped, body, skinning=skinning, backend="numpy")
    assert (graph.backend, graph.graph, graph.reason) == ("graph", f"body_{skinning}", None)
    assert numpy.backend == "numpy" and numpy.graph is None
    for lo in range(0, m.n_frames, 8):
        g = graph.pose(m.poses[lo : lo + 8], betas, m.trans[lo : lo + 8])
        n = numpy.pose(m.poses[lo : lo + 8], betas, m.trans[lo : lo + 8])
        assert g.dtype == n.dtype == np.float64 and g.shape == n.shape
        at_root = g - m.trans[lo : lo + 8, None].astype(np.float32)
        np.testing.assert_array_equal(at_root, at_root.astype(np.float32))
        np.testing.assert_allclose(g, n, rtol=0, atol=1e-6)


def test_run_poses_the_package_body_with_its_graph(tmp_path, shipped, body):
    """auto: the shipped package's body graph poses the default body; the body output is that graph's output, and the
    collisions push out of it (the same frames as body_backend='graph'); numpy still on request."""
    eff = Effects(skinning="lbs", dynamics=False, wrinkles=False, collisions=True)
    s = _run(tmp_path, ModelPackage(SHIPPED), body, eff).execute()
    assert s.body_backend == "graph" and "body_lbs" in s.sessions and s.pushed_vertices > 0
    frames, posed = read_pc2(tmp_path / "out.pc2").frames, read_pc2(tmp_path / "body.pc2").frames
    m = make_motion("dance", seconds=0.4, seed=2)
    want = shipped.run(
        "body_lbs",
        {
            "betas": np.zeros(body.n_betas, np.float32),
            "poses": m.poses.reshape(len(m.poses), -1, 3).astype(np.float32),
            "trans": np.zeros((len(m.poses), 3), np.float32),
        },
    )[0]
    np.testing.assert_array_equal(posed, at_translation(want, m.trans).astype(np.float32))
    g = _run(tmp_path / "g", shipped, body, eff, body_backend="graph").execute()
    assert g.body_backend == "graph" and g.pushed_vertices == s.pushed_vertices
    np.testing.assert_array_equal(read_pc2(tmp_path / "g" / "out.pc2").frames, frames)
    n = _run(tmp_path / "n", ModelPackage(SHIPPED), body, eff, body_backend="numpy").execute()  # its own sessions
    assert n.body_backend == "numpy" and "body_lbs" not in n.sessions
    np.testing.assert_array_equal(  # posed at the root, then moved (the collisions are resolved there)
        read_pc2(tmp_path / "n" / "body.pc2").frames,
        at_translation(body.forward(m.poses, None, 0 * m.trans).vertices, m.trans).astype(np.float32),
    )
    np.testing.assert_allclose(read_pc2(tmp_path / "n" / "body.pc2").frames, posed, rtol=0, atol=1e-6)


def test_collider_and_cloth_stage_are_built_from_the_shaped_body_at_rest(tmp_path, shipped, body, monkeypatch):
    """A run at betas far from 0 (2 m 36 tall) builds its collider and its cloth stage's body from the body at those
    betas as its frames are posed -- the package's body graph at the zero pose, float32, as Node and C++ build theirs
    -- not from the template (betas 0, up to 0.5 m away): the tree over the triangles decides between equally near
    ones, so another tree can give other frames than the other runtimes'."""
    import segadeform.body.cloth as cloth_mod
    from segadeform.body.collision import BodyCollider

    betas = (2.0,)
    built: dict = {}

    class Collider(BodyCollider):
        def __init__(self, vertices, faces, **kw):
            built["collider"] = np.array(vertices)
            super().__init__(vertices, faces, **kw)

    class Stage(cloth_mod.ClothStage):
        def __init__(self, setup, body_vertices, body_faces, *a, **kw):
            built["cloth"] = np.array(body_vertices)
            super().__init__(setup, body_vertices, body_faces, *a, **kw)

    monkeypatch.setattr(cloth_mod, "ClothStage", Stage)
    for eff in (Effects(skinning="lbs", collisions=True), Effects(skinning="lbs", cloth=True)):
        r = Run(
            garment=SKIRT,
            motion=make_motion("dance", seconds=0.2, seed=2),
            package=shipped,
            body=body,
            betas=betas,
            effects=eff,
            output=tmp_path / "out.pc2",
            batch=4,
            cache=False,
            force=True,  # the skirt was made for betas 0: played anyway
            collider=Collider,
        )
        assert r.execute().body_backend == "graph"
    rest = shipped.run(
        "body_lbs",
        {
            "betas": np.array([*betas, *[0.0] * (body.n_betas - 1)], np.float32),
            "poses": np.zeros((1, body.n_joints, 3), np.float32),
            "trans": np.zeros((1, 3), np.float32),
        },
    )[0][0]
    assert np.abs(rest - body.v_template).max() > 0.3  # the template is far from it
    for k in ("collider", "cloth"):
        np.testing.assert_array_equal(built[k], rest, err_msg=k)


def test_no_body_needed_no_body_posed(tmp_path, body):
    eff = Effects(skinning="lbs", dynamics=False, wrinkles=False, collisions=False)
    r = Run(
        garment=SKIRT,
        motion=make_motion("dance", seconds=0.2, seed=2),
        package=ModelPackage(SHIPPED),
        body=body,
        effects=eff,
        output=tmp_path / "out.pc2",
        cache=False,
        body_backend="graph",
    )
    assert r.body_poser is None
    s = r.execute()
    assert s.body_backend is None and not any(x.startswith("body_") for x in s.sessions)


def test_custom_body_falls_back_to_numpy(tmp_path, shipped, custom_body, caplog):
    """A body file that is not the package's: auto poses it with numpy (the reason logged once), graph refuses."""
    name, why = graph_body_status(shipped, custom_body, "lbs")
    assert name is None and "taller.npz" in why and "default_body.npz" in why
    eff = Effects(skinning="lbs", dynamics=False, wrinkles=False, collisions=True)
    with caplog.at_level(logging.INFO, logger="segadeform.runtime.body"):
        s = _run(tmp_path, ModelPackage(SHIPPED), custom_body, eff, force=True).execute()
    said = [r.getMessage() for r in caplog.records if r.name == "segadeform.runtime.body"]
    assert len(said) == 1 and "numpy" in said[0] and "taller.npz" in said[0], said
    assert s.body_backend == "numpy" and "body_lbs" not in s.sessions
    m = make_motion("dance", seconds=0.4, seed=2)
    np.testing.assert_array_equal(
        read_pc2(tmp_path / "body.pc2").frames,
        at_translation(custom_body.forward(m.poses, None, 0 * m.trans).vertices, m.trans).astype(np.float32),
    )
    with pytest.raises(InputError, match="cannot pose the body with the package's body graph.*taller.npz"):
        _run(tmp_path, shipped, custom_body, eff, body_backend="graph")


def test_package_without_body_graphs_falls_back_to_numpy(tmp_path, random_package, body):
    from tests.export.legacy import as_schema

    old = ModelPackage(as_schema(random_package, tmp_path / "v2", 2))  # schema 2: no body graphs
    name, why = graph_body_status(old, body, "lbs")
    assert name is None and "no body graph" in why
    assert BodyPoser(old, body, backend="auto").backend == "numpy"
    with pytest.raises(InputError, match="no body graph"):
        BodyPoser(old, body, backend="graph")


def test_bad_body_backend_and_inputs_are_refused(tmp_path, shipped, body):
    eff = Effects(collisions=True)
    with pytest.raises(InputError, match="unknown body backend"):
        _run(tmp_path, shipped, body, eff, body_backend="torch")
    p = BodyPoser(shipped, body, backend="graph")
    m = make_motion("dance", seconds=0.2, seed=2)
    with pytest.raises(InputError, match="too many shape coefficients"):
        p.pose(m.poses[:2], np.zeros(body.n_betas + 1) + 0.1, m.trans[:2])
    with pytest.raises(InputError, match="trans must be"):
        p.pose(m.poses[:2], None, m.trans[:3])
    with pytest.raises(InputError, match="poses must be"):
        p.pose(m.poses[:2, :-3], None, m.trans[:2])


def test_cli_body_backend(tmp_path):
    from segadeform.cli.main import main

    args = [
        "run",
        "--garment",
        str(SKIRT),
        "--motion",
        str(SAMPLES / "motions" / "dance.npz"),
        "--model",
        str(SHIPPED),
        "--frames",
        "0:4",
        "--no-cache",
        "--effects",
        "lbs,collisions",
    ]
    for backend in ("graph", "numpy"):
        assert (
            main(
                args
                + [
                    "-o",
                    str(tmp_path / f"{backend}.pc2"),
                    "--body-out",
                    str(tmp_path / f"{backend}_b.pc2"),
                    "--body-backend",
                    backend,
                ]
            )
            == 0
        )
    g, n = read_pc2(tmp_path / "graph_b.pc2").frames, read_pc2(tmp_path / "numpy_b.pc2").frames
    assert not np.array_equal(g, n)
    np.testing.assert_allclose(g, n, rtol=0, atol=1e-6)


def test_run_refuses_a_body_other_than_the_packages_unless_forced(tmp_path, custom_body, capsys):
    """`run --model PKG --body OTHER` ran a model trained on the package's body on another without a word (a user's
    trial): the package's body graphs record the body its model was trained on (export gives it the checkpoint's),
    so another is refused in one line naming both, writing nothing; --force runs it (posed with numpy)."""
    from segadeform.cli.main import main

    args = ["run", "--garment", str(SKIRT), "--motion", str(SAMPLES / "motions" / "dance.npz")]
    args += ["--model", str(SHIPPED), "--body", str(custom_body.path), "--frames", "0:3", "--no-cache"]
    assert main([*args, "-o", str(tmp_path / "out.pc2")]) == 1
    err = capsys.readouterr().err
    said = "the model package was made for another body than the run's (--body, or the scene's body)"
    assert err.startswith(f"Error: {SHIPPED}: {said}"), err
    assert err.count("\n") == 1 and "expected default_body.npz (sha256 " in err and "got taller.npz (sha256 " in err
    assert not (tmp_path / "out.pc2").exists() and not list(tmp_path.iterdir())
    assert main([*args, "-o", str(tmp_path / "forced.pc2"), "--force"]) == 0
    assert read_pc2(tmp_path / "forced.pc2").frames.shape[0] == 3
