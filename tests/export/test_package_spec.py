"""The package contract (segadeform.contracts.model_package, docs/package.md): manifests against the JSON Schema, the
contract's I/O against the ONNX graphs, the effect -> graph rule, schema-1 packages, shared weights."""

from __future__ import annotations

import json
import shutil

import jsonschema  # the dev extra
import numpy as np
import onnx
import onnxruntime as ort
import pytest

from segadeform.contracts import model_package as contract
from segadeform.model import ModelConfig
from segadeform.runtime import ModelPackage, PackageError
from segadeform.settings import Effects
from tests.conftest import REPO, SAMPLES

SHIPPED = SAMPLES / "models" / "default"
SCHEMA = REPO / "docs" / "manifest.schema.json"
_ORT = {"tensor(float)": "float32", "tensor(int32)": "int32", "tensor(int64)": "int64", "tensor(bool)": "bool"}


def _validator():
    schema = json.loads(SCHEMA.read_text())
    jsonschema.Draft202012Validator.check_schema(schema)
    return jsonschema.Draft202012Validator(schema)


def _errors(manifest) -> list[str]:
    return [f"{list(e.path)}: {e.message}" for e in _validator().iter_errors(manifest)]


def test_schema_file_is_the_contracts():
    """docs/manifest.schema.json is generated; regenerate with ::

        python -c "from segadeform.contracts.model_package import write_manifest_schema as w; \
            w('docs/manifest.schema.json')"
    """
    assert json.loads(SCHEMA.read_text()) == contract.manifest_schema()


def test_shipped_manifest_is_valid():
    m = json.loads((SHIPPED / "manifest.json").read_text())
    assert _errors(m) == []
    contract.validate_manifest(m)
    assert m["schema_version"] == contract.SCHEMA_VERSION and "variants" not in m
    ModelPackage(SHIPPED)  # every file present and matching its hash


def test_fresh_export_is_valid_and_named_by_the_contract(random_model):
    net, path = random_model
    m = json.loads((path / "manifest.json").read_text())
    assert _errors(m) == []
    contract.validate_manifest(m)
    want = (
        {contract.deformer_name(e) for e in contract.effect_sets(net.cfg)}
        | {contract.ENCODER}
        | {contract.body_name(s) for s in contract.SKINNING}
    )
    assert set(m["graphs"]) == want and len(want) == 11
    assert m["default_deformer"] == contract.deformer_name(contract.default_effects(net.cfg)) == "deformer_lbs"
    files = [g["file"] for g in m["graphs"].values()]
    assert len(set(files)) == len(files) and all(f == f"{n}.onnx" for n, f in zip(m["graphs"], files, strict=True))
    assert sorted(p.name for p in path.iterdir()) == sorted(files + ["manifest.json", m["weights"]["file"]])


def test_contract_io_matches_the_onnx_graphs(random_model):
    """What the contract says each graph takes and returns is what onnxruntime sees in the files."""
    net, path = random_model
    m = json.loads((path / "manifest.json").read_text())
    from segadeform.body import default_body_path, load_body
    from segadeform.body.identity import body_label

    body = load_body(default_body_path())
    for name, entry in m["graphs"].items():
        if entry["role"] == "body":
            want = contract.body_spec(
                n_vertices=body.n_vertices,
                n_faces=len(body.faces),
                n_betas=body.n_betas,
                n_joints=body.n_joints,
                skinning=entry["skinning"],
                body=body_label(body),
            )
        else:
            want = (
                contract.encoder_spec(net.cfg)
                if name == contract.ENCODER
                else contract.deformer_spec(net.cfg, entry["effects"])
            )
        assert {k: entry[k] for k in want} == dict(want, file=entry["file"]), name
        sess = ort.InferenceSession(str(path / entry["file"]), providers=["CPUExecutionProvider"])
        for got, spec in ((sess.get_inputs(), want["inputs"]), (sess.get_outputs(), want["outputs"])):
            assert [g.name for g in got] == [s["name"] for s in spec], name
            for g, s in zip(got, spec, strict=True):
                assert _ORT[g.type] == s["dtype"] and len(g.shape) == len(s["shape"]), (name, g.name)
                for gd, sd in zip(g.shape, s["shape"], strict=True):
                    assert gd == sd if isinstance(sd, int) else isinstance(gd, str), (name, g.name, g.shape)


def test_runtimes_can_feed_every_input_the_contract_names():
    cfg = ModelConfig(weights="residual")
    assert {i["name"] for i in contract.encoder_spec(cfg)["inputs"]} <= set(contract.FEEDS["encoder"])
    code = contract.encoder_spec(cfg)["outputs"][0]["name"]
    assert {i["name"] for i in contract.deformer_spec(cfg)["inputs"]} <= set(contract.FEEDS["deformer"]) | {code}
    assert set(contract.FEEDS["encoder"]) | set(contract.FEEDS["deformer"]) <= set(contract.INPUTS)


