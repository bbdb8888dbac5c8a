"""`segadeform preview` renders results without Blender; `inspect` summarises point caches."""

import numpy as np
import pytest
from click.testing import CliRunner

from segadeform.cli.main import cli
from segadeform.errors import InputError
from segadeform.io import Mesh, write_obj, write_pc2


def _scene(tmp_path, n_frames=4):
    v = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [1, 1, 0]], float)
    f = np.array([[0, 1, 2], [1, 3, 2]])
    write_obj(tmp_path / "g.obj", Mesh(vertices=v, faces=f))
    frames = np.stack([v + [0, 0.1 * k, 0] for k in range(n_frames)]).astype(np.float32)
    write_pc2(tmp_path / "g.pc2", frames)
    return frames


def test_preview_png_and_gif(tmp_path):
    _scene(tmp_path)
    r = CliRunner().invoke(
        cli,
        [
            "preview",
            str(tmp_path / "g.pc2"),
            "--garment",
            str(tmp_path / "g.obj"),
            "-o",
            str(tmp_path / "p.png"),
            "--size",
            "80x60",
        ],
    )
    assert r.exit_code == 0, r.output
    from matplotlib.image import imread

    img = imread(tmp_path / "p.png")
    assert img.shape[:2] == (60, 4 * 80)
    assert (img[..., :3] < 0.9).any()  # something was drawn on the white background
    r = CliRunner().invoke(
        cli,
        [
            "preview",
            str(tmp_path / "g.pc2"),
            "--garment",
            str(tmp_path / "g.obj"),
            "-o",
            str(tmp_path / "p.gif"),
            "--size",
            "80x60",
            "--view",
            "turntable",
        ],
    )
    assert r.exit_code == 0 and (tmp_path / "p.gif").stat().st_size > 0
    r = CliRunner().invoke(
        cli,
        [
            "preview",
            str(tmp_path / "g.pc2"),
            "--garment",
            str(tmp_path / "g.obj"),
            "-o",
            str(tmp_path / "q.png"),
            "--frames",
            "2:9",
        ],
    )
    assert r.exit_code == 1 and "outside the result's frames 0..3" in r.output and not (tmp_path / "q.png").exists()


def test_preview_counts_frames_as_the_result_does(tmp_path):
    """A run of --frames 10:40 writes a PC2 starting at frame 10; preview labelled its frames 0, 1, ... and took
    --frames from the file's start.  Now both are the result's own frame numbers, in every format that keeps one."""
    from segadeform.io import write_obj_sequence
    from segadeform.io.formats import sequence_start_frame

    frames = _scene(tmp_path)
    write_pc2(tmp_path / "s.pc2", frames, start_frame=10)
    f = np.array([[0, 1, 2], [1, 3, 2]])
    write_obj_sequence(tmp_path / "seq", f, frames, start=10)
    assert [sequence_start_frame(tmp_path / n) for n in ("g.pc2", "s.pc2", "seq")] == [0, 10, 10]
    import importlib.util

    from segadeform.io.formats import open_sequence_writer

    kept = [("s.xdmf", "xdmf", None), ("s.abc", "abc", "alembic"), ("s.usda", "usd", "pxr")]
    for name, fmt, module in kept:  # the formats that keep times, at a rate other than 30 fps
        if module is not None and importlib.util.find_spec(module) is None:
            continue  # (its extra is not installed)
        n = frames.shape[1]
        with open_sequence_writer(tmp_path / name, fmt, faces=f, num_points=n, fps=24.0, start_frame=10) as w:
            w.write(frames)
        assert sequence_start_frame(tmp_path / name) == 10, name
        with open_sequence_writer(tmp_path / f"1{name}", fmt, faces=f, num_points=n, fps=24.0, start_frame=7) as w:
            w.write(frames[:1])  # one frame: the rate is the file's, not the times'
        assert sequence_start_frame(tmp_path / f"1{name}") == 7, name

    def preview(result, rng):
        return CliRunner().invoke(
            cli,
            ["preview", str(tmp_path / result), "--garment", str(tmp_path / "g.obj"), "-o", str(tmp_path / "q.png")]
            + ["--frames", rng, "--size", "40x30"],
        )

    if (tmp_path / "s.abc").exists():  # `inspect` says an Alembic's rate and start, as a USD's (a user's trial)
        for name, want in (("s.abc", "24 fps, start frame 10"), ("1s.abc", "24 fps, start frame 7")):
            r = CliRunner().invoke(cli, ["inspect", str(tmp_path / name)])
            assert r.exit_code == 0 and want in r.output.splitlines()[0], r.output
    for result in ["s.pc2", "seq", "s.xdmf"] + (["s.abc"] if (tmp_path / "s.abc").exists() else []):
        r = preview(result, "0:2")
        assert r.exit_code == 1 and "outside the result's frames 10..13" in r.output, r.output
        r = preview(result, "11:13")
        assert r.exit_code == 0 and "2 frames rendered" in r.output, r.output


