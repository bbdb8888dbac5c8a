"""Statistics of a dataset folder from its log (what `segadeform dataset info` prints): kept and
rejected samples (and the kept ones cut to the frames that pass: ``[quality] min_frames``; those kept on a
``[[fallback]]`` attempt), rejection rates per
garment kind, garment and motion, reasons, seconds per frame by
size, and kept samples per hour of the runs that made it."""

from __future__ import annotations

import collections
import json
import re
from pathlib import Path

import numpy as np

from ..errors import FileFormatError

__all__ = ["dataset_stats", "finished_records", "reason_name"]


def finished_records(folder) -> list[dict]:
    """Every sample of a dataset folder's log once, as last finished (a re-run sample counts once; `dataset
    regate`'s verdict merged into the record of the sample it judged)."""
    p = Path(folder) / "log.jsonl"
    if not p.is_file():
        raise FileFormatError("not a dataset folder (no log.jsonl)", path=folder)
    last: dict = {}
    for line in p.read_text().splitlines():
        if line.strip():
            r = json.loads(line)
            if r.get("regated") and r["id"] in last:  # `dataset regate`'s verdict on a sample made before
                r = {**last[r["id"]], **r}
                r.pop("reasons" if r["status"] == "kept" else "trimmed", None)
            last[r["id"]] = r
    return list(last.values())


def pack_records(path) -> list[dict]:
    """The records of a dataset pack's samples, kept and rejected, from their metadata (a pack keeps no log: no
    timing of the runs that made it, and a rejected sample's reasons are its quality verdict's)."""
    from .pack import open_pack

    pack = open_pack(path)
    try:
        recs = []
        for folder in ("samples", "rejected"):
            for sid in pack.ids(folder):
                r = dict(pack.read_meta(sid))
                r.setdefault("status", "kept" if folder == "samples" else "rejected")
                r.setdefault("reasons", list((r.get("quality") or {}).get("reasons", [])))
                recs.append(r)
        return recs
    finally:
        pack.close()


def reason_name(reason: str) -> str:
    """What a gate's reason is about, without its numbers: ``"strain 1.87 > 1.0 on ..."`` -> ``"strain"``,
    ``"simulation failed: ..."`` -> ``"simulation failed"`` (``dataset info`` counts rejections by it)."""
    m = re.match(r"\s*([^\d:]*?)\s*(?:[:\d]|$)", reason)
    return (m.group(1) if m else "") or reason.split(" ")[0]


def dataset_stats(folder) -> dict:
    """Statistics of a dataset folder (its log), a dataset pack (its samples' metadata) or a folder of packs (all
    of theirs, as train and eval read such a folder: `dataset info` said "no log.jsonl" of it)."""
    f = Path(folder)
    packs = sorted(f.glob("*.sgdpack")) if f.is_dir() and not (f / "log.jsonl").is_file() else []
    if packs:
        recs = [r for p in packs for r in pack_records(p)]
    else:
        recs = pack_records(folder) if f.is_file() else finished_records(folder)
    kept = [r for r in recs if r["status"] == "kept"]
    rej = [r for r in recs if r["status"] != "kept"]
    reasons = collections.Counter(reason_name(x) for r in rej for x in r.get("reasons", []))
    by = collections.defaultdict(list)
    for r in recs:
        if "seconds_per_frame" in r:
            by[(r["garment"], r["vertices"])].append(r["seconds_per_frame"])

    def rates(key):
        groups = collections.defaultdict(lambda: [0, 0, 0, 0])
        for r in recs:
            groups[r.get(key)][0] += 1
            groups[r.get(key)][1] += r["status"] != "kept"
            groups[r.get(key)][2] += r["status"] == "kept" and "trimmed" in r
            groups[r.get(key)][3] += r["status"] == "kept" and r.get("attempt", 0) > 0
        return {
            str(k): {"samples": n, "rejected": b, "rejection_rate": b / n, "trimmed": c, "fallback": f}
            for k, (n, b, c, f) in sorted(groups.items())
        }

    for r in recs:  # what drove the body: motion capture (a file) or procedural motion, as the record says
        # (records written before it said: by name, the CMU clips named cmu-... being the captures)
        src = r.get("motion_source")
        r["source"] = (
            src
            if src in ("mocap", "procedural")
            else ("mocap" if str(r.get("motion", "")).startswith("cmu-") else "procedural")
        )
        r["kind_source"] = f"{r.get('kind')} / {r['source']}"
    return {
        "kept": len(kept),
        "trimmed": sum("trimmed" in r for r in kept),  # kept as the leading frames of a clip that failed later
        "fallback": sum(r.get("attempt", 0) > 0 for r in kept),  # kept on a [[fallback]] attempt
        "rejected": len(rej),
        "rejection_rate": len(rej) / max(len(recs), 1),
        "by_kind": rates("kind"),
        "by_garment": rates("garment"),
        "by_motion": rates("motion"),
        "by_source": rates("source"),
        "by_kind_source": rates("kind_source"),
        "throughput": _throughput(recs),
        "splits": dict(collections.Counter(r["split"] for r in kept)),
        "reasons": dict(reasons),
        "by_size": [
            {"garment": g, "vertices": v, "seconds_per_frame": float(np.mean(s)), "samples": len(s)}
            for (g, v), s in sorted(by.items(), key=lambda kv: kv[0][1])
        ],
    }


def _throughput(recs: list) -> dict:
    """Kept samples per hour of wall time, over the runs that logged their timing: a run's wall time
    is from its start to its last finished sample (several runs add up; gaps between runs do not)."""
    runs = collections.defaultdict(list)
    for r in recs:
        if "run_started" in r and "finished" in r:
            runs[r["run_started"]].append(r)
    wall = sum(max(x["finished"] for x in rs) - start for start, rs in runs.items())
    timed = [r for rs in runs.values() for r in rs]
    kept = sum(r["status"] == "kept" for r in timed)
    return {
        "runs": len(runs),
        "samples": len(timed),
        "kept": kept,
        "wall_hours": wall / 3600,
        "kept_per_hour": kept / (wall / 3600) if wall > 0 else None,
        "samples_per_hour": len(timed) / (wall / 3600) if wall > 0 else None,
    }
