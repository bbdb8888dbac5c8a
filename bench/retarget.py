"""Every BVH in a folder through the reader: naming scheme, frames, units, retarget error, load time.

    python bench/retarget.py [FOLDER ...]     (default: ../shared/data/mocap/cmu)

Per file:

* **own-skeleton error**: retargeted onto the file's *own* proportions, how far the mapped SMPL joints
  land from the file's forward kinematics (mean / max over joints and frames, mm) -- the error of
  the mapping itself (folded helper joints, virtual joints, the collars' swing-only rule);
* **limb direction error** on the default body: the largest angle between a retargeted limb bone
  (thighs, shins, upper arms, forearms) and the file's (degrees);
* **position after scale** on the default body: root-relative joint distance after the leg-length
  scale (mean, cm); this is mostly the difference in proportions between the two skeletons;
* load time against the time to parse the file alone (the same run).
"""

from __future__ import annotations

import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]


def main(argv=None) -> None:
    from segadeform.body import default_body_path, load_body
    from segadeform.body.kinematics import forward_kinematics, poses_to_rotmats
    from segadeform.body.skeleton import SMPL_JOINT_NAMES, SMPL_PARENTS
    from segadeform.motion import read_bvh
    from segadeform.motion.bvh import _own_rest, read_bvh_skeleton

    folders = [Path(a) for a in (argv or sys.argv[1:])] or [ROOT.parent / "shared" / "data" / "mocap" / "cmu"]
    files = sorted(f for d in folders for f in (d.glob("*.bvh") if d.is_dir() else [d]))
    J = load_body(default_body_path()).rest_joints()[0]
    limbs = [(1, 4), (2, 5), (4, 7), (5, 8), (16, 18), (17, 19), (18, 20), (19, 21)]
    print(
        "| file | scheme | frames | fps | units | own-skeleton mm (mean / max) | limb dir max deg "
        "| after scale cm | load s | parse s |"
    )
    print("|---|---|---|---|---|---|---|---|---|---|")
    for f in files:
        t0 = time.perf_counter()
        sk = read_bvh_skeleton(f)
        t_parse = time.perf_counter() - t0
        t0 = time.perf_counter()
        try:
            m = read_bvh(f, rest_joints=J)
        except Exception as e:  # report and go on: this is a survey
            print(f"| {f.name} | FAILED: {e} | | | | | | | | |")
            continue
        t_load = time.perf_counter() - t0
        own = read_bvh(f)
        src = np.full(24, -1)
        for k, v in own.meta["mapped"].items():
            src[SMPL_JOINT_NAMES.index(k)] = sk.names.index(v)
        sel = np.flatnonzero(src >= 0)
        Jo = _own_rest(sk.rest, src) * own.meta["scale"]
        _, po = forward_kinematics(poses_to_rotmats(own.poses, 24), Jo, SMPL_PARENTS, own.trans)
        e_own = np.linalg.norm(po[:, sel] - sk.positions[:, src[sel]] * own.meta["scale"], axis=-1)
        _, pb = forward_kinematics(poses_to_rotmats(m.poses, 24), J, SMPL_PARENTS, m.trans)
        worst = 0.0
        for a, b in limbs:
            d1 = pb[:, b] - pb[:, a]
            d2 = sk.positions[:, src[b]] - sk.positions[:, src[a]]
            c = np.einsum("ti,ti->t", d1, d2) / np.linalg.norm(d1, axis=1) / np.linalg.norm(d2, axis=1)
            worst = max(worst, float(np.degrees(np.arccos(np.clip(c, -1, 1))).max()))
        ref = sk.positions[:, src[sel]] * m.meta["scale"]
        rel = np.linalg.norm((pb[:, sel] - pb[:, :1]) - (ref - ref[:, :1]), axis=-1)
        print(
            f"| {f.name} | {m.meta['scheme']} | {m.n_frames} | {m.fps:.0f} | {m.meta['units_guess']} | "
            f"{1e3 * e_own.mean():.1f} / {1e3 * e_own.max():.1f} | {worst:.4f} | {1e2 * rel.mean():.1f} | "
            f"{t_load:.2f} | {t_parse:.2f} |"
        )


if __name__ == "__main__":
    main()
