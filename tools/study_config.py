"""What the simulator-study tools share: the continuum's config read, and TOML tables written back out.

A study config lives in ``samples/datasets/studies/``, one folder below the continuum, so its relative paths
(garment bindings, capture files) are rebased by one ``../``.
"""

from __future__ import annotations

import random
from pathlib import Path

import tomllib

CONFIG_DIR = Path(__file__).resolve().parents[1] / "samples" / "datasets"


def continuum() -> dict:
    """``samples/datasets/continuum.toml`` as a dict."""
    return tomllib.loads((CONFIG_DIR / "continuum.toml").read_text())


def training_captures(src: dict, n: int, seed: int) -> list[dict]:
    """``n`` motion-capture entries of the continuum's training split drawn at random (``random.Random(seed)``)."""
    capture = [m for m in src["motions"] if "file" in m and m.get("split", "train") == "train"]
    return random.Random(seed).sample(capture, n)


def _value(v) -> str:
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, str):
        return '"' + v.replace("\\", "\\\\").replace('"', '\\"') + '"'
    if isinstance(v, list):
        return "[" + ", ".join(_value(x) for x in v) + "]"
    return repr(v)


def table(name: str, d: dict, rebase=()) -> list[str]:
    """The lines of one TOML table (``[[garments]]`` for an array entry); the keys in ``rebase`` are paths
    relative to ``samples/datasets``, written relative to the study folder."""
    out = [f"[{name}]"]
    for k, v in d.items():
        if k in rebase:
            v = "../" + v
        out.append(f"{k} = {_value(v)}")
    return out + [""]


def head(src: dict, comment: list[str]) -> list[str]:
    """The comment, then the continuum's ``[dataset]`` (``order = "body-major"``: a motion's samples one after
    another, so any prefix of a run has every garment on the same motions), ``[quality]`` and ``[simulate]``."""
    lines = [f"# {c}" if c else "#" for c in comment] + [""]
    ds = {"fps": src["dataset"]["fps"], "seconds": src["dataset"]["seconds"], "order": "body-major"}
    return lines + table("dataset", ds) + table("quality", src["quality"]) + table("simulate", src["simulate"])
