"""``segadeform garment export``: a garment (mesh or asset) -> the garment asset of one body shape, with every
model input only Python computes, for the runtimes without Python (docs/package.md)."""

from __future__ import annotations

import dataclasses
import logging
from pathlib import Path

import click

from segadeform.errors import InputError, SegadeformError

from .garment import _betas, garment_group
from .main import PathParam

log = logging.getLogger(__name__)


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
@click.option(
    "--resolution",
    type=click.FloatRange(min=0.0, max=1.0, min_open=True),
    help="Share of the garment's vertices the model runs on, as `run --resolution`: the asset holds the garment "
    "decimated for the model and the map that carries its frames to every vertex of the garment as given, which "
    "the runtimes write, collide and step the cloth stage on (default 1: the garment as given).",
)
def garment_export_cmd(garment, output, body, betas, model, k, force, resolution=None):
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
    given = None  # with --resolution < 1: the garment as given, and the map from the model's decimated copy to it
    welded, flipped = False, ""  # the model's garment is the given one welded, rewound (then given is set too)
    if garment.suffix.lower() in (".npz", PORTABLE_SUFFIX):
        if resolution is not None and resolution < 1.0:
            raise InputError(
                "a garment asset is one resolution: --resolution takes the garment's mesh",
                path=garment,
                expected="an .obj (or another mesh file) with --resolution",
                got=garment.suffix,
            )
        asset = GarmentAsset.load(garment)
    else:
        n_star = config["n_star"]
        mesh = read_mesh(garment)
        if resolution is not None and resolution < 1.0:
            from segadeform.runtime.pipeline import decimated_garment

            v, f, smap = decimated_garment(mesh.vertices, mesh.faces, resolution, path=garment)
            given, mesh = (mesh, smap), type(mesh)(vertices=v, faces=f)
        else:  # split along seams (UV seams) or wound inward: the model's garment welded and flipped, carried to all
            from segadeform.runtime.pipeline import model_garment

            mv, mf, smap, welded, flipped = model_garment(mesh.vertices, mesh.faces, b, beta_vals)
            if smap is not None:
                given, mesh = (mesh, smap), type(mesh)(vertices=mv, faces=mf)
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
    # the garment as given is what is checked (as `run` checks it): a mesh's, or an asset's from --resolution
    if given is not None:
        on = given[0]
    elif asset.carried:
        from segadeform.io import Mesh

        on = Mesh(vertices=asset.out_vertices, faces=asset.out_faces)
    else:
        on = asset
    try:
        check_body_height(b, beta_vals)
        check_placement(
            on.vertices,
            b.shaped_vertices(beta_vals)[0],
            b.faces,
            faces=on.faces,
            path=garment,
            template_vertices=b.v_template,
            betas=beta_vals,
            recorded_betas=recorded_betas(garment),
        )
    except SegadeformError as e:
        if not force:
            raise
        unfit = e.problem  # kept in the asset: the runtimes refuse it unless forced again, as `segadeform run` does
    # what `run` says of the garment (split seams, faces wound inward ...), said here and kept in the asset for the
    # runtimes that play it to say (a developer's trial: a garment split at its UV seams tore in Node with no word)
    from segadeform.runtime.deformer import unfamiliar_warning
    from segadeform.runtime.package import ModelPackage
    from segadeform.runtime.pipeline import garment_warnings

    if garment.suffix.lower() in (".npz", PORTABLE_SUFFIX):
        # an asset exported again (another shape): what its first export said of the garment file, which the asset
        # cannot tell again (vertices in no face ...; a review: dropped), but against this model
        said = [w for w in asset.warnings if " lies outside the garments model " not in w]
    else:
        said = garment_warnings(garment, on, b, beta_vals, welded=welded, flipped=flipped)
    far = unfamiliar_warning(ModelPackage(model), asset)
    said += [] if far is None else [far]
    for w in said:
        log.warning("%s", w)
    asset = prepare_for_body(asset, b, beta_vals, weight_prior=config.get("weight_prior", "nearest"))
    asset = dataclasses.replace(asset, warnings=tuple(said))
    if unfit is not None:
        asset = dataclasses.replace(asset, body={**asset.body, "unfit": unfit})
    if given is not None:
        import numpy as np

        from segadeform.runtime.pipeline import seam_rest

        full, smap = given
        asset = dataclasses.replace(
            asset,
            out_vertices=seam_rest(full.vertices, smap),  # (a welded seam's copies at one place: the cloth stage's)
            out_faces=np.asarray(full.faces, np.int64),
            carry_face=np.asarray(smap.face, np.int64),
            carry_bary=np.asarray(smap.bary, np.float64),
            carry_offset=np.asarray(smap.offset, np.float64),
        )
    asset.save(output)
    guard.record()
    carried = f" (the model's, carried to the garment's {len(asset.out_vertices)})" if asset.carried else ""
    click.echo(
        f"{garment.name}: {asset.n_vertices} vertices{carried}, K={asset.nbr.shape[1]}, N*={len(asset.descriptor)}, "
        f"for {asset.body['name'] or 'the body'} betas {[round(float(x), 4) for x in asset.betas[: len(beta_vals)]]} "
        f"-> {output}"
    )
