"""USD output (extra 'usd'): a registered sequence format -- time-sampled points, faces, upAxis, metersPerUnit and
the frame rate -- read back by the reader and `segadeform inspect`; `run --format usd` (and `--body-out`) gives the
frames the PC2 path gives; bad targets fail whole."""

from __future__ import annotations

import numpy as np
import pytest
from click.testing import CliRunner

pytest.importorskip("pxr", reason="USD output needs the 'usd' extra")

from segadeform.cli.main import cli
from segadeform.errors import FileFormatError
from segadeform.io import format_for_path, open_sequence_writer, read_pc2, read_sequence
from segadeform.io.usd import read_usd_sequence
from segadeform.io.writer import Y_TO_Z

from ..conftest import SAMPLES, leftovers


def _mesh(n=40, frames=6, seed=0):
    rng = np.random.default_rng(seed)
    v = rng.normal(size=(n, 3))
    f = np.array([[i, i + 1, i + 2] for i in range(n - 2)])
    return v, f, np.stack([v + [0.1 * k, 0.02 * k, -0.03 * k] + 0.01 * rng.normal(size=v.shape) for k in range(frames)])


@pytest.mark.parametrize("ext", [".usd", ".usda", ".usdc"])
@pytest.mark.parametrize("up", ["y", "z"])
def test_round_trip(tmp_path, ext, up):
    v, f, frames = _mesh()
    path = tmp_path / f"garment{ext}"
    assert format_for_path(path).name == "usd"
    with open_sequence_writer(path, "usd", faces=f, num_points=len(v), fps=24.0, start_frame=7, up=up) as w:
        w.write(frames[:2])
        w.write(frames[2:])
    faces, got, times, info = read_usd_sequence(path)
    want = frames if up == "y" else frames @ np.array(Y_TO_Z).T
    np.testing.assert_array_equal(faces, f)
    np.testing.assert_array_equal(got, want.astype(np.float32))
    np.testing.assert_array_equal(times, np.arange(7, 13))
    assert info == {
        "up": up.upper(),
        "meters_per_unit": 1.0,
        "fps": 24.0,
        "start": 7.0,
        "end": 12.0,
        "prim": "/garment",
    }
    np.testing.assert_array_equal(read_sequence(path), want.astype(np.float32))
    head = path.read_bytes()[:8]
    assert head.startswith(b"#usda") == (ext == ".usda") and head.startswith(b"PXR-USDC") == (ext != ".usda")
    assert leftovers(tmp_path) == []


def test_aborted_writer_leaves_nothing(tmp_path):
    v, f, frames = _mesh()
    with pytest.raises(RuntimeError):
        with open_sequence_writer(tmp_path / "g.usd", "usd", faces=f, num_points=len(v)) as w:
            w.write(frames[:3])
            raise RuntimeError("killed")
    assert list(tmp_path.iterdir()) == []


def test_reader_refuses_what_is_not_a_polygon_mesh(tmp_path):
    from pxr import Usd, UsdGeom

    stage = Usd.Stage.CreateNew(str(tmp_path / "empty.usda"))
    UsdGeom.Xform.Define(stage, "/root")
    stage.GetRootLayer().Save()
    with pytest.raises(FileFormatError, match="empty.usda: USD file has no mesh"):
        read_usd_sequence(tmp_path / "empty.usda")
    stage = Usd.Stage.CreateNew(str(tmp_path / "quad.usda"))
    m = UsdGeom.Mesh.Define(stage, "/quad")
    m.CreatePointsAttr([(0, 0, 0), (1, 0, 0), (1, 1, 0), (0, 1, 0)])
    m.CreateFaceVertexCountsAttr([4])
    m.CreateFaceVertexIndicesAttr([0, 1, 2, 3])
    stage.GetRootLayer().Save()
    faces = read_usd_sequence(tmp_path / "quad.usda")[0]  # a quad is read as two triangles (a fan)
    np.testing.assert_array_equal(faces, [[0, 1, 2], [0, 2, 3]])
    m.GetFaceVertexCountsAttr().Set([2, 2])  # not polygons
    stage.GetRootLayer().Save()
    with pytest.raises(FileFormatError, match="quad.usda: USD mesh faces are not polygons of 3 or more corners"):
        read_usd_sequence(tmp_path / "quad.usda")
    (tmp_path / "junk.usd").write_bytes(b"PXR-USDC" + b"\0" * 40)
    with pytest.raises(FileFormatError, match="junk.usd: not a readable USD file"):
        read_usd_sequence(tmp_path / "junk.usd")