def test_shipped_graphs_take_only_what_the_contract_describes():
    """The shipped graphs: manifest I/O = the files' I/O, every name one the contract documents."""
    m = contract.read_manifest_text((SHIPPED / "manifest.json").read_text())
    for name, entry in m["graphs"].items():
        documented = set(contract.BODY_INPUTS if entry["role"] == "body" else contract.INPUTS)
        sess = ort.InferenceSession(str(SHIPPED / entry["file"]), providers=["CPUExecutionProvider"])
        assert [i.name for i in sess.get_inputs()] == [i["name"] for i in entry["inputs"]]
        assert [o.name for o in sess.get_outputs()] == [o["name"] for o in entry["outputs"]]
        assert [_ORT[i.type] for i in sess.get_inputs()] == [i["dtype"] for i in entry["inputs"]], name
        assert {i["name"] for i in entry["inputs"]} <= documented, name
        assert {i["dtype"] for i in entry["inputs"]} <= {"float32", "int32"}, name  # schema 3: WebGPU's dtypes
    assert contract.code_name(m) == "g"  # the factored encoder (older packages: P)


def test_docs_describe_every_name_and_key():
    doc = (REPO / "docs" / "package.md").read_text()
    for name in (
        list(contract.INPUTS)
        + list(contract.OUTPUTS)
        + list(contract.BODY_INPUTS)
        + list(contract.BODY_OUTPUTS)
        + ["P", "body_lbs", "body_dqs"]
    ):
        assert f"`{name}`" in doc, name
    for key in contract.manifest_schema()["properties"]:
        if key != "upgraded_from":
            assert f"`{key}`" in doc, key
    for key in ("role", "file", "sha256", "inputs", "effects", "window", "skinning", "body"):
        assert f".{key}`" in doc, key


# ---- effects -> graph -------------------------------------------------------------------------------
def test_select_deformer_is_an_exact_match(random_package):
    pkg = ModelPackage(random_package)
    for skin in contract.SKINNING:
        for wrinkles in (True, False):
            for dynamics in (True, False):
                e = Effects(skinning=skin, wrinkles=wrinkles, dynamics=dynamics)
                name = pkg.variant_for(e)
                assert name == contract.deformer_name(e) and pkg.spec(name)["effects"] == contract.effects_of(e)
                assert pkg.spec(name)["window"] == (pkg.config["window"] if dynamics else 1)
    assert pkg.spec("deformer") is pkg.spec("deformer_lbs")  # "deformer": the default deformer
    no_blend = {k: v for k, v in pkg.manifest.items()}
    no_blend["graphs"] = {k: v for k, v in pkg.manifest["graphs"].items() if "nowrinkles" in k or k == contract.ENCODER}
    with pytest.raises(PackageError, match="no deformer for these effects.*deformer_dqs_nowrinkles"):
        contract.select_deformer(no_blend, Effects(wrinkles=True))
    # a package of the model's own deformer alone (`export --no-variants`) says how to get the others
    own = dict(
        pkg.manifest,
        graphs={k: v for k, v in pkg.manifest["graphs"].items() if k in ("deformer_lbs", contract.ENCODER)},
    )
    with pytest.raises(PackageError, match="model's own alone: `segadeform export` without --no-variants"):
        contract.select_deformer(own, Effects(skinning="dqs"))
    with pytest.raises(PackageError) as e:
        contract.select_deformer(no_blend, Effects(wrinkles=True))
    assert "--no-variants" not in str(e.value)


def test_export_of_a_model_without_blend_shapes_has_no_wrinkle_graphs():
    cfg = ModelConfig(use_blend_shapes=False, skinning="dqs")
    names = [contract.deformer_name(e) for e in contract.effect_sets(cfg)]
    assert names[0] == "deformer_dqs_nowrinkles"  # the model's own first
    assert sorted(names) == [
        "deformer_dqs_nowrinkles",
        "deformer_dqs_nowrinkles_static",
        "deformer_lbs_nowrinkles",
        "deformer_lbs_nowrinkles_static",
    ]


