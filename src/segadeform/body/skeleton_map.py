"""Which joint of a foreign skeleton is which SMPL joint: name tables, a generic humanoid rule, user maps.

Motion files name their joints in many ways (``../shared/notes/facts.md``
lists the ones seen in the wild).  :func:`map_skeleton` finds, for each of
SMPL's 24 joints, the source joint that plays its part, in this order:

1. a user map (``joint_map``: SMPL name -> source name), taken as given;
2. the name tables (:data:`NAME_TABLES`): SMPL, SMPL's short names,
   Mixamo (any ``prefix:``), the CMU conversions (cgspeed MotionBuilder,
   3dsMax and DAZ/Poser styles, and the raw ASF/AMC bone names).  The table
   matching most names wins; it is used when it finds every required joint;
3. otherwise the generic humanoid rule (:func:`_generic_map`): the hips are
   the common ancestor of the two feet, the chest the common ancestor of the
   two hands, legs and arms are the paths down to them, and the joints along
   each path are picked from name words (``thigh``, ``knee``, ``forearm`` ...)
   where the names have them and from bone lengths where they do not.  Left
   and right come from name words, or from which side of the body a chain
   lies on.

Joints that play no SMPL part (eyes, fingers, toe ends, twist and helper
joints, ``LHipJoint``) are left out: the retargeting (:mod:`.retarget`)
works with global rotations and posed positions, so their rotations are
carried by the mapped joints below them.  SMPL joints the source lacks are
*virtual*: ``spine2`` between two mapped spine joints, a neck between chest
and head, collars, hands, toes; the retargeting fills them in.

Names are compared after :func:`normalize_name`: the namespace (``mixamorig:``,
``Character1:``) is dropped, then case and every non-alphanumeric character.
"""

from __future__ import annotations

import dataclasses
import re
from typing import Optional, Sequence

import numpy as np

from ..errors import InputError
from .skeleton import SMPL_JOINT_NAMES, SMPL_PARENTS

__all__ = ["NAME_TABLES", "MIXAMO_TO_SMPL", "SMPL_SHORT_NAMES", "REQUIRED_JOINTS", "SkeletonMapping",
           "normalize_name", "map_skeleton", "read_joint_map"]

#: SMPL joints a source skeleton must provide (directly or through a user map).
REQUIRED_JOINTS = ("pelvis", "left_hip", "right_hip", "left_knee", "right_knee", "left_ankle", "right_ankle",
                   "left_shoulder", "right_shoulder", "left_elbow", "right_elbow", "left_wrist", "right_wrist")

MIXAMO_TO_SMPL = {
    "Hips": "pelvis", "LeftUpLeg": "left_hip", "RightUpLeg": "right_hip", "Spine": "spine1",
    "LeftLeg": "left_knee", "RightLeg": "right_knee", "Spine1": "spine2", "LeftFoot": "left_ankle",
    "RightFoot": "right_ankle", "Spine2": "spine3", "LeftToeBase": "left_foot", "RightToeBase": "right_foot",
    "Neck": "neck", "LeftShoulder": "left_collar", "RightShoulder": "right_collar", "Head": "head",
    "LeftArm": "left_shoulder", "RightArm": "right_shoulder", "LeftForeArm": "left_elbow",
    "RightForeArm": "right_elbow", "LeftHand": "left_wrist", "RightHand": "right_wrist",
    "LeftHandMiddle1": "left_hand", "RightHandMiddle1": "right_hand",
}
SMPL_SHORT_NAMES = {
    "Pelvis": "pelvis", "L_Hip": "left_hip", "R_Hip": "right_hip", "Spine1": "spine1", "L_Knee": "left_knee",
    "R_Knee": "right_knee", "Spine2": "spine2", "L_Ankle": "left_ankle", "R_Ankle": "right_ankle",
    "Spine3": "spine3", "L_Foot": "left_foot", "R_Foot": "right_foot", "Neck": "neck", "L_Collar": "left_collar",
    "R_Collar": "right_collar", "Head": "head", "L_Shoulder": "left_shoulder", "R_Shoulder": "right_shoulder",
    "L_Elbow": "left_elbow", "R_Elbow": "right_elbow", "L_Wrist": "left_wrist", "R_Wrist": "right_wrist",
    "L_Hand": "left_hand", "R_Hand": "right_hand",
}


