"""A garment mesh from a glTF file (``.glb``/``.gltf``), as an engine exports it: `run` took none (an engine
integrator's trial).  The reader keeps the file's vertices, in the order of the scene's nodes and their primitives,
places an unskinned mesh at its node's world transform and a skinned one as stored, makes strips triangles, leaves
points out, and names the file in its errors."""

from __future__ import annotations

import numpy as np
import pytest

from segadeform.errors import FileFormatError, InputError
from segadeform.io import read_mesh


def _glb(path, prims, *, nodes=None):
    """A GLB with one mesh per entry of ``prims``: (positions (n, 3), indices or None, mode), each on a node of its
    own (``nodes``: keyword arguments per node, e.g. translation, skin); the scene holds them all."""
    import pygltflib as g

    blob = bytearray()
    views, accessors, meshes = [], [], []

    def add(arr, kind, comp):
        arr = np.ascontiguousarray(arr)
        while len(blob) % 4:
            blob.append(0)
        views.append(g.BufferView(buffer=0, byteOffset=len(blob), byteLength=arr.nbytes))
        blob.extend(arr.tobytes())
        accessors.append(g.Accessor(bufferView=len(views) - 1, componentType=comp, count=len(arr), type=kind))
        return len(accessors) - 1

    for pos, idx, mode in prims:
        attrs = g.Attributes(POSITION=add(np.asarray(pos, np.float32), g.VEC3, g.FLOAT))
        ind = None if idx is None else add(np.asarray(idx, np.uint16).ravel(), g.SCALAR, g.UNSIGNED_SHORT)
        meshes.append(g.Mesh(primitives=[g.Primitive(attributes=attrs, indices=ind, mode=mode)]))
    extra = nodes or [{} for _ in prims]
    gl = g.GLTF2(
        scene=0,
        scenes=[g.Scene(nodes=list(range(len(prims))))],
        nodes=[g.Node(mesh=k, **extra[k]) for k in range(len(prims))],
        meshes=meshes,
        accessors=accessors,
        bufferViews=views,
        buffers=[g.Buffer(byteLength=len(blob))],
    )
    gl.set_binary_blob(bytes(blob))
    gl.save_binary(str(path))
    return path


QUAD = np.array([[0.0, 1.0, 0.0], [0.1, 1.0, 0.0], [0.1, 1.1, 0.0], [0.0, 1.1, 0.0]])


def test_a_glb_garment_is_read_in_the_files_vertex_order_and_place(tmp_path):
    p = _glb(
        tmp_path / "g.glb",
        [(QUAD, [[0, 1, 2], [0, 2, 3]], 4), (QUAD, [0, 1, 3, 2], 5), (QUAD, None, 0)],
        nodes=[{"translation": [0.0, 0.0, 0.2]}, {"rotation": [0.0, 0.7071068, 0.0, 0.7071068]}, {}],
    )
    m = read_mesh(p)
    assert m.n_vertices == 8  # the points are left out
    np.testing.assert_allclose(m.vertices[:4], QUAD + [0, 0, 0.2], atol=1e-6)  # at the node's translation
    np.testing.assert_allclose(m.vertices[4:], QUAD[:, [2, 1, 0]] * [1, 1, -1], atol=1e-6)  # turned 90 deg about +Y
    np.testing.assert_array_equal(m.faces[:2], [[0, 1, 2], [0, 2, 3]])
    # a strip 0 1 3 2: two triangles wound alike
    np.testing.assert_array_equal(m.faces[2:], [[4, 5, 7], [7, 5, 6]])
    n = np.cross(*(m.vertices[m.faces[:, 1:]] - m.vertices[m.faces[:, :1]]).transpose(1, 0, 2))
    assert (n[2:] @ n[2] > 0).all()


def test_a_skinned_glb_mesh_is_read_as_stored(tmp_path):
    import pygltflib as g

    p = _glb(tmp_path / "s.glb", [(QUAD, [[0, 1, 2], [0, 2, 3]], 4)], nodes=[{"translation": [5.0, 0.0, 0.0]}])
    gl = g.GLTF2().load_binary(str(p))
    gl.nodes.append(g.Node(name="root"))
    gl.skins = [g.Skin(joints=[1])]
    gl.nodes[0].skin = 0
    gl.save_binary(str(p))
    np.testing.assert_allclose(read_mesh(p).vertices, QUAD, atol=1e-6)  # its node's transform ignored, as glTF says


