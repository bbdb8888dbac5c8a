"""Body model support (numpy only): the SMPL skeleton, an SMPL-compatible body format and
loaders, forward kinematics, skinning references and a collision proxy."""

from .collision import BodyProxy, ProximityResult
from .kinematics import forward_kinematics, poses_to_rotmats, relative_transforms
from .model import BodyModel, BodyOutput, default_body_path, load_body
from .rotations import axis_angle_to_matrix, matrix_to_axis_angle
from .skeleton import SMPL_JOINT_NAMES, SMPL_PARENTS, default_rest_joints, load_rest_joints
from .skinning import dual_quaternion_skinning, linear_blend_skinning

__all__ = [
    "SMPL_JOINT_NAMES",
    "SMPL_PARENTS",
    "load_rest_joints",
    "default_rest_joints",
    "BodyModel",
    "BodyOutput",
    "load_body",
    "default_body_path",
    "forward_kinematics",
    "relative_transforms",
    "poses_to_rotmats",
    "linear_blend_skinning",
    "dual_quaternion_skinning",
    "BodyProxy",
    "ProximityResult",
    "axis_angle_to_matrix",
    "matrix_to_axis_angle",
]
