"""Issue 29's reproductions, each run as the issue wrote it: a correct result, or one line naming the file and
exit 1 (never a traceback, never a silent wrong result).  The output-safety reproductions are in
tests/cli/test_output_safety.py, the OBJ ones in tests/io/test_obj_round_trip.py, the full disk in
tests/io/test_tiny_disk.py."""

from __future__ import annotations

import json
import shutil

import numpy as np
import pytest
from click.testing import CliRunner

from segadeform.cli.main import cli

from .conftest import SAMPLES

SKIRT = SAMPLES / "garments" / "skirt.obj"
WALK = SAMPLES / "motions" / "walk.npz"
MODEL = SAMPLES / "models" / "default"
MH = SAMPLES / "garments" / "makehuman"


def invoke(*args):
    r = CliRunner().invoke(cli, [str(a) for a in args])
    assert r.exception is None or isinstance(r.exception, SystemExit), (args, r.output, repr(r.exception))
    assert "Traceback" not in r.output
    return r


def refused(words, *args, name=None):
    """Run the CLI; exit 1, one line, naming ``name`` (a file) and containing ``words``."""
    r = invoke(*args)
    assert r.exit_code == 1, (args, r.output)
    lines = r.output.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("Error: "), r.output
    assert words in r.output, r.output
    if name is not None:
        assert str(name) in r.output, r.output
    return r.output


@pytest.fixture(scope="module")
def walk_sgdm(tmp_path_factory):
    d = tmp_path_factory.mktemp("m")
    assert invoke("motion", "export", WALK, "--frames", "0:6", "-o", d / "walk.sgdm").exit_code == 0
    return d / "walk.sgdm"


def _edit_bundle(src, dst, old: bytes, new: bytes):
    data = src.read_bytes()
    assert old in data
    dst.write_bytes(data.replace(old, new, 1))
    return dst


def test_bundle_meta_that_is_not_an_object_is_refused(walk_sgdm, tmp_path):
    data = walk_sgdm.read_bytes()
    i, j = data.index(b"\nmeta ") + 1, data.index(b"\nEND\n")
    bad = tmp_path / "list.sgdm"
    bad.write_bytes(data[:i] + b"meta [1]" + data[j:])
    refused("bundle meta must be a JSON object", "inspect", bad, name=bad)
    refused(
        "bundle meta must be a JSON object",
        "run",
        "--garment",
        SKIRT,
        "--motion",
        bad,
        "-o",
        tmp_path / "o.pc2",
        name=bad,
    )
    asset = tmp_path / "g.sgda"
    assert invoke("garment", "export", SKIRT, "-o", asset).exit_code == 0
    data = asset.read_bytes()
    i, j = data.index(b"\nmeta ") + 1, data.index(b"\nEND\n")
    bad = tmp_path / "list.sgda"
    bad.write_bytes(data[:i] + b"meta [1]" + data[j:])
    refused("bundle meta must be a JSON object", "inspect", bad, name=bad)
    refused(
        "bundle meta must be a JSON object",
        "run",
        "--garment",
        bad,
        "--motion",
        walk_sgdm,
        "-o",
        tmp_path / "o.pc2",
        name=bad,
    )
    assert not (tmp_path / "o.pc2").exists()


def test_a_bundle_shape_that_overflows_is_refused(walk_sgdm, tmp_path):
    line = next(ln for ln in walk_sgdm.read_bytes().split(b"\n") if ln.startswith(b"trans "))
    t = line.split()
    huge = b" ".join([t[0], t[1], t[2], b"4611686018427387904", b"4", *t[5:]])
    bad = _edit_bundle(walk_sgdm, tmp_path / "huge.sgdm", line, huge)
    out = refused("declares a size its shape does not have", "inspect", bad, name=bad)
    assert "73786976294838206464 bytes" in out  # the true size, not a wrapped-around one


def test_a_truncated_bundle_says_how_short_it_is(walk_sgdm, tmp_path):
    """It said "expected 2592 bytes, got 2592"."""
    bad = tmp_path / "cut.sgdm"
    data = walk_sgdm.read_bytes()
    bad.write_bytes(data[:-100])
    out = refused("runs past the end of the file", "inspect", bad, name=bad)
    assert f"got {len(data) - 100} bytes" in out


