"""Dataset configuration (TOML).

Example (``samples/datasets/tiny.toml`` is a complete one)::

    [dataset]
    fps = 30.0
    seconds = 3.0             # every motion is cut or generated to this length; a motion file with less
                              # capture after `start` gives shorter clips, which `dataset make` says before
                              # it simulates (and refuses a start past the end)
    cross_splits = false      # also simulate held-out garments on training motions and vice versa
    held_out_kinds = []       # garment kinds that only held-out entries may use (never trained on)
    held_out_motions = []     # motion kinds / motion file names / families likewise
    val_kinds = []            # garment kinds that only validation entries (split = "val") may use
    val_motions = []          # motion kinds / motion file names / families likewise
    roots = []                # read-only dataset roots (packs, folders of packs; relative to this config)
                              # read where they exist: a sample one holds is done and not made again
    order = "body-major"      # the order samples are made in: "body-major" (held-out ones first,
                              # then body, motion, garment: a run stopped early has every garment and
                              # motion of the bodies it reached) or "spread" (a fixed pseudo-random
                              # order by sample name, a held-out sample after every two training ones:
                              # any prefix covers every garment, body and motion about evenly -- for
                              # datasets grown with --limit over many runs)
    spread = 0                # order "spread": training samples made between two held-out ones (0: 2)

    [quality]                 # the gate every sample must pass (see segadeform.dataset.quality)
    max_strain = 1.0          # largest |edge length / rest - 1| ...
    max_strained_edges = 0.0  # ... that more than this share of the edges may reach (0: no edge)
    min_stretch = 0.0         # an edge counts past max_strain only when also longer than its rest by more
                              # than this (m): a 1 mm edge stretched to 3 mm is the solver's resolution, not a tear
    max_penetrating = 0.01    # largest fraction of vertices deeper than `penetration_depth`, any frame
    penetration_depth = 0.005
    max_jitter = 0.001        # largest fraction of (frame, vertex) acceleration outliers
    max_body_distance = 0.3   # no piece of the garment (a connected component) may be farther from
                              # the body in any frame (m): a piece that fell off ...
    max_vertex_distance = 1.0 # ... and no vertex farther than this (m): one that flew away
    max_pinched = 0.05        # vertices inside the body where two body parts touch (arm on torso, thigh
                              # on thigh), counted apart from penetration: largest fraction, any frame
    max_slipped = 0.05        # of the vertices on the body at rest (waistband, shoulders, cuffs), the
    slip_distance = 0.08      # largest fraction farther than slip_distance (m) from it in any frame
    min_frames = 0            # a clip that fails keeps its leading frames that pass when there are at least
                              # this many (the simulation is causal: they are the shorter clip's ground
                              # truth); 0: a clip is kept whole or not at all

    [simulate]                # as in a scene (segadeform.settings.simulation)
    effects = ["gravity", "body_collision", "bending", "air_damping"]

    [[fallback]]              # optional, any number, tried in order: a sample the gate rejects is simulated
    quality = 20              # again with these [simulate] keys changed (only the solver's accuracy:
    collision_quality = 4     # quality, collision_quality, impulse_clamp, max_step_motion), and the first
                              # attempt that passes is kept (its settings recorded in the sample)

    [[garments]]
    kind = "skirt"            # segadeform.garments kinds; other keys are GarmentParams
    name = "skirt-long"       # optional: the entry's name in sample ids (default: KIND-INDEX); a changed
                              # garment is a new name beside the old, never an edit of an entry with samples
    # length = [0.3, 0.8]     # a range [lo, hi] instead of a value: each of `count` draws samples it
    # count = 4               #     uniformly (integers for resolution), deterministically from `seed`
    # seed = 0                #     (default: from the name) and its draw number k; named NAME-k
    # mhclo = "../../shared/data/garments/makehuman_split/jeans_m/jeans_m.mhclo"   # a MakeHuman garment
    #                         # fitted to each body instead (kind then only gives its type label)
    # decimate = 0.5          # a MakeHuman garment: the share of its vertices kept (shortest edges first)
    # mesh = "my_skirt.obj"   # or a garment OBJ of your own (`garment fit`, `garment make`, any OBJ in metres,
    #                         # +Y up, on the body): simulated on the [[bodies]] of the shape it was made
    #                         # for (its `# betas:` line; the default shape when it has none); kind gives
    #                         # its type label and pin group
    pin = "waistband"         # optional: the pin group of this garment (with the "pinning" effect):
    #                         # waistband, top, or top+waist (the top and a ring at the body's waist)
    resolution = 2500
    split = "train"           # train | val (held out to choose the model) | test (held out)

    [[bodies]]
    betas = [0.0, 0.0]
    split = "train"           # a "test" body is only used in held-out samples (unseen shape), a "val" one
                              # in validation and held-out ones (never trained on)

    [[motions]]
    kind = "walk"             # procedural kind ...
    seed = 0
    split = "train"           # train | val | test, as garments
    # name = "walk-slow"     # optional: the entry's name in sample ids (default: KIND-sSEED, or the file's stem)
    # family = "walk"        # optional: what the splits hold out together (default: the file's stem, or the
    #                        #     procedural entry itself); entries of one family share a split
    # speed = 1.0            # procedural: speed and amplitude factors (either may be a range with count)
    # amplitude = 1.0
    # file = "../motions/walk.npz"   # ... or a motion file (relative to this config; BVH retargeted
    # start = 2.0                    #     onto each body, feet on the floor; an .fbx through Blender, its
    #                                #     default animation, converted once), from `start` seconds
    # ease_in = 0.0          # procedural: seconds blending in from the rest pose (default 1.0)
    # count = 3              # procedural: seeds seed .. seed+2; speed / amplitude may be ranges;
    #                        # files: `start` may be a range (clips of one file); named NAME-k

Splits: a sample is ``train`` when its garment, motion and body are all train,
``test`` when garment and motion are both held out (any body), and ``val`` (the split
that chooses the model: a training config's ``data.val_split``) when garment and motion are
both ``val`` and its body is not ``test``; with ``cross_splits`` the mixed ones of train and
test are made too, as ``test-garment``, ``test-motion`` and ``test-body`` (mixes with ``val``
are not made).  Every draw of an entry has the entry's split; a motion file, motion family
or MakeHuman garment used by a held-out (or validation) entry may not be used by a
training one, nor a ``held_out_kinds`` / ``held_out_motions`` (``val_kinds`` /
``val_motions``) kind or family; a validation sample may use nothing of the test split.

Growing a dataset: entries added to a config, or a larger ``count``, only add
samples -- draw k of an entry depends on the entry and k alone, never on the
count (see :mod:`.make` for what is checked when a dataset is continued).
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
import logging
import re
from pathlib import Path

import numpy as np

from ..bounds import check_betas
from ..errors import FileFormatError, InputError
from ..garments import GARMENT_KINDS, WAISTBAND_KINDS, GarmentParams
from ..io.toml import key, key_line, read_table, read_toml
from ..motion.procedural import MOTION_KINDS
from ..settings.simulation import PIN_GROUPS, SimSettings, parse_simulate_table

__all__ = ["GarmentSpec", "MotionEntry", "QualitySpec", "DatasetConfig", "load_dataset_config", "SAMPLE_ORDERS"]

SAMPLE_ORDERS = ("body-major", "spread")

log = logging.getLogger(__name__)


#: the motion files a dataset reads: those `segadeform.motion.load_motion` reads, and FBX (its default animation,
#: through Blender: `segadeform.physics.fbx.fbx_cached_bvh`)
MOTION_FILE_TYPES = (".bvh", ".amc", ".npz", ".glb", ".gltf", ".fbx")


@dataclasses.dataclass(frozen=True)
class GarmentSpec:
    name: str
    kind: str
    params: GarmentParams
    split: str
    pin: str | None = None  # overrides simulate.pin for this garment
    mhclo: Path | None = None  # a MakeHuman garment fitted to each body (instead of a procedural one)
    decimate: float | None = None  # a MakeHuman garment's share of vertices kept (shortest edges collapsed first)
    #: a garment OBJ of the user's (instead of a procedural one), simulated on the bodies of the shape it was made
    #: for: ``mesh_betas``, its ``# betas:`` record (``()``: the default shape, also when it records none)
    mesh: Path | None = None
    mesh_betas: tuple[float, ...] = ()

    def sits_on(self, betas) -> bool:
        """Whether this garment is simulated on a body of shape ``betas``: every garment is but a garment OBJ
        (``mesh``), which sits on the shape it was made for alone (compared with zeros appended, to 1e-4)."""
        if self.mesh is None:
            return True
        a, b = np.asarray(self.mesh_betas, np.float64), np.asarray(betas, np.float64)
        n = max(a.size, b.size)
        return bool(np.allclose(np.pad(a, (0, n - a.size)), np.pad(b, (0, n - b.size)), rtol=0.0, atol=1e-4))


@dataclasses.dataclass(frozen=True)
class MotionEntry:
    name: str
    split: str
    kind: str | None = None
    seed: int = 0
    speed: float = 1.0
    amplitude: float = 1.0
    file: Path | None = None
    start: float = 0.0  # seconds into the file where the clip begins
    ease_in: float = 1.0  # procedural: seconds blending in from the rest pose
    family: str = ""  # what splits hold out together (default: the file's stem, or the procedural entry)


@dataclasses.dataclass(frozen=True)
class QualitySpec:
    max_strain: float = 1.0
    max_strained_edges: float = 0.0  # share of edges allowed past max_strain (a few local snags)
    min_stretch: float = dataclasses.field(default=0.0, metadata={"range": (0.0, 1.0)})  # m: see the docstring
    max_penetrating: float = 0.01
    penetration_depth: float = 0.005
    max_jitter: float = 0.001
    max_body_distance: float = 0.3  # no piece (connected component) may be farther than this from the body (m)
    max_vertex_distance: float = 1.0  # and no vertex farther than this (m)
    max_pinched: float = 0.05  # largest fraction of vertices inside the body where two body parts touch
    max_slipped: float = 0.05  # largest fraction of the vertices on the body at rest ...
    slip_distance: float = 0.08  # ... farther than this from it (m), any frame
    # a clip that fails keeps its longest passing run of leading frames when it is at least this long (0: whole
    # clips only); the simulation is causal, so those frames are the ground truth of the shorter clip
    min_frames: int = dataclasses.field(default=0, metadata={"range": (0, 100_000)})


@dataclasses.dataclass(frozen=True)
class DatasetConfig:
    garments: tuple
    bodies: tuple  # tuples of betas
    motions: tuple
    simulate: SimSettings
    quality: QualitySpec = QualitySpec()
    fps: float = 30.0
    seconds: float = 3.0
    cross_splits: bool = False
    path: Path | None = None
    text: str = ""
    body_splits: tuple = ()  # "train" | "test" per body (default: all train)
    held_out_kinds: tuple = ()  # garment kinds only held-out (test) entries use
    held_out_motions: tuple = ()  # motion families only held-out (test) entries use
    order: str = "body-major"  # "body-major" | "spread": the order samples are made in
    val_kinds: tuple = ()  # garment kinds only validation entries use
    val_motions: tuple = ()  # motion families only validation entries use
    roots: tuple = ()  # read-only dataset roots (packs ...) read where they exist
    spread: int = 0  # order "spread": training samples between two held-out ones (0: 2)
    fallbacks: tuple = ()  # [[fallback]] tables, as sorted (key, value) pairs: see attempt_settings
    motion_entries: tuple = ()  # the [[motions]] table (0-based) each of `motions` was drawn from

    def motion_where(self, mi: int) -> tuple[str, int | None]:
        """``("motions[i]", line)``: the ``[[motions]]`` table motion ``mi`` was drawn from and its line in the
        config file (None where unknown), for errors found once the config is read."""
        i = self.motion_entries[mi] if mi < len(self.motion_entries) else None
        if i is None:
            return f"motion {self.motions[mi].name!r}", None
        return f"motions[{i}]", key_line(self.path, f"motions[{i}]") if self.path is not None else None

    def digest(self) -> str:
        return hashlib.sha256(self.text.encode()).hexdigest()[:16]

    @property
    def attempts(self) -> int:
        """How many simulations a sample may take: the [simulate] settings, then each [[fallback]]."""
        return 1 + len(self.fallbacks)

    def attempt_settings(self, garment: GarmentSpec, attempt: int = 0) -> SimSettings:
        """The settings of ``garment``'s samples on attempt ``attempt`` (0: [simulate] with the garment's own pin;
        k > 0: that with the k-th [[fallback]]'s keys changed)."""
        if not 0 <= attempt < self.attempts:
            raise InputError("no such simulation attempt", expected=f"0..{self.attempts - 1}", got=attempt)
        st = self.simulate.replace(pin=garment.pin) if garment.pin else self.simulate
        return st.replace(**dict(self.fallbacks[attempt - 1])) if attempt else st


