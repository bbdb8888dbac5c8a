"""Never lose a user's file (issue 29): for every command that writes, a folder holding a user's files survives
a run with and without --force, byte for byte (the folder is hashed before and after).

Two situations per command:

* **in the way**: the output path is a user's file (or, for a folder output, a folder holding a file at one of
  the output's names): refused, with --force too where the command has it; exit 1, one line naming the path;
* **beside**: the output goes into a folder holding a user's file: a file output is written, and written again
  (an earlier output of the same command is replaced); a folder output is refused without --force and written
  beside the user's file with it.

Commands that need torch, Blender or anny are checked where the refusal happens (before any of those run); the
full runs beside a user's file for simulate and dataset make need the simulator and are skipped without it.
"""

from __future__ import annotations

import hashlib
import shutil
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

from segadeform.cli.main import cli
from segadeform.io.output_guard import MANIFEST_NAME

from ..conftest import REPO, SAMPLES

SKIRT = SAMPLES / "garments" / "skirt.obj"
WALK = SAMPLES / "motions" / "walk.npz"
MODEL = SAMPLES / "models" / "default"
BODY = SAMPLES / "bodies" / "default_body.npz"
MHCLO = SAMPLES / "garments" / "makehuman" / "skirt_short_f.mhclo"


def folder_hash(d: Path) -> dict:
    """sha256 of every file under ``d`` except segadeform's outputs manifest."""
    return {
        p.relative_to(d).as_posix(): hashlib.sha256(p.read_bytes()).hexdigest()
        for p in sorted(Path(d).rglob("*"))
        if p.is_file() and p.name != MANIFEST_NAME
    }


def invoke(args):
    r = CliRunner().invoke(cli, [str(a) for a in args])
    assert r.exception is None or isinstance(r.exception, SystemExit), (args, r.output, repr(r.exception))
    assert "Traceback" not in r.output, r.output
    return r


def user_folder(tmp_path, *names) -> Path:
    d = tmp_path / "users"
    d.mkdir(exist_ok=True)
    (d / "notes.txt").write_text("a user's notes\n")
    for n in names:
        (d / n).write_bytes(b"a user's file " + n.encode())
    return d


def scene_file(tmp_path, out: str, fmt: str = "") -> Path:
    p = tmp_path / "scene.toml"
    p.write_text(
        f'[garment]\nmesh = "{SKIRT}"\n[motion]\nkind = "walk"\nseconds = 0.2\n'
        f'[output]\npath = "{out}"\n'
        + (f'format = "{fmt}"\n' if fmt else "")
        + '[simulate]\neffects = ["gravity", "body_collision"]\nquality = 3\ndrape_seconds = 0.1\n'
        "blend_seconds = 0.0\n"
    )
    return p


def pc2_result(tmp_path) -> Path:
    from segadeform.io import read_mesh, write_pc2

    v = read_mesh(SKIRT).vertices
    p = tmp_path / "result.pc2"
    write_pc2(p, np.stack([v, v + 0.01]))
    return p


def fitted_skirt(tmp_path) -> Path:
    """The skirt as `garment fit --units m` records a plain fit (what `garment unfit` undoes)."""
    p = tmp_path / "fitted.obj"
    p.write_text("# segadeform garment fit: units m, up y, scale 1 (by hand)\n" + Path(SKIRT).read_text())
    return p


def fbx_file(tmp_path) -> str:
    """An FBX character (a skinned mesh and its animation), made by Blender once per test folder."""
    from tests.physics.fbx_files import make_fbx

    p = tmp_path / "walk.fbx"
    if not p.exists():
        make_fbx(SAMPLES / "motions" / "cmu" / "02_01_walk.bvh", p, "skinned")
    return str(p)


