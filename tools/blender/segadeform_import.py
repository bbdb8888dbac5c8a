"""Load a segadeform result into Blender in one step: garment and body meshes with their point caches.

Runs inside Blender (GPL-3.0; this script is a separate program, not part of the segadeform package):

    blender --python tools/blender/segadeform_import.py -- --garment out/tshirt.obj --cache out/tshirt_walk.pc2 \\
        [--body out/body_walk.obj --body-cache out/body_walk.pc2] [--frame-start F] [--fps 30] \\
        [--save scene.blend [--force]]

or from Blender's Python console / another script: ``import_result(...)``.  ``blender -b ... --save scene.blend``
makes the .blend headless (saved whole under a temporary name, then renamed); ``--save`` never replaces an
existing file without ``--force``.

The recipe (verified in Blender 5.0.1 by ``tests/physics/test_blender_recipe.py``, on synthetic caches and on a
real ``segadeform run ... --body-out`` output): import the OBJ with Blender's default OBJ importer (it keeps
the file's +Y-up coordinates and turns the *object* 90 degrees about X), add a Mesh Cache modifier reading
the PC2 as segadeform writes it by default (``--up y``: the cache holds object-local positions, like the
OBJ), frame start = the scene frame where the cache's first sample should show.  Vertex order, count and
frames line up exactly.  A cache written with ``--up z`` would be rotated a second time by the object's
rotation: it is refused (its first frame fits the OBJ far better turned back to +Y up than as it is).

Timing: by default each cache starts at the start frame in its PC2 header (``segadeform run --frames 10:40``
writes 10, so Blender's frame 10 shows the motion's frame 10) and advances one sample per
``sampleRate`` frames; ``--frame-start`` puts the first sample of every cache at that scene frame
instead.  The scene's frame range is set to cover all caches.  A PC2 file does not say its frame rate:
``--fps`` sets the scene's to the run's (the motion's, or ``run --fps``); without it the scene keeps its own
(Blender's default is 24) and the script says so.

Errors: every input is checked before the scene changes -- each file there, each cache a whole PC2 with the
OBJ's vertex count -- and a problem is one line (``Error: FILE: problem (expected X, got Y)``) on stderr, the
scene left as it was; run headless (``blender -b``) the script then exits with status 1.

Paths: each cache is stored by its absolute path, or relative to the .blend when the file is saved and
Blender's *Default to relative paths* is on, so saving the .blend elsewhere or copying the project keeps it
(``--save`` from a new file keeps them absolute).
In a file not saved yet, Blender's untouched default cube (8 vertices at the origin, no modifiers) is removed:
it stands where the body's legs are.
"""

from __future__ import annotations

import math
import os
import struct
import sys

import bpy
import numpy as np

_PC2_HEADER = struct.Struct("<12siiffi")


def _need_file(path: str, what: str) -> None:
    """RuntimeError unless ``path`` is a file (one line naming it)."""
    if os.path.isdir(path):
        raise RuntimeError(f"{path}: a folder (expected {what})")
    if not os.path.isfile(path):
        raise RuntimeError(f"{path}: no such file (expected {what})")


def pc2_header(path: str) -> dict:
    """``{"points", "start_frame", "sample_rate", "samples"}`` of a PC2 file, checked whole (the header's samples
    of its points all there)."""
    _need_file(path, "a PC2 point cache")
    with open(path, "rb") as fh:
        raw = fh.read(_PC2_HEADER.size)
    if len(raw) < _PC2_HEADER.size:
        raise RuntimeError(f"{path}: file too short for a PC2 header (expected 32 bytes, got {len(raw)} bytes)")
    magic, _version, points, start, rate, samples = _PC2_HEADER.unpack(raw)
    if magic != b"POINTCACHE2\0":
        raise RuntimeError(f"{path}: not a PC2 file (expected magic b'POINTCACHE2\\x00', got {magic!r})")
    if not rate > 0:
        raise RuntimeError(f"{path}: PC2 sampleRate must be positive (expected > 0, got {rate})")
    if points < 1 or samples < 1:
        raise RuntimeError(
            f"{path}: an empty PC2 (expected points and samples, got {points} points, {samples} samples)"
        )
    size, want = os.path.getsize(path), _PC2_HEADER.size + 12 * points * samples
    if size < want:
        raise RuntimeError(
            f"{path}: PC2 cut short (expected {want} bytes for {samples} samples of {points} points, got {size})"
        )
    return {"points": points, "start_frame": float(start), "sample_rate": float(rate), "samples": samples}


