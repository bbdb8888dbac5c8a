"""The evaluation's report: ``eval.json``, ``eval.md`` (:func:`markdown_table`) and the PNG plots, from what
:func:`segadeform.train.evaluate.evaluate` returns."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from ..body.model import BodyModel
from ..dataset.roots import as_roots
from ..io.atomic import atomic_path
from .data import sample_asset
from .metrics import METRICS
from .predictors import Predictor

__all__ = ["markdown_table", "write_report"]


_HEAD = {
    "vertex_cm": "vertex (cm)",
    "normal_deg": "normal (°)",
    "edge_mm": "edge (mm)",
    "low_cm": "low band (cm)",
    "mid_cm": "mid band (cm)",
    "high_cm": "high band (cm)",
    "penetration_pct": "penetrating (%)",
    "pinched_pct": "of which pinched (%)",
    "through_pct": "faces across a limb (%)",
    "jitter_mm": "jitter (mm/f²)",
    "ms_per_frame": "ms/frame",
    "max_strain_pct": "max stretch (%)",
    "p99_strain_pct": "p99 stretch (%)",
}
#: the per-type table's columns
_TYPE_COLS = (
    "vertex_cm",
    "normal_deg",
    "edge_mm",
    "penetration_pct",
    "pinched_pct",
    "through_pct",
    "max_strain_pct",
    "p99_strain_pct",
)


def markdown_table(res: dict) -> str:
    cols = METRICS + ("ms_per_frame",)
    lines = ["| model | " + " | ".join(_HEAD[k] for k in cols) + " |", "|---" * (len(cols) + 1) + "|"]
    for n, m in res["models"].items():
        lines.append(
            f"| {n} | " + " | ".join(f"{m[k]:.3f}" if k != "ms_per_frame" else f"{m[k]:.1f}" for k in cols) + " |"
        )
    out = ["\n".join(lines), "", "Per garment type (vertex error, cm):", ""]
    types = sorted({t for n in res["by_type"] for t in res["by_type"][n]})
    out.append("| model | " + " | ".join(types) + " |")
    out.append("|---" * (len(types) + 1) + "|")
    for n, bt in res["by_type"].items():
        out.append(f"| {n} | " + " | ".join(f"{bt[t]['vertex_cm']:.3f}" if t in bt else "-" for t in types) + " |")
    out += [
        "",
        "Per garment type, every metric:",
        "",
        "| type | model | " + " | ".join(_HEAD[k] for k in _TYPE_COLS) + " |",
        "|---" * (len(_TYPE_COLS) + 2) + "|",
    ]
    for t in types:
        for n, bt in res["by_type"].items():
            if t in bt:
                out.append(
                    f"| {t} | {n} | " + " | ".join(f"{bt[t][k]:.3f}" if k in bt[t] else "-" for k in _TYPE_COLS) + " |"
                )
    return "\n".join(out)


def _sample_table(res: dict) -> list[str]:
    """Each sample's vertex error (cm) per model, as eval.json's ``by_sample`` (a small set of one's own is read sample
    by sample: a researcher's trial); an older result without it gives nothing."""
    rows = res.get("by_sample") or {}
    if not rows:
        return []
    names = list(res["models"])
    out = ["Per sample (vertex error, cm):", "", "| sample | type | " + " | ".join(names) + " |"]
    out.append("|---" * (len(names) + 2) + "|")
    for sid, r in rows.items():
        v = r["vertex_cm"]
        out.append(f"| {sid} | {r['type']} | " + " | ".join(f"{v[n]:.3f}" if n in v else "-" for n in names) + " |")
    return [*out, ""]


def write_report(
    res: dict,
    out_dir: Path,
    *,
    dataset: Path | None = None,
    body: BodyModel | None = None,
    heatmap: Predictor | None = None,
) -> None:
    """Write ``eval.json``, ``eval.md`` and the PNG plots into ``out_dir``; with ``dataset``, ``body`` and a
    predictor ``heatmap`` (one of those evaluated), also its per-vertex error map."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    with atomic_path(out / "eval.json") as tmp:
        Path(tmp).write_text(json.dumps(res, indent=1))
    md = [
        f"# Evaluation on the '{res['split']}' split ({len(res['samples'])} samples)",
        "",
        "Each sample's metrics averaged over its frames and vertices, then the samples averaged with equal weight "
        "(max strain: the largest); penetrating: inside the posed body by its winding number, deeper than 2 mm.",
        "",
        markdown_table(res),
        "",
        *_sample_table(res),
    ]
    with atomic_path(out / "eval.md") as tmp:
        Path(tmp).write_text("\n".join(md))
    fig, ax = plt.subplots(figsize=(7, 4))
    for i, (n, v) in enumerate(res["per_frame"].items()):  # past 10 rows the colours repeat: the dashes tell them
        ax.plot(v, label=n, linestyle=("-", "--", ":", "-.")[i // 10 % 4])
    ax.set_xlabel("frame")
    ax.set_ylabel("mean vertex error (cm)")
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(out / "error_per_frame.png", dpi=80)
    plt.close(fig)
    fig, ax = plt.subplots(figsize=(7, 4))
    names = list(res["models"])
    w = 0.8 / len(names)
    for i, n in enumerate(names):
        ax.bar(np.arange(3) + i * w, [res["models"][n][k] for k in ("low_cm", "mid_cm", "high_cm")], w, label=n)
    ax.set_xticks(np.arange(3) + 0.4 - w / 2, ["low", "mid", "high"])
    ax.set_ylabel("band error (cm)")
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(out / "error_per_band.png", dpi=80)
    plt.close(fig)
    fig, ax = plt.subplots(figsize=(6, 4))
    for n, m in res["models"].items():
        ax.scatter(m["ms_per_frame"], m["vertex_cm"])
        ax.annotate(n, (m["ms_per_frame"], m["vertex_cm"]), fontsize=7)
    ax.set_xlabel("ms per frame (one thread, this machine)")
    ax.set_ylabel("mean vertex error (cm)")
    ax.set_title("what accuracy costs")
    fig.tight_layout()
    fig.savefig(out / "error_vs_cost.png", dpi=80)
    plt.close(fig)
    if dataset is not None and body is not None and heatmap is not None:
        _heatmap(res, dataset, body, heatmap, out / "error_map.png", res.get("n_star", 32))


def _heatmap(res, dataset, body, p: Predictor, path, n_star: int = 32):
    """Per-vertex error of one held-out frame, coloured on the simulated garment."""
    import matplotlib.pyplot as plt
    from mpl_toolkits.mplot3d.art3d import Poly3DCollection

    sid = res["samples"][0]
    dataset = as_roots(dataset)
    s = dataset.load(sid)
    name = p.name
    x = p.predict(s, body, sample_asset(dataset, s, body, n_star))
    t = len(x) // 2
    err = 100 * np.linalg.norm(x[t] - s.frames[t], axis=1)
    v = s.frames[t].astype(np.float64)
    fe = err[s.faces].mean(1)
    fig = plt.figure(figsize=(5, 6))
    ax = fig.add_subplot(projection="3d")
    cmap = plt.get_cmap("viridis")
    vmax = max(float(np.percentile(err, 99)), 1e-6)
    tri = v[s.faces][:, :, [0, 2, 1]]
    ax.add_collection3d(Poly3DCollection(tri, facecolors=cmap(np.clip(fe / vmax, 0, 1)), linewidth=0))
    c = v.mean(0)
    r = np.abs(v - c).max()
    ax.set_xlim(c[0] - r, c[0] + r)
    ax.set_ylim(c[2] - r, c[2] + r)
    ax.set_zlim(c[1] - r, c[1] + r)
    ax.view_init(10, -70)
    ax.axis("off")
    sm = plt.cm.ScalarMappable(cmap=cmap, norm=plt.Normalize(0, vmax))
    fig.colorbar(sm, ax=ax, shrink=0.6, label="vertex error (cm)")
    ax.set_title(f"{name}: {sid}, frame {t}", fontsize=8)
    fig.savefig(path, dpi=80)
    plt.close(fig)
