"""Write ASF skeletons and AMC motions for tests: a CMU-like skeleton (CMU's bone names, directions, axes and
dofs, in CMU's 0.45-inch unit) and smooth motions on it, so readers can be tested without ../shared."""

from __future__ import annotations

from pathlib import Path

import numpy as np

R3 = ("rx", "ry", "rz")

#: (name, parent, direction, length, axis angles (deg, XYZ), dofs) of the left side and the spine; the right
#: side mirrors the left (x negated, the axis's second and third angles negated), as in CMU's files.
_LEFT_AND_SPINE = [
    ("lhipjoint", "root", (0.64, -0.71, 0.29), 2.45, (0, 0, 0), ()),
    ("lfemur", "lhipjoint", (0.34202, -0.939693, 0), 7.1, (0, 0, 20), R3),
    ("ltibia", "lfemur", (0.34202, -0.939693, 0), 7.4, (0, 0, 20), ("rx",)),
    ("lfoot", "ltibia", (0.09, -0.26, 0.96), 2.2, (-90, 0, 20), ("rx", "rz")),
    ("ltoes", "lfoot", (0, 0, 1), 1.1, (-90, 0, 20), ("rx",)),
    ("lowerback", "root", (0, 0.993, -0.119), 2.1, (0, 0, 0), R3),
    ("upperback", "lowerback", (0.026, 0.9995, -0.015), 2.1, (0, 0, 0), R3),
    ("thorax", "upperback", (0.026, 0.999, 0.04), 2.2, (0, 0, 0), R3),
    ("lowerneck", "thorax", (-0.06, 0.987, 0.147), 1.6, (0, 0, 0), R3),
    ("upperneck", "lowerneck", (0.065, 0.989, -0.135), 1.7, (0, 0, 0), R3),
    ("head", "upperneck", (0.026, 0.998, -0.063), 1.7, (0, 0, 0), R3),
    ("lclavicle", "thorax", (0.953, 0.23, -0.197), 3.4, (0, 0, 0), ("ry", "rz")),
    ("lhumerus", "lclavicle", (1, 0, 0), 5.1, (180, -30, -90), R3),
    ("lradius", "lhumerus", (1, 0, 0), 3.7, (180, -30, -90), ("rx",)),
    ("lwrist", "lradius", (1, 0, 0), 1.9, (0, 90, 90), ("ry",)),
    ("lhand", "lwrist", (1, 0, 0), 0.6, (0, 90, 90), ("rx", "rz")),
    ("lfingers", "lhand", (1, 0, 0), 0.5, (0, 90, 90), ("rx",)),
    ("lthumb", "lwrist", (0.707107, 0, 0.707107), 0.7, (-90, 45, 0), ("rx", "rz")),
]


def cmu_bones() -> list[tuple]:
    """The bones of a CMU-like skeleton, parents first: (name, parent, direction, length, axis, dofs)."""
    out = []
    for name, par, d, length, ax, dofs in _LEFT_AND_SPINE:
        out.append((name, par, d, length, ax, dofs))
        if name[0] == "l" and name not in ("lowerback", "lowerneck"):
            mirror = lambda n: "r" + n[1:] if n[0] == "l" and n not in ("lowerback", "lowerneck") else n  # noqa: E731
            out.append((mirror(name), mirror(par), (-d[0], d[1], d[2]), length, (ax[0], -ax[1], -ax[2]), dofs))
    return out