def _sided(table: dict) -> dict:
    """Expand ``{"{S}UpLeg": "{s}_hip"}`` into Left/Right (``{S}``), l/r (``{c}``) and left/right (``{s}``)."""
    out = {}
    for k, v in table.items():
        if "{" not in k:
            out[k] = v
            continue
        for S, c, s in (("Left", "l", "left"), ("Right", "r", "right")):
            out[k.format(S=S, c=c, s=s)] = v.format(s=s)
    return out


#: name scheme -> {source joint name: SMPL joint name}; the pattern is documented per scheme.
NAME_TABLES: dict[str, dict[str, str]] = {
    "smpl": {n: n for n in SMPL_JOINT_NAMES},
    "smpl-short": SMPL_SHORT_NAMES,
    "mixamo": MIXAMO_TO_SMPL,
    # cgspeed's MotionBuilder-friendly CMU conversion: Hips/LHipJoint/LeftUpLeg/LowerBack/Spine/Spine1/Neck/Neck1
    "cmu-motionbuilder": _sided({
        "Hips": "pelvis", "{S}UpLeg": "{s}_hip", "{S}Leg": "{s}_knee", "{S}Foot": "{s}_ankle",
        "{S}ToeBase": "{s}_foot", "LowerBack": "spine1", "Spine": "spine2", "Spine1": "spine3", "Neck": "neck",
        "Head": "head", "{S}Shoulder": "{s}_collar", "{S}Arm": "{s}_shoulder", "{S}ForeArm": "{s}_elbow",
        "{S}Hand": "{s}_wrist", "{S}FingerBase": "{s}_hand"}),
    # cgspeed's 3dsMax-friendly conversion: Hips/LHipJoint/LeftHip/LeftKnee/lowerback/Chest/Chest2/lowerneck
    "cmu-3dsmax": _sided({
        "Hips": "pelvis", "{S}Hip": "{s}_hip", "{S}Knee": "{s}_knee", "{S}Ankle": "{s}_ankle", "{S}Toe": "{s}_foot",
        "lowerback": "spine1", "Chest": "spine2", "Chest2": "spine3", "lowerneck": "neck", "Neck": "neck",
        "Head": "head",
        "{S}Collar": "{s}_collar", "{S}Shoulder": "{s}_shoulder", "{S}Elbow": "{s}_elbow", "{S}Wrist": "{s}_wrist",
        "{c}hand": "{s}_hand"}),
    # cgspeed's DAZ/Poser-friendly conversion: hip/abdomen/chest/lCollar/lShldr/lThigh/lShin (no spine2, no toes)
    "cmu-daz": _sided({
        "hip": "pelvis", "abdomen": "spine1", "chest": "spine3", "neck": "neck", "head": "head",
        "{c}Thigh": "{s}_hip", "{c}Shin": "{s}_knee", "{c}Foot": "{s}_ankle", "{c}Collar": "{s}_collar",
        "{c}Shldr": "{s}_shoulder", "{c}ForeArm": "{s}_elbow", "{c}Hand": "{s}_wrist", "{c}Mid1": "{s}_hand"}),
    # the CMU ASF/AMC bone names as some BVH conversions keep them (hip/lhipjoint/lhip/lknee/lfoot)
    "cmu-asf": _sided({
        "hip": "pelvis", "{c}hip": "{s}_hip", "{c}knee": "{s}_knee", "{c}foot": "{s}_ankle", "{S}toebase": "{s}_foot",
        "lowerback": "spine1", "abdomen": "spine2", "chest": "spine3", "neck": "neck", "head": "head",
        "{c}collar": "{s}_collar", "{c}shoulder": "{s}_shoulder", "{c}elbow": "{s}_elbow", "{c}hand": "{s}_wrist",
        "{S}fingerbase": "{s}_hand",
        # the raw ASF bone names; a joint is where its bone starts: lradius at the elbow, lwrist a
        # forearm twist bone part-way down (folded in), lhand at the wrist, lfingers at the knuckles
        "root": "pelvis", "{c}femur": "{s}_hip", "{c}tibia": "{s}_knee", "{c}toes": "{s}_foot",
        "upperback": "spine2", "thorax": "spine3", "lowerneck": "neck", "{c}clavicle": "{s}_collar",
        "{c}humerus": "{s}_shoulder", "{c}radius": "{s}_elbow", "{c}fingers": "{s}_hand"}),
}


