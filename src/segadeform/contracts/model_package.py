"""The model package contract: what a package holds and how a runtime uses it (``docs/package.md``).

One home for the format, torch-free and numpy-free: export (``export/package.py``) writes packages
through it, the Python runtime (``runtimes/python``) reads them through it, and
``docs/manifest.schema.json`` is generated from it (:func:`manifest_schema`).  What is here:

* the graph I/O: every input and output of each graph, its dtype and shape (:func:`graph_specs`,
  :data:`INPUTS`, :data:`OUTPUTS`, which also say what each array means);
* the effect -> graph rule: one deformer graph per combination of ``skinning`` x ``wrinkles`` x
  ``dynamics``, named by :func:`deformer_name`, chosen by exact match (:func:`select_deformer`);
* the body graphs: the body model as ONNX (``body_lbs``, ``body_dqs``: betas, poses and translations
  in, posed vertices and joints out), so runtimes without Python pose the body (:func:`body_spec`,
  :func:`body_name`, :func:`select_body`, :data:`BODY_INPUTS`, :data:`BODY_OUTPUTS`);
* the manifest: its keys (:func:`make_manifest`), its checks (:func:`validate_manifest`), the reading
  of schema-1 and schema-2 manifests (:func:`upgrade_manifest`) and its JSON Schema (:func:`manifest_schema`).

Layout of a package folder (schema 3)::

    manifest.json                 this module's manifest
    garment_encoder.onnx          once per garment (and body shape for schema-1 encoders)
    deformer_<effects>.onnx       one per effect combination, per frame, batched over frames
    body_lbs.onnx, body_dqs.onnx  optional: the body posed (LBS, DQS), per frame, batched over frames
    weights.bin                   optional: the graphs' weights, one copy shared by every graph
                                  (ONNX external data; offsets 64-byte aligned)
    MODEL_CARD.md                 optional
"""

from __future__ import annotations

from collections.abc import Mapping

from ..body.transfer import WEIGHT_PRIORS
from ..errors import FileFormatError

__all__ = [
    "FORMAT",
    "SCHEMA_VERSION",
    "READABLE_SCHEMAS",
    "OPSET",
    "SUPPORTED_OPSETS",
    "MANIFEST_FILE",
    "WEIGHTS_FILE",
    "ENCODER",
    "DEFORMER",
    "ROLES",
    "EFFECT_KEYS",
    "SKINNING",
    "DTYPES",
    "DIMENSIONS",
    "INPUTS",
    "OUTPUTS",
    "LEGACY_INPUTS",
    "FEEDS",
    "PackageError",
    "graph_specs",
    "encoder_spec",
    "deformer_spec",
    "deformer_name",
    "graph_file",
    "effect_sets",
    "default_effects",
    "effects_of",
    "select_deformer",
    "deformers",
    "code_name",
    "make_manifest",
    "validate_manifest",
    "upgrade_manifest",
    "read_manifest_text",
    "manifest_schema",
    "write_manifest_schema",
    "TRAINING_GARMENTS",
    "TRAINING_MOTIONS",
    "MAX_NODE_TENSORS",
    "BODY",
    "BODY_INPUTS",
    "BODY_OUTPUTS",
    "body_spec",
    "body_name",
    "body_graphs",
    "select_body",
    "PORTABLE_INPUT_DTYPES",
]

#: optional manifest key: the garments the model was trained on, as descriptors (Eq. 19 distances), so a
#: runtime can warn when a garment lies outside them: ``{"metric": "eq19", "threshold": float | null,
#: "garments": [{"name": str, "descriptor": [N* floats], "openings": int (optional)}, ...]}``.
#: ``threshold``: the largest distance from a training garment to its nearest *other* training garment
#: (null with one garment); a garment whose nearest training garment is further than that, or whose
#: number of openings (boundary loops) no training garment has, is outside the training set.
TRAINING_GARMENTS = "training_garments"

#: optional manifest key: fingerprints of the motions the model was trained on (each joint's angular speed over
#: time, :mod:`segadeform.motion.fingerprint`), so ``eval`` can say when a sample it scores plays one of them:
#: ``{"metric": "joint-speeds-v1", "rate": 30.0, "joints": [9 SMPL joints], "motions": [{"name": str, "frames":
#: int, "speeds": base64, a byte a value}, ...]}``.  Runtimes do not read it.
TRAINING_MOTIONS = "training_motions"

#: the most tensors one graph node may read and write: WebGPU's default storage buffers per shader stage (a
#: Concat of 24 joints needed 25, and onnxruntime-web's JSEP WebGPU returned wrong numbers without an error);
#: export checks it (``export/portability.py``) and the model builds its stacks within it
MAX_NODE_TENSORS = 8

