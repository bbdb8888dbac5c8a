"""Write ``samples/datasets/studies/kinds.toml``: one garment of every kind on the same motion-capture clips.

    .venv/bin/python tools/kind_study.py > samples/datasets/studies/kinds.toml

Issue #27 asks the simulator to keep >= 70 % of the samples of every garment kind under CMU motion capture.  The
continuum cannot say that fairly: its kinds met different motions (the jumpsuit, a validation garment, only the
validation families, mostly fast runs) and its counts mix entries made before later fixes.  This study puts one
garment of each kind as the continuum makes it today (a procedural entry's first draw, ``count = 1``; the
validation and held-out designs without their split; the decimated MakeHuman shirt) on the default body and the
same ``N_MOTIONS`` motion-capture entries of the continuum's training families drawn at random (``SEED``), with the
continuum's simulation settings and gate; ``order = "body-major"``, so any prefix of a run has every kind on the
same clips.

    .venv/bin/python tools/kind_study.py --fallback quality=20,collision_quality=4 \
        > samples/datasets/studies/kinds_fallback.toml

writes the same study with ``[[fallback]]`` attempts (each ``--fallback`` one table, in order): run on a copy of a
finished ``data/kinds``, ``dataset make`` simulates only the rejected samples again, with the fallbacks.

    .venv/bin/python tools/kind_study.py --report data/kinds

counts a run of it (``dataset info``'s records, ``segadeform.dataset.report.finished_records``) over the clips every
garment has finished: kept / made (clips cut to their leading frames that pass counted as kept, as ``dataset info``
counts them) per garment and per kind of issue #27, and the gate's reasons.
"""

from __future__ import annotations

import argparse
import collections
import json
import sys
from pathlib import Path

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


def _entry(garment: str, entries) -> str | None:
    """The study entry a sample's garment was made from (a procedural entry's draw is ``NAME-0``)."""
    for name in (garment, garment.rsplit("-", 1)[0]):
        if name in entries:
            return name
    return None


def report(dataset: Path) -> None:
    from segadeform.dataset.report import finished_records

    kind_of = dict(GARMENTS)
    recs = [(r, _entry(r["garment"], kind_of)) for r in finished_records(dataset)]
    recs = [(r, e) for r, e in recs if e is not None]
    clips = collections.defaultdict(set)
    for r, e in recs:
        clips[(r["body"], r["motion"])].add(e)
    full = {c for c, got in clips.items() if len(got) == len(kind_of)}
    print(f"{len(full)} clips finished by all {len(kind_of)} garments")
    rows: dict = collections.defaultdict(lambda: [0, 0, collections.Counter()])
    for r, e in recs:
        if (r["body"], r["motion"]) not in full:
            continue
        for key in (("garment", e), ("kind", kind_of[e])):
            rows[key][0] += r["status"] == "kept"
            rows[key][1] += 1
            rows[key][2].update(x.split()[0].rstrip(":") for x in r.get("reasons", []))
    for level in ("garment", "kind"):
        print(f"{level:<22} kept / made     %  rejected for")
        for (lv, name), (k, n, why) in rows.items():
            if lv == level:
                reasons = ", ".join(f"{w} {c}" for w, c in why.most_common())
                print(f"{name:<22} {k:>4} / {n:<4} {100 * k / n:>5.0f}  {reasons}")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--report", type=Path, metavar="DATASET", help="count a run of the study instead of writing it")
    ap.add_argument(
        "--fallback",
        action="append",
        default=[],
        metavar="KEY=VALUE,..",
        help="a [[fallback]] table of the [simulate] keys it changes (repeatable: attempts in order)",
    )
    a = ap.parse_args()
    if a.report is not None:
        report(a.report)
        return
    src = continuum()
    by_name = {g["name"]: g for g in src["garments"] if "name" in g}
    fallbacks = [{k: json.loads(v) for k, v in (kv.split("=", 1) for kv in f.split(","))} for f in a.fallback]
    if fallbacks:
        what = [
            "Issue #27: the kind study (kinds.toml) with fallback attempts on the samples the gate rejects (written by",
            f"tools/kind_study.py {' '.join('--fallback ' + f for f in a.fallback)}; see its docstring).",
            "Run on a copy of a finished run of kinds.toml (or of an earlier fallback study), which only its rejected",
            "samples are simulated again in:",
            "  cp -a data/kinds data/kinds-fallback",
            "  segadeform dataset make samples/datasets/studies/THIS_FILE.toml -o data/kinds-fallback -j 2",
        ]
    else:
        what = [
            "Issue #27: one garment of every kind as the continuum makes it, on the same motion-capture clips of its",
            "training families (written by tools/kind_study.py; see its docstring).",
            "  segadeform dataset make samples/datasets/studies/kinds.toml -o data/kinds -j 2",
            "  segadeform dataset info data/kinds --by-garment",
        ]
    lines = head(src, what)
    for f in fallbacks:
        lines += table("[fallback]", f)
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