def normalize_name(name: str) -> str:
    """``"mixamorig:LeftUpLeg"`` -> ``"leftupleg"``; ``"L_Hip"`` -> ``"lhip"``."""
    base = name.rsplit(":", 1)[-1]
    base = re.sub(r"^mixamorig\d*_", "", base)
    return re.sub(r"[^0-9a-z]", "", base.lower())


_NORMALIZED_TABLES = {k: {normalize_name(a): b for a, b in t.items()} for k, t in NAME_TABLES.items()}


@dataclasses.dataclass(frozen=True)
class SkeletonMapping:
    """Where each SMPL joint is in a source skeleton.

    Attributes:
        source: (24,) source joint index per SMPL joint, -1 where the source has none (virtual).
        scheme: how it was found: a key of :data:`NAME_TABLES`, ``"generic"`` or ``"joint-map"``
            (``"+joint-map"`` appended when a user map completed another scheme).
        source_names: the source skeleton's joint names.
    """

    source: np.ndarray
    scheme: str
    source_names: tuple

    def mapped(self) -> dict[str, str]:
        """SMPL name -> source name for every mapped joint."""
        return {SMPL_JOINT_NAMES[j]: self.source_names[i] for j, i in enumerate(self.source) if i >= 0}

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
        from .._toml import read_toml

        data, _ = read_toml(p, "joint map")
        data = data.get("joints", data)
    if not isinstance(data, dict) or not all(isinstance(k, str) and isinstance(v, str) for k, v in data.items()):
        raise FileFormatError("joint map must map names to names", path=p,
                              expected='entries like  left_hip = "UpperLeg_L"', got=type(data).__name__)
    out = {}
    for k, v in data.items():
        if k in SMPL_JOINT_NAMES:
            out[k] = v
        elif v in SMPL_JOINT_NAMES:
            out[v] = k
        else:
            raise FileFormatError(f"joint map entry {k!r} = {v!r} names no SMPL joint", path=p,
                                  expected="one side of each entry among " + ", ".join(SMPL_JOINT_NAMES))
    return out


# ---------------------------------------------------------------------------------------------------------
# the generic humanoid rule

_LEFT = re.compile(r"(^|[^a-z])(l|left|lft)([^a-z]|$)|^left|left$|^l(?=[a-z])", re.I)


def _side_of(name: str) -> Optional[str]:
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


def _role_of(name: str) -> Optional[str]:
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


def _lca(parents, idx: Sequence[int]) -> int:
    common = None
    for i in idx:
        anc = _ancestors(parents, i)
        common = anc if common is None else [a for a in common if a in set(anc)]
    return common[0]


def _long_pair(pos: np.ndarray, chain: list[int], min_len: float):
    """The two consecutive long bones (upper and lower limb) along ``chain``, as joint indices
    (top, middle, end) maximising their summed length; each bone must be at least ``min_len``.

    Only directly linked joints count as a bone: a straight T-posed arm puts the wrist on the line
    through shoulder and elbow, so geometry alone cannot tell a twist joint from the wrist (twist
    joints named ``...Roll``/``...Twist`` are skipped by name before this is asked)."""
    best, best_len = None, 0.0
    for a in range(len(chain) - 2):
        l1 = np.linalg.norm(pos[chain[a + 1]] - pos[chain[a]])
        l2 = np.linalg.norm(pos[chain[a + 2]] - pos[chain[a + 1]])
        if l1 >= min_len and l2 >= min_len and l1 + l2 > best_len:
            best, best_len = (chain[a], chain[a + 1], chain[a + 2]), l1 + l2
    return best


