"""torch -> ONNX export of the SEGA network as a *model package* (extra ``torch``):

    PACKAGE_DIR/manifest.json            schema, opset, I/O signature, ModelConfig, joints, units
    PACKAGE_DIR/garment_encoder.onnx     once per garment
    PACKAGE_DIR/deformer_<effects>.onnx  per frame, batched over frames: one per effect combination
    PACKAGE_DIR/weights.bin              the weights, one copy shared by every graph

``segadeform.contracts.model_package`` is the contract (names, I/O, manifest keys; ``docs/package.md``); the
packing (:mod:`.packing`) and portability check need only ``onnx``; the export itself needs torch,
onnx and onnxscript.
"""

from .package import MANIFEST_SCHEMA_VERSION, OPSET, export_package, graph_specs
from .packing import pack_graphs, repack_package
from .portability import ALLOWED_OPS, FORBIDDEN_OPS, PortabilityError, check_portability

__all__ = [
    "export_package",
    "repack_package",
    "pack_graphs",
    "graph_specs",
    "MANIFEST_SCHEMA_VERSION",
    "OPSET",
    "check_portability",
    "PortabilityError",
    "ALLOWED_OPS",
    "FORBIDDEN_OPS",
]