def test_a_png_strip_says_which_frames_it_keeps(tmp_path):
    """A user's trial: `preview ... -o x.png --every 12` over 120 frames rendered 10 frames, kept 8 in the strip and
    said "8 frames rendered": not every 12th frame, unsaid.  The strip's frames are chosen first and named."""
    frames = _scene(tmp_path, n_frames=20)
    write_pc2(tmp_path / "s.pc2", frames, start_frame=5)
    args = ["preview", str(tmp_path / "s.pc2"), "--garment", str(tmp_path / "g.obj"), "--size", "40x30"]
    r = CliRunner().invoke(cli, args + ["-o", str(tmp_path / "p.png"), "--every", "2"])
    assert r.exit_code == 0, r.output
    assert "8 of the 10 frames chosen rendered" in r.output and "frames 5, 7, 11, 13, 15, 17, 21, 23 ->" in r.output
    from matplotlib.image import imread

    assert imread(tmp_path / "p.png").shape[:2] == (30, 8 * 40)
    r = CliRunner().invoke(cli, args + ["-o", str(tmp_path / "p.gif"), "--every", "2"])
    assert r.exit_code == 0 and "10 frames rendered" in r.output, r.output
    r = CliRunner().invoke(cli, ["preview", "--help"])
    assert "at most 8 frames" in " ".join(r.output.split())


def test_inspect_pc2_bounds_nan_motion(tmp_path):
    _scene(tmp_path)
    r = CliRunner().invoke(cli, ["inspect", str(tmp_path / "g.pc2")])
    assert r.exit_code == 0, r.output
    assert "bounds [0.0, 0.0, 0.0] .. [1.0, 1.3" in r.output and "NaN/inf: none" in r.output
    assert "motion per frame: mean 100.00 mm" in r.output
    raw = bytearray((tmp_path / "g.pc2").read_bytes())  # the writer refuses NaN: patch one value in
    off = 32 + ((2 * 4) + 1) * 3 * 4
    raw[off : off + 4] = np.float32(np.nan).tobytes()
    (tmp_path / "n.pc2").write_bytes(bytes(raw))
    r = CliRunner().invoke(cli, ["inspect", str(tmp_path / "n.pc2")])
    assert r.exit_code == 1 and "1 non-finite values (NaN or inf), in 1 frames (2)" in r.output


def test_inspect_counts_what_of_a_garment_is_not_a_clean_surface(tmp_path):
    """A user's trial: `inspect` ("read and validate") said nothing of a duplicated face, a degenerate triangle, an
    isolated vertex or a non-manifold edge on a garment OBJ.  Each is counted on one informational line (exit 0)."""
    from segadeform.io import read_obj

    from ..conftest import SAMPLES

    clean = CliRunner().invoke(cli, ["inspect", str(SAMPLES / "garments" / "skirt.obj")])
    assert clean.exit_code == 0 and clean.output.splitlines()[1] == (
        "  no duplicated or degenerate faces, isolated vertices, non-manifold or misoriented edges, or coincident "
        "boundary vertices"
    ), clean.output
    g = read_obj(SAMPLES / "garments" / "skirt.obj")
    v, f = g.vertices, g.faces
    a, b, c = next(t for t in f.tolist() if ((f == t[0]).any(1) & (f == t[1]).any(1)).sum() == 2)  # a-b: inside
    # a reversed copy of a face; a flat triangle (a corner at its edge's middle); a vertex of no face; a third face on
    # its inner edge a-b
    v = np.concatenate([v, [(v[a] + v[b]) / 2, [5.0, 5.0, 5.0], [0.0, 3.0, 0.0]]])
    n = len(g.vertices)
    f = np.concatenate([f, [[c, b, a], [a, b, n], [a, b, n + 2]]])
    write_obj(tmp_path / "bad.obj", Mesh(vertices=v, faces=f))
    r = CliRunner().invoke(cli, ["inspect", str(tmp_path / "bad.obj")])
    assert r.exit_code == 0, r.output
    assert r.output.splitlines()[1] == (
        "  1 duplicated face, 1 degenerate triangle (flat or a repeated corner), 1 isolated vertex (in no face), "
        "1 non-manifold edge (in more than two faces)"
    ), r.output