def test_glb_errors_name_the_file(tmp_path):
    with pytest.raises(InputError, match="no mesh with triangles") as e:
        read_mesh(_glb(tmp_path / "points.glb", [(QUAD, None, 0)]))
    assert "points.glb" in str(e.value)
    with pytest.raises(FileFormatError, match="index outside its vertices") as e:
        read_mesh(_glb(tmp_path / "far.glb", [(QUAD, [[0, 1, 9]], 4)]))
    assert "far.glb" in str(e.value)
    (tmp_path / "not.glb").write_bytes(b"glTF\x02\x00\x00\x00garbage")
    with pytest.raises(FileFormatError) as e:
        read_mesh(tmp_path / "not.glb")
    assert "not.glb" in str(e.value)


def test_inspect_says_a_glb_without_animation_is_a_mesh(tmp_path):
    """`inspect` read every .glb as a motion and said "glTF has no skin" of a garment (an engine integrator's trial)."""
    from click.testing import CliRunner

    from segadeform.cli.main import cli

    p = _glb(tmp_path / "g.glb", [(QUAD, [[0, 1, 2], [0, 2, 3]], 4)])
    r = CliRunner().invoke(cli, ["inspect", str(p)])
    assert r.exit_code == 0 and f"{p}: mesh, 4 vertices, 2 triangles" in r.output, r.output


def test_shared_vertices_mirrors_scenes_and_compression(tmp_path):
    """Found by a review: primitives sharing one POSITION accessor had their vertices copied (vertices in no face); a
    mirroring node's faces came out wound inward; a file with no scene failed on its node tree; a Draco-compressed
    mesh read as zeros."""
    import pygltflib as g

    p = _glb(tmp_path / "shared.glb", [(QUAD, [[0, 1, 2]], 4), (QUAD, [[0, 2, 3]], 4)])
    gl = g.GLTF2().load_binary(str(p))
    second = gl.meshes[1].primitives[0]
    second.attributes.POSITION = gl.meshes[0].primitives[0].attributes.POSITION  # one vertex buffer, two materials
    gl.meshes[0].primitives.append(second)
    gl.scenes[0].nodes = [0]
    gl.save_binary(str(p))
    m = read_mesh(p)
    assert m.n_vertices == 4 and m.faces.tolist() == [[0, 1, 2], [0, 2, 3]]
    p = _glb(tmp_path / "mirror.glb", [(QUAD, [[0, 1, 2], [0, 2, 3]], 4)], nodes=[{"scale": [-1.0, 1.0, 1.0]}])
    m = read_mesh(p)
    n = np.cross(*(m.vertices[m.faces[:, 1:]] - m.vertices[m.faces[:, :1]]).transpose(1, 0, 2))
    assert (n[:, 2] > 0).all()  # the quad faces +Z as in the file, mirrored or not
    gl = g.GLTF2().load_binary(str(_glb(tmp_path / "tree.glb", [(QUAD, [[0, 1, 2]], 4)])))
    gl.nodes.insert(0, g.Node(children=[1]))
    gl.scenes, gl.scene = [], None
    gl.save_binary(str(tmp_path / "noscene.glb"))
    assert read_mesh(tmp_path / "noscene.glb").n_vertices == 4
    gl.extensionsRequired = ["KHR_draco_mesh_compression"]
    gl.save_binary(str(tmp_path / "draco.glb"))
    with pytest.raises(FileFormatError, match="compressed .KHR_draco_mesh_compression."):
        read_mesh(tmp_path / "draco.glb")


@pytest.mark.parametrize(
    "rotation, turned",
    [
        ([0.0, 0.7071067811865476, 0.0, 0.7071067811865476], True),  # 90 degrees about +Y
        ([0.0, 1e300, 0.0, 1e300], True),  # the same, scaled past float range when squared
        ([0.0, 1e-300, 0.0, 1e-300], True),  # ... and below it
        ([0.0, 0.0, 0.0, 0.0], None),  # no rotation at all: refused
    ],
)
def test_a_node_rotation_of_any_length_is_normalised_and_a_zero_one_refused(tmp_path, rotation, turned):
    """A fuzzer's trial: rotations [0, 1e300, 0, 1e300], [0, 1e-300, 0, 1e-300] and [0, 0, 0, 0] were all read as
    no rotation (the first with numpy's overflow warning), with exit 0."""
    path = _glb(tmp_path / "q.glb", [(QUAD, [[0, 1, 2], [0, 2, 3]], 4)], nodes=[{"rotation": rotation}])
    if turned is None:
        with pytest.raises(FileFormatError, match=r"q\.glb: node 0's rotation is not a rotation"):
            read_mesh(path)
        return
    v = read_mesh(path).vertices
    want = QUAD @ np.array([[0.0, 0, 1], [0, 1, 0], [-1, 0, 0]]).T  # +X -> -Z, +Z -> +X
    assert np.abs(v - want).max() < 1e-6