def member_checkpoints(tmp_path) -> list[str]:
    """Two small trained-network checkpoints of one configuration (the inputs of `segadeform ensemble`)."""
    import torch

    from segadeform.model import ModelConfig, SEGANet, save_checkpoint

    out = []
    for i in range(2):
        p = tmp_path / f"member{i}.pt"
        if not p.exists():
            torch.manual_seed(i)
            save_checkpoint(p, SEGANet(ModelConfig(hidden=16, lstm_hidden=16)))
        out.append(str(p))
    return out


# (command, output name in the user's folder, args(tmp_path, out) -> list); the output is a single file
FILE_COMMANDS = {
    "ensemble": ("e.pt", lambda t, o: ["ensemble", *member_checkpoints(t), "-o", o]),
    "run": (
        "x.pc2",
        lambda t, o: ["run", "--garment", SKIRT, "--motion", WALK, "--frames", "0:3", "--no-cache", "-o", o],
    ),
    "garment make": ("g.obj", lambda t, o: ["garment", "make", "skirt", "-o", o]),
    "garment fit": ("f.obj", lambda t, o: ["garment", "fit", MHCLO, "-o", o]),
    "garment export": ("g.sgda", lambda t, o: ["garment", "export", SKIRT, "--model", MODEL, "-o", o]),
    "garment unfit": (
        "u.pc2",
        lambda t, o: ["garment", "unfit", pc2_result(t), "--garment", fitted_skirt(t), "-o", o],
    ),
    "motion make": ("m.npz", lambda t, o: ["motion", "make", "walk", "--seconds", "0.2", "-o", o]),
    "motion export": ("m.sgdm", lambda t, o: ["motion", "export", "walk", "--seconds", "0.2", "-o", o]),
    "motion convert": ("m.bvh", lambda t, o: ["motion", "convert", fbx_file(t), "-o", o]),
    "precompute": ("a.npz", lambda t, o: ["precompute", SKIRT, "--body", BODY, "-o", o]),
    "preview": ("p.png", lambda t, o: ["preview", pc2_result(t), "--garment", SKIRT, "--size", "40x60", "-o", o]),
    "bundle": (
        "b.sgdb",
        lambda t, o: [
            "bundle",
            scene_file(t, str(t / "unused.pc2")),
            "--model",
            MODEL,
            "--no-expected",
            "--frames",
            "0:2",
            "-o",
            o,
        ],
    ),
}
# refused before their work: checked only in the way (the work needs anny, Blender or a dataset)
REFUSAL_ONLY = {
    "body bake": ("b.npz", lambda t, o: ["body", "bake", "-o", o]),
    "simulate": ("s.pc2", lambda t, o: ["simulate", scene_file(t, str(o))]),
    "dataset pack": ("d.sgdpack", lambda t, o: ["dataset", "pack", t, "-o", o]),
}


#: the commands with a --force (run, simulate: write beside a user's files; garment export, bundle: a garment off
#: the body); the others have none
HAS_FORCE = {"run", "simulate", "garment export", "bundle"}


@pytest.mark.parametrize("cmd", sorted(FILE_COMMANDS) + sorted(REFUSAL_ONLY))
def test_a_users_file_at_the_output_path_survives_with_and_without_force(cmd, tmp_path):
    name, args = {**FILE_COMMANDS, **REFUSAL_ONLY}[cmd]
    d = user_folder(tmp_path, name)
    before = folder_hash(d)
    for force in ([], ["--force"]) if cmd in HAS_FORCE else ([],):
        r = invoke(args(tmp_path, d / name) + force)
        assert r.exit_code == 1, (cmd, force, r.output)
        assert str(d / name) in r.output and "segadeform did not write it" in r.output, r.output
        assert len(r.output.strip().splitlines()) == 1, r.output
    assert folder_hash(d) == before