def test_inspect_reads_the_inputs_run_and_garment_fit_take(tmp_path):
    """`inspect` refused CMU's .amc and .asf and MakeHuman's .mhclo ("unknown mesh file extension"), though `run`
    and `garment fit` read them."""
    from pathlib import Path

    from ..motion.asf_build import write_trial

    asf, amc = write_trial(tmp_path, n_frames=12)
    mhclo = Path(__file__).resolve().parents[2] / "samples" / "garments" / "makehuman" / "skirt_short_f.mhclo"
    out = {}
    for p in (amc, asf, mhclo):
        r = CliRunner().invoke(cli, ["inspect", str(p)])
        assert r.exit_code == 0, r.output
        out[p.suffix] = r.output
    assert "CMU AMC motion, 12 frames at 120 fps" in out[".amc"]
    assert "CMU ASF skeleton" in out[".asf"] and "bones" in out[".asf"]
    assert "MakeHuman binding 'skirt_short_f', 395 garment vertices" in out[".mhclo"]
    (tmp_path / "cut.amc").write_text(amc.read_text()[: len(amc.read_text()) // 2])
    r = CliRunner().invoke(cli, ["inspect", str(tmp_path / "cut.amc")])
    assert r.exit_code == 1 and "cut.amc" in r.output and "is it cut short?" in r.output, r.output


def test_preview_refuses_an_unknown_format_and_a_rate_that_is_not_one_before_rendering(tmp_path):
    """`preview -o x.obj` rendered every frame, then said "expected .gif or .mp4" (the default is .png);
    `--fps nan` reached the animation writer."""
    _scene(tmp_path)
    base = ["preview", str(tmp_path / "g.pc2"), "--garment", str(tmp_path / "g.obj"), "--size", "40x30"]
    r = CliRunner().invoke(cli, [*base, "-o", str(tmp_path / "x.obj")])
    assert r.exit_code == 1 and "expected .png, .gif or .mp4, got .obj" in r.output, r.output
    assert not (tmp_path / "x.obj").exists()
    for fps in ("nan", "0", "-5"):
        r = CliRunner().invoke(cli, [*base, "-o", str(tmp_path / "x.gif"), "--fps", fps])
        assert r.exit_code == 2 and "--fps must be a frame rate" in r.output, r.output
    assert not (tmp_path / "x.gif").exists()
    # a size with no pixels was a traceback (zero-size array), a huge one "out of memory" (a user's trial)
    for size in ("0x10", "-5x10", "99999x99999"):
        r = CliRunner().invoke(cli, [*base[:-1], size, "-o", str(tmp_path / "x.png")])
        assert r.exit_code == 2 and "each from 16 to 8192 pixels" in r.output and size in r.output, r.output
    assert not (tmp_path / "x.png").exists()
    r = CliRunner().invoke(cli, [*base, "-o", str(tmp_path / "x.gif"), "--fps", "12"])
    assert r.exit_code == 0 and (tmp_path / "x.gif").is_file(), r.output


def test_a_point_cache_of_no_frames_is_said_so(tmp_path):
    """A PC2 with a valid header and no frames: `inspect` was a traceback (a zero-size reduction), `preview` said
    "frame range 0:0 is outside the result's frames 0..-1" (a user's trial)."""
    _scene(tmp_path)
    import struct

    (tmp_path / "z.pc2").write_bytes(b"POINTCACHE2\0" + struct.pack("<iiffi", 1, 4, 0.0, 1.0, 0))
    r = CliRunner().invoke(cli, ["inspect", str(tmp_path / "z.pc2")])
    assert r.exit_code == 0 and r.output.splitlines()[-1] == "  no frames", r.output
    out = tmp_path / "z.png"
    args = ["preview", str(tmp_path / "z.pc2"), "--garment", str(tmp_path / "g.obj"), "-o", str(out)]
    r = CliRunner().invoke(cli, args)
    assert r.exit_code == 1 and "the result has no frames" in r.output and "z.pc2" in r.output, r.output
    assert not out.exists()


def test_preview_mp4_without_ffmpeg_is_refused_before_rendering(tmp_path, monkeypatch):
    """A user's trial: `preview -o x.mp4` on a machine without ffmpeg rendered every frame (6.8 s), then refused.
    Now the encoder is checked first: one line naming the output, exit 1, nothing rendered or written."""
    import shutil

    import segadeform.preview.render as render_module

    _scene(tmp_path)
    which = shutil.which
    monkeypatch.setattr(shutil, "which", lambda name, *a, **k: None if name == "ffmpeg" else which(name, *a, **k))
    rendered = []
    monkeypatch.setattr(render_module, "render", lambda *a, **k: rendered.append(1) or np.zeros((30, 40, 3), np.uint8))
    out = tmp_path / "x.mp4"
    r = CliRunner().invoke(
        cli, ["preview", str(tmp_path / "g.pc2"), "--garment", str(tmp_path / "g.obj"), "-o", str(out)]
    )
    assert not rendered and r.exit_code == 1 and r.output.count("\n") == 1, r.output
    assert f"{out}: writing .mp4 needs ffmpeg on PATH (expected" in r.output and "got no ffmpeg" in r.output, r.output
    assert not out.exists() and not (tmp_path / ".segadeform-outputs.json").exists()
    with pytest.raises(InputError, match="needs ffmpeg"):  # the writer refuses it too, before writing anything
        render_module.save_animation(out, [np.zeros((30, 40, 3), np.uint8)], 30.0)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["g.obj", "g.pc2"]


def test_preview_names_a_body_sequence_that_is_not_the_body(tmp_path):
    """A user's trial: a garment's cache given as --body said `face indices out of range (..., got (np.int64(0),
    np.int64(13717)))`, naming no file.  Now: the file, what it has and what the body needs."""
    _scene(tmp_path)
    (tmp_path / "h.pc2").write_bytes((tmp_path / "g.pc2").read_bytes())  # no OBJ beside it: the body model's faces
    r = CliRunner().invoke(
        cli,
        ["preview", str(tmp_path / "g.pc2"), "--garment", str(tmp_path / "g.obj"), "--body", str(tmp_path / "h.pc2")]
        + ["-o", str(tmp_path / "p.png")],
    )
    assert r.exit_code == 1 and not (tmp_path / "p.png").exists()
    line = r.output.strip().splitlines()[-1]
    assert line.startswith(f"Error: {tmp_path / 'h.pc2'}: the body sequence does not match its rest mesh"), line
    assert "expected 13718 vertices" in line and "got 4 vertices" in line and "np.int64" not in line


def test_inspect_reads_a_scene_bundle(tmp_path):
    """A user's trial: `inspect` read .sgda and .sgdm but not the bundle `segadeform bundle` writes."""
    from segadeform.io.sgdb import write_bundle

    meta = {"garment": "skirt.obj", "motion": "walk", "fps": 30.0, "start_frame": 10, "graph": "deformer_lbs"}
    meta["effects"] = {"skinning": "lbs", "dynamics": True, "wrinkles": False}
    write_bundle(tmp_path / "s.sgdb", {"rest": np.zeros((7, 3), np.float32), "poses": np.zeros((5, 72))}, meta)
    r = CliRunner().invoke(cli, ["inspect", str(tmp_path / "s.sgdb")])
    assert r.exit_code == 0, r.output
    assert "scene bundle, garment skirt.obj (7 vertices), motion walk (5 frames at 30.0 fps, from frame 10)" in r.output
    assert "effects lbs,dynamics" in r.output and "poses (5, 72) float64" in r.output


def test_preview_without_matplotlib_says_which_extra(tmp_path, monkeypatch):
    """A fresh clone's base install (`pip install -e .`) rendered the README's preview, then died in a traceback
    (`No module named 'matplotlib'`).  Now one line naming the extra, before any rendering, and no file."""
    import sys

    _scene(tmp_path)
    monkeypatch.setitem(sys.modules, "matplotlib", None)  # as if not installed: `import matplotlib` raises
    r = CliRunner().invoke(
        cli, ["preview", str(tmp_path / "g.pc2"), "--garment", str(tmp_path / "g.obj"), "-o", str(tmp_path / "p.png")]
    )
    assert r.exit_code == 1 and r.output.strip() == "Error: preview needs matplotlib: pip install 'segadeform[plot]'"
    assert not (tmp_path / "p.png").exists()


def test_inspect_tells_toml_files_apart(tmp_path):
    """`inspect` read every .toml as a scene: a dataset config failed with "unknown table [bodies]" (a docs audit).
    Dataset configs, training configs and jobs files are read by their own readers; a bad one still names itself."""
    from tests.conftest import REPO, SAMPLES

    def inspect(p):
        return CliRunner().invoke(cli, ["inspect", str(p)])

    r = inspect(SAMPLES / "datasets" / "tiny.toml")
    assert r.exit_code == 0, r.output
    assert "dataset config" in r.output and "2 garments x 1 bodies x 2 motions: 4 planned samples" in r.output
    assert "1 train" in r.output and "1 test," in r.output
    r = inspect(REPO / "samples" / "train" / "default.toml")
    assert r.exit_code == 0, r.output
    assert "training config" in r.output and "steps" in r.output
    jobs = tmp_path / "jobs.toml"
    jobs.write_text(
        f'[batch]\noutput = "out"\n[[garments]]\nmesh = "{SAMPLES / "garments" / "skirt.obj"}"\n'
        '[[motions]]\nkind = "walk"\nseconds = 0.3\n'
    )
    r = inspect(jobs)
    assert r.exit_code == 0, r.output
    assert "jobs file, 1 garments x 1 motions" in r.output
    r = inspect(SAMPLES / "scenes" / "dress_dance.toml")
    assert r.exit_code == 0 and "scene, garment dress.obj" in r.output, r.output
    bad = tmp_path / "bad.toml"
    bad.write_text((SAMPLES / "datasets" / "tiny.toml").read_text().replace('kind = "skirt"', 'kind = "skirtt"'))
    r = inspect(bad)
    assert r.exit_code == 1 and str(bad) in r.output and "skirtt" in r.output, r.output


def test_inspect_names_a_dataset_sample_not_a_motion(tmp_path):
    """A simulated sample's .npz (rest, faces, frames, poses, ...) was read as a motion ("motion, 30 frames at 30
    fps": a user's trial); it is named a dataset sample, with its record's split and kind."""
    from segadeform.dataset.store import Sample, save_sample

    v = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0]], float)
    s = Sample(
        id="g__b0__walk",
        rest=v,
        faces=np.array([[0, 1, 2]]),
        betas=np.zeros(0),
        poses=np.zeros((4, 72)),
        trans=np.zeros((4, 3)),
        frames=np.repeat(v[None], 4, axis=0).astype(np.float32),
        meta={"id": "g__b0__walk", "split": "train", "kind": "skirt", "status": "kept"},
    )
    save_sample(tmp_path, s)
    r = CliRunner().invoke(cli, ["inspect", str(tmp_path / "samples" / "g__b0__walk.npz")])
    assert r.exit_code == 0, r.output
    assert "dataset sample, 4 frames of 3 garment vertices (1 triangle); split train, kind skirt" in r.output
    assert "motion" not in r.output.split(";")[0]


