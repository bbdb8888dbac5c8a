"""``segadeform motion convert``: an FBX character's animation -> a BVH file, through Blender's FBX importer
(:mod:`segadeform.physics.fbx`); and :func:`fbx_as_bvh`, with which ``motion info`` and ``motion export`` read an
FBX file directly."""

from __future__ import annotations

import contextlib
import logging
import tempfile
from collections.abc import Iterator
from pathlib import Path

import click

from .main import PathParam
from .motion import motion_group


def _say(src: Path, got) -> None:
    others = [a for a in got.animations if a != got.animation]
    click.echo(
        f"{src.name}: armature {got.armature!r} ({got.bones} bones), animation {got.animation!r}, {got.frames} frames "
        f"at {got.fps:g} fps (Blender {got.blender})"
        + (f"; other animations: {', '.join(repr(a) for a in others)} (--animation NAME)" if others else ""),
        err=True,
    )
    if not got.skinned:
        click.echo(
            f"warning: {src.name} has no mesh skinned to its armature, so its rest pose is whatever pose the bones "
            "stand in, not a bind pose: the motion is read relative to it (check it with `segadeform preview` or "
            "`segadeform motion info`; an export with the character's mesh carries the bind pose)",
            err=True,
        )


def bvh_up(up: str) -> str:
    """The up axis to read the BVH made of an FBX file with: +Y (the worker writes it so), unless one is given."""
    return "y" if up == "auto" else up


@contextlib.contextmanager
def fbx_as_bvh(path: Path, animation: str | None, sim_python=None) -> Iterator[Path]:
    """``path`` itself, or for an ``.fbx`` the BVH that Blender makes of it in a temporary folder (removed after),
    named as the FBX is (the motion's name).  Errors and warnings about the BVH name the FBX file."""
    if path.suffix.lower() != ".fbx":
        yield path
        return
    from segadeform.physics.fbx import fbx_to_bvh

    with tempfile.TemporaryDirectory(prefix="segadeform-fbx-") as tmp:
        bvh = Path(tmp) / (path.stem + ".bvh")
        _say(path, fbx_to_bvh(path, bvh, animation=animation, sim_python=sim_python))
        with as_the_fbx(bvh, path):
            yield bvh


@contextlib.contextmanager
def motion_spec_read(spec, sim_python=None) -> Iterator:
    """A scene's (or jobs file's) motion as it is read: ``spec`` itself, or for an ``.fbx`` file the same spec on the
    BVH Blender makes of it (:func:`fbx_as_bvh`: its animation taken, read +Y up unless the spec says otherwise),
    valid inside the block."""
    import dataclasses

    if spec.file is None or Path(spec.file).suffix.lower() != ".fbx":
        yield spec
        return
    with fbx_as_bvh(Path(spec.file), spec.animation, sim_python) as bvh:
        yield dataclasses.replace(spec, file=bvh, animation=None, up=bvh_up(spec.up))


class _Rename(logging.Filter):
    """A warning that names the temporary BVH names the user's FBX file instead."""

    def __init__(self, bvh: Path, fbx: Path) -> None:
        super().__init__()
        self.pairs = ((str(bvh), str(fbx)), (bvh.name, fbx.name))

    def filter(self, record: logging.LogRecord) -> bool:
        msg = record.getMessage()
        for a, b in self.pairs:
            msg = msg.replace(a, b)
        record.msg, record.args = msg, None
        return True


@contextlib.contextmanager
def as_the_fbx(bvh: Path, fbx: Path) -> Iterator[None]:
    """While reading the BVH made of ``fbx``: its errors and segadeform's warnings name the FBX file.  The warnings
    go through a filter on the handlers that print them (with none configured, as in the command line, a handler
    that prints them as Python's last resort does: the message alone, to stderr)."""
    from segadeform.errors import InputError

    f = _Rename(bvh, fbx)
    pkg = logging.getLogger("segadeform")
    handlers = [*logging.root.handlers, *pkg.handlers]
    added = None
    if not handlers:
        added = logging.StreamHandler()  # sys.stderr at the time of the call, as the last resort's
        added.setLevel(logging.WARNING)
        pkg.addHandler(added)
        handlers = [added]
    for h in handlers:
        h.addFilter(f)
    try:
        yield
    except InputError as e:  # the BVH's reader named the temporary file: the user's file is the FBX
        if e.path is None or Path(e.path) != bvh:
            raise
        raise type(e)(
            e.problem + " (read from the BVH Blender wrote of it)", path=fbx, expected=e.expected, got=e.got
        ) from None
    finally:
        for h in handlers:
            h.removeFilter(f)
        if added is not None:
            pkg.removeHandler(added)


@motion_group.command("convert")
@click.argument("source", type=PathParam(dir_okay=False, path_type=Path))
@click.option(
    "-o",
    "--output",
    required=True,
    type=PathParam(dir_okay=False, path_type=Path),
    help="The BVH file to write (.bvh).",
)
@click.option("--animation", help="The FBX file's animation (take) to convert (default: the armature's own).")
@click.option("--sim-python", type=PathParam(dir_okay=False, path_type=Path), help="The simulator's Python (Blender).")
def convert_cmd(source, output, animation, sim_python):
    """Write the animation of SOURCE (.fbx: Mixamo, Maya, MotionBuilder, Unreal, Unity ...) as a BVH file, through
    Blender's FBX importer (the simulator environment: python -m segadeform.physics.setup).

    The BVH is in metres, +Y up, in world space (root motion on the armature object or a parent null kept), over
    the animation's frames at its frame rate; every command that takes a motion reads it (run, motion info and motion
    export also take the .fbx itself)."""
    from segadeform.errors import InputError
    from segadeform.io.atomic import atomic_path
    from segadeform.io.output_guard import OutputGuard
    from segadeform.physics.fbx import FBX_EXTENSIONS, fbx_to_bvh

    if source.suffix.lower() not in FBX_EXTENSIONS:
        raise InputError("motion convert reads FBX files", path=source, expected=".fbx", got=source.suffix or "none")
    if output.suffix.lower() != ".bvh":
        raise click.UsageError(f"-o must end in .bvh, got {output.name!r}")
    guard = OutputGuard("motion convert", inputs=(source, sim_python))
    guard.file(output)
    from segadeform.motion.bvh import read_bvh

    with atomic_path(output) as tmp:
        got = fbx_to_bvh(source, tmp, animation=animation, sim_python=sim_python)
        with as_the_fbx(tmp, source):  # a skeleton segadeform cannot play (not a humanoid) is refused, not written
            read_bvh(tmp, up="y")
        guard.recheck()
    guard.record()
    _say(source, got)
    click.echo(f"{source.name}: {got.frames} frames at {got.fps:g} fps -> {output}")