@pytest.mark.parametrize("cmd", sorted(FILE_COMMANDS))
def test_an_output_beside_a_users_file_is_written_and_its_own_output_replaced(cmd, tmp_path):
    name, args = FILE_COMMANDS[cmd]
    d = user_folder(tmp_path)
    before = folder_hash(d)
    out = d / ("new-" + name)
    for force in ([], ["--force"]) if cmd in HAS_FORCE else ([], []):
        r = invoke(args(tmp_path, out) + force)  # the second time over its own earlier output
        assert r.exit_code == 0, r.output
        after = folder_hash(d)
        assert {k: v for k, v in after.items() if k in before} == before and set(after) == set(before) | {out.name}


def test_another_commands_output_is_not_replaced(tmp_path):
    g = tmp_path / "g.obj"
    assert invoke(["garment", "make", "skirt", "-o", g]).exit_code == 0
    first = g.read_bytes()
    r = invoke(["garment", "fit", MHCLO, "-o", g])
    assert r.exit_code == 1 and "written by `segadeform garment make`" in r.output and str(g) in r.output
    assert g.read_bytes() == first


def test_run_into_a_folder_of_the_users_files_issue_reproduction(tmp_path):
    """`run --garment keep/skirt.obj --motion walk.sgdm -o keep` deleted keep/ whole; now: refused, and with
    --force the frames are written beside the garment, which is the run's own input."""
    d = tmp_path / "keep"
    d.mkdir()
    shutil.copy(SKIRT, d / "skirt.obj")
    (d / "notes.txt").write_text("notes")
    before = folder_hash(d)

    def args(frames="0:3"):
        return [
            "run",
            "--garment",
            d / "skirt.obj",
            "--motion",
            WALK,
            "--frames",
            frames,
            "--format",
            "obj-seq",
            "--no-cache",
            "-o",
            d,
        ]

    r = invoke(args())
    assert r.exit_code == 1 and "did not write (notes.txt, skirt.obj)" in r.output and str(d) in r.output
    assert folder_hash(d) == before
    r = invoke(args() + ["--force"])
    assert r.exit_code == 0, r.output
    after = folder_hash(d)
    assert {k: after[k] for k in before} == before
    assert sorted(set(after) - set(before)) == ["frame_00000.obj", "frame_00001.obj", "frame_00002.obj"]
    # a second, shorter run replaces its own frames and removes those it does not write again
    r = invoke(args("0:2") + ["--force"])
    assert r.exit_code == 0, r.output
    assert sorted(set(folder_hash(d)) - set(before)) == ["frame_00000.obj", "frame_00001.obj"]


def test_run_body_out_into_a_folder_of_the_users_files(tmp_path):
    """`--body-out` without an extension is a folder of OBJ frames: into a folder of a user's files it is refused
    (nothing written, the garment output neither), with --force its frames go beside them, and a later, shorter run
    removes only the frames it wrote."""
    d = user_folder(tmp_path, "body_notes.obj")
    before = folder_hash(d)

    def args(frames="0:3"):
        out = tmp_path / "g.pc2"
        return [
            "run",
            "--garment",
            SKIRT,
            "--motion",
            WALK,
            "--frames",
            frames,
            "--no-cache",
            "-o",
            out,
            "--body-out",
            d,
        ]

    r = invoke(args())
    assert r.exit_code == 1 and str(d) in r.output and "body_notes.obj, notes.txt" in r.output, r.output
    assert len(r.output.strip().splitlines()) == 1 and not (tmp_path / "g.pc2").exists()
    assert folder_hash(d) == before
    r = invoke(args() + ["--force"])
    assert r.exit_code == 0, r.output
    after = folder_hash(d)
    assert {k: after[k] for k in before} == before
    assert sorted(set(after) - set(before)) == ["frame_00000.obj", "frame_00001.obj", "frame_00002.obj"]
    r = invoke(args("0:2") + ["--force"])
    assert r.exit_code == 0, r.output
    after = folder_hash(d)
    assert {k: after[k] for k in before} == before
    assert sorted(set(after) - set(before)) == ["frame_00000.obj", "frame_00001.obj"]