#: the [simulate] keys a [[fallback]] may change: how accurately the solver steps and collides, not the cloth, the
#: body or the scene (a sample kept on a fallback is the same physics, solved more finely)
FALLBACK_KEYS = ("quality", "collision_quality", "impulse_clamp", "max_step_motion")


def _fallbacks(tables, sim: SimSettings, p) -> tuple:
    """``[[fallback]]`` tables -> sorted (key, value) pairs each, checked against ``sim``."""
    if not isinstance(tables, list) or not all(isinstance(t, dict) for t in tables):
        raise FileFormatError("fallback must be [[fallback]] tables", path=p, got=tables)
    out = []
    for i, t in enumerate(tables):
        bad = sorted(set(t) - set(FALLBACK_KEYS))
        if bad:
            raise FileFormatError(
                f"fallback[{i}] may not change {bad[0]}", path=p, expected=" | ".join(FALLBACK_KEYS), got=bad[0]
            )
        if not t:
            raise FileFormatError(f"fallback[{i}] changes nothing", path=p, expected=" | ".join(FALLBACK_KEYS))
        floats = ("impulse_clamp", "max_step_motion")
        kw = {k: float(v) if k in floats and type(v) is int else v for k, v in t.items()}
        try:
            sim.replace(**kw)
        except InputError as e:
            raise FileFormatError(f"fallback[{i}]: {e}", path=p) from None
        pairs = tuple(sorted(kw.items()))
        if pairs in out or all(getattr(sim, k) == v for k, v in pairs):
            raise FileFormatError(f"fallback[{i}] repeats an earlier attempt", path=p, got=dict(pairs))
        out.append(pairs)
    return tuple(out)