def test_nodes_nested_thousands_deep_are_one_line_and_a_buffer_is_read_to_its_length(tmp_path):
    """A fuzzer's trial: 5,000 nested nodes gave a RecursionError traceback, and a buffer whose uri was /dev/zero was
    read until the kernel killed the process."""
    import json
    import os

    path = _glb(tmp_path / "g.glb", [(QUAD, [[0, 1, 2], [0, 2, 3]], 4)])
    import pygltflib as g

    gl = g.GLTF2().load(str(path))
    depth = 400
    gl.nodes = [g.Node(children=[k + 1]) for k in range(depth)] + [g.Node(mesh=0)]
    gl.scenes = [g.Scene(nodes=[0])]
    gl.save_binary(str(tmp_path / "deep.glb"))
    with pytest.raises(FileFormatError, match=r"deep\.glb: nodes nest too deeply \(expected at most 256 levels"):
        read_mesh(tmp_path / "deep.glb")
    # a .gltf whose buffer is a device, and one whose file is shorter than its byteLength
    gl = g.GLTF2().load(str(path))
    blob = gl.binary_blob()
    (tmp_path / "g.bin").write_bytes(blob)
    doc = json.loads(gl.to_json())
    os.symlink("/dev/zero", tmp_path / "zero.bin")  # beside it, but a device (an absolute uri is refused before)
    doc["buffers"] = [{"byteLength": len(blob), "uri": "zero.bin"}]
    (tmp_path / "zero.gltf").write_text(json.dumps(doc))
    with pytest.raises(FileFormatError, match=r"zero\.gltf: buffer 0's file is not a regular file"):
        read_mesh(tmp_path / "zero.gltf")
    doc["buffers"] = [{"byteLength": len(blob) + 8, "uri": "g.bin"}]
    (tmp_path / "short.gltf").write_text(json.dumps(doc))
    with pytest.raises(FileFormatError, match=r"short\.gltf: buffer 0's file is shorter than the glTF says"):
        read_mesh(tmp_path / "short.gltf")
    doc["buffers"] = [{"byteLength": len(blob), "uri": "g.bin"}]
    (tmp_path / "ok.gltf").write_text(json.dumps(doc))
    assert np.abs(read_mesh(tmp_path / "ok.gltf").vertices - QUAD).max() < 1e-6


def test_a_buffer_outside_the_gltfs_folder_and_an_unbacked_huge_accessor_are_refused(tmp_path):
    """A security review: a buffer uri of ../secret or an absolute path read any file and copied its bytes into the
    garment (normalised unsigned bytes pass every bound), and a 276-byte file asked for 30 million zeros (6 GB)."""
    import json

    import pygltflib as g

    path = _glb(tmp_path / "g.glb", [(QUAD, [[0, 1, 2], [0, 2, 3]], 4)])
    gl = g.GLTF2().load(str(path))
    blob = gl.binary_blob()
    (tmp_path / "sub").mkdir()
    (tmp_path / "g.bin").write_bytes(blob)
    (tmp_path / "sub" / "g.bin").write_bytes(blob)
    doc = json.loads(gl.to_json())
    for uri in ("../g.bin", str(tmp_path / "g.bin"), "..%2Fg.bin", "sub/../../g.bin"):
        doc["buffers"] = [{"byteLength": len(blob), "uri": uri}]
        (tmp_path / "sub" / "x.gltf").write_text(json.dumps(doc))
        with pytest.raises(FileFormatError, match="buffer 0's file is outside the glTF's folder"):
            read_mesh(tmp_path / "sub" / "x.gltf")
    doc["buffers"] = [{"byteLength": len(blob), "uri": "g.bin"}]  # beside it: read
    (tmp_path / "sub" / "x.gltf").write_text(json.dumps(doc))
    assert len(read_mesh(tmp_path / "sub" / "x.gltf").vertices) == 4
    pos = doc["meshes"][0]["primitives"][0]["attributes"]["POSITION"]
    doc["accessors"][pos] = {"componentType": 5126, "count": 30_000_000, "type": "VEC3"}  # no bufferView
    (tmp_path / "sub" / "x.gltf").write_text(json.dumps(doc))
    with pytest.raises(FileFormatError, match="has no bufferView and a count too large"):
        read_mesh(tmp_path / "sub" / "x.gltf")
