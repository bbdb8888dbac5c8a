"""`segadeform inspect` reads every registered sequence format through segadeform.io.formats: a format registered
at run time (a writer and a reader, nothing else) is inspected like the built-in ones."""

from __future__ import annotations

import numpy as np
import pytest
from click.testing import CliRunner

from segadeform.cli.main import cli
from segadeform.io import SequenceFormat, SequenceWriter, open_sequence_writer, read_sequence, register_sequence_format
from segadeform.io.atomic import atomic_path
from segadeform.io.formats import SEQUENCE_FORMATS


class _NpyWriter(SequenceWriter):
    """Throw-away format: every frame in one .npy array, written at close."""

    def __init__(self, path, num_points, *, up="y"):
        super().__init__(path, num_points, up=up)
        self._frames = []

    def _append(self, frames):
        self._frames.append(np.asarray(frames, np.float32))

    def _commit(self):
        with atomic_path(self.path) as tmp:
            with open(tmp, "wb") as fh:
                np.save(fh, np.concatenate(self._frames))

    def _discard(self):
        self._frames = []


@pytest.fixture
def npyseq():
    fmt = register_sequence_format(
        SequenceFormat(
            "npyseq",
            (".npyseq",),
            lambda path, *, faces, num_points, fps, start_frame, rest, up: _NpyWriter(path, num_points, up=up),
            lambda path, faces: np.load(path, allow_pickle=False),
            "frames in one .npy array (a test format)",
        )
    )
    yield fmt
    del SEQUENCE_FORMATS["npyseq"]


def test_inspect_a_format_registered_at_run_time(tmp_path, npyseq):
    v = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0]], float)
    frames = np.stack([v + [0, 0.1 * k, 0] for k in range(5)])
    path = tmp_path / "g.npyseq"
    with open_sequence_writer(path, "npyseq", faces=np.array([[0, 1, 2]]), num_points=3) as w:
        w.write(frames)
    np.testing.assert_allclose(read_sequence(path), frames, atol=1e-6)
    r = CliRunner().invoke(cli, ["inspect", str(path)])
    assert r.exit_code == 0, r.output
    lines = r.output.splitlines()
    assert lines[0] == f"{path}: npyseq sequence, 5 frames x 3 vertices"
    assert "bounds [0.0, 0.0, 0.0] .. [1.0, 1.4, 0.0]" in lines[1] and "NaN/inf: none" in lines[1]
    assert "motion per frame: mean 100.00 mm" in lines[2]
    # non-finite values are reported by inspect (the format's reader keeps them)
    bad = frames.copy()
    bad[3, 1, 2] = np.nan
    np.save(tmp_path / "n.npy", bad.astype(np.float32))
    (tmp_path / "n.npy").rename(tmp_path / "n.npyseq")
    r = CliRunner().invoke(cli, ["inspect", str(tmp_path / "n.npyseq")])
    assert r.exit_code == 1 and "1 non-finite values (NaN or inf), in 1 frames (3)" in r.output
    # so is a point past 10 km (a user's trial: "mean inf mm" and numpy's overflow warning, exit 0), in one line
    far = frames.astype(np.float32)
    far[2, 0, 1] = 1e30
    np.save(tmp_path / "f.npy", far)
    (tmp_path / "f.npy").rename(tmp_path / "f.npyseq")
    r = CliRunner().invoke(cli, ["inspect", str(tmp_path / "f.npyseq")])
    assert r.exit_code == 1 and "beyond 10 km" in r.output and "Traceback" not in r.output and "inf mm" not in r.output
    # and a sequence of no frames is summarised, not a traceback (zero-size reduction)
    np.save(tmp_path / "z.npy", frames[:0].astype(np.float32))
    (tmp_path / "z.npy").rename(tmp_path / "z.npyseq")
    r = CliRunner().invoke(cli, ["inspect", str(tmp_path / "z.npyseq")])
    assert r.exit_code == 0 and r.output.splitlines()[-1] == "  no frames", r.output


def test_builtin_formats_through_the_registry(tmp_path):
    """PC2 (header hook), an OBJ-sequence folder (faces hook) and XDMF (the reader alone)."""
    v = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0]], float)
    frames = np.stack([v + [0.1 * k, 0, 0] for k in range(3)])
    for fmt, name, words in (
        ("pc2", "g.pc2", "3 samples x 3 points, start frame 4, sample rate 1"),
        ("obj-seq", "g_frames", "3 frames x 3 vertices, 1 faces"),
        ("xdmf", "g.xdmf", "3 frames x 3 vertices"),
    ):
        with open_sequence_writer(
            tmp_path / name, fmt, faces=np.array([[0, 1, 2]]), num_points=3, start_frame=4, rest=v
        ) as w:
            w.write(frames)
        r = CliRunner().invoke(cli, ["inspect", str(tmp_path / name)])
        assert r.exit_code == 0, r.output
        assert r.output.splitlines()[0] == f"{tmp_path / name}: {fmt} sequence, {words}", r.output