def test_a_negative_seed_is_refused_everywhere(tmp_path):
    refused("seed out of range", "motion", "export", "walk", "--seed", "-5", "-o", tmp_path / "s.sgdm")
    scene = tmp_path / "s.toml"
    scene.write_text(f'[garment]\nmesh = "{SKIRT}"\n[motion]\nkind = "walk"\nseed = -5\n[output]\npath = "o.pc2"\n')
    refused("motion.seed out of range", "run", scene, name=scene)
    jobs = tmp_path / "jobs.toml"
    jobs.write_text(f'[[garments]]\nmesh = "{SKIRT}"\n[[motions]]\nkind = "walk"\nseed = -5\n')
    refused("motions[0].seed out of range", "batch", jobs, "-o", tmp_path / "b", name=jobs)
    assert not (tmp_path / "b").exists() and not (tmp_path / "s.sgdm").exists()


def _mhclo(tmp_path, edit):
    shutil.copy(MH / "skirt_short_f.obj", tmp_path / "skirt_short_f.obj")
    lines = (MH / "skirt_short_f.mhclo").read_text().split("\n")
    p = tmp_path / "b.mhclo"
    p.write_text("\n".join(edit(lines)))
    return p


def _first_binding(lines):
    return next(i for i, ln in enumerate(lines) if ln.startswith("verts")) + 1


def test_mhclo_weights_must_sum_to_one(tmp_path):
    """Weights `0 0 0` crashed the fit (LinAlgError)."""

    def zero(lines):
        k = _first_binding(lines)
        t = lines[k].split()
        lines[k] = " ".join(t[:3] + ["0", "0", "0"] + t[6:])
        return lines

    p = _mhclo(tmp_path, zero)
    k = _first_binding(p.read_text().split("\n")) + 1
    refused("binding weights must sum to 1", "garment", "fit", p, "-o", tmp_path / "f.obj", name=f"{p}:{k}")


@pytest.mark.parametrize("where", ["binding", "x_scale", "delete_verts"])
def test_mhclo_negative_indices_are_refused(tmp_path, where):
    """A negative base-mesh index counted from the end of the base mesh."""

    def neg(lines):
        if where == "binding":
            k = _first_binding(lines)
            lines[k] = "-5 " + lines[k].split(None, 1)[1]
        elif where == "x_scale":
            k = next(i for i, ln in enumerate(lines) if ln.startswith("x_scale"))
            lines[k] = "x_scale -3 11998 1.3980"
        else:
            k = next(i for i, ln in enumerate(lines) if ln.startswith("delete_verts"))
            lines.insert(k + 1, "-7")
        return lines

    p = _mhclo(tmp_path, neg)
    refused("negative base-mesh index", "garment", "fit", p, "-o", tmp_path / "f.obj", name=p)
    assert not (tmp_path / "f.obj").exists()


def test_betas_outside_the_shape_space_are_refused(tmp_path, walk_sgdm):
    """`run --betas 1e300` and scene `betas = [1e300]` raised IndexError; NaN betas did not name the scene."""
    refused(
        "betas out of range",
        "run",
        "--garment",
        SKIRT,
        "--motion",
        WALK,
        "--betas",
        "1e300",
        "--no-cache",
        "-o",
        tmp_path / "o.pc2",
    )
    for text, words in (("1e300", "body.betas out of range"), ("nan", "body.betas must be finite")):
        scene = tmp_path / f"s_{text}.toml"
        scene.write_text(
            f'[garment]\nmesh = "{SKIRT}"\n[body]\nbetas = [{text}]\n[motion]\nkind = "walk"\n'
            '[output]\npath = "o.pc2"\n'
        )
        refused(words, "run", scene, name=scene)
    assert not (tmp_path / "o.pc2").exists()


def test_a_body_no_human_has_needs_force(tmp_path):
    """betas 4 make a 2.9 m body: refused with the height, run with --force."""
    out = tmp_path / "o.pc2"
    args = ["run", "--garment", SKIRT, "--motion", WALK, "--frames", "0:2", "--betas", "4", "--no-cache", "-o", out]
    refused("not a human's height", *args)
    r = invoke(*args, "--force")
    assert r.exit_code == 0, r.output


