"""Build GLB files of skinned skeletons for tests (through pygltflib): any names, rest poses whose joints have
their own orientations, an ``Armature`` node above the root with a scale, one or more animations.

The skeleton is given like ``bvh_build.write_skeleton_bvh``'s (rest positions, local rotations relative to
the rest pose with world-aligned rest frames, root positions), so the same motion can be written as a BVH
and as a GLB and the two readers compared.
"""

from __future__ import annotations

import numpy as np

from segadeform.body.rotations import matrix_to_quaternion

from .bvh_build import source_fk


def _quat_xyzw(R):
    q = matrix_to_quaternion(R)  # (w, x, y, z)
    return q[..., [1, 2, 3, 0]]


def write_skeleton_glb(
    path,
    names,
    parents,
    rest,
    local_rot,
    root_pos,
    *,
    fps=30.0,
    armature_scale=1.0,
    seed=0,
    animations=("take",),
    interpolation="LINEAR",
    skin=True,
    nan_key=False,
):
    """Write a GLB.  ``rest`` (J, 3), ``root_pos`` (T, 3) are in metres divided by ``armature_scale`` (the
    Armature node scales them back); ``local_rot`` (T, J, 3, 3).  Every joint gets a random rest orientation
    (its node's rotation at rest), which the channels carry.  ``animations``: names; the k-th plays the motion
    k + 1 times faster (so they differ).  ``nan_key``: one NaN in a rotation channel."""
    import pygltflib as g

    parents = np.asarray(parents)
    J, T = len(names), local_rot.shape[0]
    rng = np.random.default_rng(seed)
    from segadeform.body.rotations import axis_angle_to_matrix

    W = axis_angle_to_matrix(rng.normal(size=(J, 3)))  # rest world orientations of the joints' frames
    blob = bytearray()
    views, accessors = [], []

    def add(arr, kind, comp=g.FLOAT, minmax=False):
        arr = np.ascontiguousarray(arr)
        while len(blob) % 4:
            blob.append(0)
        views.append(g.BufferView(buffer=0, byteOffset=len(blob), byteLength=arr.nbytes))
        blob.extend(arr.tobytes())
        acc = g.Accessor(bufferView=len(views) - 1, componentType=comp, count=len(arr), type=kind)
        if minmax:
            acc.min, acc.max = [float(arr.min())], [float(arr.max())]
        accessors.append(acc)
        return len(accessors) - 1

    nodes = [g.Node(name="Armature", scale=[armature_scale] * 3, children=[])]
    idx = [j + 1 for j in range(J)]
    for j in range(J):
        p = parents[j]
        Wp = W[p] if p >= 0 else np.eye(3)
        off = rest[j] - (rest[p] if p >= 0 else 0.0)
        nodes.append(
            g.Node(
                name=names[j], translation=(Wp.T @ off).tolist(), rotation=_quat_xyzw(Wp.T @ W[j]).tolist(), children=[]
            )
        )
        (nodes[0] if p < 0 else nodes[idx[p]]).children.append(idx[j])
    # a one-triangle mesh skinned to the root, so the file is a skinned character
    mesh_node = len(nodes)
    pos = add(np.array([[0, 0, 0], [0.1, 0, 0], [0, 0.1, 0]], np.float32), "VEC3")
    accessors[pos].min, accessors[pos].max = [0.0, 0.0, 0.0], [0.1, 0.1, 0.0]
    jts = add(np.zeros((3, 4), np.uint16), "VEC4", comp=g.UNSIGNED_SHORT)
    wts = add(np.tile(np.array([1, 0, 0, 0], np.float32), (3, 1)), "VEC4")
    mesh = g.Mesh(
        name="body", primitives=[g.Primitive(attributes=g.Attributes(POSITION=pos, JOINTS_0=jts, WEIGHTS_0=wts))]
    )
    nodes.append(g.Node(name="body", mesh=0, skin=0 if skin else None))
    # bind pose: world = Armature scale x joint's rest world transform
    ibm = []
    for j in range(J):
        M = np.eye(4)
        M[:3, :3] = W[j] * armature_scale
        M[:3, 3] = rest[j] * armature_scale
        ibm.append(np.linalg.inv(M).T.ravel())  # column-major
    ibm_acc = add(np.array(ibm, np.float32), "MAT4")
    anims = []
    for k, name in enumerate(animations):
        sub = np.arange(0, T, k + 1)
        G, _ = source_fk(parents, rest, local_rot[sub], root_pos[sub])
        times = add((np.arange(len(sub)) / fps).astype(np.float32), "SCALAR", minmax=True)
        samplers, channels = [], []
        for j in range(J):
            p = parents[j]
            Lw = (np.swapaxes(G[:, p] @ W[p], -1, -2) if p >= 0 else np.eye(3)) @ (G[:, j] @ W[j])
            q = _quat_xyzw(Lw).astype(np.float32)
            if nan_key and j == 1:
                q[len(q) // 2, 0] = np.nan
            if interpolation == "CUBICSPLINE":
                q = np.stack([np.zeros_like(q), q, np.zeros_like(q)], axis=1).reshape(-1, 4)
            samplers.append(g.AnimationSampler(input=times, output=add(q, "VEC4"), interpolation=interpolation))
            channels.append(
                g.AnimationChannel(
                    sampler=len(samplers) - 1, target=g.AnimationChannelTarget(node=idx[j], path="rotation")
                )
            )
            if p < 0:
                tr = root_pos[sub].astype(np.float32)
                if interpolation == "CUBICSPLINE":
                    tr = np.stack([np.zeros_like(tr), tr, np.zeros_like(tr)], axis=1).reshape(-1, 3)
                samplers.append(g.AnimationSampler(input=times, output=add(tr, "VEC3"), interpolation=interpolation))
                channels.append(
                    g.AnimationChannel(
                        sampler=len(samplers) - 1, target=g.AnimationChannelTarget(node=idx[j], path="translation")
                    )
                )
        anims.append(g.Animation(name=name, samplers=samplers, channels=channels))
    gl = g.GLTF2(
        scene=0,
        scenes=[g.Scene(nodes=[0, mesh_node])],
        nodes=nodes,
        meshes=[mesh],
        skins=[g.Skin(joints=idx, inverseBindMatrices=ibm_acc, skeleton=idx[0])] if skin else [],
        animations=anims,
        accessors=accessors,
        bufferViews=views,
        buffers=[g.Buffer(byteLength=len(blob))],
    )
    gl.set_binary_blob(bytes(blob))
    gl.save_binary(str(path))
    return path