#: the splits an entry may name: trained on, held out for choosing the model, held out for the report
SPLITS = ("train", "val", "test")


def _split(d, where, what):
    s = d.get("split", "train")
    if s not in SPLITS:
        raise FileFormatError(f"{what}.split must be 'train', 'val' or 'test'", path=where, got=s)
    return s


#: garment parameters that may be ranges, and whether they are integers
_GARMENT_RANGED = {
    "length": False,
    "flare": False,
    "ease": False,
    "sleeve": False,
    "resolution": True,
    "subdivisions": True,
}


def _entry_seed(seed, name: str) -> int:
    """An entry's sampling seed: the config's ``seed``, else a stable number from its name."""
    if seed is None:
        return int.from_bytes(hashlib.sha256(name.encode()).digest()[:4], "little")
    return int(seed)


def draw_values(ranges: dict, integer: dict, seed: int, k: int) -> dict:
    """Draw ``k`` of an entry: every ``key: [lo, hi]`` of ``ranges`` sampled uniformly (integers in
    ``lo..hi`` where ``integer[key]``), from a generator seeded by ``(seed, k)`` alone -- so a draw
    never changes when the count grows.  Keys are drawn in sorted order."""
    rng = np.random.default_rng([int(seed) & 0xFFFFFFFF, int(k)])
    out = {}
    for name in sorted(ranges):
        lo, hi = ranges[name]
        out[name] = int(rng.integers(lo, hi + 1)) if integer.get(name) else float(lo + (hi - lo) * rng.random())
    return out