@pytest.mark.parametrize(
    "edit, words, schema_sees",
    [
        (
            lambda m: m["graphs"]["deformer_lbs"].update(
                effects={"skinning": "lbs", "wrinkles": True, "dynamics": False}
            ),
            "not named by its effects",
            False,
        ),
        (lambda m: m["graphs"]["deformer_lbs"].update(window=3), "window does not match", False),
        (lambda m: m["graphs"]["deformer_lbs"].update(file="../x.onnx"), "file name in the package folder", True),
        (lambda m: m["graphs"]["deformer_lbs"]["inputs"][0].update(dtype="float16"), "unknown dtype", True),
        (lambda m: m["graphs"]["garment_encoder"].update(role="deformer"), "wrong role", True),
        (lambda m: m.pop("default_deformer"), "no 'default_deformer'", True),
        (lambda m: m.update(format="onnx-bundle"), "not a segadeform model package", True),
        (lambda m: m["graphs"]["deformer_lbs"]["inputs"][4].update(dtype="int64"), "schema 3 does not allow", False),
        (lambda m: m["graphs"]["garment_encoder"]["inputs"][2].update(dtype="bool"), "mask bool", False),
        (lambda m: m["graphs"]["body_lbs"].update(skinning="dqs"), "not named by its skinning", False),
        (lambda m: m["graphs"]["body_dqs"]["inputs"][1].update(shape=["B", 22, 3]), "another skeleton", False),
        (lambda m: m["graphs"]["body_lbs"].update(role="deformer"), "wrong role", True),
    ],
)
def test_malformed_manifests_are_refused(random_package, edit, words, schema_sees):
    """The runtime's checks refuse what the JSON Schema refuses, and the rules a schema cannot state."""
    m = json.loads((random_package / "manifest.json").read_text())
    edit(m)
    with pytest.raises(PackageError, match=words):
        contract.validate_manifest(m)
    assert bool(_errors(m)) == schema_sees


# ---- schemas 1 and 2 ---------------------------------------------------------------------------------
def _as_schema_1(src, dst):
    """``src`` rewritten as the exporter wrote packages before schema 2: the model's own deformer as
    ``deformer.onnx``, listed in ``graphs`` and again in ``variants``, every graph self-contained, int64/bool
    inputs, no body graphs (:mod:`tests.export.legacy`)."""
    from tests.export.legacy import as_schema

    return as_schema(src, dst, 1)


def contract_sha(path):
    from segadeform.io.hashing import file_sha256

    return file_sha256(path)


def _outputs(pkg_path, seed=0):
    """Every deformer's outputs and the encoder's on one random garment, by graph name."""
    from segadeform.body import default_body_path, load_body
    from segadeform.export.body import body_sample_inputs
    from segadeform.export.package import sample_inputs

    pkg = ModelPackage(pkg_path)
    cfg = ModelConfig.from_dict(pkg.config)
    out = {}
    for name, g in pkg.manifest["graphs"].items():
        if g["role"] == "body":
            out[name] = pkg.run(name, body_sample_inputs(load_body(default_body_path()), b=2, seed=seed))
            continue
        gcfg = cfg.replace(window=g["window"]) if name != contract.ENCODER else cfg
        out[name] = pkg.run(name, sample_inputs(gcfg, name, n=50, k=6, b=3, seed=seed))
    return out


def test_schema_1_packages_still_load_and_repack_to_the_same_outputs(tmp_path, random_package):
    from segadeform.export.packing import repack_package

    old = _as_schema_1(random_package, tmp_path / "v1")
    pkg = ModelPackage(old)
    assert pkg.manifest["upgraded_from"] == 1 and pkg.default_deformer == "deformer_lbs"
    assert pkg.spec("deformer_lbs")["file"] == "deformer.onnx" and len(pkg.manifest["graphs"]) == 9
    assert _errors({k: v for k, v in pkg.manifest.items()}) == []  # the upgraded form is a valid schema-3 manifest
    assert pkg.spec("garment_encoder")["inputs"][1]["dtype"] == "int64"  # fed as the graphs take them
    ref = _outputs(random_package)
    for name, got in _outputs(old).items():
        assert all(a.tobytes() == b.tobytes() for a, b in zip(ref[name], got, strict=True)), name
    new = repack_package(old, tmp_path / "v3")
    assert new["schema_version"] == 3 and "upgraded_from" not in new and _errors(new) == []
    contract.validate_manifest(new)  # int32 and float32 inputs again
    assert not (tmp_path / "v3" / "deformer.onnx").exists() and (tmp_path / "v3" / "deformer_lbs.onnx").is_file()
    for name, got in _outputs(tmp_path / "v3").items():
        assert all(a.tobytes() == b.tobytes() for a, b in zip(ref[name], got, strict=True)), name


