"""The browser runtime (runtimes/web): the viewer page runs a garment asset and a motion file (named in its query,
or dropped on it with the package's files) through the package in headless Chromium, on onnxruntime-web's wasm and
WebGPU backends (WebGPU on SwiftShader, a software GPU), poses the body with the package's body graph, and matches
`segadeform run`; it still runs scene bundles."""

from __future__ import annotations

import json
import os
import shutil
import subprocess

import pytest

from tests.conftest import REPO

WEB = REPO / "runtimes" / "web"
CHROMIUM = os.environ.get("SEGADEFORM_CHROMIUM", "/usr/bin/chromium")
#: the same target as every runtime.  WebGPU's sin and cos (WGSL builtins) are only accurate to 2^-11 absolute;
#: the graphs compute them as polynomials (export.portability.replace_trig), which took WebGPU on SwiftShader from
#: 1.0e-4 to 1.5e-7 relative (docs/runtimes.md)
RTOL = 1e-5
#: frames the WebGPU runs take: a software GPU needs seconds per deformer call
WEBGPU_FRAMES = 4


def _page(site, ep, tmp_path, *extra, shot=True):
    if shutil.which("node") is None:
        pytest.fail("node is not on PATH (the project's runtimes need Node.js >= 18)")
    if not (WEB / "node_modules" / "onnxruntime-web").is_dir() or not (WEB / "node_modules" / "three").is_dir():
        pytest.fail("runtimes/web has no node_modules: run `npm ci` there (.ci/run does)")
    if not os.path.exists(CHROMIUM):
        pytest.fail(f"no Chromium at {CHROMIUM}: run runtimes/web/install-browser.sh (.ci/run does)")
    cmd = [
        "node",
        str(WEB / "test" / "page.mjs"),
        "--root",
        str(site),
        "--package",
        "pkg",
        "--ep",
        ep,
        "--chromium",
        CHROMIUM,
        "--batch",
        "5",
        *extra,
    ]
    if shot:
        cmd += ["--screenshot", str(tmp_path / f"{ep}.png")]
    p = subprocess.run(cmd, capture_output=True, text=True, timeout=900)
    assert p.returncode == 0, (p.stdout + p.stderr)[-3000:]
    line = next(ln for ln in p.stdout.splitlines() if ln.startswith("PAGE "))
    return json.loads(line[5:])


def _asset_args(
    check: str, effects: str | None = None, motion: str = "motion.sgdm", garment: str = "garment.sgda"
) -> list[str]:
    """The page's arguments for the garment asset and a motion in its site, the check vector and the effects."""
    return ["--garment", garment, "--motion", motion, "--check", check] + (["--effects", effects] if effects else [])


@pytest.fixture(scope="module")
def site(tmp_path_factory, shared_bundle, portable_scene, random_package):
    """A folder the page's server roots at: the runtimes, the package, the bundle, the asset, the motion and the
    check vector side by side; and the first WEBGPU_FRAMES frames as a motion of their own (their frames do not
    depend on later ones)."""
    from segadeform.io.sgdb import read_bundle, write_bundle
    from segadeform.motion import read_motion_file, write_motion_file

    d = tmp_path_factory.mktemp("site")
    (d / "runtimes").symlink_to(REPO / "runtimes")
    (d / "pkg").symlink_to(random_package)
    (d / "s.sgdb").symlink_to(shared_bundle)
    for k in ("garment", "motion", "check"):
        (d / portable_scene[k].name).symlink_to(portable_scene[k])
    m, meta = read_motion_file(portable_scene["motion"])
    import dataclasses

    n = WEBGPU_FRAMES
    write_motion_file(
        d / "short.sgdm",
        dataclasses.replace(m, poses=m.poses[:n], trans=m.trans[:n]),
        body=meta["body"],
        betas=meta["betas"],
    )
    c, _ = read_bundle(portable_scene["check"])
    write_bundle(d / "short.sgdb", {"expected": c["expected"][:n], "body": c["body"][:n]})
    return d