def _ranges(d: dict, allowed: dict, p, what: str) -> dict:
    """Pop the ``[lo, hi]`` ranges out of entry ``d`` (validated)."""
    out = {}
    for name in [k for k, v in d.items() if isinstance(v, list)]:
        v = d.pop(name)
        if name not in allowed:
            raise FileFormatError(
                f"{what}.{name} cannot be a range",
                path=p,
                expected=" | ".join(sorted(allowed)) or "no range here",
                got=v,
            )
        num = all(isinstance(x, (int, float)) and not isinstance(x, bool) for x in v)
        if len(v) != 2 or not num or v[0] > v[1] or (allowed[name] and not all(isinstance(x, int) for x in v)):
            raise FileFormatError(
                f"{what}.{name} must be a range [lo, hi] with lo <= hi",
                path=p,
                expected="two integers" if allowed[name] else "two numbers",
                got=v,
            )
        out[name] = (v[0], v[1])
    return out


def _count(d: dict, p, what: str) -> int | None:
    c = d.pop("count", None)
    if c is not None and (not isinstance(c, int) or isinstance(c, bool) or not 1 <= c <= 100_000):
        raise FileFormatError(f"{what}.count must be an integer 1..100000", path=p, got=c)
    return c


@dataclasses.dataclass(frozen=True)
class _DatasetTable:
    """``[dataset]`` (what each key takes: :func:`segadeform.io.toml.read_table`)."""

    fps: float = key(30.0, range=(1, 240))
    seconds: float = key(3.0, range=(0.1, 60))
    cross_splits: bool = False
    held_out_kinds: tuple = ()
    held_out_motions: tuple = ()
    order: str = key("body-major", choices=SAMPLE_ORDERS)
    val_kinds: tuple = ()
    val_motions: tuple = ()
    roots: tuple = key((), types=(str, list))
    spread: int = key(0, range=(0, 1000))


#: the keys of a [[motions]] entry: a procedural one (kind) and a motion file's
#: the keys of a [[garments]] entry besides GarmentParams' fields, and of a [[bodies]] entry (the parser's and the
#: docstring test's one list)
_GARMENT_KEYS = frozenset({"kind", "name", "split", "pin", "mhclo", "mesh", "decimate", "count", "seed"})
_BODY_KEYS = ("betas", "split")
_MOTION_KEYS = {
    "kind": frozenset({"kind", "seed", "speed", "amplitude", "name", "count", "ease_in", "family", "split"}),
    "file": frozenset({"file", "name", "start", "count", "seed", "family", "split"}),
}


def _said(v) -> str:
    """A value as an error quotes it: its TOML-ish repr, cut to 40 characters."""
    r = repr(v)
    return r if len(r) <= 40 else r[:37] + "..."


