// segadeform's JavaScript core, shared by the Node runtime (index.js) and the browser runtime
// (runtimes/web): no Node or DOM APIs here, the onnxruntime module is passed in.
// The package format is docs/package.md; the container of scene bundles (.sgdb), garment assets (.sgda)
// and motion files (.sgdm) is src/segadeform/bundle.py.  Collisions: collide.js (the port of the C kernel); the cloth
// stage: cloth.js (the port of _cloth.c).

import { clothFrames, DEFAULT_CLOTH, parseCloth } from "./cloth.js";
import { BodyCollider, pushOutFrames } from "./collide.js";

export { BodyCollider, clothFrames, DEFAULT_CLOTH, parseCloth, pushOutFrames };
export const FORMAT = "segadeform-model-package";
/** The collision margin when none is given (metres): segadeform.scene.Effects.collision_margin's default. */
export const DEFAULT_COLLISION_MARGIN = 0.004;
const MAGIC = "SEGADEFORM-BUNDLE 1\n";
const DTYPES = {
  f32: [Float32Array, 4], f64: [Float64Array, 8], i32: [Int32Array, 4], i64: [BigInt64Array, 8], u8: [Uint8Array, 1],
};

/** What to make of a file that is not a bundle, by its extension: a mesh or a motion the runtimes cannot read. */
export function notBundleHint(where) {
  const ext = (String(where).match(/\.[^./\\]+$/) || [""])[0].toLowerCase();
  if ([".obj", ".ply", ".stl", ".off", ".mhclo"].includes(ext)) {
    return " (a mesh: these runtimes read a garment asset, `segadeform garment export GARMENT -o G.sgda`)";
  }
  if ([".bvh", ".amc", ".npz", ".glb", ".gltf", ".fbx"].includes(ext)) {
    return " (a motion file: these runtimes read one made by `segadeform motion export MOTION -o M.sgdm`)";
  }
  return "";
}

/** Parse a bundle from bytes: { arrays: {name: {dtype, shape, data}}, meta }. */
export function parseBundle(bytes, where = "bundle") {
  const buf = bytes instanceof Uint8Array ? bytes : new Uint8Array(bytes);
  const head = new TextDecoder().decode(buf.subarray(0, Math.min(buf.length, 1 << 20)));
  if (!head.startsWith(MAGIC)) throw new Error(`${where}: not a segadeform bundle${notBundleHint(where)}`);
  const end = head.indexOf("\nEND\n");
  if (end < 0) throw new Error(`${where}: bundle header has no END line`);
  const lines = head.slice(MAGIC.length, end).split("\n");
  const n = parseInt(lines[0], 10);
  if (!(n >= 0) || lines.length !== n + 2 || !lines[n + 1].startsWith("meta ")) {
    throw new Error(`${where}: malformed bundle header`);
  }
  const headerBytes = new TextEncoder().encode(head.slice(0, end + 5)).length;
  const start = Math.ceil(headerBytes / 64) * 64;
  let meta;
  try {
    meta = JSON.parse(lines[n + 1].slice(5));
  } catch (e) { // (NaN or Infinity in the meta said "Unexpected token 'N'" and no file: a user's trial)
    throw new Error(`${where}: the header's meta is not valid JSON (${e.message.split("\n")[0]})`);
  }
  const arrays = {};
  for (const ln of lines.slice(1, n + 1)) {
    const t = ln.trim().split(/\s+/);
    const [name, dt] = t;
    const nd = parseInt(t[2], 10);
    const shape = t.slice(3, 3 + nd).map((x) => parseInt(x, 10));
    const off = parseInt(t[3 + nd], 10);
    const nbytes = parseInt(t[4 + nd], 10);
    const [Ctor, size] = DTYPES[dt] || [];
    const count = shape.reduce((a, b) => a * b, 1);
    if (!Ctor || count * size !== nbytes || start + off + nbytes > buf.length) {
      throw new Error(`${where}: bundle array ${name} does not fit the file`);
    }
    // copy into an aligned buffer of the right type
    const raw = buf.slice(start + off, start + off + nbytes);
    arrays[name] = { dtype: dt, shape, data: new Ctor(raw.buffer, raw.byteOffset, count) };
  }
  return { arrays, meta };
}

/**
 * Check a parsed manifest and return it in schema-3 form (schema 1 and 2 upgraded: `graphs` holds every graph
 * once, each deformer with its `effects`; `default_deformer` names the model's own; schema-2 graphs keep their
 * int64/bool inputs, fed as their manifest entries say).
 */
