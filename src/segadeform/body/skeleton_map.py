"""Which joint of a foreign skeleton is which SMPL joint: name tables, a shape rule, user maps.

Motion files name their joints in many ways (``../shared/notes/facts.md``
lists the ones seen in the wild).  :func:`map_skeleton` finds, for each of
SMPL's 24 joints, the source joint that plays its part, in this order:

1. a user map (``joint_map``: SMPL name -> source name), taken as given;
2. the name tables (:data:`NAME_TABLES`): SMPL, SMPL's short names, Mixamo,
   the CMU conversions (cgspeed MotionBuilder, 3dsMax and DAZ/Poser styles,
   and the raw ASF/AMC bone names), Unity-humanoid style (``UpperLeg_L``),
   Character Creator / iClone (``CC_Base_L_Thigh``), Unreal's mannequin
   (``thigh_l``), Xsens MVN (``RightUpperLeg``, ``L5``, ``T8``), VRM
   (``leftUpperLeg``, VRoid's ``J_Bip_L_UpperLeg``), Rigify's deform bones
   (``DEF-thigh.L``) and Rokoko (``LeftThigh``, ``Spine4``).  Names are
   compared as they are and without a prefix most of them share
   (:func:`common_prefix`: ``Character1_``, ``CC_Base_``).  The table matching
   most names wins; it is used when it finds every required joint, and its
   chest is moved to where the arms branch when that is higher (UE5's
   ``spine_05``);
3. otherwise the shape rule (:func:`_shape_map`), which needs no names: the
   feet are the lowest chain ends of two branches, the hands the chain ends
   farthest out on either side whose branches meet in a chest above the hips,
   the pelvis the common ancestor of legs and chest.  Along each limb the
   ankle is where the chain turns forward, the wrist where the fingers branch
   (or the chain's end), and the upper and lower bones are the pair of joints
   closest to the built-in skeleton's proportions (twist joints inside a bone
   are passed over; a collar or a hip helper at the pelvis is told from the
   limb by how far it is from the chest or pelvis).  Spine joints are those
   between pelvis and chest; the neck and head lie on the way to the chain
   ends above the shoulders.  Left and right come from the rest offsets:
   left is up x forward, forward being where the toes point.  Name words
   (``thigh``, ``knee``, ``forearm``, ``L``/``Left``) help where there are any.

``SkeletonMapping.found_by`` records, per joint, whether it was found by name
(which table), by name words, by shape or by the user map (``segadeform motion
info`` prints it).  A skeleton the rule cannot read as a humanoid is refused
with what is missing (no two legs, no arms ...).

Joints that play no SMPL part (eyes, face, fingers, toe ends, twist and share
helpers, ``LHipJoint``) are left out: the retargeting (:mod:`.retarget`)
works with global rotations and posed positions, so their rotations are
carried by the mapped joints below them.  SMPL joints the source lacks are
*virtual*: ``spine2`` between two mapped spine joints, a neck between chest
and head, collars, hands, toes; the retargeting fills them in.

Names are compared after :func:`normalize_name`: the namespace (``mixamorig:``,
``Armature|``) is dropped, then case and every non-alphanumeric character.
"""

from __future__ import annotations

import dataclasses
import functools
import re
from collections.abc import Sequence
from typing import cast

import numpy as np

from ..errors import InputError
from .skeleton import SMPL_JOINT_NAMES, SMPL_PARENTS

__all__ = [
    "NAME_TABLES",
    "MIXAMO_TO_SMPL",
    "SMPL_SHORT_NAMES",
    "REQUIRED_JOINTS",
    "SkeletonMapping",
    "normalize_name",
    "common_prefix",
    "map_skeleton",
    "read_joint_map",
]

#: SMPL joints a source skeleton must provide (directly or through a user map).
REQUIRED_JOINTS = (
    "pelvis",
    "left_hip",
    "right_hip",
    "left_knee",
    "right_knee",
    "left_ankle",
    "right_ankle",
    "left_shoulder",
    "right_shoulder",
    "left_elbow",
    "right_elbow",
    "left_wrist",
    "right_wrist",
)

MIXAMO_TO_SMPL = {
    "Hips": "pelvis",
    "LeftUpLeg": "left_hip",
    "RightUpLeg": "right_hip",
    "Spine": "spine1",
    "LeftLeg": "left_knee",
    "RightLeg": "right_knee",
    "Spine1": "spine2",
    "LeftFoot": "left_ankle",
    "RightFoot": "right_ankle",
    "Spine2": "spine3",
    "LeftToeBase": "left_foot",
    "RightToeBase": "right_foot",
    "Neck": "neck",
    "LeftShoulder": "left_collar",
    "RightShoulder": "right_collar",
    "Head": "head",
    "LeftArm": "left_shoulder",
    "RightArm": "right_shoulder",
    "LeftForeArm": "left_elbow",
    "RightForeArm": "right_elbow",
    "LeftHand": "left_wrist",
    "RightHand": "right_wrist",
    "LeftHandMiddle1": "left_hand",
    "RightHandMiddle1": "right_hand",
}
SMPL_SHORT_NAMES = {
    "Pelvis": "pelvis",
    "L_Hip": "left_hip",
    "R_Hip": "right_hip",
    "Spine1": "spine1",
    "L_Knee": "left_knee",
    "R_Knee": "right_knee",
    "Spine2": "spine2",
    "L_Ankle": "left_ankle",
    "R_Ankle": "right_ankle",
    "Spine3": "spine3",
    "L_Foot": "left_foot",
    "R_Foot": "right_foot",
    "Neck": "neck",
    "L_Collar": "left_collar",
    "R_Collar": "right_collar",
    "Head": "head",
    "L_Shoulder": "left_shoulder",
    "R_Shoulder": "right_shoulder",
    "L_Elbow": "left_elbow",
    "R_Elbow": "right_elbow",
    "L_Wrist": "left_wrist",
    "R_Wrist": "right_wrist",
    "L_Hand": "left_hand",
    "R_Hand": "right_hand",
}