#: ``manifest.json``'s ``format``
FORMAT = "segadeform-model-package"
#: the manifest layout this version writes; 2: one name per graph (``graphs`` holds every graph, each
#: deformer with its ``effects``), ``default_deformer``, an optional shared ``weights`` file; 3: graph inputs
#: are float32 or int32 only (``nbr`` int32, ``mask`` float32 1/0: what WebGPU and engines take), and the
#: optional body graphs (role ``body``)
SCHEMA_VERSION = 3
#: what the runtime reads (1: ``graphs`` = encoder + ``deformer``, ``variants`` repeating the default;
#: 2: int64 ``nbr`` and bool ``mask``, no body graphs)
READABLE_SCHEMAS = (1, 2, 3)
OPSET = 18
#: opsets a package may declare: export writes OPSET; ``segadeform repack --opset 15`` converts for engines
#: that read older ones (Unity Sentis reads 7-15; below 15 onnx has no converter for the graphs' Shape nodes)
SUPPORTED_OPSETS = range(15, 22)
MANIFEST_FILE = "manifest.json"
WEIGHTS_FILE = "weights.bin"
#: roles, and the names of the two graph kinds in :func:`graph_specs`
ENCODER = "garment_encoder"
DEFORMER = "deformer"
BODY = "body"
ROLES = {ENCODER: "encoder", DEFORMER: "deformer", BODY: "body"}
#: the effects that choose a deformer graph (collisions are the host's post-process, not a graph)
EFFECT_KEYS = ("skinning", "wrinkles", "dynamics")
SKINNING = ("lbs", "dqs")
DTYPES = ("float32", "int32", "int64", "bool")
#: the only graph input dtypes a schema-3 package has: WebGPU has no 64-bit integers (onnxruntime-web emulates
#: them or falls back to the CPU) and engines such as Unity Sentis take float and int32 tensors from the host;
#: manifests upgraded from schema 2 keep their int64 and bool
PORTABLE_INPUT_DTYPES = ("float32", "int32")

#: symbolic axes of the graphs' inputs and outputs (everything else is fixed by ``config``)
DIMENSIONS = {
    "B": "batch: frames per deformer call; 1 for the encoder (one garment)",
    "N": "garment vertices, in the garment file's order",
    "K": "neighbour slots per vertex (the precompute's K; any K >= 1 works)",
}

#: every input a runtime may have to feed: name -> meaning (units, layout, padding).  Shapes use
#: S = config.n_joints, F = config.feat_dim (= 6 + S), N* = config.n_star, |beta| = config.n_betas,
#: T = the deformer's window (``window`` of its manifest entry).
INPUTS = {
    "features": "float32 (B, N, F): per garment vertex [position (3, metres), unit normal (3; 0 where "
    "undefined: area-weighted over the incident faces), distance to each of the S rest-pose "
    "joints of the body shape (S, metres)]; F = 6 + S = 30 for SMPL's 24 joints",
    "nbr": "int32 (N, K): the padded 1-ring: row i lists vertex i's edge neighbours, nearest first by rest "
    "length (ties by index), at most K; unused slots hold i itself (schema-2 packages: int64)",
    "mask": "float32 (N, K): 1 where nbr is a real neighbour, 0 in padded slots (an isolated vertex "
    "has an all-zero row; schema-2 packages: bool, true and false)",
    "descriptor": "float32 (B, N*): the garment type descriptor (the precompute's descriptor, N* values)",
    "g": "float32 (N, K S): the encoder's output for this garment without its batch axis, the same array "
    "for every deformer call (K = config.ensemble, the networks averaged; absent: 1)",
    "window": "float32 (B, T, 3 S): motion windows; window[b, k] = the pose k frames before frame b "
    "(window[b, 0] is the frame itself), each pose the S joints' local axis-angle rotations "
    "(radians, SMPL joint order, joint-major: x, y, z of joint 0, then joint 1, ...); frames "
    "before the first frame repeat the first frame",
    "betas": "float32 (B, |beta|): the body shape coefficients, zero-padded to |beta|, the same row "
    "repeated for every frame",
    "rest": "float32 (N, 3): garment rest positions (metres, +Y up)",
    "joints": "float32 (B, S, 3): the body's rest-pose joints for betas (metres), the same (S, 3) "
    "repeated for every frame",
    "trans": "float32 (B, 3): root translation of each frame (metres)",
    "log_wbody": "float32 (N, S): log(w + 1e-5), w = the body's skinning weights carried to the garment on "
    "the rest body of shape betas by config.weight_prior: 'nearest' (absent: the closest body "
    "point's weights), 'inpaint' (the closest point's weights where the garment vertex is within "
    "2 cm of the body with its normal within 35 degrees of the body's, harmonic inpainting with the "
    "cotangent Laplacian elsewhere), 'idw', 'gaussian' or 'smooth' (kernel priors: "
    "segadeform.body.transfer) (residual-weights models only, "
    "config.weights = 'residual')",
}
#: inputs of schema-1-era graphs that current exports no longer have (still read)
LEGACY_INPUTS = {
    "P": "float32 (N, S, F_enc): the encoder output of packages exported before the factored encoder "
    "(fed like g: the encoder's output without its batch axis)",
    "betas (encoder)": "float32 (B, |beta|): those encoders also took the body shape; their output depends on it",
}
OUTPUTS = {
    "g": "float32 (B, N, K S): the garment's per-joint code, K networks' side by side (K = config.ensemble, "
    "absent: 1; older encoders: P (B, N, S, F_enc))",
    "vertices": "float32 (B, N, 3): the deformed garment per frame (metres, +Y up, world space: includes trans)",
    "weights": "float32 (B, N, S): the skinning weights used (positive, each row sums to 1)",
    "blend_shapes": "float32 (B, N, 3): the pose-dependent offsets added to rest before skinning "
    "(zero without wrinkles)",
}
#: the body graphs' inputs (``betas`` here is one row, not one per frame) and outputs; S = the body's joints
#: (24), V and F its vertices and triangles (fixed by the body: integers in the manifest)
BODY_INPUTS = {
    "betas": "float32 (|beta_body|,): the body's shape coefficients (the body file's count, zero-padded), one "
    "row for every frame of the call",
    "poses": "float32 (B, S, 3): each frame's local axis-angle joint rotations (radians, SMPL order; the "
    "motion file's poses)",
    "trans": "float32 (B, 3): each frame's root translation (metres), added to the root joint's rest position",
}
BODY_OUTPUTS = {
    "vertices": "float32 (B, V, 3): the posed body (metres, +Y up, world space: trans included), skinned "
    "with the graph's skinning (LBS or DQS) as segadeform.body.BodyModel.forward does",
    "joints": "float32 (B, S, 3): the posed joints (world space)",
    "rest_joints": "float32 (S, 3): the rest-pose joints for betas (what the deformers' joints input "
    "repeats per frame)",
    "faces": "int32 (F, 3): the body's triangles (constant), so the graph alone describes the mesh",
}
#: by role, every input name a runtime must know how to feed (the encoder's ``betas``: older packages),
#: besides the deformer's encoder output (``g``, or ``P``: :func:`code_name`)
FEEDS = {
    "encoder": ("features", "nbr", "mask", "descriptor", "betas"),
    "deformer": ("window", "betas", "rest", "nbr", "mask", "joints", "trans", "log_wbody"),
    "body": ("betas", "poses", "trans"),
}


