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