def asf_text(
    bones=None,
    *,
    length_unit=0.45,
    angle="deg",
    root_order="TX TY TZ RX RY RZ",
    root_axis="XYZ",
    position=(0, 0, 0),
    orientation=(0, 0, 0),
    limits=True,
) -> str:
    """An ASF file's text for ``bones`` (default :func:`cmu_bones`); angles in degrees, converted for ``rad``."""
    bones = cmu_bones() if bones is None else bones
    k = 1.0 if angle == "deg" else np.pi / 180
    lines = [
        "# test skeleton",
        ":version 1.10",
        ":name test",
        ":units",
        "  mass 1.0",
        f"  length {length_unit}",
        f"  angle {angle}",
        ":documentation",
        "   written by tests/motion/asf_build.py",
        ":root",
        f"   order {root_order}",
        f"   axis {root_axis}",
        "   position " + " ".join(map(str, position)),
        "   orientation " + " ".join(repr(float(a) * k) for a in orientation),
        ":bonedata",
    ]
    for i, (name, _, d, length, ax, dofs) in enumerate(bones, 1):
        lines += [
            "  begin",
            f"     id {i}",
            f"     name {name}",
            "     direction " + " ".join(repr(float(x)) for x in d),
            f"     length {length}",
            "     axis " + " ".join(repr(float(a) * k) for a in ax) + "  XYZ",
        ]
        if dofs:
            lines.append("    dof " + " ".join(dofs))
            if limits:
                lims = [f"({-170.0 * k!r} {170.0 * k!r})" for _ in dofs]
                lines.append("    limits " + lims[0])
                lines += ["           " + x for x in lims[1:]]
        lines.append("  end")
    children: dict[str, list[str]] = {}
    for name, par, *_ in bones:
        children.setdefault(par, []).append(name)
    lines += [":hierarchy", "  begin"] + [f"    {p} {' '.join(c)}" for p, c in children.items()] + ["  end"]
    return "\n".join(lines) + "\n"


def smooth_values(bones=None, n_frames=40, *, seed=0, amplitude=25.0, travel=(0.0, 0.0, 8.0)) -> dict:
    """{bone: (T, k)} smooth dof values in degrees; the root: (T, 6) TX TY TZ RX RY RZ walking along ``travel``
    (file units over the clip) at hip height."""
    bones = cmu_bones() if bones is None else bones
    rng = np.random.default_rng(seed)
    t = np.linspace(0.0, 1.0, n_frames)[:, None]
    out = {"root": None}  # first, as in CMU's files
    for name, _, _, _, _, dofs in bones:
        if dofs:
            a = rng.uniform(-amplitude, amplitude, (1, len(dofs)))
            f = rng.uniform(0.5, 2.0, (1, len(dofs)))
            out[name] = a * np.sin(2 * np.pi * f * t + rng.uniform(0, 6, (1, len(dofs))))
    root = np.zeros((n_frames, 6))
    root[:, :3] = np.array([0.0, 16.5, 0.0]) + t * np.asarray(travel)
    root[:, 3:] = rng.uniform(-8, 8, (1, 3)) * np.sin(2 * np.pi * t + rng.uniform(0, 6, (1, 3)))
    root[:, 4] += 30.0 * t[:, 0]  # a turn
    out["root"] = root
    return out


def amc_text(values: dict, order=None, *, first=1, header=(":FULLY-SPECIFIED", ":DEGREES")) -> str:
    """An AMC file's text: ``values`` {bone: (T, k)}, bones written in ``order`` (default: the dict's)."""
    order = list(values) if order is None else order
    n = len(next(iter(values.values())))
    lines = ["#!OML:ASF test.asf", *header]
    for f in range(n):
        lines.append(str(first + f))
        for b in order:
            lines.append(b + " " + " ".join(f"{x:.6f}" for x in values[b][f]))
    return "\n".join(lines) + "\n"


def write_trial(folder, name="01_01", *, n_frames=40, seed=0, asf=None, values=None) -> tuple[Path, Path]:
    """Write ``folder/01.asf`` (or ``asf`` text) and ``folder/NAME.amc``; returns (asf path, amc path)."""
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    a = folder / (name.split("_")[0] + ".asf")
    a.write_text(asf_text() if asf is None else asf)
    m = folder / f"{name}.amc"
    m.write_text(amc_text(smooth_values(n_frames=n_frames, seed=seed) if values is None else values))
    return a, m
