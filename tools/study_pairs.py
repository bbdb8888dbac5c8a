"""Kept / made of a simulator study's two arms, paired by garment and motion, with an exact sign test.

    .venv/bin/python tools/study_pairs.py DATASET [--suffix -coarse]

A study config (``samples/datasets/studies/``) makes every garment entry twice, as it is (``NAME``) and changed
(``NAME<suffix>``), on the same bodies and motions.  This reads the dataset's ``log.jsonl`` as ``dataset info`` does
(``segadeform.dataset.report.finished_records``) and prints, over the (garment, body, motion) pairs made in
both arms: how many each arm kept, the pairs kept by one arm only, the two-sided exact sign test on those
(the chance of a split at least that uneven if the change did nothing), per garment, and the gate's reasons per arm.
"""

from __future__ import annotations

import argparse
import collections
from math import comb
from pathlib import Path

from segadeform.dataset.report import reason_name


def sign_test(a: int, b: int) -> float:
    """Two-sided exact sign test of a against b discordant pairs."""
    m = a + b
    if m == 0:
        return 1.0
    return min(1.0, 2 * sum(comb(m, k) for k in range(min(a, b) + 1)) / 2**m)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("dataset", type=Path)
    ap.add_argument("--suffix", default="-coarse", help="what the changed arm's entry names end with")
    a = ap.parse_args()
    from segadeform.dataset.report import finished_records

    arms: dict = collections.defaultdict(dict)
    reasons: dict = collections.defaultdict(collections.Counter)
    for r in finished_records(a.dataset):
        changed = r["garment"].endswith(a.suffix)
        base = r["garment"][: -len(a.suffix)] if changed else r["garment"]
        arm = "changed" if changed else "plain"
        arms[(base, r.get("body"), r["motion"])][arm] = r["status"] == "kept"
        for x in r.get("reasons", []) if r["status"] != "kept" else []:
            reasons[arm][reason_name(x)] += 1
    per: dict = collections.defaultdict(collections.Counter)
    for (base, _, _), d in arms.items():
        if len(d) == 2:
            per[base][(d["plain"], d["changed"])] += 1
            per["(all)"][(d["plain"], d["changed"])] += 1
    print(
        f"{'garment':28s} {'pairs':>5s} {'plain kept':>10s} {'changed kept':>12s} {'only plain':>10s} "
        f"{'only changed':>12s} {'sign test p':>11s}"
    )
    for base, c in sorted(per.items(), key=lambda kv: (kv[0] == "(all)", kv[0])):
        n, op, oc = sum(c.values()), c[(True, False)], c[(False, True)]
        kp, kc = c[(True, True)] + op, c[(True, True)] + oc
        print(f"{base:28s} {n:5d} {kp:10d} {kc:12d} {op:10d} {oc:12d} {sign_test(op, oc):11.3f}")
    for arm in ("plain", "changed"):
        print(f"rejections ({arm}): " + ", ".join(f"{k} {v}" for k, v in sorted(reasons[arm].items())))


if __name__ == "__main__":
    main()
