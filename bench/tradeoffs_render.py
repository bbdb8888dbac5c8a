"""What ``bench/tradeoffs.py`` writes from :mod:`bench.tradeoffs_measure`'s results: the Pareto frontier
(:func:`frontier`) and the docs (:func:`write_docs`: ``accuracy-vs-time.md``, ``.json``, ``.png``/``.svg``).
Nothing here measures; ``bench/tradeoffs.py --redraw`` calls :func:`write_docs` on a recorded JSON alone.

Importable (``from bench import tradeoffs_render`` from the repository root).
"""

from __future__ import annotations

import json
import os
import platform
import subprocess
from pathlib import Path

import numpy as np

from .tradeoffs_measure import _mm, effects_key

__all__ = ["frontier", "write_docs"]

REPO = Path(__file__).resolve().parents[1]


def frontier(points: dict[str, tuple[float, float]]) -> list[str]:
    """Names of the points (ms, error) no other point beats on both (ties kept), fastest first."""
    out = []
    for n, (t, e) in points.items():
        if not any((t2 <= t and e2 <= e) and (t2 < t or e2 < e) for m, (t2, e2) in points.items() if m != n):
            out.append(n)
    return sorted(out, key=lambda n: points[n][0])


def _training_note(rows: dict) -> str:
    """' Training took: NAME N s, ...' from each model row's run folder (``train.json`` beside its package)."""
    done = []
    for n, r in rows.items():
        if r["knob"] != "model":
            continue
        tj = Path(r["spec"]).parent / "train.json"
        if tj.is_file():
            d = json.loads(tj.read_text())
            done.append(f"{n} {d['train_seconds']:.0f} s")
    return f" Training took (one thread, other work on the machine): {', '.join(done)}." if done else ""


def _fmt(k, v):
    return f"{v:.1f}" if k.startswith("ms_per_frame") or k == "setup_ms" else f"{v:.3f}"


