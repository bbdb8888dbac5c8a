"""The malformed-input corpus: files that must each give a clear error through the CLI.

``build(dir, package)`` writes every file into ``dir`` and returns the cases:
(name, CLI arguments, a fragment the message must contain, the output path
that must not appear).  The files are generated (not committed) so the corpus
follows the formats as they evolve; ``python -m tests.malformed.corpus DIR``
writes them for a fuzzer's seed corpus.
"""

from __future__ import annotations

import io
import json
import os
import pickle
import shutil
import struct
import sys
import zipfile
from pathlib import Path

import numpy as np

PC2 = struct.Struct("<12siiffi")
MAGIC = b"POINTCACHE2\0"
ROOT = Path(__file__).resolve().parents[2]
JOINTS = ROOT / "samples" / "skeletons" / "tpose_joints_24.npy"
GOOD_OBJ = "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 1 1 0\nf 1 2 3\nf 2 4 3\n"


def _npz_with_huge_header(path: Path, name: str, shape=(10**10,)):
    """An .npz whose member declares ``shape`` float64 but stores 8 bytes."""
    buf = io.BytesIO()
    np.lib.format.write_array_header_1_0(buf, {"descr": "<f8", "fortran_order": False, "shape": shape})
    buf.write(b"\0" * 8)
    with zipfile.ZipFile(path, "w") as zf:
        zf.writestr(f"{name}.npy", buf.getvalue())


class _Evil:
    def __init__(self, cmd):
        self.cmd = cmd

    def __reduce__(self):
        return (os.system, (self.cmd,))