def _generic_map(names: list[str], parents: np.ndarray, rest: np.ndarray, leaf_ends: np.ndarray) -> dict[str, int]:
    """The generic humanoid rule (module docstring).  ``rest (J, 3)`` y-up rest positions; ``leaf_ends (J, 3)``
    the end-site position of each joint (its own position when it has none)."""
    nj = len(names)
    children = [[] for _ in range(nj)]
    for i, p in enumerate(parents):
        if p >= 0:
            children[int(p)].append(i)
    leaves = [i for i in range(nj) if not children[i]]
    if len(leaves) < 4:
        return {}
    ends = leaf_ends
    height = float(np.ptp(np.concatenate([rest[:, 1], ends[:, 1]])))
    if height <= 0:
        return {}
    roles = [_role_of(n) for n in names]
    sides = [_side_of(n) for n in names]
    # feet: the lowest leaf, then the lowest leaf in another branch (their common ancestor well above the floor)
    by_low = sorted(leaves, key=lambda i: ends[i, 1])
    floor = ends[by_low[0], 1]
    foot_a = by_low[0]
    foot_b = next((i for i in by_low[1:] if rest[_lca(parents, [foot_a, i]), 1] - floor > 0.3 * height), None)
    if foot_b is None:
        return {}
    legs_root = _lca(parents, [foot_a, foot_b])
    leg_leaves = set()
    for f in (foot_a, foot_b):
        top = _path(parents, legs_root, f)[0]
        leg_leaves |= {i for i in leaves if top in _ancestors(parents, i)}
    # hands: the two leaves farthest out sideways, in different branches, above the legs' root
    centre = rest[legs_root]
    cand = [i for i in leaves if i not in leg_leaves]
    if len(cand) < 3:
        return {}
    by_lat = sorted(cand, key=lambda i: -abs(ends[i, 0] - centre[0]))
    hand_a = by_lat[0]
    hand_b = next((i for i in by_lat[1:] if np.sign(ends[i, 0] - centre[0]) != np.sign(ends[hand_a, 0] - centre[0])
                   and _lca(parents, [hand_a, i]) not in (hand_a, i)), None)
    if hand_b is None:
        return {}
    chest = _lca(parents, [hand_a, hand_b])
    pelvis = _lca(parents, [legs_root, chest])
    arm_tops = {_path(parents, chest, h)[0] for h in (hand_a, hand_b)}
    head_cand = [i for i in leaves if i not in leg_leaves and chest in _ancestors(parents, i) and i != chest
                 and not (arm_tops & set(_ancestors(parents, i)))]
    out: dict[str, int] = {"pelvis": pelvis}
    # left/right: name words, else which side of the body (left = up x facing; facing from the toes, else +z)
    fwd = np.array([0.0, 0.0, 1.0])

    def side(chain_end: int, other_end: int) -> str:
        s = sides[chain_end] or next((sides[j] for j in _ancestors(parents, chain_end) if sides[j]), None)
        if s:
            return s
        left_dir = np.cross([0.0, 1.0, 0.0], fwd)
        return "left" if (ends[chain_end] - ends[other_end]) @ left_dir > 0 else "right"

    # legs
    for f, other in ((foot_a, foot_b), (foot_b, foot_a)):
        s = side(f, other)
        chain = _path(parents, legs_root, f)
        named = {}
        for j in chain:
            if roles[j] in ("knee", "ankle", "foot") and roles[j] not in named:
                named[roles[j]] = j
        if "knee" in named and "ankle" in named and 1 <= chain.index(named["knee"]) < chain.index(named["ankle"]):
            knee, ankle = named["knee"], named["ankle"]
            before = chain[:chain.index(knee)]
            hips = [j for j in before if roles[j] == "hip"]
            hip = hips[-1] if hips else next(j for j in reversed(before) if roles[j] != "twist") \
                if any(roles[j] != "twist" for j in before) else before[-1]
        else:
            trip = _long_pair(rest, [j for j in chain if roles[j] != "twist"], 0.12 * height)
            if trip is None:
                return {}
            hip, knee, ankle = trip
        out[f"{s}_hip"], out[f"{s}_knee"], out[f"{s}_ankle"] = hip, knee, ankle
        if "foot" in named:
            out[f"{s}_foot"] = named["foot"]
        else:
            after = chain[chain.index(ankle) + 1:] if ankle in chain else []
            if after:
                out[f"{s}_foot"] = after[0]
    # arms
    for h, other in ((hand_a, hand_b), (hand_b, hand_a)):
        s = side(h, other)
        chain = _path(parents, chest, h)
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
            before = chain[:chain.index(el)]
            shoulders = [j for j in before if roles[j] == "shoulder"]
            plain = [j for j in before if roles[j] != "twist"] or before
            sh = shoulders[-1] if shoulders else plain[-1]
            if named.get("collar") is None and shoulders and shoulders[0] != sh:
                named["collar"] = shoulders[0]  # LeftShoulder -> LeftArm: the first "shoulder" is the collar
        else:
            trip = _long_pair(rest, [j for j in chain if roles[j] != "twist"], 0.09 * height)
            if trip is None:
                return {}
            sh, el, wr = trip
            named = {k: v for k, v in named.items() if k in ("collar", "hand")}
        out[f"{s}_shoulder"], out[f"{s}_elbow"], out[f"{s}_wrist"] = sh, el, wr
        i_sh = chain.index(sh)
        if "collar" in named and chain.index(named["collar"]) < i_sh:
            out[f"{s}_collar"] = named["collar"]
        elif i_sh > 0:
            out[f"{s}_collar"] = chain[i_sh - 1]
        after = chain[chain.index(wr) + 1:]
        if "hand" in named and named["hand"] in after:
            out[f"{s}_hand"] = named["hand"]
        elif after:
            out[f"{s}_hand"] = after[0]
    # spine: the joints from the pelvis up to the chest; spine3 is the chest
    spine = _path(parents, pelvis, chest)
    if spine:
        out["spine3"] = spine[-1]
        if len(spine) >= 2:
            out["spine1"] = spine[0]
        if len(spine) >= 3:
            out["spine2"] = spine[-2]
    # neck and head: the path up to the highest remaining leaf
    if head_cand:
        top = max(head_cand, key=lambda i: ends[i, 1])
        path = _path(parents, chest, top)
        heads = [j for j in path if "head" in normalize_name(names[j])]
        head = heads[0] if heads else path[-1]
        out["head"] = head
        before = path[:path.index(head)]
        if before:
            out["neck"] = before[0]
    if len(set(out.values())) != len(out):
        return {}
    return out


