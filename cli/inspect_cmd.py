"""``segadeform inspect PATH``: read any file segadeform understands and summarise it."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import click
import numpy as np

from .main import PathParam, cli


@dataclasses.dataclass
class FrameStats:
    """What ``inspect`` says of a sequence's frames (:func:`frame_stats`).

    Attributes:
        n_frames, n_points: S and N.
        nonfinite: NaN/inf values; bad_frames: the frames holding them (the rest is not computed when there are any).
        far: the largest ``|x|``; lo, hi: the bounds (3,) over all frames.
        step_mean, step_max: a vertex's motion from one frame to the next (metres), its mean and largest;
        step_max_frame: the frame the largest ends at; still: frames identical to the one before.
        centroid_range: how far each frame's centroid ranges over the frames (x, y, z).
    """

    n_frames: int
    n_points: int
    nonfinite: int = 0
    bad_frames: list = dataclasses.field(default_factory=list)
    far: float = 0.0
    lo: np.ndarray = dataclasses.field(default_factory=lambda: np.full(3, np.inf))
    hi: np.ndarray = dataclasses.field(default_factory=lambda: np.full(3, -np.inf))
    step_mean: float = 0.0
    step_max: float = 0.0
    step_max_frame: int = 0
    still: int = 0
    centroid_range: np.ndarray = dataclasses.field(default_factory=lambda: np.zeros(3))


def frame_stats(frames, max_values: int | None = None) -> FrameStats:
    """The statistics of ``frames (S, N, 3)`` (an array or :class:`~segadeform.io.sequence.LazyFrames`), streamed
    over the frames a bounded chunk at a time (``max_values`` coordinates, default
    :data:`~segadeform.io.sequence.CHUNK_VALUES`; at least one frame): a long clip is never held whole, and each
    chunk is upcast to float64 on its own (steps of float32 frames near 1e38 overflow).  The numbers are those of
    the whole array, the mean step up to summation order."""
    from segadeform.io.sequence import CHUNK_VALUES, frame_chunks

    st = FrameStats(n_frames=len(frames), n_points=int(frames.shape[1]))
    if st.n_frames == 0 or st.n_points == 0:
        return st
    prev = None
    n_steps, step_sum, step_max = 0, 0.0, -1.0
    cmin, cmax = np.full(3, np.inf), np.full(3, -np.inf)
    for s, block in frame_chunks(frames, CHUNK_VALUES if max_values is None else max_values):
        finite = np.isfinite(block)
        ok = finite.all(axis=(1, 2))
        if st.nonfinite or not ok.all():  # an error: the rest need not be computed
            st.nonfinite += int(finite.size - np.count_nonzero(finite))
            st.bad_frames.extend((s + np.flatnonzero(~ok)).tolist())
            continue
        del finite, ok
        b = block.astype(np.float64)
        st.far = max(st.far, float(b.max()), -float(b.min()))  # the largest |x| (np.abs would be another copy)
        flat = b.reshape(-1, 3)
        st.lo, st.hi = np.minimum(st.lo, flat.min(0)), np.maximum(st.hi, flat.max(0))
        c = b.mean(axis=1)
        cmin, cmax = np.minimum(cmin, c.min(0)), np.maximum(cmax, c.max(0))
        d = np.diff(b, axis=0) if prev is None else np.diff(b, axis=0, prepend=prev[None])
        first = s + 1 if prev is None else s  # the frame the first step of d ends at
        prev = b[-1].copy()
        if len(d):
            step = np.linalg.norm(d, axis=2)  # (k, N)
            n_steps += step.size
            step_sum += float(step.sum())
            m = step.max(axis=1)
            j = int(m.argmax())
            if m[j] > step_max:  # the first frame of the largest, as argmax over the whole
                step_max, st.step_max_frame = float(m[j]), first + j
            st.still += int((m == 0).sum())
    if n_steps:
        st.step_mean, st.step_max = step_sum / n_steps, step_max
    st.centroid_range = cmax - cmin
    return st


def _frames_summary(path, frames, head: str | None = None, first: int = 0, unit: float | None = None) -> None:
    """Bounds, a NaN check and the motion per frame of a (S, N, 3) sequence (an array or
    :class:`~segadeform.io.sequence.LazyFrames`, streamed: :func:`frame_stats`); NaN/inf is an error.  ``head``:
    the summary's first line, said once the frames are read (an error is then the one line said).  ``first``: the
    file's number for its first frame (a run's --frames 10:40 writes 10): frames are named by the file's numbers, as
    preview and a DCC number them (they were counted from 0: a new user's trial).  ``unit``: the metres per unit the
    file records (a USD's ``metersPerUnit``; None: none recorded, its numbers read as metres): bounds are said in
    the file's units, motion in metres (a centimetre USD's steps were said 100 times too long)."""
    from segadeform.bounds import MAX_POSITION
    from segadeform.errors import FileFormatError

    st = frame_stats(frames)
    k = 1.0 if unit is None else unit  # metres per file unit
    if st.nonfinite:
        idx = st.bad_frames
        raise FileFormatError(
            f"{st.nonfinite} non-finite values (NaN or inf), in {len(idx)} frames "
            f"({', '.join(str(first + i) for i in idx[:8])}{' ...' if len(idx) > 8 else ''})",
            path=path,
        )
    if st.n_frames and st.n_points and st.far * k > MAX_POSITION:
        raise FileFormatError(
            "a point lies beyond 10 km of the origin (another unit? --output-units says the one it was written in)",
            path=path,
            expected=f"|x| <= {MAX_POSITION:g} m",
            got=f"{st.far * k:.3g} m" + ("" if unit is not None else " read as metres"),
        )
    if head is not None:
        click.echo(head)
    if st.n_frames == 0 or st.n_points == 0:
        click.echo(f"  no {'frames' if st.n_frames == 0 else 'points'}")
        return
    said = "" if k == 1.0 else f", in the file's units of {k:g} m"
    click.echo(
        f"  bounds {np.round(st.lo, 4).tolist()} .. {np.round(st.hi, 4).tolist()} (all frames{said}); NaN/inf: none"
    )
    if st.n_frames > 1:
        click.echo(
            f"  motion per frame: mean {1e3 * k * st.step_mean:.2f} mm, largest {1e3 * k * st.step_max:.2f} mm "
            f"(frame {first + st.step_max_frame}); centroid travels "
            f"{np.round(k * np.asarray(st.centroid_range), 4).tolist()} m (x, y, z range)"
        )
        if st.still:
            click.echo(f"  {st.still} frames identical to the one before")


@cli.command("inspect")
@click.argument("path", type=PathParam(path_type=Path))
@click.option(
    "--output-units",
    metavar="UNITS",
    help="Units a sequence was written in (run --output-units: m, dm, cm, mm, inch, ft or metres per unit); "
    "default: what a USD records (metersPerUnit), else metres.",
)
def inspect_cmd(path, output_units=None):
    """Read PATH (mesh, point cache or any registered sequence format, body, motion, garment asset, scene,
    scene bundle, dataset pack or model package), validate it fully, and print a summary."""
    from segadeform.errors import file_error
    from segadeform.io.formats import inspect_sequence, sequence_format_of
    from segadeform.io.writer import output_unit

    from .main import option_value

    unit = None if output_units is None else option_value(output_unit, output_units, option="--output-units")

    ext = path.suffix.lower()
    if path.is_dir() and (path / "manifest.json").exists():
        from segadeform.runtime import ModelPackage

        pkg = ModelPackage(path)
        for name in pkg.manifest["graphs"]:
            pkg.session(name)
        n_dec = sum(1 for g in pkg.manifest["graphs"].values() if g["role"] == "deformer")
        click.echo(
            f"{path}: model package, graphs {', '.join(pkg.manifest['graphs'])} "
            f"({n_dec} deformers, default {pkg.default_deformer})"
        )
        return
    try:
        path.stat()
    except OSError as e:
        raise file_error(e, path) from None
    if sequence_format_of(path) is not None:  # every registered output format (segadeform.io.formats)
        fmt, summary, frames = inspect_sequence(path)
        from segadeform.io.formats import sequence_start_frame, sequence_units

        # streamed (never held whole); frames named by the file's own numbers
        _frames_summary(
            path,
            frames,
            f"{path}: {fmt.name} sequence, {summary}",
            sequence_start_frame(path),
            unit=unit if unit is not None else sequence_units(path),
        )
    elif ext in (".bvh", ".amc") or (ext in (".glb", ".gltf") and _animated(path)):
        # motions `run --motion` takes (an AMC with its ASF beside it); a glTF with no animation is a garment mesh
        from segadeform.motion import load_motion

        m = load_motion(path)
        what = {".bvh": "BVH", ".amc": "CMU AMC", ".glb": "glTF", ".gltf": "glTF"}[ext]
        from segadeform.io.writer import nominal_fps

        click.echo(f"{path}: {what} motion, {m.n_frames} frames at {nominal_fps(m.fps):g} fps")
    elif ext == ".asf":
        from segadeform.motion.asf import metres_per_unit, read_asf

        sk = read_asf(path)
        click.echo(
            f"{path}: CMU ASF skeleton, {len(sk.names)} bones (root first), {metres_per_unit(sk.length_unit):g} m "
            f"per unit, angles in {sk.angle}"
        )
    elif ext == ".mhclo":
        from segadeform.io.mhclo import read_mhclo

        b = read_mhclo(path)
        obj = b.obj_path()
        click.echo(
            f"{path}: MakeHuman binding {b.name!r}, {len(b.verts)} garment vertices bound to the hm08 base mesh, "
            f"mesh {obj.name if obj is not None else 'not named'}"
            + ("" if obj is None or obj.is_file() else " (missing)")
        )
    elif ext == ".toml":
        _inspect_toml(path)
    elif ext == ".pkl":
        from segadeform.body import load_body

        click.echo(f"{path}: body {load_body(path)!r}")
    elif ext == ".sgdm":
        from segadeform.motion import read_motion_file

        m, meta = read_motion_file(path)
        body = meta.get("body") or {}
        made = f", made for body {body.get('name', '?')}" if body else ""
        betas = meta.get("betas")
        if betas is not None:
            nz = [float(b) for b in betas]
            while nz and nz[-1] == 0:
                nz.pop()
            made += f" with betas [{', '.join(f'{b:g}' for b in nz)}]"
        click.echo(
            f"{path}: motion file, {m.n_frames} frames at {m.fps:g} fps, {m.poses.shape[1] // 3} joints"
            f"{made}; source {meta.get('source', meta.get('name', '?'))}"
        )
        rot = np.linalg.norm(m.poses.reshape(m.n_frames, -1, 3), axis=2)
        click.echo(
            f"  root translation {np.round(m.trans.min(0), 4).tolist()} .. {np.round(m.trans.max(0), 4).tolist()} m; "
            f"largest joint rotation {float(rot.max()):.3f} rad"
        )
        for w in meta.get("warnings", []):  # what `motion export` said, which the runtimes say again
            click.echo(f"  said when exported: {w}")
    elif ext == ".sgdb":  # a scene bundle (`segadeform bundle`): what the Node, C++ and browser runtimes run
        from segadeform.io.sgdb import read_bundle

        arrays, meta = read_bundle(path)
        rest, poses = arrays.get("rest"), arrays.get("poses")
        n_v = "?" if rest is None else len(rest)
        n_f = "?" if poses is None else len(poses)
        eff = meta.get("effects")
        if isinstance(eff, dict):  # the deformer's effects the bundle was made with (post-processes are the runner's)
            eff = ",".join([str(eff.get("skinning", "?"))] + [k for k, v in eff.items() if v is True])
        click.echo(
            f"{path}: scene bundle, garment {meta.get('garment', '?')} ({n_v} vertices), "
            f"motion {meta.get('motion', '?')} ({n_f} frames at {meta.get('fps', '?')} fps, "
            f"from frame {meta.get('start_frame', 0)}), graph {meta.get('graph', '?')}, effects {eff}"
        )
        click.echo("  arrays: " + ", ".join(f"{k} {tuple(v.shape)} {v.dtype}" for k, v in arrays.items()))
    elif ext == ".sgdpack":  # a dataset pack (`segadeform dataset pack`): every sample read and its SHA-256 checked
        import collections

        from segadeform.dataset.pack import open_pack

        pack = open_pack(path)
        try:
            kept, rejected = pack.ids("samples"), pack.ids("rejected")
            splits = collections.Counter(str(pack.read_meta(s).get("split")) for s in kept)
            frames = vertices = 0
            for s in kept:
                smp = pack.load(s)
                frames += len(smp.frames)
                vertices = max(vertices, smp.frames.shape[1])
            sim = pack.simulator
            per_split = ", ".join(f"{k} {v}" for k, v in sorted(splits.items()))
            click.echo(
                f"{path}: dataset pack, {len(kept)} kept samples ({per_split}; "
                f"{frames} frames, up to {vertices} vertices), {len(rejected)} rejected; "
                f"{len(pack.configs())} configs, body sha256 {(pack.body_sha256 or '?')[:12]}, "
                f"simulator {', '.join(f'{k} {v}' for k, v in sorted(sim.items())) or '?'}"
            )
            click.echo("  every sample read, its SHA-256 checked and its frames decoded")
        finally:
            pack.close()
    elif ext == ".sgda":
        from segadeform.geometry import GarmentAsset

        a = GarmentAsset.load(path)
        click.echo(f"{path}: portable {a!r}")
        for w in a.warnings:  # what `garment export` said, which the runtimes say again
            click.echo(f"  said when exported: {w}")
    elif ext == ".npz":
        from segadeform.io.npz import load_npz

        z = load_npz(path)
        keys = set(z)
        if {"rest", "faces", "frames", "poses"} <= keys:  # a dataset sample (it was read as a motion: a user's trial)
            import json

            rec = Path(path).with_suffix(".json")
            meta = json.loads(rec.read_text()) if rec.is_file() else {}
            t, n = np.asarray(z["frames"]).shape[:2]
            nf = len(np.asarray(z["faces"]))
            said = ", ".join(f"{k} {meta[k]}" for k in ("split", "kind", "garment", "motion", "status") if k in meta)
            click.echo(
                f"{path}: dataset sample, {t} frames of {n} garment vertices ({nf} triangle{'' if nf == 1 else 's'})"
                f"{'; ' + said if said else ''} (segadeform dataset info FOLDER for the whole dataset)"
            )
        elif "poses" in keys:
            from segadeform.motion import load_motion

            m = load_motion(path)
            click.echo(f"{path}: motion, {m.n_frames} frames at {m.fps:g} fps")
        elif "features" in keys and "nbr" in keys:
            from segadeform.geometry import GarmentAsset

            a = GarmentAsset.load(path)
            click.echo(f"{path}: {a!r}")
            for w in a.warnings:
                click.echo(f"  said when exported: {w}")
        else:
            from segadeform.body import load_body

            click.echo(f"{path}: body {load_body(path)!r}")
    else:
        from segadeform.io import read_mesh

        if unit is not None and ext == ".obj":  # a rest mesh `run --output-units` wrote: bounded in its units
            from segadeform.bounds import MAX_POSITION
            from segadeform.errors import FileFormatError
            from segadeform.io.obj import read_obj

            m = read_obj(path, bounded=False)
            far = float(np.abs(m.vertices).max()) * unit if m.n_vertices else 0.0
            if far > MAX_POSITION:
                raise FileFormatError(
                    "a vertex lies beyond 10 km of the origin", path=path, expected="|x| <= 10000 m", got=f"{far:.3g} m"
                )
        else:
            m = read_mesh(path)
        v = m.vertices
        said = "" if unit is None or unit == 1.0 else f" (in the file's units of {unit:g} m)"
        click.echo(
            f"{path}: mesh, {m.n_vertices} vertices, {m.n_faces} triangles, bounds "
            f"{np.round(v.min(0), 4).tolist()} .. {np.round(v.max(0), 4).tolist()}{said}"
        )
        _mesh_defects(m.vertices, m.faces)


def _animated(path) -> bool:
    """Whether a glTF file holds an animation (a motion), else a mesh (a garment, as an engine exports it: `inspect`
    said "glTF has no skin" of one: an engine integrator's trial)."""
    from segadeform.motion.gltf import gltf_animations

    return bool(gltf_animations(path))


def _mesh_defects(vertices, faces) -> None:
    """One informational line: what of the mesh is not a clean surface (it was read; nothing here is an error)."""
    from segadeform.geometry.mesh_ops import mesh_defects

    d = mesh_defects(vertices, faces)
    said = [
        f"{n} {what if n == 1 else whats}{why}"
        for n, what, whats, why in (
            (d["duplicated"], "duplicated face", "duplicated faces", ""),
            (d["degenerate"], "degenerate triangle", "degenerate triangles", " (flat or a repeated corner)"),
            (d["isolated"], "isolated vertex", "isolated vertices", " (in no face)"),
            (d["non_manifold"], "non-manifold edge", "non-manifold edges", " (in more than two faces)"),
            (d["misoriented"], "misoriented edge", "misoriented edges", " (between faces wound against each other)"),
            (
                d["coincident"],
                "coincident boundary vertex",
                "coincident boundary vertices",
                " (at another's place on an open boundary, no edge between: a split seam, which `run` welds for the "
                "model and the cloth stage; `garment fit --weld` merges them in a file)",
            ),
        )
        if n
    ]
    click.echo(
        "  " + ", ".join(said)
        if said
        else "  no duplicated or degenerate faces, isolated vertices, non-manifold or misoriented edges, or coincident "
        "boundary vertices"
    )
    from segadeform.geometry.mesh_ops import SMALL_PIECE, small_pieces

    pieces = small_pieces(vertices, faces)
    if len(pieces):  # stray triangles: each an opening the model counts (a technical artist's trial: unsaid)
        click.echo(
            f"  {len(pieces)} small loose piece{'s' if len(pieces) > 1 else ''} ({int(pieces.sum())} faces in all, "
            f"each under {100 * SMALL_PIECE:g} % of the faces: "
            + ", ".join(str(int(n)) for n in pieces[:8])
            + (" ..." if len(pieces) > 8 else "")
            + "): each is an opening the model reads; delete them if they are not part of the garment"
        )


def _inspect_toml(path) -> None:
    """A scene, a dataset config, a training config or a jobs file, told apart by their tables (a dataset config
    was read as a scene: "unknown table [bodies]")."""
    import tomllib

    try:
        with open(path, "rb") as f:
            tables = set(tomllib.load(f))
    except (OSError, tomllib.TOMLDecodeError, RecursionError):
        tables = set()  # the scene reader says what is wrong, with the line
    if tables & {"dataset", "bodies"}:
        from collections import Counter

        from segadeform.dataset.config import load_dataset_config
        from segadeform.dataset.make import check_splits, sample_plan

        cfg = load_dataset_config(path)
        plan = sample_plan(cfg)
        check_splits(cfg, plan)
        per = Counter(p.split for p in plan)
        splits = ", ".join(f"{n} {k}" for k, n in sorted(per.items()))
        click.echo(
            f"{path}: dataset config {cfg.digest()}, {len(cfg.garments)} garments x {len(cfg.bodies)} bodies x "
            f"{len(cfg.motions)} motions: {len(plan)} planned samples ({splits or 'none'}), "
            f"{cfg.seconds:g} s at {cfg.fps:g} fps"
        )
    elif tables & {"model", "loss", "optim", "base", "physics"} and not tables & {"garment", "motion", "output"}:
        try:
            from segadeform.train.config import load_train_config
        except ImportError as e:  # the training layer needs torch
            raise click.ClickException(
                f"{path}: a training config; reading it needs the torch extra (pip install -e '.[torch]'): {e}"
            ) from None
        c = load_train_config(path)
        roots = [str(r) for r in (*c.dataset, *c.optional)]
        click.echo(
            f"{path}: training config, {c.optim.steps} steps, hidden {c.model.hidden}, seed {c.optim.seed}, "
            f"prior {c.model.weight_prior}, data {', '.join(roots) or 'given on the command line'}"
        )
    elif "batch" in tables:
        from segadeform.runtime.batch import load_batch

        b = load_batch(path)
        click.echo(
            f"{path}: jobs file, {len(b.garments)} garments x {len(b.motions)} motions, format {b.format}, "
            f"output {b.output}"
        )
    else:
        from segadeform.settings import load_scene

        s = load_scene(path)
        click.echo(f"{path}: scene, garment {s.garment.name}, effects {s.effects.label()}, output {s.output}")
