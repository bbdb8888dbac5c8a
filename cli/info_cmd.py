"""``segadeform info PACKAGE_DIR``: a model package's manifest, I/O signature and op set."""

from __future__ import annotations

import json
from pathlib import Path

import click

from .main import PathParam, cli


@cli.command("info")
@click.argument("package", type=PathParam(file_okay=False, path_type=Path, package=True))
def info_cmd(package):
    """Print a model package's manifest, I/O signature and op set."""
    from segadeform.runtime import ModelPackage

    pkg = ModelPackage(package)
    m = pkg.manifest
    click.echo(
        f"{package}: {m.get('format', 'model package')} schema {m['schema_version']}, opset {m['opset']}, "
        f"{m.get('producer', '?')}, exporter {m.get('exporter', '?')}"
    )
    click.echo(f"  units {m.get('units')}, up +{m.get('up_axis')}, {len(m['joint_names'])} joints")
    click.echo("  config: " + json.dumps(m["config"], sort_keys=True))
    if m.get("upgraded_from"):
        click.echo(
            f"  (read as schema {m['schema_version']} from schema {m['upgraded_from']}; "
            "`segadeform repack` rewrites it)"
        )
    for name, spec in m["graphs"].items():
        sig = ", ".join(f"{i['name']}{i['shape']}" for i in spec["inputs"])
        outs = ", ".join(f"{o['name']}{o['shape']}" for o in spec["outputs"])
        eff = f" effects={spec['effects']}" if "effects" in spec else ""
        dflt = " (default)" if name == m["default_deformer"] else ""
        click.echo(f"  {name} ({spec['file']}){dflt}{eff}\n    in:  {sig}\n    out: {outs}")
    files = [spec["file"] for spec in m["graphs"].values()] + ([m["weights"]["file"]] if "weights" in m else [])
    size = sum((Path(package) / f).stat().st_size for f in files)
    w = m.get("weights")
    shared = f", weights shared in {w['file']} ({w['bytes'] / 1e6:.2f} MB)" if w else ""
    click.echo(f"  {len(m['graphs'])} graphs, {size / 1e6:.2f} MB{shared}")
    ops = sorted({op for g in m.get("ops", {}).values() for op in g})
    click.echo(f"  ops ({len(ops)}): " + " ".join(ops))