export function readManifest(m, where = "manifest.json") {
  if (m.format !== FORMAT && m.schema_version !== 1) throw new Error(`${where}: not a segadeform model package`);
  if (m.schema_version === 1) m = upgradeManifest(m);
  else if (m.schema_version === 2) m = { ...m, schema_version: 3, upgraded_from: 2 };
  else if (m.schema_version !== 3) {
    throw new Error(`${where}: unsupported manifest schema version (expected 1, 2 or 3, got ${m.schema_version})`);
  }
  if (!m.graphs || !m.graphs.garment_encoder) throw new Error(`${where}: manifest has no garment_encoder`);
  return m;
}

/** Schema 1 -> 3 (segadeform.package_spec.upgrade_manifest): one name per graph. */
function upgradeManifest(m) {
  const graphs = { garment_encoder: { ...m.graphs.garment_encoder, role: "encoder" } };
  let dflt = null;
  for (const [name, v] of Object.entries(m.variants || {})) {
    graphs[name] = { ...v, role: "deformer" };
    if (v.file === m.graphs.deformer.file) dflt = name;
  }
  if (dflt === null) {
    const c = m.config;
    const effects = { skinning: c.skinning, wrinkles: c.use_blend_shapes, dynamics: true };
    dflt = `deformer_${c.skinning}${c.use_blend_shapes ? "" : "_nowrinkles"}`;
    const win = m.graphs.deformer.inputs.find((i) => i.name === "window").shape[1];
    graphs[dflt] = { ...m.graphs.deformer, role: "deformer", effects, window: win };
  }
  const { variants, ...rest } = m;
  return { ...rest, format: FORMAT, schema_version: 3, graphs, default_deformer: dflt, upgraded_from: 1 };
}

/** The deformer graph for a set of effects: the one whose effects equal them exactly (skinning, wrinkles, dynamics). */
export function pickVariant(manifest, effects) {
  for (const [name, g] of Object.entries(manifest.graphs)) {
    const e = g.effects;
    if (g.role === "deformer" && e.skinning === effects.skinning && e.wrinkles === effects.wrinkles &&
        e.dynamics === effects.dynamics) {
      return { name, spec: g };
    }
  }
  const have = Object.entries(manifest.graphs).filter(([, g]) => g.role === "deformer").map(([n]) => n).join(", ");
  throw new Error(`the package has no deformer graph for effects ${JSON.stringify(effects)} (expected one of ${have})`);
}

/**
 * The effects of a run that names none, as `segadeform run` without --effects: the model's own (its default
 * deformer's) and collisions when the package can pose the body (it has a body graph).
 */
export function defaultEffects(manifest) {
  return { ...manifest.graphs[manifest.default_deformer].effects, collisions: hasBody(manifest), cloth: false };
}

/**
 * Effects as `segadeform run --effects` reads them (src/segadeform/settings/effects.py): a complete list such as
 * "dqs,dynamics,wrinkles,collisions" (what is not named is off; lbs unless dqs is named), `none` (every effect off),
 * or signed changes to `base` (the run's default effects: the model's own and collisions with a body graph) such as
 * "+cloth" or "dqs,-wrinkles" (lbs/dqs may join either form).  Collisions are not a graph: the push-out out of the
 * body posed by the package's body graph (collide.js), after the deformer; cloth (off unless named) is the cloth stage
 * (cloth.js), which resolves contact itself: with it the push-out is not run.
 */
export function parseEffects(text, base = null) {
  const items = text.split(",").map((s) => s.trim()).filter(Boolean);
  if (!items.length) {
    throw new Error(`an empty effects list (expected effect names, signed changes (+name,-name) or none, got "${text}")`);
  }
  const names = ["dynamics", "wrinkles", "collisions", "cloth"];
  const off = { skinning: "lbs", wrinkles: false, dynamics: false, collisions: false, cloth: false };
  if (items.length === 1 && items[0] === "none") return off;
  const picked = items.filter((i) => i === "lbs" || i === "dqs");
  const named = items.filter((i) => i !== "lbs" && i !== "dqs");
  const signed = named.map((i) => i[0] === "+" || i[0] === "-");
  if (signed.some(Boolean) && !signed.every(Boolean)) {
    throw new Error(`effects mix a complete list with changes (expected names only or signed changes only, got ${text})`);
  }
  const complete = !signed.some(Boolean);
  if (!complete && !base) throw new Error(`signed effect changes need the run's default effects (got ${text})`);
  const stripped = named.map((i) => i.replace(/^[+-]/, ""));
  const twice = stripped.find((n, k) => stripped.indexOf(n) !== k);
  if (twice !== undefined) throw new Error(`effects name ${twice} twice (expected each effect once, got ${text})`);
  const on = complete ? { ...off } : { ...off, ...base };
  for (const item of named) {
    const name = item.replace(/^[+-]/, "");
    if (!names.includes(name)) {
      throw new Error(`unknown effect '${item}' (expected lbs, dqs, ${names.map((n) => `[+-]${n}`).join(", ")} or none)`);
    }
    on[name] = item[0] !== "-";
  }
  if (picked.includes("lbs") && picked.includes("dqs")) throw new Error("name one skinning (expected lbs or dqs, got both)");
  on.skinning = picked.length ? picked[picked.length - 1] : complete ? "lbs" : base.skinning;
  return on;
}

