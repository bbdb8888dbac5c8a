"""One wording for a file that is missing or cannot be opened, from every reader and every command
(segadeform.errors.file_error): ``PATH: no such file``, ``PATH: is a directory, not a file``."""

from __future__ import annotations

import numpy as np
import pytest
from click.testing import CliRunner

from segadeform.cli.main import cli
from segadeform.errors import FileFormatError


def _readers():
    """name -> (file name, reader(path)): every reader of a user-named file."""
    from segadeform.body.skeleton import load_rest_joints
    from segadeform.body.skeleton_map import read_joint_map
    from segadeform.dataset.store import load_sample
    from segadeform.io import read_obj, read_pc2
    from segadeform.io.alembic import read_alembic_sequence
    from segadeform.motion import read_bvh
    from segadeform.runtime import ModelPackage
    from segadeform.runtime.batch import batch_jobs, load_batch
    from segadeform.settings import load_scene

    def batch(p):
        jobs = p.parent / "jobs.toml"
        jobs.write_text(f'[batch]\noutput = "out"\n[[garments]]\nmesh = "{p.name}"\n[[motions]]\nkind = "walk"\n')
        return batch_jobs(load_batch(jobs))

    def sample(p):  # a dataset's sample: DIR/samples/ID.json
        return load_sample(p.parent.parent, p.stem)

    return {
        "obj": ("g.obj", read_obj),
        "pc2": ("c.pc2", read_pc2),
        "bvh": ("m.bvh", read_bvh),
        "toml": ("s.toml", load_scene),
        "npy joints": ("j.npy", load_rest_joints),
        "json joint map": ("map.json", read_joint_map),
        "toml joint map": ("map.toml", read_joint_map),
        "alembic": ("a.abc", read_alembic_sequence),
        "dataset sample": ("samples/x.json", sample),
        "batch garment": ("g.obj", batch),
        "model package": ("pkg", ModelPackage),
    }


@pytest.mark.parametrize("name", list(_readers()))
def test_missing_file_same_wording_from_every_reader(tmp_path, name):
    fname, read = _readers()[name]
    p = tmp_path / fname
    p.parent.mkdir(parents=True, exist_ok=True)
    with pytest.raises(FileFormatError) as e:
        read(p)
    assert str(e.value) == f"{p}: no such file"


@pytest.mark.parametrize("name", [n for n in _readers() if n not in ("model package", "dataset sample")])
def test_a_folder_for_a_file_same_wording_from_every_reader(tmp_path, name):
    fname, read = _readers()[name]
    p = tmp_path / fname
    p.mkdir(parents=True)
    with pytest.raises(FileFormatError) as e:
        read(p)
    assert str(e.value) == f"{p}: is a directory, not a file"


def test_missing_file_same_wording_from_every_command(tmp_path):
    """Each command names the missing file and says the same thing, exit status 1."""
    missing = tmp_path / "nope"
    (tmp_path / "g.obj").write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n")
    np.save(tmp_path / "j.npy", np.zeros((24, 3)))
    cases = [
        (["inspect", f"{missing}.obj"], f"{missing}.obj"),
        (["inspect", f"{missing}.pc2"], f"{missing}.pc2"),
        (["inspect", f"{missing}.bvh"], f"{missing}.bvh"),
        (["inspect", f"{missing}.toml"], f"{missing}.toml"),
        (["inspect", f"{missing}.abc"], f"{missing}.abc"),
        (["motion", "info", f"{missing}.bvh"], f"{missing}.bvh"),
        (["info", str(missing)], str(missing)),
        (
            ["precompute", str(tmp_path / "g.obj"), "--joints", f"{missing}.npy", "-o", str(tmp_path / "a.npz")],
            f"{missing}.npy",
        ),
        (["run", "--garment", f"{missing}.obj", "--motion", f"{missing}.bvh", "-o", str(tmp_path / "o.pc2")], None),
        (["simulate", f"{missing}.toml"], f"{missing}.toml"),
    ]
    for args, path in cases:
        r = CliRunner().invoke(cli, args)
        assert r.exit_code == 1, (args, r.output)
        line = r.output.strip().splitlines()[-1]
        if path is None:
            assert line.startswith(f"Error: {missing}.") and line.endswith(": no such file"), (args, line)
        else:
            assert line == f"Error: {path}: no such file", (args, line)