def obj_vertices(path: str) -> np.ndarray:
    """(N, 3): the ``v`` lines of an OBJ file, in order."""
    _need_file(path, "an OBJ mesh")
    rows = []
    with open(path, "rb") as fh:
        for no, line in enumerate(fh, 1):
            if line[:2] in (b"v ", b"v\t"):
                try:
                    rows.append([float(x) for x in line.split()[1:4]])
                except ValueError:
                    rows.append([])
                if len(rows[-1]) != 3:
                    got = line.decode("utf-8", "replace").strip()
                    raise RuntimeError(f"{path}:{no}: not a vertex (expected 'v X Y Z', got {got!r})")
    if not rows:
        raise RuntimeError(f"{path}: no vertices (expected an OBJ mesh, got no 'v' lines)")
    return np.array(rows, np.float64)


def _fit(rest: np.ndarray, frame: np.ndarray) -> float:
    """The median distance of ``frame``'s vertices from ``rest``'s, both centred and ``frame`` turned about +Y to
    fit best (a motion's first frame is posed, anywhere, facing anywhere, but stands as the OBJ does)."""
    p, q = rest - rest.mean(0), frame - frame.mean(0)
    u, _, vt = np.linalg.svd(p[:, [0, 2]].T @ q[:, [0, 2]])
    turn = u @ np.diag([1.0, 1.0 if np.linalg.det(u @ vt) >= 0 else -1.0]) @ vt
    d = np.concatenate([p[:, [0, 2]] @ turn - q[:, [0, 2]], (p[:, 1] - q[:, 1])[:, None]], axis=1)
    return float(np.median(np.linalg.norm(d, axis=1)))


def check_up_axis(obj: str, rest: np.ndarray, pc2: str, first: np.ndarray) -> None:
    """Refuse a cache written with ``--up z``: its first frame fits the OBJ far better once turned from Z up to
    +Y up than as it is (Blender would turn it a second time: metres off).  Measured on segadeform's own runs: a
    garment's first frame fits its OBJ 7-15 times better the right way up, a body's (rest OBJ in the T-pose)
    3.5 times."""
    as_is = _fit(rest, first)
    turned = _fit(rest, np.stack([first[:, 0], first[:, 2], -first[:, 1]], axis=1))  # (x, y, z) -> (x, z, -y)
    if as_is > 0.05 and turned < 0.5 * as_is:
        raise RuntimeError(
            f"{pc2}: written with --up z (expected a +Y-up cache, as {os.path.basename(obj)}: its first frame lies "
            f"{100 * turned:.1f} cm from it (median) turned from Z up to +Y up, {100 * as_is:.1f} cm as it is); "
            "Blender's OBJ import turns the object itself: write the cache with segadeform run's default --up y"
        )


#: the most the OBJ's size may differ from its cache's first frame (a garment moves and swings, but does not change
#: size tenfold: an OBJ in centimetres beside a cache in metres is a 100-fold)
SIZE_RATIO = 3.0


def check_size(obj: str, rest: np.ndarray, pc2: str, first: np.ndarray) -> None:
    """Refuse an OBJ of another size than its cache: the one given is not the one segadeform ran on (an artist's own
    file in centimetres beside a cache of the file `segadeform garment fit` wrote: the animation played, the rest mesh
    100 times too large, without a word)."""
    a = float(np.sqrt(((rest - rest.mean(0)) ** 2).sum(1).mean()))
    b = float(np.sqrt(((first - first.mean(0)) ** 2).sum(1).mean()))
    if a > 0 and b > 0 and not 1 / SIZE_RATIO <= a / b <= SIZE_RATIO:
        raise RuntimeError(
            f"{obj}: {a / b:.3g} times the size of {os.path.basename(pc2)}'s first frame (expected the OBJ segadeform "
            "ran on: after `segadeform garment fit`, the file it wrote, in metres)"
        )


def _check_pair(obj: str, pc2: str | None, up_check: bool = True) -> dict | None:
    """The OBJ and its cache (PC2 header), checked before anything is imported: files there, the cache whole, the
    same vertex count, the cache +Y up as the OBJ (:func:`check_up_axis`; ``up_check=False`` skips it: a cache
    whose first frame lies down, head along +Z, fits the OBJ better turned and would be refused)."""
    rest = obj_vertices(obj)
    if pc2 is None:
        return None
    h = pc2_header(pc2)
    if h["points"] != len(rest):
        raise RuntimeError(f"{pc2}: point count does not match {obj} (expected {len(rest)}, got {h['points']})")
    first = np.fromfile(pc2, "<f4", count=3 * h["points"], offset=_PC2_HEADER.size).reshape(-1, 3)
    check_size(obj, rest, pc2, first.astype(np.float64))
    if up_check:
        check_up_axis(obj, rest, pc2, first.astype(np.float64))
    return h