def _sided(table: dict) -> dict:
    """Expand ``{"{S}UpLeg": "{s}_hip"}`` into Left/Right (``{S}``), l/r (``{c}``), L/R (``{C}``) and
    left/right (``{s}``)."""
    out = {}
    for k, v in table.items():
        if "{" not in k:
            out[k] = v
            continue
        for S, c, s in (("Left", "l", "left"), ("Right", "r", "right")):
            out[k.format(S=S, c=c, C=c.upper(), s=s)] = v.format(s=s)
    return out


#: name scheme -> {source joint name: SMPL joint name}; the pattern is documented per scheme.
NAME_TABLES: dict[str, dict[str, str]] = {
    "smpl": {n: n for n in SMPL_JOINT_NAMES},
    "smpl-short": SMPL_SHORT_NAMES,
    "mixamo": MIXAMO_TO_SMPL,
    # cgspeed's MotionBuilder-friendly CMU conversion: Hips/LHipJoint/LeftUpLeg/LowerBack/Spine/Spine1/Neck/Neck1
    "cmu-motionbuilder": _sided(
        {
            "Hips": "pelvis",
            "{S}UpLeg": "{s}_hip",
            "{S}Leg": "{s}_knee",
            "{S}Foot": "{s}_ankle",
            "{S}ToeBase": "{s}_foot",
            "LowerBack": "spine1",
            "Spine": "spine2",
            "Spine1": "spine3",
            "Neck": "neck",
            "Head": "head",
            "{S}Shoulder": "{s}_collar",
            "{S}Arm": "{s}_shoulder",
            "{S}ForeArm": "{s}_elbow",
            "{S}Hand": "{s}_wrist",
            "{S}FingerBase": "{s}_hand",
        }
    ),
    # cgspeed's 3dsMax-friendly conversion: Hips/LHipJoint/LeftHip/LeftKnee/lowerback/Chest/Chest2/lowerneck
    "cmu-3dsmax": _sided(
        {
            "Hips": "pelvis",
            "{S}Hip": "{s}_hip",
            "{S}Knee": "{s}_knee",
            "{S}Ankle": "{s}_ankle",
            "{S}Toe": "{s}_foot",
            "lowerback": "spine1",
            "Chest": "spine2",
            "Chest2": "spine3",
            "lowerneck": "neck",
            "Neck": "neck",
            "Head": "head",
            "{S}Collar": "{s}_collar",
            "{S}Shoulder": "{s}_shoulder",
            "{S}Elbow": "{s}_elbow",
            "{S}Wrist": "{s}_wrist",
            "{c}hand": "{s}_hand",
        }
    ),
    # cgspeed's DAZ/Poser-friendly conversion: hip/abdomen/chest/lCollar/lShldr/lThigh/lShin (no spine2, no toes)
    "cmu-daz": _sided(
        {
            "hip": "pelvis",
            "abdomen": "spine1",
            "chest": "spine3",
            "neck": "neck",
            "head": "head",
            "{c}Thigh": "{s}_hip",
            "{c}Shin": "{s}_knee",
            "{c}Foot": "{s}_ankle",
            "{c}Collar": "{s}_collar",
            "{c}Shldr": "{s}_shoulder",
            "{c}ForeArm": "{s}_elbow",
            "{c}Hand": "{s}_wrist",
            "{c}Mid1": "{s}_hand",
        }
    ),
    # the CMU ASF/AMC bone names as some BVH conversions keep them (hip/lhipjoint/lhip/lknee/lfoot)
    "cmu-asf": _sided(
        {
            "hip": "pelvis",
            "{c}hip": "{s}_hip",
            "{c}knee": "{s}_knee",
            "{c}foot": "{s}_ankle",
            "{S}toebase": "{s}_foot",
            "lowerback": "spine1",
            "abdomen": "spine2",
            "chest": "spine3",
            "neck": "neck",
            "head": "head",
            "{c}collar": "{s}_collar",
            "{c}shoulder": "{s}_shoulder",
            "{c}elbow": "{s}_elbow",
            "{c}hand": "{s}_wrist",
            "{S}fingerbase": "{s}_hand",
            # the raw ASF bone names; a joint is where its bone starts: lradius at the elbow, lwrist a
            # forearm twist bone part-way down (folded in), lhand at the wrist, lfingers at the knuckles
            "root": "pelvis",
            "{c}femur": "{s}_hip",
            "{c}tibia": "{s}_knee",
            "{c}toes": "{s}_foot",
            "upperback": "spine2",
            "thorax": "spine3",
            "lowerneck": "neck",
            "{c}clavicle": "{s}_collar",
            "{c}humerus": "{s}_shoulder",
            "{c}radius": "{s}_elbow",
            "{c}fingers": "{s}_hand",
        }
    ),
    # Unity-humanoid style with side suffixes (Bandai-Namco-style game rigs: UpperLeg_L, LowerArm_R; often a
    # floor joint above the hips and six channels on every joint)
    "unity": _sided(
        {
            "Hips": "pelvis",
            "Spine": "spine1",
            "Chest": "spine2",
            "UpperChest": "spine3",
            "Neck": "neck",
            "Head": "head",
            "UpperLeg_{C}": "{s}_hip",
            "LowerLeg_{C}": "{s}_knee",
            "Foot_{C}": "{s}_ankle",
            "Toes_{C}": "{s}_foot",
            "Toe_{C}": "{s}_foot",
            "Shoulder_{C}": "{s}_collar",
            "UpperArm_{C}": "{s}_shoulder",
            "LowerArm_{C}": "{s}_elbow",
            "Hand_{C}": "{s}_wrist",
            "Middle1_{C}": "{s}_hand",
        }
    ),
    # Character Creator / iClone / ActorCore (CC_Base_ prefix; twist, ShareBone, finger and face joints left out)
    "character-creator": _sided(
        {
            p + k: v
            for p in ("CC_Base_", "")
            for k, v in {
                "Hip": "pelvis",
                "Waist": "spine1",
                "Spine01": "spine2",
                "Spine02": "spine3",
                "NeckTwist01": "neck",
                "Head": "head",
                "{C}_Thigh": "{s}_hip",
                "{C}_Calf": "{s}_knee",
                "{C}_Foot": "{s}_ankle",
                "{C}_ToeBase": "{s}_foot",
                "{C}_Clavicle": "{s}_collar",
                "{C}_Upperarm": "{s}_shoulder",
                "{C}_Forearm": "{s}_elbow",
                "{C}_Hand": "{s}_wrist",
                "{C}_Mid1": "{s}_hand",
            }.items()
        }
    ),
    # Unreal's mannequin (UE4: spine_01..03; UE5's spine_04/05 are found by the chest rule)
    "unreal": _sided(
        {
            "pelvis": "pelvis",
            "spine_01": "spine1",
            "spine_02": "spine2",
            "spine_03": "spine3",
            "neck_01": "neck",
            "head": "head",
            "thigh_{c}": "{s}_hip",
            "calf_{c}": "{s}_knee",
            "foot_{c}": "{s}_ankle",
            "ball_{c}": "{s}_foot",
            "clavicle_{c}": "{s}_collar",
            "upperarm_{c}": "{s}_shoulder",
            "lowerarm_{c}": "{s}_elbow",
            "hand_{c}": "{s}_wrist",
            "middle_01_{c}": "{s}_hand",
        }
    ),
    # Xsens MVN: Pelvis/L5/L3/T12/T8, RightUpperLeg/RightLowerLeg
    "xsens": _sided(
        {
            "Pelvis": "pelvis",
            "L3": "spine1",
            "T12": "spine2",
            "T8": "spine3",
            "Neck": "neck",
            "Head": "head",
            "{S}UpperLeg": "{s}_hip",
            "{S}LowerLeg": "{s}_knee",
            "{S}Foot": "{s}_ankle",
            "{S}Toe": "{s}_foot",
            "{S}Shoulder": "{s}_collar",
            "{S}UpperArm": "{s}_shoulder",
            "{S}ForeArm": "{s}_elbow",
            "{S}Hand": "{s}_wrist",
        }
    ),
    # VRM humanoid bones (leftUpperLeg; also Unity's Mecanim names) and VRoid's node names (J_Bip_L_UpperLeg)
    "vrm": _sided(
        {
            "hips": "pelvis",
            "spine": "spine1",
            "chest": "spine2",
            "upperChest": "spine3",
            "neck": "neck",
            "head": "head",
            "{s}UpperLeg": "{s}_hip",
            "{s}LowerLeg": "{s}_knee",
            "{s}Foot": "{s}_ankle",
            "{s}Toes": "{s}_foot",
            "{s}Shoulder": "{s}_collar",
            "{s}UpperArm": "{s}_shoulder",
            "{s}LowerArm": "{s}_elbow",
            "{s}Hand": "{s}_wrist",
            "{s}MiddleProximal": "{s}_hand",
            "J_Bip_C_Hips": "pelvis",
            "J_Bip_C_Spine": "spine1",
            "J_Bip_C_Chest": "spine2",
            "J_Bip_C_UpperChest": "spine3",
            "J_Bip_C_Neck": "neck",
            "J_Bip_C_Head": "head",
            "J_Bip_{C}_UpperLeg": "{s}_hip",
            "J_Bip_{C}_LowerLeg": "{s}_knee",
            "J_Bip_{C}_Foot": "{s}_ankle",
            "J_Bip_{C}_ToeBase": "{s}_foot",
            "J_Bip_{C}_Shoulder": "{s}_collar",
            "J_Bip_{C}_UpperArm": "{s}_shoulder",
            "J_Bip_{C}_LowerArm": "{s}_elbow",
            "J_Bip_{C}_Hand": "{s}_wrist",
            "J_Bip_{C}_Middle1": "{s}_hand",
        }
    ),
    # Blender Rigify's deform bones (DEF-thigh.L; the .001 twist segments left out), with or without DEF-
    "rigify": _sided(
        {
            p + k: v
            for p in ("DEF-", "")
            for k, v in {
                "spine": "pelvis",
                "spine.001": "spine1",
                "spine.002": "spine2",
                "spine.003": "spine3",
                "spine.004": "neck",
                "spine.006": "head",
                "thigh.{C}": "{s}_hip",
                "shin.{C}": "{s}_knee",
                "foot.{C}": "{s}_ankle",
                "toe.{C}": "{s}_foot",
                "shoulder.{C}": "{s}_collar",
                "upper_arm.{C}": "{s}_shoulder",
                "forearm.{C}": "{s}_elbow",
                "hand.{C}": "{s}_wrist",
                "f_middle.01.{C}": "{s}_hand",
            }.items()
        }
    ),
    # Rokoko Studio: Hips/Spine1..Spine4, LeftThigh/LeftShin/LeftToe
    "rokoko": _sided(
        {
            "Hips": "pelvis",
            "Spine1": "spine1",
            "Spine2": "spine2",
            "Spine4": "spine3",
            "Neck": "neck",
            "Head": "head",
            "{S}Thigh": "{s}_hip",
            "{S}Shin": "{s}_knee",
            "{S}Foot": "{s}_ankle",
            "{S}Toe": "{s}_foot",
            "{S}Shoulder": "{s}_collar",
            "{S}Arm": "{s}_shoulder",
            "{S}ForeArm": "{s}_elbow",
            "{S}Hand": "{s}_wrist",
            "{S}Finger3Proximal": "{s}_hand",
        }
    ),
}


