"""Body model support (numpy only).  This first part holds the SMPL skeleton's
joint names and hierarchy and reads rest-pose joints from files; the full
body format, forward kinematics and skinning build on it."""

from .skeleton import SMPL_JOINT_NAMES, SMPL_PARENTS, load_rest_joints

__all__ = ["SMPL_JOINT_NAMES", "SMPL_PARENTS", "load_rest_joints"]