/** Whether a package has body graphs (schema 3 with `segadeform export-body`): what collisions need. */
export function hasBody(manifest) {
  return Object.values(manifest.graphs).some((g) => g.role === "body");
}

/** The body graph posing with `skinning` ({name, spec}), or null when the package has no body graph. */
export function pickBody(manifest, skinning) {
  const bodies = Object.entries(manifest.graphs).filter(([, g]) => g.role === "body");
  if (!bodies.length) return null;
  const hit = bodies.find(([, g]) => g.skinning === skinning);
  if (!hit) throw new Error(`the package has no body graph for skinning ${skinning} (expected one of ${bodies.map(([n]) => n).join(", ")})`);
  return { name: hit[0], spec: hit[1] };
}

const ASSET_KIND = "segadeform-garment-asset";
const MOTION_KIND = "segadeform-motion";

function need(parsed, name, dtype, ndim, where) {
  const a = parsed.arrays[name];
  if (!a || a.dtype !== dtype || a.shape.length !== ndim) {
    throw new Error(`${where}: field '${name}' is missing or malformed (expected ${dtype} with ${ndim} dims, got ` +
      `${a ? `${a.dtype} ${JSON.stringify(a.shape)}` : "none"})`);
  }
  return a;
}

/**
 * Check a parsed garment asset (.sgda, docs/package.md): schema 1 or 2.  Animating it needs one prepared for a
 * body shape (schema 2 with betas, log_wbody and the body: `segadeform garment export`).
 */
export function readAsset(parsed, where = "garment asset") {
  const { meta } = parsed;
  if (meta.kind !== ASSET_KIND) throw new Error(`${where}: not a garment asset (expected meta.kind '${ASSET_KIND}', got ${JSON.stringify(meta.kind)})`);
  if (meta.schema_version !== 1 && meta.schema_version !== 2) {
    throw new Error(`${where}: unsupported garment asset schema version (expected 1 or 2, got ${meta.schema_version})`);
  }
  const v = need(parsed, "vertices", "f64", 2, where);
  const N = v.shape[0];
  for (const [k, dt] of [["faces", "i32"], ["normals", "f32"], ["features", "f32"], ["nbr", "i32"], ["mask", "u8"], ["joints", "f64"]]) {
    need(parsed, k, dt, 2, where);
  }
  need(parsed, "descriptor", "f64", 1, where);
  const { nbr, mask, features, joints } = parsed.arrays;
  if (nbr.shape[0] !== N || mask.shape[0] !== N || mask.shape[1] !== nbr.shape[1] || features.shape[0] !== N ||
      features.shape[1] !== 6 + joints.shape[0]) {
    throw new Error(`${where}: fields do not agree (expected nbr and mask (${N}, K), features (${N}, ${6 + joints.shape[0]}), ` +
      `got ${JSON.stringify([nbr.shape, mask.shape, features.shape])})`);
  }
  for (let i = 0; i < nbr.data.length; i++) {
    if (!(nbr.data[i] >= 0 && nbr.data[i] < N)) throw new Error(`${where}: nbr index out of range (expected 0..${N - 1}, got ${nbr.data[i]})`);
  }
  const faces = parsed.arrays.faces;
  if (faces.shape[1] !== 3 || faces.shape[0] < 1) {
    throw new Error(`${where}: field 'faces' has the wrong shape (expected (F, 3), F >= 1, got ${JSON.stringify(faces.shape)})`);
  }
  for (let i = 0; i < faces.data.length; i++) {
    if (!(faces.data[i] >= 0 && faces.data[i] < N)) throw new Error(`${where}: face index out of range (expected 0..${N - 1}, got ${faces.data[i]})`);
  }
  // values, as the Python runtime checks them (NaN or inf here gave a cache of NaN with exit 0: a user's trial)
  for (const k of ["vertices", "normals", "features", "joints", "descriptor", "betas", "log_wbody"]) {
    if (parsed.arrays[k]) finite(parsed.arrays[k], k, where);
  }
  for (const k of ["vertices", "joints"]) { // positions within 10 km, as Python's GarmentAsset holds them
    const d = parsed.arrays[k].data;
    for (let i = 0; i < d.length; i++) {
      if (Math.abs(d[i]) > 1e4) throw new Error(`${where}: field '${k}' lies beyond 10 km (expected |x| <= 10000 m, got ${d[i]})`);
    }
  }
  return parsed;
}

