"""Write ``samples/datasets/studies/kinds.toml``: one garment of every kind on the same motion-capture clips.

    .venv/bin/python tools/kind_study.py > samples/datasets/studies/kinds.toml

Issue #27 asks the simulator to keep >= 70 % of the samples of every garment kind under CMU motion capture.  The
continuum cannot say that fairly: its kinds met different motions (the jumpsuit, a validation garment, only the
validation families, mostly fast runs) and its counts mix entries made before later fixes.  This study puts one
garment of each kind as the continuum makes it today (a procedural entry's first draw, ``count = 1``; the
validation and held-out designs without their split; the decimated MakeHuman shirt) on the default body and the
same ``N_MOTIONS`` motion-capture entries of the continuum's training families drawn at random (``SEED``), with the
continuum's simulation settings and gate; ``order = "body-major"``, so any prefix of a run has every kind on the
same clips.  ``segadeform dataset info DIR --by-garment`` counts it.
"""

from __future__ import annotations

import sys

from study_config import continuum, head, table, training_captures

GARMENTS = (  # (continuum entry, kind it stands for)
    ("dress", "dress"),
    ("sleeved-dress-test", "sleeved dress"),
    ("skirt", "skirt"),
    ("tshirt", "tops"),
    ("tank", "tops"),
    ("mh-tshirt-m-coarse", "tops"),
    ("jacket", "tops"),
    ("trousers-fit", "trousers"),
    ("shorts-fit", "trousers"),
    ("jumpsuit-val", "jumpsuit"),
)
N_MOTIONS = 12
SEED = 11


def main() -> None:
    src = continuum()
    by_name = {g["name"]: g for g in src["garments"] if "name" in g}
    lines = head(
        src,
        [
            "Issue #27: one garment of every kind as the continuum makes it, on the same motion-capture clips of its",
            "training families (written by tools/kind_study.py; see its docstring).",
            "  segadeform dataset make samples/datasets/studies/kinds.toml -o data/kinds -j 2",
            "  segadeform dataset info data/kinds --by-garment",
        ],
    )
    for name, _ in GARMENTS:
        g = dict(by_name[name])
        g.pop("split", None)
        if "count" in g:
            g["count"] = 1
        lines += table("[garments]", g, rebase=("mhclo",))
    lines += table("[bodies]", {"betas": []})
    for m in training_captures(src, N_MOTIONS, SEED):
        lines += table("[motions]", m, rebase=("file",))
    sys.stdout.write("\n".join(lines))


if __name__ == "__main__":
    main()
