"""Closed test meshes."""

import numpy as np


def sphere(n=24, m=16):
    """A UV sphere of radius 1: ``n`` segments around, ``m`` rings pole to pole (poles included)."""
    th = np.linspace(0, np.pi, m)
    ph = np.linspace(0, 2 * np.pi, n, endpoint=False)
    v = [[0, 1, 0]]
    for t in th[1:-1]:
        for p in ph:
            v.append([np.sin(t) * np.cos(p), np.cos(t), np.sin(t) * np.sin(p)])
    v.append([0, -1, 0])
    v = np.array(v)
    f = []
    for j in range(n):
        f.append([0, 1 + (j + 1) % n, 1 + j])
    for i in range(m - 3):
        for j in range(n):
            a = 1 + i * n + j
            b = 1 + i * n + (j + 1) % n
            c = a + n
            d = b + n
            f += [[a, b, d], [a, d, c]]
    last = len(v) - 1
    base = 1 + (m - 3) * n
    for j in range(n):
        f.append([last, base + j, base + (j + 1) % n])
    return v, np.array(f)


def pressed_spheres(n=32, m=24):
    """One closed mesh that intersects itself, as a posed body with an arm pressed into its torso: a unit sphere
    (the torso) and a sphere of radius 0.3 centred at x = 0.9 (the arm), a third of it inside the first."""
    v, f = sphere(n, m)
    return np.concatenate([v, v * 0.3 + [0.9, 0.0, 0.0]]), np.concatenate([f, f + len(v)])


def with_reach(v, f, x=40.0):
    """The mesh (v, f) and a small sphere at (x, 0, 0): a hand at the end of a long reach, which makes the body's size
    (its box's longest side) about x, and with it the distance within which the rule for buried skin takes a pinched
    point out (``PINCH`` times the size), without changing anything near the rest of the mesh."""
    hv, hf = sphere(8, 6)
    return np.concatenate([v, hv * 0.05 + [x, 0.0, 0.0]]), np.concatenate([f, hf + len(v)])


def crease_points(rng, k, jitter=0.04, arm_x=0.9):
    """``k`` points within ``jitter`` of the circle where :func:`pressed_spheres`'s arm (centred at x = ``arm_x``,
    radius 0.3) enters the unit torso: many are in the torso, nearest the arm's buried skin, with open skin a
    centimetre or two away."""
    x = (1.0 + arm_x**2 - 0.09) / (2.0 * arm_x)
    r = np.sqrt(1.0 - x * x)
    t = rng.uniform(0, 2 * np.pi, k)
    c = np.stack([np.full(k, x), r * np.cos(t), r * np.sin(t)], 1)
    return c + rng.uniform(-jitter, jitter, (k, 3))
