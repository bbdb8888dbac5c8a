"""Which format each output of `run` is written in, and the outputs refused before anything is written (a new user's
trial, 28 Nov 2026): the body in the format its own extension names, two outputs at one path, --format against the
extension, a format segadeform only reads; Alembic objects named after their file; a closed pipe on stdout."""

from __future__ import annotations

import subprocess
import sys

import numpy as np
import pytest
from click.testing import CliRunner

from segadeform.cli.main import cli
from segadeform.io import read_pc2
from segadeform.io.output_guard import MANIFEST_NAME
from segadeform.io.outputs import body_output_format, output_format_for
from segadeform.settings import load_scene

from ..conftest import SAMPLES

DRESS = SAMPLES / "garments" / "dress.obj"
WALK = SAMPLES / "motions" / "walk.npz"


def run(tmp_path, *args):
    r = CliRunner().invoke(
        cli, ["run", "--garment", str(DRESS), "--motion", str(WALK), "--frames", "0:3", "--no-cache", *map(str, args)]
    )
    assert "Traceback" not in r.output, r.output
    return r


def written(d):
    return sorted(p.name for p in d.iterdir() if p.name != MANIFEST_NAME)


def test_the_body_is_written_in_the_format_its_extension_names(tmp_path):
    """`-o d.xdmf --body-out b.pc2` wrote XDMF into b.pc2 (no PC2 reader opened it); now a point cache and the
    rest mesh it animates."""
    r = run(tmp_path, "-o", tmp_path / "d.xdmf", "--body-out", tmp_path / "b.pc2")
    assert r.exit_code == 0, r.output
    assert written(tmp_path) == ["b.obj", "b.pc2", "d.xdmf"]
    body = read_pc2(tmp_path / "b.pc2")
    assert body.frames.shape[0] == 3 and body.frames.shape[1] > 10_000 and np.isfinite(body.frames).all()
    assert (tmp_path / "d.xdmf").read_bytes().lstrip().startswith(b"<")


@pytest.mark.parametrize(
    ("out", "body", "says"),
    [
        ("e.pc2", "e_body.obj", "cannot tell the output format"),  # an OBJ file is no frame sequence
        ("e.pc2", "e_body.png", "cannot tell the output format"),
        ("same.pc2", "same.pc2", "two outputs of this run"),  # the body would replace the garment
        ("g.abc", "b.pc2", None),  # fine: a control that the cases above fail for their own reason
    ],
)
def test_a_body_output_that_cannot_be_written_is_refused_before_anything_is(tmp_path, out, body, says):
    r = run(tmp_path, "-o", tmp_path / out, "--body-out", tmp_path / body)
    if says is None:
        assert r.exit_code == 0, r.output
        return
    lines = [ln for ln in r.output.splitlines() if ln.strip()]
    assert r.exit_code == 1 and len(lines) == 1 and says in lines[0] and body in lines[0], r.output
    assert written(tmp_path) == []


@pytest.mark.parametrize("out", ["g.pc2", "g.abc", "g.usd"])
def test_a_body_output_without_an_extension_is_a_folder_of_obj_frames(tmp_path, out):
    """As `run --help` says, whatever the garment's format."""
    r = run(tmp_path, "-o", tmp_path / out, "--body-out", tmp_path / "body")
    assert r.exit_code == 0, r.output
    assert written(tmp_path) == sorted([out, "body"]) and (tmp_path / "body").is_dir()
    frames = sorted(p.name for p in (tmp_path / "body").glob("*.obj"))
    assert len(frames) == 3, frames


def test_format_and_extension_must_agree_and_read_only_formats_are_not_offered(tmp_path):
    r = run(tmp_path, "-o", tmp_path / "x.usda", "--format", "pc2")
    assert r.exit_code == 1 and "the extension says usd, the format asked for is pc2" in r.output, r.output
    r = run(tmp_path, "-o", tmp_path / "x.glb")
    assert r.exit_code == 1 and "--format" not in r.output and ".pc2" in r.output and ".usd" in r.output, r.output
    assert written(tmp_path) == []
    # an extension no format claims still takes --format (a point cache named .cache)
    r = run(tmp_path, "-o", tmp_path / "x.cache", "--format", "pc2")
    assert r.exit_code == 0, r.output
    assert read_pc2(tmp_path / "x.cache").frames.shape[0] == 3


