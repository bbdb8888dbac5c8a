"""Statistics of a dataset folder from its log (what `segadeform dataset info` prints)."""

from __future__ import annotations

import collections
import json
import re
from pathlib import Path

import numpy as np

from ..errors import FileFormatError

__all__ = ["dataset_stats"]


def dataset_stats(folder) -> dict:
    p = Path(folder) / "log.jsonl"
    if not p.is_file():
        raise FileFormatError("not a dataset folder (no log.jsonl)", path=folder)
    last = {}
    for line in p.read_text().splitlines():
        if line.strip():
            r = json.loads(line)
            last[r["id"]] = r  # a re-run sample counts once, as last finished
    recs = list(last.values())
    kept = [r for r in recs if r["status"] == "kept"]
    rej = [r for r in recs if r["status"] != "kept"]
    reasons = collections.Counter(re.sub(r"[\d.]+", "#", x).split(" > ")[0] for r in rej for x in r.get("reasons", []))
    by = collections.defaultdict(list)
    for r in recs:
        if "seconds_per_frame" in r:
            by[(r["garment"], r["vertices"])].append(r["seconds_per_frame"])
    return {"kept": len(kept), "rejected": len(rej), "rejection_rate": len(rej) / max(len(recs), 1),
            "splits": dict(collections.Counter(r["split"] for r in kept)), "reasons": dict(reasons),
            "by_size": [{"garment": g, "vertices": v, "seconds_per_frame": float(np.mean(s)), "samples": len(s)}
                        for (g, v), s in sorted(by.items(), key=lambda kv: kv[0][1])]}
