"""``segadeform garment export``: a garment (mesh or asset) -> the garment asset of one body shape, with every
model input only Python computes, for the runtimes without Python (docs/package.md)."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import click

from segadeform.errors import InputError, SegadeformError

from .garment import _betas, garment_group
from .main import PathParam


@garment_group.command("export")
@click.argument("garment", type=PathParam(dir_okay=False, exists=True, path_type=Path))
@click.option(
    "-o",
    "--output",
    required=True,
    type=PathParam(dir_okay=False, path_type=Path),
    help="The asset to write: .sgda (portable) or .npz.",
)
@click.option(
    "--body",
    type=PathParam(dir_okay=False, exists=True, path_type=Path),
    help="Body .npz (default: the shipped body): the body the model package's body graphs pose.",
)
@click.option("--betas", help="Comma-separated body shape coefficients.")
@click.option(
    "--model",
    type=PathParam(file_okay=False, exists=True, path_type=Path),
    help="Model package the asset is for: its descriptor length N* and skinning-weight prior "
    "(default: the shipped model).",
)
@click.option("--k", type=click.IntRange(min=1), default=None, help="Neighbour slots K (default: max valence, capped).")
@click.option(
    "--force",
    is_flag=True,
    help="Export a garment even when it does not sit on the body, or for a body no human's height.",
)
def garment_export_cmd(garment, output, body, betas, model, k, force):
    """Prepare GARMENT (a mesh, or an asset from `segadeform precompute`) for a body shape: neighbours, mask,
    descriptor, the encoder features for the shape's rest joints, the body's weights at the garment
    (log_wbody), betas and the body's hash: what `segadeform run` computes before the model runs."""
    from segadeform.body import default_body_path, load_body
    from segadeform.body.placement import check_placement
    from segadeform.body.prepare import prepare_for_body
    from segadeform.bounds import check_body_height
    from segadeform.contracts.model_package import read_manifest_text
    from segadeform.geometry import GarmentAsset, precompute_garment
    from segadeform.io import read_mesh
    from segadeform.io.garment_asset import PORTABLE_SUFFIX, check_asset_path
    from segadeform.io.hashing import file_sha256
    from segadeform.io.obj import recorded_betas
    from segadeform.io.output_guard import OutputGuard

    check_asset_path(output)  # before any work
    guard = OutputGuard("garment export", inputs=(garment, body, model))
    guard.file(output)
    b = load_body(body or default_body_path())
    beta_vals = _betas(betas) or ()
    if model is None:
        from segadeform.runtime.pipeline import default_model_path

        model = default_model_path()
    config = read_manifest_text((Path(model) / "manifest.json").read_text(encoding="utf-8"))["config"]
    if garment.suffix.lower() in (".npz", PORTABLE_SUFFIX):
        asset = GarmentAsset.load(garment)
    else:
        n_star = config["n_star"]
        mesh = read_mesh(garment)
        try:
            asset = precompute_garment(
                mesh.vertices,
                mesh.faces,
                b.rest_joints()[0],
                k=k,
                n_star=n_star,
                source_name=garment.name,
                source_sha256=file_sha256(garment),
            )
        except InputError as e:  # of the garment's mesh ("no face with an area"): named by its file (it was not)
            raise e.with_path(garment) from None
    unfit = None
    try:
        check_body_height(b, beta_vals)
        check_placement(
            asset.vertices,
            b.shaped_vertices(beta_vals)[0],
            b.faces,
            faces=asset.faces,
            path=garment,
            template_vertices=b.v_template,
            betas=beta_vals,
            recorded_betas=recorded_betas(garment),
        )
    except SegadeformError as e:
        if not force:
            raise
        unfit = e.problem  # kept in the asset: the runtimes refuse it unless forced again, as `segadeform run` does
    asset = prepare_for_body(asset, b, beta_vals, weight_prior=config.get("weight_prior", "nearest"))
    if unfit is not None:
        asset = dataclasses.replace(asset, body={**asset.body, "unfit": unfit})
    asset.save(output)
    guard.record()
    click.echo(
        f"{garment.name}: {asset.n_vertices} vertices, K={asset.nbr.shape[1]}, N*={len(asset.descriptor)}, "
        f"for {asset.body['name'] or 'the body'} betas {[round(float(x), 4) for x in asset.betas[: len(beta_vals)]]} "
        f"-> {output}"
    )
