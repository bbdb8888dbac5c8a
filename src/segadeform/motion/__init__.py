"""Motions on the 24-joint SMPL skeleton: AMASS ``.npz``, BVH and ASF/AMC IO, resampling,
motion windows, joint limits, a procedural motion library (numpy only), and the motion a scene
describes (:class:`MotionSpec` -> :func:`build_motion`; :func:`frame_range`, the one ``--frames`` check)."""

from __future__ import annotations

import os
from pathlib import Path

from ..errors import FileFormatError
from .bvh import read_bvh, write_bvh
from .motion import (
    N_POSE,
    Motion,
    face_forward,
    feet_on_floor,
    floor_shift,
    history_inputs,
    load_motion_npz,
    motion_windows,
    read_motion_file,
    resample,
    write_motion_file,
)
from .procedural import MOTION_KINDS, make_motion
from .spec import MotionSpec, build_motion, frame_range, glitch_words, glitches_in_range, root_cuts, select_frames

__all__ = [
    "Motion",
    "N_POSE",
    "load_motion",
    "load_motion_npz",
    "feet_on_floor",
    "floor_shift",
    "face_forward",
    "read_bvh",
    "write_bvh",
    "resample",
    "motion_windows",
    "history_inputs",
    "MOTION_KINDS",
    "make_motion",
    "MotionSpec",
    "build_motion",
    "frame_range",
    "select_frames",
    "glitches_in_range",
    "glitch_words",
    "root_cuts",
    "read_motion_file",
    "write_motion_file",
]


def load_motion(
    path: str | os.PathLike,
    *,
    rest_joints=None,
    up: str = "auto",
    units=None,
    joint_map=None,
    floor: bool = False,
    skeleton: str | os.PathLike | None = None,
    animation: str | None = None,
) -> Motion:
    """Read a motion by extension onto the SMPL skeleton of a body.

    Args:
        path: ``.npz`` (AMASS / SMPL / segadeform), ``.bvh`` (any common humanoid skeleton), ``.amc`` (CMU's
            ASF/AMC motion capture, at CMU's 120 fps: :mod:`.asf`) or ``.sgdm`` (a motion file from
            ``segadeform motion export``: played as it is, already retargeted onto the body shape it was made
            for, whatever ``rest_joints``).
        rest_joints: (24, 3) rest joints of the body that will play it (T-pose, metres): BVH files are
            retargeted onto it (BVH and AMC alike), SMPL files' root position is carried over to it.  Default:
            the built-in T-pose skeleton for ``.npz``, the file's own proportions for ``.bvh`` and ``.amc``.
        up: the file's up axis, ``"auto"``, ``"y"`` or ``"z"``.
        units: BVH only: metres per file unit or a unit name (``cm``, ``inch`` ...); default: fit the
            file's legs to the body's.
        joint_map: BVH and AMC: SMPL name -> file joint (bone) name, a dict or a TOML/JSON file.
        floor: shift the motion so its lowest foot joint is where the rest pose's is (needs
            ``rest_joints``, else the built-in skeleton).
        skeleton: AMC only: the ASF skeleton; default: the one ``.asf`` in the AMC's folder
            (:func:`.asf.find_asf`).
        animation: glTF only (``.glb``/``.gltf``, a skinned character's animation read like a BVH file:
            :mod:`.gltf`): the animation's name when the file has several (default: the first).
    """
    p = Path(path)
    ext = p.suffix.lower()
    if floor and rest_joints is None:
        from ..body.skeleton import default_rest_joints

        rest_joints = default_rest_joints()
    if skeleton is not None and ext != ".amc":
        raise FileFormatError(
            "a skeleton (.asf) applies to AMC motions only",
            path=p,
            expected=".amc with --skeleton",
            got=ext or "no extension",
        )
    if animation is not None and ext not in (".glb", ".gltf"):
        raise FileFormatError(
            "an animation name applies to glTF files only (an FBX file's: `segadeform motion convert --animation`)",
            path=p,
            expected=".glb or .gltf with --animation",
            got=ext or "no extension",
        )
    if ext == ".npz":
        if units is not None or joint_map is not None:
            raise FileFormatError(
                "units and joint maps apply to BVH files only",
                path=p,
                expected=".bvh for --units / --joint-map",
                got=ext,
            )
        m = load_motion_npz(p, up=up, rest_joints=rest_joints)
    elif ext == ".bvh":
        m = read_bvh(p, rest_joints=rest_joints, up=up, units=units, joint_map=joint_map)
    elif ext in (".glb", ".gltf"):
        from .gltf import read_gltf

        m = read_gltf(p, rest_joints=rest_joints, up=up, units=units, joint_map=joint_map, animation=animation)
    elif ext == ".amc":
        from .asf import read_amc

        if units is not None:
            raise FileFormatError(
                "units apply to BVH files only: an ASF states its own (:units length)",
                path=p,
                expected="no --units for .amc",
                got=units,
            )
        m = read_amc(p, skeleton, rest_joints=rest_joints, up=up, joint_map=joint_map)
    elif ext == ".sgdm":  # a motion file (segadeform motion export): already on the skeleton, y-up, retargeted
        if units is not None or joint_map is not None or up not in ("auto", "y"):
            raise FileFormatError(
                "a motion file (.sgdm) is already retargeted, y-up: units, joint maps and up axes do not apply",
                path=p,
                expected="no --units, --joint-map or --motion-up z",
                got=", ".join(
                    k
                    for k, v in (("units", units), ("joint map", joint_map), ("up " + str(up), up not in ("auto", "y")))
                    if v
                ),
            )
        m, _ = read_motion_file(p)
    elif ext == ".fbx":  # read through Blender, a layer above this one: said, with the command that does it
        raise FileFormatError(
            "an FBX motion is read through Blender: `segadeform run`, `motion info` and `motion export` take it, and "
            "`segadeform motion convert FILE.fbx -o FILE.bvh` writes it as a BVH file for the rest",
            path=p,
        )
    else:
        raise FileFormatError(
            "unknown motion file type",
            path=p,
            expected=".npz, .bvh, .amc, .glb, .gltf, .sgdm (or .fbx through `segadeform motion convert`)",
            got=ext or "none",
        )
    return feet_on_floor(m, rest_joints) if floor else m