def _run(args):
    return CliRunner().invoke(
        cli, ["run", "--garment", str(SAMPLES / "garments" / "dress.obj"), "--motion", "walk", "--no-cache"] + args
    )


@pytest.fixture(scope="module")
def walk_motion(tmp_path_factory):
    from segadeform.motion import make_motion

    p = tmp_path_factory.mktemp("m") / "walk.npz"
    make_motion("walk", seconds=0.3, fps=30).save(p)
    return p


def test_run_format_usd_matches_pc2_and_inspect_reads_it(tmp_path, walk_motion):
    """`run ... -o x.usd --body-out b.usd` writes the garment and body frames the PC2 path writes (the same
    float32 numbers), with the faces and the motion's rate; `inspect` summarises the file."""

    def run(out, body):
        r = CliRunner().invoke(
            cli,
            [
                "run",
                "--garment",
                str(SAMPLES / "garments" / "dress.obj"),
                "--motion",
                str(walk_motion),
                "--frames",
                "2:8",
                "--no-cache",
                "-o",
                str(out),
                "--body-out",
                str(body),
            ],
        )
        assert r.exit_code == 0, r.output
        return r.output

    out = run(tmp_path / "dress.usd", tmp_path / "body.usd")
    assert f"wrote {tmp_path / 'dress.usd'}" in out and f"wrote {tmp_path / 'body.usd'}" in out
    run(tmp_path / "dress.pc2", tmp_path / "body.pc2")
    for name in ("dress", "body"):
        faces, frames, times, info = read_usd_sequence(tmp_path / f"{name}.usd")
        np.testing.assert_array_equal(frames, read_pc2(tmp_path / f"{name}.pc2").frames)
        np.testing.assert_array_equal(times, np.arange(2, 8))
        assert info["fps"] == 30.0 and info["up"] == "Y" and info["meters_per_unit"] == 1.0
    from segadeform.io import read_obj

    np.testing.assert_array_equal(read_usd_sequence(tmp_path / "body.usd")[0], read_obj(tmp_path / "body.obj").faces)
    r = CliRunner().invoke(cli, ["inspect", str(tmp_path / "dress.usd")])
    assert r.exit_code == 0, r.output
    first = r.output.splitlines()[0]
    assert first.startswith(f"{tmp_path / 'dress.usd'}: usd sequence, 6 time samples x ")
    assert "upAxis Y, 1 m per unit, 30 fps, time codes 2..7" in first
    assert "NaN/inf: none" in r.output


def test_usd_target_that_cannot_be_written(tmp_path, walk_motion):
    """A USD output in a folder that cannot be made (its parent is a file): one line naming the target, exit 1,
    nothing written (not the body either)."""
    (tmp_path / "afile").write_text("x")
    r = CliRunner().invoke(
        cli,
        [
            "run",
            "--garment",
            str(SAMPLES / "garments" / "dress.obj"),
            "--motion",
            str(walk_motion),
            "--no-cache",
            "-o",
            str(tmp_path / "afile" / "dress.usd"),
            "--body-out",
            str(tmp_path / "body.usd"),
        ],
    )
    assert r.exit_code == 1
    lines = [ln for ln in r.output.splitlines() if ln.strip()]
    assert len(lines) == 1 and lines[0].startswith("Error: ") and "dress.usd" in lines[0], r.output
    assert "afile" in lines[0].split("dress.usd", 1)[1]  # and says why: afile is a file
    assert sorted(p.name for p in tmp_path.iterdir()) == ["afile"]