class PackageError(FileFormatError):
    """A model package is malformed or its manifest and ONNX files disagree."""


# ---- config access (a ModelConfig or the manifest's config dict) ------------------------------------
def _cfg(cfg, key: str, default=None):
    if isinstance(cfg, Mapping):
        return cfg.get(key, default)
    return getattr(cfg, key, default)


def _io(name: str, dtype: str, shape: list) -> dict:
    return {"name": name, "dtype": dtype, "shape": list(shape)}


# ---- graph I/O ---------------------------------------------------------------------------------------
def encoder_spec(cfg) -> dict:
    """Inputs and outputs of the garment encoder for ``cfg`` (a ModelConfig or a config dict)."""
    s = int(_cfg(cfg, "n_joints"))
    k = int(_cfg(cfg, "ensemble", 1) or 1)
    return {
        "role": ROLES[ENCODER],
        "file": graph_file(ENCODER),
        "inputs": [
            _io("features", "float32", ["B", "N", int(_cfg(cfg, "feat_dim"))]),
            _io("nbr", "int32", ["N", "K"]),
            _io("mask", "float32", ["N", "K"]),
            _io("descriptor", "float32", ["B", int(_cfg(cfg, "n_star"))]),
        ],
        "outputs": [_io("g", "float32", ["B", "N", k * s])],
    }


def deformer_spec(cfg, effects: Mapping | None = None) -> dict:
    """Inputs, outputs, effects and window of the deformer for ``effects`` (default: ``cfg``'s own)."""
    eff = dict(default_effects(cfg) if effects is None else effects)
    s, nb = int(_cfg(cfg, "n_joints")), int(_cfg(cfg, "n_betas"))
    t = int(_cfg(cfg, "window")) if eff["dynamics"] else 1
    k = int(_cfg(cfg, "ensemble", 1) or 1)
    inputs = [
        _io("g", "float32", ["N", k * s]),
        _io("window", "float32", ["B", t, 3 * s]),
        _io("betas", "float32", ["B", nb]),
        _io("rest", "float32", ["N", 3]),
        _io("nbr", "int32", ["N", "K"]),
        _io("mask", "float32", ["N", "K"]),
        _io("joints", "float32", ["B", s, 3]),
        _io("trans", "float32", ["B", 3]),
    ]
    if _cfg(cfg, "weights", "free") == "residual":
        inputs.append(_io("log_wbody", "float32", ["N", s]))
    name = deformer_name(eff)
    return {
        "role": ROLES[DEFORMER],
        "file": graph_file(name),
        "effects": eff,
        "window": t,
        "inputs": inputs,
        "outputs": [
            _io("vertices", "float32", ["B", "N", 3]),
            _io("weights", "float32", ["B", "N", s]),
            _io("blend_shapes", "float32", ["B", "N", 3]),
        ],
    }


def body_name(skinning: str) -> str:
    """The name (and, + ``.onnx``, file name) of the body graph for ``skinning``: ``body_lbs`` or ``body_dqs``."""
    if skinning not in SKINNING:
        raise PackageError("unknown skinning", expected=" | ".join(SKINNING), got=skinning)
    return f"{BODY}_{skinning}"


def body_spec(
    *, n_vertices: int, n_faces: int, n_betas: int, n_joints: int, skinning: str, body: Mapping | None = None
) -> dict:
    """Inputs, outputs and skinning of a body graph (the manifest entry without its hash); ``body``: what
    identifies the body (``name``, ``sha256`` of its arrays: :func:`segadeform.body.identity.body_sha256`)."""
    v, f, nb, s = int(n_vertices), int(n_faces), int(n_betas), int(n_joints)
    out = {
        "role": ROLES[BODY],
        "file": graph_file(body_name(skinning)),
        "skinning": skinning,
        "inputs": [
            _io("betas", "float32", [nb]),
            _io("poses", "float32", ["B", s, 3]),
            _io("trans", "float32", ["B", 3]),
        ],
        "outputs": [
            _io("vertices", "float32", ["B", v, 3]),
            _io("joints", "float32", ["B", s, 3]),
            _io("rest_joints", "float32", [s, 3]),
            _io("faces", "int32", [f, 3]),
        ],
    }
    if body is not None:
        out["body"] = dict(body)
    return out


def graph_specs(cfg) -> dict:
    """``{"garment_encoder": spec, "deformer": spec}``: the encoder and ``cfg``'s own deformer (its
    ``skinning`` and ``use_blend_shapes``, with dynamics), each with role, file, inputs and outputs."""
    return {ENCODER: encoder_spec(cfg), DEFORMER: deformer_spec(cfg)}


