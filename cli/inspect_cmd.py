"""``segadeform inspect PATH``: read any file segadeform understands and summarise it."""

from __future__ import annotations

from pathlib import Path

import click
import numpy as np

from .main import cli


@cli.command("inspect")
@click.argument("path", type=click.Path(path_type=Path))
def inspect_cmd(path):
    """Read PATH (mesh, point cache, sequence, body, motion, garment asset, scene or model package),
    validate it fully, and print a summary."""
    from segadeform.errors import FileFormatError

    ext = path.suffix.lower()
    if path.is_dir():
        if (path / "manifest.json").exists():
            from segadeform.runtime import ModelPackage

            pkg = ModelPackage(path)
            for name in pkg.manifest["graphs"]:
                pkg.session(name)
            click.echo(f"{path}: model package, graphs {', '.join(pkg.manifest['graphs'])}, "
                       f"{len(pkg.manifest.get('variants', {}))} deformer variants")
        else:
            from segadeform.io import read_obj_sequence

            faces, frames = read_obj_sequence(path)
            click.echo(f"{path}: OBJ sequence, {frames.shape[0]} frames x {frames.shape[1]} vertices, {len(faces)} faces")
        return
    if not path.exists():
        raise FileFormatError("no such file", path=path)
    if ext == ".pc2":
        from segadeform.io import read_pc2

        pc = read_pc2(path, check_finite=True)
        h = pc.header
        click.echo(f"{path}: PC2, {h.num_samples} samples x {h.num_points} points, start frame {h.start_frame:g}, "
                   f"sample rate {h.sample_rate:g}")
    elif ext in (".xdmf", ".xmf", ".abc"):
        from segadeform.io import read_sequence

        fr = read_sequence(path)
        click.echo(f"{path}: sequence, {fr.shape[0]} frames x {fr.shape[1]} vertices")
    elif ext == ".bvh":
        from segadeform.motion import load_motion

        m = load_motion(path)
        click.echo(f"{path}: BVH motion, {m.n_frames} frames at {m.fps:g} fps")
    elif ext == ".toml":
        from segadeform.scene import load_scene

        s = load_scene(path)
        click.echo(f"{path}: scene, garment {s.garment.name}, effects {s.effects.label()}, output {s.output}")
    elif ext == ".pkl":
        from segadeform.body import load_body

        click.echo(f"{path}: body {load_body(path)!r}")
    elif ext == ".npz":
        from segadeform.io.npz import load_npz

        keys = set(load_npz(path))
        if "poses" in keys:
            from segadeform.motion import load_motion

            m = load_motion(path)
            click.echo(f"{path}: motion, {m.n_frames} frames at {m.fps:g} fps")
        elif "features" in keys and "nbr" in keys:
            from segadeform.geometry import GarmentAsset

            click.echo(f"{path}: {GarmentAsset.load(path)!r}")
        else:
            from segadeform.body import load_body

            click.echo(f"{path}: body {load_body(path)!r}")
    else:
        from segadeform.io import read_mesh

        m = read_mesh(path)
        v = m.vertices
        click.echo(f"{path}: mesh, {m.n_vertices} vertices, {m.n_faces} triangles, bounds "
                   f"{np.round(v.min(0), 4).tolist()} .. {np.round(v.max(0), 4).tolist()}")
