"""Which ONNX ops an exported graph may use, so the same file runs in onnxruntime (CPU, CUDA),
onnxruntime-web (wasm, WebGPU), Unity Sentis and Unreal NNE.

The allowed set is the intersection we rely on (see ``../shared/notes/facts.md``
"Engines"): elementwise maths, MatMul/Gemm, Gather, reductions, shape ops,
Where, Softmax, ArgMax/OneHot; no node reads and writes more than ``MAX_NODE_TENSORS`` (8) tensors,
WebGPU's default storage buffers per shader stage; and graph inputs are float32 or int32 only
(``PORTABLE_INPUT_DTYPES``: WebGPU has no 64-bit integers, onnxruntime-web emulating them or falling back to
the CPU, and engines such as Unity Sentis take float and int32 tensors from the host; inside a graph the
engines convert what they need).  :func:`make_inputs_portable` rewrites
an older graph's int64 and bool inputs as int32 and float32 read through a Cast, computing the same.
Forbidden ops, with the reason:
"""

from __future__ import annotations

from collections import Counter

from segadeform.contracts.model_package import MAX_NODE_TENSORS, PORTABLE_INPUT_DTYPES
from segadeform.errors import SegadeformError

__all__ = [
    "ALLOWED_OPS",
    "FORBIDDEN_OPS",
    "PortabilityError",
    "iter_graphs",
    "iter_nodes",
    "op_counts",
    "check_portability",
    "input_dtypes",
    "make_inputs_portable",
    "replace_trig",
]

#: ONNX TensorProto element types by name (the manifest's dtype names)
_ELEM = {1: "float32", 6: "int32", 7: "int64", 9: "bool", 10: "float16", 11: "float64"}

FORBIDDEN_OPS = {
    "Einsum": "limited in Unity Sentis; write MatMul",
    "NonZero": "data-dependent output shape; CPU-only in Sentis",
    "ScatterElements": "scatter with reduction is missing or slow on GPU engines; use padded Gather",
    "ScatterND": "scatter with reduction is missing or slow on GPU engines; use padded Gather",
    "LSTM": "no LSTM on Sentis' GPU backends nor onnxruntime-web WebGPU; unroll it",
    "GRU": "unsupported in Sentis",
    "RNN": "unsupported in Sentis",
    "Loop": "unsupported in Sentis",
    "Scan": "unsupported in Sentis",
    "If": "control flow; not portable",
    "Unique": "data-dependent output shape",
    "SequenceConstruct": "sequence types are not portable",
}
ALLOWED_OPS = frozenset(
    """
Abs Add And ArgMax Cast Ceil Clip Concat Constant ConstantOfShape Cos Div Elu Equal Erf Exp Expand
Flatten Floor Gather Gemm Greater GreaterOrEqual Identity LeakyRelu Less LessOrEqual Log MatMul Max
Min Mul Neg Not OneHot Or Pow Range Reciprocal ReduceL2 ReduceMax ReduceMean ReduceMin ReduceSum Relu
Reshape Shape Sigmoid Sign Sin Slice Softmax Split Sqrt Squeeze Sub Tanh Tile Transpose Unsqueeze Where
""".split()
)


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


def input_dtypes(model) -> dict[str, str]:
    """``{input name: dtype}`` of an ``onnx.ModelProto``'s graph inputs (initializers excluded)."""
    inits = {t.name for t in model.graph.initializer}
    return {
        i.name: _ELEM.get(i.type.tensor_type.elem_type, f"elem_type {i.type.tensor_type.elem_type}")
        for i in model.graph.input
        if i.name not in inits
    }


def make_inputs_portable(model) -> dict[str, str]:
    """Rewrite ``model``'s int64 graph inputs as int32 and its bool inputs as float32 (nonzero = true), each
    read through a Cast to its old type under its old name, so every node and output is unchanged; in place.
    Returns ``{name: new dtype}`` of the inputs changed."""
    from onnx import TensorProto, helper

    changed, casts = {}, []
    for inp in model.graph.input:
        tt = inp.type.tensor_type
        if tt.elem_type not in (TensorProto.INT64, TensorProto.BOOL):
            continue
        old_type = tt.elem_type
        new_type = TensorProto.INT32 if old_type == TensorProto.INT64 else TensorProto.FLOAT
        inner = f"{inp.name}__as_{_ELEM[old_type]}"
        for node in model.graph.node:  # every reader now reads the Cast's output
            for k, x in enumerate(node.input):
                if x == inp.name:
                    node.input[k] = inner
        for out in model.graph.output:
            if out.name == inp.name:
                raise PortabilityError(f"graph input '{inp.name}' is also an output; cannot retype it")
        casts.append(helper.make_node("Cast", [inp.name], [inner], to=old_type, name=f"{inp.name}__cast"))
        tt.elem_type = new_type
        changed[inp.name] = _ELEM[new_type]
    nodes = list(model.graph.node)
    del model.graph.node[:]
    model.graph.node.extend(casts + nodes)
    return changed


