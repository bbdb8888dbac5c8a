"""``segadeform train``: deterministic, resumable training with a loss log and curves.

Run folder::

    RUN/config.toml        the config (copied) and RUN/train.json (resolved config, hardware, timings)
    RUN/last.pt            {config, state_dict, optimizer, step, rng} -- resumed from when present
    RUN/best.pt            the checkpoint with the lowest vertex error on the validation split so far
    RUN/model.pt           {config, state_dict, body, ...}: the best on the validation split when the config
                           names one (``data.val_split``), else the final step; ``body`` (in train.json and
                           last.pt too) is the body it was trained on (``body_label``: file name and sha256)
    RUN/cache/             garment precomputes and contacts when no dataset folder is writable
    RUN/loss.csv           step, total and every term (one row per logged step)
    RUN/loss.png           the curves

``optim.garments`` garments (samples) per step, ``optim.frames`` random frames of each, their losses
averaged into one batch; samples and frames come from a seeded generator whose state is checkpointed,
so a resumed run continues the same sequence.  Samples come from the config's dataset roots (folders
and read-only packs, :class:`~segadeform.dataset.roots.DatasetRoots`).
"""

from __future__ import annotations

import csv
import dataclasses
import functools
import hashlib
import json
import logging
import os
import platform
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np
import torch

from ..body.model import BodyModel
from ..body.transfer import RESIDUAL_EPS
from ..dataset.mirror import body_asymmetry
from ..errors import InputError
from ..io.atomic import atomic_path
from ..model.network import SEGANet
from . import losses as L
from .config import TrainConfig, config_copy
from .data import TrainItem, load_items

__all__ = ["train", "step_losses", "TERMS", "pick_device", "plot_losses"]

log = logging.getLogger(__name__)

TERMS = ("vertex", "normal", "edge", "stretch", "shear", "gravity", "collision", "skin_prior")
#: logged beside TERMS: the self-supervised cloth energy of a pair never simulated (weighted already)
PHYSICS_TERM = "physics"
#: the most (m) a body's rest joints may be from their twins' mirror images for ``data.mirror`` (the default body:
#: 6.3 mm, its collar joints; 6.8 mm at betas of +-2; its vertices 0.06 mm on average)
MIRROR_TOLERANCE = 0.01


def config_changes(old: dict | None, new: dict, *, most: int = 4) -> str:
    """The settings that differ between two :meth:`TrainConfig.to_dict` (``"optim.seconds 120 -> 0"``, at most
    ``most``); empty when ``old`` is unknown (a run saved before it was recorded) or nothing differs there."""
    if not isinstance(old, dict):
        return ""

    def flat(d, pre=""):
        out = {}
        for k, v in d.items():
            out.update(flat(v, f"{pre}{k}.") if isinstance(v, dict) else {f"{pre}{k}": v})
        return out

    a, b = flat(old), flat(new)
    diff = [f"{k} {a.get(k)!r} -> {b.get(k)!r}" for k in sorted(set(a) | set(b)) if a.get(k) != b.get(k)]
    return ", ".join(diff[:most]) + (f" and {len(diff) - most} more" if len(diff) > most else "")


def _init_state(path: Path, m, body: BodyModel) -> dict:
    """The state dict of checkpoint ``path`` (``optim.init``), which must be a model of config ``m`` (every field
    but the ensemble's size) trained on ``body`` when it records one."""
    from ..body.identity import body_text, other_body
    from ..model.config import ModelConfig

    try:
        ck = torch.load(path, map_location="cpu", weights_only=True)
    except FileNotFoundError:
        raise InputError("optim.init: no such file", path=path) from None
    except Exception as e:
        raise InputError(
            "optim.init: not a model checkpoint", path=path, expected="a run's model.pt", got=type(e).__name__
        ) from None
    if not isinstance(ck, dict) or "state_dict" not in ck or "config" not in ck:
        raise InputError("optim.init: not a model checkpoint", path=path, expected="a run's model.pt (config, weights)")
    theirs, mine = dataclasses.asdict(ModelConfig.from_dict(ck["config"])), dataclasses.asdict(m)
    differ = [f"model.{k} {theirs[k]!r} -> {mine[k]!r}" for k in mine if k != "ensemble" and theirs.get(k) != mine[k]]
    if differ or theirs.get("ensemble", 1) != 1:
        raise InputError(
            "optim.init: the checkpoint is a model of another [model] config than this run's",
            path=path,
            expected="the checkpoint's [model] (its train.json; the shipped model's is "
            "samples/train/continuum/light_prior_seed1.toml)",
            got=", ".join(differ[:4]) + (f" and {len(differ) - 4} more" if len(differ) > 4 else "")
            or "an ensemble (fine-tune one of its networks)",
        )
    mine_body = other_body(ck.get("body"), body)
    if mine_body is not None:
        raise InputError(
            "optim.init: the checkpoint was trained on another body than this run's",
            path=path,
            expected=body_text(ck["body"]),
            got=body_text(mine_body),
        )
    return ck["state_dict"]