def _import_obj(path: str):
    before = set(bpy.data.objects)
    bpy.ops.wm.obj_import(filepath=path)  # default settings: forward -Z, up Y
    new = [o for o in bpy.data.objects if o not in before]
    if len(new) != 1:
        raise RuntimeError(f"{path}: expected one object from the OBJ import, got {len(new)}")
    return new[0]


def _stored_path(path: str) -> str:
    """``path`` as a modifier keeps it: absolute, or relative to the saved .blend (``//...``) when Blender's
    *Default to relative paths* is on."""
    path = os.path.abspath(path)
    if bpy.data.filepath and bpy.context.preferences.filepaths.use_relative_paths:
        try:
            return bpy.path.relpath(path)
        except ValueError:  # another drive than the .blend's
            pass
    return path


def _remove_default_cube() -> bool:
    """Remove Blender's untouched default cube from a file not saved yet; whether there was one."""
    cube = bpy.data.objects.get("Cube")
    if (
        bpy.data.filepath
        or cube is None
        or cube.type != "MESH"
        or len(cube.data.vertices) != 8
        or cube.modifiers
        or cube.parent is not None
        or any(abs(x) > 1e-9 for x in cube.location)
    ):
        return False
    mesh = cube.data
    bpy.data.objects.remove(cube)
    if mesh.users == 0:
        bpy.data.meshes.remove(mesh)
    return True


def _attach_cache(obj, pc2: str, h: dict, frame_start: float | None):
    """A Mesh Cache modifier on ``obj`` playing ``pc2`` (``h``: its header); returns (modifier, first frame, last
    frame)."""
    if h["points"] != len(obj.data.vertices):  # Blender's importer drops vertices in no face
        raise RuntimeError(
            f"{pc2}: point count does not match {obj.name} as Blender imports it (expected "
            f"{len(obj.data.vertices)}, got {h['points']}; Blender drops vertices that are in no face)"
        )
    start = h["start_frame"] if frame_start is None else float(frame_start)
    mod = obj.modifiers.new(name="segadeform cache", type="MESH_CACHE")
    mod.cache_format = "PC2"
    mod.filepath = _stored_path(pc2)
    # Blender shows sample frame_scale * scene frame - frame_start (measured in Blender 5.0; the header's start and
    # rate are not read): sample k at scene frame start + k * sampleRate (frame_start = start was right only for
    # a sampleRate of 1)
    mod.frame_scale = 1.0 / h["sample_rate"]
    mod.frame_start = start / h["sample_rate"]
    return mod, start, start + max(h["samples"] - 1, 0) * h["sample_rate"]


def import_result(
    garment: str,
    cache: str,
    body: str | None = None,
    body_cache: str | None = None,
    frame_start: float | None = None,
    frames: int | None = None,
    fps: float | None = None,
    save: str | None = None,
    force: bool = False,
    up_check: bool = True,
):
    """Import the garment (and body) OBJ, attach the PC2 caches, set the scene's frame range (and rate).

    ``frame_start``: the scene frame of every cache's first sample (None: each cache's header start frame).
    ``frames``: the scene's number of frames (None: up to the last sample of the caches).
    ``fps``: the scene's frame rate, the run's (None: the scene's is kept).
    ``save``: a .blend to save the scene to (an existing file only with ``force``).
    ``up_check``: refuse a cache written with ``--up z`` (:func:`check_up_axis`; off for a first frame lying down).
    Returns the objects, garment first.
    """
    if fps is not None and not (fps > 0 and fps < 1000):
        raise RuntimeError(f"fps must be in (0, 1000) (got {fps})")
    if save is not None:
        _check_save(save, force)
    if body_cache and not body:  # (it was ignored without a word)
        raise RuntimeError(f"{body_cache}: --body-cache needs --body (expected the body OBJ too, got its cache alone)")
    # every input checked before the scene changes (a missing body cache left a garment without its cache)
    pairs = [(garment, cache, _check_pair(garment, cache, up_check))]
    if body:
        pairs.append((body, body_cache, _check_pair(body, body_cache, up_check)))
    objs, spans = [], []
    before = {c: set(c) for c in (bpy.data.objects, bpy.data.meshes, bpy.data.materials)}
    try:
        for path, pc2, h in pairs:
            ob = _import_obj(path)
            if pc2 is not None:
                spans.append(_attach_cache(ob, pc2, h, frame_start)[1:])
            objs.append(ob)
    except BaseException:  # what was imported is taken out again: the scene as it was
        for c, had in before.items():
            for item in [x for x in c if x not in had]:
                c.remove(item)
        raise
    if _remove_default_cube():
        print("segadeform_import: removed Blender's default cube (it stood where the body's legs are)")
    first = min(s for s, _ in spans)
    last = max(e for _, e in spans) if frames is None else first + int(frames) - 1
    scene = bpy.context.scene
    if fps is not None:
        scene.render.fps = max(1, int(round(fps)))
        scene.render.fps_base = scene.render.fps / fps
    else:
        rate = scene.render.fps / scene.render.fps_base
        print(
            f"segadeform_import: the scene plays at {rate:g} fps; pass --fps with the run's frame rate "
            "(a PC2 file does not record it) if that is not it"
        )
    scene.frame_start = math.floor(first + 1e-6)  # the frames that hold every sample (round(6.5) was 6)
    scene.frame_end = math.ceil(last - 1e-6)
    scene.frame_set(scene.frame_start)
    if save is not None:
        _save_blend(save)
    return objs


