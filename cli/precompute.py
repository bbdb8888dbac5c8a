"""``segadeform precompute``: garment mesh -> garment asset (.npz, or .sgda: the portable form)."""

from __future__ import annotations

import time
from pathlib import Path

import click

from .main import PathParam, cli


@cli.command("precompute")
@click.argument("garment", type=PathParam(dir_okay=False, path_type=Path))
@click.option(
    "-o",
    "--output",
    required=True,
    type=PathParam(dir_okay=False, path_type=Path),
    help="Asset file to write: .npz, or .sgda (portable: read without Python; docs/package.md).",
)
@click.option(
    "--joints",
    "joints_path",
    type=PathParam(dir_okay=False, path_type=Path),
    help="Rest-pose joints, an (S, 3) .npy array (metres, +Y up).",
)
@click.option(
    "--body",
    "body_path",
    type=PathParam(dir_okay=False, path_type=Path),
    help="Body .npz to take the rest-pose joints from.",
)
@click.option("--k", type=click.IntRange(min=1), default=None, help="Neighbour slots K (default: max valence, capped).")
@click.option("--max-k", type=click.IntRange(min=1), default=None, help="Cap for automatic K.")
@click.option("--n-star", type=click.IntRange(min=1), default=None, help="Descriptor length N*.")
@click.option("--geodesic", type=click.Choice(["heat", "dijkstra"]), default=None, help="Geodesic method.")
def precompute_cmd(garment, output, joints_path, body_path, k, max_k, n_star, geodesic):
    """Precompute graph, features and descriptor of GARMENT (OBJ, PLY, OFF, STL ...)."""
    from segadeform.body import load_rest_joints
    from segadeform.errors import InputError
    from segadeform.geometry import DEFAULT_GEODESIC, DEFAULT_MAX_K, DEFAULT_N_STAR, precompute_garment
    from segadeform.io import read_mesh
    from segadeform.io.garment_asset import check_asset_path
    from segadeform.io.hashing import file_sha256

    if (joints_path is None) == (body_path is None):
        raise click.UsageError("give exactly one of --joints JOINTS.npy or --body BODY.npz")
    from segadeform.io.output_guard import OutputGuard

    check_asset_path(output)  # before any work
    guard = OutputGuard("precompute", inputs=(garment, joints_path, body_path))
    guard.file(output)
    t0 = time.perf_counter()
    mesh = read_mesh(garment)
    joints = load_rest_joints(joints_path or body_path)
    try:
        asset = precompute_garment(
            mesh.vertices,
            mesh.faces,
            joints,
            k=k,
            max_k=max_k or DEFAULT_MAX_K,
            n_star=n_star or DEFAULT_N_STAR,
            geodesic=geodesic or DEFAULT_GEODESIC,
            source_name=garment.name,
            source_sha256=file_sha256(garment),
        )
    except InputError as e:  # of the garment's mesh ("no face with an area"): named by its file (it was not)
        raise e.with_path(garment) from None
    asset.save(output)
    guard.record()
    dt = time.perf_counter() - t0
    click.echo(
        f"{garment.name}: {asset.n_vertices} vertices, {len(asset.faces)} triangles, "
        f"K={asset.nbr.shape[1]}, S={len(asset.joints)}, N*={len(asset.descriptor)}, "
        f"{asset.params['n_components']} part(s) -> {output} ({dt:.2f} s)"
    )
