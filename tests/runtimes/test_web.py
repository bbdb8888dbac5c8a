"""The browser runtime (runtimes/web): the viewer page runs the shared test vector in headless Chromium on
onnxruntime-web's wasm and WebGPU backends (WebGPU on SwiftShader, a software GPU) and matches Python."""

from __future__ import annotations

import json
import os
import shutil
import subprocess

import pytest

from tests.conftest import REPO

WEB = REPO / "runtimes" / "web"
CHROMIUM = os.environ.get("SEGADEFORM_CHROMIUM", "/usr/bin/chromium")
#: WebGPU's float32 arithmetic (fused multiply-adds, its own exp/tanh) is not bit-for-bit the CPU's:
#: measured 4.7e-5 relative on SwiftShader for the shipped model (docs/runtimes.md)
WEBGPU_RTOL = 2e-4


def _page(site, ep, tmp_path, shot=True):
    if shutil.which("node") is None:
        pytest.fail("node is not on PATH (the project's runtimes need Node.js >= 18)")
    if not (WEB / "node_modules" / "onnxruntime-web").is_dir() or not (WEB / "node_modules" / "three").is_dir():
        pytest.fail("runtimes/web has no node_modules: run `npm ci` there (.ci/run does)")
    if not os.path.exists(CHROMIUM):
        pytest.fail(f"no Chromium at {CHROMIUM}: run runtimes/web/install-browser.sh (.ci/run does)")
    cmd = ["node", str(WEB / "test" / "page.mjs"), "--root", str(site), "--package", "pkg", "--bundle", "s.sgdb",
           "--ep", ep, "--chromium", CHROMIUM, "--batch", "5"]
    if shot:
        cmd += ["--screenshot", str(tmp_path / f"{ep}.png")]
    p = subprocess.run(cmd, capture_output=True, text=True, timeout=900)
    assert p.returncode == 0, (p.stdout + p.stderr)[-3000:]
    line = next(ln for ln in p.stdout.splitlines() if ln.startswith("PAGE "))
    return json.loads(line[5:])


@pytest.fixture(scope="module")
def site(tmp_path_factory, shared_bundle, random_package):
    """A folder the page's server roots at: the runtimes, the package and the bundle side by side."""
    d = tmp_path_factory.mktemp("site")
    (d / "runtimes").symlink_to(REPO / "runtimes")
    (d / "pkg").symlink_to(random_package)
    (d / "s.sgdb").symlink_to(shared_bundle)
    return d


def test_page_on_wasm_matches_python(site, tmp_path):
    r = _page(site, "wasm", tmp_path)
    assert r["finite"] and r["sameLength"] and r["T"] >= 10
    assert r["rel"] <= 1e-5, r
    assert (tmp_path / "wasm.png").stat().st_size > 10_000  # the viewer drew the garment


def test_page_on_webgpu_matches_python(site, tmp_path):
    r = _page(site, "webgpu", tmp_path, shot=False)
    assert r["webgpu"], "Chromium offered no WebGPU adapter (flags in runtimes/web/test/page.mjs)"
    assert r["ep"] == "webgpu" and r["finite"] and r["sameLength"]
    assert r["rel"] <= WEBGPU_RTOL, r