def test_a_body_that_folds_through_itself_needs_force(tmp_path):
    """betas 0,8 keep a human's height (1.87 m) but turn 67 of the body's faces over (a new user's trial: it ran with
    no word and the preview showed a twisted torso): refused with the count, run with --force; a shape within +-3
    is not refused."""
    from segadeform.body import default_body_path, load_body
    from segadeform.bounds import FOLDED_FACES, folded_faces

    body = load_body(default_body_path())
    assert folded_faces(body, (0, 8)) > FOLDED_FACES * len(body.faces) >= folded_faces(body, (1.5, -2, 3, 1))
    assert folded_faces(body, None) == 0
    out = tmp_path / "o.pc2"
    args = ["run", "--garment", SKIRT, "--motion", WALK, "--frames", "0:2", "--betas", "0,8", "--no-cache", "-o", out]
    refused("the body shape folds through itself (expected at most 27 of the body's 27420 faces", *args)
    assert not out.exists()
    refused("folds through itself", "motion", "export", WALK, "--betas=0,8", "-o", tmp_path / "m.sgdm")
    r = invoke(*args, "--force")
    assert r.exit_code == 0, r.output


@pytest.fixture(scope="module")
def shaped_inputs(tmp_path_factory):
    """The README's runtime files: a dress made and exported for betas 0.5,-0.3 and a walk retargeted onto them."""
    d = tmp_path_factory.mktemp("shape")
    b = "0.5,-0.3"
    assert invoke("garment", "make", "dress", "--betas", b, "-o", d / "dress.obj").exit_code == 0
    r = invoke("garment", "export", d / "dress.obj", "--betas", b, "--model", MODEL, "-o", d / "dress.sgda")
    assert r.exit_code == 0, r.output
    r = invoke(
        "motion",
        "export",
        SAMPLES / "motions" / "cmu" / "02_01_walk.bvh",
        "--betas",
        b,
        "--fps",
        "30",
        "--frames",
        "0:4",
        "-o",
        d / "walk.sgdm",
    )
    assert r.exit_code == 0, r.output
    return d


def test_an_asset_exported_for_another_model_is_refused_naming_it(shaped_inputs, tmp_path):
    """A garment asset exported for a model with another descriptor length gave `garment descriptor length does not
    match the model`, naming no file and no fix (a new user's trial)."""
    import dataclasses

    from segadeform.io.garment_asset import GarmentAsset

    a = GarmentAsset.load(shaped_inputs / "dress.sgda")
    other = dataclasses.replace(a, descriptor=a.descriptor[:16], fps_samples=a.fps_samples[:16])
    bad = other.save(tmp_path / "other.sgda")
    out = tmp_path / "o.pc2"
    said = refused(
        "the garment asset was exported for another model; export it for this one: segadeform garment export dress.obj",
        *("run", "--garment", bad, "--motion", shaped_inputs / "walk.sgdm", "-o", out),
        name=bad,
    )
    assert "(expected a garment descriptor of 32 values, got 16)" in said and not out.exists()


def test_run_on_an_asset_uses_the_betas_it_was_exported_for(shaped_inputs, tmp_path):
    """`run --garment X.sgda` ignored the asset's betas (8.5 mm off the same run with --betas)."""
    d = shaped_inputs
    from segadeform.io import read_pc2

    r = invoke("run", "--garment", d / "dress.sgda", "--motion", d / "walk.sgdm", "-o", tmp_path / "a.pc2")
    assert r.exit_code == 0, r.output
    r = invoke(
        "run",
        "--garment",
        d / "dress.sgda",
        "--motion",
        d / "walk.sgdm",
        "--betas",
        "0.5,-0.3",
        "-o",
        tmp_path / "b.pc2",
    )
    assert r.exit_code == 0, r.output
    np.testing.assert_array_equal(read_pc2(tmp_path / "a.pc2").frames, read_pc2(tmp_path / "b.pc2").frames)
    refused(
        "prepared for another body shape than the run's betas",
        "run",
        "--garment",
        d / "dress.sgda",
        "--motion",
        d / "walk.sgdm",
        "--betas",
        "0.4",
        "-o",
        tmp_path / "c.pc2",
        name=d / "dress.sgda",
    )


def test_a_motion_file_for_another_shape_is_refused(shaped_inputs, walk_sgdm, tmp_path):
    """A .sgdm made for another body shape was played without a word; --force plays it."""
    args = ["run", "--garment", SKIRT, "--motion", shaped_inputs / "walk.sgdm", "--no-cache", "-o", tmp_path / "o.pc2"]
    out = refused(
        "retargeted onto body shape betas [0.5, -0.3], and this run's body has betas 0",
        *args,
        name=shaped_inputs / "walk.sgdm",
    )
    assert "got the run's betas 0 (the default shape)" in out  # expected: the motion's; got: the run's
    assert invoke(*args, "--force").exit_code == 0
    refused(
        "retargeted onto body shape betas 0 (the default shape), and this run's body has betas [0.5, -0.3]",
        "run",
        "--garment",
        shaped_inputs / "dress.sgda",
        "--motion",
        walk_sgdm,
        "-o",
        tmp_path / "p.pc2",
        name=walk_sgdm,
    )


