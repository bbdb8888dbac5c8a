"""Write ``samples/datasets/studies/mh_shirts.toml``: the MakeHuman shirts as they are and decimated, paired.

    .venv/bin/python tools/mh_shirt_study.py > samples/datasets/studies/mh_shirts.toml

Issue #27's ninth simulator study (``docs/simulator-gate.md``): the three MakeHuman shirts of the continuum's
training split, each as the continuum makes it and as a ``-coarse`` entry (``decimate = 0.85``: its shortest
edges, the narrow hem rows, collapsed first), on the default body and ``N_MOTIONS`` motion-capture entries of the
continuum's training families drawn at random (``SEED``).  The simulation settings and the gate are the
continuum's, copied from ``samples/datasets/continuum.toml``.  ``order = "body-major"`` makes every motion's six
samples one after another, so any prefix of a run is paired: both arms on the same motions.
"""

from __future__ import annotations

import sys

from study_config import continuum, head, table, training_captures

SHIRTS = ("mh-tshirt-m", "mh-tshirt-long-m", "mh-shirt-striped-m")
DECIMATE = 0.85
N_MOTIONS = 24
SEED = 7


def main() -> None:
    src = continuum()
    by_name = {g["name"]: g for g in src["garments"] if "name" in g}
    motions = training_captures(src, N_MOTIONS, SEED)
    lines = head(
        src,
        [
            "Issue #27's ninth simulator study: the MakeHuman shirts as the continuum makes them and decimated to 85 %",
            "of their vertices, paired on the same motions (written by tools/mh_shirt_study.py; see its docstring).",
            "  segadeform dataset make samples/datasets/studies/mh_shirts.toml -o data/mh-shirts -j 1",
        ],
    )
    for name in SHIRTS:
        for coarse in (False, True):
            g = dict(by_name[name])
            g.pop("split", None)
            if coarse:
                g["name"] = name + "-coarse"
                g["decimate"] = DECIMATE
            lines += table("[garments]", g, rebase=("mhclo",))
    lines += table("[bodies]", {"betas": []})
    for m in motions:
        lines += table("[motions]", m, rebase=("file",))
    sys.stdout.write("\n".join(lines))


if __name__ == "__main__":
    main()