def map_skeleton(names: Sequence[str], parents, rest, *, leaf_ends=None,
                 joint_map: Optional[dict[str, str]] = None, path=None) -> SkeletonMapping:
    """Find the SMPL joints in a source skeleton (module docstring).

    Args:
        names: (J,) source joint names; parents: (J,) parent index, -1 for the root.
        rest: (J, 3) rest-pose joint positions, +Y up (any unit).
        leaf_ends: (J, 3) end-site positions (defaults to ``rest``).
        joint_map: SMPL name -> source name, applied first.
        path: the file, for error messages.

    Raises:
        InputError: a required joint (:data:`REQUIRED_JOINTS`) cannot be found; the message lists
            the joints found, the SMPL joints missing and the source joints left over.
    """
    names = [str(n) for n in names]
    par = np.asarray(parents, np.int64)
    rest = np.asarray(rest, np.float64)
    ends = rest if leaf_ends is None else np.asarray(leaf_ends, np.float64)
    norm = [normalize_name(n) for n in names]
    if len(set(norm)) != len(norm):
        dup = sorted({n for n in names if norm.count(normalize_name(n)) > 1})
        if joint_map is None:
            raise InputError("joint names repeat (after ignoring case and punctuation)", path=path,
                             got=", ".join(dup[:6]))
    src = np.full(24, -1, np.int64)
    user = {}
    if joint_map:
        by_name = {n: i for i, n in enumerate(names)}
        for smpl, s in joint_map.items():
            if smpl not in SMPL_JOINT_NAMES:
                raise InputError(f"joint map names an unknown SMPL joint {smpl!r}", path=path,
                                 expected=", ".join(SMPL_JOINT_NAMES))
            if s not in by_name:
                raise InputError(f"joint map names {s!r}, which is not in the file", path=path,
                                 expected="one of " + ", ".join(names[:40]))
            user[SMPL_JOINT_NAMES.index(smpl)] = by_name[s]
    # name tables
    best_scheme, best = None, {}
    for scheme, table in _NORMALIZED_TABLES.items():
        found = {}
        for i, n in enumerate(norm):
            smpl = table.get(n)
            if smpl is not None and smpl not in found:
                found[smpl] = i
        if len(found) > len(best):
            best_scheme, best = scheme, found
    def candidates():
        if best and all(r in best for r in REQUIRED_JOINTS):
            yield best_scheme, best
        generic = _generic_map(names, par, rest, ends)
        if generic:
            yield "generic", generic
        if best:
            yield best_scheme, best

    chosen_scheme, chosen = None, {}
    for scheme, found in candidates():
        found = dict(found)
        if "spine3" not in found:  # the topmost mapped spine joint is the chest (Hips/Chest/LeftCollar rigs)
            top = next((k for k in ("spine2", "spine1") if k in found), None)
            if top is not None:
                found["spine3"] = found.pop(top)
        trial = {SMPL_JOINT_NAMES.index(k): v for k, v in found.items()}
        trial.update(user)
        if all(SMPL_JOINT_NAMES.index(r) in trial for r in REQUIRED_JOINTS):
            chosen_scheme, chosen = scheme, trial
            break
    if not chosen and user:
        chosen_scheme, chosen = "joint-map", dict(user)
    if user and chosen_scheme != "joint-map":
        chosen_scheme += "+joint-map"
    for j, i in chosen.items():
        src[j] = i
    missing = [r for r in REQUIRED_JOINTS if src[SMPL_JOINT_NAMES.index(r)] < 0]
    if missing:
        found = {SMPL_JOINT_NAMES[j]: names[i] for j, i in enumerate(src) if i >= 0}
        shown = ", ".join(f"{k}={v}" for k, v in found.items()) or "none"
        raise InputError(
            "cannot map this skeleton onto SMPL's joints: missing " + ", ".join(missing), path=path,
            expected="a humanoid (hips, two legs, spine, two arms, head) with SMPL, Mixamo, CMU or "
                     "similar joint names, or --joint-map FILE",
            got=f"{len(names)} joints ({', '.join(names[:30])}{' ...' if len(names) > 30 else ''}); "
                f"found {shown}")
    # a mapped joint's SMPL parent chain must be an ancestor chain in the source
    for j in range(1, 24):
        i = src[j]
        if i < 0:
            continue
        pj = int(SMPL_PARENTS[j])
        while pj >= 0 and src[pj] < 0:
            pj = int(SMPL_PARENTS[pj])
        if pj >= 0 and src[pj] not in _ancestors(par, int(i))[1:]:
            raise InputError(f"joint {names[i]!r} (SMPL {SMPL_JOINT_NAMES[j]}) does not descend from "
                             f"{names[src[pj]]!r} (SMPL {SMPL_JOINT_NAMES[pj]}) in the file's hierarchy",
                             path=path, expected="the SMPL joint order along each limb")
    return SkeletonMapping(source=src, scheme=chosen_scheme, source_names=tuple(names))