def pick_device(name: str) -> torch.device:
    if name == "auto":
        return torch.device("cuda" if torch.cuda.is_available() else "cpu")
    if name == "cuda" and not torch.cuda.is_available():
        raise InputError("optim.device is 'cuda' but no CUDA device is available")
    return torch.device(name)


def _history(model: SEGANet, history_in: torch.Tensor, rows: torch.Tensor) -> torch.Tensor | None:
    """The model's motion history at ``rows`` of ``history_in (L, 3 S + 3)`` (None without one): the recurrence
    runs from the first row to the last one asked for."""
    if model.hist is None:
        return None
    return model.history_states(history_in[None, : int(rows.max()) + 1])[0, rows]


def step_losses(
    model: SEGANet, item: TrainItem, t: torch.Tensor, w, *, prior_scale: float = 1.0, terms_scale: float = 1.0
) -> dict:
    """Every loss term for frames ``t (B,)`` of ``item``; returns {term: tensor} and 'total'.

    ``prior_scale`` multiplies the skinning-weight prior's weight (the trainer fades it out), ``terms_scale`` every
    other term's but the vertex error's (``loss.terms_from``: 0 before that fraction of the steps)."""
    b = len(t)
    lw = torch.log(item.body_weights + RESIDUAL_EPS) if model.residual else None
    hist = _history(model, item.history_in, item.lead + t)
    verts, weights, _ = model(
        item.features,
        item.nbr,
        item.mask,
        item.descriptor,
        item.betas.expand(b, -1),
        item.windows[t],
        item.skin_rest,
        item.joints[None].expand(b, -1, -1),
        item.trans[t],
        lw,
        hist,
    )
    y = item.frames[t]
    out = {
        "vertex": L.vertex_loss(verts, y),
        "normal": L.normal_loss(verts, y, item.faces),
        "edge": L.edge_loss(verts, y, item.edges),
        "stretch": L.stretch_loss(verts, item.rest, item.edges),
        "shear": L.shear_loss(verts, item.rest, item.faces),
        "gravity": L.gravity_loss(verts, item.rest),
        "collision": L.collision_loss(
            verts, item.contact_p[t], item.contact_n[t], w.collision_margin, w.collision_power, w.collision_near, y
        ),
        "skin_prior": ((weights - item.body_weights[None]) ** 2).sum(-1).mean(),
    }
    scale = {"vertex": 1.0, "skin_prior": prior_scale}
    weight = {k: getattr(w, k) for k in TERMS}
    weight["collision"] = w.collision_for(item.meta.get("type"))
    out["total"] = sum(weight[k] * scale.get(k, terms_scale) * out[k] for k in TERMS if weight[k] != 0)
    return out


def physics_losses(model: SEGANet, pair, t0: int, frames: int, mat, body_faces, device, collider=None) -> dict:
    """The cloth energy (:func:`~segadeform.train.energies.cloth_energy`) of frames ``t0+2 .. t0+frames-1``
    of a pair never simulated, the two frames before each (the network's own, detached) as history."""
    from .energies import body_contact, cloth_energy

    t = torch.arange(t0, t0 + frames, device=device)
    lw = torch.log(pair.body_weights + RESIDUAL_EPS) if model.residual else None
    hist = _history(model, pair.history_in, pair.lead + t)
    x, _, _ = model(
        pair.features,
        pair.nbr,
        pair.mask,
        pair.descriptor,
        pair.betas.expand(frames, -1),
        pair.windows[t],
        pair.rest,
        pair.joints[None].expand(frames, -1, -1),
        pair.trans[t],
        lw,
        hist,
    )
    cp, cn = body_contact(x[2:].detach().cpu().numpy(), pair.posed_body[t0 + 2 : t0 + frames], body_faces, collider)
    h = x.detach()
    return cloth_energy(
        x[2:],
        pair.topo.to(device),
        mat,
        prev=h[1:-1],
        prev2=h[:-2],
        dt=1.0 / pair.fps,
        contact_p=torch.as_tensor(cp, device=device),
        contact_n=torch.as_tensor(cn, device=device),
        height_ref=pair.trans[t[2:], 1],
    )