@pytest.mark.parametrize("ext", [".usd", ".usda"])
def test_lazy_frames_read_the_time_samples_asked_for(tmp_path, ext, monkeypatch):
    """`read_usd_mesh(lazy=True)` reads a time sample when it is indexed, as float32 (`inspect` and `preview` of a
    long USD held the whole clip as float64, 7.5 GB for a 756 MB body; a user's trial); the start frame is read
    from the time codes alone."""
    from segadeform.io import usd
    from segadeform.io.formats import sequence_start_frame
    from segadeform.io.sequence import open_sequence_frames

    v, f, frames = _mesh(n=12, frames=9)
    path = tmp_path / f"g{ext}"
    with open_sequence_writer(path, "usd", faces=f, num_points=len(v), fps=30.0, start_frame=5) as w:
        w.write(frames)
    lazy = usd.read_usd_mesh(path, lazy=True)[2]
    assert isinstance(lazy, usd.UsdFrames) and lazy.shape == (9, 12, 3) and lazy.dtype == np.float32
    np.testing.assert_array_equal(lazy.times, 5 + np.arange(9))
    asked = []
    real = usd.UsdFrames._read
    monkeypatch.setattr(usd.UsdFrames, "_read", lambda self, idx: asked.append(list(idx)) or real(self, idx))
    np.testing.assert_array_equal(lazy[[2, 7]], frames[[2, 7]].astype(np.float32))
    assert lazy[4].dtype == np.float32 and asked == [[2, 7], [4]]
    np.testing.assert_array_equal(open_sequence_frames(path)[1:3], frames[1:3].astype(np.float32))
    assert sequence_start_frame(path) == 5 and usd.usd_start_frame(path) == 5.0
    whole = usd.read_usd_mesh(path)[2]  # not lazy: the whole clip, float64, as before
    assert whole.dtype == np.float64
    np.testing.assert_array_equal(whole, frames.astype(np.float32))


def test_a_binary_usd_is_streamed_to_its_file(tmp_path, monkeypatch):
    """`run -o g.usd --body-out b.usd` held the whole clip in memory (1.1 GB at 4,593 frames; PC2 and Alembic stay
    flat).  A .usd/.usdc writer now saves its file every SAVE_BYTES of points, under its temporary name (USD's
    crate format appends; the samples saved leave memory), and renames it when closed; a .usda (text) is written
    when closed.  The frames read back are those written, and an abort after saves leaves nothing."""
    from segadeform.io import usd

    v, f, frames = _mesh(n=10, frames=10)
    monkeypatch.setattr(usd, "SAVE_BYTES", 3 * 10 * 12)  # every 3 frames
    sizes = {}
    real = usd.UsdSequenceWriter._save

    def save(self):
        real(self)
        sizes.setdefault(self.path.suffix, []).append(self._tmp.stat().st_size)

    monkeypatch.setattr(usd.UsdSequenceWriter, "_save", save)
    for ext in (".usd", ".usdc", ".usda"):
        with open_sequence_writer(tmp_path / f"g{ext}", "usd", faces=f, num_points=len(v), start_frame=4) as w:
            for fr in frames:
                w.write(fr)
            held = leftovers(tmp_path)  # the name held, and a binary file's frames so far
            assert not (tmp_path / f"g{ext}").exists() and len(held) == (1 if ext == ".usda" else 2), held
        faces, got, times, info = read_usd_sequence(tmp_path / f"g{ext}")
        np.testing.assert_array_equal(got, frames.astype(np.float32))
        np.testing.assert_array_equal(times, 4 + np.arange(10))
        assert (info["start"], info["end"], info["fps"]) == (4.0, 13.0, 30.0) and leftovers(tmp_path) == []
    for ext in (".usd", ".usdc"):  # saved at frames 3, 6, 9 and when closed, the file growing
        assert len(sizes[ext]) == 4 and sizes[ext] == sorted(sizes[ext]), sizes
    assert ".usda" not in sizes  # text is written whole, when closed
    with pytest.raises(RuntimeError):
        with open_sequence_writer(tmp_path / "a.usd", "usd", faces=f, num_points=len(v)) as w:
            w.write(frames[:7])  # two saves
            raise RuntimeError("killed")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["g.usd", "g.usda", "g.usdc"]