# ---- effects -> graphs ---------------------------------------------------------------------------------
def effects_of(effects) -> dict:
    """``{"skinning", "wrinkles", "dynamics"}`` of a :class:`segadeform.settings.scene.Effects` or a mapping."""
    get = (lambda k: effects[k]) if isinstance(effects, Mapping) else (lambda k: getattr(effects, k))
    try:
        out = {"skinning": str(get("skinning")), "wrinkles": bool(get("wrinkles")), "dynamics": bool(get("dynamics"))}
    except (KeyError, AttributeError):
        raise PackageError("effects must name skinning, wrinkles and dynamics", got=effects) from None
    if out["skinning"] not in SKINNING:
        raise PackageError("unknown skinning", expected=" | ".join(SKINNING), got=out["skinning"])
    return out


def deformer_name(effects) -> str:
    """The graph name (and, + ``.onnx``, file name) of the deformer for ``effects``:
    ``deformer_<lbs|dqs>[_nowrinkles][_static]``."""
    e = effects_of(effects)
    return f"deformer_{e['skinning']}" + ("" if e["wrinkles"] else "_nowrinkles") + ("" if e["dynamics"] else "_static")


def graph_file(name: str) -> str:
    return f"{name}.onnx"


def default_effects(cfg) -> dict:
    """The effects of the model as trained: its skinning, its blend shapes, dynamics on."""
    return {
        "skinning": str(_cfg(cfg, "skinning", "lbs")),
        "wrinkles": bool(_cfg(cfg, "use_blend_shapes", True)),
        "dynamics": True,
    }


def effect_sets(cfg) -> list[dict]:
    """Every effect combination an export makes a deformer for: skinning x wrinkles x dynamics (no
    wrinkles-on graph for a model without blend shapes), the model's own first."""
    out = [default_effects(cfg)]
    for skin in SKINNING:
        for wrinkles in (True, False):
            if wrinkles and not _cfg(cfg, "use_blend_shapes", True):
                continue
            for dynamics in (True, False):
                e = {"skinning": skin, "wrinkles": wrinkles, "dynamics": dynamics}
                if e not in out:
                    out.append(e)
    return out


def deformers(manifest: Mapping) -> dict:
    """The deformer graphs of a (schema-2 or later) manifest: name -> entry."""
    return {k: g for k, g in manifest["graphs"].items() if g.get("role") == ROLES[DEFORMER]}


def body_graphs(manifest: Mapping) -> dict:
    """The body graphs of a manifest (none in packages before schema 3): name -> entry."""
    return {k: g for k, g in manifest["graphs"].items() if g.get("role") == ROLES[BODY]}


def select_body(manifest: Mapping, skinning: str, *, path=None) -> str | None:
    """The body graph that poses the body with ``skinning`` (the garment's, so the body and the garment are
    skinned alike); None when the package has no body graph, an error when it has others only."""
    bodies = body_graphs(manifest)
    if not bodies:
        return None
    for name, g in bodies.items():
        if g.get("skinning") == skinning:
            return name
    raise PackageError(
        "package has no body graph for this skinning", path=path, expected=", ".join(sorted(bodies)), got=skinning
    )


def select_deformer(manifest: Mapping, effects, *, path=None) -> str:
    """The rule every runtime follows: the deformer graph whose ``effects`` equal the requested
    skinning, wrinkles and dynamics exactly; none is an error listing what the package has."""
    want = effects_of(effects)
    for name, g in deformers(manifest).items():
        if g.get("effects") == want:
            return name
    have = "; ".join(f"{n} {g.get('effects')}" for n, g in sorted(deformers(manifest).items()))
    # (a package exported --no-variants refused `--quality fast` with no word of why: an ML user's trial)
    only = " (it has the model's own alone: `segadeform export` without --no-variants writes the others)"
    why = "package has no deformer for these effects" + (only if len(deformers(manifest)) == 1 else "")
    raise PackageError(why, path=path, expected=have, got=want)


def code_name(manifest: Mapping) -> str:
    """The encoder's one output name (``g``; ``P`` in older packages), also a deformer input name."""
    return manifest["graphs"][ENCODER]["outputs"][0]["name"]


# ---- manifests ---------------------------------------------------------------------------------------
def make_manifest(
    *,
    config: dict,
    graphs: dict,
    default_deformer: str,
    producer: str,
    joint_names,
    parents,
    units: str,
    up_axis: str,
    ops: dict | None = None,
    weights: dict | None = None,
    **extra,
) -> dict:
    """A schema-3 manifest.  ``graphs``: name -> entry (role, file, sha256, inputs, outputs; deformers
    also effects and window, body graphs skinning and body); ``weights``: ``{"file", "sha256", "bytes"}`` when
    the graphs share one."""
    m = {
        "format": FORMAT,
        "schema_version": SCHEMA_VERSION,
        "opset": OPSET,
        "producer": producer,
        "config": dict(config),
        "joint_names": list(joint_names),
        "parents": [int(p) for p in parents],
        "units": units,
        "up_axis": up_axis,
        "graphs": dict(graphs),
        "default_deformer": default_deformer,
        "ops": dict(ops or {}),
    }
    if weights is not None:
        m["weights"] = dict(weights)
    m.update(extra)
    return m


def read_manifest_text(text: str, *, path=None) -> dict:
    """Parse, upgrade (schemas 1 and 2) and validate a manifest's text; the schema-3 form."""
    import json

    try:
        m = json.loads(text)
    except (json.JSONDecodeError, UnicodeDecodeError) as e:
        raise PackageError(f"manifest is not valid JSON ({e})", path=path) from None
    except RecursionError:  # (arrays nested thousands deep: found by fuzzing)
        raise PackageError("manifest nests too deeply to be read", path=path) from None
    m = upgrade_manifest(m, path=path)
    validate_manifest(m, path=path)
    return m


