"""Skeletons of the common humanoid namings, built for tests (no copied file): each is SMPL's T-pose skeleton
(:func:`default_rest_joints`) renamed the way a tool names it, with the tool's extra joints -- floor roots,
twist and share helpers, fingers, face, IK bones -- where the tool has them.

:func:`naming_skeleton` returns ``(names, parents, rest (J, 3) metres +Y up, expected {smpl: name},
twist)``, where ``twist`` lists the helper joints that sit *inside* a bone (between two mapped joints) and
may only turn about that bone, and structural joints between two mapped ones that keep still (a helper between
two mapped joints that turned off its bone would move the joints below it where SMPL's skeleton cannot
follow); :func:`naming_motion` makes a motion for it and :func:`write_naming_bvh` a BVH file
(``tests/motion/bvh_build.py``).
"""

from __future__ import annotations

import numpy as np

from segadeform.body.rotations import axis_angle_to_matrix
from segadeform.body.skeleton import SMPL_JOINT_NAMES, default_rest_joints

from .bvh_build import smooth_local_rotations, write_skeleton_bvh

#: every naming :func:`naming_skeleton` builds, with the name table that should read it
NAMINGS = {
    "unity": "unity",
    "character-creator": "character-creator",
    "unreal": "unreal",
    "unreal5": "unreal",
    "xsens": "xsens",
    "vrm": "vrm",
    "vroid": "vrm",
    "rigify": "rigify",
    "rokoko": "rokoko",
    "armature-mixamo": "mixamo",
    "character1": "mixamo",
}
_IDX = {n: i for i, n in enumerate(SMPL_JOINT_NAMES)}
_SIDES = (("left", "L", "l", "Left", 1.0), ("right", "R", "r", "Right", -1.0))


class _Builder:
    def __init__(self):
        self.names, self.parents, self.pos, self.expected, self.twist = [], [], [], {}, []

    def add(self, name, parent, pos, smpl=None, twist=False):
        """``twist``: a helper inside a bone that only turns about it; ``"fixed"``: a structural joint that
        does not turn (CC's CC_Base_Pelvis between the hips and the thighs)."""
        self.names.append(name)
        self.parents.append(-1 if parent is None else self.names.index(parent))
        self.pos.append(np.asarray(pos, float))
        if smpl:
            self.expected[smpl] = name
        if twist:
            self.twist.append(name if twist is True else (name, twist))
        return name

    def fingers(self, hand, names_of, side_sign, mid_smpl=None, metacarpal=None):
        """Five fingers of three joints from ``hand``; ``names_of(finger, k)``; the middle finger's first
        joint is SMPL's hand when ``mid_smpl`` names it."""
        J = default_rest_joints()
        w = J[_IDX["left_wrist"]] * [side_sign, 1, 1]
        for f, (dz, dy) in zip(
            ("Thumb", "Index", "Middle", "Ring", "Pinky"),
            ((0.035, -0.01), (0.02, 0.0), (0.0, 0.0), (-0.018, 0.0), (-0.034, -0.005)),
            strict=True,
        ):
            par = hand
            base = w + [side_sign * (0.03 if f == "Thumb" else 0.08), dy, dz]
            if metacarpal:
                par = self.add(metacarpal(f), par, w + [side_sign * 0.03, dy, dz * 0.8])
            for k in range(1, 4):
                par = self.add(
                    names_of(f, k),
                    par,
                    base + [side_sign * 0.028 * (k - 1), 0, 0],
                    smpl=mid_smpl if (f == "Middle" and k == 1) else None,
                )

    def build(self):
        return list(self.names), np.array(self.parents), np.stack(self.pos), dict(self.expected), list(self.twist)


def _j(name):
    return default_rest_joints()[_IDX[name]]


def _lerp(a, b, t):
    return _j(a) + t * (_j(b) - _j(a))


def _side(name, s):
    return name.replace("{s}", s)