def build(d: Path, package: Path | None = None) -> list[tuple[str, list[str], str, Path | None]]:
    d = Path(d)
    d.mkdir(parents=True, exist_ok=True)
    cases: list = []
    out = d / "OUT.npz"

    def obj(name, text, words):
        p = d / f"{name}.obj"
        p.write_text(text) if isinstance(text, str) else p.write_bytes(text)
        cases.append((f"obj/{name}", ["precompute", str(p), "--joints", str(JOINTS), "-o", str(out)], words, out))

    obj("index_out_of_range", GOOD_OBJ + "f 1 2 9\n", "vertex index out of range")
    obj("index_zero", GOOD_OBJ + "f 0 1 2\n", "index 0")
    obj("relative_out_of_range", GOOD_OBJ + "f -1 -2 -9\n", "relative vertex index out of range")
    obj("two_vertex_face", GOOD_OBJ + "f 1 2\n", "fewer than 3")
    obj("nan_coordinate", "v 0 nan 0\n" + GOOD_OBJ + "f 1 2 3\n", "not finite")
    obj("inf_coordinate", "v 0 0 -inf\n" + GOOD_OBJ, "not finite")
    obj("non_numeric", "v 0 zero 0\n" + GOOD_OBJ, "non-numeric")
    obj("empty", "", "no vertices")
    obj("no_faces", "v 0 0 0\nv 1 0 0\nv 0 1 0\n", "no faces")
    obj("binary_garbage", b"\x00\x01\x02OBJ?\xff" * 50, "NUL")
    obj("bad_texcoord_index", GOOD_OBJ + "vt 0 0\nf 1/3 2/1 3/1\n", "texture coordinate index out of range")
    obj("bad_normal_index", GOOD_OBJ + "f 1//1 2//1 3//1\n", "normal index out of range")
    obj("truncated_vertex_line", "v 0 0 0\nv 1 0\n", "x y z")
    obj("bad_corner", GOOD_OBJ + "f 1/1/1/1 2 3\n", "bad face corner")
    # numbers only as files write them: Python's float() and int() also read "0.15_9" and other scripts' digits
    obj("digit_separator", "v 0 0.15_9 0\n" + GOOD_OBJ, "non-numeric")
    obj("arabic_digit", "v 0 \u0661 0\n" + GOOD_OBJ, "non-numeric")
    obj("index_separator", GOOD_OBJ + "f 1 2 1_0\n", "bad vertex index")

    def mesh(name, ext, data, words):
        p = d / f"{name}{ext}"
        p.write_text(data) if isinstance(data, str) else p.write_bytes(data)
        cases.append((f"mesh/{name}", ["precompute", str(p), "--joints", str(JOINTS), "-o", str(out)], words, out))

    mesh("off_truncated", ".off", "OFF\n4 2 0\n0 0 0\n1 0 0\n", "truncated")
    mesh("off_bad_counts", ".off", "OFF\nfour two zero\n", "counts")
    mesh("off_index", ".off", "OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 7\n", "out of range")
    mesh("off_not_off", ".off", "COFFEE\n", "not an OFF file")
    mesh("off_digit_separator", ".off", "OFF\n3 1 0\n0 0 0\n1_0 0 0\n0 1 0\n3 0 1 2\n", "non-numeric")
    mesh("off_count_separator", ".off", "OFF\n1_0 1 0\n", "counts")
    mesh("ply_garbage", ".ply", "ply\nformat nonsense 9\n", "cannot parse mesh")
    mesh(
        "ply_truncated",
        ".ply",
        b"ply\nformat binary_little_endian 1.0\nelement vertex 100\nproperty float x\n"
        b"property float y\nproperty float z\nelement face 10\nproperty list uchar int vertex_indices\n"
        b"end_header\n\x00\x00",
        "cannot parse mesh",
    )
    mesh("unknown_extension", ".xyz", "1 2 3\n", "unknown mesh file extension")
    mesh("glb_garbage", ".glb", b"glTF\x02\x00\x00\x00" + b"\xff" * 40, "glTF")
    mesh("gltf_not_json", ".gltf", "{not json", "glTF")
    mesh("gltf_no_mesh", ".gltf", '{"asset": {"version": "2.0"}, "scenes": [{"nodes": []}], "scene": 0}', "no mesh")

    def pc2(name, data, words):
        p = d / f"{name}.pc2"
        p.write_bytes(data)
        cases.append((f"pc2/{name}", ["inspect", str(p)], words, None))

    def hdr(magic=MAGIC, version=1, n=4, start=0.0, rate=1.0, s=2):
        return PC2.pack(magic, version, n, start, rate, s)

    body = b"\0" * (2 * 4 * 12)
    pc2("empty", b"", "too short")
    pc2("short_header", MAGIC + b"\0\0", "too short")
    pc2("bad_magic", hdr(magic=b"POINTCACHE1\0") + body, "bad magic")
    pc2("version_2", hdr(version=2) + body, "version")
    pc2("zero_points", hdr(n=0, s=0), "numPoints")
    pc2("negative_samples", hdr(s=-3), "numSamples")
    pc2("huge_declared", hdr(n=2**31 - 1, s=2**31 - 1) + body, "size does not match")
    pc2("truncated_data", hdr() + body[:50], "size does not match")
    pc2("trailing_data", hdr() + body + b"\0" * 7, "size does not match")
    pc2("nan_sample", hdr() + np.array([0, 0, 0] * 7 + [np.nan, 0, 0], "<f4").tobytes(), "non-finite")
    pc2("zero_rate", hdr(rate=0.0) + body, "sampleRate")

    def bodyfile(name, ext, writer, words):
        p = d / f"{name}{ext}"
        writer(p)
        cases.append((f"body/{name}", ["body", "info", str(p)], words, None))

    from tests.body.conftest import toy_body

    good = toy_body()
    good.save(d / "good_body.npz")
    arrays = dict(np.load(d / "good_body.npz", allow_pickle=False))

    def body_variant(**changes):
        def write(p):
            z = dict(arrays)
            for k, v in changes.items():
                if v is None:
                    z.pop(k)
                else:
                    z[k] = v(z[k]) if callable(v) else v
            np.savez(p, **z)

        return write

    bodyfile("missing_weights", ".npz", body_variant(weights=None), "missing arrays")
    bodyfile("weights_not_normalised", ".npz", body_variant(weights=lambda w: w * 2), "do not sum to 1")
    bodyfile("parents_cycle", ".npz", body_variant(parents=np.array([-1] + [5] * 23)), "invalid parent")
    bodyfile(
        "nan_template",
        ".npz",
        body_variant(v_template=lambda v: np.where(np.arange(v.size).reshape(v.shape) == 4, np.nan, v)),
        "NaN",
    )
    bodyfile("string_weights", ".npz", body_variant(weights=np.array(["a"] * 10)), "numeric")
    bodyfile("huge_declared_shape", ".npz", lambda p: _npz_with_huge_header(p, "v_template"), "declares more data")
    bodyfile(
        "truncated_zip", ".npz", lambda p: p.write_bytes((d / "good_body.npz").read_bytes()[:300]), "not a readable"
    )
    bodyfile(
        "object_array", ".npz", lambda p: np.savez(p, v_template=np.array([{"a": 1}], dtype=object)), "pickled objects"
    )
    bodyfile(
        "pickle_os_system",
        ".pkl",
        lambda p: p.write_bytes(pickle.dumps({"v_template": _Evil("true")}, protocol=2)),
        "forbidden global",
    )
    bodyfile("pickle_eval", ".pkl", lambda p: p.write_bytes(b"cbuiltins\neval\n(V1+1\ntR."), "forbidden global")
    bodyfile(
        "pickle_truncated",
        ".pkl",
        lambda p: p.write_bytes(pickle.dumps({"a": np.zeros(3)}, protocol=2)[:-5]),
        "malformed",
    )
    bodyfile("pickle_not_dict", ".pkl", lambda p: p.write_bytes(pickle.dumps([1, 2, 3], protocol=2)), "expected a dict")

    def motionfile(name, ext, writer, words):
        p = d / f"{name}{ext}"
        writer(p)
        cases.append((f"motion/{name}", ["motion", "info", str(p)], words, None))

    motionfile("no_poses", ".npz", lambda p: np.savez(p, trans=np.zeros((3, 3))), "no 'poses'")
    motionfile("bad_width", ".npz", lambda p: np.savez(p, poses=np.zeros((3, 70))), "unknown width")
    motionfile("zero_frames", ".npz", lambda p: np.savez(p, poses=np.zeros((0, 72))), "no frames")
    motionfile("nan_pose", ".npz", lambda p: np.savez(p, poses=np.full((2, 72), np.nan)), "NaN")
    motionfile(
        "trans_mismatch", ".npz", lambda p: np.savez(p, poses=np.zeros((4, 72)), trans=np.zeros((3, 3))), "trans"
    )
    motionfile(
        "huge_declared_poses", ".npz", lambda p: _npz_with_huge_header(p, "poses", (10**9, 72)), "declares more data"
    )
    motionfile("bad_layout", ".npz", lambda p: np.savez(p, poses=np.zeros((3, 23, 3))), "unknown layout")
    motionfile(
        "split_keys_mismatch",
        ".npz",
        lambda p: np.savez(p, root_orient=np.zeros((3, 3)), pose_body=np.zeros((2, 63))),
        "do not fit",
    )
    motionfile(
        "nan_framerate",
        ".npz",
        lambda p: np.savez(p, poses=np.zeros((3, 72)), mocap_framerate=np.float64(np.nan)),
        "positive",
    )

    from segadeform.body import default_rest_joints
    from segadeform.motion import make_motion, write_bvh

    write_bvh(d / "good.bvh", make_motion("idle", seconds=0.2), default_rest_joints())
    good_bvh = (d / "good.bvh").read_text()
    for name, text, words in (
        ("bvh_bad_keyword", good_bvh.replace("HIERARCHY", "HEIRARCHY"), "unexpected token"),
        ("bvh_truncated", "\n".join(good_bvh.splitlines()[:30]), "ends too early"),
        ("bvh_frame_mismatch", good_bvh.replace("Frames: 6", "Frames: 7"), "does not match its declared size"),
        ("bvh_huge_frames", good_bvh.replace("Frames: 6", "Frames: 999999999"), "does not match its declared size"),
        (
            "bvh_unmappable",
            "HIERARCHY\nROOT a\n{\n OFFSET 0 0 0\n CHANNELS 3 Xrotation Yrotation Zrotation\n"
            " JOINT b\n {\n  OFFSET 0 1 0\n  CHANNELS 3 Xrotation Yrotation Zrotation\n"
            "  End Site\n  {\n   OFFSET 0 1 0\n"
            "  }\n }\n}\nMOTION\nFrames: 1\nFrame Time: 0.1\n0 0 0 0 0 0\n",
            "cannot map this skeleton",
        ),
        ("bvh_duplicate_joints", good_bvh.replace("JOINT left_knee", "JOINT Left_Hip"), "joint names repeat"),
        ("bvh_nan", good_bvh.replace("0.000000", "nan", 1), "not finite"),
        ("bvh_channels", good_bvh.replace("CHANNELS 3", "CHANNELS 9", 1), "channel count"),
        ("bvh_digit_separator", good_bvh.replace("0.000000", "0.000_000", 1), "expected a number"),
        ("bvh_data_separator", good_bvh.rstrip("\n").rsplit(" ", 1)[0] + " 1_0\n", "non-numeric value"),
    ):
        motionfile(name, ".bvh", lambda p, t=text: p.write_text(t), words)

    asf_amc_cases(d, cases)

    # MakeHuman bindings, through `garment fit`
    mh_src = ROOT / "samples" / "garments" / "makehuman"
    fit_out = d / "FIT_OUT.obj"
    good_mhclo = (mh_src / "skirt_short_f.mhclo").read_text()
    shutil.copy(mh_src / "skirt_short_f.obj", d / "skirt_short_f.obj")

    def mhclo(name, text, words):
        p = d / f"{name}.mhclo"
        p.write_text(text.replace("obj_file skirt_short_f.obj", "obj_file skirt_short_f.obj"))
        cases.append((f"mhclo/{name}", ["garment", "fit", str(p), "-o", str(fit_out)], words, fit_out))

    mhclo("other_basemesh", good_mhclo.replace("basemesh hm08", "basemesh hm07"), "only hm08")
    mhclo("short_line", good_mhclo.replace("verts 0", "verts 0\n12 13 0.5 0.5", 1), "1, 6 or 9 numbers")
    mhclo("not_a_number", good_mhclo.replace("verts 0", "verts 0\n12 13 14 0.5 x 0.5 0 0 0", 1), "expected a number")
    mhclo(
        "digit_separator",
        good_mhclo.replace("verts 0", "verts 0\n12 13 14 0.5 0.2_5 0.25 0 0 0", 1),
        "expected a number",
    )
    mhclo("no_bindings", good_mhclo.split("verts 0")[0], "no binding lines")
    mhclo(
        "index_out_of_range", good_mhclo.replace("verts 0", "verts 0\n99999 1 2 0.3 0.3 0.4 0 0 0", 1), "does not have"
    )
    mhclo("obj_missing", good_mhclo.replace("obj_file skirt_short_f.obj", "obj_file nowhere.obj"), "nowhere.obj")
    mhclo(
        "count_mismatch",
        good_mhclo.replace("verts 0", "verts 0\n12 13 14 0.3 0.3 0.4 0 0 0", 1),
        "different vertex counts",
    )
    mhclo("backwards_range", good_mhclo.replace("delete_verts", "delete_verts\n20 - 10"), "runs backwards")

    scene_out = d / "SCENE_OUT.pc2"
    pkg_arg = ["--model", str(package)] if package else []

    def scene(name, text, words):
        p = d / f"{name}.toml"
        p.write_text(text)
        cases.append((f"scene/{name}", ["run", str(p), *pkg_arg, "-o", str(scene_out), "--no-cache"], words, scene_out))

    garment = ROOT / "samples" / "garments" / "skirt.obj"
    base = f'[garment]\nmesh = "{garment}"\n[motion]\nkind = "walk"\nseconds = 0.2\n[output]\npath = "{scene_out}"\n'
    scene("unknown_key", base + "[effects]\nsparkles = true\n", "unknown key effects.sparkles")
    scene("unknown_table", base + "[camera]\nfov = 40\n", "unknown table")
    scene("wrong_type", base + "[effects]\ncollisions = 1\n", "wrong type")
    scene(
        "missing_garment",
        base.split("[motion]")[0].replace("mesh", "file") + '[motion]\nkind = "walk"\n[output]\npath = "x.pc2"\n',
        "unknown key garment.file",
    )
    scene("invalid_toml", "[garment\nmesh = ", "invalid TOML")
    scene("file_and_kind", base.replace('kind = "walk"', 'kind = "walk"\nfile = "m.npz"'), "exactly one")
    scene("bad_format", base.replace(f'path = "{scene_out}"', 'path = "out.fbx"'), "output.format")
    scene("garment_missing_file", base.replace(str(garment), str(d / "nope.obj")), "nope.obj")
    scene("bad_skinning", base + '[effects]\nskinning = "quaternion"\n', "skinning must be")
    issue29_cases(d, cases, package, base)

    if package is not None:
        good_scene = d / "good_scene.toml"
        good_scene.write_text(base)

        def pkgcase(name, edit, words):
            p = d / f"pkg_{name}"
            shutil.copytree(package, p)
            edit(p)
            cases.append(
                (
                    f"package/{name}",
                    ["run", str(good_scene), "--model", str(p), "-o", str(scene_out), "--no-cache"],
                    words,
                    scene_out,
                )
            )

        def man(**kw):
            def edit(p):
                m = json.loads((p / "manifest.json").read_text())
                for k, v in kw.items():
                    if callable(v):
                        v(m)
                    else:
                        m[k] = v
                (p / "manifest.json").write_text(json.dumps(m))

            return edit

        pkgcase("no_manifest", lambda p: (p / "manifest.json").unlink(), "no manifest.json")
        pkgcase("manifest_not_json", lambda p: (p / "manifest.json").write_text("{,"), "not valid JSON")
        pkgcase("schema_99", man(schema_version=99), "schema version")
        pkgcase("graph_missing", lambda p: (p / "garment_encoder.onnx").unlink(), "file is missing")
        pkgcase("graph_corrupt", lambda p: (p / "deformer_lbs.onnx").write_bytes(b"\x08\x01junk"), "manifest hash")
        pkgcase(
            "manifest_disagrees_with_onnx",
            man(rename=lambda m: m["graphs"]["garment_encoder"]["inputs"][0].update(name="vertex_features")),
            "disagree with the manifest",
        )
        pkgcase("joint_count_mismatch", man(joint_names=["pelvis"]), "joint_names do not match")

    def usd(name, ext, data, words):
        p = d / f"{name}{ext}"
        p.write_bytes(data)
        cases.append((f"usd/{name}", ["inspect", str(p)], words, None))

    # OpenUSD's own errors ran over 2-4 lines of pxr internals (a new user's trial): one line now
    usd("garbage", ".usd", b"garbage\n", "not a readable USD file")
    usd("usdc_truncated", ".usdc", b"PXR-USDC" + b"\x00" * 16 + b"junk", "not a readable USD file")
    usd("usda_bad_syntax", ".usda", b'#usda 1.0\n(\n    doc = "x\n', "not a readable USD file")
    return [c for c in cases if c is not None]