def upgrade_manifest(m, *, path=None) -> dict:
    """A schema-1 or schema-2 manifest in the current (schema-3) form (a copy; current manifests come back
    as they are), with ``upgraded_from`` set to the version read.

    Schema 1 named the model's own deformer twice (``graphs.deformer`` and its entry in
    ``variants``, both the same file); here each file is one graph, named by its effects.  Schema 2 has the
    schema-3 layout without body graphs; its graphs take ``nbr`` as int64 and ``mask`` as bool, which the
    upgraded manifest keeps saying (the inputs are the ONNX files'): a runtime feeds each input in the dtype
    its manifest entry names (``segadeform repack`` rewrites such a package with int32 and float32 inputs)."""
    if not isinstance(m, dict):
        raise PackageError("manifest must be a JSON object", path=path, got=type(m).__name__)
    if m.get("schema_version") == 2:
        return dict(m, schema_version=SCHEMA_VERSION, upgraded_from=2)
    if m.get("schema_version") != 1:
        return m
    for key in ("config", "graphs"):
        if not isinstance(m.get(key), dict):
            raise PackageError(f"manifest has no '{key}'", path=path)
    old, cfg = m["graphs"], m["config"]
    if ENCODER not in old or DEFORMER not in old:
        raise PackageError("manifest must describe 'garment_encoder' and 'deformer'", path=path, got=", ".join(old))
    graphs = {ENCODER: dict(old[ENCODER], role=ROLES[ENCODER])}
    ops = dict(m.get("ops", {}))
    dflt = dict(old[DEFORMER])
    default = None
    for name, v in (m.get("variants") or {}).items():
        graphs[name] = dict(v, role=ROLES[DEFORMER])
        if v.get("file") == dflt.get("file"):
            default = name
    if default is None:  # no variants (or none for the model's own effects): the model's own deformer
        eff = default_effects(cfg)
        default = deformer_name(eff)
        win = next((i["shape"][1] for i in dflt.get("inputs", []) if i.get("name") == "window"), cfg.get("window"))
        graphs[default] = dict(dflt, role=ROLES[DEFORMER], effects=eff, window=win)
    if DEFORMER in ops:
        ops.setdefault(default, ops.pop(DEFORMER))
    out = {k: v for k, v in m.items() if k not in ("variants", "graphs", "ops")}
    out.update(schema_version=SCHEMA_VERSION, graphs=graphs, default_deformer=default, ops=ops, upgraded_from=1)
    out.setdefault("format", FORMAT)
    return out


# ---- the manifest's rules, written once: JSON Schema fragments that manifest_schema() assembles into
# docs/manifest.schema.json and validate_manifest() checks values against (_conforms), adding what a schema
# cannot say (its messages and the rules between fields).
_DIM = {"oneOf": [{"type": "integer", "minimum": 1}, {"type": "string", "minLength": 1}]}
_TENSOR = {
    "type": "object",
    "required": ["name", "dtype", "shape"],
    "additionalProperties": False,
    "properties": {
        "name": {"type": "string", "minLength": 1},
        "dtype": {"enum": list(DTYPES)},
        "shape": {"type": "array", "items": _DIM},
    },
}
_SHA = {"type": "string", "pattern": "^[0-9a-f]{64}$"}
_GRAPH_FILE = {"type": "string", "pattern": r"^[^./\\][^/\\]*\.onnx$"}
_WEIGHTS_FILE = {"type": "string", "pattern": r"^[^./\\][^/\\]*$"}
_EFFECTS = {
    "type": "object",
    "required": list(EFFECT_KEYS),
    "additionalProperties": False,
    "properties": {
        "skinning": {"enum": list(SKINNING)},
        "wrinkles": {"type": "boolean"},
        "dynamics": {"type": "boolean"},
    },
}
_OPSET = {"type": "integer", "minimum": SUPPORTED_OPSETS.start, "maximum": SUPPORTED_OPSETS.stop - 1}
_POSITIVE = {"type": "integer", "minimum": 1}
_TRAINING_MOTIONS = {
    "type": "object",
    "required": ["metric", "rate", "joints", "motions"],
    "additionalProperties": False,
    "description": "fingerprints of the training motions (segadeform.motion.fingerprint); eval says when a sample "
    "it scores plays one of them",
    "properties": {
        "metric": {"type": "string"},
        "rate": {"type": "number", "minimum": 0},
        "joints": {"type": "array", "items": {"type": "integer", "minimum": 0}},
        "motions": {
            "type": "array",
            "items": {
                "type": "object",
                "required": ["name", "frames", "speeds"],
                "additionalProperties": False,
                "properties": {
                    "name": {"type": "string"},
                    "frames": {"type": "integer", "minimum": 0},
                    "speeds": {"type": "string"},
                },
            },
        },
    },
}
_TRAINING_GARMENTS = {
    "type": "object",
    "required": ["metric", "threshold", "garments"],
    "additionalProperties": False,
    "description": "descriptors of the training garments; a runtime warns when a garment's nearest "
    "one (Eq. 19) is further than threshold",
    "properties": {
        "metric": {"const": "eq19"},
        "threshold": {"oneOf": [{"type": "number", "minimum": 0}, {"type": "null"}]},
        "garments": {
            "type": "array",
            "minItems": 1,
            "items": {
                "type": "object",
                "required": ["name", "descriptor"],
                "additionalProperties": False,
                "properties": {
                    "name": {"type": "string"},
                    "descriptor": {"type": "array", "items": {"type": "number"}, "minItems": 1},
                    "openings": {"type": "integer", "minimum": 0},
                },
            },
        },
    },
}