def _unknown_key(where: str, name: str, allowed, p, hint: str = "") -> FileFormatError:
    """``unknown key where.name`` as :func:`segadeform.io.toml.read_table` says it (the allowed keys, the one given),
    with a hint where the key belongs elsewhere: a ``[dataset]`` key (``seconds``, ``fps``) in an entry is one for
    every sample, not for the entry."""
    if not hint and name in {f.name for f in dataclasses.fields(_DatasetTable)}:
        hint = "a [dataset] key (one for every sample): put it in [dataset]"
    return FileFormatError(
        f"unknown key {where}.{name}",
        path=p,
        line=key_line(p, where, name),
        expected=", ".join(sorted(allowed)),
        got=name + (f", {hint}" if hint else ""),
    )


def _at_entry(e: InputError, p, where: str) -> InputError:
    """Error ``e`` about entry ``where`` (``garments[2]``) of config ``p``, given the line of the key it names
    (``garments[2].mhclo``) or else of the entry's table, as the [dataset] and [quality] errors name theirs."""
    if e.line is not None or e.path is None or Path(e.path) != Path(p):
        return e
    m = re.search(rf"{re.escape(where)}\.(\w+)", e.problem)
    line = (key_line(p, where, m.group(1)) if m else None) or key_line(p, where)
    return type(e)(e.problem, path=e.path, line=line, expected=e.expected, got=e.got)