def test_a_motion_file_for_another_body_is_refused(walk_sgdm, tmp_path):
    import dataclasses

    from segadeform.body import load_body

    b = load_body(SAMPLES / "bodies" / "default_body.npz")
    other = tmp_path / "other_body.npz"
    dataclasses.replace(b, v_template=b.v_template * 1.01).save(other)
    refused(
        "retargeted onto another body",
        "run",
        "--garment",
        SKIRT,
        "--motion",
        walk_sgdm,
        "--body",
        other,
        "--no-cache",
        "-o",
        tmp_path / "o.pc2",
        name=walk_sgdm,
    )


def test_the_readme_runtime_files_work_as_written(shaped_inputs, tmp_path):
    """README: `garment export samples/garments/dress.obj --betas 0.5,-0.3` was refused as not on the body; the
    README now makes the dress for that shape (shaped_inputs ran its commands), and the sample dress is refused
    naming the shape it was made for."""
    out = refused(
        "made for body shape betas 0 (the default shape), not for this body's betas 0.5,-0.3",
        "garment",
        "export",
        SAMPLES / "garments" / "dress.obj",
        "--betas",
        "0.5,-0.3",
        "--model",
        MODEL,
        "-o",
        tmp_path / "d.sgda",
    )
    assert "garment make KIND --betas 0.5,-0.3" in out
    r = invoke(
        "run",
        "--garment",
        shaped_inputs / "dress.sgda",
        "--motion",
        shaped_inputs / "walk.sgdm",
        "-o",
        tmp_path / "python.pc2",
    )
    assert r.exit_code == 0, r.output


def test_a_procedural_garment_for_other_betas_is_not_blamed_on_an_origin(tmp_path):
    g = tmp_path / "skirt.obj"
    assert invoke("garment", "make", "skirt", "-o", g).exit_code == 0
    out = refused(
        "made for body shape betas 0 (the default shape)",
        "garment",
        "export",
        g,
        "--betas",
        "1.5",
        "-o",
        tmp_path / "s.sgda",
        name=g,
    )
    assert "origin" not in out and "--offset" not in out


def test_garment_fit_flags_are_used_or_refused(tmp_path):
    """`garment fit X.obj --betas` ignored --betas; `garment fit X.mhclo --offset --units --up` ignored all three."""
    refused(
        "--betas needs a garment that can be refitted",
        "garment",
        "fit",
        SKIRT,
        "--betas",
        "1",
        "-o",
        tmp_path / "a.obj",
        name=SKIRT,
    )
    refused(
        "--units, --up do not apply to a MakeHuman binding",
        "garment",
        "fit",
        MH / "skirt_short_f.mhclo",
        "--units",
        "cm",
        "--up",
        "z",
        "-o",
        tmp_path / "b.obj",
        name=MH / "skirt_short_f.mhclo",
    )
    from segadeform.io import read_obj

    for off, name in (("0,0,0", "c.obj"), ("0,0.2,0", "d.obj")):
        r = invoke(
            "garment", "fit", MH / "skirt_short_f.mhclo", "--offset", off, "--margin", "0", "-o", tmp_path / name
        )
        assert r.exit_code == 0, r.output
    moved = read_obj(tmp_path / "d.obj").vertices - read_obj(tmp_path / "c.obj").vertices
    exact = np.abs(moved - [0, 0.2, 0]).max(axis=1) < 2e-6  # the rest were pushed off the body after the move
    assert exact.mean() > 0.8 and np.abs(moved - [0, 0.2, 0]).max() < 0.03, exact.mean()


def test_complex_poses_and_two_frame_rates_are_refused(tmp_path):
    """Complex poses were cast with only a numpy warning; `mocap_framerate=[30,60]` used 30."""
    c = tmp_path / "complex.npz"
    np.savez(c, poses=np.zeros((3, 72), complex) + 1j)
    refused("poses must be real", "motion", "info", c, name=c)
    t = tmp_path / "rates.npz"
    np.savez(t, poses=np.zeros((3, 72)), mocap_framerate=np.array([30.0, 60.0]))
    refused("mocap_framerate must be one number", "motion", "info", t, name=t)


