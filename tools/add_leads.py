"""Record the lead of samples made before samples recorded it (issue #27).

``dataset make`` simulates up to a second of motion before each clip (the lead, so that the cloth enters the clip
in motion) and drops it; since the motion-history experiment (``ModelConfig.history``) a sample keeps it as
``lead_poses`` / ``lead_trans``.  For each sample of the dataset folder DATASET (made from CONFIG; kept and
rejected, since ``regate`` may keep a rejected one later) without them, this rebuilds the motion ``dataset make``
simulated from CONFIG's motion entry, checks that dropping the lead gives the stored clip (poses and translations
to 1e-4), and rewrites the sample with its lead (metadata first: a run stopped in between leaves a sample to make
again).  A sample whose clip does not match is left as it is and named.  Packs are never written.

    .venv/bin/python tools/add_leads.py data/continuum samples/datasets/continuum.toml [--body BODY.npz]

``--body``: the body the dataset was made on (``dataset make --body``; default: the shipped body); a sample made on
another body (its ``body_sha256``) is named and left as it is.

CPU: about 0.1 s a sample (the capture is read and retargeted again).
"""

from __future__ import annotations

import argparse
import dataclasses
import sys
from pathlib import Path

import numpy as np

from segadeform.body.identity import body_sha256
from segadeform.body.model import default_body_path, load_body
from segadeform.dataset.config import load_dataset_config
from segadeform.dataset.make import _motion, _rewrite_sample
from segadeform.dataset.store import SAMPLE_FOLDERS, load_sample


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("dataset", type=Path)
    ap.add_argument("config", type=Path)
    ap.add_argument("--body", type=Path, default=None, help="the body the dataset was made on")
    a = ap.parse_args(argv)
    cfg = load_dataset_config(a.config)
    body = load_body(a.body or default_body_path())
    sha = body_sha256(body)
    motions = {m.name: m for m in cfg.motions}
    done = have = 0
    bad = []
    todo = [(f, p.stem) for f in SAMPLE_FOLDERS for p in sorted((a.dataset / f).glob("*.json"))]
    for folder, sid in todo:
        s = load_sample(a.dataset, sid, folder)
        if s.lead_poses is not None:
            have += 1
            continue
        m = motions.get(s.meta.get("motion"))
        if m is None or not 0 <= int(s.meta.get("body", -1)) < len(cfg.bodies):
            bad.append(f"{folder}/{sid}: its motion or body is not in {a.config}")
            continue
        if s.meta.get("body_sha256", sha) != sha:
            bad.append(f"{folder}/{sid}: made on another body than {a.body or default_body_path()} (--body)")
            continue
        betas = cfg.bodies[int(s.meta["body"])]
        full, lead = _motion(m, cfg, body.rest_joints(betas or None)[0], with_lead=True)
        n = len(s.poses)
        clip_p, clip_t = full.poses[lead : lead + n], full.trans[lead : lead + n]
        same = clip_p.shape == s.poses.shape and np.abs(clip_p - s.poses).max() <= 1e-4
        if not same or np.abs(clip_t - s.trans).max() > 1e-4:
            bad.append(f"{folder}/{sid}: the motion rebuilt from {a.config} is not the stored clip")
            continue
        _rewrite_sample(
            a.dataset, dataclasses.replace(s, lead_poses=full.poses[:lead], lead_trans=full.trans[:lead]), folder
        )
        done += 1
    for line in bad:
        print(line, file=sys.stderr)
    print(f"{a.dataset}: {done} samples given their lead, {have} had one, {len(bad)} left as they are")
    return 1 if bad else 0


if __name__ == "__main__":
    raise SystemExit(main())