def _assert_matches(r, frames, ep):
    assert r["ep"] == ep and r["finite"] and r["sameLength"] and r["T"] == frames, r
    assert r["rel"] <= RTOL, r
    b = r["body"]
    assert b["graph"] == "body_dqs" and b["finite"] and b["sameLength"] and b["rel"] <= RTOL, b


def test_page_runs_asset_and_motion_on_wasm_like_segadeform_run(site, portable_scene, tmp_path):
    r = _page(site, "wasm", tmp_path, *_asset_args("check.sgdb", portable_scene["effects"]))
    _assert_matches(r, len(portable_scene["frames"]), "wasm")
    assert (tmp_path / "wasm.png").stat().st_size > 10_000  # the viewer drew the garment and the body


def test_page_runs_dropped_package_asset_and_motion(site, portable_scene, tmp_path):
    """Drag and drop: the package's files dropped first, then the asset and the motion together."""
    r = _page(site, "wasm", tmp_path, "--drop", *_asset_args("check.sgdb", portable_scene["effects"]), shot=False)
    _assert_matches(r, len(portable_scene["frames"]), "wasm")


def test_page_runs_a_bundle_on_wasm(site, tmp_path):
    r = _page(site, "wasm", tmp_path, "--bundle", "s.sgdb", shot=False)
    assert r["finite"] and r["sameLength"] and r["T"] >= 10
    assert r["rel"] <= RTOL, r


def test_page_on_webgpu_matches_segadeform_run(site, portable_scene, tmp_path):
    r = _page(site, "webgpu", tmp_path, *_asset_args("short.sgdb", portable_scene["effects"], "short.sgdm"), shot=False)
    assert r["webgpu"], "Chromium offered no WebGPU adapter (flags in runtimes/web/test/page.mjs)"
    _assert_matches(r, WEBGPU_FRAMES, "webgpu")