def asf_amc_cases(d: Path, cases: list) -> None:
    """CMU's ASF/AMC through `motion export` (each case in a folder of its own, its skeleton the one .asf
    beside the .amc): ``amc/`` cases are the AMC's fault, ``asf/`` cases the skeleton's (the message names
    the .asf)."""
    from tests.motion.asf_build import amc_text, asf_text, cmu_bones, smooth_values

    good_asf, good_amc = asf_text(), amc_text(smooth_values(n_frames=3))
    out = d / "AMC_OUT.sgdm"

    def line_of(text, line):
        return text.splitlines().index(line) + 1

    def case(kind, name, asf, amc, words, extra=()):
        f = d / f"{kind}_{name}"
        f.mkdir(parents=True, exist_ok=True)
        if asf is not None:
            (f / f"{name}.asf").write_text(asf)
        (f / f"{name}.amc").write_text(amc)
        words = words.replace("FILE", f"{name}.{kind}")
        args = ["motion", "export", str(f / f"{name}.amc"), *extra, "-o", str(out)]
        cases.append((f"{kind}/{name}", args, words, out))

    def first_value(bone, value):
        lines = good_amc.splitlines()
        i = next(k for k, ln in enumerate(lines) if ln.startswith(bone + " "))
        lines[i] = " ".join([bone, value] + lines[i].split()[2:])
        return "\n".join(lines) + "\n", i + 1

    tail = good_amc.replace("\nlhumerus", "\ntail 1 2 3\nlhumerus", 1)
    case(
        "amc",
        "bone_not_in_asf",
        good_asf,
        tail,
        f"FILE:{line_of(tail, 'tail 1 2 3')}: bone 'tail' is not in the skeleton",
    )
    many = good_amc.replace("\nltibia ", "\nltibia 5 ", 1)
    case(
        "amc",
        "wrong_value_count",
        good_asf,
        many,
        f"FILE:{next(i for i, ln in enumerate(many.splitlines(), 1) if ln.startswith('ltibia'))}: "
        "wrong number of values for bone 'ltibia' (expected 1 (dof rx in wrong_value_count.asf), got 2)",
    )
    case(
        "amc",
        "frames_not_consecutive",
        good_asf,
        good_amc.replace("\n3\n", "\n5\n"),
        f"FILE:{line_of(good_amc, '3')}: frame numbers are not consecutive (expected frame 3, got frame 5)",
    )
    text, ln = first_value("lfemur", "nan")
    case("amc", "nan", good_asf, text, f"FILE:{ln}: bone 'lfemur' has a value that is not finite")
    text, ln = first_value("lfemur", "1_0")
    case("amc", "digit_separator", good_asf, text, f"FILE:{ln}: bone 'lfemur' has a value that is not a number")
    case("amc", "empty", good_asf, "", "FILE: AMC has no frames")
    case("amc", "skeleton_missing", None, good_amc, "FILE: cannot tell which skeleton this AMC uses")
    # a skeleton that does not fit the motion: its ltibia bends two ways
    other = asf_text([b if b[0] != "ltibia" else b[:5] + (("rx", "rz"),) for b in cmu_bones()])
    case(
        "amc",
        "skeleton_mismatch",
        other,
        good_amc,
        f"FILE:{next(i for i, ln in enumerate(good_amc.splitlines(), 1) if ln.startswith('ltibia'))}: wrong number "
        "of values for bone 'ltibia' (expected 2 (dof rx rz in skeleton_mismatch.asf), got 1)",
    )
    case(
        "asf",
        "skeleton_not_found",
        None,
        good_amc,
        "FILE: no such file",
        extra=("--skeleton", str(d / "asf_skeleton_not_found" / "skeleton_not_found.asf")),
    )
    loop = good_asf.replace("    root lhipjoint rhipjoint lowerback\n", "    root rhipjoint lowerback\n").replace(
        "    lfemur ltibia\n", "    lfemur ltibia\n    ltoes lhipjoint\n"
    )
    case(
        "asf",
        "hierarchy_cycle",
        loop,
        good_amc,
        f"FILE:{line_of(loop, '    lhipjoint lfemur')}: the hierarchy has a cycle (expected a tree under root, "
        "got lhipjoint -> lfemur -> ltibia -> lfoot -> ltoes -> lhipjoint)",
    )
    unknown = good_asf.replace("    lfemur ltibia", "    lfemur ltibia tail")
    case(
        "asf",
        "hierarchy_unknown_bone",
        unknown,
        good_amc,
        f"FILE:{line_of(unknown, '    lfemur ltibia tail')}: unknown bone 'tail' in the hierarchy",
    )
    case("asf", "empty", "", good_amc, "FILE: ASF is empty")
    case(
        "asf",
        "bad_units",
        good_asf.replace("length 0.45", "length 0"),
        good_amc,
        f"FILE:{line_of(good_asf, '  length 0.45')}: units length must be positive",
    )