@pytest.fixture
def good_bvh(tmp_path):
    p = tmp_path / "w.bvh"
    assert invoke("motion", "make", "walk", "--seconds", "0.2", "-o", p).exit_code == 0
    return p.read_text()


def test_bvh_frame_time_and_translation_within_physical_bounds(good_bvh, tmp_path):
    """BVH `Frame Time 1e30` and `trans 1e30` ran and wrote a 1e30 cache."""
    import re

    ft = tmp_path / "ft.bvh"
    ft.write_text(re.sub(r"Frame Time: .*", "Frame Time: 1e30", good_bvh))
    refused("frame rate is outside", "run", "--garment", SKIRT, "--motion", ft, "-o", tmp_path / "o.pc2", name=ft)
    head, motion = good_bvh.split("MOTION")
    rows = motion.strip().split("\n")
    far = tmp_path / "far.bvh"
    far.write_text(head + "MOTION\n" + "\n".join(rows[:2] + ["1e30 " + r.split(None, 1)[1] for r in rows[2:]]) + "\n")
    said = refused(
        "the motion's root moves too far",
        "run",
        "--garment",
        SKIRT,
        "--motion",
        far,
        "-o",
        tmp_path / "o.pc2",
        name=far,
    )
    assert re.search(r"got [0-9.e+]+ m, first at frame \d+\)", said), said  # the frame named (a user's trial)
    assert not (tmp_path / "o.pc2").exists()


def test_a_manifest_without_weights_does_not_skip_the_weights_hash(tmp_path):
    pkg = tmp_path / "pkg"
    shutil.copytree(MODEL, pkg)
    m = json.loads((pkg / "manifest.json").read_text())
    del m["weights"]
    (pkg / "manifest.json").write_text(json.dumps(m))
    refused(
        "holds weights.bin but its manifest has no 'weights' entry",
        "run",
        "--garment",
        SKIRT,
        "--motion",
        WALK,
        "--model",
        pkg,
        "-o",
        tmp_path / "o.pc2",
        name=pkg / "manifest.json",
    )


def test_frames_past_the_end_name_the_scene(tmp_path):
    scene = tmp_path / "s.toml"
    scene.write_text(
        f'[garment]\nmesh = "{SKIRT}"\n[motion]\nkind = "walk"\nseconds = 0.2\nframes = "3:100"\n'
        '[output]\npath = "o.pc2"\n'
    )
    refused("frame range 3:100 is outside the motion's 6 frames", "run", scene, name=scene)


def test_a_folder_given_as_the_body_says_so(tmp_path):
    (tmp_path / "bodydir").mkdir()
    scene = tmp_path / "s.toml"
    scene.write_text(
        f'[garment]\nmesh = "{SKIRT}"\n[body]\nmodel = "bodydir"\n[motion]\nkind = "walk"\n[output]\npath = "o.pc2"\n'
    )
    refused("is a folder, not a body file", "run", scene, name=tmp_path / "bodydir")


def test_a_scene_with_a_byte_order_mark_reads(tmp_path):
    """A scene saved with a BOM said "Invalid statement (line 1, col 1)"."""
    scene = tmp_path / "s.toml"
    scene.write_bytes(
        b"\xef\xbb\xbf"
        + f'[garment]\nmesh = "{SKIRT}"\n[motion]\nkind = "walk"\nseconds = 0.1\n[output]\npath = "o.pc2"\n'.encode()
    )
    r = invoke("run", scene, "--no-cache")
    assert r.exit_code == 0, r.output
    assert (tmp_path / "o.pc2").is_file()


def test_clearing_the_cache_never_deletes_a_users_file(tmp_path, monkeypatch):
    """$SEGADEFORM_CACHE_DIR may name a folder that holds the user's files: `run` (which prunes the cache) and
    `cache clear` remove the cache's own entries only."""
    d = tmp_path / "mine"
    d.mkdir()
    (d / "thesis.pdf").write_bytes(b"%PDF" + b"0" * 4096)
    (d / "P-notes.npy").write_bytes(b"not an entry")  # a cache-like name without a content hash
    monkeypatch.setenv("SEGADEFORM_CACHE_DIR", str(d))
    monkeypatch.setenv("SEGADEFORM_CACHE_MAX_MB", "0")
    r = invoke("run", "--garment", SKIRT, "--motion", WALK, "--frames", "0:2", "-o", tmp_path / "o.pc2")
    assert r.exit_code == 0, r.output
    assert invoke("cache", "clear").exit_code == 0
    assert sorted(p.name for p in d.iterdir()) == ["P-notes.npy", "thesis.pdf"]