def normalize_name(name: str) -> str:
    """``"mixamorig:LeftUpLeg"`` -> ``"leftupleg"``; ``"Armature|L_Hip"`` -> ``"lhip"``: the namespace (up to the
    last ``:`` or ``|``) and a ``mixamorig_`` prefix dropped, then case and every non-alphanumeric character."""
    base = re.split(r"[:|]", name)[-1]
    base = re.sub(r"^mixamorig\d*_", "", base)
    return re.sub(r"[^0-9a-z]", "", base.lower())


def common_prefix(names: Sequence[str], share: float = 0.6) -> str:
    """The longest prefix ending in ``_``, ``-``, ``.`` or a space that at least ``share`` of the names (after
    their namespace) start with, and at least 3 of them: ``Character1_``, ``CC_Base_``, ``DEF-``, ``J_Bip_``;
    ``""`` when there is none."""
    bases = [re.split(r"[:|]", n)[-1] for n in names]
    counts: dict[str, int] = {}
    for b in bases:
        for m in re.finditer(r"[_\-. ]", b):
            if m.end() < len(b):
                counts[b[: m.end()]] = counts.get(b[: m.end()], 0) + 1
    need = max(3, share * len(bases))
    good = [k for k, c in counts.items() if c >= need]
    return max(good, key=len) if good else ""