def check_portability(model, name: str = "graph") -> Counter:
    """Raise :class:`PortabilityError` listing every op outside the allowed set, every node with more than
    ``MAX_NODE_TENSORS`` tensors and every graph input that is not float32 or int32; return the op counts."""
    wrong = {k: v for k, v in input_dtypes(model).items() if v not in PORTABLE_INPUT_DTYPES}
    if wrong:
        raise PortabilityError(
            f"{name} has graph inputs WebGPU and engines do not take: "
            + ", ".join(f"{k} {v}" for k, v in wrong.items())
            + f" (expected {' or '.join(PORTABLE_INPUT_DTYPES)}; int64 indices as int32, bool "
            "masks as float32 1/0)"
        )
    counts = op_counts(model)
    bad = sorted(op for op in counts if op not in ALLOWED_OPS)
    if bad:
        why = "; ".join(f"{op}: {FORBIDDEN_OPS.get(op, 'not in the portable op set')}" for op in bad)
        raise PortabilityError(f"{name} uses non-portable ops: {why}")
    wide = sorted(
        {
            (n.op_type, len(n.input) + len(n.output))
            for n in iter_nodes(model)
            if len(n.input) + len(n.output) > MAX_NODE_TENSORS
        }
    )
    if wide:
        raise PortabilityError(
            f"{name} has nodes reading and writing more than {MAX_NODE_TENSORS} tensors (WebGPU's "
            f"default storage buffers per shader): " + ", ".join(f"{op} with {k}" for op, k in wide)
        )
    return counts


# ---- sine and cosine as polynomials -----------------------------------------------------------------------
#: Taylor coefficients of sin(r) / r - 1 (in r^2) and cos(r) - 1 (in r^2) on |r| <= pi/2: the truncation
#: errors are 6e-8 and 6e-9, below float32's half ulp of 1
_SIN = (-1 / 6, 1 / 120, -1 / 5040, 1 / 362880, -1 / 39916800)
_COS = (-1 / 2, 1 / 24, -1 / 720, 1 / 40320, -1 / 3628800, 1 / 479001600)
#: pi in two parts (Cody and Waite): k * _PI_HI is exact for |k| < 2^16, so r = x - k pi loses no bits
_PI_HI = 3.140625
_PI_LO = 9.676535897932795e-04


def replace_trig(model) -> int:
    """Replace every ``Sin`` and ``Cos`` node of ``model`` (an ``onnx.ModelProto``, in place) by the same function
    built from Mul, Add, Sub and Floor: ``x = k pi + r`` with ``|r| <= pi/2`` (two-part pi), a degree-11/12
    polynomial in ``r``, the sign ``(-1)^k``.  Returns the number of nodes replaced.

    Why: WebGPU's ``sin`` and ``cos`` (WGSL builtins, which onnxruntime-web's kernels call) only promise an absolute
    error of 2^-11 on [-pi, pi]; SwiftShader's were off by 5e-5, and through Rodrigues' formula and 23 levels of
    forward kinematics that became 1e-4 relative in the posed vertices (``bench/webgpu_nodes.py``).  Mul, Add and
    Floor are exact to an ulp on every backend, so the polynomial gives the CPU's numbers to ~1e-7 everywhere."""
    import numpy as np
    from onnx import helper, numpy_helper

    count = 0
    for graph in iter_graphs(model):
        if not any(n.op_type in ("Sin", "Cos") and n.domain in ("", "ai.onnx") for n in graph.node):
            continue
        consts = {"inv_pi": 1 / np.pi, "half": 0.5, "one": 1.0, "four": 4.0, "pi_hi": _PI_HI, "pi_lo": _PI_LO}
        consts.update({f"s{i}": c for i, c in enumerate(_SIN)})
        consts.update({f"c{i}": c for i, c in enumerate(_COS)})
        names = {k: f"__trig_{k}" for k in consts}
        have = {t.name for t in graph.initializer}
        for k, v in consts.items():
            if names[k] not in have:
                graph.initializer.append(numpy_helper.from_array(np.array(v, np.float32), names[k]))
        out = []
        for node in graph.node:
            if node.op_type not in ("Sin", "Cos") or node.domain not in ("", "ai.onnx"):
                out.append(node)
                continue
            count += 1
            x, y = node.input[0], node.output[0]
            pre = f"{node.name or y}__poly"
            c = names

            def op(kind, a, b, tag, _pre=pre, _out=out):
                name = f"{_pre}_{tag}"
                _out.append(helper.make_node(kind, [a, b] if b is not None else [a], [name], name=name))
                return name

            k = op("Floor", op("Add", op("Mul", x, c["inv_pi"], "q"), c["half"], "q5"), None, "k")
            r = op("Sub", op("Sub", x, op("Mul", k, c["pi_hi"], "khi"), "r0"), op("Mul", k, c["pi_lo"], "klo"), "r")
            half_k = op("Mul", k, c["half"], "hk")
            parity = op("Sub", half_k, op("Floor", half_k, None, "fhk"), "par")  # 0 or 0.5
            sign = op("Sub", c["one"], op("Mul", parity, c["four"], "p4"), "sign")  # (-1)^k
            r2 = op("Mul", r, r, "r2")
            coef = _SIN if node.op_type == "Sin" else _COS
            key = "s" if node.op_type == "Sin" else "c"
            acc = c[f"{key}{len(coef) - 1}"]
            for i in range(len(coef) - 2, -1, -1):
                acc = op("Add", op("Mul", acc, r2, f"h{i}"), c[f"{key}{i}"], f"a{i}")
            if node.op_type == "Sin":
                val = op("Add", r, op("Mul", op("Mul", acc, r2, "t2"), r, "t3"), "val")
            else:
                val = op("Add", c["one"], op("Mul", acc, r2, "t2"), "val")
            out.append(helper.make_node("Mul", [sign, val], [y], name=f"{pre}_out"))
        del graph.node[:]
        graph.node.extend(out)
        used = {i for n in graph.node for i in n.input}
        keep = [t for t in graph.initializer if not t.name.startswith("__trig_") or t.name in used]
        del graph.initializer[:]
        graph.initializer.extend(keep)
    return count