def naming_skeleton(kind: str):
    """``(names, parents, rest, expected, twist)`` of the naming ``kind`` (a key of :data:`NAMINGS`); ``twist``
    lists the helpers inside a bone (a name) and the structural joints that keep still (``(name, "fixed")``)."""
    b = _Builder()
    if kind == "unity":  # Bandai-Namco-style: a floor root, Unity-humanoid names with side suffixes
        b.add("joint_Root", None, [0, 0, 0])
        b.add("Hips", "joint_Root", _j("pelvis"), "pelvis")
        b.add("Spine", "Hips", _j("spine1"), "spine1")
        b.add("Chest", "Spine", _j("spine3"), "spine3")
        b.add("Neck", "Chest", _j("neck"), "neck")
        b.add("Head", "Neck", _j("head"), "head")
        for s, S, _, _, _ in _SIDES:
            b.add(f"Shoulder_{S}", "Chest", _j(f"{s}_collar"), f"{s}_collar")
            b.add(f"UpperArm_{S}", f"Shoulder_{S}", _j(f"{s}_shoulder"), f"{s}_shoulder")
            b.add(f"LowerArm_{S}", f"UpperArm_{S}", _j(f"{s}_elbow"), f"{s}_elbow")
            b.add(f"Hand_{S}", f"LowerArm_{S}", _j(f"{s}_wrist"), f"{s}_wrist")
            b.add(f"UpperLeg_{S}", "Hips", _j(f"{s}_hip"), f"{s}_hip")
            b.add(f"LowerLeg_{S}", f"UpperLeg_{S}", _j(f"{s}_knee"), f"{s}_knee")
            b.add(f"Foot_{S}", f"LowerLeg_{S}", _j(f"{s}_ankle"), f"{s}_ankle")
            b.add(f"Toes_{S}", f"Foot_{S}", _j(f"{s}_foot"), f"{s}_foot")
    elif kind == "character-creator":  # ~100 joints: twist, share, finger, face and breast helpers
        c = "CC_Base_"
        b.add("CC_Base_BoneRoot", None, [0, 0, 0])
        b.add(c + "Hip", "CC_Base_BoneRoot", _j("pelvis"), "pelvis")
        b.add(c + "Pelvis", c + "Hip", _j("pelvis") + [0, -0.01, 0], twist="fixed")
        b.add(c + "Waist", c + "Hip", _j("spine1"), "spine1")
        b.add(c + "Spine01", c + "Waist", _j("spine2"), "spine2")
        b.add(c + "Spine02", c + "Spine01", _j("spine3"), "spine3")
        b.add(c + "NeckTwist01", c + "Spine02", _j("neck"), "neck")
        b.add(c + "NeckTwist02", c + "NeckTwist01", _lerp("neck", "head", 0.5), twist=True)
        b.add(c + "Head", c + "NeckTwist02", _j("head"), "head")
        b.add(c + "FacialBone", c + "Head", _j("head") + [0, 0.06, 0.02])
        b.add(c + "JawRoot", c + "FacialBone", _j("head") + [0, 0.0, 0.05])
        for k in range(1, 4):
            b.add(
                c + f"Tongue0{k}",
                c + ("JawRoot" if k == 1 else f"Tongue0{k - 1}"),
                _j("head") + [0, 0.0, 0.06 + 0.01 * k],
            )
        b.add(c + "Teeth02", c + "JawRoot", _j("head") + [0, 0.0, 0.09])
        b.add(c + "UpperJaw", c + "FacialBone", _j("head") + [0, 0.03, 0.07])
        b.add(c + "Teeth01", c + "UpperJaw", _j("head") + [0, 0.03, 0.09])
        for s, S, _, _, sg in _SIDES:
            b.add(c + f"{S}_Eye", c + "FacialBone", _j("head") + [sg * 0.03, 0.08, 0.08])
            b.add(c + f"{S}_Breast", c + "Spine02", _j("spine3") + [sg * 0.09, 0.02, 0.1])
            b.add(c + f"{S}_RibsTwist", c + "Spine02", _j("spine3") + [sg * 0.1, 0.05, 0])
            b.add(c + f"{S}_Thigh", c + "Pelvis", _j(f"{s}_hip"), f"{s}_hip")
            b.add(c + f"{S}_ThighTwist01", c + f"{S}_Thigh", _lerp(f"{s}_hip", f"{s}_knee", 0.3))
            b.add(c + f"{S}_ThighTwist02", c + f"{S}_Thigh", _lerp(f"{s}_hip", f"{s}_knee", 0.6))
            b.add(c + f"{S}_Calf", c + f"{S}_Thigh", _j(f"{s}_knee"), f"{s}_knee")
            b.add(c + f"{S}_KneeShareBone", c + f"{S}_Calf", _j(f"{s}_knee") + [0, 0, 0.04])
            b.add(c + f"{S}_CalfTwist01", c + f"{S}_Calf", _lerp(f"{s}_knee", f"{s}_ankle", 0.3))
            b.add(c + f"{S}_CalfTwist02", c + f"{S}_Calf", _lerp(f"{s}_knee", f"{s}_ankle", 0.6))
            b.add(c + f"{S}_Foot", c + f"{S}_Calf", _j(f"{s}_ankle"), f"{s}_ankle")
            b.add(c + f"{S}_ToeBase", c + f"{S}_Foot", _j(f"{s}_foot"), f"{s}_foot")
            b.add(c + f"{S}_ToeBaseShareBone", c + f"{S}_ToeBase", _j(f"{s}_foot") + [0, 0.01, 0.0])
            b.add(c + f"{S}_BigToe1", c + f"{S}_ToeBase", _j(f"{s}_foot") + [-sg * 0.02, 0, 0.04])
            b.add(c + f"{S}_Clavicle", c + "Spine02", _j(f"{s}_collar"), f"{s}_collar")
            b.add(c + f"{S}_Upperarm", c + f"{S}_Clavicle", _j(f"{s}_shoulder"), f"{s}_shoulder")
            b.add(c + f"{S}_UpperarmTwist01", c + f"{S}_Upperarm", _lerp(f"{s}_shoulder", f"{s}_elbow", 0.3))
            b.add(c + f"{S}_UpperarmTwist02", c + f"{S}_Upperarm", _lerp(f"{s}_shoulder", f"{s}_elbow", 0.6))
            b.add(c + f"{S}_Forearm", c + f"{S}_Upperarm", _j(f"{s}_elbow"), f"{s}_elbow")
            b.add(c + f"{S}_ElbowShareBone", c + f"{S}_Forearm", _j(f"{s}_elbow") + [0, 0, -0.03])
            b.add(c + f"{S}_ForearmTwist01", c + f"{S}_Forearm", _lerp(f"{s}_elbow", f"{s}_wrist", 0.3))
            b.add(c + f"{S}_ForearmTwist02", c + f"{S}_Forearm", _lerp(f"{s}_elbow", f"{s}_wrist", 0.6))
            b.add(c + f"{S}_Hand", c + f"{S}_Forearm", _j(f"{s}_wrist"), f"{s}_wrist")
            b.fingers(
                c + f"{S}_Hand",
                lambda f, k, S=S: c + f"{S}_{'Mid' if f == 'Middle' else f}{k}",
                sg,
                mid_smpl=f"{s}_hand",
            )
    elif kind in ("unreal", "unreal5"):  # a floor root, twist leaves, IK bones at the feet and hands
        b.add("root", None, [0, 0, 0])
        b.add("pelvis", "root", _j("pelvis"), "pelvis")
        if kind == "unreal":
            b.add("spine_01", "pelvis", _j("spine1"), "spine1")
            b.add("spine_02", "spine_01", _j("spine2"), "spine2")
            chest = b.add("spine_03", "spine_02", _j("spine3"), "spine3")
            b.add("neck_01", chest, _j("neck"), "neck")
            b.add("head", "neck_01", _j("head"), "head")
        else:  # UE5: five spine joints; the arms hang from spine_05 (the chest), two neck joints
            b.add("spine_01", "pelvis", _j("spine1"), "spine1")
            b.add("spine_02", "spine_01", _lerp("spine1", "spine2", 0.5))
            b.add("spine_03", "spine_02", _j("spine2"), "spine2")
            b.add("spine_04", "spine_03", _lerp("spine2", "spine3", 0.5))
            chest = b.add("spine_05", "spine_04", _j("spine3"), "spine3")
            b.add("neck_01", chest, _j("neck"), "neck")
            b.add("neck_02", "neck_01", _lerp("neck", "head", 0.5))
            b.add("head", "neck_02", _j("head"), "head")
        for s, _, c, _, sg in _SIDES:
            b.add(f"clavicle_{c}", chest, _j(f"{s}_collar"), f"{s}_collar")
            b.add(f"upperarm_{c}", f"clavicle_{c}", _j(f"{s}_shoulder"), f"{s}_shoulder")
            b.add(f"upperarm_twist_01_{c}", f"upperarm_{c}", _lerp(f"{s}_shoulder", f"{s}_elbow", 0.5))
            b.add(f"lowerarm_{c}", f"upperarm_{c}", _j(f"{s}_elbow"), f"{s}_elbow")
            b.add(f"lowerarm_twist_01_{c}", f"lowerarm_{c}", _lerp(f"{s}_elbow", f"{s}_wrist", 0.5))
            b.add(f"hand_{c}", f"lowerarm_{c}", _j(f"{s}_wrist"), f"{s}_wrist")
            b.fingers(f"hand_{c}", lambda f, k, c=c: f"{f.lower()}_0{k}_{c}", sg, mid_smpl=f"{s}_hand")
            b.add(f"thigh_{c}", "pelvis", _j(f"{s}_hip"), f"{s}_hip")
            b.add(f"thigh_twist_01_{c}", f"thigh_{c}", _lerp(f"{s}_hip", f"{s}_knee", 0.5))
            b.add(f"calf_{c}", f"thigh_{c}", _j(f"{s}_knee"), f"{s}_knee")
            b.add(f"calf_twist_01_{c}", f"calf_{c}", _lerp(f"{s}_knee", f"{s}_ankle", 0.5))
            b.add(f"foot_{c}", f"calf_{c}", _j(f"{s}_ankle"), f"{s}_ankle")
            b.add(f"ball_{c}", f"foot_{c}", _j(f"{s}_foot"), f"{s}_foot")
        b.add("ik_foot_root", "root", [0, 0, 0])
        b.add("ik_foot_l", "ik_foot_root", _j("left_ankle"))
        b.add("ik_foot_r", "ik_foot_root", _j("right_ankle"))
        b.add("ik_hand_root", "root", [0, 0, 0])
        b.add("ik_hand_gun", "ik_hand_root", _j("right_wrist"))
        b.add("ik_hand_r", "ik_hand_gun", _j("right_wrist"))
        b.add("ik_hand_l", "ik_hand_gun", _j("left_wrist"))
    elif kind == "xsens":  # MVN's 23 segments
        b.add("Pelvis", None, _j("pelvis"), "pelvis")
        b.add("L5", "Pelvis", _lerp("pelvis", "spine1", 0.5))
        b.add("L3", "L5", _j("spine1"), "spine1")
        b.add("T12", "L3", _j("spine2"), "spine2")
        b.add("T8", "T12", _j("spine3"), "spine3")
        b.add("Neck", "T8", _j("neck"), "neck")
        b.add("Head", "Neck", _j("head"), "head")
        for s, _, _, S, _ in _SIDES:
            b.add(f"{S}Shoulder", "T8", _j(f"{s}_collar"), f"{s}_collar")
            b.add(f"{S}UpperArm", f"{S}Shoulder", _j(f"{s}_shoulder"), f"{s}_shoulder")
            b.add(f"{S}ForeArm", f"{S}UpperArm", _j(f"{s}_elbow"), f"{s}_elbow")
            b.add(f"{S}Hand", f"{S}ForeArm", _j(f"{s}_wrist"), f"{s}_wrist")
            b.add(f"{S}UpperLeg", "Pelvis", _j(f"{s}_hip"), f"{s}_hip")
            b.add(f"{S}LowerLeg", f"{S}UpperLeg", _j(f"{s}_knee"), f"{s}_knee")
            b.add(f"{S}Foot", f"{S}LowerLeg", _j(f"{s}_ankle"), f"{s}_ankle")
            b.add(f"{S}Toe", f"{S}Foot", _j(f"{s}_foot"), f"{s}_foot")
    elif kind in ("vrm", "vroid"):  # VRM humanoid bone names, or VRoid's J_Bip_ node names
        v = kind == "vroid"
        nm = (
            (lambda c, part: f"J_Bip_{c}_{part}")
            if v
            else (lambda c, part: part[0].lower() + part[1:] if c == "C" else ("left" if c == "L" else "right") + part)
        )
        b.add(nm("C", "Hips"), None, _j("pelvis"), "pelvis")
        b.add(nm("C", "Spine"), nm("C", "Hips"), _j("spine1"), "spine1")
        b.add(nm("C", "Chest"), nm("C", "Spine"), _j("spine2"), "spine2")
        chest = b.add(nm("C", "UpperChest"), nm("C", "Chest"), _j("spine3"), "spine3")
        b.add(nm("C", "Neck"), chest, _j("neck"), "neck")
        b.add(nm("C", "Head"), nm("C", "Neck"), _j("head"), "head")
        for s, S, _, _, sg in _SIDES:
            b.add(nm(S, "Shoulder"), chest, _j(f"{s}_collar"), f"{s}_collar")
            b.add(nm(S, "UpperArm"), nm(S, "Shoulder"), _j(f"{s}_shoulder"), f"{s}_shoulder")
            b.add(nm(S, "LowerArm"), nm(S, "UpperArm"), _j(f"{s}_elbow"), f"{s}_elbow")
            b.add(nm(S, "Hand"), nm(S, "LowerArm"), _j(f"{s}_wrist"), f"{s}_wrist")
            if v:
                b.fingers(nm(S, "Hand"), lambda f, k, S=S: f"J_Bip_{S}_{f}{k}", sg, mid_smpl=f"{s}_hand")
            b.add(nm(S, "UpperLeg"), nm("C", "Hips"), _j(f"{s}_hip"), f"{s}_hip")
            b.add(nm(S, "LowerLeg"), nm(S, "UpperLeg"), _j(f"{s}_knee"), f"{s}_knee")
            b.add(nm(S, "Foot"), nm(S, "LowerLeg"), _j(f"{s}_ankle"), f"{s}_ankle")
            b.add(nm(S, "ToeBase" if v else "Toes"), nm(S, "Foot"), _j(f"{s}_foot"), f"{s}_foot")
        if v:
            for _s, S, _, _, sg in _SIDES:
                b.add(f"J_Adj_{S}_FaceEye", nm("C", "Head"), _j("head") + [sg * 0.03, 0.08, 0.08])
    elif kind == "rigify":  # DEF- bones; the .001 segments sit inside the limbs (twist)
        b.add("DEF-spine", None, _j("pelvis"), "pelvis")
        b.add("DEF-spine.001", "DEF-spine", _j("spine1"), "spine1")
        b.add("DEF-spine.002", "DEF-spine.001", _j("spine2"), "spine2")
        b.add("DEF-spine.003", "DEF-spine.002", _j("spine3"), "spine3")
        b.add("DEF-spine.004", "DEF-spine.003", _j("neck"), "neck")
        b.add("DEF-spine.005", "DEF-spine.004", _lerp("neck", "head", 0.5), twist=True)
        b.add("DEF-spine.006", "DEF-spine.005", _j("head"), "head")
        for s, S, _, _, sg in _SIDES:
            b.add(f"DEF-pelvis.{S}", "DEF-spine", _j("pelvis") + [sg * 0.06, 0.05, 0.03])
            b.add(f"DEF-thigh.{S}", "DEF-spine", _j(f"{s}_hip"), f"{s}_hip")
            b.add(f"DEF-thigh.{S}.001", f"DEF-thigh.{S}", _lerp(f"{s}_hip", f"{s}_knee", 0.5), twist=True)
            b.add(f"DEF-shin.{S}", f"DEF-thigh.{S}.001", _j(f"{s}_knee"), f"{s}_knee")
            b.add(f"DEF-shin.{S}.001", f"DEF-shin.{S}", _lerp(f"{s}_knee", f"{s}_ankle", 0.5), twist=True)
            b.add(f"DEF-foot.{S}", f"DEF-shin.{S}.001", _j(f"{s}_ankle"), f"{s}_ankle")
            b.add(f"DEF-toe.{S}", f"DEF-foot.{S}", _j(f"{s}_foot"), f"{s}_foot")
            b.add(f"DEF-shoulder.{S}", "DEF-spine.003", _j(f"{s}_collar"), f"{s}_collar")
            b.add(f"DEF-upper_arm.{S}", f"DEF-shoulder.{S}", _j(f"{s}_shoulder"), f"{s}_shoulder")
            b.add(f"DEF-upper_arm.{S}.001", f"DEF-upper_arm.{S}", _lerp(f"{s}_shoulder", f"{s}_elbow", 0.5), twist=True)
            b.add(f"DEF-forearm.{S}", f"DEF-upper_arm.{S}.001", _j(f"{s}_elbow"), f"{s}_elbow")
            b.add(f"DEF-forearm.{S}.001", f"DEF-forearm.{S}", _lerp(f"{s}_elbow", f"{s}_wrist", 0.5), twist=True)
            b.add(f"DEF-hand.{S}", f"DEF-forearm.{S}.001", _j(f"{s}_wrist"), f"{s}_wrist")
            b.fingers(
                f"DEF-hand.{S}",
                lambda f, k, S=S: f"DEF-f_{f.lower()}.0{k}.{S}" if f != "Thumb" else f"DEF-thumb.0{k}.{S}",
                sg,
                mid_smpl=f"{s}_hand",
            )
    elif kind == "rokoko":  # Hips/Spine1..4, LeftThigh/LeftShin, metacarpal finger joints
        b.add("Hips", None, _j("pelvis"), "pelvis")
        b.add("Spine1", "Hips", _j("spine1"), "spine1")
        b.add("Spine2", "Spine1", _j("spine2"), "spine2")
        b.add("Spine3", "Spine2", _lerp("spine2", "spine3", 0.5))
        b.add("Spine4", "Spine3", _j("spine3"), "spine3")
        b.add("Neck", "Spine4", _j("neck"), "neck")
        b.add("Head", "Neck", _j("head"), "head")
        b.add("HeadTop", "Head", _j("head") + [0, 0.15, 0])
        for s, _, _, S, sg in _SIDES:
            b.add(f"{S}Shoulder", "Spine4", _j(f"{s}_collar"), f"{s}_collar")
            b.add(f"{S}Arm", f"{S}Shoulder", _j(f"{s}_shoulder"), f"{s}_shoulder")
            b.add(f"{S}ForeArm", f"{S}Arm", _j(f"{s}_elbow"), f"{s}_elbow")
            b.add(f"{S}Hand", f"{S}ForeArm", _j(f"{s}_wrist"), f"{s}_wrist")
            num = {"Thumb": 1, "Index": 2, "Middle": 3, "Ring": 4, "Pinky": 5}
            b.fingers(
                f"{S}Hand",
                lambda f, k, S=S, num=num: f"{S}Finger{num[f]}{('Proximal', 'Medial', 'Distal')[k - 1]}",
                sg,
                mid_smpl=f"{s}_hand",
                metacarpal=lambda f, S=S, num=num: f"{S}Finger{num[f]}Metacarpal",
            )
            b.add(f"{S}Thigh", "Hips", _j(f"{s}_hip"), f"{s}_hip")
            b.add(f"{S}Shin", f"{S}Thigh", _j(f"{s}_knee"), f"{s}_knee")
            b.add(f"{S}Foot", f"{S}Shin", _j(f"{s}_ankle"), f"{s}_ankle")
            b.add(f"{S}Toe", f"{S}Foot", _j(f"{s}_foot"), f"{s}_foot")
            b.add(f"{S}ToeEnd", f"{S}Toe", _j(f"{s}_foot") + [0, 0, 0.05])
    elif kind in ("armature-mixamo", "character1"):  # Mixamo names behind a namespace or a character prefix
        from segadeform.body.skeleton import SMPL_PARENTS
        from segadeform.body.skeleton_map import MIXAMO_TO_SMPL

        inv = {v: k for k, v in MIXAMO_TO_SMPL.items()}
        pre = "Armature|mixamorig:" if kind == "armature-mixamo" else "Character1_"
        for j, n in enumerate(SMPL_JOINT_NAMES):
            b.add(pre + inv[n], None if j == 0 else pre + inv[SMPL_JOINT_NAMES[SMPL_PARENTS[j]]], _j(n), n)
        b.add(pre + "HeadTop_End", pre + "Head", _j("head") + [0, 0.15, 0])
        if kind == "character1":
            b.names.insert(0, "Character1_Reference")  # MotionBuilder's floor reference above the hips
            b.parents = [-1] + [p + 1 for p in b.parents]
            b.parents[1] = 0
            b.pos.insert(0, np.zeros(3))
    else:
        raise KeyError(kind)
    return b.build()