def test_a_folder_for_a_file_same_wording_from_every_command(tmp_path):
    """A user's trial: `run --garment "some dir"` printed click's three lines of usage ("File 'some dir' is a
    directory") and exit 2.  A path option or argument that is not what it must be -- a folder for a file, a file for
    a folder, a path that must exist and does not -- is bad input: one line naming the path, exit 1, nothing written;
    a command line click cannot read (an unknown option) stays a usage error, exit 2."""
    import click

    from segadeform.cli.main import PathParam

    folder, afile, missing = tmp_path / "some dir", tmp_path / "g.obj", tmp_path / "nope"
    folder.mkdir()
    afile.write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n")
    (tmp_path / "m.pt").write_bytes(b"a checkpoint")
    (tmp_path / "p.sgdpack").write_bytes(b"a pack")
    (tmp_path / "c.toml").write_text("[dataset]\n")
    out = tmp_path / "o.pc2"
    cases = [
        (
            ["run", "--garment", str(folder), "--motion", "walk.bvh", "-o", str(out)],
            f"{folder}: is a directory, not a file",
        ),
        (
            ["run", "--garment", str(afile), "--motion", str(folder), "-o", str(out)],
            f"{folder}: is a directory, not a file",
        ),
        (["run", str(folder)], f"{folder}: is a directory, not a file"),
        (["preview", str(out), "--garment", str(folder), "-o", str(tmp_path / "p.png")], f"{folder}: is a directory"),
        (["info", str(afile)], f"{afile}: is a file, not a directory (expected a folder)"),
        # a pack where a dataset folder is written (a user's trial: "is a file, not a directory")
        (
            ["dataset", "regate", str(tmp_path / "c.toml"), "-o", str(tmp_path / "p.sgdpack")],
            f"{tmp_path / 'p.sgdpack'}: is a dataset pack, which is only ever read (expected a dataset folder (what "
            "dataset make writes), got a pack)",
        ),
        # a checkpoint given as the model: what makes a package of it (a user's trial)
        (
            ["run", "--garment", str(afile), "--motion", "walk.bvh", "--model", str(tmp_path / "m.pt"), "-o", str(out)],
            f"{tmp_path / 'm.pt'}: is a training checkpoint, not a model package (expected a package folder: "
            f"segadeform export {tmp_path / 'm.pt'} -o PACKAGE)",
        ),
        (["garment", "export", f"{missing}.obj", "-o", str(tmp_path / "g.sgda")], f"{missing}.obj: no such file"),
    ]
    for args, said in cases:
        r = CliRunner().invoke(cli, args)
        assert r.exit_code == 1 and r.output.startswith(f"Error: {said}") and r.output.count("\n") == 1, (
            args,
            r.output,
        )
    assert sorted(p.name for p in tmp_path.iterdir()) == ["c.toml", "g.obj", "m.pt", "p.sgdpack", "some dir"]
    r = CliRunner().invoke(cli, ["run", "--garment", str(afile), "--no-such-option"])
    assert r.exit_code == 2 and "Usage:" in r.output, r.output

    def params(group):
        for cmd in group.commands.values():
            yield from params(cmd) if isinstance(cmd, click.Group) else ((cmd.name, p) for p in cmd.params)

    plain = [
        (name, p.name) for name, p in params(cli) if isinstance(p.type, click.Path) and type(p.type) is not PathParam
    ]
    assert plain == [], "path parameters of the commands must be segadeform.cli.main.PathParam"
