"""The same package and scene through the Node and C++ runtimes: parity with Python on a shared bundle."""

from __future__ import annotations

import json
import os
import shutil
import subprocess

import numpy as np
import pytest

from segadeform.bundle import read_bundle, write_bundle
from segadeform.errors import FileFormatError
from tests.conftest import REPO

RTOL = 1e-5


def test_bundle_round_trip_and_errors(tmp_path):
    arrays = {"a": np.arange(12, dtype=np.float32).reshape(3, 4), "b": np.array([1, -2], np.int32),
              "m": np.array([[True, False]]), "s": np.float32(2.5)}
    write_bundle(tmp_path / "x.sgdb", arrays, {"k": [1, 2]})
    got, meta = read_bundle(tmp_path / "x.sgdb")
    assert meta == {"k": [1, 2]}
    np.testing.assert_array_equal(got["a"], arrays["a"])
    np.testing.assert_array_equal(got["b"], arrays["b"])
    assert got["m"].dtype == np.uint8 and got["m"].tolist() == [[1, 0]] and got["s"].shape == ()
    raw = (tmp_path / "x.sgdb").read_bytes()
    (tmp_path / "t.sgdb").write_bytes(raw[:200])
    with pytest.raises(FileFormatError, match="does not fit the file"):
        read_bundle(tmp_path / "t.sgdb")
    (tmp_path / "n.sgdb").write_bytes(b"hello")
    with pytest.raises(FileFormatError, match="not a segadeform bundle"):
        read_bundle(tmp_path / "n.sgdb")


def _parity(output: str) -> dict:
    line = next(ln for ln in output.splitlines() if "PARITY" in ln)
    return json.loads(line.split("PARITY", 1)[1].strip())


def test_node_runtime_matches_python(shared_bundle, random_package):
    if shutil.which("node") is None:
        pytest.fail("node is not on PATH (the project's runtimes need Node.js >= 18)")
    node_dir = REPO / "runtimes" / "node"
    if not (node_dir / "node_modules" / "onnxruntime-node").is_dir():
        pytest.fail("runtimes/node has no node_modules: run `ONNXRUNTIME_NODE_INSTALL=skip npm ci` there "
                    "(.ci/run does)")
    env = dict(os.environ, SEGADEFORM_PACKAGE=str(random_package), SEGADEFORM_BUNDLE=str(shared_bundle))
    p = subprocess.run(["npm", "test"], cwd=node_dir, env=env, capture_output=True, text=True, timeout=600)
    assert p.returncode == 0, (p.stdout + p.stderr)[-3000:]
    r = _parity(p.stdout)
    assert r["rel"] <= RTOL, r
    assert "# skipped 0" in p.stdout and "# fail 0" in p.stdout  # the parity test ran


def test_cpp_runtime_matches_python(shared_bundle, random_package, tmp_path):
    for tool in ("go", "cmake", "g++"):
        if shutil.which(tool) is None:
            pytest.fail(f"{tool} is not on PATH (building the C++ runtime needs go, cmake and g++)")
    b = subprocess.run([str(REPO / "tools" / "onnxruntime_cpp.sh"), str(tmp_path / "build")], capture_output=True,
                       text=True, timeout=900)
    assert b.returncode == 0, (b.stdout + b.stderr)[-3000:]
    exe = b.stdout.strip().splitlines()[-1]
    p = subprocess.run([exe, str(random_package), str(shared_bundle), "-o", str(tmp_path / "o.pc2"), "--check",
                        "--batch", "3"], capture_output=True, text=True, timeout=600)
    assert p.returncode == 0, p.stderr
    assert _parity(p.stdout)["rel"] <= RTOL
    from segadeform.io import read_pc2

    arrays, _ = read_bundle(shared_bundle)
    np.testing.assert_allclose(read_pc2(tmp_path / "o.pc2").frames, arrays["expected"], rtol=0, atol=1e-5)
    bad = subprocess.run([exe, str(random_package), str(tmp_path / "missing.sgdb"), "-o", str(tmp_path / "x.pc2")],
                         capture_output=True, text=True)
    assert bad.returncode == 1 and "missing.sgdb: no such file" in bad.stderr and not (tmp_path / "x.pc2").exists()