def naming_motion(parents, rest, names, twist=(), *, frames=30, seed=0, amplitude=0.4):
    """Local rotations ``(T, J, 3, 3)`` and root positions ``(T, 3)``: smooth random turns of every joint,
    helpers included; joints in ``twist`` only turn about their bone (towards their child)."""
    parents = np.asarray(parents)
    loc = smooth_local_rotations(frames, len(names), seed=seed, amplitude=amplitude)
    rng = np.random.default_rng(seed + 1)
    for n in twist:
        if isinstance(n, tuple):  # a joint that keeps still
            loc[:, names.index(n[0])] = np.eye(3)
            continue
        j = names.index(n)
        child = next(c for c in range(len(names)) if parents[c] == j)
        axis = rest[child] - rest[j]
        axis = axis / np.linalg.norm(axis)
        ang = 0.6 * np.sin(np.linspace(0, 3, frames) + rng.uniform(0, 6))
        loc[:, j] = axis_angle_to_matrix(ang[:, None] * axis)
    root = int(np.flatnonzero(parents < 0)[0])
    root_pos = rest[root] + np.stack(
        [np.linspace(0, 0.4, frames), 0.02 * np.sin(np.arange(frames)), np.zeros(frames)], axis=1
    )
    return loc, root_pos


def write_naming_bvh(path, kind, *, scale=1.0, six_channels=False, rename=None, seed=0, frames=30):
    """A BVH of naming ``kind`` (``scale``: file units per metre); ``rename``: a list of new names.  Returns
    ``(path, names, parents, rest, expected, local_rot, root_pos)``."""
    names, parents, rest, expected, twist = naming_skeleton(kind)
    loc, root_pos = naming_motion(parents, rest, names, twist, frames=frames, seed=seed)
    out_names = list(rename) if rename is not None else names
    write_skeleton_bvh(path, out_names, parents, rest, loc, root_pos, scale=scale, six_channels=six_channels)
    return path, names, parents, rest, expected, loc, root_pos