def test_a_binary_usd_writer_holds_no_more_memory_for_more_frames(tmp_path):
    """The memory a .usd writer takes does not grow with the frames (max RSS of a process writing 100 and 1,600
    frames of 2,000 vertices: 2.4 and 38 MB of points; it grew by the points, 12 bytes a vertex a frame)."""
    import subprocess
    import sys

    script = (
        "import resource, sys, numpy as np\n"
        "from segadeform.io import open_sequence_writer, usd\n"
        "usd.SAVE_BYTES = 1 << 20\n"
        "n, s = 2000, int(sys.argv[1])\n"
        "f = np.array([[i, i + 1, i + 2] for i in range(n - 2)])\n"
        "v = np.random.default_rng(0).normal(size=(n, 3)).astype(np.float32)\n"
        "with open_sequence_writer(sys.argv[2], 'usd', faces=f, num_points=n) as w:\n"
        "    for k in range(s):\n"
        "        w.write(v + np.float32(0.001 * k))\n"
        "print(resource.getrusage(resource.RUSAGE_SELF).ru_maxrss)\n"
    )

    def max_rss_kb(frames):
        out = tmp_path / f"m{frames}.usd"
        r = subprocess.run([sys.executable, "-c", script, str(frames), str(out)], capture_output=True, text=True)
        assert r.returncode == 0, r.stderr[-2000:]
        return int(r.stdout.split()[-1])

    few, many = max_rss_kb(100), max_rss_kb(1600)
    assert many - few < 12_000, (few, many)  # 36 MB more points were written


def test_a_usd_file_that_cannot_be_saved_is_one_error_naming_it(tmp_path, monkeypatch):
    """A save that fails while the frames stream (a full disk: USD says so in its own error) is one error naming the
    target, and nothing is left; as is an export of a .usda that fails when the writer closes."""
    from segadeform.io import usd
    from segadeform.io.atomic import WriteError

    class Refusing:
        def Save(self):
            return False

        def Export(self, *args):
            raise RuntimeError("Error in 'pxrInternal...': disk full\nmore lines of pxr")

    class Stage:  # a .usda stage whose layer refuses
        def __init__(self, stage):
            self.stage = stage

        def SetEndTimeCode(self, t):
            pass

        def GetRootLayer(self):
            return Refusing()

    v, f, frames = _mesh(n=10, frames=5)
    monkeypatch.setattr(usd, "SAVE_BYTES", 3 * 10 * 12)
    w = open_sequence_writer(tmp_path / "g.usd", "usd", faces=f, num_points=len(v))
    w._layer = Refusing()
    with pytest.raises(WriteError) as ei:
        w.write(frames)
    assert str(ei.value) == f"{tmp_path / 'g.usd'}: cannot write: USD could not save the file; nothing was left behind"
    assert list(tmp_path.iterdir()) == []
    w = open_sequence_writer(tmp_path / "g.usda", "usd", faces=f, num_points=len(v))
    w.write(frames)
    w._stage = Stage(w._stage)
    with pytest.raises(WriteError) as ei:
        w.close()
    # said once, on one line (the target was said twice), pxr's report of its error cut to what it says
    assert str(ei.value) == (
        f"{tmp_path / 'g.usda'}: cannot write: USD could not export the stage (Error in 'pxrInternal...': disk full "
        "more lines of pxr); nothing was left behind"
    )
    assert list(tmp_path.iterdir()) == []


def test_a_stop_during_the_usd_import_still_stops_the_command():
    """USD's module set-up catches what is raised while it runs: a SIGTERM (the CLI's KeyboardInterrupt) in that half
    second was lost and the run wrote its output (a session's trial).  It is now held until the import is done."""
    import subprocess
    import sys

    pytest.importorskip("pxr")
    code = """
import builtins, os, signal
from segadeform.cli.main import _terminated
signal.signal(signal.SIGTERM, _terminated)
real = builtins.__import__
def imp(name, *a, **k):
    if name == "pxr":  # as USD's set-up: the signal arrives, and what its handler raises is caught
        try:
            os.kill(os.getpid(), signal.SIGTERM)
            for _ in range(100000):
                pass
        except BaseException as e:
            print("swallowed", type(e).__name__)
    return real(name, *a, **k)
builtins.__import__ = imp
from segadeform.io import usd
try:
    usd._modules()
    print("not stopped")
except KeyboardInterrupt:
    print("stopped")
"""
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert out.stdout.split() == ["stopped"], (out.stdout, out.stderr)