/** Throw unless every value of a parsed array is finite (a field named `name` of `where`). */
function finite(a, name, where) {
  const d = a.data;
  for (let i = 0; i < d.length; i++) {
    if (!Number.isFinite(d[i])) throw new Error(`${where}: field '${name}' contains NaN or inf (at value ${i})`);
  }
}

/**
 * The same rotations with every angle in [0, pi] (Python's canonical_axis_angle, segadeform.body.rotations): an
 * angle above pi is taken modulo 2 pi, and one still above pi becomes 2 pi minus it about the opposite axis; a
 * vector in range is left bit for bit.  In place on a Float32Array of axis-angle triples (computed in double, as
 * Python computes them before the network's float32).
 */
export function canonicalAxisAngle(r) {
  for (let i = 0; i < r.length; i += 3) {
    const x = r[i], y = r[i + 1], z = r[i + 2];
    const t = Math.sqrt(x * x + y * y + z * z);
    if (!(t > Math.PI)) continue;
    let a = t % (2 * Math.PI);
    let s = 1;
    if (a > Math.PI) {
      a = 2 * Math.PI - a;
      s = -1;
    }
    r[i] = (s * x / t) * a;
    r[i + 1] = (s * y / t) * a;
    r[i + 2] = (s * z / t) * a;
  }
  return r;
}

/** Check a parsed motion file (.sgdm): poses f32 (T, S, 3), trans f32 (T, 3), meta.fps. */
export function readMotion(parsed, where = "motion file") {
  const { meta } = parsed;
  if (meta.kind !== MOTION_KIND) throw new Error(`${where}: not a motion file (expected meta.kind '${MOTION_KIND}', got ${JSON.stringify(meta.kind)})`);
  if (meta.schema_version !== 1) throw new Error(`${where}: unsupported motion file schema version (expected 1, got ${meta.schema_version})`);
  const p = need(parsed, "poses", "f32", 3, where);
  const t = need(parsed, "trans", "f32", 2, where);
  if (p.shape[2] !== 3 || p.shape[0] < 1 || t.shape[0] !== p.shape[0] || t.shape[1] !== 3) {
    throw new Error(`${where}: poses and trans do not fit (expected (T, S, 3) and (T, 3), got ${JSON.stringify(p.shape)} and ${JSON.stringify(t.shape)})`);
  }
  if (!(typeof meta.fps === "number" && meta.fps >= 1 && meta.fps <= 1000)) {
    throw new Error(`${where}: meta.fps must be a frame rate (expected 1..1000, got ${JSON.stringify(meta.fps)})`);
  }
  if (meta.start_frame !== undefined && !(Number.isInteger(meta.start_frame) && Math.abs(meta.start_frame) <= 2 ** 31 - 1)) {
    throw new Error(`${where}: meta.start_frame must be a frame number (expected an integer of 32 bits, got ${meta.start_frame})`);
  }
  // values, as the Python runtime checks them: finite, translations within 10 km (segadeform.bounds), and every
  // rotation written one way (a turn more about a joint's axis moved the garment 2 cm here, not in Python)
  finite(p, "poses", where);
  finite(t, "trans", where);
  for (let i = 0; i < t.data.length; i++) {
    if (Math.abs(t.data[i]) > 1e4) throw new Error(`${where}: field 'trans' is beyond 10 km (expected |translation| <= 10000 m, got ${t.data[i]})`);
  }
  if (Array.isArray(meta.betas) && !meta.betas.every((b) => Number.isFinite(b))) {
    throw new Error(`${where}: meta.betas contains NaN or inf (got ${JSON.stringify(meta.betas)})`);
  }
  canonicalAxisAngle(p.data);
  return parsed;
}

const f32 = (a) => (a instanceof Float32Array ? a : Float32Array.from(a));

/**
 * The model inputs of a source, in one form: a scene bundle, or { asset, motion } (parsed .sgda and .sgdm).
 * Returns { features, nbr, mask, descriptor, betas, rest, joints, log_wbody, poses, trans, faces, N, K, S, T,
 * D, F, effects (the bundle's, else undefined), body (the asset's body label), fps }.
 */