def _check_save(path: str, force: bool) -> None:
    """RuntimeError unless ``path`` is a .blend the scene may be saved to: in a folder that exists, and not there
    yet unless ``force``."""
    if os.path.splitext(path)[1].lower() != ".blend":
        raise RuntimeError(f"{path}: --save writes a .blend (expected a name ending .blend)")
    folder = os.path.dirname(os.path.abspath(path))
    if not os.path.isdir(folder):
        raise RuntimeError(f"{path}: no such folder {folder} (expected an existing folder)")
    if os.path.isdir(path) or (os.path.lexists(path) and not os.path.isfile(path)):
        raise RuntimeError(f"{path}: exists and is not a file (expected a .blend to write)")
    if os.path.lexists(path) and not force:
        raise RuntimeError(f"{path}: exists; --save never overwrites a file (pass --force to replace it)")


def _save_blend(path: str) -> None:
    """Save the scene as ``path`` whole or not at all: a copy under a temporary name beside it, then renamed (no
    ``.blend1`` backup is made of a file replaced)."""
    path = os.path.abspath(path)
    tmp = os.path.join(os.path.dirname(path), f".{os.path.basename(path)}.tmp-{os.getpid()}.blend")
    try:
        bpy.ops.wm.save_as_mainfile(filepath=tmp, copy=True)
        os.replace(tmp, path)
    finally:
        if os.path.exists(tmp):
            os.remove(tmp)
    print(f"segadeform_import: saved {path}")


def _main(argv):
    import argparse

    ap = argparse.ArgumentParser(prog="segadeform_import.py")
    ap.add_argument("--garment", required=True)
    ap.add_argument("--cache", required=True)
    ap.add_argument("--body")
    ap.add_argument("--body-cache")
    ap.add_argument(
        "--frame-start",
        type=float,
        default=None,
        help="scene frame of the first sample (default: the PC2 header's start frame)",
    )
    ap.add_argument(
        "--fps", type=float, default=None, help="the scene's frame rate: the run's (default: the scene's is kept)"
    )
    ap.add_argument("--save", metavar="FILE.blend", help="save the scene as FILE.blend (for a headless run)")
    ap.add_argument("--force", action="store_true", help="--save may replace an existing file")
    ap.add_argument(
        "--no-up-check",
        action="store_true",
        help="import a cache whose first frame lies down (head along +Z) without the --up z check, which refuses it",
    )
    a = ap.parse_args(argv)
    if a.force and not a.save:
        raise RuntimeError("--force only lets --save replace a file (expected --save FILE.blend, got no --save)")
    return import_result(
        a.garment,
        a.cache,
        a.body,
        a.body_cache,
        a.frame_start,
        fps=a.fps,
        save=a.save,
        force=a.force,
        up_check=not a.no_up_check,
    )


if __name__ == "__main__":
    try:
        _main(sys.argv[sys.argv.index("--") + 1 :] if "--" in sys.argv else sys.argv[1:])
    except (RuntimeError, OSError) as e:  # one line; the scene as it was
        print(f"Error: {e}", file=sys.stderr)
        if bpy.app.background:
            sys.exit(1)