def _whole_array_stats(frames):
    """What inspect computed before it streamed: the whole clip as float64 at once."""
    a = np.asarray(frames, np.float64)
    step = np.linalg.norm(np.diff(a, axis=0), axis=2)
    return {
        "far": np.abs(a).max(),
        "lo": a.reshape(-1, 3).min(0),
        "hi": a.reshape(-1, 3).max(0),
        "step_mean": step.mean(),
        "step_max": step.max(),
        "step_max_frame": int(np.unravel_index(step.argmax(), step.shape)[0]) + 1,
        "still": int((step.max(axis=1) == 0).sum()),
        "centroid_range": np.ptp(a.mean(axis=1), axis=0),
    }


def _long_cache(path, s, n=4, seed=0):
    """A long PC2 of few vertices (a random walk, a frame repeated, the largest step twice)."""
    rng = np.random.default_rng(seed)
    fr = np.cumsum(0.01 * rng.normal(size=(s, n, 3)), axis=0).astype(np.float32)
    fr[s // 3] = fr[s // 3 - 1]  # a frame identical to the one before
    fr[5], fr[6] = fr[4] + 1.0, fr[4]  # the largest step, at frame 5 and (back, as large) at 6: the first is named
    write_pc2(path, fr, start_frame=3)
    return fr


def test_inspect_streams_the_same_statistics_as_the_whole_array(tmp_path):
    """inspect's statistics are computed a chunk of frames at a time (a long cache was held whole, as float64, and
    its differences besides: 8x the file); they are the whole array's, whatever the chunk (the mean step to
    summation order), and so is what inspect prints."""
    from segadeform.cli.inspect_cmd import frame_stats
    from segadeform.io.pc2 import PC2Frames

    fr = _long_cache(tmp_path / "l.pc2", 301, n=6)
    want = _whole_array_stats(fr)
    pc = PC2Frames(tmp_path / "l.pc2")
    for chunk in (1, 3 * 6, 7 * 3 * 6, 300 * 3 * 6, None):  # at least a frame; one; 7; the file less one; default
        st = frame_stats(pc, max_values=chunk)
        assert (st.n_frames, st.n_points, st.nonfinite) == (301, 6, 0)
        for k in ("far", "lo", "hi", "step_max", "centroid_range"):
            np.testing.assert_array_equal(getattr(st, k), want[k], err_msg=f"{k} at chunk {chunk}")
        assert (st.step_max_frame, st.still) == (want["step_max_frame"], want["still"]) == (5, 1)
        assert st.step_mean == pytest.approx(want["step_mean"], rel=1e-12)
        from_array = frame_stats(fr, max_values=chunk)  # an array streams alike
        assert all(np.array_equal(getattr(from_array, k), v) for k, v in vars(st).items())
    r = CliRunner().invoke(cli, ["inspect", str(tmp_path / "l.pc2")])
    assert r.exit_code == 0, r.output
    assert f"bounds {np.round(want['lo'], 4).tolist()} .. {np.round(want['hi'], 4).tolist()} (all frames)" in r.output
    assert (
        f"motion per frame: mean {1e3 * want['step_mean']:.2f} mm, largest {1e3 * want['step_max']:.2f} mm (frame 8); "
        f"centroid travels {np.round(want['centroid_range'], 4).tolist()} m" in r.output
    )
    assert "1 frames identical to the one before" in r.output


def test_inspect_of_a_long_cache_reads_bounded_chunks_and_holds_no_more(tmp_path, monkeypatch):
    """The reader is asked for chunks of a bounded number of values, each frame once, and the memory inspect
    takes (tracemalloc's peak) is that of a few chunks, not of the clip: a cache of 60,000 frames peaks where one of
    600 does.  NaN/inf is still counted over the whole clip."""
    import tracemalloc

    from segadeform.cli import inspect_cmd
    from segadeform.io import sequence
    from segadeform.io.pc2 import PC2Frames

    monkeypatch.setattr(sequence, "CHUNK_VALUES", 3000)  # 250 frames of 4 vertices
    long_ = _long_cache(tmp_path / "long.pc2", 60_000)
    _long_cache(tmp_path / "short.pc2", 600)
    asked = []
    real = PC2Frames._read
    monkeypatch.setattr(PC2Frames, "_read", lambda self, idx: asked.append(list(idx)) or real(self, idx))
    r = CliRunner().invoke(cli, ["inspect", str(tmp_path / "long.pc2")])
    assert r.exit_code == 0 and "60000 samples x 4 points" in r.output, r.output
    assert max(len(a) for a in asked) == 250 and sorted(i for a in asked for i in a) == list(range(60_000))
    monkeypatch.setattr(PC2Frames, "_read", real)

    def peak(name):
        tracemalloc.start()
        try:
            inspect_cmd.frame_stats(PC2Frames(tmp_path / name))
            return tracemalloc.get_traced_memory()[1]
        finally:
            tracemalloc.stop()

    short, long_peak = peak("short.pc2"), peak("long.pc2")
    assert long_peak < 2 * short + 64_000, (short, long_peak)
    assert long_peak < long_.nbytes / 8, (long_peak, long_.nbytes)  # the whole clip as float32 is 2.9 MB
    raw = bytearray((tmp_path / "long.pc2").read_bytes())  # NaN in two far-apart frames: both counted
    for frame in (10, 59_990):
        off = 32 + frame * 4 * 12
        raw[off : off + 4] = np.float32(np.nan).tobytes()
    (tmp_path / "n.pc2").write_bytes(bytes(raw))
    r = CliRunner().invoke(cli, ["inspect", str(tmp_path / "n.pc2")])
    # named by the file's numbers: it starts at frame 3
    assert r.exit_code == 1 and "2 non-finite values (NaN or inf), in 2 frames (13, 59993)" in r.output, r.output


@pytest.mark.parametrize("fmt", ["pc2", "abc", "usd"])
def test_preview_reads_only_the_frames_it_draws(tmp_path, monkeypatch, fmt):
    """`preview CACHE --body BODY --frames 0:3` read both caches whole, as float64 (2.5 GB to draw 3 frames of a
    756 MB body; a user's trial).  Now the garment's and the body's frames drawn are read and no other: a PC2's by
    seeking to them, an Alembic's or a USD's time samples one by one.  A frame of NaN not drawn is not read."""
    import importlib.util

    if fmt != "pc2" and importlib.util.find_spec({"abc": "alembic3d", "usd": "pxr"}[fmt]) is None:
        pytest.skip(f"{fmt} needs its extra")
    from segadeform.io import open_sequence_writer
    from segadeform.io.alembic import AlembicFrames
    from segadeform.io.pc2 import PC2Frames
    from segadeform.io.usd import UsdFrames

    fr = _scene(tmp_path, n_frames=40)
    f = np.array([[0, 1, 2], [1, 3, 2]])
    ext = {"pc2": ".pc2", "abc": ".abc", "usd": ".usd"}[fmt]
    fr[30, 1] = np.nan  # not drawn
    body = fr + [0.0, 0.0, -0.1]
    for name, frames in (("r", fr), ("b", body)):
        w = open_sequence_writer(tmp_path / f"{name}{ext}", fmt, faces=f, num_points=4, start_frame=10)
        w._append(frames)  # the writers refuse NaN: written past the check
        w.num_samples = len(frames)
        w.close()
    write_obj(tmp_path / "b.obj", Mesh(vertices=body[0], faces=f))
    asked = []
    cls = {"pc2": PC2Frames, "abc": AlembicFrames, "usd": UsdFrames}[fmt]
    real = cls._read
    monkeypatch.setattr(cls, "_read", lambda self, idx: asked.append((self.path.stem, list(idx))) or real(self, idx))
    args = ["preview", str(tmp_path / f"r{ext}"), "--garment", str(tmp_path / "g.obj"), "--size", "40x30"]
    args += ["--body", str(tmp_path / f"b{ext}"), "-o", str(tmp_path / "p.png")]
    r = CliRunner().invoke(cli, args + ["--frames", "12:15"])
    assert r.exit_code == 0 and "3 frames rendered" in r.output, r.output
    assert sorted({i for _, idx in asked for i in idx}) == [2, 3, 4] and {n for n, _ in asked} == {"r", "b"}
    r = CliRunner().invoke(cli, args + ["--frames", "39:41"])
    assert r.exit_code == 1 and "frame 40 has a non-finite coordinate" in r.output and f"r{ext}" in r.output


def test_inspect_counts_a_seam_split_mesh_and_a_sequence_past_10_km_is_one_line(tmp_path):
    """A garment split along its UV seams (vertices duplicated on the boundary, no edge between) was "clean" to
    inspect (a new user's trial); a point cache past 10 km printed its summary line before the error."""
    from segadeform.io import read_obj, write_obj
    from segadeform.io.pc2 import PC2Writer

    from ..conftest import SAMPLES

    g = read_obj(SAMPLES / "garments" / "skirt.obj")
    v, f = np.asarray(g.vertices), np.asarray(g.faces).copy()
    # cut the skirt along the faces of one vertex of its hem: that vertex duplicated for half its faces
    hem = int(np.argmin(v[:, 1]))
    rows = np.flatnonzero((f == hem).any(1))[:1]
    f[rows] = np.where(f[rows] == hem, len(v), f[rows])
    write_obj(tmp_path / "seam.obj", type(g)(vertices=np.vstack([v, v[hem]]), faces=f))
    r = CliRunner().invoke(cli, ["inspect", str(tmp_path / "seam.obj")])
    assert r.exit_code == 0 and "1 coincident boundary vertex (at another's place" in r.output, r.output
    with PC2Writer(tmp_path / "far.pc2", 3) as w:
        w.write(np.full((2, 3, 3), 2e4, np.float32))
    r = CliRunner().invoke(cli, ["inspect", str(tmp_path / "far.pc2")])
    lines = [ln for ln in r.output.splitlines() if ln.strip()]
    assert r.exit_code == 1 and len(lines) == 1 and "beyond 10 km" in lines[0], r.output


def test_inspect_names_frames_by_the_files_own_numbers(tmp_path):
    """A cache a run wrote with --frames 10:40 starts at frame 10: inspect names its frames so (it counted from 0,
    so that a TD scrubbing to the frame it named found nothing there: a new user's trial), as preview does."""
    from segadeform.io.pc2 import PC2Writer

    x = np.zeros((6, 3, 3), np.float32)
    x[4:] += 0.05  # the largest step ends at the file's 5th frame
    with PC2Writer(tmp_path / "a.pc2", 3, start_frame=10.0) as w:
        w.write(x)
    r = CliRunner().invoke(cli, ["inspect", str(tmp_path / "a.pc2")])
    assert r.exit_code == 0 and "largest 86.60 mm (frame 14)" in r.output, r.output
    raw = bytearray((tmp_path / "a.pc2").read_bytes())
    raw[32 + 2 * 36 : 32 + 2 * 36 + 4] = np.float32(np.nan).tobytes()  # a NaN in the file's third frame
    (tmp_path / "b.pc2").write_bytes(bytes(raw))
    r = CliRunner().invoke(cli, ["inspect", str(tmp_path / "b.pc2")])
    assert r.exit_code == 1 and "in 1 frames (12)" in r.output, r.output


def test_preview_says_a_result_that_looks_written_in_centimetres_or_z_up(tmp_path):
    """A technical artist's trial: a centimetre, +Z-up point cache (run --output-units cm --up z; a PC2 records
    neither) was drawn lying on its back, 100 times too big, with no word.  Preview says what it looks like and the
    options that read it; with them, nothing is said."""
    from pathlib import Path

    from segadeform.io import read_mesh

    skirt = read_mesh(Path(__file__).resolve().parents[2] / "samples" / "garments" / "dress.obj")
    v = skirt.vertices
    z_up_cm = np.stack([v[:, 0], -v[:, 2], v[:, 1]], axis=1) * 100.0  # (x, y, z) -> (x, -z, y), in cm
    write_pc2(tmp_path / "d.pc2", np.stack([z_up_cm, z_up_cm]))
    write_obj(tmp_path / "d.obj", Mesh(v, skirt.faces))
    base = ["preview", str(tmp_path / "d.pc2"), "--garment", str(tmp_path / "d.obj"), "--size", "40x60"]
    r = CliRunner().invoke(cli, [*base, "-o", str(tmp_path / "a.png")])
    assert r.exit_code == 0, r.output
    assert "pass the same --output-units" in r.output and "pass --up z" in r.output, r.output
    r = CliRunner().invoke(cli, [*base, "--up", "z", "--output-units", "cm", "-o", str(tmp_path / "b.png")])
    assert r.exit_code == 0 and "warning" not in r.output, r.output
    # a belt alone (40 x 6 x 26 cm: flat top to bottom, metres, +Y up) is not taken for a +Z-up result (a review)
    a = np.linspace(0, 2 * np.pi, 24, endpoint=False)
    ring = np.array([[0.2 * np.cos(t), 1.0 + dy, 0.13 * np.sin(t)] for t in a for dy in (0.0, 0.06)])
    rf = [[2 * i, 2 * ((i + 1) % 24), 2 * i + 1] for i in range(24)]
    write_obj(tmp_path / "belt.obj", Mesh(ring, np.array(rf)))
    write_pc2(tmp_path / "belt.pc2", np.stack([ring, ring]))
    r = CliRunner().invoke(
        cli,
        [
            "preview",
            str(tmp_path / "belt.pc2"),
            "--garment",
            str(tmp_path / "belt.obj"),
            "--size",
            "40x60",
            "-o",
            str(tmp_path / "belt.png"),
        ],
    )
    assert r.exit_code == 0 and "warning" not in r.output, r.output
    write_pc2(tmp_path / "m.pc2", np.stack([v, v]))  # metres, +Y up: nothing said
    r = CliRunner().invoke(
        cli,
        [
            "preview",
            str(tmp_path / "m.pc2"),
            "--garment",
            str(tmp_path / "d.obj"),
            "--size",
            "40x60",
            "-o",
            str(tmp_path / "c.png"),
        ],
    )
    assert r.exit_code == 0 and "warning" not in r.output, r.output


def test_preview_refuses_a_point_beyond_10_km_as_inspect_does(tmp_path):
    """A fuzzer's trial: a point cache with one value at 3e38 was drawn by preview (a warning, exit 0) while inspect
    refuses it."""
    frames = _scene(tmp_path).copy()
    g = tmp_path / "g.obj"
    frames[2, 3, 0] = 3e38
    bad = tmp_path / "far.pc2"
    write_pc2(bad, frames)
    out = tmp_path / "far.png"
    r = CliRunner().invoke(cli, ["preview", str(bad), "--garment", str(g), "-o", str(out), "--size", "64x64"])
    assert r.exit_code == 1 and "far.pc2: frame 2 has a point beyond 10 km" in r.output and not out.exists(), r.output
    r = CliRunner().invoke(cli, ["inspect", str(bad)])
    assert r.exit_code == 1 and "beyond 10 km" in r.output
