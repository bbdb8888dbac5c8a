import numpy as np
import pytest

from segadeform.body import SMPL_JOINT_NAMES, SMPL_PARENTS, BodyModel, default_rest_joints
from segadeform.geometry.primitives import cylinder


def toy_body(n_betas=4, posedirs=False, seed=0) -> BodyModel:
    """A small valid 24-joint body: a closed-ish tube around the spine, weights to the nearest joint."""
    rng = np.random.default_rng(seed)
    v, f = cylinder(12, 10, radius=0.15, height=1.6)
    joints = default_rest_joints()
    d = np.linalg.norm(v[:, None] - joints[None], axis=2)
    w = np.exp(-d / 0.05)
    w /= w.sum(1, keepdims=True)
    jr = np.zeros((24, len(v)))
    nearest = np.argsort(d, axis=0)[:4]  # each joint: mean of its 4 nearest vertices, plus an offset
    for j in range(24):
        jr[j, nearest[:, j]] = 0.25
    return BodyModel(
        v_template=v,
        faces=f,
        shapedirs=rng.normal(scale=0.01, size=(len(v), 3, n_betas)),
        weights=w,
        parents=SMPL_PARENTS.copy(),
        joint_names=SMPL_JOINT_NAMES,
        J_regressor=jr,
        posedirs=rng.normal(scale=1e-3, size=(len(v), 3, 207)) if posedirs else None,
    ).validate()


@pytest.fixture
def body():
    return toy_body()
