import struct

import numpy as np
import pytest

from segadeform.errors import FileFormatError, InputError
from segadeform.io import PC2Writer, read_pc2, read_pc2_header, write_pc2
from segadeform.io.pc2 import PC2_HEADER, PC2_MAGIC
from tests.conftest import leftovers


def frames(s=4, n=7, seed=0):
    return np.random.default_rng(seed).normal(size=(s, n, 3)).astype(np.float32)


def test_header_layout_is_the_documented_one(tmp_path):
    a = frames()
    write_pc2(tmp_path / "a.pc2", a, start_frame=3.0, sample_rate=1.0)
    raw = (tmp_path / "a.pc2").read_bytes()
    assert raw[:12] == b"POINTCACHE2\0"
    assert struct.unpack("<i", raw[12:16])[0] == 1
    assert struct.unpack("<i", raw[16:20])[0] == 7
    assert struct.unpack("<f", raw[20:24])[0] == 3.0
    assert struct.unpack("<f", raw[24:28])[0] == 1.0
    assert struct.unpack("<i", raw[28:32])[0] == 4
    assert len(raw) == 32 + 4 * 7 * 12
    np.testing.assert_array_equal(np.frombuffer(raw[32:], "<f4").reshape(4, 7, 3), a)


def test_round_trip_memmapped(tmp_path):
    a = frames()
    write_pc2(tmp_path / "a.pc2", a)
    pc = read_pc2(tmp_path / "a.pc2")
    assert isinstance(pc.frames, np.memmap)
    np.testing.assert_array_equal(pc.frames, a)
    assert pc.header.num_samples == 4 and pc.header.num_points == 7
    np.testing.assert_array_equal(read_pc2(tmp_path / "a.pc2", mmap=False).frames, a)


def test_streaming_writer_appends_and_patches_count(tmp_path):
    a = frames(10)
    with PC2Writer(tmp_path / "s.pc2", 7, start_frame=1.0) as w:
        w.write(a[:3])
        w.write(a[3])  # single frame (N, 3)
        w.write(a[4:])
        assert not (tmp_path / "s.pc2").exists()  # published only on close
    pc = read_pc2(tmp_path / "s.pc2")
    assert pc.header.num_samples == 10 and pc.header.start_frame == 1.0
    np.testing.assert_array_equal(pc.frames, a)
    assert leftovers(tmp_path) == []


def test_failure_inside_writer_leaves_nothing(tmp_path):
    with pytest.raises(RuntimeError):
        with PC2Writer(tmp_path / "f.pc2", 7) as w:
            w.write(frames(2))
            raise RuntimeError("boom")
    assert list(tmp_path.iterdir()) == []


def test_writer_rejects_bad_frames(tmp_path):
    with PC2Writer(tmp_path / "f.pc2", 7) as w:
        with pytest.raises(InputError, match="wrong shape"):
            w.write(np.zeros((2, 6, 3)))
        bad = frames(1)
        bad[0, 0, 0] = np.nan
        with pytest.raises(InputError, match="NaN"):
            w.write(bad)
        w.write(frames(1))
    assert read_pc2(tmp_path / "f.pc2").header.num_samples == 1


def header(magic=PC2_MAGIC, version=1, n=7, start=0.0, rate=1.0, s=2):
    return PC2_HEADER.pack(magic, version, n, start, rate, s)


@pytest.mark.parametrize(
    "raw, words",
    [
        (b"", "too short"),
        (b"POINTCACHE2\0" + b"\0" * 8, "too short"),
        (header(magic=b"POINTCACHE3\0") + b"\0" * 168, "bad magic"),
        (header(version=2) + b"\0" * 168, "version"),
        (header(n=0, s=0), "numPoints"),
        (header(n=-5), "numPoints"),
        (header(s=-1), "numSamples"),
        (header(rate=0.0) + b"\0" * 168, "sampleRate"),
        (header(start=float("nan")) + b"\0" * 168, "startFrame"),
        (header() + b"\0" * 100, "size does not match"),  # truncated data
        (header() + b"\0" * 200, "size does not match"),  # trailing bytes
        (header(n=2**31 - 1, s=2**31 - 1), "size does not match"),  # huge declared size
    ],
)
def test_malformed_pc2(tmp_path, raw, words):
    p = tmp_path / "bad.pc2"
    p.write_bytes(raw)
    with pytest.raises(FileFormatError, match=words) as ei:
        read_pc2(p)
    assert str(p) in str(ei.value)


