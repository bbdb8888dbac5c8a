"""Coverage-guided fuzzing (atheris, libFuzzer) of the file readers.

    python tests/fuzz/fuzz_readers.py TARGET [libFuzzer options] [CORPUS_DIR ...]

TARGET is one of obj, off, pc2, bvh, toml, npz, mhclo, motion (AMASS-style .npz), amc (an ASF skeleton, a line
``%%``, then an AMC motion: CMU's format), sgda (a garment asset), sgdm (a motion file), batch (a jobs file),
manifest (a model package's manifest.json, through ModelPackage), bvhbody (a BVH mapped by the skeleton rules and
retargeted onto the default body's joints).  Every input is written to a file and read with the package's reader;
a reader may only fail with :class:`segadeform.errors.SegadeformError` (a clear error).  Anything else
-- IndexError, struct.error, RecursionError, a NaN slipping through -- is a
crash and libFuzzer stops with the input saved as ``crash-*``.

A short run is part of the test suite (``tests/fuzz/test_fuzz.py``); a
longer run, e.g. ten minutes per target::

    python tests/fuzz/fuzz_readers.py obj -max_total_time=600 -rss_limit_mb=4096 fuzz-corpus/obj

Seed corpora come from ``python tests/fuzz/fuzz_readers.py --seeds DIR``.
"""

from __future__ import annotations

import sys
import tempfile
from pathlib import Path

import numpy as np

TARGETS = (
    "obj",
    "off",
    "pc2",
    "bvh",
    "toml",
    "npz",
    "mhclo",
    "motion",
    "amc",
    "sgda",
    "sgdm",
    "batch",
    "manifest",
    "bvhbody",
)
_TMP = Path(tempfile.mkdtemp(prefix="segadeform-fuzz-"))


def _check_finite(*arrays):
    for a in arrays:
        a = np.asarray(a)
        if a.dtype.kind == "f" and not np.isfinite(a).all():
            raise AssertionError("a reader returned NaN or inf")


def make_target(name: str):
    from segadeform.errors import SegadeformError

    if name == "obj":
        from segadeform.io import read_obj

        def read(p):
            m = read_obj(p)
            _check_finite(m.vertices)
            assert m.faces.min() >= 0 and m.faces.max() < m.n_vertices
    elif name == "off":
        from segadeform.io import read_off

        def read(p):
            m = read_off(p)
            _check_finite(m.vertices)
            assert m.faces.max() < m.n_vertices
    elif name == "pc2":
        from segadeform.io import read_pc2

        def read(p):
            pc = read_pc2(p, check_finite=True)
            _check_finite(pc.frames)
    elif name == "bvh":
        from segadeform.motion import read_bvh

        def read(p):
            m = read_bvh(p)
            _check_finite(m.poses, m.trans)
    elif name == "toml":
        from segadeform.settings import load_scene

        def read(p):
            load_scene(p)
    elif name == "npz":
        from segadeform.body import load_body

        def read(p):
            load_body(p)
    elif name == "mhclo":
        from segadeform.io.mhclo import read_mhclo

        def read(p):
            b = read_mhclo(p)
            _check_finite(b.weights, b.offsets)
            assert b.verts.min() >= 0
    elif name == "motion":
        from segadeform.motion import load_motion_npz

        def read(p):
            m = load_motion_npz(p)
            _check_finite(m.poses, m.trans)
    elif name == "amc":
        from segadeform.motion.asf import read_amc

        def read(p):
            skeleton, _, motion = p.read_bytes().partition(b"\n%%\n")
            p.with_suffix(".asf").write_bytes(skeleton)
            p.write_bytes(motion)
            m = read_amc(p, p.with_suffix(".asf"))
            _check_finite(m.poses, m.trans)
    elif name == "sgda":
        from segadeform.geometry import GarmentAsset

        def read(p):
            a = GarmentAsset.load(p)
            _check_finite(a.vertices, a.descriptor, *(x for x in (a.betas, a.log_wbody) if x is not None))
            assert a.faces.min() >= 0 and a.faces.max() < a.n_vertices
            assert a.nbr.min() >= 0 and a.nbr.max() < a.n_vertices
    elif name == "sgdm":
        from segadeform.motion import read_motion_file

        def read(p):
            m, meta = read_motion_file(p)
            _check_finite(m.poses, m.trans)
            assert isinstance(meta, dict)
    elif name == "batch":
        from segadeform.runtime.batch import load_batch

        def read(p):
            cfg = load_batch(p)
            assert cfg.garments and cfg.motions
    elif name == "manifest":
        from segadeform.runtime.package import ModelPackage

        def read(p):
            ModelPackage(p.parent, verify_hashes=True)
    elif name == "bvhbody":
        from segadeform.body import default_rest_joints
        from segadeform.motion import load_motion

        joints = default_rest_joints()

        def read(p):
            m = load_motion(p, rest_joints=joints)
            _check_finite(m.poses, m.trans)
    else:
        raise SystemExit(f"unknown target {name!r}; expected one of {', '.join(TARGETS)}")
    path = _TMP / {
        "motion": "input.npz",
        "manifest": "pkg/manifest.json",
        "bvhbody": "input.bvh",
        "batch": "jobs.toml",
    }.get(name, f"input.{name}")
    path.parent.mkdir(parents=True, exist_ok=True)

    def one_input(data: bytes) -> None:
        path.write_bytes(data)
        try:
            read(path)
        except SegadeformError:
            pass

    return one_input


