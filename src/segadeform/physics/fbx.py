"""FBX motion through Blender: an FBX character's animation written as a BVH file that the motion readers take.

FBX is a closed format with no maintained Python reader; Blender's importer (``io_scene_fbx``, in the simulator
environment that ``python -m segadeform.physics.setup`` makes) reads the files Mixamo, Maya, MotionBuilder,
Unreal and Unity write.  :func:`fbx_to_bvh` runs it out of process (:mod:`.fbx_worker`, in Blender's own Python, as
the cloth simulator runs) and writes the animated armature's motion as a BVH file:

* **which armature and animation**: the animations are the actions that animate an armature's bones (a null's or
  a camera's are not offered); by default the one the importer gave an armature, the armature with a mesh skinned
  to it first (a character before a prop's rig), then the one with the most bones animated.  ``animation=NAME``
  takes another, by Blender's name (``Armature|Armature|Walk``) or by the take's own (``Walk``) when one action has
  it, on the armature whose bones it animates; an unknown name is refused with the names there are;
* **frames**: the animation's own frame range, at the file's frame rate;
* **world space**: the bones' world transforms are sampled every frame, so root motion carried by the armature
  object or by an animated parent (MotionBuilder's ``Reference`` null) is kept, and the BVH is +Y up in metres
  whatever the FBX file's axes, units (the objects' scales applied) and bone orientations;
* **names**: the bones' own, with white space turned into ``_`` (3ds Max's ``Bip01 L Thigh``: BVH names are one
  word each); a bone that moves against its parent gets position channels;
* **rest pose**: the armature's rest, placed as the armature stands at the first frame.  An FBX with a mesh skinned
  to the armature has its bind pose there; one without (an "animation only" export) has whatever pose the file's
  bones stand in, which need not be a T-pose or an A-pose: the result says so (``FbxMotion.skinned``) and the CLI
  warns.

The BVH is then read like any other (:func:`segadeform.motion.load_motion`: the joint names of Mixamo, Unreal,
Unity and the rest, the retargeting onto the body).  Measured on a CMU walk taken through Blender to an FBX with
a skinned mesh and back (``tests/physics/test_fbx.py``): every SMPL joint within 0.5 degrees of the BVH read
directly, the root within 3 mm.
"""

from __future__ import annotations

import contextlib
import dataclasses
import json
import os
import subprocess
import tempfile
from collections.abc import Iterator
from pathlib import Path

from ..errors import FileFormatError, SimulationError, check_readable
from .blender import find_sim_python

__all__ = ["FbxMotion", "fbx_to_bvh", "fbx_cached_bvh", "FBX_EXTENSIONS", "WORKER"]

FBX_EXTENSIONS = (".fbx",)
#: the Blender-side script (run by the simulator environment's Python, never imported)
WORKER = Path(__file__).with_name("fbx_worker.py")


@dataclasses.dataclass(frozen=True)
class FbxMotion:
    """What :func:`fbx_to_bvh` read: the armature and animation taken, the others there are, the frames and frame
    rate, whether a mesh is skinned to the armature (its rest is then the bind pose), Blender's version and how many
    bone names lost their white space."""

    armature: str
    armatures: tuple[str, ...]
    animation: str
    animations: tuple[str, ...]
    bones: int
    frames: int
    fps: float
    skinned: bool
    blender: str
    renamed: int = 0


