"""How well the motion fingerprint (segadeform.motion.fingerprint) tells one capture from another, on the CMU files.

    python tools/fingerprint_separation.py [MOCAP_ROOT] [-o OUT.json]

Same capture: each BVH under cmu/ and cmu_more/ whose trial is also under cmu_asf_amc/ (a 2-second clip of one
against the whole other, both ways), and each file against itself read at 24 fps and on another body shape.  Files
are read as `dataset make` reads them (leading T-pose and settling frames dropped, glitches rebuilt).
Different captures: every ordered pair of trials of one ASF/AMC subject (the hardest case: one person, one day,
often the same action), and every BVH against the next file.  Prints the extremes of each and writes every
distance to OUT.json."""

from __future__ import annotations

import argparse
import glob
import itertools
import json
import os
import sys

import numpy as np

from segadeform.body import default_body_path, load_body
from segadeform.motion import load_motion
from segadeform.motion.fingerprint import SAME_CAPTURE, capture_distance, joint_speeds
from segadeform.motion.motion import (
    drop_leading_glitches,
    drop_leading_jumps,
    drop_leading_tpose,
    repair_glitches,
    resample,
)


def main() -> int:
    ap = argparse.ArgumentParser()
    ap.add_argument(
        "root", nargs="?", default=os.path.join(os.path.dirname(__file__), "..", "..", "shared", "data", "mocap")
    )
    ap.add_argument("-o", "--output", default=None)
    a = ap.parse_args()
    body = load_body(default_body_path())
    rj, rj2 = body.rest_joints(None)[0], body.rest_joints([2.0, 1.0] + [0.0] * 8)[0]
    cache: dict = {}

    def read(f, joints=rj):
        k = (f, joints is rj)
        if k not in cache:
            try:  # read as `dataset make` reads a capture: its leading T-pose and settling frames dropped, glitches
                mo = load_motion(f, rest_joints=joints, floor=True)  # rebuilt (segadeform.dataset.make._capture)
                mo, _ = drop_leading_jumps(mo)
                mo, _ = drop_leading_glitches(mo, joints)
                mo, _ = drop_leading_tpose(mo)
                cache[k], _ = repair_glitches(mo, joints)
            except Exception as e:
                sys.stderr.write(f"skipped {f}: {e}\n")
                cache[k] = None
        return cache[k]

    def clip(m, t0, seconds=2.0):
        i = int(t0 * m.fps)
        return m.poses[i : i + int(seconds * m.fps)], m.fps

    def fp(m, t0=None):
        return joint_speeds(*clip(m, t0)) if t0 is not None else joint_speeds(m.poses, m.fps)

    def trial(f):
        return "_".join(os.path.basename(f).split("_")[:2]).split(".")[0]

    amc = sorted(glob.glob(os.path.join(a.root, "cmu_asf_amc", "*", "*.amc")))
    bvh = sorted(glob.glob(os.path.join(a.root, "cmu", "*.bvh")) + glob.glob(os.path.join(a.root, "cmu_more", "*.bvh")))
    by_trial = {trial(f): f for f in amc}
    same, other = [], []
    for b in bvh:
        mb = read(b)
        if mb is None or mb.n_frames / mb.fps < 2.5:
            continue
        t0 = 0.5
        r24 = resample(mb, 24.0)
        same.append(("24fps", trial(b), capture_distance(joint_speeds(*clip(r24, t0)), fp(mb))))
        mb2 = read(b, rj2)
        same.append(("body", trial(b), capture_distance(fp(mb2, t0), fp(mb))))
        if trial(b) in by_trial and (ma := read(by_trial[trial(b)])) is not None and ma.n_frames / ma.fps >= 2.5:
            same.append(("bvh-amc", trial(b), capture_distance(fp(mb, t0), fp(ma))))
            same.append(("amc-bvh", trial(b), capture_distance(fp(ma, t0), fp(mb))))
    for x, y in zip(bvh, bvh[1:] + bvh[:1], strict=True):
        mx, my = read(x), read(y)
        if mx is not None and my is not None and mx.n_frames / mx.fps >= 2.5:
            other.append(("bvh", f"{trial(x)}~{trial(y)}", capture_distance(fp(mx, 0.5), fp(my))))
    subjects: dict = {}
    for f in amc:
        subjects.setdefault(os.path.dirname(f), []).append(f)
    for fs in subjects.values():
        for x, y in itertools.permutations(fs, 2):
            mx, my = read(x), read(y)
            if mx is not None and my is not None and mx.n_frames / mx.fps >= 2.5:
                other.append(("subject", f"{trial(x)}~{trial(y)}", capture_distance(fp(mx, 0.5), fp(my))))
    s, o = np.array([d for *_, d in same]), np.array([d for *_, d in other])
    print(f"same capture: {len(s)} pairs, largest {s.max():.3f} ({max(same, key=lambda r: r[2])[:2]})")
    print(f"different captures: {len(o)} pairs, smallest {o.min():.3f} ({min(other, key=lambda r: r[2])[:2]})")
    print(
        f"SAME_CAPTURE = {SAME_CAPTURE}: same pairs above it {int((s > SAME_CAPTURE).sum())}, different below it "
        f"{int((o <= SAME_CAPTURE).sum())}"
    )
    if a.output:
        with open(a.output, "w") as fh:
            json.dump({"same": same, "other": other}, fh, indent=0)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