def test_a_page_of_ones_own_runs_the_vendored_runtime_a_chunk_at_a_time(portable_scene, random_package, tmp_path):
    """An integrator's trial: the viewer was the only page that ran (runtime.js imports the core by a path into the
    repository; which onnxruntime-web files to serve was not said).  `npm run vendor -- SITE` makes one folder to
    serve; runtimes/web/examples/embed.html on it plays the motion through a Player in chunks of 3 frames (not a
    multiple of its batch) and matches `segadeform run`.  vendor never writes over a folder it did not write."""
    if not os.path.exists(CHROMIUM):
        pytest.fail(f"no Chromium at {CHROMIUM}: run runtimes/web/install-browser.sh (.ci/run does)")
    site = tmp_path / "site"
    (site / "segadeform").mkdir(parents=True)
    (site / "segadeform" / "mine.js").write_text("// the user's")
    v = subprocess.run(["node", str(WEB / "vendor.mjs"), str(site)], capture_output=True, text=True, timeout=120)
    assert v.returncode == 1 and "was not written by vendor.mjs" in v.stderr, v.stderr
    assert sorted(p.name for p in (site / "segadeform").iterdir()) == ["mine.js"]
    shutil.rmtree(site / "segadeform")
    for _ in range(2):  # a second vendor replaces its own files
        v = subprocess.run(
            ["npm", "run", "vendor", "--", str(site)], cwd=WEB, capture_output=True, text=True, timeout=120
        )
        assert v.returncode == 0, v.stdout + v.stderr
    got = sorted(str(p.relative_to(site / "segadeform")) for p in (site / "segadeform").rglob("*") if p.is_file())
    assert got == sorted(
        ["VENDORED.json", "cloth.js", "collide.js", "core.js", "runtime.js", "ort/ort.wasm.min.mjs"]
        + ["ort/ort-wasm-simd-threaded.mjs", "ort/ort-wasm-simd-threaded.wasm"]
    )
    shutil.copy(WEB / "examples" / "embed.html", site / "embed.html")
    (site / "pkg").symlink_to(random_package)
    for k in ("garment", "motion", "check"):
        (site / portable_scene[k].name).symlink_to(portable_scene[k])
    query = "package=pkg/&garment=garment.sgda&motion=motion.sgdm&check=check.sgdb&chunk=3"
    query += f"&effects={portable_scene['effects']}"
    p = subprocess.run(
        [
            "node",
            str(WEB / "test" / "embed.mjs"),
            "--root",
            str(site),
            "--page",
            f"embed.html?{query}",
            "--chromium",
            CHROMIUM,
        ],
        capture_output=True,
        text=True,
        timeout=600,
    )
    assert p.returncode == 0, (p.stdout + p.stderr)[-3000:]
    r = json.loads(next(ln for ln in p.stdout.splitlines() if ln.startswith("PAGE "))[5:])
    assert "error" not in r, r
    assert r["T"] == len(portable_scene["frames"]) and r["chunk"] == 3 and r["variant"] == "deformer_dqs", r
    assert r["finite"] and r["sameLength"] and r["rel"] <= RTOL, r
    # the package's files fetched when a run first needs them: the encoder, the one deformer and the shared weights
    # (every graph was fetched before)
    assert sorted(r["fetched"]) == ["deformer_dqs.onnx", "garment_encoder.onnx", "weights.bin"], r["fetched"]
    # the same work in a module Web Worker (a web developer's trial: the docs said to use one, with no example; the
    # page's thread then only receives frames): the same frames
    for name in ("embed-worker.html", "embed-worker.js"):
        shutil.copy(WEB / "examples" / name, site / name)
    p = subprocess.run(
        ["node", str(WEB / "test" / "embed.mjs"), "--root", str(site), "--page", f"embed-worker.html?{query}"]
        + ["--chromium", CHROMIUM],
        capture_output=True,
        text=True,
        timeout=600,
    )
    assert p.returncode == 0, (p.stdout + p.stderr)[-3000:]
    w = json.loads(next(ln for ln in p.stdout.splitlines() if ln.startswith("PAGE "))[5:])
    assert "error" not in w and w["inWorker"], w
    assert w["T"] == r["T"] and w["chunk"] == 3 and w["variant"] == r["variant"], w
    assert w["finite"] and w["sameLength"] and w["rel"] <= RTOL, w


def test_page_plays_a_decimated_model_garment_like_segadeform_run(site, portable_scene, random_package, tmp_path):
    """`garment export --resolution 0.5`: the page runs the model on the decimated copy and shows every vertex of
    the garment as given, as `segadeform run` writes it (tests/runtimes/test_resolution_assets.py for Node, C++)."""
    from segadeform.cli.main import main
    from segadeform.io import read_pc2
    from segadeform.io.sgdb import write_bundle

    d = tmp_path / "half"
    d.mkdir()
    export = ["garment", "export", str(portable_scene["dir"] / "dress_b.obj"), "--betas", "0.5,-0.3"]
    assert main([*export, "--model", str(random_package), "--resolution", "0.5", "-o", str(d / "half.sgda")]) == 0
    effects = portable_scene["effects"]
    run = ["run", "--model", str(random_package), "--garment", str(d / "half.sgda"), "--motion"]
    run += [str(portable_scene["motion"]), "--effects", effects, "--no-cache", "--force"]
    assert main([*run, "-o", str(d / "p.pc2"), "--body-out", str(d / "b.pc2")]) == 0
    frames, body = read_pc2(d / "p.pc2").frames, read_pc2(d / "b.pc2").frames
    write_bundle(d / "check_half.sgdb", {"expected": frames, "body": body}, {"effects": effects})
    for name in ("half.sgda", "check_half.sgdb"):
        link = site / name
        if not link.exists():
            link.symlink_to(d / name)
    r = _page(site, "wasm", tmp_path, *_asset_args("check_half.sgdb", effects, garment="half.sgda"), shot=False)
    _assert_matches(r, len(frames), "wasm")