def load_dataset_config(path, *, require_files: bool = True) -> DatasetConfig:
    """Read and check a dataset config.  ``require_files=False`` lets MakeHuman files be absent (training's
    physics pairs on a machine without ``../shared``, whose garments were made elsewhere into its cache)."""
    p = Path(path)
    data, text = read_toml(p, "dataset config")
    known = {"dataset", "quality", "simulate", "fallback", "garments", "bodies", "motions"}
    bad = sorted(set(data) - known)
    if bad:
        raise FileFormatError(f"unknown table [{bad[0]}]", path=p, expected=", ".join(sorted(known)))
    ds = read_table(data.get("dataset", {}), _DatasetTable, where="dataset", path=p)
    order = ds.get("order", "body-major")
    held_kinds = tuple(ds.get("held_out_kinds", ()))
    held_motions = tuple(ds.get("held_out_motions", ()))
    val_kinds = tuple(ds.get("val_kinds", ()))
    val_motions = tuple(ds.get("val_motions", ()))
    for field, kinds in (("held_out_kinds", held_kinds), ("val_kinds", val_kinds)):
        if not all(isinstance(k, str) and k in GARMENT_KINDS for k in kinds):
            raise FileFormatError(
                f"dataset.{field} must list garment kinds", path=p, expected=" | ".join(GARMENT_KINDS), got=list(kinds)
            )
    for field, fams in (("held_out_motions", held_motions), ("val_motions", val_motions)):
        if not all(isinstance(k, str) for k in fams):
            raise FileFormatError(f"dataset.{field} must list motion kinds or families", path=p, got=list(fams))
    both = sorted((set(held_kinds) & set(val_kinds)) | (set(held_motions) & set(val_motions)))
    if both:
        raise FileFormatError(
            f"{both[0]!r} is held out for both validation and test",
            path=p,
            expected="validation and test kinds and motion families apart",
        )
    roots = ds.get("roots", [])
    if isinstance(roots, str):
        roots = [roots]
    if not isinstance(roots, list) or not all(isinstance(r, str) for r in roots):
        raise FileFormatError("dataset.roots must list paths (packs, folders of packs)", path=p, got=roots)
    roots = tuple((p.parent / r).resolve() for r in roots)
    spread = ds.get("spread", 0)
    q = QualitySpec(**read_table(data.get("quality", {}), QualitySpec, where="quality", path=p))
    garments, names = [], set()
    for i, g in enumerate(data.get("garments", [])):
        try:
            g = dict(g)
            kind = g.pop("kind", None)
            if kind not in GARMENT_KINDS:
                raise FileFormatError(
                    f"garments[{i}].kind is not a garment kind", path=p, expected=" | ".join(GARMENT_KINDS), got=kind
                )
            split = _split(g, p, f"garments[{i}]")
            g.pop("split", None)
            name = g.pop("name", None) or f"{kind}-{i}"
            pin = g.pop("pin", None)
            mhclo = g.pop("mhclo", None)
            mesh = g.pop("mesh", None)
            if mesh is not None and mhclo is not None:
                raise FileFormatError(
                    f"garments[{i}].mesh is one garment OBJ, as it is",
                    path=p,
                    expected="mesh = 'FILE.obj' or mhclo = 'FILE.mhclo', not both",
                    got="both",
                )
            decimate = g.pop("decimate", None)
            count = _count(g, p, f"garments[{i}]")
            seed = g.pop("seed", None)
            if seed is not None and (not isinstance(seed, int) or isinstance(seed, bool)):
                raise FileFormatError(f"garments[{i}].seed must be an integer", path=p, got=seed)
            ranged = _ranges(g, _GARMENT_RANGED, p, f"garments[{i}]")
            if mhclo is not None:
                mhclo = (p.parent / mhclo).resolve()
                if require_files and not mhclo.is_file():
                    raise FileFormatError(f"garments[{i}].mhclo does not exist", path=p, got=str(mhclo))
                if require_files:  # read now, not after the first samples of `dataset make` (an OBJ given as mhclo)
                    from ..io.mhclo import read_mhclo

                    try:
                        read_mhclo(mhclo)
                    except InputError as e:
                        raise FileFormatError(f"garments[{i}].mhclo: {e}", path=p) from None
                if ranged or (count or 1) > 1:
                    raise FileFormatError(
                        f"garments[{i}]: a MakeHuman garment has no parameters to draw",
                        path=p,
                        expected="no ranges and no count with mhclo",
                    )
            mesh_betas: tuple[float, ...] = ()
            if mesh is not None:
                if not isinstance(mesh, str) or count is not None or ranged or decimate is not None:
                    raise FileFormatError(
                        f"garments[{i}].mesh is one garment OBJ, as it is",
                        path=p,
                        expected="mesh = 'FILE.obj' without count, ranges or decimate",
                        got=mesh if not isinstance(mesh, str) else "a count, range or decimate beside it",
                    )
                mesh = (p.parent / mesh).resolve()
                if require_files:  # found and read now, not hours into `dataset make`
                    from ..io import read_mesh
                    from ..io.obj import recorded_betas

                    if not mesh.is_file():
                        raise FileFormatError(f"garments[{i}].mesh does not exist", path=p, got=str(mesh))
                    try:
                        read_mesh(mesh)
                        mesh_betas = recorded_betas(mesh) or ()
                    except InputError as e:
                        raise FileFormatError(f"garments[{i}].mesh: {e}", path=p) from None
            if decimate is not None:
                if mhclo is None:
                    raise FileFormatError(
                        f"garments[{i}].decimate is for MakeHuman garments (a procedural garment's resolution is its "
                        "own parameter)",
                        path=p,
                        expected="mhclo = ... beside decimate",
                    )
                ok = isinstance(decimate, (int, float)) and not isinstance(decimate, bool)
                if not (ok and 0 < decimate < 1):
                    raise FileFormatError(
                        f"garments[{i}].decimate must be the share of vertices kept",
                        path=p,
                        expected="a number in (0, 1)",
                        got=decimate,
                    )
                decimate = float(decimate)
            if pin is not None and pin not in PIN_GROUPS:
                raise FileFormatError(
                    f"garments[{i}].pin is not a pin group", path=p, expected=" | ".join(PIN_GROUPS), got=pin
                )
            if split != "test" and kind in held_kinds:
                raise FileFormatError(
                    f"garments[{i}] is a {split} garment of the held-out kind {kind!r}",
                    path=p,
                    expected="split = 'test' for kinds in dataset.held_out_kinds",
                )
            if split != "val" and kind in val_kinds:
                raise FileFormatError(
                    f"garments[{i}] is a {split} garment of the validation kind {kind!r}",
                    path=p,
                    expected="split = 'val' for kinds in dataset.val_kinds",
                )
            if count is None and not ranged:
                draws = [(name, {})]
            elif not ranged and count > 1:
                raise FileFormatError(
                    f"garments[{i}]: count = {count} with no range draws {count} identical garments",
                    path=p,
                    expected="at least one parameter as a range [lo, hi]",
                )
            else:
                es = _entry_seed(seed, name)
                draws = [(f"{name}-{k}", draw_values(ranged, _GARMENT_RANGED, es, k)) for k in range(count or 1)]
            known = {f.name for f in dataclasses.fields(GarmentParams)}
            extra = sorted(set(g) - known)
            if extra:  # a typo (`mhcl`, `spilt`) said as the other tables say it, not as Python's TypeError
                allowed = known | _GARMENT_KEYS
                raise _unknown_key(f"garments[{i}]", extra[0], allowed, p)
            for dname, vals in draws:
                if dname in names:
                    raise FileFormatError(f"garment name {dname!r} is used twice", path=p)
                names.add(dname)
                try:
                    params = GarmentParams(**g, **vals)
                except (TypeError, InputError) as e:
                    raise FileFormatError(f"garments[{i}] ({dname}): {e}", path=p) from None
                if params.waist_ease is not None and kind not in WAISTBAND_KINDS:
                    raise FileFormatError(
                        f"garments[{i}] ({dname}): waist_ease is for garments with a waistband",
                        path=p,
                        expected=" | ".join(WAISTBAND_KINDS),
                        got=kind,
                    )
                garments.append(
                    GarmentSpec(dname, kind, params, split, pin, mhclo, decimate, mesh=mesh, mesh_betas=mesh_betas)
                )
        except InputError as e:  # the entry's line, as the other tables' errors name theirs
            raise _at_entry(e, p, f"garments[{i}]") from None
    bodies, body_splits = [], []
    tables = data.get("bodies", [{"betas": []}])
    if not isinstance(tables, list):  # [bodies] for [[bodies]]: a traceback (a user's trial)
        raise FileFormatError("bodies must be [[bodies]] tables", path=p, got=f"[bodies] ({type(tables).__name__})")
    for i, b in enumerate(tables):
        try:
            if not isinstance(b, dict):
                raise FileFormatError(f"bodies[{i}] must be a [[bodies]] table", path=p, got=type(b).__name__)
            extra = sorted(set(b) - set(_BODY_KEYS))
            if extra:  # (said as a Python dict, without the key's line: a user's trial)
                raise _unknown_key(f"bodies[{i}]", extra[0], _BODY_KEYS, p)
            betas = b.get("betas", [])
            if not isinstance(betas, list) or not all(
                isinstance(x, (int, float)) and not isinstance(x, bool) for x in betas
            ):
                raise FileFormatError(
                    f"bodies[{i}].betas must be a list of numbers",
                    path=p,
                    expected="betas = [numbers]",
                    got=_said(betas),
                )
            check_betas(betas, path=p, what=f"bodies[{i}].betas")  # (found when its garment was made, the file unnamed)
            bodies.append(tuple(float(x) for x in betas))
            body_splits.append(_split(b, p, f"bodies[{i}]"))
        except InputError as e:  # the entry's line, as the other tables' errors name theirs
            raise _at_entry(e, p, f"bodies[{i}]") from None
    for g in garments:
        if not any(g.sits_on(b) for b in bodies):
            shape = ",".join(f"{x:g}" for x in g.mesh_betas) or "0 (the default shape)"
            raise FileFormatError(
                f"garments ({g.name}): the garment mesh was made for betas {shape}, and no [[bodies]] entry has that "
                "shape",
                path=p,
                expected=f"a [[bodies]] entry with betas = [{','.join(f'{x:g}' for x in g.mesh_betas)}], or the "
                "garment fitted for a listed shape (`segadeform garment fit ... --betas ...`)",
                got=", ".join(str(list(b)) for b in bodies),
            )
    for i, b in enumerate(bodies):  # (a test body added for a garment OBJ made nothing, unsaid: an ML user's trial)
        if not any(g.sits_on(b) for g in garments):
            log.warning(
                "%s: bodies[%d] (betas %s) gets no samples: each garment is a garment OBJ (mesh =), simulated on "
                "the shape it was made for alone; `segadeform garment fit ... --betas` makes one for this shape, and "
                "a MakeHuman garment (mhclo =) is fitted to every shape",
                p.name,
                i,
                list(b),
            )
    motions, mnames, entries = [], set(), []
    for i, m in enumerate(data.get("motions", [])):
        try:
            m = dict(m)
            what = f"motions[{i}]"
            split = _split(m, p, what)
            m.pop("split", None)
            if ("kind" in m) == ("file" in m):
                raise FileFormatError(f"{what} needs exactly one of kind or file", path=p)
            if "kind" in m and m["kind"] not in MOTION_KINDS:
                raise FileFormatError(
                    f"{what}.kind is not a motion kind", path=p, expected=" | ".join(MOTION_KINDS), got=m["kind"]
                )
            allowed = _MOTION_KEYS["kind" if "kind" in m else "file"]
            extra = sorted(set(m) - allowed)
            if extra:
                other = "file" if "kind" in m else "kind"
                hint = (
                    f"a key of motions with {other}, not {'kind' if other == 'file' else 'file'}"
                    if extra[0] in _MOTION_KEYS[other]
                    else ""
                )
                raise _unknown_key(what, extra[0], allowed, p, hint)
            count = _count(m, p, what)
            ranged = _ranges(m, {"speed": False, "amplitude": False} if "kind" in m else {"start": False}, p, what)
            f = (p.parent / m["file"]).resolve() if "file" in m else None
            if f is not None and require_files and not f.is_file():  # found now, not hours into `dataset make`
                raise FileFormatError(f"{what}.file does not exist", path=p, got=str(f))
            if f is not None and f.suffix.lower() not in MOTION_FILE_TYPES:  # not after other samples were simulated
                raise FileFormatError(
                    f"{what}.file is not a motion file",
                    path=p,
                    expected=" | ".join(MOTION_FILE_TYPES),
                    got=f.suffix or f.name,
                )
            seed = m.get("seed", 0)
            if not isinstance(seed, int) or isinstance(seed, bool):
                raise FileFormatError(f"{what}.seed must be an integer", path=p, got=seed)
            base = m.get("name") or (f.stem if f else f"{m['kind']}-s{seed}")
            family = m.get("family") or (f.stem if f else base)  # a procedural entry is its own family
            if not isinstance(family, str):
                raise FileFormatError(f"{what}.family must be a name", path=p, got=family)
            names_of = {family, *((f.stem, f.name) if f is not None else (m["kind"],))}
            if split != "test" and names_of & set(held_motions):
                raise FileFormatError(
                    f"{what} is a {split} motion of the held-out family {family!r}",
                    path=p,
                    expected="split = 'test' for motions in dataset.held_out_motions",
                )
            if split != "val" and names_of & set(val_motions):
                raise FileFormatError(
                    f"{what} is a {split} motion of the validation family {family!r}",
                    path=p,
                    expected="split = 'val' for motions in dataset.val_motions",
                )
            if count is None and not ranged:
                draws = [(base, 0, {})]
            elif not ranged and f is not None and (count or 1) > 1:
                raise FileFormatError(
                    f"{what}: count = {count} of one file with no start range repeats one clip",
                    path=p,
                    expected="start = [lo, hi]",
                )
            else:
                es = _entry_seed(m.get("seed"), base)
                draws = [(f"{base}-{k}", k, draw_values(ranged, {}, es, k)) for k in range(count or 1)]
            for dname, k, vals in draws:
                if dname in mnames:
                    raise FileFormatError(f"motion name {dname!r} is used twice", path=p)
                mnames.add(dname)
                kw = dict(
                    speed=vals.get("speed", m.get("speed", 1.0)),
                    amplitude=vals.get("amplitude", m.get("amplitude", 1.0)),
                    start=vals.get("start", m.get("start", 0.0)),
                    ease_in=m.get("ease_in", 1.0),
                )
                for name, v in kw.items():  # numbers, not strings of them ("1.0" was read as 1.0)
                    if isinstance(v, bool) or not isinstance(v, (int, float)):
                        raise FileFormatError(f"{what}.{name} must be a number", path=p, got=repr(v)[:40])
                    kw[name] = float(v)
                if kw["start"] < 0 or kw["ease_in"] < 0:
                    raise FileFormatError(
                        f"{what}: start and ease_in must be >= 0", path=p, got=(kw["start"], kw["ease_in"])
                    )
                entries.append(i)
                motions.append(
                    MotionEntry(
                        name=dname,
                        split=split,
                        kind=m.get("kind"),
                        seed=seed + k if f is None else 0,
                        file=f,
                        family=family,
                        **kw,
                    )
                )
        except InputError as e:  # the entry's line, as the other tables' errors name theirs
            raise _at_entry(e, p, f"motions[{i}]") from None
    # one source, one side: a motion file or a MakeHuman garment is either trained on or held out
    for what, items in (
        ("motion file", [(mo.file, mo.split) for mo in motions if mo.file is not None]),
        ("MakeHuman garment", [(g.mhclo, g.split) for g in garments if g.mhclo is not None]),
        ("garment mesh", [(g.mesh, g.split) for g in garments if g.mesh is not None]),
    ):
        sides = {}
        for src, sp in items:
            sides.setdefault(src, set()).add(sp)
        both = sorted(str(k) for k, v in sides.items() if len(v) > 1)
        if both:
            raise FileFormatError(
                f"the {what} {both[0]} is used by entries of two splits", path=p, expected="each source in one split"
            )
    fam_sides = {}
    for mo in motions:
        fam_sides.setdefault(mo.family, set()).add(mo.split)
    both = sorted(k for k, v in fam_sides.items() if len(v) > 1)
    if both:
        raise FileFormatError(
            f"the motion family {both[0]!r} has entries in two splits",
            path=p,
            expected="a family trained on or held out whole",
        )
    if not garments or not motions:
        raise FileFormatError("a dataset needs at least one [[garments]] and one [[motions]]", path=p)
    sim = parse_simulate_table(data.get("simulate"), where=p)
    fallbacks = _fallbacks(data.get("fallback", []), sim, p)
    fps, seconds = float(ds.get("fps", 30.0)), float(ds.get("seconds", 3.0))
    return DatasetConfig(
        garments=tuple(garments),
        bodies=tuple(bodies),
        motions=tuple(motions),
        simulate=sim,
        fallbacks=fallbacks,
        motion_entries=tuple(entries),
        body_splits=tuple(body_splits),
        held_out_kinds=held_kinds,
        held_out_motions=held_motions,
        val_kinds=val_kinds,
        val_motions=val_motions,
        roots=roots,
        spread=spread,
        quality=q,
        fps=fps,
        seconds=seconds,
        cross_splits=bool(ds.get("cross_splits", False)),
        order=order,
        path=p,
        text=json.dumps(data, sort_keys=True, default=str),
    )