def plot_losses(csv_path: Path, png_path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    rows = list(csv.DictReader(open(csv_path)))
    if not rows:
        return
    steps = [int(r["step"]) for r in rows]
    fig, ax = plt.subplots(1, 2, figsize=(11, 4))
    ax[0].plot(steps, [float(r["total"]) for r in rows], label="total")
    ax[0].plot(steps, [float(r["vertex"]) for r in rows], label="vertex (m)")
    if "val_vertex" in rows[0]:
        pts = [(s, float(r["val_vertex"])) for s, r in zip(steps, rows, strict=True) if r.get("val_vertex")]
        if pts:
            ax[0].plot(*zip(*pts, strict=True), "o-", label="held-out vertex (m)")
    ax[0].set_yscale("log")
    ax[0].set_xlabel("step")
    ax[0].legend()
    for k in TERMS[1:]:
        vals = [abs(float(r[k])) for r in rows]
        if max(vals) > 0:
            ax[1].plot(steps, vals, label=k)
    ax[1].set_yscale("log")
    ax[1].set_xlabel("step")
    ax[1].legend()
    fig.tight_layout()
    with atomic_path(png_path) as tmp:
        fig.savefig(tmp, format="png", dpi=80)
    plt.close(fig)


class _PairPrefetch:
    """The physics pairs one ahead: pair ``k + 1`` is built in a background thread while step ``k`` trains.

    The pairs are drawn from a stream of their own (seeded by the training seed), so the sequence does not
    depend on timing; :meth:`state` holds the stream and the index drawn ahead, so a resumed run draws the
    same pairs as one that was never stopped."""

    def __init__(self, pairs, seed: int, state: dict | None = None) -> None:
        from concurrent.futures import ThreadPoolExecutor

        self.pairs = pairs
        self.rng = np.random.default_rng([int(seed), 1])
        ahead = None
        if state is not None:
            self.rng.bit_generator.state = state["rng"]
            ahead = state.get("ahead")
        self.pool = ThreadPoolExecutor(1, thread_name_prefix="segadeform-pairs")
        self.ahead = int(ahead) if ahead is not None else int(self.rng.integers(len(pairs)))
        self.future = self.pool.submit(pairs.item, self.ahead)

    def next(self):
        item = self.future.result()
        self.ahead = int(self.rng.integers(len(self.pairs)))
        self.future = self.pool.submit(self.pairs.item, self.ahead)
        return item

    def state(self) -> dict:
        return {"rng": self.rng.bit_generator.state, "ahead": self.ahead}

    def close(self) -> None:
        """Stop: the pair being built is dropped (not waited for)."""
        self.future.cancel()
        self.pool.shutdown(wait=False, cancel_futures=True)


def _splits_of(roots) -> list[str]:
    """The splits the dataset roots' samples are of, sorted (what an error about a split name offers)."""
    return sorted({str(roots.meta(s).get("split")) for s in roots.ids()})


def _roots_said(roots) -> str:
    """The dataset roots as an error names them: the roots read, else the folders given that hold no samples (an
    empty folder was said to be "no dataset root: none given": a user's trial), else the optional roots missing."""
    if roots.roots:
        return str(roots)
    if roots.given:
        return ", ".join(str(r) for r in roots.given) + (
            ", an empty folder: no samples" if len(roots.given) == 1 else ", empty folders: no samples"
        )
    return "no dataset root: " + (", ".join(f"{r} is not there" for r in roots.skipped) or "none given")


def _training_motions(items, init) -> dict:
    """The fingerprints of the motions ``items`` play (:func:`segadeform.motion.fingerprint.motions_record`),
    one per motion name (a mirrored sample's motion is another motion), and those of the starting model
    ``init`` when it records them (a fine-tuned model has seen its starting model's motions too)."""
    from ..motion.fingerprint import motions_record, read_motions_record

    names, speeds = [], []
    for i in items:
        if i.motion_speeds is not None:
            names.append(str(i.meta.get("motion") or i.id) + ("~mirror" if str(i.id).endswith("~mirror") else ""))
            speeds.append(i.motion_speeds)
    if init and Path(init).is_file():
        from ..model.network import checkpoint_training_motions

        before = checkpoint_training_motions(init)
        if before is None:  # (a fine-tuned shipped model forgot the 246 motions it started from: an ML user's trial)
            log.warning(
                "%s records no training motions: the fine-tuned model records only its own samples', so eval cannot "
                "warn of a test motion the starting model was trained on; `segadeform export --training-motions "
                "CONFIG` adds the starting model's",
                init,
            )
        for n, sp in read_motions_record(before) if before is not None else []:
            names.append(n)
            speeds.append(sp)
    return motions_record(names, speeds)


def _hardware(device: torch.device) -> dict:
    hw = {
        "device": str(device),
        "cpu": platform.processor() or platform.machine(),
        "cpu_count": os.cpu_count(),
        "torch_threads": torch.get_num_threads(),
        "torch": torch.__version__,
        "python": platform.python_version(),
    }
    if device.type == "cuda":
        hw["gpu"] = torch.cuda.get_device_name(device)
    return hw


def train(
    cfg: TrainConfig,
    run_dir: Path,
    body: BodyModel,
    *,
    progress: Callable[[int, dict], None] | None = None,
    val_ids=None,
    log_every: int = 10,
    resumed: Callable[[int, int], None] | None = None,
) -> Path:
    """Train (or resume) into ``run_dir``; returns the final ``model.pt``.  ``resumed(step, steps)``: called when the
    run goes on from its checkpoint ``last.pt`` at ``step`` of ``steps``, once the checkpoint is found to be this
    run's (before any step is trained).

    Under a time budget (``optim.seconds``) this call -- loading the samples, training and validating -- ends
    within the budget of its start; writing the final model follows.  The step count is fixed once, at the end of
    the warm-up, and kept in the checkpoint (a run resumed after that trains toward it).  Steps slower than the
    warm-up's (other processes sharing the machine) do not overrun the budget: the loop stops before a step that
    would not end within it, the validation split's choice so far is the model, and ``train.json`` records the step
    (``stopped_at_budget``)."""
    started = time.perf_counter()
    run = Path(run_dir)
    o = cfg.optim
    device = pick_device(o.device)
    torch.manual_seed(o.seed)
    m = cfg.model
    from ..dataset.roots import DatasetRoots

    # the roots, their body and the split first: a run that cannot start writes nothing (a damaged pack left the
    # run's folder behind, a typo'd split said "segadeform dataset make first")
    roots = DatasetRoots(list(cfg.dataset), optional=cfg.optional, cache_dir=run / "cache")
    roots.check_body(body)
    from ..body.identity import body_label, body_text, other_body

    # the body the model learns on: recorded in last.pt, model.pt and train.json (eval, export and run refuse the
    # model on another one; a model trained on a second body was taken on the first without a word)
    trained_body = body_label(body)
    parts = cfg.split.split("+")
    by_part = {part: roots.ids(part) for part in parts}
    empty = [part for part, got in by_part.items() if not got]
    if empty and len(parts) > 1:  # a misspelled part trained on the others without a word (a review)
        have = _splits_of(roots)
        raise InputError(
            f"no '{empty[0]}' samples in the dataset (data.split = {cfg.split!r})",
            path=cfg.path,
            expected=f"each part a split of the dataset: {' | '.join(have)}",
            got=_roots_said(roots),
        )
    ids = cfg.select(sorted({i for got in by_part.values() for i in got}))
    from ..dataset.config import SPLITS

    # a validation split no dataset makes (a typo) is refused before anything is written; one a dataset makes but
    # this one lacks trains unvalidated, said below (a researcher's trial: "vall" trained on with a warning)
    if cfg.val_split and not val_ids and not roots.ids(cfg.val_split):
        if not (cfg.val_split in SPLITS or cfg.val_split.startswith("test-")):
            have = _splits_of(roots)
            raise InputError(
                f"no '{cfg.val_split}' samples in the dataset, and no dataset makes such a split (data.val_split)",
                path=cfg.path,
                expected=f'data.val_split = {" | ".join(have)}, or "" for no validation',
                got=_roots_said(roots),
            )
    if not ids:
        have = _splits_of(roots)
        raise InputError(
            f"no '{cfg.split}' samples in the dataset",
            path=cfg.path,
            expected=(f"data.split = {' | '.join(have)}" if have else "segadeform dataset make first")
            + (
                " (or samples that data.exclude and data.fraction leave)"
                if have and set(cfg.split.split("+")) & set(have)
                else ""
            ),
            got=(f"the splits {', '.join(have)} in " if have else "") + _roots_said(roots),
        )
    if cfg.mirror:  # a mirrored sample is trained on the body itself: it must be its own mirror image at every shape
        # (a sample's record names its shape; a pack's index does not, and its sample is read)
        recorded = {i: roots.meta(i).get("betas") for i in ids}
        shapes = {
            tuple(np.asarray(roots.load(i).betas if b is None else b, float).ravel()) for i, b in recorded.items()
        }
        asym = max(body_asymmetry(body, np.asarray(b)[None] if b else None) for b in shapes | {()})
        if not asym <= MIRROR_TOLERANCE:
            raise InputError(
                "data.mirror needs a left-right symmetric body: its rest joints are not their twins' mirror images",
                path=cfg.path,
                expected=f"at most {MIRROR_TOLERANCE * 1000:g} mm apart",
                got=f"{asym * 1000:.1f} mm",
            )
    # the weights a fresh run starts from (optim.init: fine-tuning), checked before anything is written
    init_state = _init_state(Path(o.init), m, body) if o.init and not (run / "last.pt").is_file() else None
    run.mkdir(parents=True, exist_ok=True)
    # training and validation samples and the physics pairs alike: the model's garment precompute, motion window,
    # shape coefficients, weight prior and drape
    model_inputs = dict(
        n_star=m.n_star, window=m.window, n_betas=m.n_betas, weight_prior=m.weight_prior, rest_drape=m.rest_drape
    )
    load = functools.partial(load_items, roots, body, **model_inputs)
    items = load(ids=ids, mirror=cfg.mirror)
    if not items:
        raise InputError(
            f"no '{cfg.split}' samples in the dataset",
            expected="segadeform dataset make first",
            got=_roots_said(roots),
        )
    if cfg.val_split and not val_ids:
        val_ids = roots.ids(cfg.val_split)
        if not val_ids:  # (it went unsaid: model.pt was the last step, not a validated choice)
            log.warning(
                "no '%s' samples in the dataset: nothing validates the run, and model.pt is its last step "
                "(data.val_split names the split that chooses the model)",
                cfg.val_split,
            )
    elif val_ids:  # samples given by id (--val): choosing the model on the test split leaves nothing unseen to score
        held = sorted(i for i in val_ids if str(roots.meta(i).get("split", "")).startswith("test"))
        if held:
            log.warning(
                "%d of the %d samples that choose the model are of the test split (first: %s): the model is then "
                "chosen on the data it is scored on (data.val_split or --val of validation samples keep them apart)",
                len(held),
                len(val_ids),
                held[0],
            )
    if items[0].features.shape[-1] != m.feat_dim:
        raise InputError(
            "model.feat_dim does not match the garment features", expected=items[0].features.shape[-1], got=m.feat_dim
        )
    items = [it.to(device) for it in items]
    val = [it.to(device) for it in load(split=None, ids=val_ids)] if val_ids else []
    # a history runs from the lead's first frame: samples made before leads were recorded start at their first
    no_lead = sorted(it.id for it in items + val if not it.lead_known) if m.history else []
    if no_lead:
        log.warning(
            "%d of %d samples record no lead: their motion history starts at their first frame "
            "(tools/add_leads.py DATASET CONFIG records it)",
            len(no_lead),
            len(items) + len(val),
        )
    model = SEGANet(m).to(device)
    if init_state is not None:
        model.load_state_dict(init_state)
    # weight decay 0 keeps plain Adam (the optimiser every earlier run used, so its last.pt resumes)
    opt = (
        torch.optim.AdamW(model.parameters(), lr=o.lr, weight_decay=o.weight_decay)
        if o.weight_decay > 0
        else torch.optim.Adam(model.parameters(), lr=o.lr)
    )
    # the step count: optim.steps, or under a time budget the count the warm-up's timing fixes (below)
    total = [o.steps]
    sched = torch.optim.lr_scheduler.LambdaLR(opt, lambda s: o.lr_factor(s, total[0]))
    rng = np.random.default_rng(o.seed)
    step, elapsed = 0, 0.0
    seen_frames = [0]  # sample-frames the loss has seen: a clip shorter than optim.frames gives all its frames
    ck_pairs = None  # the prefetched pairs' stream, when resumed
    ck_window = None  # the loss rows' running sums, when resumed
    budget = {"seconds": o.seconds, "probe": [], "steps": None} if o.seconds > 0 else None
    last = run / "last.pt"
    # what the run trains on: a run resumes only on the samples it started with (the dataset roots are not part of
    # the config's digest; a grown or other dataset under the same run folder was taken as the run finished)
    trained_on = json.dumps([sorted(i.id for i in items), sorted(val_ids or [])])
    data_digest = hashlib.sha256(trained_on.encode()).hexdigest()[:16]
    # ... and the roots it read them from (other roots holding samples of the same names were taken, and train.json
    # then named the new roots alone)
    data_roots = [str(Path(r).resolve()) for r in (*cfg.dataset, *cfg.optional)]
    if last.is_file():
        ck = torch.load(last, map_location=device, weights_only=False)
        if ck.get("config_digest") != cfg.digest():
            changed = config_changes(ck.get("train_config"), cfg.to_dict())
            raise InputError(
                "the run folder holds a run of a different config (a run resumes only with the config it started "
                "with, and the command line's --steps / --seconds / --dataset as it was then)",
                path=run,
                expected=f"config {ck.get('config_digest')} (the run's config.toml and options), or a new -o folder",
                got=f"config {cfg.digest()}" + (f": {changed}" if changed else ""),
            )
        if ck.get("data_digest") not in (None, data_digest):  # (runs saved before it was recorded: not checked)
            raise InputError(
                "the run folder holds a run trained on other samples (a run resumes only on the samples it "
                "started with)",
                path=run,
                expected="the --dataset roots and samples the run started with (its train.json), or a new -o folder",
                got=f"{len(items)} training and {len(val_ids or [])} validation samples now",
            )
        if ck.get("data_roots") not in (None, data_roots):  # (runs saved before they were recorded: not checked)
            raise InputError(
                "the run folder holds a run trained on other dataset roots (a run resumes only with the --dataset "
                "it started with)",
                path=run,
                expected=", ".join(ck["data_roots"]) + " (the run's), or a new -o folder",
                got=", ".join(data_roots),
            )
        if other_body(ck.get("body"), body) is not None:  # (runs saved before it was recorded: not checked)
            raise InputError(
                "the run folder holds a run trained on another body (a run resumes only with the --body it started "
                "with)",
                path=run,
                expected=body_text(ck["body"]),
                got=body_text(trained_body),
            )
        model.load_state_dict(ck["state_dict"])
        opt.load_state_dict(ck["optimizer"])
        sched.load_state_dict(ck["scheduler"])
        rng.bit_generator.state = ck["rng"]
        torch.set_rng_state(ck["torch_rng"])
        step, elapsed = int(ck["step"]), float(ck["elapsed"])
        # (a checkpoint from before the count: its steps at optim.frames each, what train.json said then)
        seen_frames[0] = int(ck.get("frames_seen", step * o.garments * o.frames))
        total[0] = int(ck.get("total_steps", o.steps))
        ck_pairs = ck.get("pairs")
        ck_window = ck.get("log_window")
        if budget is not None and ck.get("budget_steps"):
            budget["steps"] = int(ck["budget_steps"])
        best_val = (float(ck.get("best_val", float("inf"))), int(ck.get("best_step", -1)))
    else:
        best_val = (float("inf"), -1)  # (vertex error on the validation split, step)
    final = run / "model.pt"
    if step >= total[0] and final.is_file() and (run / "train.json").is_file():
        return final  # a finished run run again: nothing to do, nothing rewritten (its record kept as it was)
    if step > 0 and resumed is not None:
        resumed(step, total[0])
    # the config beside the run once there is something to train and it is this run's (a run that finds no data,
    # or that another run's folder refuses, leaves no file)
    if cfg.path is not None and cfg.path.resolve() != (run / "config.toml").resolve():
        (run / "config.toml").write_text(config_copy(cfg.path), encoding="utf-8")
    best_path = run / "best.pt"
    log_path = run / "loss.csv"
    fields = ["step", "total", *TERMS, PHYSICS_TERM, "lr", "seconds", "val_vertex"]
    if step == 0 or not log_path.is_file():
        with open(log_path, "w", newline="") as fh:
            csv.writer(fh).writerow(fields)
    else:  # drop rows logged after the checkpoint we resume from (rewritten under a temporary name)
        with open(log_path, newline="") as fh:
            rows = [r for r in csv.DictReader(fh) if int(r["step"]) <= step]
        with atomic_path(log_path) as tmp, open(tmp, "w", newline="") as fh:
            wr = csv.DictWriter(fh, fields)
            wr.writeheader()
            wr.writerows(rows)

    def save_last():
        with atomic_path(last) as tmp:
            torch.save(
                {
                    "config": dataclasses.asdict(m),
                    "state_dict": model.state_dict(),
                    "optimizer": opt.state_dict(),
                    "scheduler": sched.state_dict(),
                    "rng": rng.bit_generator.state,
                    "torch_rng": torch.get_rng_state(),
                    "step": step,
                    "frames_seen": seen_frames[0],
                    "elapsed": elapsed + (time.perf_counter() - t0),  # up to now (elapsed lags until the next log)
                    "config_digest": cfg.digest(),
                    "train_config": cfg.to_dict(),  # what a refused resume names as changed
                    "data_digest": data_digest,
                    "data_roots": data_roots,
                    "body": trained_body,
                    "best_val": best_val[0],
                    "best_step": best_val[1],
                    "total_steps": total[0],
                    "budget_steps": budget["steps"] if budget is not None else None,
                    "pairs": prefetch.state() if prefetch is not None else None,
                    # the loss rows' running sums since the last logged step (a checkpoint between two logged
                    # steps: a resumed run's next row averaged only the steps after the checkpoint); a logged step
                    # is written right after, so its window starts empty
                    "log_window": (
                        None
                        if step % log_every == 0 or step == total[0]
                        else ({k: float(v) for k, v in acc.items()}, n_acc)
                    ),
                },
                tmp,
            )

    def validate() -> float:
        if not val:
            return float("nan")
        model.eval()
        with torch.no_grad():
            errs = []
            for it in val:
                t = torch.arange(it.n_frames, device=device)
                errs.append(float(step_losses(model, it, t, cfg.loss)["vertex"]))
        model.train()
        return float(np.mean(errs))

    ph = cfg.physics
    pairs = None
    if ph.every:
        from .energies import PhysicsPairs

        # the pairs' garments are made once into the dataset's cache (the same files `dataset make` writes)
        pairs = PhysicsPairs(
            cfg.pairs,
            (roots.cache_dir or run / "cache") / "pairs",
            body,
            exclude=cfg.exclude,
            **model_inputs,
        )
        mat = ph.material()
        body_faces = np.asarray(body.faces)
        from ..body.collision import BodyCollider

        collider = BodyCollider(body.v_template, body.faces)  # exact closest points, built once
    prefetch = _PairPrefetch(pairs, o.seed, ck_pairs) if pairs is not None and ph.prefetch else None
    acc = {k: 0.0 for k in ("total", *TERMS, PHYSICS_TERM)}
    n_acc = 0
    if step > 0 and ck_window is not None:  # resumed between two logged steps: the window goes on
        acc.update({k: v for k, v in ck_window[0].items() if k in acc})
        n_acc = int(ck_window[1])
    val_seconds = 0.0
    if val and step == 0 and best_val[1] < 0:
        # the untrained model is a candidate too (a residual model at step 0 is its weight prior's LBS):
        # the validation split never chooses a model worse than where training started
        v0 = time.perf_counter()
        best_val = (validate(), 0)
        val_seconds = time.perf_counter() - v0
        with atomic_path(best_path) as tmp:
            torch.save({"state_dict": model.state_dict(), "step": 0, "val_vertex": best_val[0]}, tmp)
    t0 = time.perf_counter()
    model.train()
    stopped_at = None  # the step the budget stopped the loop at, when it did
    step_seconds = 0.0  # the last step's time (a validation's left out)
    try:
        while step < total[0]:
            if budget is not None and budget["steps"] is not None:
                nxt = step_seconds + (val_seconds if val and (step + 1) % o.checkpoint_every == 0 else 0.0)
                if time.perf_counter() - started + nxt > o.seconds:
                    stopped_at = step
                    break
            s0 = time.perf_counter()
            fade = o.prior_fade(step, total[0], cfg.loss.skin_prior_until)
            late = 1.0 if step >= cfg.loss.terms_from * total[0] else 0.0  # the physical terms, from terms_from on
            opt.zero_grad(set_to_none=True)
            ls = {}
            for _ in range(o.garments):  # one batch: each garment's loss backpropagated as it is made (memory)
                it = items[int(rng.integers(len(items)))]
                t = torch.as_tensor(
                    rng.choice(it.n_frames, size=min(o.frames, it.n_frames), replace=False), device=device
                )
                seen_frames[0] += int(t.numel())
                one = step_losses(model, it, t, cfg.loss, prior_scale=fade, terms_scale=late)
                if not torch.isfinite(one["total"]):
                    raise InputError(f"the loss became {float(one['total'])} at step {step} on {it.id}; lower optim.lr")
                (one["total"] / o.garments).backward()
                for k, v in one.items():
                    ls[k] = ls.get(k, 0.0) + v.detach() / o.garments
            ls[PHYSICS_TERM] = torch.zeros(())
            if pairs is not None and step % ph.every == 0 and late:
                pair = (prefetch.next() if prefetch is not None else pairs.item(int(rng.integers(len(pairs))))).to(
                    device
                )
                f = min(ph.frames, pair.n_frames)
                if f >= 3:
                    first = int(rng.integers(pair.n_frames - f + 1))
                    phys = ph.weight * physics_losses(model, pair, first, f, mat, body_faces, device, collider)["total"]
                    if not torch.isfinite(phys):
                        raise InputError(
                            f"the physics loss became {float(phys)} at step {step} on {pair.id}; lower optim.lr"
                        )
                    phys.backward()
                    ls[PHYSICS_TERM] = phys.detach()
                    ls["total"] = ls["total"] + ls[PHYSICS_TERM]
            torch.nn.utils.clip_grad_norm_(model.parameters(), o.grad_clip)
            opt.step()
            sched.step()
            step += 1
            if budget is not None and budget["steps"] is None:
                # the warm-up times the machine (its first 5 steps, which compile and allocate, left out); at its end
                # the step count is fixed so that the loop ends within the budget, and never changes again
                if device.type == "cuda":
                    torch.cuda.synchronize(device)
                budget["probe"].append(time.perf_counter())
                if step >= o.warmup:
                    probe = budget["probe"]
                    so_far = probe[-1] - started  # this call's time: loading, validation and the warm-up
                    # a run resumed near the warm-up's end has few timed steps: this call's steps alone, then
                    per_step = (
                        (probe[-1] - probe[4]) / (len(probe) - 5)
                        if len(probe) > 6
                        else (probe[-1] - started) / len(probe)
                    )
                    per_step += val_seconds / o.checkpoint_every  # the validations still to come
                    budget["steps"] = total[0] = o.budget_steps(step, so_far, per_step)
            step_seconds = time.perf_counter() - s0
            for k in acc:  # summed on the device in float64 (as Python floats would be): no sync per step
                acc[k] = acc[k] + ls[k].detach().to(torch.float64)
            n_acc += 1
            val_err = ""
            if step % o.checkpoint_every == 0 or step == total[0]:
                if val:
                    v0 = time.perf_counter()
                    val_err = validate()
                    val_seconds = time.perf_counter() - v0  # the budget counts the validations still to come
                    # the model the validation split chooses, among those trained on the whole loss (loss.terms_from:
                    # a checkpoint of the vertex error alone is not a candidate)
                    if val_err < best_val[0] and step > cfg.loss.terms_from * total[0]:
                        best_val = (val_err, step)
                        with atomic_path(best_path) as tmp:
                            torch.save({"state_dict": model.state_dict(), "step": step, "val_vertex": val_err}, tmp)
                save_last()
            if step % log_every == 0 or step == total[0]:
                now = time.perf_counter()
                elapsed += now - t0
                t0 = now
                row = {
                    "step": step,
                    **{k: float(acc[k]) / n_acc for k in acc},
                    "lr": sched.get_last_lr()[0],
                    "seconds": round(elapsed, 2),
                    "val_vertex": val_err,
                }
                with open(log_path, "a", newline="") as fh:
                    csv.DictWriter(fh, fields).writerow(row)
                if progress is not None:
                    progress(step, {**row, "of": total[0]})
                acc = {k: 0.0 for k in acc}
                n_acc = 0
    finally:  # the pair thread ends however the loop does (an error, a KeyboardInterrupt)
        if prefetch is not None:
            prefetch.close()
    elapsed += time.perf_counter() - t0
    # the garments it saw, by descriptor: export writes them to the manifest, and runtimes warn about garments
    # far from all of them (segadeform.contracts.model_package.TRAINING_GARMENTS)
    from ..geometry.mesh_ops import boundary_loops, surface_faces
    from ..model.network import save_checkpoint

    chosen = {"step": step}
    if val and best_path.is_file():  # the checkpoint the validation split chose
        best = torch.load(best_path, map_location=device, weights_only=False)
        model.load_state_dict(best["state_dict"])
        chosen = {
            "step": int(best["step"]),
            "val_vertex": float(best["val_vertex"]),
            "val_split": cfg.val_split,
            "val_samples": len(val),
        }
    garments = {(i.asset.source_name or i.id, i.asset.descriptor.tobytes()): i.asset for i in items}
    seen = {
        "names": [k[0] for k in garments],
        "descriptors": [[float(x) for x in a.descriptor] for a in garments.values()],
        "openings": [len(boundary_loops(surface_faces(a.vertices, a.faces), a.n_vertices)) for a in garments.values()],
    }
    init_record = None
    if o.init:  # a fine-tuned model saw its starting model's garments too (their familiarity is not lost: a review)
        from ..model.network import checkpoint_training_garments

        init_record = {"path": o.init, "sha256": hashlib.sha256(Path(o.init).read_bytes()).hexdigest()}
        before = checkpoint_training_garments(o.init) if Path(o.init).is_file() else None
        if before is not None and before[2] is not None:  # (a checkpoint that records no openings: not merged)
            names, desc, openings = before
            have = {tuple(d) for d in seen["descriptors"]}
            for n, d, k in zip(names, np.asarray(desc).tolist(), openings, strict=True):
                if tuple(float(x) for x in d) not in have:
                    seen["names"].append(n)
                    seen["descriptors"].append([float(x) for x in d])
                    seen["openings"].append(int(k))
    save_checkpoint(
        final,
        model,
        train_config=cfg.to_dict(),
        steps=step,
        body=trained_body,
        training_garments=seen,
        training_motions=_training_motions(items, o.init),
    )
    info = {
        "config": cfg.to_dict(),
        "config_digest": cfg.digest(),
        "steps": step,
        "train_seconds": round(elapsed, 1),
        "chosen": chosen,
        "sample_frames_seen": seen_frames[0],
        **(
            {
                "time_budget": {"seconds": o.seconds, "warmup": o.warmup, "steps_chosen": budget["steps"]},
                "stopped_at_budget": stopped_at,
            }
            if budget is not None
            else {}
        ),
        "samples": [i.id for i in items],
        **({"init": init_record} if init_record is not None else {}),
        "body": trained_body,
        **({"history_without_lead": no_lead} if m.history else {}),
        "hardware": _hardware(device),
    }
    with atomic_path(run / "train.json") as tmp:
        Path(tmp).write_text(json.dumps(info, indent=1))
    plot_losses(log_path, run / "loss.png")
    return final
