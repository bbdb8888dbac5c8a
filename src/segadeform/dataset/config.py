"""Dataset configuration (TOML).

Example (``samples/datasets/tiny.toml`` is a complete one)::

    [dataset]
    fps = 30.0
    seconds = 3.0             # every motion is cut or generated to this length
    cross_splits = false      # also simulate held-out garments on training motions and vice versa

    [quality]                 # the gate every sample must pass (see segadeform.dataset.quality)
    max_strain = 1.0          # largest |edge length / rest - 1|
    max_penetrating = 0.01    # largest fraction of vertices deeper than `penetration_depth`, any frame
    penetration_depth = 0.005
    max_jitter = 0.001        # largest fraction of (frame, vertex) acceleration outliers

    [simulate]                # as in a scene (segadeform.physics.settings)
    effects = ["gravity", "body_collision", "bending", "air_damping"]

    [[garments]]
    kind = "skirt"            # segadeform.garments kinds; other keys are GarmentParams
    # mhclo = "../../shared/data/garments/makehuman_split/jeans_m/jeans_m.mhclo"   # a MakeHuman garment
    #                         # fitted to each body instead (kind then only gives its type label)
    pin = "waistband"         # optional: the pin group of this garment (with the "pinning" effect)
    resolution = 2500
    split = "train"           # train | test (held out)

    [[bodies]]
    betas = [0.0, 0.0]
    split = "train"           # a "test" body is only used in held-out samples (unseen shape)

    [[motions]]
    kind = "walk"             # procedural kind ...
    seed = 0
    split = "train"
    # file = "../motions/walk.npz"   # ... or a motion file (relative to this config; BVH retargeted
    # start = 2.0                    #     onto each body, feet on the floor), from `start` seconds

Splits: a sample is ``train`` when its garment, motion and body are all train,
``test`` when garment and motion are both held out (any body); with
``cross_splits`` the mixed ones are made too, as ``test-garment``,
``test-motion`` and ``test-body``.
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
from pathlib import Path
from typing import Optional

from .._toml import read_toml
from ..errors import FileFormatError, InputError
from ..garments import GARMENT_KINDS, GarmentParams
from ..motion.procedural import MOTION_KINDS
from ..physics.settings import SimSettings, parse_simulate_table


__all__ = ["GarmentSpec", "MotionEntry", "QualitySpec", "DatasetConfig", "load_dataset_config"]


@dataclasses.dataclass(frozen=True)
class GarmentSpec:
    name: str
    kind: str
    params: GarmentParams
    split: str
    pin: Optional[str] = None  # overrides simulate.pin for this garment
    mhclo: Optional[Path] = None  # a MakeHuman garment fitted to each body (instead of a procedural one)


@dataclasses.dataclass(frozen=True)
class MotionEntry:
    name: str
    split: str
    kind: Optional[str] = None
    seed: int = 0
    speed: float = 1.0
    amplitude: float = 1.0
    file: Optional[Path] = None
    start: float = 0.0  # seconds into the file where the clip begins


@dataclasses.dataclass(frozen=True)
class QualitySpec:
    max_strain: float = 1.0
    max_penetrating: float = 0.01
    penetration_depth: float = 0.005
    max_jitter: float = 0.001


@dataclasses.dataclass(frozen=True)
class DatasetConfig:
    garments: tuple
    bodies: tuple          # tuples of betas
    motions: tuple
    simulate: SimSettings
    quality: QualitySpec = QualitySpec()
    fps: float = 30.0
    seconds: float = 3.0
    cross_splits: bool = False
    path: Optional[Path] = None
    text: str = ""
    body_splits: tuple = ()  # "train" | "test" per body (default: all train)

    def digest(self) -> str:
        return hashlib.sha256(self.text.encode()).hexdigest()[:16]


def _split(d, where, what):
    s = d.get("split", "train")
    if s not in ("train", "test"):
        raise FileFormatError(f"{what}.split must be 'train' or 'test'", path=where, got=s)
    return s


def load_dataset_config(path) -> DatasetConfig:
    p = Path(path)
    data, text = read_toml(p, "dataset config")
    known = {"dataset", "quality", "simulate", "garments", "bodies", "motions"}
    bad = sorted(set(data) - known)
    if bad:
        raise FileFormatError(f"unknown table [{bad[0]}]", path=p, expected=", ".join(sorted(known)))
    ds = data.get("dataset", {})
    bad = sorted(set(ds) - {"fps", "seconds", "cross_splits"})
    if bad:
        raise FileFormatError(f"unknown key dataset.{bad[0]}", path=p)
    try:
        q = QualitySpec(**data.get("quality", {}))
    except TypeError as e:
        raise FileFormatError(f"[quality]: {e}", path=p) from None
    garments, names = [], set()
    for i, g in enumerate(data.get("garments", [])):
        g = dict(g)
        kind = g.pop("kind", None)
        if kind not in GARMENT_KINDS:
            raise FileFormatError(f"garments[{i}].kind is not a garment kind", path=p,
                                  expected=" | ".join(GARMENT_KINDS), got=kind)
        split = _split(g, p, f"garments[{i}]")
        g.pop("split", None)
        name = g.pop("name", None) or f"{kind}-{i}"
        pin = g.pop("pin", None)
        mhclo = g.pop("mhclo", None)
        if mhclo is not None:
            mhclo = (p.parent / mhclo).resolve()
            if not mhclo.is_file():
                raise FileFormatError(f"garments[{i}].mhclo does not exist", path=p, got=str(mhclo))
        if pin is not None and pin not in ("waistband", "top"):
            raise FileFormatError(f"garments[{i}].pin must be 'waistband' or 'top'", path=p, got=pin)
        if name in names:
            raise FileFormatError(f"garment name {name!r} is used twice", path=p)
        names.add(name)
        try:
            params = GarmentParams(**g)
        except (TypeError, InputError) as e:
            raise FileFormatError(f"garments[{i}]: {e}", path=p) from None
        garments.append(GarmentSpec(name, kind, params, split, pin, mhclo))
    bodies, body_splits = [], []
    for i, b in enumerate(data.get("bodies", [{"betas": []}])):
        betas = b.get("betas", [])
        if set(b) - {"betas", "split"} or not all(isinstance(x, (int, float)) for x in betas):
            raise FileFormatError(f"bodies[{i}] must be {{betas = [numbers], split = train|test}}", path=p, got=b)
        bodies.append(tuple(float(x) for x in betas))
        body_splits.append(_split(b, p, f"bodies[{i}]"))
    motions, mnames = [], set()
    for i, m in enumerate(data.get("motions", [])):
        m = dict(m)
        split = _split(m, p, f"motions[{i}]")
        if ("kind" in m) == ("file" in m):
            raise FileFormatError(f"motions[{i}] needs exactly one of kind or file", path=p)
        if "kind" in m and m["kind"] not in MOTION_KINDS:
            raise FileFormatError(f"motions[{i}].kind is not a motion kind", path=p,
                                  expected=" | ".join(MOTION_KINDS), got=m["kind"])
        extra = set(m) - {"kind", "file", "seed", "speed", "amplitude", "split", "name", "start"}
        if extra:
            raise FileFormatError(f"unknown key motions[{i}].{sorted(extra)[0]}", path=p)
        f = (p.parent / m["file"]).resolve() if "file" in m else None
        name = m.get("name") or (f.stem if f else f"{m['kind']}-s{m.get('seed', 0)}")
        if name in mnames:
            raise FileFormatError(f"motion name {name!r} is used twice", path=p)
        mnames.add(name)
        motions.append(MotionEntry(name=name, split=split, kind=m.get("kind"), seed=int(m.get("seed", 0)),
                                   speed=float(m.get("speed", 1.0)), amplitude=float(m.get("amplitude", 1.0)), file=f,
                                   start=float(m.get("start", 0.0))))
    if not garments or not motions:
        raise FileFormatError("a dataset needs at least one [[garments]] and one [[motions]]", path=p)
    sim = parse_simulate_table(data.get("simulate"), where=p)
    fps, seconds = float(ds.get("fps", 30.0)), float(ds.get("seconds", 3.0))
    if not (1 <= fps <= 240 and 0.1 <= seconds <= 60):
        raise FileFormatError("dataset.fps / dataset.seconds out of range", path=p, got=(fps, seconds))
    return DatasetConfig(garments=tuple(garments), bodies=tuple(bodies), motions=tuple(motions), simulate=sim,
                         body_splits=tuple(body_splits),
                         quality=q, fps=fps, seconds=seconds, cross_splits=bool(ds.get("cross_splits", False)),
                         path=p, text=json.dumps(data, sort_keys=True, default=str))