_JSON_TYPES = {"object": dict, "array": list, "string": str, "boolean": bool, "null": type(None)}


def _conforms(x, schema: dict) -> bool:
    """Whether the JSON value ``x`` satisfies ``schema`` (the draft 2020-12 keywords this module's fragments use;
    a boolean is neither an integer nor a number, patterns match the whole string as ECMA regexes do)."""
    import re

    t = schema.get("type")
    if t in ("integer", "number"):
        ok = isinstance(x, int) if t == "integer" else isinstance(x, (int, float))
        if not ok or isinstance(x, bool):
            return False
    elif t is not None and not isinstance(x, _JSON_TYPES[t]):
        return False
    if "const" in schema and (x != schema["const"] or isinstance(x, bool) != isinstance(schema["const"], bool)):
        return False
    if "enum" in schema and not any(x == e and isinstance(x, bool) == isinstance(e, bool) for e in schema["enum"]):
        return False
    if "minimum" in schema and x < schema["minimum"] or "maximum" in schema and x > schema["maximum"]:
        return False
    if "minLength" in schema and len(x) < schema["minLength"]:
        return False
    if "pattern" in schema and re.fullmatch(schema["pattern"].removeprefix("^").removesuffix("$"), x) is None:
        return False
    if "oneOf" in schema and sum(_conforms(x, s) for s in schema["oneOf"]) != 1:
        return False
    if isinstance(x, list):
        if len(x) < schema.get("minItems", 0) or len(x) > schema.get("maxItems", len(x)):
            return False
        if "items" in schema and not all(_conforms(v, schema["items"]) for v in x):
            return False
    if isinstance(x, dict):
        props = schema.get("properties", {})
        if any(k not in x for k in schema.get("required", ())):
            return False
        if schema.get("additionalProperties") is False and set(x) - set(props):
            return False
        if not all(_conforms(v, props[k]) for k, v in x.items() if k in props):
            return False
    return True


def _check_io(name, kind, entries, path) -> None:
    if not isinstance(entries, list) or not entries:
        raise PackageError(f"graph '{name}' has no {kind}", path=path, expected="a non-empty list", got=entries)
    seen = set()
    for e in entries:
        if not isinstance(e, dict) or not _conforms(e.get("name"), _TENSOR["properties"]["name"]):
            raise PackageError(
                f"graph '{name}' has a malformed {kind[:-1]}", path=path, expected="{name, dtype, shape}", got=e
            )
        if e["name"] in seen:
            raise PackageError(f"graph '{name}' names {kind[:-1]} '{e['name']}' twice", path=path)
        seen.add(e["name"])
        if not _conforms(e.get("dtype"), _TENSOR["properties"]["dtype"]):
            raise PackageError(
                f"graph '{name}' {kind[:-1]} '{e['name']}' has an unknown dtype",
                path=path,
                expected=" | ".join(DTYPES),
                got=e.get("dtype"),
            )
        if not _conforms(e.get("shape"), _TENSOR["properties"]["shape"]):
            raise PackageError(
                f"graph '{name}' {kind[:-1]} '{e['name']}' has a malformed shape",
                path=path,
                expected="a list of positive sizes and axis names",
                got=e.get("shape"),
            )