def test_nonfinite_samples_found_when_asked(tmp_path):
    a = frames(5)
    a[3, 2, 1] = np.inf
    p = tmp_path / "x.pc2"
    p.write_bytes(header(s=5) + a.astype("<f4").tobytes())
    read_pc2(p)  # memory-mapped, not scanned
    with pytest.raises(FileFormatError, match="sample 3"):
        read_pc2(p, check_finite=True)


def test_point_count_must_match_mesh(tmp_path):
    write_pc2(tmp_path / "a.pc2", frames())
    with pytest.raises(FileFormatError, match="point count"):
        read_pc2(tmp_path / "a.pc2", num_points=8)


def test_zero_samples_is_valid(tmp_path):
    with PC2Writer(tmp_path / "e.pc2", 3):
        pass
    assert read_pc2_header(tmp_path / "e.pc2").num_samples == 0
    assert read_pc2(tmp_path / "e.pc2").frames.shape == (0, 3, 3)


def test_outputs_respect_the_umask(tmp_path):
    import os
    import stat

    from segadeform.io import atomic_open

    old = os.umask(0o022)
    try:
        write_pc2(tmp_path / "a.pc2", frames())
        with atomic_open(tmp_path / "b.txt", "w") as fh:
            fh.write("x")
    finally:
        os.umask(old)
    for name in ("a.pc2", "b.txt"):
        assert stat.S_IMODE((tmp_path / name).stat().st_mode) == 0o644


def test_pc2_frames_read_only_the_frames_asked_for_as_float32(tmp_path, monkeypatch):
    """PC2Frames seeks to the frames indexed (one read per run of consecutive frames) and gives them as the file
    holds them, float32: a frame or a range of a long cache is not the whole cache, nor the whole cache as
    float64 (`inspect` and `preview` of a 756 MB cache held 6.2 and 2.5 GB; a user's trial)."""
    from segadeform.io.pc2 import PC2Frames
    from segadeform.io.sequence import frame_chunks

    a = frames(s=50, n=5)
    write_pc2(tmp_path / "a.pc2", a, start_frame=4)
    pc = PC2Frames(tmp_path / "a.pc2")
    assert (len(pc), pc.shape, pc.dtype, pc.header.start_frame) == (50, (50, 5, 3), np.float32, 4.0)
    reads = []
    real = PC2Frames._read

    def spy(self, idx):
        reads.append(list(idx))
        return real(self, idx)

    monkeypatch.setattr(PC2Frames, "_read", spy)
    one = pc[3]
    assert one.dtype == np.float32 and one.shape == (5, 3)
    np.testing.assert_array_equal(one, a[3])
    np.testing.assert_array_equal(pc[-1], a[-1])
    np.testing.assert_array_equal(pc[10:14], a[10:14])
    np.testing.assert_array_equal(pc[[7, 8, 30]], a[[7, 8, 30]])
    np.testing.assert_array_equal(pc[40:46:2], a[40:46:2])
    assert pc[5:5].shape == (0, 5, 3)
    assert reads == [[3], [49], [10, 11, 12, 13], [7, 8, 30], [40, 42, 44]]
    reads.clear()
    blocks = list(frame_chunks(pc, max_values=4 * 5 * 3))  # 4 frames a chunk
    assert [len(r) for r in reads] == [4] * 12 + [2] and all(b.dtype == np.float32 for _, b in blocks)
    np.testing.assert_array_equal(np.concatenate([b for _, b in blocks]), a)
    monkeypatch.undo()
    np.testing.assert_array_equal(np.asarray(pc), a)  # the whole clip when asked for
    with pytest.raises(InputError, match="frame index out of range"):
        pc[50]
    with pytest.raises(FileFormatError, match="point count does not match"):
        PC2Frames(tmp_path / "a.pc2", num_points=6)


def test_pc2_frames_name_a_file_cut_short_after_it_was_opened(tmp_path):
    from segadeform.io.pc2 import PC2Frames

    write_pc2(tmp_path / "a.pc2", frames(s=6, n=5))
    pc = PC2Frames(tmp_path / "a.pc2")
    raw = (tmp_path / "a.pc2").read_bytes()
    (tmp_path / "a.pc2").write_bytes(raw[: 32 + 4 * 5 * 12 + 7])
    np.testing.assert_array_equal(pc[1], frames(s=6, n=5)[1])
    with pytest.raises(FileFormatError, match="ends inside frame 4") as ei:
        pc[3:6]
    assert "a.pc2" in str(ei.value)
