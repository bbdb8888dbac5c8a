"""``segadeform cache info | clear``: the user cache of precompute and encoder results."""

from __future__ import annotations

import click

from .main import cli


@cli.group("cache")
def cache_group():
    """The user cache (precomputed garments, encoder outputs): where it is, how big, clear it."""


@cache_group.command("info")
def cache_info_cmd():
    from segadeform.io.cache import _max_bytes, cache_dir

    d = cache_dir(create=False)
    files = [p for p in d.iterdir() if p.is_file()] if d.is_dir() else []
    size = sum(p.stat().st_size for p in files)
    click.echo(f"{d}: {len(files)} entries, {size / 2**20:.1f} MB (bound {_max_bytes() / 2**20:.0f} MB)")


@cache_group.command("clear")
def cache_clear_cmd():
    from segadeform.io.cache import cache_dir, prune

    d = cache_dir(create=False)
    freed = prune(d, max_bytes=0)
    click.echo(f"{d}: {freed / 2**20:.1f} MB removed")