def _strip(name: str, prefix: str) -> str:
    base = re.split(r"[:|]", name)[-1]
    return base[len(prefix) :] if prefix and base.startswith(prefix) else base


_NORMALIZED_TABLES = {k: {normalize_name(a): b for a, b in t.items()} for k, t in NAME_TABLES.items()}


@dataclasses.dataclass(frozen=True)
class SkeletonMapping:
    """Where each SMPL joint is in a source skeleton.

    Attributes:
        source: (24,) source joint index per SMPL joint, -1 where the source has none (virtual).
        scheme: how it was found: a key of :data:`NAME_TABLES`, ``"shape"`` (the skeleton's shape, helped by
            name words where there are any) or ``"joint-map"`` (``"+joint-map"`` appended when a user map
            completed another scheme).
        source_names: the source skeleton's joint names.
        found_by: (24,) how each SMPL joint was found: ``"name (TABLE)"``, ``"name words"``, ``"shape"``,
            ``"joint map"``, or ``""`` for a virtual joint.
    """

    source: np.ndarray
    scheme: str
    source_names: tuple
    found_by: tuple = ()

    def mapped(self) -> dict[str, str]:
        """SMPL name -> source name for every mapped joint."""
        return {SMPL_JOINT_NAMES[j]: self.source_names[i] for j, i in enumerate(self.source) if i >= 0}

    def how(self) -> dict[str, str]:
        """SMPL name -> how it was found (``found_by``) for every mapped joint."""
        return {
            SMPL_JOINT_NAMES[j]: (self.found_by[j] if self.found_by else self.scheme)
            for j, i in enumerate(self.source)
            if i >= 0
        }

    @property
    def virtual(self) -> list[str]:
        return [SMPL_JOINT_NAMES[j] for j in np.flatnonzero(self.source < 0)]

    @property
    def ignored(self) -> list[str]:
        used = set(int(i) for i in self.source if i >= 0)
        return [n for i, n in enumerate(self.source_names) if i not in used]


def read_joint_map(path) -> dict[str, str]:
    """A user joint map: TOML or JSON ``{smpl_name: source_name}`` (a ``[joints]`` table in TOML).

    Either side may be given as the key: entries whose key is not an SMPL name
    but whose value is are turned around.
    """
    import json
    from pathlib import Path

    from ..errors import FileFormatError, file_error

    p = Path(path)
    if p.suffix.lower() == ".json":
        try:
            text = p.read_bytes().decode("utf-8")
        except OSError as e:
            raise file_error(e, p, "joint map") from None
        except UnicodeDecodeError:
            raise FileFormatError("joint map is not UTF-8 text", path=p) from None
        try:
            data = json.loads(text)
        except json.JSONDecodeError as e:
            raise FileFormatError(f"not valid JSON ({e.msg})", path=p, line=e.lineno) from None
    else:
        from ..io.toml import read_toml

        data, _ = read_toml(p, "joint map")
        data = data.get("joints", data)
    if not isinstance(data, dict) or not all(isinstance(k, str) and isinstance(v, str) for k, v in data.items()):
        raise FileFormatError(
            "joint map must map names to names",
            path=p,
            expected='entries like  left_hip = "UpperLeg_L"',
            got=type(data).__name__,
        )
    out = {}
    for k, v in data.items():
        if k in SMPL_JOINT_NAMES:
            out[k] = v
        elif v in SMPL_JOINT_NAMES:
            out[v] = k
        else:
            raise FileFormatError(
                f"joint map entry {k!r} = {v!r} names no SMPL joint",
                path=p,
                expected="one side of each entry among " + ", ".join(SMPL_JOINT_NAMES),
            )
    return out


# ---------------------------------------------------------------------------------------------------------
# the shape rule

_LEFT = re.compile(r"(^|[^a-z])(l|left|lft)([^a-z]|$)|^left|left$|^l(?=[a-z])", re.I)


def _side_of(name: str) -> str | None:
    """'left', 'right' or None from name words: LeftArm, lThigh, L_Hip, UpperLeg_L, arm.l, Arm Left."""
    base = name.rsplit(":", 1)[-1]
    low = base.lower()
    words = [w for w in re.split(r"[^a-z0-9]+", low) if w]
    for w in words:
        if w in ("l", "left", "lft"):
            return "left"
        if w in ("r", "right", "rgt"):
            return "right"
    if low.startswith("left") or low.endswith("left"):
        return "left"
    if low.startswith("right") or low.endswith("right"):
        return "right"
    # camel-case prefix: LThigh, lShldr, RHipJoint, rForeArm
    if len(base) >= 2 and base[0] in "lLrR" and base[1].isupper():
        return "left" if base[0] in "lL" else "right"
    return None