def test_format_rules_as_functions():
    assert output_format_for("a/b.usdc") == "usd" and output_format_for("a/frames") == "obj-seq"
    assert output_format_for("a/b.bin", "pc2") == "pc2" and body_output_format("b.abc", "pc2") == "abc"
    # an extension no format claims: the garment's format, as before (a body.cache beside a .cache); no extension:
    # a folder of OBJ frames, as `run --help` says and as the garment's own path (it was the garment's format: a
    # new user's trial found an extension-less Alembic that inspect refused and a USD refused as no USD name)
    assert body_output_format("b.cache", "pc2") == "pc2"
    assert all(body_output_format("out/body", f) == "obj-seq" for f in ("pc2", "abc", "usd", "obj-seq", None))
    assert all(body_output_format("out/body", f, "out/g.pc2") == "obj-seq" for f in ("pc2", "abc"))
    # ... unless the garment's path has none either: its format was given apart (--format), and the body follows it
    # as before (a review: `-o anim --format pc2 --body-out body` wrote the body as OBJ frames)
    assert body_output_format("out/body", "pc2", "out/anim") == "pc2"
    with pytest.raises(ValueError, match="extension says xdmf"):
        output_format_for("b.xmf", "abc")


def test_a_scene_whose_outputs_disagree_names_the_scene(tmp_path):
    scene = tmp_path / "s.toml"
    scene.write_text(
        f'[garment]\nmesh = "{DRESS.as_posix()}"\n[motion]\nfile = "{WALK.as_posix()}"\n'
        '[output]\npath = "out.usd"\nformat = "pc2"\n'
    )
    with pytest.raises(
        ValueError,
        match=r"s\.toml: output\.path: the extension says usd, the format asked for is pc2 \(output\.format: ",
    ):
        load_scene(scene)
    scene.write_text(scene.read_text().replace('format = "pc2"\n', 'body = "body.obj"\n'))
    with pytest.raises(ValueError, match=r"s\.toml: output\.body: cannot tell the output format"):
        load_scene(scene)


def test_alembic_objects_are_named_after_their_file(tmp_path):
    """Garment and body were both called `garment` (Blender imported `garment` and `garment.001`)."""
    Abc = pytest.importorskip("alembic3d").Abc  # the 'alembic' extra (CI installs it)

    r = run(tmp_path, "-o", tmp_path / "dress walk.abc", "--body-out", tmp_path / "body.abc")
    assert r.exit_code == 0, r.output
    names = {}
    for f in ("dress walk.abc", "body.abc"):
        top = Abc.IArchive(str(tmp_path / f)).getTop()
        names[f] = [top.getChild(i).getName() for i in range(top.getNumChildren())]
    assert names == {"dress walk.abc": ["dress_walk"], "body.abc": ["body"]}


def test_a_closed_pipe_on_stdout_ends_quietly(tmp_path):
    """`segadeform inspect X | head -1` printed `Error: Broken pipe`."""
    r = run(tmp_path, "-o", tmp_path / "d.pc2")
    assert r.exit_code == 0, r.output
    code = "from segadeform.cli.main import main; import sys; sys.exit(main(sys.argv[1:]))"
    # help is long: its writer meets the closed pipe
    p = subprocess.Popen([sys.executable, "-c", code, "run", "--help"], stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    p.stdout.close()  # the reader goes away at once, as `head -0` would
    err = p.stderr.read().decode()
    assert p.wait(timeout=120) in (0, 141) and "Error" not in err and "Traceback" not in err, err


def test_bundle_says_which_effects_the_host_runs(tmp_path):
    """`bundle` of a scene with the cloth stage said only "wrote X.sgdb": Node and C++ then ran it without cloth or
    collisions (12.8 cm from `run`).  The bundle leaves both to the host and says how to name them there."""
    scene = tmp_path / "s.toml"
    scene.write_text(
        f'[garment]\nmesh = "{DRESS.as_posix()}"\n[motion]\nfile = "{WALK.as_posix()}"\nframes = "0:3"\n'
        '[output]\npath = "o.pc2"\n[effects]\nskinning = "lbs"\ndynamics = true\nwrinkles = true\n'
        "collisions = true\ncloth = true\n"
    )
    r = CliRunner().invoke(cli, ["bundle", str(scene), "-o", str(tmp_path / "b.sgdb")])
    assert r.exit_code == 0, r.output
    assert "collisions and cloth are not in the bundle" in r.output
    assert "segadeform garment export" in r.output and "--effects lbs,dynamics,wrinkles,collisions,cloth" in r.output
    # the scene's margin and cloth knobs go with it (a scene's trial: left out, Node ran 6-7 mm from `run`)
    scene.write_text(scene.read_text() + "collision_margin = 0.01\ncloth_iterations = 12\ncloth_stiffness = 0.3\n")
    r = CliRunner().invoke(cli, ["bundle", str(scene), "-o", str(tmp_path / "c.sgdb")])
    assert r.exit_code == 0, r.output
    assert "collisions,cloth --collision-margin 0.01 --cloth iterations=12,stiffness=0.3" in r.output, r.output