def fbx_to_bvh(
    src: str | os.PathLike,
    dst: str | os.PathLike,
    *,
    animation: str | None = None,
    sim_python: str | os.PathLike | None = None,
    timeout: float = 600.0,
) -> FbxMotion:
    """Write the motion of FBX file ``src`` to BVH file ``dst`` through Blender (the module docstring).

    ``dst`` is written as it is (the caller commits it: an :class:`~segadeform.io.output_guard.OutputGuard`, a
    temporary folder).  Errors name ``src``: not a readable FBX, no armature, no animation, an animation it does not
    have (with the names it has); :class:`SimulationError` when there is no simulator environment or Blender failed.
    """
    src, dst = Path(src), Path(dst)
    check_readable(src, "FBX file")
    if src.stat().st_size == 0:
        raise FileFormatError("empty file", path=src, expected="an FBX file")
    exe = find_sim_python(sim_python)
    part = dst.with_name(dst.name + ".part")  # the worker writes here and renames it when complete
    with tempfile.TemporaryDirectory(prefix="segadeform-fbx-") as tmp:
        info_path = Path(tmp) / "info.json"
        cmd = [str(exe), str(WORKER), str(src.resolve()), str(Path(dst).resolve()), str(info_path)]
        if animation is not None:
            cmd.append(animation)
        env = {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH", "PYTHONHOME")}
        env.update(TMPDIR=tmp, TEMP=tmp, TMP=tmp)  # Blender's own temporary files go with the folder
        try:
            proc = subprocess.run(cmd, capture_output=True, text=True, env=env, cwd=tmp, timeout=timeout)
        except subprocess.TimeoutExpired:
            part.unlink(missing_ok=True)
            raise SimulationError(f"{src}: Blender ran past its {timeout:.0f} s limit reading the FBX file") from None
        except BaseException:
            part.unlink(missing_ok=True)
            raise
        if proc.returncode != 0 or not info_path.is_file():
            part.unlink(missing_ok=True)
            tail = [s for s in (proc.stderr or proc.stdout or "").strip().splitlines() if s.strip()][-1:]
            why = f": {tail[0]}" if tail else ""
            raise SimulationError(f"{src}: Blender failed reading the FBX file (exit {proc.returncode}){why}")
        info = json.loads(info_path.read_text())
    if "error" in info:
        names = info.get("actions")
        listed = "an animation of " + ", ".join(repr(n) for n in names) if animation is not None and names else None
        raise FileFormatError(info["error"], path=src, expected=listed)
    return FbxMotion(
        armature=info["armature"],
        armatures=tuple(info["armatures"]),
        animation=info["animation"],
        animations=tuple(info["actions"]),
        bones=int(info["bones"]),
        frames=int(info["frames"]),
        fps=float(info["fps"]),
        skinned=bool(info["skinned"]),
        renamed=int(info.get("renamed", 0)),
        blender=str(info["blender"]),
    )


@contextlib.contextmanager
def fbx_cached_bvh(src: str | os.PathLike, *, sim_python: str | os.PathLike | None = None) -> Iterator[Path]:
    """``with fbx_cached_bvh(FBX) as bvh:`` -- the BVH :func:`fbx_to_bvh` makes of FBX file ``src`` (its default
    animation; +Y up), as ``<stem>.bvh`` in a temporary folder removed after the block.  A copy is kept in the user
    cache (:mod:`segadeform.io.cache`, ``F-<hash>.bvh``: the hash of the file's bytes and of the Blender-side script),
    so the samples a dataset cuts from one FBX file launch Blender once; the block reads its own copy, so a cache too
    small to keep it, pruned or cleared meanwhile (another process), costs a conversion, not the read (a review)."""
    import hashlib
    import shutil

    from ..io.cache import cache_dir, prune
    from ..io.hashing import file_sha256

    src = Path(src)
    check_readable(src, "FBX file")
    key = hashlib.sha256(f"{file_sha256(src)}:{file_sha256(WORKER)}".encode()).hexdigest()[:32]
    try:
        d: Path | None = cache_dir()
    except OSError:  # the cache is a convenience: one that cannot be made (read-only home) is skipped
        d = None
    with tempfile.TemporaryDirectory(prefix="segadeform-fbx-") as tmp:
        out = Path(tmp) / (src.stem + ".bvh")
        try:
            if d is None:
                raise FileNotFoundError
            shutil.copyfile(d / f"F-{key}.bvh", out)
        except OSError:
            fbx_to_bvh(src, out, sim_python=sim_python)
            if d is not None:
                with contextlib.suppress(OSError):  # a full or read-only cache is skipped
                    part = d / f".F-{key}.{os.getpid()}.part"
                    try:
                        shutil.copyfile(out, part)
                        os.replace(part, d / f"F-{key}.bvh")
                    finally:
                        part.unlink(missing_ok=True)
                    prune(d)
        yield out