def write_seeds(d: Path) -> None:
    """Valid example files per target, to start the fuzzer from."""
    from segadeform.body import default_rest_joints
    from segadeform.io import write_pc2
    from segadeform.motion import make_motion, write_bvh

    root = Path(__file__).resolve().parents[2]
    for t in TARGETS:
        (d / t).mkdir(parents=True, exist_ok=True)
    (d / "obj" / "quad.obj").write_text(
        "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nvt 0 0\nvn 0 0 1\nf 1/1/1 2/1/1 3/1/1 -1/1/1\n"
    )
    (d / "obj" / "skirt_head.obj").write_text(
        "\n".join((root / "samples/garments/skirt.obj").read_text().splitlines()[:200])
    )
    (d / "off" / "quad.off").write_text("OFF\n4 1 0\n0 0 0\n1 0 0\n1 1 0\n0 1 0\n4 0 1 2 3\n")
    write_pc2(d / "pc2" / "small.pc2", np.random.default_rng(0).normal(size=(3, 5, 3)))
    write_bvh(d / "bvh" / "idle.bvh", make_motion("idle", seconds=0.1), default_rest_joints())
    for f in ("07_03_walk", "02_01_walk"):
        head, motion = (root / "samples/motions/cmu" / f"{f}.bvh").read_text().split("MOTION")
        first = [ln for ln in motion.splitlines() if ln.strip() and ln.strip()[0] in "-0123456789"][:2]
        (d / "bvh" / f"cmu_{f}.bvh").write_text(head + "MOTION\nFrames: 2\nFrame Time: 0.1\n" + "\n".join(first) + "\n")
    mh = (root / "samples/garments/makehuman/skirt_short_f.mhclo").read_text().splitlines()
    (d / "mhclo" / "skirt_head.mhclo").write_text("\n".join(mh[:60] + [ln for ln in mh if "delete_verts" in ln]))
    make_motion("walk", seconds=0.1).save(d / "motion" / "walk.npz")
    (d / "toml" / "scene.toml").write_text((root / "samples/scenes/skirt_walk.toml").read_text())
    from tests.body.conftest import toy_body

    toy_body(n_betas=2).save(d / "npz" / "toy_body.npz")
    from tests.motion.asf_build import amc_text, asf_text, smooth_values

    (d / "amc" / "cmu_like.asfamc").write_text(asf_text() + "%%\n" + amc_text(smooth_values(n_frames=2)))
    (d / "amc" / "radians.asfamc").write_text(
        asf_text(angle="rad", limits=False) + "%%\n" + amc_text(smooth_values(n_frames=1), header=(":RADIANS",))
    )
    _write_portable_seeds(d, root)


def _write_portable_seeds(d: Path, root: Path) -> None:
    """Seeds of the runtimes' files (.sgda, .sgdm), jobs files, manifests and BVH for the body (issue 29)."""
    import json
    import shutil

    from segadeform.body import load_body
    from segadeform.body.identity import body_label
    from segadeform.geometry import precompute_garment
    from segadeform.motion import make_motion, write_motion_file

    body = load_body(root / "samples/bodies/default_body.npz")
    u, w = np.meshgrid(np.linspace(0, 2 * np.pi, 9)[:-1], np.linspace(0.9, 1.1, 3))
    v = np.stack([0.2 * np.cos(u), w, 0.2 * np.sin(u)], -1).reshape(-1, 3)
    f = np.array(
        [[r * 8 + c, r * 8 + (c + 1) % 8, (r + 1) * 8 + c] for r in range(2) for c in range(8)]
        + [[r * 8 + (c + 1) % 8, (r + 1) * 8 + (c + 1) % 8, (r + 1) * 8 + c] for r in range(2) for c in range(8)]
    )
    a = precompute_garment(v, f, body.rest_joints()[0], n_star=4)
    a.save(d / "sgda" / "tube.sgda")
    from segadeform.body.prepare import prepare_for_body

    prepare_for_body(a, body, (0.3,)).save(d / "sgda" / "tube_for_body.sgda")
    m = make_motion("walk", seconds=0.1)
    write_motion_file(d / "sgdm" / "walk.sgdm", m, body=body_label(body), betas=[0.0] * body.n_betas, source="walk")
    write_motion_file(d / "sgdm" / "bare.sgdm", m)
    (d / "batch" / "jobs.toml").write_text(
        '[batch]\noutput = "out"\nformat = "pc2"\neffects = "dqs,collisions"\nup = "y"\nframes_per_call = 4\n'
        '[[garments]]\nmesh = "skirt.obj"\nname = "skirt"\nbetas = [0.0, 0.5]\n'
        '[[motions]]\nfile = "walk.npz"\nfps = 30.0\nframes = "0:6"\n[[motions]]\nkind = "dance"\nseconds = 0.5\n'
        "seed = 2\n"
    )
    man = json.loads((root / "samples/models/default/manifest.json").read_text())
    man.pop("training_garments", None)  # (large; the rest of the manifest's structure stays)
    (d / "manifest" / "manifest.json").write_text(json.dumps(man))
    for src in (d / "bvh").iterdir():
        shutil.copy(src, d / "bvhbody" / src.name)


def main() -> None:
    if len(sys.argv) >= 3 and sys.argv[1] == "--seeds":
        write_seeds(Path(sys.argv[2]))
        return
    if len(sys.argv) < 2 or sys.argv[1] not in TARGETS:
        raise SystemExit(__doc__)
    import atheris

    target = sys.argv.pop(1)
    with atheris.instrument_imports(include=["segadeform"]):
        fn = make_target(target)
    atheris.Setup(sys.argv, fn)
    atheris.Fuzz()


if __name__ == "__main__":
    sys.path.insert(0, str(Path(__file__).resolve().parents[2]))
    main()