export function sceneInputs(source) {
  if (source.asset) {
    const A = source.asset.arrays, M = source.motion.arrays, am = source.asset.meta, mm = source.motion.meta;
    if (!A.betas || !A.log_wbody || !am.body) {
      throw new Error("the garment asset is not prepared for a body shape (expected a schema-2 asset with betas, " +
        "log_wbody and body: segadeform garment export GARMENT --betas ... -o G.sgda)");
    }
    const S = A.joints.shape[0];
    if (M.poses.shape[1] !== S) throw new Error(`the motion has ${M.poses.shape[1]} joints, the garment asset ${S}`);
    const warnings = [];
    if (mm.body && mm.body.sha256 !== am.body.sha256) warnings.push("the motion was retargeted onto another body than the garment asset's");
    if (mm.betas && mm.betas.some((b, i) => Math.abs(b - (A.betas.data[i] || 0)) > 1e-6)) { // (C++'s tolerance)
      warnings.push("the motion was retargeted onto another body shape (betas) than the garment asset's");
    }
    return {
      features: A.features.data, nbr: A.nbr.data, mask: A.mask.data, descriptor: f32(A.descriptor.data),
      betas: f32(A.betas.data), rest: f32(A.vertices.data), joints: f32(A.joints.data), log_wbody: A.log_wbody.data,
      poses: M.poses.data, trans: M.trans.data, faces: A.faces.data, N: A.vertices.shape[0], K: A.nbr.shape[1], S,
      T: M.poses.shape[0], D: 3 * S, F: A.features.shape[1], effects: undefined, body: am.body, fps: mm.fps, warnings,
    };
  }
  const { arrays: A, meta } = source;
  return {
    features: A.features.data, nbr: A.nbr.data, mask: A.mask.data, descriptor: A.descriptor.data, betas: A.betas.data,
    rest: A.rest.data, joints: A.joints.data, log_wbody: A.log_wbody ? A.log_wbody.data : null, poses: A.poses.data,
    trans: A.trans.data, faces: A.faces ? A.faces.data : null, N: A.rest.shape[0], K: A.nbr.shape[1],
    S: A.joints.shape[0], T: A.poses.shape[0], D: A.poses.shape[1], F: A.features.shape[1], effects: meta.effects,
    body: null, fps: meta.fps, warnings: [],
  };
}

/** Feed for an input spec from a typed array, in the dtype the graph's manifest entry names (int32 indices become
 * int64 and 0/1 masks bool for schema-2 graphs; schema 3 takes int32 and float32). */
function feed(ort, spec, arr, dims) {
  if (spec.dtype === "int64") {
    const out = new BigInt64Array(arr.length);
    for (let i = 0; i < arr.length; i++) out[i] = BigInt(arr[i]);
    return new ort.Tensor("int64", out, dims);
  }
  if (spec.dtype === "int32") return new ort.Tensor("int32", arr instanceof Int32Array ? arr : Int32Array.from(arr), dims);
  if (spec.dtype === "bool") return new ort.Tensor("bool", Uint8Array.from(arr, (x) => (x ? 1 : 0)), dims);
  return new ort.Tensor("float32", f32(arr), dims);
}

/** The model's betas from a source's (zero-padded or cut to the model's count; a cut coefficient must be 0). */
function modelBetas(betas, nb) {
  const out = new Float32Array(nb);
  for (let i = 0; i < betas.length; i++) {
    if (i < nb) out[i] = betas[i];
    else if (betas[i] !== 0) throw new Error(`too many shape coefficients for this model (expected <= ${nb}, got ${betas.length})`);
  }
  return out;
}

/**
 * Animate a source with a package's graphs: a scene bundle, or { asset, motion } (parsed .sgda and .sgdm).
 * `session(spec)` returns an onnxruntime InferenceSession for a graph's manifest entry.
 * Returns { frames: Float32Array (T*N*3), T, N, msPerFrame, variant, effects, faces, fps, warnings }.
 * options: { effects (default: the bundle's, else defaultEffects), batch (8), force (false: a motion retargeted onto another
 * body or shape than the asset's is refused; true: played, with a warning) }.  With effects.collisions the frames
 * are the deformer's: the host pushes them out of the posed body afterwards (poseBodyWith, collideWith).
 */