_PART_WORDS = [  # (smpl role, words); checked in this order on the side-stripped name
    ("twist", ("twist", "roll")),
    ("finger", ("thumb", "index", "middle", "ring", "pinky", "pinkie", "finger", "mid1", "mid2", "mid3")),
    ("foot", ("toe", "toes", "toebase", "ball")),
    ("ankle", ("foot", "ankle")),
    ("hip", ("thigh", "upleg", "upperleg", "femur")),
    ("knee", ("shin", "calf", "knee", "lowerleg", "lowleg", "tibia", "leg")),
    ("collar", ("collar", "clavicle")),
    ("elbow", ("forearm", "elbow", "lowerarm", "lowarm", "radius")),
    ("shoulder", ("upperarm", "uparm", "shldr", "humerus", "shoulder", "arm")),
    ("wrist", ("wrist", "hand")),
]


def _role_of(name: str) -> str | None:
    n = normalize_name(name)
    n = re.sub(r"^(left|right|l|r)(?=[a-z])", "", n) if _side_of(name) else n
    n = re.sub(r"(left|right|l|r)$", "", n) if _side_of(name) else n
    for role, words in _PART_WORDS:
        if any(w in n for w in words):
            return role
    return None


def _path(parents: np.ndarray, a: int, b: int) -> list[int]:
    """Joints from a (exclusive) down to its descendant b (inclusive)."""
    out = []
    while b != a:
        if b < 0:
            return []
        out.append(b)
        b = int(parents[b])
    return out[::-1]


def _ancestors(parents, i) -> list[int]:
    out = [i]
    while parents[i] >= 0:
        i = int(parents[i])
        out.append(i)
    return out


def _subtree(children: list[list[int]], j: int) -> list[int]:
    out, todo = [], [j]
    while todo:
        k = todo.pop()
        out.append(k)
        todo.extend(children[k])
    return out


def _lca(parents, idx: Sequence[int]) -> int:
    common: list[int] | None = None
    for i in idx:
        anc = _ancestors(parents, i)
        common = anc if common is None else [a for a in common if a in set(anc)]
    return cast(list[int], common)[0]  # idx is never empty


@functools.lru_cache(maxsize=1)
def _template() -> dict[str, float]:
    """Proportions of the built-in T-pose skeleton the shape rule compares limbs with: thigh / shin and upper
    arm / forearm, and how far the hip (shoulder) is from the pelvis (chest) as a share of the limb."""
    from .skeleton import default_rest_joints

    J = default_rest_joints()
    d = lambda a, b: float(np.linalg.norm(J[a] - J[b]))  # noqa: E731
    leg, arm = d(1, 4) + d(4, 7), d(16, 18) + d(18, 20)
    return {
        "leg_ratio": d(1, 4) / d(4, 7),
        "arm_ratio": d(16, 18) / d(18, 20),
        "hip_out": d(1, 0) / leg,
        "shoulder_out": d(16, 9) / arm,
    }


def _limb_triple(
    pos: np.ndarray, chain: list[int], ends_at: Sequence[int], root: int, ratio: float, out: float, min_len: float
):
    """The (top, middle, end) joints of a limb along ``chain`` -- hip, knee, ankle or shoulder, elbow, wrist --
    whose two bones are closest to the template's proportions: ``log(upper/lower / ratio)^2`` plus half of
    ``log(top's distance from root / (out x limb length))^2`` (this tells the upper arm from the collar and the
    thigh from a hip helper at the pelvis).  Joints need not be linked directly: twist joints in a bone's
    middle are passed over.  ``ends_at``: the joints of ``chain`` allowed as the end.  None when no two bones
    reach ``min_len``."""
    best, best_score = None, np.inf
    tol = 0.05 * min_len
    for c in sorted({_first_at(pos, chain, c, tol) for c in ends_at}, key=chain.index):
        ic = chain.index(c)
        for ib in range(1, ic):
            for ia in range(ib):
                a, b = chain[ia], chain[ib]
                up, low = np.linalg.norm(pos[b] - pos[a]), np.linalg.norm(pos[c] - pos[b])
                if up < min_len or low < min_len:
                    continue
                reach = np.linalg.norm(pos[a] - pos[root]) + 0.02 * (up + low)
                score = np.log(up / low / ratio) ** 2 + 0.5 * np.log(reach / ((out + 0.02) * (up + low))) ** 2
                if score < best_score - 1e-9:
                    best, best_score = (a, b, c), score
    if best is not None:  # a limb starts at the last of joints at (nearly) one point (DAZ's lButtock -> lThigh)
        a, b, c = best
        ia = chain.index(a)
        while chain[ia + 1] != b and np.linalg.norm(pos[chain[ia + 1]] - pos[a]) < 6 * tol:
            ia += 1
        best = (chain[ia], b, c)
    return best


def _first_at(pos: np.ndarray, chain: list[int], j: int, tol: float) -> int:
    """The first joint of ``chain`` at (nearly) the point where ``j`` is: a hand, not the finger base at its
    place (CMU's LeftHand -> LeftFingerBase)."""
    i = chain.index(j)
    while i > 0 and np.linalg.norm(pos[chain[i - 1]] - pos[j]) < tol:
        i -= 1
    return chain[i]