def test_a_scene_writing_into_its_own_folder_keeps_every_toml(tmp_path):
    """A scene whose output.path is its own folder deleted the 39 .toml files beside it (exit 0)."""
    d = tmp_path / "scenes"
    d.mkdir()
    for p in (SAMPLES / "scenes").glob("*.toml"):
        shutil.copy(p, d / p.name)
    own = d / "own.toml"
    own.write_text(
        f'[garment]\nmesh = "{SKIRT}"\n[motion]\nkind = "walk"\nseconds = 0.2\n[output]\npath = "."\n'
        'format = "obj-seq"\n'
    )
    before = folder_hash(d)
    r = invoke(["run", own, "--no-cache"])
    assert r.exit_code == 1 and "own.toml" in r.output and "--force to write beside them" in r.output
    assert folder_hash(d) == before
    r = invoke(["run", own, "--no-cache", "--force"])
    assert r.exit_code == 0, r.output
    after = folder_hash(d)
    assert {k: after[k] for k in before} == before and len(after) == len(before) + 6


def test_output_inside_a_file_and_the_working_folder(tmp_path, monkeypatch):
    """`-o file.obj/x.pc2` said "File exists"; `-o .` said "Device or resource busy"."""
    f = tmp_path / "file.obj"
    f.write_text("v 0 0 0\n")
    r = invoke(["run", "--garment", SKIRT, "--motion", WALK, "--frames", "0:2", "--no-cache", "-o", f / "x.pc2"])
    assert r.exit_code == 1 and "is a file, so nothing can be written inside it" in r.output and "file.obj" in r.output
    assert f.read_text() == "v 0 0 0\n"
    work = tmp_path / "work"
    work.mkdir()
    monkeypatch.chdir(work)
    r = invoke(
        ["run", "--garment", SKIRT, "--motion", WALK, "--frames", "0:2", "--no-cache", "--format", "obj-seq", "-o", "."]
    )
    assert r.exit_code == 0, r.output
    assert sorted(p.name for p in work.iterdir()) == [MANIFEST_NAME, "frame_00000.obj", "frame_00001.obj"]


FOLDER_COMMANDS = {  # a folder output: a user's file beside survives; --force writes beside it (run, eval)
    "run obj-seq": lambda t, o: [
        "run",
        "--garment",
        SKIRT,
        "--motion",
        WALK,
        "--frames",
        "0:2",
        "--no-cache",
        "--format",
        "obj-seq",
        "-o",
        o,
    ],
}


@pytest.mark.parametrize("cmd", ["export", "quantize", "repack", "export-body --to", "eval"])
def test_a_users_folder_is_never_a_package_or_report(cmd, tmp_path):
    """Model package folders (export, quantize, repack, export-body) and eval reports: a folder holding a user's
    file at one of the output's names is refused with and without --force."""
    pytest.importorskip("onnx", reason="the package writers need the 'torch' extra")
    d = user_folder(tmp_path, "manifest.json", "eval.md")
    before = folder_hash(d)
    args = {
        "export": ["export", "--random-init", "--legacy", "--no-check", "-o", d],
        "quantize": ["quantize", MODEL, "-o", d],
        "repack": ["repack", MODEL, "-o", d],
        "export-body --to": ["export-body", "-o", MODEL, "--to", d],
        "eval": ["eval", tmp_path, "-m", "l=lbs", "-o", d],
    }[cmd]
    for force in ([], ["--force"]) if cmd == "eval" else ([],):  # (the package writers have no --force)
        r = invoke(args + force)
        assert r.exit_code == 1 and str(d) in r.output and "did not write" in r.output, (cmd, force, r.output)
    assert folder_hash(d) == before