export async function animateWith(ort, manifest, source, session, options = {}) {
  const I = sceneInputs(source);
  // a motion made for another body or shape is refused, as `segadeform run` and the command lines refuse it (the
  // API played it with a warning); options.force plays it, the warning kept
  const other = I.warnings.find((w) => w.startsWith("the motion was retargeted onto another"));
  if (other && !options.force) {
    throw new Error(`${other} (expected a motion exported for the asset's body and betas: segadeform motion export ` +
      "... --betas ..., or the option force: true)");
  }
  const effects = { collisions: false, cloth: false, ...(options.effects || I.effects || defaultEffects(manifest)) };
  if (options.collisionMargin !== undefined) checkMargin(options.collisionMargin);
  if ((effects.collisions || effects.cloth) && !hasBody(manifest)) {
    throw new Error(`${effects.cloth ? "the cloth stage needs" : "collisions need"} the posed body, and the package has ` +
      "no body graph (segadeform export-body [BODY] -o PACKAGE adds one)");
  }
  if (effects.cloth && !source.asset) {
    throw new Error("the cloth stage needs a garment asset and a motion file (expected .sgda and .sgdm, got a scene bundle)");
  }
  const batch = options.batch || 8;
  const encSpec = manifest.graphs.garment_encoder;
  const { name: variant, spec: decSpec } = pickVariant(manifest, effects);
  const enc = await session(encSpec);
  const dec = await session(decSpec);
  const { N, K, S, T, D } = I;
  const inDec = Object.fromEntries(decSpec.inputs.map((i) => [i.name, i]));
  const window = inDec.window.shape[1];
  const nb = inDec.betas.shape[1];
  const betasRow = modelBetas(I.betas, nb);
  const t0 = performance.now();
  // the encoder's inputs, fed by name (older encoders also take betas)
  const encArrays = {
    features: [I.features, [1, N, I.F]], nbr: [I.nbr, [N, K]], mask: [I.mask, [N, K]],
    descriptor: [I.descriptor, [1, I.descriptor.length]], betas: [betasRow, [1, nb]],
  };
  const encFeeds = {};
  for (const i of encSpec.inputs) {
    if (!encArrays[i.name]) throw new Error(`the garment encoder takes '${i.name}', which this runtime cannot feed`);
    encFeeds[i.name] = feed(ort, i, ...encArrays[i.name]);
  }
  const encOut = await enc.run(encFeeds);
  // its one output, without the batch axis, is a deformer input of the same name: g (N, K S), K networks of an ensemble (older: P (N, S, F_enc))
  const codeName = encSpec.outputs[0].name;
  const code = encOut[codeName];
  const codeT = new ort.Tensor("float32", await code.getData(), code.dims.slice(1));
  const nbr = feed(ort, inDec.nbr, I.nbr, [N, K]);
  const mask = feed(ort, inDec.mask, I.mask, [N, K]);
  const rest = feed(ort, inDec.rest, I.rest, [N, 3]);
  let lw = null;
  if (inDec.log_wbody) {
    if (!I.log_wbody) throw new Error("this model needs the body's weights at the garment (log_wbody), which the input lacks");
    const want = manifest.config.weight_prior || "nearest", got = I.body ? I.body.weight_prior || "nearest" : want;
    if (got !== want) {
      throw new Error(`the garment asset's log_wbody was made with the ${got} weight prior, the model wants ${want} ` +
        "(expected an asset from segadeform garment export --model PACKAGE)");
    }
    lw = feed(ort, inDec.log_wbody, I.log_wbody, [N, S]);
  }
  const frames = new Float32Array(T * N * 3);
  for (let lo = 0; lo < T; lo += batch) {
    const hi = Math.min(lo + batch, T);
    const B = hi - lo;
    // the motion window: frame t, t-1, ... t-window+1, frames before the first repeat the first
    const win = new Float32Array(B * window * D);
    for (let b = 0; b < B; b++) {
      for (let k = 0; k < window; k++) {
        const src = Math.max(lo + b - k, 0);
        win.set(I.poses.subarray(src * D, src * D + D), (b * window + k) * D);
      }
    }
    const betas = new Float32Array(B * nb);
    const joints = new Float32Array(B * S * 3);
    for (let b = 0; b < B; b++) {
      betas.set(betasRow, b * nb);
      joints.set(I.joints, b * S * 3);
    }
    const feeds = {
      [codeName]: codeT, window: new ort.Tensor("float32", win, [B, window, D]),
      betas: new ort.Tensor("float32", betas, [B, nb]), rest, nbr, mask,
      joints: new ort.Tensor("float32", joints, [B, S, 3]),
      trans: new ort.Tensor("float32", I.trans.slice(lo * 3, hi * 3), [B, 3]),
    };
    if (lw) feeds.log_wbody = lw;
    const out = await dec.run(feeds);
    frames.set(await out[decSpec.outputs[0].name].getData(), lo * N * 3);
  }
  const ms = (performance.now() - t0) / T;
  return { frames, T, N, msPerFrame: ms, variant, effects, faces: I.faces, fps: I.fps, warnings: I.warnings };
}

/**
 * Pose the body with the package's body graph for `skinning` (docs/package.md: betas (|beta|,), poses (B, S, 3),
 * trans (B, 3) in; vertices (B, V, 3), joints (B, S, 3), rest_joints (S, 3), faces (F, 3) out), over a source's
 * motion and body shape.  Returns { vertices (T*V*3), joints (T*S*3), restJoints, faces, V, T, msPerFrame, graph },
 * or throws when the package has no body graph or the garment asset was prepared for another body.
 */