def issue29_cases(d: Path, cases: list, package, base: str) -> None:
    """Issue 29's bad inputs that crashed or passed silently: runtime files (.sgdm/.sgda), .mhclo bindings, motion
    values past physical bounds, scenes, jobs files, and manifests (each must now give one line naming the file)."""
    from segadeform.motion import make_motion, write_motion_file

    def inspect(name, data, words, ext=".sgdm"):
        p = d / f"{name}{ext}"
        p.write_bytes(data)
        cases.append((f"runtime/{name}", ["inspect", str(p)], words, None))

    write_motion_file(d / "good.sgdm", make_motion("walk", seconds=0.2))
    good = (d / "good.sgdm").read_bytes()
    i, j = good.index(b"\nmeta ") + 1, good.index(b"\nEND\n")
    inspect("sgdm_meta_list", good[:i] + b"meta [1]" + good[j:], "bundle meta must be a JSON object")
    line = next(ln for ln in good.split(b"\n") if ln.startswith(b"trans "))
    t = line.split()
    inspect(
        "sgdm_shape_overflow",
        good.replace(line, b" ".join([*t[:3], b"4611686018427387904", b"4", *t[5:]])),
        "declares a size its shape does not have",
    )
    inspect("sgdm_truncated", good[:-64], "runs past the end of the file")
    # a crafted header (a C++ integrator's trial: out-of-bounds reads and a stack overflow in that runtime)
    inspect(
        "sgdm_negative_offset", good.replace(line, b" ".join([*t[:-2], b"-5000", t[-1]])), "negative size or offset"
    )
    inspect("sgdm_negative_dim", good.replace(line, b" ".join([*t[:3], b"-1", *t[4:]])), "negative size or offset")
    inspect("sgdm_deep_meta", good[:i] + b"meta " + b"[" * 200_000 + good[j:], "malformed bundle header")
    inspect("sgda_meta_list", good[:i] + b"meta [1]" + good[j:], "bundle meta must be a JSON object", ".sgda")

    mh_src = ROOT / "samples" / "garments" / "makehuman"
    lines = (mh_src / "skirt_short_f.mhclo").read_text().split("\n")
    k = next(n for n, ln in enumerate(lines) if ln.startswith("verts")) + 1
    fit_out = d / "FIT_OUT.obj"

    def mhclo(name, edited, words):
        p = d / f"{name}.mhclo"
        p.write_text("\n".join(edited))
        cases.append((f"mhclo/{name}", ["garment", "fit", str(p), "-o", str(fit_out)], words, fit_out))

    tok = lines[k].split()
    mhclo("weights_zero", lines[:k] + [" ".join(tok[:3] + ["0", "0", "0"] + tok[6:])] + lines[k + 1 :], "must sum to 1")
    mhclo(
        "negative_scale_index",
        [("x_scale -3 11998 1.3980" if ln.startswith("x_scale") else ln) for ln in lines],
        "negative base-mesh index",
    )
    mhclo(
        "negative_delete_index",
        [ln + ("\n-7" if ln.startswith("delete_verts") else "") for ln in lines],
        "negative base-mesh index",
    )

    def motion(name, ext, write, words):
        p = d / f"{name}{ext}"
        write(p)
        cases.append((f"motion/{name}", ["motion", "info", str(p)], words, None))

    motion("complex_poses", ".npz", lambda p: np.savez(p, poses=np.zeros((3, 72), complex) + 1j), "must be real")
    motion(
        "two_frame_rates",
        ".npz",
        lambda p: np.savez(p, poses=np.zeros((3, 72)), mocap_framerate=np.array([30.0, 60.0])),
        "one number",
    )
    from segadeform.body import default_rest_joints
    from segadeform.motion import write_bvh

    write_bvh(d / "bounds.bvh", make_motion("idle", seconds=0.2), default_rest_joints())
    bvh = (d / "bounds.bvh").read_text()
    head, rows = bvh.split("MOTION")
    rows = rows.strip().split("\n")
    motion(
        "bvh_frame_time_huge",
        ".bvh",
        lambda p: p.write_text(bvh.replace(rows[1], "Frame Time: 1e30")),
        "frame rate is outside",
    )
    motion(
        "bvh_root_far",
        ".bvh",
        lambda p: p.write_text(
            head + "MOTION\n" + "\n".join(rows[:2] + ["1e30 " + r.split(None, 1)[1] for r in rows[2:]]) + "\n"
        ),
        "root moves too far",
    )

    scene_out = d / "SCENE_OUT.pc2"
    pkg_arg = ["--model", str(package)] if package else []

    def scene(name, text, words):
        p = d / f"{name}.toml"
        p.write_text(text)
        cases.append((f"scene/{name}", ["run", str(p), *pkg_arg, "-o", str(scene_out), "--no-cache"], words, scene_out))

    scene("nan_betas", base + "[body]\nbetas = [nan]\n", "body.betas must be finite")
    scene("huge_betas", base + "[body]\nbetas = [1e300]\n", "body.betas out of range")
    scene("negative_seed", base.replace('kind = "walk"', 'kind = "walk"\nseed = -5'), "motion.seed out of range")
    scene("frames_past_end", base.replace('kind = "walk"', 'kind = "walk"\nframes = "3:100"'), "is outside the motion")
    scene("nested_deep", "a = " + "[" * 50000, "nests too deeply")
    jobs = d / "negative_seed_jobs.toml"
    jobs.write_text(
        f'[[garments]]\nmesh = "{ROOT / "samples" / "garments" / "skirt.obj"}"\n[[motions]]\nkind = "walk"\nseed = -5\n'
    )
    cases.append(
        ("batch/negative_seed", ["batch", str(jobs), "-o", str(d / "BATCH_OUT")], "seed out of range", d / "BATCH_OUT")
    )
    if package is not None and (Path(package) / "weights.bin").is_file():
        good_scene = d / "good_scene_29.toml"
        good_scene.write_text(base)
        for name, edit, words in (
            ("no_weights_entry", lambda m: m.pop("weights"), "no 'weights' entry"),
            ("manifest_nested_deep", None, "nests too deeply"),
        ):
            p = d / f"pkg_{name}"
            shutil.copytree(package, p)
            if edit is None:
                (p / "manifest.json").write_text("[" * 50000)
            else:
                m = json.loads((p / "manifest.json").read_text())
                edit(m)
                (p / "manifest.json").write_text(json.dumps(m))
            cases.append(
                (
                    f"package/{name}",
                    ["run", str(good_scene), "--model", str(p), "-o", str(scene_out), "--no-cache"],
                    words,
                    scene_out,
                )
            )


if __name__ == "__main__":
    target = Path(sys.argv[1] if len(sys.argv) > 1 else "malformed-corpus")
    print(len(build(target)), "files in", target)
