import os
import pickle
import sys
import types

import numpy as np
import pytest
import scipy.sparse as sp

from segadeform.body import load_body
from segadeform.errors import FileFormatError
from tests.body.conftest import toy_body
from tests.conftest import leftovers


def test_save_load_round_trip(tmp_path, body):
    body.save(tmp_path / "b.npz")
    b = load_body(tmp_path / "b.npz")
    np.testing.assert_allclose(b.v_template, body.v_template, atol=1e-6)
    np.testing.assert_array_equal(b.faces, body.faces)
    assert b.joint_names == body.joint_names and b.n_betas == 4
    out1 = body.forward(np.zeros((1, 72)))
    np.testing.assert_allclose(out1.vertices[0], body.v_template, atol=1e-12)
    assert leftovers(tmp_path) == []


def test_forward_shapes_betas_and_posedirs():
    b = toy_body(posedirs=True)
    poses = np.random.default_rng(0).normal(scale=0.3, size=(3, 72))
    out = b.forward(poses, betas=[1.0, -2.0], trans=np.ones((3, 3)))
    assert out.vertices.shape == (3, b.n_vertices, 3) and out.joints.shape == (3, 24, 3)
    assert np.isfinite(out.vertices).all()
    dqs = b.forward(poses, betas=[1.0, -2.0], skinning="dqs")
    assert dqs.vertices.shape == out.vertices.shape
    with pytest.raises(Exception, match="too many shape"):
        b.forward(poses, betas=np.zeros(9))


def smpl_style_arrays(body):
    kt = np.stack([np.r_[4294967295, body.parents[1:]], np.arange(24)]).astype(np.int64)
    return dict(
        v_template=body.v_template,
        f=body.faces.astype(np.uint32),
        shapedirs=body.shapedirs,
        J_regressor=body.J_regressor,
        weights=body.weights,
        kintree_table=kt,
    )


def test_official_smpl_npz_layout(tmp_path, body):
    np.savez(tmp_path / "SMPL_NEUTRAL.npz", **smpl_style_arrays(body))
    b = load_body(tmp_path / "SMPL_NEUTRAL.npz")
    np.testing.assert_array_equal(b.parents, body.parents)
    assert b.joint_names[0] == "pelvis"


def make_smpl_pickle(body) -> bytes:
    """A pickle laid out like SMPL's: chumpy Ch objects, a scipy CSC J_regressor, numpy arrays."""
    ch_mod = types.ModuleType("chumpy.ch")
    chumpy = types.ModuleType("chumpy")

    class Ch:  # stands in for chumpy.ch.Ch when writing the test file
        def __init__(self, x):
            self.x = x
            self.dterms = ("x",)

    Ch.__module__, Ch.__qualname__ = "chumpy.ch", "Ch"
    ch_mod.Ch = Ch
    sys.modules["chumpy"], sys.modules["chumpy.ch"] = chumpy, ch_mod
    try:
        a = smpl_style_arrays(body)
        d = dict(
            a,
            v_template=Ch(a["v_template"]),
            shapedirs=Ch(a["shapedirs"]),
            weights=Ch(a["weights"]),
            J_regressor=sp.csc_matrix(a["J_regressor"]),
            bs_type="lrotmin",
        )
        return pickle.dumps(d, protocol=2)
    finally:
        del sys.modules["chumpy"], sys.modules["chumpy.ch"]


def test_smpl_pickle_without_chumpy(tmp_path, body):
    data = make_smpl_pickle(body)
    assert b"chumpy" in data and b"scipy.sparse" in data
    (tmp_path / "basicModel.pkl").write_bytes(data)
    b = load_body(tmp_path / "basicModel.pkl")
    np.testing.assert_allclose(b.J_regressor, body.J_regressor)
    np.testing.assert_allclose(b.shapedirs, body.shapedirs)
    assert "chumpy" not in sys.modules


class _Evil:
    def __init__(self, cmd):
        self.cmd = cmd

    def __reduce__(self):
        return (os.system, (self.cmd,))


@pytest.mark.parametrize(
    "payload",
    [
        lambda marker: pickle.dumps({"v_template": _Evil(f"touch {marker}")}, protocol=2),
        lambda marker: pickle.dumps({"x": _Evil(f"touch {marker}")}, protocol=4),
        lambda marker: b"cbuiltins\neval\n(V__import__('os').system('touch " + str(marker).encode() + b"')\ntR.",
        lambda marker: b"ccopyreg\n_reconstructor\n(csubprocess\nPopen\nc__builtin__\nobject\nNtR.",
    ],
)
def test_crafted_pickles_are_refused_and_never_run(tmp_path, payload):
    marker = tmp_path / "pwned"
    p = tmp_path / "evil.pkl"
    p.write_bytes(payload(marker))
    with pytest.raises(FileFormatError, match="refused|malformed") as ei:
        load_body(p)
    assert str(p) in str(ei.value)
    assert not marker.exists()


@pytest.mark.parametrize(
    "change, words",
    [
        (dict(weights="scale"), "do not sum to 1"),
        (dict(parents=np.array([0] + list(range(23)))), "root"),
        (dict(parents=np.array([-1, 5] + list(range(1, 23)))), "invalid parent"),
        (dict(faces=np.array([[0, 1, 100000]])), "faces"),
        (dict(v_template="nan"), "NaN"),
        (dict(shapedirs=np.zeros((3, 3, 2))), "shapedirs"),
        (dict(weights=None), "missing"),
        (dict(J_regressor=None), "J_regressor"),
    ],
)
def test_malformed_body_files(tmp_path, body, change, words):
    body.save(tmp_path / "ok.npz")
    z = dict(np.load(tmp_path / "ok.npz", allow_pickle=False))
    for k, val in change.items():
        if val is None:
            z.pop(k)
        elif isinstance(val, str) and val == "scale":
            z[k] = z[k] * 1.5
        elif isinstance(val, str) and val == "nan":
            z[k] = z[k].copy()
            z[k][3, 1] = np.nan
        else:
            z[k] = val
    np.savez(tmp_path / "bad.npz", **z)
    with pytest.raises(FileFormatError, match=words) as ei:
        load_body(tmp_path / "bad.npz")
    assert "bad.npz" in str(ei.value)


def test_object_arrays_and_garbage(tmp_path):
    np.savez(tmp_path / "o.npz", v_template=np.array([object()], dtype=object))
    with pytest.raises(FileFormatError, match="pickled objects"):
        load_body(tmp_path / "o.npz")
    (tmp_path / "g.npz").write_bytes(b"PK\x03\x04 truncated")
    with pytest.raises(FileFormatError):
        load_body(tmp_path / "g.npz")
    (tmp_path / "t.pkl").write_bytes(pickle.dumps({"a": 1})[:-3])
    with pytest.raises(FileFormatError, match="malformed"):
        load_body(tmp_path / "t.pkl")
    with pytest.raises(FileFormatError, match="unknown body file type"):
        load_body(__file__)