def _shape_map(
    names: list[str], parents: np.ndarray, rest: np.ndarray, ends: np.ndarray
) -> tuple[dict[str, int], dict[str, str], str]:
    """The shape rule (module docstring): ``({smpl name: joint}, {smpl name: "shape" | "name words"}, problem)``;
    the problem says what is missing when the skeleton is not a humanoid (the map is then empty).

    ``rest (J, 3)``: +Y-up rest positions; ``ends (J, 3)``: the end-site position of each joint (its own
    position when it has none)."""
    nj = len(names)
    children: list[list[int]] = [[] for _ in range(nj)]
    for i, p in enumerate(parents):
        if p >= 0:
            children[int(p)].append(i)
    leaves = [i for i in range(nj) if not children[i]]
    height = float(np.ptp(np.concatenate([rest[:, 1], ends[:, 1]]))) if nj else 0.0
    if nj < 7 or height <= 0:
        return (
            {},
            {},
            ("a flat skeleton (no height)" if height <= 0 else f"{nj} joints: too few for hips, two legs and two arms"),
        )
    roles = [_role_of(n) for n in names]
    sides = [_side_of(n) for n in names]
    anc = [set(_ancestors(parents, i)) for i in range(nj)]
    tmpl = _template()
    # feet: the lowest chain end, then the lowest in another branch meeting it well above the floor
    by_low = sorted(leaves, key=lambda i: ends[i, 1])
    floor = ends[by_low[0], 1]
    foot_a = by_low[0]
    foot_b = next((i for i in by_low[1:] if rest[_lca(parents, [foot_a, i]), 1] - floor > 0.3 * height), None)
    if foot_b is None:
        return {}, {}, "no two legs (two low chain ends, the feet, hanging from one joint above the knees)"
    legs_root = _lca(parents, [foot_a, foot_b])
    leg_tops = {_path(parents, legs_root, f)[0] for f in (foot_a, foot_b)}
    # facing: the feet point forward (from the ankles' region to the toes), else +Z; left = up x forward
    fwd = np.zeros(3)
    for f in (foot_a, foot_b):
        low = [j for j in _path(parents, legs_root, f) if rest[j, 1] - floor < 0.15 * height] or [f]
        fwd += ends[f] - rest[low[0]]
    fwd[1] = 0.0
    fwd = fwd / np.linalg.norm(fwd) if np.linalg.norm(fwd) > 0.02 * height else np.array([0.0, 0.0, 1.0])
    left_dir = np.cross([0.0, 1.0, 0.0], fwd)
    # hands: the two chain ends farthest out on either side whose branches meet in a chest above the hips,
    # under a pelvis that also carries the legs
    centre = rest[legs_root]
    cand = [i for i in leaves if not (leg_tops & anc[i])]
    lateral = {i: float((ends[i] - centre) @ left_dir) for i in cand}
    by_lat = sorted(cand, key=lambda i: -abs(lateral[i]))
    hands = None
    for ka, a in enumerate(by_lat):
        for b in by_lat[ka + 1 :]:
            if np.sign(lateral[b]) == np.sign(lateral[a]):
                continue
            chest = _lca(parents, [a, b])
            if chest in (a, b):
                continue
            pelvis = _lca(parents, [legs_root, chest])
            if rest[pelvis, 1] - floor > 0.3 * height and rest[chest, 1] > rest[pelvis, 1]:
                hands = (a, b, chest, pelvis)
                break
        if hands:
            break
    if hands is None:
        return (
            {},
            {},
            f"no arms (two chain ends on either side of the body whose branches meet in a chest above "
            f"the hips; found two legs hanging from {names[legs_root]})",
        )
    hand_a, hand_b, chest, pelvis = hands
    out: dict[str, int] = {"pelvis": pelvis, "spine3": chest}
    how: dict[str, str] = {"pelvis": "shape", "spine3": "shape"}

    def put(key, joint, by="shape"):
        out[key], how[key] = joint, by

    def side(chain_end: int, other_end: int) -> tuple[str, str]:
        s = sides[chain_end] or next((sides[j] for j in _ancestors(parents, chain_end) if sides[j]), None)
        if s:
            return s, "name words"
        return ("left" if (ends[chain_end] - ends[other_end]) @ left_dir > 0 else "right"), "shape"

    # legs
    for f, other in ((foot_a, foot_b), (foot_b, foot_a)):
        s, _ = side(f, other)
        chain = _path(parents, legs_root, f)
        plain = [j for j in chain if roles[j] != "twist"]
        named = {}
        for j in chain:
            if roles[j] in ("knee", "ankle", "foot") and roles[j] not in named:
                named[roles[j]] = j
        if "knee" in named and "ankle" in named and 1 <= chain.index(named["knee"]) < chain.index(named["ankle"]):
            knee, ankle = named["knee"], named["ankle"]
            before = [j for j in chain[: chain.index(knee)] if roles[j] != "twist"] or chain[: chain.index(knee)]
            hips = [j for j in before if roles[j] == "hip"]
            hip = hips[-1] if hips else before[-1]
            by = "name words"
        else:
            # the ankle: the first joint from which the rest of the chain runs forward more than down
            ankle = next(
                (j for j in plain[2:] if abs(ends[f, 1] - rest[j, 1]) < np.linalg.norm((ends[f] - rest[j])[[0, 2]])),
                plain[-1],
            )
            trip = _limb_triple(rest, plain, [ankle], pelvis, tmpl["leg_ratio"], tmpl["hip_out"], 0.08 * height)
            if trip is None:
                return (
                    {},
                    {},
                    f"the {s} leg has no thigh and shin (two bones of at least {0.08 * height:.3g} "
                    f"units from the hips to the foot {names[f]})",
                )
            hip, knee, ankle = trip
            by = "shape"
        put(f"{s}_hip", hip, by)
        put(f"{s}_knee", knee, by)
        put(f"{s}_ankle", ankle, by)
        if "foot" in named and chain.index(named["foot"]) > chain.index(ankle):
            put(f"{s}_foot", named["foot"], "name words")
        else:
            after = [j for j in chain[chain.index(ankle) + 1 :] if roles[j] != "twist"]
            if after:
                put(f"{s}_foot", after[0])
    # arms
    arm_tops = set()
    for h, other in ((hand_a, hand_b), (hand_b, hand_a)):
        s, _ = side(h, other)
        chain = _path(parents, chest, h)
        arm_tops.add(chain[0])
        plain = [j for j in chain if roles[j] != "twist"]
        named = {}
        for j in chain:
            r = roles[j]
            if r in ("collar", "shoulder", "elbow", "wrist") and r not in named:
                named[r] = j
            elif r == "finger" and "hand" not in named and "wrist" in named:
                named["hand"] = j
        # "Shoulder" is the collar in Mixamo-like rigs (LeftShoulder -> LeftArm) and the upper arm
        # where a collar comes before it (LeftCollar -> LeftShoulder): the elbow decides
        if "elbow" in named and "wrist" in named and 1 <= chain.index(named["elbow"]) < chain.index(named["wrist"]):
            el, wr = named["elbow"], named["wrist"]
            before = chain[: chain.index(el)]
            shoulders = [j for j in before if roles[j] == "shoulder"]
            sh = shoulders[-1] if shoulders else ([j for j in before if roles[j] != "twist"] or before)[-1]
            if named.get("collar") is None and shoulders and shoulders[0] != sh:
                named["collar"] = shoulders[0]  # LeftShoulder -> LeftArm: the first "shoulder" is the collar
            by = "name words"
        else:
            # the wrist: where the fingers branch (three or more children near the hand's end); else the chain's
            # end, or the joint before it when the last bone is too short for a forearm (a hand's end joint)
            branch = [
                j for j in plain[2:] if len(children[j]) >= 3 and np.linalg.norm(ends[h] - rest[j]) <= 0.15 * height
            ]
            wrists = branch[-1:]
            if not wrists and len(plain) >= 3:
                prev = _first_at(rest, plain, plain[-2], 0.0025 * height)
                short = np.linalg.norm(rest[plain[-1]] - rest[prev]) < 0.06 * height
                wrists = [prev if short and plain.index(prev) >= 2 else plain[-1]]
            trip = _limb_triple(rest, plain, wrists, chest, tmpl["arm_ratio"], tmpl["shoulder_out"], 0.05 * height)
            if trip is None:
                return (
                    {},
                    {},
                    f"the {s} arm has no upper arm and forearm (two bones of at least "
                    f"{0.05 * height:.3g} units from the chest to the hand {names[h]})",
                )
            sh, el, wr = trip
            named = {k: v for k, v in named.items() if k in ("collar", "hand")}
            by = "shape"
        put(f"{s}_shoulder", sh, by)
        put(f"{s}_elbow", el, by)
        put(f"{s}_wrist", wr, by)
        i_sh = chain.index(sh)
        if "collar" in named and chain.index(named["collar"]) < i_sh:
            put(f"{s}_collar", named["collar"], "name words")
        elif i_sh > 0:
            put(f"{s}_collar", chain[i_sh - 1])
        after = [j for j in chain[chain.index(wr) + 1 :] if roles[j] != "twist"]
        fingers = [j for j in children[wr] if roles[j] != "twist"]
        along = rest[wr] - rest[el]
        along = along / max(np.linalg.norm(along), 1e-12)
        reach = {j: max(float((ends[k] - rest[wr]) @ along) for k in _subtree(children, j)) for j in fingers}
        if "hand" in named and named["hand"] in after:
            put(f"{s}_hand", named["hand"], "name words")
        elif len(fingers) >= 4:  # the middle finger: the middle one front to back, the thumb (the finger
            fingers.remove(min(fingers, key=reach.__getitem__))  # reaching least far out along the arm) left out
            fingers.sort(key=lambda j: rest[j] @ fwd)
            put(f"{s}_hand", fingers[len(fingers) // 2])
        elif fingers:  # a finger base and a thumb (CMU): the one reaching farther
            put(f"{s}_hand", max(fingers, key=reach.__getitem__))
    # spine: the joints from the pelvis up to the chest (the chest is spine3)
    spine = _path(parents, pelvis, chest)
    if len(spine) >= 2:
        put("spine1", spine[0])
    if len(spine) >= 3:
        put("spine2", spine[-2])
    # neck and head: the chain ends above the shoulders that are not in the arms
    shoulder_y = max(rest[out["left_shoulder"], 1], rest[out["right_shoulder"], 1])
    head_leaves = [
        i for i in leaves if chest in anc[i] and i != chest and not (arm_tops & anc[i]) and ends[i, 1] > shoulder_y
    ]
    head = None
    if head_leaves:
        top = max(head_leaves, key=lambda i: ends[i, 1])
        worded = [
            j
            for j in _path(parents, chest, top)
            if "head" in normalize_name(names[j])
            and "top" not in normalize_name(names[j])
            and "end" not in normalize_name(names[j])
        ]
        if worded:
            head, by = worded[0], "name words"
        elif len(head_leaves) >= 2 and _lca(parents, head_leaves) != chest:
            head, by = _lca(parents, head_leaves), "shape"  # where the face's joints branch
        else:
            par = int(parents[top])
            # a head-top end joint (Mixamo's HeadTop_End) rises above the head more than the head above the neck
            end_joint = (
                par != chest
                and parents[par] >= 0
                and rest[top, 1] - rest[par, 1] > 1.2 * (rest[par, 1] - rest[int(parents[par]), 1])
            )
            head, by = (par if end_joint else top), "shape"
        put("head", head, by)
        path = _path(parents, chest, head)
        if path and path[0] != head:
            put("neck", path[0])
    if len(set(out.values())) != len(out):
        return {}, {}, "the shape rule found one joint in two places"
    return out, how, ""


def _fix_chest(found: dict[str, int], parents: np.ndarray) -> dict[str, int]:
    """A name table's chest (spine3) is where the arms branch: when the collars (or shoulders) meet in a joint
    below the table's chest -- UE5's spine_05 above spine_03 -- that joint becomes spine3 and the old chest
    spine2."""
    arms = [found.get(f"{s}_collar", found.get(f"{s}_shoulder")) for s in ("left", "right")]
    top = found.get("spine3")
    if top is None or None in arms:
        return found
    branch = _lca(parents, cast(list[int], arms))  # None is not in arms
    if branch in arms or branch == top or top not in _ancestors(parents, branch) or branch in found.values():
        return found
    out = dict(found)
    out["spine3"] = branch
    if out.get("spine1") != top:
        out["spine2"] = top
    return out


def map_skeleton(
    names: Sequence[str], parents, rest, *, leaf_ends=None, joint_map: dict[str, str] | None = None, path=None
) -> SkeletonMapping:
    """Find the SMPL joints in a source skeleton (module docstring).

    Args:
        names: (J,) source joint names; parents: (J,) parent index, -1 for the root.
        rest: (J, 3) rest-pose joint positions, +Y up (any unit).
        leaf_ends: (J, 3) end-site positions (defaults to ``rest``).
        joint_map: SMPL name -> source name, applied first.
        path: the file, for error messages.

    Raises:
        InputError: a required joint (:data:`REQUIRED_JOINTS`) cannot be found; the message lists
            the joints found, the SMPL joints missing, what the shape rule misses and the source joints.
    """
    names = [str(n) for n in names]
    par = np.asarray(parents, np.int64)
    rest = np.asarray(rest, np.float64)
    ends = rest if leaf_ends is None else np.asarray(leaf_ends, np.float64)
    if par.shape != (len(names),) or rest.shape != (len(names), 3) or ends.shape != rest.shape:
        raise InputError(
            "skeleton arrays do not fit",
            path=path,
            expected=f"({len(names)},) parents and ({len(names)}, 3) positions",
            got=f"{par.shape} and {rest.shape}",
        )
    norm = [normalize_name(n) for n in names]
    prefix = common_prefix(names)
    stripped = [normalize_name(_strip(n, prefix)) for n in names]
    if len(set(norm)) != len(norm):
        dup = sorted({n for n in names if norm.count(normalize_name(n)) > 1})
        if joint_map is None:
            raise InputError(
                "joint names repeat (after ignoring case and punctuation)", path=path, got=", ".join(dup[:6])
            )
    src = np.full(24, -1, np.int64)
    user = {}
    if joint_map:
        by_name = {n: i for i, n in enumerate(names)}
        for smpl, s in joint_map.items():
            if smpl not in SMPL_JOINT_NAMES:
                raise InputError(
                    f"joint map names an unknown SMPL joint {smpl!r}", path=path, expected=", ".join(SMPL_JOINT_NAMES)
                )
            if s not in by_name:
                raise InputError(
                    f"joint map names {s!r}, which is not in the file",
                    path=path,
                    expected="one of " + ", ".join(names[:40]),
                )
            user[SMPL_JOINT_NAMES.index(smpl)] = by_name[s]
    # name tables, on the names as they are and without their common prefix
    best_scheme: str | None = None
    best: dict[str, int] = {}
    for scheme, table in _NORMALIZED_TABLES.items():
        for keys in (norm, stripped) if prefix else (norm,):
            found: dict[str, int] = {}
            for i, n in enumerate(keys):
                hit = table.get(n)
                if hit is not None and hit not in found:
                    found[hit] = i
            if len(found) > len(best):
                best_scheme, best = scheme, found
    shape, shape_how, problem = _shape_map(names, par, rest, ends)

    def candidates():
        if best and all(r in best for r in REQUIRED_JOINTS):
            yield best_scheme, best, {k: f"name ({best_scheme})" for k in best}
        if shape:
            yield "shape", shape, shape_how
        if best:
            yield best_scheme, best, {k: f"name ({best_scheme})" for k in best}

    chosen_scheme, chosen, chosen_how = None, {}, {}
    for scheme, found, how in candidates():
        found = dict(found)
        if "spine3" not in found:  # the topmost mapped spine joint is the chest (Hips/Chest/LeftCollar rigs)
            top = next((k for k in ("spine2", "spine1") if k in found), None)
            if top is not None:
                found["spine3"] = found.pop(top)
                how = dict(how, spine3=how[top])
        if scheme != "shape":
            fixed = _fix_chest(found, par)
            how = {k: how.get(k, how.get("spine3", "shape")) for k in fixed}
            found = fixed
        trial = {SMPL_JOINT_NAMES.index(k): v for k, v in found.items()}
        trial.update(user)
        if all(SMPL_JOINT_NAMES.index(r) in trial for r in REQUIRED_JOINTS):
            chosen_scheme, chosen, chosen_how = scheme, trial, {SMPL_JOINT_NAMES.index(k): v for k, v in how.items()}
            break
    if not chosen and user:
        chosen_scheme, chosen = "joint-map", dict(user)
    if user and chosen_scheme != "joint-map":
        chosen_scheme = cast(str, chosen_scheme) + "+joint-map"
    for j in user:
        chosen_how[j] = "joint map"
    for j, i in chosen.items():
        src[j] = i
    missing = [r for r in REQUIRED_JOINTS if src[SMPL_JOINT_NAMES.index(r)] < 0]
    if missing:
        known = {SMPL_JOINT_NAMES[j]: names[i] for j, i in enumerate(src) if i >= 0}
        if not known and best:
            known = {k: names[i] for k, i in best.items()}
        shown = ", ".join(f"{k}={v}" for k, v in known.items()) or "none"
        raise InputError(
            "cannot map this skeleton onto SMPL's joints: missing "
            + ", ".join(missing)
            + (f"; by shape: {problem}" if problem else ""),
            path=path,
            expected="a humanoid (hips, two legs, spine, two arms, head) with SMPL, Mixamo, CMU or "
            "similar joint names, or --joint-map FILE",
            got=f"{len(names)} joints ({', '.join(names[:30])}{' ...' if len(names) > 30 else ''}); found {shown}",
        )
    # a mapped joint's SMPL parent chain must be an ancestor chain in the source
    for j in range(1, 24):
        i = src[j]
        if i < 0:
            continue
        pj = int(SMPL_PARENTS[j])
        while pj >= 0 and src[pj] < 0:
            pj = int(SMPL_PARENTS[pj])
        if pj >= 0 and src[pj] not in _ancestors(par, int(i))[1:]:
            raise InputError(
                f"joint {names[i]!r} (SMPL {SMPL_JOINT_NAMES[j]}) does not descend from "
                f"{names[src[pj]]!r} (SMPL {SMPL_JOINT_NAMES[pj]}) in the file's hierarchy",
                path=path,
                expected="the SMPL joint order along each limb",
            )
    found_by = tuple(chosen_how.get(j, chosen_scheme) if src[j] >= 0 else "" for j in range(24))
    # a mapping was chosen (else the required joints were missing, refused above)
    return SkeletonMapping(source=src, scheme=cast(str, chosen_scheme), source_names=tuple(names), found_by=found_by)