def write_docs(
    res: dict,
    out: Path,
    *,
    command: str,
    seconds: float,
    threads_all: int,
    load: tuple,
    presets: dict,
    sim: dict | None,
    sim_error: str,
    split: str,
    dataset: Path,
    git: str | None = None,
) -> list[str]:
    """The markdown, JSON and plots; returns the markdown lines."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from segadeform.settings.presets import QUALITY_PRESETS

    rows = res["rows"]
    pts1 = {n: (m["ms_per_frame"], m["vertex_cm"]) for n, m in rows.items()}
    ptsn = {n: (m["ms_per_frame_all"], m["vertex_cm"]) for n, m in rows.items()}
    front, front_n = frontier(pts1), frontier(ptsn)
    metrics = res["metrics"]
    cols = list(metrics) + ["ms_per_frame", "ms_per_frame_all", "setup_ms"]
    head = (
        ["knob", "setting"]
        + [c if c != "ms_per_frame_all" else f"ms_per_frame_{threads_all}t" for c in cols]
        + ["frontier"]
    )
    lines = ["| " + " | ".join(head) + " |", "|---" * len(head) + "|"]
    for n, m in sorted(rows.items(), key=lambda kv: kv[1]["ms_per_frame"]):
        mark = "yes" if n in front else ""
        if n in front_n:
            mark += (", " if mark else "") + f"{threads_all}t"
        lines.append(f"| {m['knob']} | {n} | " + " | ".join(_fmt(k, m[k]) for k in cols) + f" | {mark} |")
    if git is None:
        git = subprocess.run(
            ["git", "rev-parse", "--short", "HEAD"], cwd=REPO, capture_output=True, text=True
        ).stdout.strip()
        dirty = subprocess.run(
            ["git", "status", "--porcelain"], cwd=REPO, capture_output=True, text=True
        ).stdout.strip()
        git += " (with uncommitted changes)" if dirty else ""
    ptab = [
        "| preset | effects | push-out | row | vertex_cm | penetration_pct | ms/frame (1 thread) | fps (1 thread) "
        f"| ms/frame ({threads_all} threads) | fps ({threads_all} threads) |",
        "|---" * 10 + "|",
    ]
    for name, rn in presets.items():
        p, m = QUALITY_PRESETS[name], rows[rn]
        e = p.effects
        ptab.append(
            f"| {name} | {effects_key(e) + ('+cloth' if e.cloth else '')} | "
            f"{_mm(e.collision_margin) if e.collisions or e.cloth else 'off'} | {rn} | "
            f"{m['vertex_cm']:.3f} | {m['penetration_pct']:.3f} | {m['ms_per_frame']:.1f} | "
            f"{1e3 / m['ms_per_frame']:.0f} | {m['ms_per_frame_all']:.1f} | "
            f"{1e3 / m['ms_per_frame_all']:.0f} |"
        )
    n_samples = len(res["samples"])
    md = [
        f"# Accuracy against time ({split} split of `{dataset.name}`, {n_samples} samples)",
        "",
        f"Made by `{command}` at {git}; {seconds:.0f} s "
        f"({seconds / 60:.1f} min) on {platform.processor() or platform.machine()} with {os.cpu_count()} "
        f"CPU cores; load average {load[0]:.2f} at the start and {load[1]:.2f} at the end (other work shared "
        "the machine when it is above ~0: the times are this run's, the ratios between rows hold better "
        "than the absolute values).",
        "",
    ]
    if n_samples < 10:
        md += [
            f"**This run is small, and says so**: {n_samples} samples of the {split} split "
            f"({', '.join(f'`{s}`' for s in res['samples'])}); the errors are exact for them, the times are one "
            "run's: read differences under ~1 ms/frame as ties.",
            "",
        ]
    md += [
        "What changed from one run of this table to the next, and why, is in "
        "[accuracy-vs-time-history.md](accuracy-vs-time-history.md).",
        "",
        "Errors are against the Blender simulation stored in the dataset; units: vertex and band errors cm, "
        "normal degrees, edge mm, penetration % of vertices deeper than 2 mm inside the body (by the body's "
        "winding number), `pinched_pct` the part of that % pinched where the posed body intersects itself (an "
        "arm pressed into the torso: outside the skin nearest them), `through_pct` % of "
        "faces across a limb (the centre more than 5 mm inside the body while no corner penetrates: a render "
        "shows a hole), the strain columns the stretch of edges over their rest length (the largest over every "
        "edge and frame, and the 99th percentile), jitter mm/frame². "
        f"`ms_per_frame` is one onnxruntime thread, `ms_per_frame_{threads_all}t` {threads_all} threads "
        "(best of the repeats): the deformer calls and the collision push-out (the runtime's BodyCollider, "
        "frames in batches of 8), not the once-per-garment `setup_ms` (precompute and encoder) nor writing. "
        "LBS is numpy (both columns are one timing); LBS is the body's skinning weights moved to the "
        "garment, no learned part.",
        "",
        f"The dataset is `{dataset}` (its plan: `{dataset}/config.toml`, made by `segadeform dataset make`); "
        f"its {split} split is what the models never trained on (garment kinds, motion families and a body "
        "shape held out by the plan).",
        "",
        "\n".join(lines),
        "",
        f"Pareto frontier at one thread (fastest first): {', '.join(front)}.",
        "",
        f"Pareto frontier at {threads_all} threads: {', '.join(front_n)}.",
        "",
        "## Presets",
        "",
        "`segadeform run --quality fast|balanced|best` (`src/segadeform/settings/presets.py`) picks these rows; "
        "`--effects=+name/-name` changes a preset, a complete `--effects` list with `--quality` is an error. "
        "Frames per second are 1000 / ms per frame (deformer and push-out; setup and writing excluded).",
        "",
        "\n".join(ptab),
        "",
    ]
    for name, p in QUALITY_PRESETS.items():
        md.append(f"* **{name}**: {p.why}.")
    md += [
        "",
        "## The knobs",
        "",
        "How to set each: `effects`, the push-out margin, the cloth knobs, `threads`, `batch` and the presets "
        "are `segadeform run` options (`--effects`, `--collision-margin`, `--cloth KEY=VALUE`, `--threads`, "
        "`--batch`, `--quality`); precision is the package (`segadeform quantize PACKAGE -o PKG8 --precision int8` "
        "or `fp16-weights`, then `run --model PKG8`); **K and N\\*** are the garment's precompute (`segadeform "
        "precompute GARMENT.obj -o G.sgda --k 4` or `--n-star`, then `run --garment G.sgda`); **garment "
        "resolution** is `run --resolution R`, a scene's `[model] resolution` or a jobs file's `batch.resolution` "
        "(the share of the vertices the model runs on: the garment decimated with `segadeform.body.resample`, its "
        "frames carried back to every vertex of the file by a `SurfaceMap`, as the bench's rows do; collisions, the "
        "cloth stage and the outputs stay at full resolution; decimation alone -- the 4x row, subdivided, is the "
        "bench's).  Node, the browser and C++ take it from the garment asset: `segadeform garment export GARMENT "
        '--resolution R` (docs/package.md, "A decimated model garment").',
        "",
        "* **threads**: every row at one thread and at all of this machine's threads; the predictions agree "
        "(largest difference over rows: "
        f"{max(v.get('threads_max_diff_mm', 0.0) for s in res['per_sample'].values() for v in s.values()):.2g}"
        " mm).",
        "* **batch**: frames per deformer call; the same prediction (checked to 1e-5 m; its errors are "
        "those of `all effects`), only the time differs.",
        "* **K**: neighbours kept per vertex in the garment graph (the nearest by rest edge length). The "
        "models were trained with K = the garment's largest valence capped at 16, which is 8 on these "
        "garments (`all effects`); K = 12 adds only padding.",
        "* **N\\***: descriptor samples; the eigenvalues at N* are rescaled to the model's 32 "
        "(`rescale_descriptor`). N* changes only `setup_ms` (one geodesic solve per sample), not ms/frame.",
        "* **garment resolution**: each garment decimated (shortest-edge collapse) or subdivided (midpoint), "
        "the model run there and its frames carried to the full-resolution vertices (barycentric "
        "place on the nearest triangle plus the rest offset along its normal: `body/resample.py`); "
        "errors on the full-resolution garment, ms/frame including the carry, setup including the resampling.",
        "* **collisions**: the push-out at the margin named, on the row named.",
        "* **cloth**: the runtime's cloth stage (`segadeform run --effects=+cloth --cloth ...`: stretch limit, "
        "contact with neighbours following, inertia and gravity, attachment to the network's frame; "
        "`src/segadeform/body/_cloth.c`) on the row named, contact at 4 mm unless the row names another margin "
        "(`run --collision-margin`), its knobs at their defaults but the one named (every knob `run --cloth` "
        "takes: `iterations`, sweeps per frame; `stiffness`, of the stretch limit; `stretch`, `compress`, "
        "`bending`, `damping`, `follow`, `gravity`, `attachment`, `max_distance`, `reset`, `backstop`: "
        "`segadeform run --help`); ms/frame includes its per-garment setup spread over the sample's frames.",
        "* **not in the table**: `run --body-backend graph|numpy` (the body's posing: the same frames to float32 "
        "rounding, at the body's cost, not the garment's: `bench/effects.py`) and `run --providers` "
        "(onnxruntime's execution providers: the CPU's is measured here; CUDA in `bench/gpu.py` where a GPU is).",
        "* **models**: variants of the package's recipe in width, depth, heads or window T (the setting "
        "column, read from each package's manifest), each trained on the training split of the same dataset "
        "with the same steps and seed (`segadeform train CONFIG -o runs/NAME --dataset DATASET --threads 1`, "
        "then `segadeform export runs/NAME/model.pt -o runs/NAME/pkg`), or an ensemble of trained networks "
        "(`segadeform ensemble A.pt B.pt -o E.pt`, then `segadeform export`: the mean of their frames at the "
        "sum of their costs)."
        + (
            _training_note(rows)
            if any(r["knob"] == "model" for r in rows.values())
            else " None in this run (`--model NAME=SPEC` adds them; none were trained on this model's data here)."
        ),
        "",
    ]
    if sim is not None:
        md += [
            "## The simulator's quality axis",
            "",
            f"Sample `{sim['sample']}` made again by Blender (the dataset config's settings, its garment "
            f"files and the motion with its simulated lead) at cloth quality (steps per frame) "
            f"{', '.join(q for q, r in sim['qualities'].items() if not r.get('reference'))} and at "
            f"{sim['reference_quality']}, the reference; {sim['seconds']:.0f} s of this run. Seconds per frame "
            "are Blender's own (pre-roll frames included, its own threads); errors are the mean (max) vertex "
            "distance to the reference over the sample's frames. The learned rows are the same run's "
            "predictions of this sample against the same reference (every row is in the JSON); "
            "speed-up = Blender's s/frame at the "
            "quality named / the model's.",
            "",
            "| simulator | s/frame | vertex_cm vs reference | max_cm |",
            "|---|---|---|---|",
        ]
        for q, r in sim["qualities"].items():
            md.append(
                f"| Blender quality {q}{' (reference)' if r.get('reference') else ''} | "
                f"{r['s_per_frame']:.3f} | {r['vertex_cm']:.3f} | {r['max_cm']:.2f} |"
            )
        dq = str(sim.get("dataset_quality", ""))
        md += [
            "",
            f"| learned | ms/frame (1 thread) | vertex_cm vs reference | max_cm | speed-up vs quality {dq} "
            f"(1 thread) | speed-up vs quality {dq} ({threads_all} threads) | speed-up vs reference (1 thread) |",
            "|---|---|---|---|---|---|---|",
        ]
        shown = {"lbs": "lbs", "all effects": "all effects"}
        shown.update({rn: f"{name} ({rn})" for name, rn in presets.items()})
        shown = {n: label for n, label in shown.items() if n in sim["learned"]}
        for n, label in shown.items():
            r = sim["learned"][n]
            md.append(
                f"| {label} | {r['ms_per_frame']:.1f} | {r['vertex_cm']:.3f} | {r['max_cm']:.2f} | "
                f"{r['speedup'].get(dq, float('nan')):.0f}x | {r['speedup_all'].get(dq, float('nan')):.0f}x | "
                f"{r['speedup'][str(sim['reference_quality'])]:.0f}x |"
            )
        md += [
            "",
            f"The dataset's stored frames (quality {dq}) are {sim['stored_vs_reference_cm']:.3f} cm from the "
            "reference; a re-run at each quality is this far from the stored frames (cm; 0 at the dataset's "
            "quality when Blender repeats itself exactly): "
            + ", ".join(f"quality {q}: {v:.3f}" for q, v in sim["stored_vs_rerun_cm"].items())
            + ".",
            "",
        ]
    elif sim_error:
        md += ["## The simulator's quality axis", "", f"Not measured in this run: {sim_error}.", ""]
    md += ["![error against time](accuracy-vs-time.png)", ""]
    out.mkdir(parents=True, exist_ok=True)
    from segadeform.io.atomic import atomic_path

    with atomic_path(out / "accuracy-vs-time.md") as tmp:
        Path(tmp).write_text("\n".join(md))
    data = {
        "rows": rows,
        "metrics": metrics,
        "frontier": front,
        f"frontier_{threads_all}t": front_n,
        "presets": presets,
        "samples": res["samples"],
        "per_sample": res["per_sample"],
        "simulator": sim,
        "seconds": seconds,
        "threads_all": threads_all,
        "load_average": list(load),
        "command": command,
        "git": git,
        "simulator_error": sim_error,
    }
    with atomic_path(out / "accuracy-vs-time.json") as tmp:
        Path(tmp).write_text(json.dumps(data, indent=1, default=float))
    fig, axes = plt.subplots(
        1,
        2 if sim else 1,
        figsize=(14 if sim else 8, 6),
        squeeze=False,
        gridspec_kw={"width_ratios": [3, 2]} if sim else None,
    )
    ax = axes[0, 0]
    # rows far above the rest (more than 1.5x LBS's error) sit on the top edge, named, so the rest can be read
    errs = sorted(e for _, e in pts1.values())
    cap = max(1.5 * rows["lbs"]["vertex_cm"], errs[0] * 1.3) if "lbs" in rows else errs[-1] * 1.05
    top = min(cap, errs[-1] * 1.02)
    clip = lambda e: min(e, top)  # noqa: E731
    knobs = sorted({m["knob"] for m in rows.values()})
    for i, k in enumerate(knobs):
        names = [n for n, m in rows.items() if m["knob"] == k]
        c = f"C{i % 10}"
        ax.scatter([pts1[n][0] for n in names], [clip(pts1[n][1]) for n in names], color=c, label=k, s=18)
        ax.scatter(
            [ptsn[n][0] for n in names], [clip(ptsn[n][1]) for n in names], facecolors="none", edgecolors=c, s=18
        )
        for n in names:
            ax.plot([pts1[n][0], ptsn[n][0]], [clip(pts1[n][1]), clip(ptsn[n][1])], color=c, lw=0.4)
    named = set(front) | {"lbs", "all effects"} | {n for n, m in rows.items() if m["knob"] in ("model",)}
    off = 0
    for n, (t, e) in pts1.items():
        if e > top:
            off += 1
            right = t > np.sqrt(min(x for x, _ in pts1.values()) * max(x for x, _ in pts1.values()))
            ax.annotate(
                f"{n}: {e:.2f} cm (off scale)",
                (t, top),
                xytext=(-3 if right else 3, -4 - 7 * off),
                textcoords="offset points",
                fontsize=5,
                ha="right" if right else "left",
            )
        elif n in named:
            ax.annotate(n, (t, e), fontsize=6)
    ax.plot([pts1[n][0] for n in front], [pts1[n][1] for n in front], "k--", lw=0.8, label="frontier (1 thread)")
    for i, (name, rn) in enumerate(presets.items()):
        ax.annotate(
            name,
            (pts1[rn][0], clip(pts1[rn][1])),
            xytext=(-10 + 14 * i, -12 - 9 * (i % 2)),
            textcoords="offset points",
            fontsize=8,
            weight="bold",
        )
    ax.set_xscale("log")
    ax.set_ylim(min(errs) - 0.1, top + 0.1)
    ax.set_xlabel(f"ms per frame (filled: 1 thread, hollow: {threads_all} threads)")
    ax.set_ylabel("mean vertex error (cm) vs the simulation")
    ax.set_title(
        f"{split} split of {dataset.name}, {n_samples} samples (every row in the table; frontier, "
        "presets and models named)",
        fontsize=9,
    )
    ax.legend(fontsize=7, loc="center right")
    if sim:
        ax = axes[0, 1]
        qs = [(q, r) for q, r in sim["qualities"].items()]
        ax.plot([1e3 * r["s_per_frame"] for _, r in qs], [r["vertex_cm"] for _, r in qs], "o-", label="Blender")
        for q, r in qs:
            ax.annotate(f"q{q}", (1e3 * r["s_per_frame"], r["vertex_cm"]), fontsize=7)
        for n in shown:
            r = sim["learned"][n]
            ax.scatter([r["ms_per_frame"]], [r["vertex_cm"]], marker="s", s=18)
            ax.annotate(
                shown[n].split(" (")[0],
                (r["ms_per_frame"], r["vertex_cm"]),
                xytext=(3, 3),
                textcoords="offset points",
                fontsize=7,
            )
        ax.set_xscale("log")
        ax.set_xlabel("ms per frame (Blender: its own threads; learned: 1 thread)")
        ax.set_ylabel(f"mean vertex distance (cm) to Blender quality {sim['reference_quality']}")
        ax.set_title(f"simulator quality: {sim['sample']}", fontsize=9)
    fig.tight_layout()
    fig.savefig(out / "accuracy-vs-time.png", dpi=90)
    fig.savefig(out / "accuracy-vs-time.svg")
    plt.close(fig)
    return md
