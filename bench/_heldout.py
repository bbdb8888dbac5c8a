"""What the held-out cloth benches share (bench/cloth_strain.py, bench/cloth_holes.py): their sample arguments and
the body, dataset, cloth settings, sample ids and shipped-package predictor those arguments name."""

from __future__ import annotations

import argparse
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]


def add_sample_args(ap: argparse.ArgumentParser, types: str) -> None:
    """DATASET, ``--split``, ``--types`` (default ``types``), ``--sample`` (repeatable), ``--package``, ``--cloth``,
    ``-o``."""
    ap.add_argument("dataset", type=Path)
    ap.add_argument("--split", default="test")
    ap.add_argument("--types", default=types)
    ap.add_argument("--sample", action="append", default=[])
    ap.add_argument("--package", default=str(REPO / "samples" / "models" / "default"))
    ap.add_argument("--cloth", default="default")
    ap.add_argument("-o", "--output", type=Path)


def open_samples(a: argparse.Namespace):
    """``(body, dataset, cloth settings, sample ids, predictor)`` for parsed arguments ``a``: each ``--sample``, else
    every sample of ``--split`` whose garment type is one of ``--types``; the package as a predictor."""
    from segadeform.body import default_body_path, load_body
    from segadeform.dataset.roots import DatasetRoots
    from segadeform.runtime.predictor import PackagePredictor
    from segadeform.settings.cloth import ClothSettings
    from segadeform.train.predictors import make_predictor

    body = load_body(default_body_path())
    ds = DatasetRoots([a.dataset])
    settings = ClothSettings.parse("" if a.cloth == "default" else a.cloth)
    types = {t for t in a.types.split(",") if t}
    ids = a.sample or [i for i in ds.ids(a.split) if ds.load(i).meta.get("type") in types]
    return body, ds, settings, ids, make_predictor("shipped", a.package, package=PackagePredictor)


def refuse_existing_output(a: argparse.Namespace) -> None:
    """``SystemExit`` (one line, exit 1) when ``-o`` names a file that exists: a bench never overwrites a file."""
    if a.output is not None and a.output.exists():
        raise SystemExit(f"{a.output}: exists; give a new path")


def emit(text: str, output: Path | None) -> None:
    """Print the report and write it to ``output`` (a new file: :func:`refuse_existing_output` ran first)."""
    print(text)
    if output is not None:
        output.write_text(text)