export async function poseBodyWith(ort, manifest, source, session, { skinning = "lbs", batch = 8 } = {}) {
  const I = sceneInputs(source);
  const picked = pickBody(manifest, skinning);
  if (!picked) throw new Error("the package has no body graph (segadeform export-body [BODY] -o PACKAGE adds one)");
  const { name, spec } = picked;
  if (I.body && spec.body && I.body.sha256 !== spec.body.sha256) {
    throw new Error(`the garment asset was prepared for another body than the package's (expected ${spec.body.name} ` +
      `${spec.body.sha256.slice(0, 12)}, got ${I.body.name} ${I.body.sha256.slice(0, 12)})`);
  }
  const sess = await session(spec);
  const nb = spec.inputs[0].shape[0];
  const V = spec.outputs[0].shape[1], S = spec.inputs[1].shape[1];
  if (S !== I.S) throw new Error(`the body graph poses ${S} joints, the motion has ${I.S}`);
  const betas = feed(ort, spec.inputs[0], modelBetas(I.betas, nb), [nb]);
  const { T } = I;
  const vertices = new Float32Array(T * V * 3), joints = new Float32Array(T * S * 3);
  let restJoints = null, faces = null;
  const t0 = performance.now();
  for (let lo = 0; lo < T; lo += batch) {
    const hi = Math.min(lo + batch, T);
    const out = await sess.run({
      betas, poses: new ort.Tensor("float32", I.poses.slice(lo * S * 3, hi * S * 3), [hi - lo, S, 3]),
      trans: new ort.Tensor("float32", I.trans.slice(lo * 3, hi * 3), [hi - lo, 3]),
    });
    vertices.set(await out.vertices.getData(), lo * V * 3);
    joints.set(await out.joints.getData(), lo * S * 3);
    if (!restJoints) {
      restJoints = Float32Array.from(await out.rest_joints.getData());
      faces = Int32Array.from(await out.faces.getData());
    }
  }
  return { vertices, joints, restJoints, faces, V, T, msPerFrame: (performance.now() - t0) / T, graph: name };
}

/**
 * The body at rest: the package's body graph for `skinning` at zero pose and no translation (the shape of the source's
 * betas), V*3 float32: what the cloth stage measures each garment vertex's rest distance from, as `segadeform run`.
 */
export async function restBodyWith(ort, manifest, source, session, { skinning = "lbs" } = {}) {
  const I = sceneInputs(source);
  const picked = pickBody(manifest, skinning);
  if (!picked) throw new Error("the package has no body graph (segadeform export-body [BODY] -o PACKAGE adds one)");
  const sess = await session(picked.spec);
  const nb = picked.spec.inputs[0].shape[0], S = picked.spec.inputs[1].shape[1];
  const out = await sess.run({
    betas: feed(ort, picked.spec.inputs[0], modelBetas(I.betas, nb), [nb]),
    poses: new ort.Tensor("float32", new Float32Array(S * 3), [1, S, 3]),
    trans: new ort.Tensor("float32", new Float32Array(3), [1, 3]),
  });
  return Float32Array.from(await out.vertices.getData());
}

/**
 * The cloth stage on animateWith's frames (changed in place), as `segadeform run --effects=+cloth`: `body`
 * poseBodyWith's, `restBody` restBodyWith's, `source` the { asset, motion } animated.  Returns { contacts, pushed,
 * resets, firstReset, msPerFrame, settings, margin } (cloth.js clothFrames).
 */
export function clothWith(r, body, restBody, source, { settings = DEFAULT_CLOTH, margin = DEFAULT_COLLISION_MARGIN,
  batch = 8 } = {}) {
  checkMargin(margin);
  if (!body || body.error) throw new Error(`the cloth stage needs the posed body${body && body.error ? `: ${body.error}` : ""}`);
  if (body.T !== r.T) throw new Error(`the posed body has ${body.T} frames, the garment ${r.T}`);
  if (!source.asset) throw new Error("the cloth stage needs a garment asset (.sgda)");
  const A = source.asset.arrays;
  return clothFrames(r.frames, r.T, r.N, body.vertices, body.V, body.faces, restBody, A.vertices.data, A.faces.data,
    { settings: typeof settings === "string" ? parseCloth(settings) : settings, margin, dt: 1.0 / r.fps, batch });
}

/** A collision margin must be in [0, 1) metres, as a scene's collision_margin. */
export function checkMargin(margin) {
  if (!(typeof margin === "number" && margin >= 0 && margin < 1)) {
    throw new Error(`the collision margin must be in [0, 1) metres (got ${margin})`);
  }
}

