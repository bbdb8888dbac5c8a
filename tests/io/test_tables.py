"""The one TOML table reader (:func:`segadeform.io.toml.read_table`) and the one file hash."""

from __future__ import annotations

import dataclasses
import hashlib
from pathlib import Path
from typing import Optional

import pytest

from segadeform.errors import FileFormatError
from segadeform.io.hashing import file_sha256
from segadeform.io.toml import key, read_table, toml_types


@dataclasses.dataclass(frozen=True)
class Table:
    name: str
    count: int = 1
    scale: float = key(1.0, range=(0.0, 10.0))
    flag: bool = False
    where: Path | None = None
    items: tuple = ()
    mode: str = key("a", choices=("a", "b"))
    units: str | None = key(None, types=(str, int, float))


def _err(table, **kw) -> str:
    with pytest.raises(FileFormatError) as e:
        read_table(table, Table, where="t", path=Path("cfg.toml"), **kw)
    return str(e.value)


def test_a_good_table_is_returned_as_read():
    t = {"name": "x", "count": 3, "scale": 2, "flag": True, "where": "a/b", "items": [1, 2], "mode": "b", "units": 0.01}
    assert read_table(t, Table, where="t") == t


@pytest.mark.parametrize(
    "table, words",
    [
        (
            {"name": "x", "extra": 1},
            ["unknown key t.extra", "expected count, flag, items, mode, name, scale, units, where", "got extra"],
        ),
        ({"count": 1}, ["missing t.name"]),
        ({"name": 3}, ["t.name has the wrong type", "expected str", "got int 3"]),
        ({"name": "x", "count": True}, ["t.count has the wrong type", "expected int", "got bool True"]),
        ({"name": "x", "count": 1.5}, ["t.count has the wrong type", "expected int", "got float 1.5"]),
        ({"name": "x", "scale": False}, ["t.scale has the wrong type", "expected int or float", "got bool False"]),
        ({"name": "x", "scale": 11}, ["t.scale out of range", "expected 0.0..10.0", "got 11"]),
        ({"name": "x", "scale": float("nan")}, ["t.scale out of range"]),
        ({"name": "x", "flag": 1}, ["t.flag has the wrong type", "expected bool", "got int 1"]),
        ({"name": "x", "items": "ab"}, ["t.items has the wrong type", "expected list"]),
        ({"name": "x", "where": 2}, ["t.where has the wrong type", "expected str"]),
        ({"name": "x", "mode": "c"}, ["t.mode must be one of a, b", "expected a | b", "got c"]),
        ({"name": "x", "units": True}, ["t.units has the wrong type", "expected str or int or float"]),
    ],
)
def test_each_rule_names_the_file_the_key_and_what_was_expected(table, words):
    msg = _err(table)
    assert msg.startswith("cfg.toml: ")
    for w in words:
        assert w in msg, (w, msg)


def test_not_a_table_and_skipped_fields():
    assert "[t] must be a table" in _err([1, 2])
    assert "unknown key t.count" in _err({"name": "x", "count": 2}, skip=("count",))


def test_types_of_annotations():
    assert toml_types(float) == (int, float) and toml_types(Optional[Path]) == (str,)  # noqa: UP045 (typing's spelling)
    assert toml_types(int | str) == (int, str)
    with pytest.raises(TypeError):
        toml_types(complex)


def test_file_sha256_streams_the_bytes(tmp_path):
    p = tmp_path / "f.bin"
    data = bytes(range(256)) * 9000  # > 2 chunks of 1 MiB
    p.write_bytes(data)
    assert file_sha256(p) == hashlib.sha256(data).hexdigest()
    (tmp_path / "e").write_bytes(b"")
    assert file_sha256(tmp_path / "e") == hashlib.sha256(b"").hexdigest()
    with pytest.raises(OSError):
        file_sha256(tmp_path / "missing")


def test_the_format_registry_knows_the_portable_and_garment_files(tmp_path):
    """.sgdb, .sgda, .sgdm and .mhclo are registered beside the sequence formats, and each entry's reader reads
    what its writer wrote."""
    import numpy as np

    from segadeform.io.formats import FILE_FORMATS, file_format_for

    assert {f.name for f in FILE_FORMATS.values()} >= {"sgdb", "sgda", "sgdm", "mhclo"}
    assert file_format_for("a/B.SGDM").name == "sgdm" and file_format_for("x.obj") is None
    fmt = file_format_for("t.sgdm")
    poses = np.zeros((3, 24, 3), np.float32)
    poses[:, 1, 0] = [0.1, 0.2, 0.3]
    fmt.write(tmp_path / "t.sgdm", poses, np.ones((3, 3)), fps=25.0, name="n", joint_names=[f"j{i}" for i in range(24)])
    p, t, fps, meta = fmt.read(tmp_path / "t.sgdm")
    assert np.array_equal(p, poses) and t.shape == (3, 3) and fps == 25.0 and meta["name"] == "n"
    b = file_format_for("t.sgdb")
    b.write(tmp_path / "t.sgdb", {"a": np.arange(5, dtype=np.int32)}, {"k": 1})
    arrays, meta = b.read(tmp_path / "t.sgdb")
    assert arrays["a"].tolist() == [0, 1, 2, 3, 4] and meta == {"k": 1}
    with pytest.raises(FileFormatError, match="not a motion file"):
        fmt.read(tmp_path / "t.sgdb")


def test_errors_name_the_line_of_the_key_or_table(tmp_path):
    """Scene and jobs-file errors named the file but no line, though errors promise FILE[:LINE]."""
    from segadeform.io.toml import key_line
    from segadeform.settings import load_scene

    p = tmp_path / "s.toml"
    p.write_text(
        '# a scene\n[garment]\nmesh = "g.obj"\n\n[motion]\nkind = "walk"\nseconds = 0.2\nspeeed = 2\n'
        '[output]\npath = "o.pc2"\n[[garments]]\nmesh = "a"\n[[garments]]  # the second\nmesh = "b"\n'
    )
    assert key_line(p, "motion") == 5 and key_line(p, "motion", "speeed") == 8
    assert key_line(p, "garments[1]") == 13 and key_line(p, "garments[1]", "mesh") == 14
    assert key_line(p, "motion", "nope") is None and key_line(p, "nope") is None
    assert key_line(tmp_path / "missing.toml", "motion") is None
    p.write_text(p.read_text().split("[[garments]]")[0])
    with pytest.raises(FileFormatError, match=r"s\.toml:8: unknown key motion\.speeed"):
        load_scene(p)
    p.write_text(p.read_text().replace("speeed = 2\n", "").replace("[output]", "[outputs]"))
    with pytest.raises(FileFormatError, match=r"s\.toml:8: unknown table \[outputs\]"):
        load_scene(p)
