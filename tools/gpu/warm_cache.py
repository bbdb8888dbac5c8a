"""Fill a dataset folder's cache for a training config with many processes, before several trainings read it.

Each training run otherwise computes every garment's precompute (geodesics, spectra), the samples' body
contacts and the physics pairs' garments itself, one process each; on a lent GPU machine that is minutes of
a short lease.  This computes them once, in parallel, into ``CACHE_ROOT/cache`` (an empty dataset folder given
first to ``segadeform train --dataset``, so every run reads and writes that cache).

    python tools/gpu/warm_cache.py CONFIG.toml CACHE_ROOT --dataset PACK [--dataset ...] [-j 14] [--pairs-only]

``--pairs-only`` makes only the pairs' part (``CACHE_ROOT/cache/pairs``: garments, their precompute, motion
clips), which needs ``../shared`` (MakeHuman garments, capture files): made beside the checkout and carried
as a tar to a machine without it.
"""

from __future__ import annotations

import argparse
import os
import time
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path


def _samples(args):
    cfg_path, roots, ids = args
    from segadeform.body import default_body_path, load_body
    from segadeform.dataset.roots import DatasetRoots
    from segadeform.train import load_train_config
    from segadeform.train.data import load_items

    cfg = load_train_config(cfg_path, dataset=roots)
    m = cfg.model
    body = load_body(default_body_path())
    r = DatasetRoots(list(cfg.dataset), optional=cfg.optional)
    load_items(r, body, n_star=m.n_star, window=m.window, n_betas=m.n_betas, ids=ids, weight_prior=m.weight_prior)
    return len(ids)


def _pair_garments(args):
    cfg_path, roots, keys = args
    from segadeform.body import default_body_path, load_body
    from segadeform.dataset.roots import DatasetRoots
    from segadeform.train import load_train_config
    from segadeform.train.energies import PhysicsPairs

    cfg = load_train_config(cfg_path, dataset=roots)
    m = cfg.model
    body = load_body(default_body_path())
    r = DatasetRoots(list(cfg.dataset), optional=cfg.optional)
    pairs = PhysicsPairs(
        cfg.pairs,
        r.cache_dir / "pairs",
        body,
        n_star=m.n_star,
        window=m.window,
        n_betas=m.n_betas,
        weight_prior=m.weight_prior,
        exclude=cfg.exclude,
    )
    for gi, bi in keys:
        if gi is None:  # a motion clip for body bi
            pairs._clip(bi[0], body.rest_joints(pairs.cfg.bodies[bi[1]] or None)[0])
        else:
            pairs._garment(gi, bi)
    return len(keys)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("config")
    ap.add_argument("cache_root", help="an empty dataset folder (made here): its cache/ is filled")
    ap.add_argument("--dataset", action="append", required=True)
    ap.add_argument("-j", "--jobs", type=int, default=os.cpu_count() or 1)
    ap.add_argument("--pairs-only", action="store_true", help="only the physics pairs' garments and motion clips")
    a = ap.parse_args()
    os.environ.setdefault("OMP_NUM_THREADS", "1")
    root = Path(a.cache_root)
    (root / "samples").mkdir(parents=True, exist_ok=True)
    roots = [str(root), *a.dataset]
    from segadeform.dataset.roots import DatasetRoots
    from segadeform.train import load_train_config

    cfg = load_train_config(a.config, dataset=roots)
    r = DatasetRoots(list(cfg.dataset), optional=cfg.optional)
    ids = cfg.select(r.ids(cfg.split)) + (r.ids(cfg.val_split) if cfg.val_split else [])
    t0 = time.perf_counter()
    chunks = [ids[i :: a.jobs] for i in range(a.jobs) if ids[i :: a.jobs]]
    with ProcessPoolExecutor(a.jobs) as ex:
        if not a.pairs_only:
            n = sum(ex.map(_samples, [(a.config, roots, c) for c in chunks]))
            print(f"{n} samples cached in {time.perf_counter() - t0:.0f} s", flush=True)
        if cfg.physics.every:
            from segadeform.dataset.config import load_dataset_config
            from segadeform.dataset.make import sample_plan

            plan = sample_plan(load_dataset_config(cfg.pairs, require_files=False))
            train = [p for p in plan if p.split == "train"]
            keys = sorted({(p.garment, p.body) for p in train})
            keys += [(None, k) for k in sorted({(p.motion, p.body) for p in train})]
            t1 = time.perf_counter()
            n = sum(ex.map(_pair_garments, [(a.config, roots, keys[i :: a.jobs]) for i in range(a.jobs)]))
            print(f"{n} pair garments and motion clips cached in {time.perf_counter() - t1:.0f} s", flush=True)


if __name__ == "__main__":
    main()