def test_export_body_in_place_only_rewrites_a_package_segadeform_wrote(tmp_path):
    pytest.importorskip("onnx", reason="export-body needs the 'torch' extra")
    pkg = tmp_path / "pkg"
    shutil.copytree(MODEL, pkg)  # a package segadeform did not write here (no outputs manifest)
    (pkg / "my-notes.txt").write_text("mine")
    before = folder_hash(pkg)
    r = invoke(["export-body", "-o", pkg])
    assert r.exit_code == 1 and "--to NEW_DIR" in r.output and str(pkg) in r.output, r.output
    assert folder_hash(pkg) == before


@pytest.mark.parametrize("cmd", sorted(FOLDER_COMMANDS))
def test_a_folder_output_beside_a_users_file_needs_force(cmd, tmp_path):
    d = user_folder(tmp_path)
    before = folder_hash(d)
    r = invoke(FOLDER_COMMANDS[cmd](tmp_path, d))
    assert r.exit_code == 1 and "notes.txt" in r.output and "--force to write beside them" in r.output
    r = invoke(FOLDER_COMMANDS[cmd](tmp_path, d) + ["--force"])
    assert r.exit_code == 0, r.output
    after = folder_hash(d)
    assert {k: after[k] for k in before} == before and len(after) > len(before)


@pytest.mark.parametrize("cmd", ["batch", "dataset make", "train", "dataset regate"])
def test_resumable_commands_refuse_a_folder_of_the_users_files(cmd, tmp_path):
    """batch, dataset make and train continue their own folders; one holding a user's file where they write
    (config.toml, jobs/...) is refused with and without --force, and one holding only other files needs --force."""
    d = user_folder(tmp_path, "config.toml", "jobs", "loss.csv")
    before = folder_hash(d)
    jobs = tmp_path / "jobs.toml"
    jobs.write_text(f'[[garments]]\nmesh = "{SKIRT}"\n[[motions]]\nkind = "walk"\nseconds = 0.2\n')
    args = {
        "batch": ["batch", jobs, "-o", d],
        "dataset make": ["dataset", "make", SAMPLES / "datasets" / "tiny.toml", "-o", d],
        "train": ["train", SAMPLES / "train" / "default.toml", "-o", d],
        "dataset regate": ["dataset", "regate", SAMPLES / "datasets" / "tiny.toml", "-o", d],
    }[cmd]
    if cmd == "train":
        pytest.importorskip("torch", reason="train needs the 'torch' extra")
    for force in ([], ["--force"]) if cmd != "dataset regate" else ([],):
        r = invoke(args + force)
        assert r.exit_code == 1 and str(d) in r.output, (cmd, force, r.output)
        assert ("where segadeform" in r.output) if force else ("did not write" in r.output), r.output
    assert folder_hash(d) == before


def test_batch_beside_a_users_file_with_force_and_resumed_without(tmp_path):
    d = user_folder(tmp_path)
    before = folder_hash(d)
    jobs = tmp_path / "jobs.toml"
    jobs.write_text(f'[[garments]]\nmesh = "{SKIRT}"\n[[motions]]\nkind = "walk"\nseconds = 0.2\n')
    r = invoke(["batch", jobs, "-o", d])
    assert r.exit_code == 1 and "--force to write beside them" in r.output
    r = invoke(["batch", jobs, "-o", d, "--force"])
    assert r.exit_code == 0, r.output
    r = invoke(["batch", jobs, "-o", d])  # its own folder now: resumed, nothing made again
    assert r.exit_code == 0 and "1 already done, 0 made" in r.output, r.output
    after = folder_hash(d)
    assert {k: after[k] for k in before} == before and "skirt__walk.pc2" in after


def test_a_failed_batch_leaves_no_empty_folder(tmp_path):
    bad = tmp_path / "bad.obj"
    bad.write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 4\n")
    jobs = tmp_path / "jobs.toml"
    jobs.write_text(f'[[garments]]\nmesh = "{bad}"\n[[motions]]\nkind = "walk"\nseconds = 0.2\n')
    r = invoke(["batch", jobs, "-o", tmp_path / "out"])
    assert r.exit_code == 1 and "bad.obj:4" in r.output
    assert not (tmp_path / "out").exists()


