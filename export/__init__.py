"""torch -> ONNX export of the SEGA network as a *model package* (extra ``torch``):

    PACKAGE_DIR/garment_encoder.onnx   once per garment and body shape
    PACKAGE_DIR/deformer.onnx          per frame, batched over frames
    PACKAGE_DIR/manifest.json          schema, opset, I/O signature, ModelConfig, joints, units

The manifest and the portability check need only ``onnx``-free Python; the
export itself needs torch, onnx and onnxscript.
"""

from .package import MANIFEST_SCHEMA_VERSION, OPSET, export_package, graph_specs
from .portability import ALLOWED_OPS, FORBIDDEN_OPS, PortabilityError, check_portability

__all__ = ["export_package", "graph_specs", "MANIFEST_SCHEMA_VERSION", "OPSET", "check_portability",
           "PortabilityError", "ALLOWED_OPS", "FORBIDDEN_OPS"]
