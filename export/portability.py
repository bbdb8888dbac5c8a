"""Which ONNX ops an exported graph may use, so the same file runs in onnxruntime (CPU, CUDA),
onnxruntime-web (wasm, WebGPU), Unity Sentis and Unreal NNE.

The allowed set is the intersection we rely on (see ``../shared/notes/facts.md``
"Engines"): elementwise maths, MatMul/Gemm, Gather, reductions, shape ops,
Where, Softmax, ArgMax/OneHot; and no node reads and writes more than ``MAX_NODE_TENSORS`` (8) tensors,
WebGPU's default storage buffers per shader stage.  Forbidden, with the reason:
"""

from __future__ import annotations

from collections import Counter

from segadeform.errors import SegadeformError
from segadeform.package_spec import MAX_NODE_TENSORS

__all__ = ["ALLOWED_OPS", "FORBIDDEN_OPS", "PortabilityError", "iter_graphs", "iter_nodes", "op_counts",
           "check_portability"]

FORBIDDEN_OPS = {
    "Einsum": "limited in Unity Sentis; write MatMul",
    "NonZero": "data-dependent output shape; CPU-only in Sentis",
    "ScatterElements": "scatter with reduction is missing or slow on GPU engines; use padded Gather",
    "ScatterND": "scatter with reduction is missing or slow on GPU engines; use padded Gather",
    "LSTM": "no LSTM on Sentis' GPU backends nor onnxruntime-web WebGPU; unroll it",
    "GRU": "unsupported in Sentis", "RNN": "unsupported in Sentis",
    "Loop": "unsupported in Sentis", "Scan": "unsupported in Sentis", "If": "control flow; not portable",
    "Unique": "data-dependent output shape", "SequenceConstruct": "sequence types are not portable",
}
ALLOWED_OPS = frozenset("""
Abs Add And ArgMax Cast Ceil Clip Concat Constant ConstantOfShape Cos Div Elu Equal Erf Exp Expand
Flatten Floor Gather Gemm Greater GreaterOrEqual Identity LeakyRelu Less LessOrEqual Log MatMul Max
Min Mul Neg Not OneHot Or Pow Range Reciprocal ReduceL2 ReduceMax ReduceMean ReduceMin ReduceSum Relu
Reshape Shape Sigmoid Sign Sin Slice Softmax Split Sqrt Squeeze Sub Tanh Tile Transpose Unsqueeze Where
""".split())


class PortabilityError(SegadeformError):
    """An exported graph uses an op outside :data:`ALLOWED_OPS`."""


def iter_graphs(model):
    """Every graph of an ``onnx.ModelProto``: the main graph and, depth first, the subgraphs of its nodes'
    attributes (If/Loop/Scan bodies)."""

    def walk(graph):
        yield graph
        for node in graph.node:
            for attr in node.attribute:
                if attr.HasField("g"):
                    yield from walk(attr.g)
                for g in attr.graphs:
                    yield from walk(g)

    yield from walk(model.graph)


def iter_nodes(model):
    """Every node of an ``onnx.ModelProto``: those of :func:`iter_graphs` and of its local functions."""
    for graph in iter_graphs(model):
        yield from graph.node
    for fn in model.functions:
        yield from fn.node


def op_counts(model) -> Counter:
    """Op types used by an ``onnx.ModelProto`` (including subgraphs and local functions)."""
    return Counter(node.op_type for node in iter_nodes(model))


def check_portability(model, name: str = "graph") -> Counter:
    """Raise :class:`PortabilityError` listing every op outside the allowed set; return the op counts."""
    counts = op_counts(model)
    bad = sorted(op for op in counts if op not in ALLOWED_OPS)
    if bad:
        why = "; ".join(f"{op}: {FORBIDDEN_OPS.get(op, 'not in the portable op set')}" for op in bad)
        raise PortabilityError(f"{name} uses non-portable ops: {why}")
    wide = sorted({(n.op_type, len(n.input) + len(n.output)) for n in iter_nodes(model)
                   if len(n.input) + len(n.output) > MAX_NODE_TENSORS})
    if wide:
        raise PortabilityError(f"{name} has nodes reading and writing more than {MAX_NODE_TENSORS} tensors (WebGPU's "
                               f"default storage buffers per shader): "
                               + ", ".join(f"{op} with {k}" for op, k in wide))
    return counts