def validate_manifest(m, *, path=None) -> None:
    """Check a schema-3 manifest's structure (what :func:`manifest_schema` says, plus the rules a
    schema cannot: one deformer per effect set, the default a deformer, the encoder's output a
    deformer input, file names without folders, float32/int32 inputs unless upgraded from schema 2,
    body graphs named by their skinning with a body graph's inputs and outputs).  Files and ONNX contents are
    the runtime's checks."""
    if not isinstance(m, dict):
        raise PackageError("manifest must be a JSON object", path=path, got=type(m).__name__)
    for key in ("format", "schema_version", "opset", "config", "graphs", "joint_names", "default_deformer"):
        if key not in m:
            raise PackageError(f"manifest has no '{key}'", path=path)
    if m["format"] != FORMAT:
        raise PackageError("not a segadeform model package", path=path, expected=FORMAT, got=m["format"])
    if m["schema_version"] not in READABLE_SCHEMAS:
        raise PackageError(
            "unsupported manifest schema version",
            path=path,
            expected=" or ".join(map(str, READABLE_SCHEMAS)),
            got=m["schema_version"],
        )
    if not _conforms(m["opset"], _OPSET):
        raise PackageError(
            "unsupported ONNX opset",
            path=path,
            expected=f"{SUPPORTED_OPSETS.start}..{SUPPORTED_OPSETS.stop - 1}",
            got=m["opset"],
        )
    cfg, graphs = m["config"], m["graphs"]
    if not isinstance(cfg, dict):
        raise PackageError("manifest config must be an object", path=path, got=type(cfg).__name__)
    for key in ("n_joints", "n_betas", "n_star"):
        if not _conforms(cfg.get(key), _POSITIVE):
            raise PackageError(f"manifest config.{key} must be a positive integer", path=path, got=cfg.get(key))
    if not isinstance(m["joint_names"], list) or len(m["joint_names"]) != cfg["n_joints"]:
        raise PackageError(
            "manifest joint_names do not match config.n_joints",
            path=path,
            expected=cfg["n_joints"],
            got=len(m["joint_names"]) if isinstance(m["joint_names"], list) else m["joint_names"],
        )
    if not isinstance(graphs, dict) or ENCODER not in graphs:
        raise PackageError(
            f"manifest must describe '{ENCODER}'",
            path=path,
            got=", ".join(graphs) if isinstance(graphs, dict) else graphs,
        )
    files = {}
    for name, g in graphs.items():
        if not isinstance(g, dict):
            raise PackageError(f"graph '{name}' must be an object", path=path, got=g)
        f = g.get("file")
        if not _conforms(f, _GRAPH_FILE):
            raise PackageError(f"graph '{name}' file must be a .onnx file name in the package folder", path=path, got=f)
        if f in files:
            raise PackageError(
                f"graphs '{files[f]}' and '{name}' name the same file (one name per graph)", path=path, got=f
            )
        files[f] = name
        role = g.get("role")
        want_role = (
            ROLES[ENCODER] if name == ENCODER else ROLES[BODY] if name.startswith(BODY + "_") else ROLES[DEFORMER]
        )
        if role != want_role:
            raise PackageError(f"graph '{name}' has the wrong role", path=path, expected=want_role, got=role)
        _check_io(name, "inputs", g.get("inputs"), path)
        _check_io(name, "outputs", g.get("outputs"), path)
        if not m.get("upgraded_from"):  # schema 3 as written: WebGPU's and engines' input dtypes only
            bad = [f"{i['name']} {i['dtype']}" for i in g["inputs"] if i["dtype"] not in PORTABLE_INPUT_DTYPES]
            if bad:
                raise PackageError(
                    f"graph '{name}' has inputs of a dtype schema {SCHEMA_VERSION} does not allow",
                    path=path,
                    expected=" or ".join(PORTABLE_INPUT_DTYPES),
                    got=", ".join(bad),
                )
        if role == ROLES[BODY]:
            _check_body(name, g, m, path)
    if len(graphs[ENCODER]["outputs"]) != 1:
        raise PackageError("the garment encoder must have one output", path=path, got=len(graphs[ENCODER]["outputs"]))
    code = code_name(m)
    seen_effects = {}
    decs = deformers(m)
    if not decs:
        raise PackageError("manifest has no deformer graph", path=path)
    for name, g in decs.items():
        e = g.get("effects")
        if not _conforms(e, _EFFECTS):
            raise PackageError(
                f"deformer '{name}' has malformed effects",
                path=path,
                expected="{skinning: lbs|dqs, wrinkles: bool, dynamics: bool}",
                got=e,
            )
        if name != deformer_name(e):
            raise PackageError(
                f"deformer '{name}' is not named by its effects", path=path, expected=deformer_name(e), got=name
            )
        key = (e["skinning"], e["wrinkles"], e["dynamics"])
        if key in seen_effects:
            raise PackageError(f"deformers '{seen_effects[key]}' and '{name}' have the same effects", path=path, got=e)
        seen_effects[key] = name
        win = next((i["shape"] for i in g["inputs"] if i["name"] == "window"), None)
        if win is None or len(win) != 3 or g.get("window") != win[1] or (not e["dynamics"] and win[1] != 1):
            raise PackageError(
                f"deformer '{name}' window does not match its window input",
                path=path,
                expected="window = T of input window (B, T, 3S), T = 1 without dynamics",
                got=f"window {g.get('window')}, input {win}",
            )
        if code not in [i["name"] for i in g["inputs"]]:
            raise PackageError(f"deformer '{name}' does not take the encoder's output '{code}'", path=path)
    if m["default_deformer"] not in decs:
        raise PackageError(
            "default_deformer is not a deformer graph",
            path=path,
            expected=", ".join(sorted(decs)),
            got=m["default_deformer"],
        )
    w = m.get("weights")
    if w is not None and (not isinstance(w, dict) or not _conforms(w.get("file"), _WEIGHTS_FILE)):
        raise PackageError("manifest weights must name a file in the package folder", path=path, got=w)
    if w is not None and w["file"] in files:
        raise PackageError("manifest weights file is also a graph file", path=path, got=w["file"])
    if TRAINING_GARMENTS in m:
        _check_training_garments(m[TRAINING_GARMENTS], cfg["n_star"], path)
    if TRAINING_MOTIONS in m and not _conforms(m[TRAINING_MOTIONS], _TRAINING_MOTIONS):
        raise PackageError(
            f"manifest {TRAINING_MOTIONS} is malformed",
            path=path,
            expected='{"metric": str, "rate": number > 0, "joints": [int], "motions": [{"name": str, "frames": int, '
            '"speeds": str}, ...]}',
            got=str(m[TRAINING_MOTIONS])[:200],
        )


def _check_body(name, g, m, path) -> None:
    """A body graph's entry: named by its skinning, the body's inputs and outputs in order."""
    if g.get("skinning") not in SKINNING or name != body_name(g["skinning"]):
        raise PackageError(
            f"body graph '{name}' is not named by its skinning",
            path=path,
            expected="body_lbs (skinning lbs) or body_dqs (skinning dqs)",
            got=g.get("skinning"),
        )
    ins, outs = [i["name"] for i in g["inputs"]], [o["name"] for o in g["outputs"]]
    if ins != list(BODY_INPUTS) or outs != list(BODY_OUTPUTS):
        raise PackageError(
            f"body graph '{name}' has other inputs or outputs than a body graph",
            path=path,
            expected=f"{', '.join(BODY_INPUTS)} -> {', '.join(BODY_OUTPUTS)}",
            got=f"{', '.join(ins)} -> {', '.join(outs)}",
        )
    joints = g["inputs"][1]["shape"]
    if len(joints) != 3 or joints[1] != len(m["joint_names"]):
        raise PackageError(
            f"body graph '{name}' poses another skeleton than the model's",
            path=path,
            expected=f"poses (B, {len(m['joint_names'])}, 3)",
            got=joints,
        )