def test_schema_2_packages_still_load_and_repack_to_schema_3(tmp_path, random_package):
    """Schema 2 (int64 nbr, bool mask, no body graphs): read as schema 3 with its graphs' dtypes, fed as they
    say; repack retypes the inputs (a Cast inside) and the outputs stay bit-identical."""
    from segadeform.export.packing import repack_package
    from segadeform.export.portability import PortabilityError, check_portability
    from tests.export.legacy import as_schema

    old = as_schema(random_package, tmp_path / "v2", 2)
    pkg = ModelPackage(old)
    assert pkg.manifest["upgraded_from"] == 2 and pkg.manifest["schema_version"] == 3 and _errors(pkg.manifest) == []
    assert {i["name"]: i["dtype"] for i in pkg.spec("deformer_lbs")["inputs"]}["mask"] == "bool"
    assert contract.select_body(pkg.manifest, "lbs") is None  # no body graph before schema 3
    with pytest.raises(PortabilityError, match="nbr int64, mask bool"):
        check_portability(onnx.load(str(old / "garment_encoder.onnx")), "encoder")
    ref = _outputs(random_package)
    for name, got in _outputs(old).items():
        assert all(a.tobytes() == b.tobytes() for a, b in zip(ref[name], got, strict=True)), name
    new = repack_package(old, tmp_path / "v3")
    assert new["schema_version"] == 3 and _errors(new) == []
    for name, g in new["graphs"].items():
        check_portability(onnx.load(str(tmp_path / "v3" / g["file"])), name)
        assert {i["dtype"] for i in g["inputs"]} <= {"float32", "int32"}
    for name, got in _outputs(tmp_path / "v3").items():
        assert all(a.tobytes() == b.tobytes() for a, b in zip(ref[name], got, strict=True)), name


def test_repack_to_opset_15_for_engines_keeps_the_outputs(tmp_path, random_package):
    """``repack --opset 15`` (Unity Sentis reads opsets 7-15): every graph declares 15 and computes the same."""
    import onnx

    from segadeform.cli.main import main

    assert main(["repack", str(random_package), "-o", str(tmp_path / "o15"), "--opset", "15"]) == 0
    pkg = ModelPackage(tmp_path / "o15")
    assert pkg.manifest["opset"] == 15 and _errors(pkg.manifest) == [] and "body_lbs" in pkg.manifest["graphs"]
    for g in pkg.manifest["graphs"].values():
        m = onnx.load(str(tmp_path / "o15" / g["file"]), load_external_data=False)
        assert [o.version for o in m.opset_import if o.domain in ("", "ai.onnx")] == [15], g["file"]
    ref = _outputs(random_package)
    for name, got in _outputs(tmp_path / "o15").items():
        for a, b in zip(ref[name], got, strict=True):
            np.testing.assert_allclose(b, a, rtol=1e-6, atol=1e-6, err_msg=name)
    assert main(["repack", str(random_package), "-o", str(tmp_path / "o11"), "--opset", "11"]) != 0  # no converter
    assert not (tmp_path / "o11").exists()


# ---- shared weights ---------------------------------------------------------------------------------
def test_shared_weights_are_stored_once_and_change_nothing(tmp_path, random_package):
    from segadeform.export.packing import repack_package

    inline = tmp_path / "inline"
    m = repack_package(random_package, inline, shared=False)
    assert "weights" not in m and not (inline / "weights.bin").exists() and _errors(m) == []
    ref = _outputs(random_package, seed=4)
    for name, got in _outputs(inline, seed=4).items():
        assert all(a.tobytes() == b.tobytes() for a, b in zip(ref[name], got, strict=True)), name

    def size(p):
        return sum(f.stat().st_size for f in p.iterdir() if f.suffix in (".onnx", ".bin"))

    assert size(random_package) < 0.6 * size(inline)
    # every large initializer of every graph lives in weights.bin; no graph carries debug metadata
    shared = json.loads((random_package / "manifest.json").read_text())
    for g in shared["graphs"].values():
        proto = onnx.load(str(random_package / g["file"]), load_external_data=False)
        assert not any(n.metadata_props for n in proto.graph.node)
        for t in proto.graph.initializer:
            if t.data_location != onnx.TensorProto.EXTERNAL:
                assert len(t.raw_data) + 4 * len(t.float_data) + 8 * len(t.int64_data) < 256, t.name
            else:
                assert {e.key: e.value for e in t.external_data}["location"] == "weights.bin"
    # a copy without weights.bin cannot run: the graphs really read it
    broken = tmp_path / "broken"
    shutil.copytree(random_package, broken)
    (broken / "weights.bin").unlink()
    with pytest.raises(PackageError, match="weights file is missing"):
        ModelPackage(broken)


def test_pack_graphs_offsets_are_aligned(random_package):
    from segadeform.export.packing import ALIGN

    seen = set()
    for f in random_package.glob("*.onnx"):
        for t in onnx.load(str(f), load_external_data=False).graph.initializer:
            if t.data_location == onnx.TensorProto.EXTERNAL:
                e = {x.key: int(x.value) for x in t.external_data if x.key in ("offset", "length")}
                assert e["offset"] % ALIGN == 0
                seen.add((e["offset"], e["length"]))
    total = (random_package / "weights.bin").stat().st_size
    assert sum(n for _, n in seen) <= total < sum(n for _, n in seen) + ALIGN * len(seen)