def _need_simulator():
    from segadeform.errors import SimulationError
    from segadeform.physics import find_sim_python

    try:
        find_sim_python()
    except SimulationError as e:
        pytest.skip(f"no simulator environment here ({e})")


def test_simulate_into_a_users_folder_with_force(tmp_path, monkeypatch):
    """simulate's outputs are claimed before Blender starts (refused at once); with --force beside the user's
    file."""
    _need_simulator()
    from segadeform.body import load_body
    from segadeform.garments import make_garment
    from segadeform.io import Mesh, write_obj

    g = make_garment("skirt", load_body(BODY))
    write_obj(tmp_path / "coarse.obj", Mesh(vertices=g.vertices, faces=g.faces))
    d = user_folder(tmp_path)
    before = folder_hash(d)
    scene = scene_file(tmp_path, str(d), "obj-seq")
    scene.write_text(scene.read_text().replace(str(SKIRT), str(tmp_path / "coarse.obj")))
    r = invoke(["simulate", scene])
    assert r.exit_code == 1 and "--force to write beside them" in r.output
    r = invoke(["simulate", scene, "--force"])
    assert r.exit_code == 0, r.output
    after = folder_hash(d)
    assert {k: after[k] for k in before} == before and "frame_00000.obj" in after


def test_dataset_make_beside_a_users_file_with_force(tmp_path):
    _need_simulator()
    d = user_folder(tmp_path)
    before = folder_hash(d)
    tiny = SAMPLES / "datasets" / "tiny.toml"
    r = invoke(["dataset", "make", tiny, "-o", d, "--limit", "1"])
    assert r.exit_code == 1 and "--force to write beside them" in r.output
    r = invoke(["dataset", "make", tiny, "-o", d, "--limit", "1", "--force"])
    assert r.exit_code == 0, r.output
    after = folder_hash(d)
    assert {k: after[k] for k in before} == before and "config.toml" in after
    assert any(k.startswith(("samples/", "rejected/")) for k in after)
    # --split continues the same folder (a dataset folder now: no --force needed) and leaves the user's file too
    r = invoke(["dataset", "make", tiny, "-o", d, "--limit", "1", "--split", "test"])
    assert r.exit_code == 0, r.output
    again = folder_hash(d)
    assert {k: again[k] for k in before} == before
    new = {k for k in again if k.startswith(("samples/", "rejected/")) and k.endswith(".json")} - set(after)
    assert len(new) == 1 and "skirt-0__b0__walk-s0" not in next(iter(new))  # a held-out sample, not the training one


def test_every_writing_command_claims_its_outputs():
    """Every command with an output option claims it through OutputGuard, and every kind is covered here."""
    import re

    covered = set(FILE_COMMANDS) | set(REFUSAL_ONLY) | {"package", "eval", "batch", "dataset", "train"}
    guarded = set()
    for f in sorted((REPO / "cli").glob("*.py")):
        text = f.read_text()
        for cmd in re.split(r"\n@[a-z_]+\.command\(", text)[1:]:  # each command's source
            if '"--output"' in cmd or '"--to"' in cmd:
                kinds = re.findall(r'OutputGuard\(\s*"([a-z ]+)"', cmd) + re.findall(r"_package_guard\(", cmd)
                assert kinds, f"{f.name}: a command with an output option claims none: {cmd[:80]!r}"
        guarded |= set(re.findall(r'OutputGuard\(\s*"([a-z ]+)"', text))
    assert guarded <= covered, guarded - covered
    assert {
        "run",
        "simulate",
        "batch",
        "dataset",
        "preview",
        "garment fit",
        "garment export",
        "motion export",
        "package",
        "dataset pack",
    } <= guarded