def _check_training_garments(t, n_star: int, path) -> None:
    ok = _conforms(t, _TRAINING_GARMENTS) and all(len(g["descriptor"]) == n_star for g in t["garments"])
    if not ok:
        raise PackageError(
            f"manifest {TRAINING_GARMENTS} is malformed",
            path=path,
            expected=f'{{"metric": "eq19", "threshold": number >= 0 or null, "garments": '
            f'[{{"name": str, "descriptor": [{n_star} numbers], "openings": int >= 0 (optional)}}, ...]}}',
            got=str(t)[:200],
        )


def manifest_schema() -> dict:
    """The JSON Schema (draft 2020-12) of a schema-3 ``manifest.json`` (``docs/manifest.schema.json``); input
    dtypes are float32 or int32 (manifests upgraded from schema 2, ``upgraded_from``, may keep int64 and bool)."""
    tensor, sha, fname = _TENSOR, _SHA, _GRAPH_FILE
    graph_common = {
        "file": fname,
        "sha256": sha,
        "inputs": {"type": "array", "minItems": 1, "items": {"$ref": "#/$defs/tensor"}},
        "outputs": {"type": "array", "minItems": 1, "items": {"$ref": "#/$defs/tensor"}},
    }
    effects = _EFFECTS
    encoder = {
        "type": "object",
        "required": ["role", "file", "inputs", "outputs"],
        "properties": dict(
            graph_common, role={"const": ROLES[ENCODER]}, outputs=dict(graph_common["outputs"], maxItems=1)
        ),
    }
    deformer = {
        "type": "object",
        "required": ["role", "file", "inputs", "outputs", "effects", "window"],
        "properties": dict(
            graph_common,
            role={"const": ROLES[DEFORMER]},
            effects={"$ref": "#/$defs/effects"},
            window={"type": "integer", "minimum": 1},
        ),
    }
    body = {
        "type": "object",
        "required": ["role", "file", "inputs", "outputs", "skinning"],
        "properties": dict(
            graph_common,
            role={"const": ROLES[BODY]},
            skinning={"enum": list(SKINNING)},
            body={
                "type": "object",
                "description": "the body posed: its name and the sha256 of its arrays (segadeform.body.identity)",
                "properties": {"name": {"type": "string"}, "sha256": sha},
            },
        ),
    }
    return {
        "$schema": "https://json-schema.org/draft/2020-12/schema",
        "$id": "https://segadeform.invalid/manifest.schema.json",
        "title": f"segadeform model package manifest (schema {SCHEMA_VERSION})",
        "description": "manifest.json of a segadeform model package; docs/package.md says what each field and "
        # (the module's name when the published schema was made: kept so the file stays the same)
        "each graph input means. Generated by segadeform.contracts.model_package.manifest_schema().",
        "type": "object",
        "required": [
            "format",
            "schema_version",
            "opset",
            "producer",
            "config",
            "joint_names",
            "parents",
            "units",
            "up_axis",
            "graphs",
            "default_deformer",
        ],
        "properties": {
            "format": {"const": FORMAT},
            "schema_version": {"const": SCHEMA_VERSION},
            "opset": _OPSET,
            "producer": {"type": "string"},
            "exporter": {"enum": ["dynamo", "legacy"]},
            "torch": {"type": "string"},
            "precision": {"enum": ["fp32", "fp16-weights", "int8"]},
            "upgraded_from": {"type": "integer"},
            "config": {
                "type": "object",
                "required": ["n_joints", "n_betas", "n_star", "feat_dim", "window", "skinning", "use_blend_shapes"],
                "properties": {
                    k: _POSITIVE for k in ("n_joints", "n_betas", "n_star", "feat_dim", "window", "ensemble")
                }
                | {
                    "skinning": {"enum": list(SKINNING)},
                    "use_blend_shapes": {"type": "boolean"},
                    "weights": {"enum": ["free", "residual"]},
                    "weight_prior": {"enum": list(WEIGHT_PRIORS)},
                },
            },
            "joint_names": {"type": "array", "items": {"type": "string"}, "minItems": 1},
            "parents": {"type": "array", "items": {"type": "integer", "minimum": -1}, "minItems": 1},
            "units": {"const": "m"},
            "up_axis": {"const": "y"},
            "graphs": {
                "type": "object",
                "required": [ENCODER],
                "properties": {ENCODER: {"$ref": "#/$defs/encoder"}},
                "patternProperties": {
                    "^deformer_(lbs|dqs)(_nowrinkles)?(_static)?$": {"$ref": "#/$defs/deformer"},
                    "^body_(lbs|dqs)$": {"$ref": "#/$defs/body"},
                },
                "additionalProperties": False,
                "minProperties": 2,
            },
            "default_deformer": {"type": "string", "pattern": "^deformer_"},
            "weights": {
                "type": "object",
                "required": ["file", "sha256", "bytes"],
                "additionalProperties": False,
                "properties": {"file": _WEIGHTS_FILE, "sha256": sha, "bytes": {"type": "integer", "minimum": 0}},
            },
            "ops": {
                "type": "object",
                "additionalProperties": {"type": "object", "additionalProperties": {"type": "integer"}},
            },
            TRAINING_GARMENTS: _TRAINING_GARMENTS,
            TRAINING_MOTIONS: _TRAINING_MOTIONS,
        },
        "$defs": {"tensor": tensor, "effects": effects, "encoder": encoder, "deformer": deformer, "body": body},
    }


def write_manifest_schema(path) -> None:
    """Write :func:`manifest_schema` as JSON to ``path`` (how ``docs/manifest.schema.json`` is made)."""
    import json

    from ..io.atomic import atomic_open

    with atomic_open(path, "w", encoding="utf-8") as fh:
        fh.write(json.dumps(manifest_schema(), indent=2) + "\n")
