"""Build BVH files of arbitrary skeletons for tests: any names, extra joints, A-poses, channel layouts.

A skeleton is made from SMPL's (:func:`default_rest_joints`) by renaming joints, inserting helper
joints (twist, hip-joint, neck1 ...), adding leaves (eyes, fingers) and re-posing the rest (A-pose).
The motion is written as local rotations of the *source* skeleton, so the expected result of reading
it -- the source's own forward kinematics -- is known exactly.
"""

from __future__ import annotations

import numpy as np

from segadeform.body.rotations import axis_angle_to_matrix, matrix_to_euler


def write_skeleton_bvh(
    path,
    names,
    parents,
    rest,
    local_rot,
    root_pos,
    *,
    fps=30.0,
    order="zxy",
    six_channels=False,
    end_sites=None,
    scale=1.0,
    channel_order=None,
):
    """Write a BVH.

    Shapes:
        rest: (J, 3) rest joint positions; local_rot: (T, J, 3, 3); root_pos: (T, 3)
    ``end_sites``: {joint index: offset (3,)}.  ``six_channels``: positions on every joint (their
    offsets), as game rigs do.  ``channel_order``: e.g. "Xrotation Yrotation Zrotation" spelled per joint.
    """
    names = list(names)
    parents = np.asarray(parents)
    J = len(names)
    children = [[] for _ in range(J)]
    for i, p in enumerate(parents):
        if p >= 0:
            children[p].append(i)
    end_sites = end_sites or {}
    lines = ["HIERARCHY"]
    dfs = []
    rot_ch = " ".join(f"{a.upper()}rotation" for a in order)

    def emit(j, depth):
        dfs.append(j)
        ind = "\t" * depth
        off = rest[j] if parents[j] < 0 else rest[j] - rest[parents[j]]
        off = off * scale
        lines.append(f"{ind}{'ROOT' if parents[j] < 0 else 'JOINT'} {names[j]}")
        lines.append(f"{ind}{{")
        lines.append(f"{ind}\tOFFSET {off[0]:.6f} {off[1]:.6f} {off[2]:.6f}")
        if parents[j] < 0 or six_channels:
            lines.append(f"{ind}\tCHANNELS 6 Xposition Yposition Zposition {rot_ch}")
        else:
            lines.append(f"{ind}\tCHANNELS 3 {rot_ch}")
        for c in children[j]:
            emit(c, depth + 1)
        if not children[j]:
            e = end_sites.get(j, np.array([0.0, 0.05, 0.0])) * scale
            lines.extend(
                [f"{ind}\tEnd Site", f"{ind}\t{{", f"{ind}\t\tOFFSET {e[0]:.6f} {e[1]:.6f} {e[2]:.6f}", f"{ind}\t}}"]
            )
        lines.append(f"{ind}}}")

    emit(int(np.flatnonzero(parents < 0)[0]), 0)
    T = local_rot.shape[0]
    eul = np.rad2deg(matrix_to_euler(local_rot, order))  # (T, J, 3)
    lines += ["MOTION", f"Frames: {T}", f"Frame Time: {1.0 / fps:.8f}"]
    for t in range(T):
        vals = []
        for j in dfs:
            if parents[j] < 0:
                vals += list(root_pos[t] * scale)
            elif six_channels:
                vals += list((rest[j] - rest[parents[j]]) * scale)
            vals += list(eul[t, j])
        lines.append(" ".join(f"{v:.6f}" for v in vals))
    path.write_text("\n".join(lines) + "\n")
    return path


def source_fk(parents, rest, local_rot, root_pos):
    """Global rotations (T, J, 3, 3) and positions (T, J, 3) of a skeleton."""
    T, J = local_rot.shape[:2]
    G = np.empty_like(local_rot)
    P = np.empty((T, J, 3))
    for j in range(J):
        p = parents[j]
        if p < 0:
            G[:, j] = local_rot[:, j]
            P[:, j] = root_pos
        else:
            G[:, j] = G[:, p] @ local_rot[:, j]
            P[:, j] = P[:, p] + np.einsum("tij,j->ti", G[:, p], rest[j] - rest[p])
    return G, P


def smooth_local_rotations(n_frames, n_joints, seed=0, amplitude=0.5):
    """Smooth random local rotations (T, J, 3, 3): sums of slow sines per joint and axis."""
    rng = np.random.default_rng(seed)
    t = np.arange(n_frames)[:, None, None] / 30.0
    f = rng.uniform(0.3, 1.5, size=(1, n_joints, 3))
    ph = rng.uniform(0, 2 * np.pi, size=(1, n_joints, 3))
    aa = amplitude * np.sin(2 * np.pi * f * t + ph)
    return axis_angle_to_matrix(aa)