def test_a_frame_rate_that_is_not_a_number_is_refused(tmp_path):
    """`run --fps nan` ran at the motion's own rate (NaN compared unequal to nothing) and wrote its output; a
    scene's [motion] fps and `run --fps` now go through one range check, and `--fps 0` with a scene is no longer
    read as "not given".  The error names the option (a user's trial: "the motion's frame rate is out of range"
    named nothing), in `motion export` and `motion make` too."""
    # a bad option value is a command-line mistake: exit 2, as the C++ and Node runtimes and click's own ranges have
    # it (a technical artist's trial: --fps 0 exited 1, --batch 0 2)
    said = "Error: Invalid value for '--fps': the motion's frame rate is out of range (expected 1..1000 fps, got "
    scene = SAMPLES / "scenes" / "dress_dance.toml"
    for fps, args in [
        *(
            (fps, ("run", "--garment", SKIRT, "--motion", WALK, "--fps", fps, "-o", tmp_path / "o.pc2"))
            for fps in ("nan", "inf", "0", "-30", "2000")
        ),
        ("0", ("run", scene, "--fps", "0", "-o", tmp_path / "scene.pc2")),
        ("0", ("motion", "export", WALK, "--fps", "0", "-o", tmp_path / "m.sgdm")),
        ("0", ("motion", "make", "walk", "--fps", "0", "-o", tmp_path / "m.npz")),
    ]:
        r = invoke(*args)
        assert r.exit_code == 2 and r.output.strip().splitlines()[-1].startswith(said), (args, r.output)
        assert "got 0.0)" in r.output or fps != "0", r.output
    assert sorted(p.name for p in tmp_path.iterdir()) == []


def test_the_garment_cache_does_not_take_a_file_that_cannot_be_read(tmp_path):
    """The asset cache is keyed by the file's bytes: a garment OBJ run once and copied to `skirt.txt` ran from the
    cache, where `--no-cache` refused it; the file is now read (and so checked) either way."""
    ok = tmp_path / "o.pc2"
    assert invoke("run", "--garment", SKIRT, "--motion", WALK, "--frames", "0:2", "-o", ok).exit_code == 0
    for suffix, words in ((".txt", "unknown mesh file extension"), (".stl", "")):
        renamed = tmp_path / f"skirt{suffix}"
        shutil.copy(SKIRT, renamed)
        out = tmp_path / f"o{suffix}.pc2"
        r = invoke("run", "--garment", renamed, "--motion", WALK, "--frames", "0:2", "-o", out)
        assert r.exit_code == 1 and words in r.output and "skirt" + suffix in r.output, r.output
        assert not out.exists()


def test_motion_export_refuses_a_body_no_human_has_unless_forced(tmp_path):
    """A user's trial: `garment export --betas=4` was refused (a 2.86 m body, --force to mean it) and `motion export
    --betas=4` wrote its file silently and had no --force."""
    refused("not a human's height", "motion", "export", WALK, "--betas=4", "-o", tmp_path / "m.sgdm")
    assert not (tmp_path / "m.sgdm").exists()
    assert (
        invoke("motion", "export", WALK, "--betas=4", "--force", "--frames", "0:4", "-o", tmp_path / "m.sgdm").exit_code
        == 0
    )
    assert (tmp_path / "m.sgdm").is_file()


def test_a_device_given_as_an_input_file_is_refused_not_read_for_ever(tmp_path):
    """A fuzzer's trial: a garment or motion that is (a link to) /dev/zero was read until the kernel killed the
    process after about 30 s, with no word."""
    import os

    link = tmp_path / "zero.obj"
    os.symlink("/dev/zero", link)
    out = tmp_path / "o.pc2"
    r = invoke("run", "--garment", link, "--motion", WALK, "-o", out)
    assert r.exit_code == 1 and "zero.obj: is a device, not a file" in r.output and not out.exists()
    r = invoke("inspect", "/dev/zero")
    assert r.exit_code == 1 and "/dev/zero: is a device, not a file" in r.output
