"""Write the motion-capture entries of ``samples/datasets/continuum.toml`` from the shared mocap folders.

    .venv/bin/python tools/continuum_motions.py > /tmp/motions.toml

Every CMU clip in ``../shared/data/mocap`` (BVH in ``cmu/`` and ``cmu_more/``, ASF/AMC in ``cmu_asf_amc/``)
gets one ``[[motions]]`` entry with a *family* (what the splits hold out whole) from its CMU description:
walk, run, obstacle run, jump, everyday actions, exercise, ballet, basketball, martial arts, salsa and
Indian dance.  Held out for the report (``test``): jumps and salsa; for choosing the model (``val``):
obstacle runs and Indian dance.  Of a held-out family only a few clips are simulated (``HELD_CLIPS``): the
family stays unseen either way, and the held-out split stays small enough to simulate first.

Left out: the BVH copies of trials that are here as ASF/AMC too (02_01, 16_15, 16_31, 16_36), cartwheels,
acrobatics on ropes and the motorcycle (the body upside down or seated: no garment hangs as it does on a
standing body).  Long captures get several clips (``start`` a range, ``count``); short ones one clip.

The output is the ``[[motions]]`` part of the config; the rest of the config is written by hand.
"""

from __future__ import annotations

import re
import sys
from pathlib import Path

MOCAP = Path(__file__).resolve().parents[2] / "shared" / "data" / "mocap"
CONFIG_DIR = Path(__file__).resolve().parents[1] / "samples" / "datasets"
REL = "../../../shared/data/mocap"  # the mocap folder as the config (samples/datasets) names it

TEST_FAMILIES = ("jump", "salsa")
#: duck-run and reach were added when the simulator rejected all 11 first val samples of obstacle-run and
#: indian-dance (too fast for it); the families keep their clips so that no sample made before changes split
VAL_FAMILIES = ("obstacle-run", "indian-dance", "duck-run", "reach")
#: clips simulated per held-out family (picked in a fixed order)
HELD_CLIPS = {
    "jump": ["16_01", "49_02"],
    "salsa": ["60_03"],
    "obstacle-run": ["127_25"],
    "indian-dance": ["94_06"],
    "duck-run": ["127_29"],
    "reach": ["14_07"],
}
SKIP = {
    "02_01_walk",
    "16_15_walk",
    "16_31_walk",
    "16_36_run_jog",  # here as ASF/AMC too
    "49_06",
    "49_07",
    "49_08",
    "49_21",
    "127_01",
}  # cartwheels, ropes, motorcycle


def family(trial: str, text: str) -> str:
    """The family of CMU trial ``trial`` (``"16_01"``) from its description (CMU's words or the file name)."""
    t = text.lower()
    subject = trial.split("_")[0]
    if subject in ("60", "61"):
        return "salsa"
    if subject == "94":
        return "indian-dance"
    if subject == "05" or (subject == "49" and ("dance" in t or "balance" in t)):
        return "ballet"
    if subject == "06":
        return "basketball"
    if subject in ("135", "10") or "kick" in t or "karate" in t or "boxing" in t or "sword" in t or "punch" in t:
        return "martial"
    if "duck" in t:
        return "duck-run"
    if "reach" in t:
        return "reach"
    if re.search(r"jump over|run over|dive over|jump stop", t):
        return "obstacle-run"
    if re.search(r"jumping jacks|squat|stretch|range of motion", t):
        return "exercise"
    if "jump" in t or "hop" in t or ("leap" in t and "run" not in t):
        return "jump"
    if re.search(r"\brun|jog", t):
        return "run"
    if "walk" in t or "navigate" in t:
        return "walk"
    if re.search(r"wash|mop|drink|bottle|laugh", t):
        return "everyday"
    raise ValueError(f"no family for {trial}: {text}")


def _bvh_clips():
    for folder in ("cmu", "cmu_more"):
        for p in sorted((MOCAP / folder).glob("*.bvh")):
            trial = "_".join(p.stem.split("_")[:2])
            if p.stem in SKIP:
                continue
            yield trial, p.stem.replace("_", " "), f"{REL}/{folder}/{p.name}", None


def _amc_clips():
    manifest = (MOCAP / "cmu_asf_amc" / "MANIFEST.md").read_text()
    for m in re.finditer(r"^\| (\d+)/(\d+_\d+)\.amc \| [^|]+ \| ([^|]+) \| [^|]+ \| (\d+) \|", manifest, re.M):
        subject, trial, text, frames = m.group(1), m.group(2), m.group(3).strip(), int(m.group(4))
        if trial in SKIP:
            continue
        yield trial, text, f"{REL}/cmu_asf_amc/{subject}/{trial}.amc", frames / 120.0


def _bvh_seconds(path: Path) -> float:
    text = path.read_text(errors="replace")
    n = int(re.search(r"Frames:\s*(\d+)", text).group(1))
    ft = float(re.search(r"Frame Time:\s*([0-9.eE+-]+)", text).group(1))
    return n * ft


def entries():
    out = []
    for trial, text, rel, seconds in [*_bvh_clips(), *_amc_clips()]:
        fam = family(trial, text)
        split = "test" if fam in TEST_FAMILIES else "val" if fam in VAL_FAMILIES else "train"
        if split != "train" and trial not in HELD_CLIPS[fam]:
            continue
        if seconds is None:
            seconds = _bvh_seconds((CONFIG_DIR / rel).resolve())
        # clips of 2 s after a 1 s lead; a capture of S seconds gets about one clip per 8 s, at most 4
        usable = seconds - 3.0
        count = 1 if usable < 8.0 or split != "train" else min(4, int(usable // 8.0) + 1)
        out.append(
            {
                "name": f"cmu-{trial}",
                "file": rel,
                "family": fam,
                "split": split,
                "start": 1.0 if seconds >= 3.2 else max(0.0, seconds - 2.2) / 2,
                "count": count,
                "last_start": max(1.0, seconds - 2.2),
            }
        )
    return out


def main() -> int:
    lines = []
    for e in entries():
        lines += ["[[motions]]", f'name = "{e["name"]}"', f'file = "{e["file"]}"', f'family = "{e["family"]}"']
        if e["count"] > 1:
            lines += [f"count = {e['count']}", f"start = [1.0, {e['last_start']:.1f}]"]
        else:
            lines.append(f"start = {e['start']:.2f}")
        if e["split"] != "train":
            lines.append(f'split = "{e["split"]}"')
        lines.append("")
    sys.stdout.write("\n".join(lines))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