/**
 * Collisions: push the garment's frames out of the posed body (`segadeform run`'s post-process: p' = closest +
 * margin * n for every vertex inside the body or closer than `margin`, up to 3 passes; collide.js).  `r` is
 * animateWith's result (its frames are changed in place), `body` poseBodyWith's.  Returns { moved (vertex-frames
 * moved), msPerFrame (collider build, refit and push-out), margin }.
 */
export function collideWith(r, body, { margin = DEFAULT_COLLISION_MARGIN, iterations = 3, batch = 8 } = {}) {
  checkMargin(margin);
  if (!body || body.error) throw new Error(`collisions need the posed body${body && body.error ? `: ${body.error}` : ""}`);
  if (body.T !== r.T) throw new Error(`the posed body has ${body.T} frames, the garment ${r.T}`);
  const c = pushOutFrames(r.frames, r.T, r.N, body.vertices, body.V, body.faces, { margin, iterations, batch });
  return { moved: c.moved, msPerFrame: c.msPerFrame, margin };
}

/** Parity of `got` against `expected` (same length): { maxAbs, rel (to the largest |expected|), finite, sameLength }. */
export function compareFrames(got, expected) {
  let maxAbs = 0, maxRef = 0, finite = true;
  const n = Math.min(got.length, expected.length);
  for (let i = 0; i < n; i++) {
    if (!Number.isFinite(got[i])) finite = false;
    maxAbs = Math.max(maxAbs, Math.abs(got[i] - expected[i]));
    maxRef = Math.max(maxRef, Math.abs(expected[i]));
  }
  return { maxAbs, rel: maxAbs / maxRef, finite, sameLength: got.length === expected.length };
}

/** PC2 point-cache bytes (header + T*N*3 float32 little-endian) for frames. */
export function pc2Bytes(frames, T, N, { startFrame = 0, sampleRate = 1 } = {}) {
  const out = new Uint8Array(32 + frames.byteLength);
  const dv = new DataView(out.buffer);
  const sig = "POINTCACHE2\0";
  for (let i = 0; i < sig.length; i++) out[i] = sig.charCodeAt(i);
  dv.setInt32(12, 1, true);
  dv.setInt32(16, N, true);
  dv.setFloat32(20, startFrame, true);
  dv.setFloat32(24, sampleRate, true);
  dv.setInt32(28, T, true);
  out.set(new Uint8Array(frames.buffer, frames.byteOffset, frames.byteLength), 32);
  return out;
}

/** Parse PC2 bytes: { frames: Float32Array (T*N*3), T, N }. */
export function parsePC2(bytes, where = "pc2") {
  const buf = bytes instanceof Uint8Array ? bytes : new Uint8Array(bytes);
  const sig = new TextDecoder().decode(buf.subarray(0, 11));
  if (buf.length < 32 || sig !== "POINTCACHE2") throw new Error(`${where}: not a PC2 point cache`);
  const dv = new DataView(buf.buffer, buf.byteOffset, buf.byteLength);
  const N = dv.getInt32(16, true);
  const T = dv.getInt32(28, true);
  if (N < 1 || T < 0 || 32 + T * N * 12 > buf.length) throw new Error(`${where}: PC2 header does not fit the file`);
  const frames = new Float32Array(buf.slice(32, 32 + T * N * 12).buffer);
  return { frames, T, N };
}

/** Parse an OBJ's vertices and faces (polygons fanned into triangles): { vertices: Float32Array, faces: Uint32Array }. */
export function parseOBJ(text, where = "obj") {
  const v = [];
  const f = [];
  const lines = text.split(/\r?\n/);
  for (let ln = 0; ln < lines.length; ln++) {
    const t = lines[ln].trim().split(/\s+/);
    if (t[0] === "v") {
      if (t.length < 4) throw new Error(`${where}:${ln + 1}: a vertex needs 3 coordinates`);
      v.push(+t[1], +t[2], +t[3]);
    } else if (t[0] === "f") {
      const idx = t.slice(1).map((s) => {
        const i = parseInt(s.split("/")[0], 10);
        return i < 0 ? v.length / 3 + i : i - 1;
      });
      if (idx.length < 3 || idx.some((i) => !(i >= 0 && i < v.length / 3))) {
        throw new Error(`${where}:${ln + 1}: face index out of range`);
      }
      for (let k = 1; k + 1 < idx.length; k++) f.push(idx[0], idx[k], idx[k + 1]);
    }
  }
  if (!v.length) throw new Error(`${where}: no vertices`);
  return { vertices: Float32Array.from(v), faces: Uint32Array.from(f) };
}
