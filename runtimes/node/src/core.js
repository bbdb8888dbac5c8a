// segadeform's JavaScript core, shared by the Node runtime (index.js) and the browser runtime
// (runtimes/web): no Node or DOM APIs here, the onnxruntime module is passed in.
// The package format is docs/package.md; the container of scene bundles (.sgdb), garment assets (.sgda)
// and motion files (.sgdm) is src/segadeform/bundle.py.  Collisions: collide.js (the port of the C kernel); the cloth
// stage: cloth.js (the port of _cloth.c).

import { clothStart, clothStep, DEFAULT_CLOTH, parseCloth } from "./cloth.js";
import { BodyCollider, pushOutFrames } from "./collide.js";

export { BodyCollider, DEFAULT_CLOTH, parseCloth, pushOutFrames };
export const FORMAT = "segadeform-model-package";
/** The collision margin when none is given (metres): segadeform.scene.Effects.collision_margin's default. */
export const DEFAULT_COLLISION_MARGIN = 0.004;
// the most vertex-frames (batch x garment vertices) one deformer call takes: a bigger garment runs fewer frames a
// call, as segadeform run does (runtimes/python/pipeline.py MAX_VERTEX_FRAMES; at 69k vertices batch 8 took 10 GB
// and its frames were not segadeform run's)
export const MAX_VERTEX_FRAMES = 32768;

/** Frames per deformer call for a garment of n vertices: batch, lowered (to at least 1) so that batch x n <=
 * MAX_VERTEX_FRAMES. */
export function effectiveBatch(batch, n) {
  return Math.max(1, Math.min(batch, Math.floor(MAX_VERTEX_FRAMES / Math.max(n, 1))));
}
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
  const body = Math.max(buf.length - start, 0); // bytes of array data
  // a whole decimal in 0..body (a crafted header's negative or huge sizes and offsets are refused here, never read)
  const size = (x) => (/^\d+$/.test(x || "") && Number(x) <= body ? Number(x) : -1);
  // a dimension: up to 2^31 (an array with a 0 in its shape holds no bytes: a 0-frame motion is (0, 24, 3))
  const dim = (x) => (/^\d+$/.test(x || "") && Number(x) <= 2 ** 31 ? Number(x) : -1);
  for (const ln of lines.slice(1, n + 1)) {
    const t = ln.trim().split(/\s+/);
    const [name, dt] = t;
    const nd = /^\d$/.test(t[2] || "") ? Number(t[2]) : -1;
    const shape = nd >= 0 ? t.slice(3, 3 + nd).map(dim) : [];
    const off = size(t[3 + nd]), nbytes = size(t[4 + nd]);
    const [Ctor, width] = DTYPES[dt] || [];
    const count = shape.some((d) => d < 0) ? -1 : shape.includes(0) ? 0
      : shape.reduce((a, b) => (a < 0 || a > body || b > body ? -1 : a * b), 1);
    if (!Ctor || nd < 0 || t.length !== 5 + nd || shape.some((d) => d < 0) || off < 0 || nbytes < 0 || count < 0 ||
        count * width !== nbytes || off + nbytes > body || start > buf.length) {
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
  // every file a plain name in the package folder, as Python's manifest schema has it: a name with a path in it read
  // a graph from outside the package (or a device, or a FIFO that hung: a security review)
  for (const [name, g] of Object.entries(m.graphs)) {
    if (typeof g.file !== "string" || !GRAPH_FILE.test(g.file)) {
      throw new Error(`${where}: graph '${name}' file must be a .onnx file name in the package folder ` +
        `(got ${JSON.stringify(g.file)})`);
    }
  }
  if (m.weights !== undefined && m.weights !== null &&
      (typeof m.weights.file !== "string" || !WEIGHTS_FILE.test(m.weights.file))) {
    throw new Error(`${where}: manifest weights must name a file in the package folder ` +
      `(got ${JSON.stringify(m.weights.file)})`);
  }
  return m;
}

/* a graph's and the shared weights' file names (segadeform.contracts.model_package's _GRAPH_FILE, _WEIGHTS_FILE) */
const GRAPH_FILE = /^[^./\\][^/\\]*\.onnx$/;
const WEIGHTS_FILE = /^[^./\\][^/\\]*$/;

/** Schema 1 -> 3 (segadeform.contracts.model_package.upgrade_manifest): one name per graph. */
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
  const names = Object.entries(manifest.graphs).filter(([, g]) => g.role === "deformer").map(([n]) => n);
  const only = names.length === 1 ? "; it has the model's own alone: `segadeform export` without --no-variants writes the others" : "";
  throw new Error(`the package has no deformer graph for effects ${JSON.stringify(effects)} (expected one of ${names.join(", ")}${only})`);
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
  if (picked.length > 1) throw new Error(`effects name ${picked[0]} twice (expected each effect once, got ${text})`);
  on.skinning = picked.length ? picked[picked.length - 1] : complete ? "lbs" : base.skinning;
  return on;
}

/**
 * The effects that run, named by the rule of `segadeform run` (Effects.label in src/segadeform/settings/effects.py)
 * and segadeform-run: the skinning, then dynamics, wrinkles and collisions that are on -- with the cloth stage, cloth
 * in collisions' place (its contact replaces the push-out, so collisions is not named apart).
 * effectsLabel({ skinning: "lbs", dynamics: true, wrinkles: true, collisions: true, cloth: true })
 * is "lbs, dynamics, wrinkles, cloth".
 */
export function effectsLabel(effects, separator = ", ") {
  const names = effects.cloth ? ["dynamics", "wrinkles", "cloth"] : ["dynamics", "wrinkles", "collisions"];
  return [effects.skinning, ...names.filter((n) => effects[n])].join(separator);
}

/** Whether a package has body graphs (schema 3 with `segadeform export-body`): what collisions need. */
export function hasBody(manifest) {
  return Object.values(manifest.graphs).some((g) => g.role === "body");
}

/**
 * Why a package's body graph poses another body than its model was trained on (manifest.training_body, which
 * `segadeform export` writes and `segadeform export-body --force` keeps when it gives the package another body's
 * graphs), or null when it poses that body (or the package records no training body).
 */
export function otherTrainingBody(manifest) {
  const trained = manifest.training_body;
  if (!trained || typeof trained.sha256 !== "string" || !trained.sha256) return null;
  for (const [name, spec] of Object.entries(manifest.graphs || {})) {
    // a graph that records no body is not checked (the Python runtime poses with numpy there)
    if (spec.role !== "body" || !spec.body || typeof spec.body.sha256 !== "string" || !spec.body.sha256 ||
      spec.body.sha256 === trained.sha256) continue;
    return `the package's body graph '${name}' poses another body than its model was trained on (expected ` +
      `${trained.name} ${trained.sha256.slice(0, 12)}, got ${spec.body.name} ${spec.body.sha256.slice(0, 12)})`;
  }
  return null;
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

/** The fields of a schema-3 asset whose model garment is a decimated copy of the garment as given (`segadeform
 * garment export --resolution R`), and their dtypes and dims. */
const CARRY_FIELDS = [["out_vertices", "f64", 2], ["out_faces", "i32", 2], ["carry_face", "i32", 1],
  ["carry_bary", "f64", 2], ["carry_offset", "f64", 1]];

/**
 * Check a parsed garment asset (.sgda, docs/package.md): schema 1, 2 or 3.  Animating it needs one prepared for a
 * body shape (schema 2 with betas, log_wbody and the body: `segadeform garment export`); schema 3 also carries the
 * model garment's frames to the garment as given (`garment export --resolution`).
 */
export function readAsset(parsed, where = "garment asset") {
  const { meta } = parsed;
  if (meta.kind !== ASSET_KIND) throw new Error(`${where}: not a garment asset (expected meta.kind '${ASSET_KIND}', got ${JSON.stringify(meta.kind)})`);
  if (![1, 2, 3].includes(meta.schema_version)) {
    throw new Error(`${where}: unsupported garment asset schema version (expected 1, 2 or 3, got ${meta.schema_version})`);
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
  readCarry(parsed, where);
  // what `garment export` said of the garment, said again when it plays: one-line texts, as Python's GarmentAsset
  // holds them
  oneLineTexts(parsed.meta.warnings, where);
  if (parsed.where === undefined) parsed.where = where; // named in later errors (Player.open's)
  return parsed;
}

/** The carry fields of a parsed asset, checked as Python's GarmentAsset checks them: all five or none. */
function readCarry(parsed, where) {
  const A = parsed.arrays, given = CARRY_FIELDS.filter(([k]) => A[k]).map(([k]) => k);
  if (!given.length && parsed.meta.schema_version !== 3) return;
  if (given.length !== CARRY_FIELDS.length) {
    throw new Error(`${where}: a decimated model garment needs ${CARRY_FIELDS.map(([k]) => k).join(", ")} (expected ` +
      `all five, got ${given.join(", ") || "none"})`);
  }
  for (const [k, dt, nd] of CARRY_FIELDS) need(parsed, k, dt, nd, where);
  const P = A.out_vertices.shape[0], F = A.faces.shape[0];
  const shapes = [["out_vertices", [P, 3]], ["carry_face", [P]], ["carry_bary", [P, 3]], ["carry_offset", [P]]];
  for (const [k, want] of shapes) {
    if (P < 1 || JSON.stringify(A[k].shape) !== JSON.stringify(want)) {
      throw new Error(`${where}: field '${k}' has the wrong shape (expected ${JSON.stringify(want)}, got ` +
        `${JSON.stringify(A[k].shape)})`);
    }
  }
  if (A.out_faces.shape[1] !== 3 || A.out_faces.shape[0] < 1) {
    throw new Error(`${where}: field 'out_faces' has the wrong shape (expected (G, 3), G >= 1, got ${JSON.stringify(A.out_faces.shape)})`);
  }
  for (const [k, hi] of [["out_faces", P], ["carry_face", F]]) {
    const d = A[k].data;
    for (let i = 0; i < d.length; i++) {
      if (!(d[i] >= 0 && d[i] < hi)) throw new Error(`${where}: field '${k}' has an index out of range (expected 0..${hi - 1}, got ${d[i]})`);
    }
  }
  for (const k of ["out_vertices", "carry_bary", "carry_offset"]) finite(A[k], k, where);
  const w = A.carry_bary.data; // weights (1, 1, 0) on a face (A, A, B) put a vertex twice as far (Python refuses them)
  for (let i = 0; i < P; i++) {
    const sum = w[3 * i] + w[3 * i + 1] + w[3 * i + 2];
    if (!(Math.abs(sum - 1) <= 1e-6)) {
      throw new Error(`${where}: field 'carry_bary' has weights that do not sum to 1 (an asset exported by a release ` +
        `that put a vertex on a face with a repeated corner twice: export it again) (expected each row summing to 1 ` +
        `within 1e-06, got row ${i} sums to ${sum})`);
    }
  }
  const d = A.out_vertices.data;
  for (let i = 0; i < d.length; i++) {
    if (Math.abs(d[i]) > 1e4) throw new Error(`${where}: field 'out_vertices' lies beyond 10 km (expected |x| <= 10000 m, got ${d[i]})`);
  }
}

/**
 * Frames of the model's garment, B*M*3 (M vertices), carried to the garment as given, B*N*3: each vertex at its
 * barycentric place on its triangle of the model's garment plus its offset along that triangle's unit normal
 * (segadeform.body.resample.SurfaceMap.apply; float64 sums, float32 frames).  carry: { N, face (N), bary (N*3),
 * offset (N), faces (the model garment's triangles) }.
 */
export function carryFrames(x, B, M, carry) {
  const { N, face, bary, offset, faces } = carry;
  const out = new Float32Array(B * N * 3);
  for (let b = 0; b < B; b++) {
    const xo = b * M * 3, oo = b * N * 3;
    for (let i = 0; i < N; i++) {
      const t = 3 * face[i], p0 = xo + 3 * faces[t], p1 = xo + 3 * faces[t + 1], p2 = xo + 3 * faces[t + 2];
      const w0 = bary[3 * i], w1 = bary[3 * i + 1], w2 = bary[3 * i + 2];
      const e1x = x[p1] - x[p0], e1y = x[p1 + 1] - x[p0 + 1], e1z = x[p1 + 2] - x[p0 + 2];
      const e2x = x[p2] - x[p0], e2y = x[p2 + 1] - x[p0 + 1], e2z = x[p2 + 2] - x[p0 + 2];
      let nx = e1y * e2z - e1z * e2y, ny = e1z * e2x - e1x * e2z, nz = e1x * e2y - e1y * e2x;
      const len = Math.max(Math.sqrt(nx * nx + ny * ny + nz * nz), 1e-300), o = offset[i];
      nx /= len; ny /= len; nz /= len; // (Python's order of operations: the same float64 numbers)
      out[oo + 3 * i] = w0 * x[p0] + w1 * x[p1] + w2 * x[p2] + o * nx;
      out[oo + 3 * i + 1] = w0 * x[p0 + 1] + w1 * x[p1 + 1] + w2 * x[p2 + 1] + o * ny;
      out[oo + 3 * i + 2] = w0 * x[p0 + 2] + w1 * x[p1 + 2] + w2 * x[p2 + 2] + o * nz;
    }
  }
  return out;
}

/** The index [i0, i1, ...] of flat position `i` in an array of `shape` (a motion's poses: [frame, joint, axis]). */
function indexOf(i, shape) {
  const out = [];
  for (let k = shape.length - 1; k >= 0; k--) {
    out.unshift(i % shape[k]);
    i = Math.floor(i / shape[k]);
  }
  return `[${out.join(", ")}]`;
}

/** Throw unless every value of a parsed array is finite (a field named `name` of `where`); the first bad value's
 * index is named, as segadeform run names it (a motion's poses: [frame, joint, axis]). */
function finite(a, name, where) {
  const d = a.data;
  for (let i = 0; i < d.length; i++) {
    if (!Number.isFinite(d[i])) {
      throw new Error(`${where}: field '${name}' contains NaN or inf (first at index ${indexOf(i, a.shape)})`);
    }
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
  if (p.shape[0] === 0) throw new Error(`${where}: the motion has no frames (expected T >= 1, got ${JSON.stringify(p.shape)})`);
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
  oneLineTexts(meta.warnings, where);
  canonicalAxisAngle(p.data);
  return parsed;
}

/** Throw unless `said` (a file's meta.warnings: what the command that wrote it said) is absent or a list of
 * one-line texts, as Python's readers hold them. */
function oneLineTexts(said, where) {
  if (said !== undefined && !(Array.isArray(said) && said.every((w) => typeof w === "string" && w && !w.includes("\n")))) {
    throw new Error(`${where}: meta.warnings is not a list of one-line texts (expected strings without line breaks, ` +
      `got ${JSON.stringify(said).slice(0, 60)})`);
  }
}

const f32 = (a) => (a instanceof Float32Array ? a : Float32Array.from(a));

/**
 * The garment's model inputs of a source, in one form: a scene bundle, or { asset } (a parsed .sgda; a motion beside
 * it is not read).  Returns { features, nbr, mask, descriptor, betas, rest, joints, log_wbody, faces, N, K, S, D (the
 * values of one frame's pose), F, effects (the bundle's, else undefined), body (the asset's body label), asset }.
 */
export function garmentInputs(source) {
  if (source.asset) {
    const A = source.asset.arrays, am = source.asset.meta;
    if (!A.betas || !A.log_wbody || !am.body) {
      throw new Error("the garment asset is not prepared for a body shape (expected a schema-2 asset with betas, " +
        "log_wbody and body: segadeform garment export GARMENT --betas ... -o G.sgda)");
    }
    const S = A.joints.shape[0], M = A.vertices.shape[0];
    // N, faces and outRest: the garment the frames are written, collided and stepped on (a schema-3 asset's garment
    // as given); M, rest: the model's garment (its decimated copy there), carry: the map between them
    const carry = A.out_vertices ? { N: A.out_vertices.shape[0], face: A.carry_face.data, bary: A.carry_bary.data,
      offset: A.carry_offset.data, faces: A.faces.data } : null;
    return {
      features: A.features.data, nbr: A.nbr.data, mask: A.mask.data, descriptor: f32(A.descriptor.data),
      betas: f32(A.betas.data), rest: f32(A.vertices.data), joints: f32(A.joints.data), log_wbody: A.log_wbody.data,
      faces: carry ? A.out_faces.data : A.faces.data, N: carry ? carry.N : M, M, carry,
      outRest: carry ? A.out_vertices.data : A.vertices.data, K: A.nbr.shape[1], S, D: 3 * S, F: A.features.shape[1],
      effects: undefined, body: am.body, asset: source.asset,
    };
  }
  if (!source.arrays || !source.meta) {
    throw new Error("expected a garment asset ({ asset }: readAsset(...)) or a scene bundle (parseBundle(...)), got " +
      (source === null ? "null" : typeof source === "object" ? `an object with ${Object.keys(source).join(", ") || "no keys"}` : typeof source));
  }
  const { arrays: A, meta } = source;
  return {
    features: A.features.data, nbr: A.nbr.data, mask: A.mask.data, descriptor: A.descriptor.data, betas: A.betas.data,
    rest: A.rest.data, joints: A.joints.data, log_wbody: A.log_wbody ? A.log_wbody.data : null,
    faces: A.faces ? A.faces.data : null, N: A.rest.shape[0], M: A.rest.shape[0], carry: null, K: A.nbr.shape[1],
    S: A.joints.shape[0],
    D: A.poses.shape[1], F: A.features.shape[1], effects: meta.effects, body: null, asset: null,
  };
}

/**
 * The model inputs of a source, in one form: a scene bundle, or { asset, motion } (parsed .sgda and .sgdm).
 * Returns garmentInputs' and { poses, trans, T, fps, warnings }.
 */
export function sceneInputs(source) {
  const G = garmentInputs(source);
  if (source.asset) {
    if (!source.motion || !source.motion.arrays) throw new Error("a garment asset needs a motion (a parsed .sgdm)");
    const M = source.motion.arrays, am = source.asset.meta, mm = source.motion.meta;
    if (M.poses.shape[1] !== G.S) throw new Error(`the motion has ${M.poses.shape[1]} joints, the garment asset ${G.S}`);
    const warnings = [];
    if (mm.body && mm.body.sha256 !== am.body.sha256) warnings.push("the motion was retargeted onto another body than the garment asset's");
    // what `segadeform motion export` said of the motion (capture glitches ...), said again here
    for (const w of mm.warnings || []) warnings.push(`when the motion file was exported: ${w}`);
    if (mm.betas && mm.betas.some((b, i) => Math.abs(b - (G.betas[i] || 0)) > 1e-6)) { // (C++'s tolerance)
      warnings.push("the motion was retargeted onto another body shape (betas) than the garment asset's");
    }
    return { ...G, poses: M.poses.data, trans: M.trans.data, T: M.poses.shape[0], fps: mm.fps, warnings };
  }
  const { arrays: A, meta } = source;
  return { ...G, poses: A.poses.data, trans: A.trans.data, T: A.poses.shape[0], fps: meta.fps, warnings: [] };
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
 * Free the onnxruntime sessions of `made` (a Map of file -> Promise<InferenceSession>) and empty it: they hold native
 * or WebAssembly memory the garbage collector does not see.  A session that failed to load has nothing to free.
 */
export async function releaseSessions(made) {
  const all = [...made.values()];
  made.clear();
  for (const p of all) {
    try {
      await (await p).release();
    } catch {
      // nothing was made
    }
  }
}

/* A value as an error shows it: numbers as themselves (JSON.stringify(NaN) is "null": a web developer's trial) */
function shown(v) {
  return typeof v === "number" ? String(v) : JSON.stringify(v);
}

/** Throw unless `options` holds only the keys of `allowed` (`where`: whose options), each of a usable value. */
export function checkOptions(options, allowed, where) {
  if (options === null || typeof options !== "object" || Array.isArray(options)) {
    throw new Error(`${where}: options must be an object (got ${options === null ? "null" : typeof options})`);
  }
  for (const k of Object.keys(options)) {
    if (!allowed.includes(k)) throw new Error(`${where}: unknown option '${k}' (expected ${allowed.join(", ")})`);
  }
  for (const k of ["batch", "threads"]) {
    const v = options[k];
    if (v !== undefined && !(Number.isInteger(v) && v >= 1 && v <= 1e6)) {
      throw new Error(`${where}: option ${k} must be an integer >= 1 (got ${shown(v)})`);
    }
  }
  const m = options.collisionMargin;
  if (m !== undefined && typeof m !== "number") {
    throw new Error(`${where}: option collisionMargin must be a number of metres (got ${typeof m} ${JSON.stringify(m)})`);
  }
  const e = options.effects;
  if (e !== undefined && e !== null && typeof e !== "string" && (typeof e !== "object" || Array.isArray(e))) {
    throw new Error(`${where}: option effects must be a string such as "dqs,dynamics" or an object (got ${JSON.stringify(e)})`);
  }
  const f = options.fps;
  if (f !== undefined && !(typeof f === "number" && f >= 1 && f <= 1000)) {
    throw new Error(`${where}: option fps must be a frame rate (expected 1..1000, got ${shown(f)})`);
  }
  return options;
}

/**
 * A source's effects from options.effects: text as parseEffects reads it over the run's defaults (the bundle's, else
 * defaultEffects), or an object naming what is on ({ skinning: "dqs", dynamics: true }: what it leaves out is off,
 * lbs unless it names dqs).
 */
export function effectsOf(manifest, source, effects) {
  const base = (source && !source.asset && source.meta && source.meta.effects) || defaultEffects(manifest);
  if (typeof effects === "string") return { collisions: false, cloth: false, ...parseEffects(effects, base) };
  if (!effects) return { collisions: false, cloth: false, ...base };
  const keys = ["skinning", "dynamics", "wrinkles", "collisions", "cloth"];
  for (const [k, v] of Object.entries(effects)) {
    if (!keys.includes(k)) throw new Error(`unknown effect '${k}' (expected an object of ${keys.join(", ")})`);
    if (k === "skinning" ? v !== "lbs" && v !== "dqs" : typeof v !== "boolean") {
      throw new Error(`effect ${k} must be ${k === "skinning" ? '"lbs" or "dqs"' : "true or false"} (got ${JSON.stringify(v)})`);
    }
  }
  return { skinning: "lbs", dynamics: false, wrinkles: false, collisions: false, cloth: false, ...effects };
}

/** The options Player.open takes (checkOptions). */
export const PLAYER_OPTIONS = ["effects", "collisionMargin", "cloth", "fps", "batch", "body", "stages", "force"];

/**
 * A garment on a package, played a chunk of motion at a time: what a game loop, a network stream or a clip too long
 * to hold needs.  The garment is encoded once; each push() runs the deformer on the motion window (the chunk's
 * frames and the ones before it: the frames before the first repeat the first), then -- as the effects name them --
 * the cloth stage or collisions against the body posed by the package's body graph, whose state (the stage's
 * previous frames, the collider built on the body at rest) carries over.  Pushing a motion in chunks gives the frames
 * of one push of the whole, bit for bit when every chunk is a multiple of `p.batch` frames (the option batch, lowered
 * for a garment over MAX_VERTEX_FRAMES / batch vertices; batch 1 for a frame at a
 * time); other chunks run the network on other batch sizes, which onnxruntime rounds differently (~1e-6 m), and a
 * push-out in a crease of the body can turn that into another face (millimetres).  Memory is the chunk's, whatever
 * the clip's length.
 *
 *   const p = await Player.open(ort, manifest, { asset }, session, { effects: "+cloth", fps: 30 });
 *   const { frames } = await p.push(poses, trans);   // poses (B*S*3 axis-angle), trans (B*3) -> frames (B*N*3)
 *   p.reset();                                       // a new clip: no history, the stage and collider anew
 *
 * `source`: { asset, motion } (a checked .sgda and the .sgdm to be pushed: a motion made for another body or shape
 * than the asset's is refused unless force; its frames are not played by open, push them), { asset } (a stream with no
 * file: the host answers for its body shape) or a scene bundle (its garment; push its poses).  `session(spec)`: an onnxruntime InferenceSession for a graph's manifest entry, made
 * once by the caller.  options: effects (an object or "dqs,dynamics,..."/"+cloth"; default: the bundle's, else the
 * model's own and collisions when the package has a body graph), collisionMargin (0.004 m), cloth (the stage's knobs:
 * "iterations=8,..." or an object; DEFAULT_CLOTH), fps (the motion's frame rate: the cloth stage's time step; needed
 * with cloth), batch (frames per graph run, 8), body (also return the posed body of every pushed frame), stages
 * (false: the deformer alone, the host running collisions or cloth itself, as animateWith), force (play an asset
 * exported with --force for a body it does not sit on; player.warnings says so).
 */
export class Player {
  static async open(ort, manifest, source, session, options = {}) {
    checkOptions(options, PLAYER_OPTIONS, "Player.open");
    const p = new Player();
    const G = garmentInputs(source);
    // an asset exported with --force for a body it does not sit on: refused unless forced again, as `segadeform run`
    // refuses it (it checks the fit itself)
    p.warnings = [];
    if (G.body && typeof G.body.unfit === "string") {
      const why = `the garment asset was exported with --force although ${G.body.unfit}`;
      if (!options.force) throw new Error(`${why} (expected a garment that sits on its body, or the option force: true)`);
      p.warnings.push(why);
    }
    // a motion given with the asset ({ asset, motion }, as animate takes them) made for another body or shape: refused
    // unless forced, as playWith and `segadeform run` refuse it (a Player opened so played it without a word)
    if (source.asset && source.motion && source.motion.arrays) {
      const other = sceneInputs(source).warnings.find((w) => w.startsWith("the motion was retargeted onto another"));
      if (other && !options.force) {
        throw new Error(`${other} (expected a motion exported for the asset's body and betas: segadeform motion ` +
          "export ... --betas ..., or the option force: true)");
      }
      if (other) p.warnings.push(other);
    }
    // what `segadeform garment export` said of the garment (a mesh split at its seams tears ...), said again here
    if (G.asset && Array.isArray(G.asset.meta.warnings)) {
      for (const w of G.asset.meta.warnings) p.warnings.push(`when the garment asset was exported: ${w}`);
    }
    // an asset prepared for another body than the package's is refused whatever the effects (only the body graph's
    // poser checked it, so effects "none" played it), as `segadeform run` refuses it
    for (const spec of Object.values(manifest.graphs || {})) {
      if (spec.role === "body" && spec.body && G.body && G.body.sha256 && G.body.sha256 !== spec.body.sha256) {
        throw new Error(`the garment asset was prepared for another body than the package's (expected ${spec.body.name} ` +
          `${spec.body.sha256.slice(0, 12)}, got ${G.body.name} ${G.body.sha256.slice(0, 12)})`);
      }
    }
    // a package whose body graph poses another body than its model was trained on: refused unless forced, as
    // `segadeform run` refuses it
    const otherBody = otherTrainingBody(manifest);
    if (otherBody && !options.force) {
      throw new Error(`${otherBody}: the model never saw this body (segadeform export-body without --force gives ` +
        "the package its training body back; or the option force: true)");
    }
    if (otherBody) p.warnings.push(otherBody);
    const effects = effectsOf(manifest, source, options.effects);
    const margin = options.collisionMargin ?? DEFAULT_COLLISION_MARGIN;
    if (options.collisionMargin !== undefined) checkMargin(options.collisionMargin);
    if ((effects.collisions || effects.cloth) && !hasBody(manifest)) {
      throw new Error(`${effects.cloth ? "the cloth stage needs" : "collisions need"} the posed body, and the package has ` +
        "no body graph (segadeform export-body [BODY] -o PACKAGE adds one)");
    }
    if (effects.cloth && !source.asset) {
      throw new Error("the cloth stage needs a garment asset and a motion file (expected .sgda and .sgdm, got a scene bundle)");
    }
    const stages = options.stages !== false;
    if (options.cloth && !effects.cloth) {
      throw new Error("the option cloth sets the cloth stage's knobs, but the stage is off (name cloth in the effects)");
    }
    if (stages && effects.cloth && options.fps === undefined) {
      throw new Error("the cloth stage needs the motion's frame rate (expected the option fps, 1..1000)");
    }
    Object.assign(p, { ort, manifest, G, effects, margin, stages, batch: effectiveBatch(options.batch || 8, G.M), N: G.N,
      S: G.S, D: G.D, faces: G.faces, fps: options.fps, wantBody: !!options.body });
    p.settings = typeof options.cloth === "string" ? parseCloth(options.cloth) : options.cloth || DEFAULT_CLOTH;
    const t0 = performance.now();
    await p.#openDeformer(session);
    p.msDeform = performance.now() - t0;
    p.msBody = p.msAfter = 0;
    p.frames = 0;
    p.moved = 0;
    p.poser = (stages && (effects.collisions || effects.cloth)) || p.wantBody
      ? await bodyPoserWith(ort, manifest, G, session, { skinning: effects.skinning }) : null;
    p.V = p.poser ? p.poser.V : 0;
    // the stage's rest, and the body the collider's tree is built from (as segadeform run builds it: the tree decides
    // between equally near triangles, and built from the clip's first pose a frame moved 2 cm where Python's did not)
    if (stages && (effects.cloth || effects.collisions)) p.rest = await p.poser.rest();
    p.reset();
    return p;
  }

  async #openDeformer(session) {
    const { ort, manifest, G, effects } = this;
    const { M: N, K, S } = G; // the model's garment
    const encSpec = manifest.graphs.garment_encoder;
    const { name: variant, spec: decSpec } = pickVariant(manifest, effects);
    const enc = await session(encSpec);
    this.dec = await session(decSpec);
    this.variant = variant;
    this.decSpec = decSpec;
    const inDec = Object.fromEntries(decSpec.inputs.map((i) => [i.name, i]));
    this.window = inDec.window.shape[1];
    this.nb = inDec.betas.shape[1];
    this.betasRow = modelBetas(G.betas, this.nb);
    if (inDec.window.shape[2] !== undefined && typeof inDec.window.shape[2] === "number" && inDec.window.shape[2] !== G.D) {
      throw new Error(`the deformer takes poses of ${inDec.window.shape[2]} values, the garment's body ${G.D}`);
    }
    // the encoder's inputs, fed by name (older encoders also take betas)
    const encArrays = {
      features: [G.features, [1, N, G.F]], nbr: [G.nbr, [N, K]], mask: [G.mask, [N, K]],
      descriptor: [G.descriptor, [1, G.descriptor.length]], betas: [this.betasRow, [1, this.nb]],
    };
    const encFeeds = {};
    const want = (encSpec.inputs.find((i) => i.name === "descriptor") || { shape: [] }).shape[1];
    if (typeof want === "number" && want !== G.descriptor.length) { // (onnxruntime's own error named neither)
      const name = G.asset && G.asset.where && G.asset.where !== "garment asset" ? `${G.asset.where}: ` : "";
      throw new Error(`${name}the garment asset was exported for another model; export it for this one: segadeform ` +
        `garment export GARMENT --model PACKAGE (expected a garment descriptor of ${want} values, got ` +
        `${G.descriptor.length})`);
    }
    for (const i of encSpec.inputs) {
      if (!encArrays[i.name]) throw new Error(`the garment encoder takes '${i.name}', which this runtime cannot feed`);
      encFeeds[i.name] = feed(ort, i, ...encArrays[i.name]);
    }
    const encOut = await enc.run(encFeeds);
    // its one output, without the batch axis, is a deformer input of the same name: g (N, K S), K networks of an
    // ensemble (older: P (N, S, F_enc))
    this.codeName = encSpec.outputs[0].name;
    const code = encOut[this.codeName];
    const fixed = { [this.codeName]: new ort.Tensor("float32", await code.getData(), code.dims.slice(1)) };
    fixed.nbr = feed(ort, inDec.nbr, G.nbr, [N, K]);
    fixed.mask = feed(ort, inDec.mask, G.mask, [N, K]);
    fixed.rest = feed(ort, inDec.rest, G.rest, [N, 3]);
    if (inDec.log_wbody) {
      if (!G.log_wbody) throw new Error("this model needs the body's weights at the garment (log_wbody), which the input lacks");
      const want = manifest.config.weight_prior || "nearest", got = G.body ? G.body.weight_prior || "nearest" : want;
      if (got !== want) {
        throw new Error(`the garment asset's log_wbody was made with the ${got} weight prior, the model wants ${want} ` +
          "(expected an asset from segadeform garment export --model PACKAGE)");
      }
      fixed.log_wbody = feed(ort, inDec.log_wbody, G.log_wbody, [N, S]);
    }
    this.fixed = fixed;
  }

  /** A new clip: no motion history; the cloth stage starts again from the network's frame, the collider anew, the
   * push-out's carried corrections at zero. */
  reset() {
    this.prev = new Float32Array(0); // the last window - 1 poses pushed (fewer at the start)
    this.seen = 0;
    this.moved = 0; // the counts are the clip's (they added up over reset(): a web developer's trial)
    this.collider = null;
    this.carry = new Float64Array(3 * this.N); // each vertex's push-out correction at the frame before
    this.broken = false; // a push failed part-way: refused until reset() (as the C++ Player)
    this.stage = null;
    if (this.stages && this.effects.cloth) {
      const t0 = performance.now();
      this.stage = clothStart(this.rest.vertices, this.rest.faces, this.G.outRest, this.G.faces,
        { settings: this.settings, margin: this.margin, dt: 1.0 / this.fps });
      this.msAfter += performance.now() - t0;
    }
  }

  /**
   * The next B frames of the motion: poses (B*D float32: axis-angle per joint, D = 3 S; written any way, they are
   * read one way, as motion files are) and trans (B*3 metres).  Returns { frames (B*N*3), body (B*V*3) and joints
   * (B*S*3: the posed body, with the option body; restJoints on the player), T: B }.
   */
  async push(poses, trans) {
    const { D, N, V, ort } = this;
    const P = Float32Array.from(poses), Tr = Float32Array.from(trans);
    const B = P.length / D;
    if (!Number.isInteger(B) || B < 1 || Tr.length !== 3 * B) {
      throw new Error(`push: poses and trans do not fit (expected B*${D} and B*3 values, B >= 1, got ${P.length} and ` +
        `${Tr.length})`);
    }
    for (let i = 0; i < P.length; i++) if (!Number.isFinite(P[i])) throw new Error(`push: poses contain NaN or inf (at value ${i})`);
    for (let i = 0; i < Tr.length; i++) {
      if (!(Math.abs(Tr[i]) <= 1e4)) throw new Error(`push: trans must be finite and within 10 km (got ${Tr[i]} at value ${i})`);
    }
    if (D === 3 * this.S) canonicalAxisAngle(P);
    if (this.broken) {
      throw new Error("push: an earlier push failed part-way, leaving the stages' state behind the motion (expected " +
        "reset() first)");
    }
    this.broken = true; // until this push ends: a batch that throws leaves the stages' state ahead of the history
    const frames = new Float32Array(B * N * 3);
    const body = this.wantBody ? new Float32Array(B * V * 3) : null;
    const joints = this.wantBody ? new Float32Array(B * this.S * 3) : null;
    // the motion the windows read: the poses before this chunk, then the chunk (frame `first` at index 0)
    const hist = this.prev.length / D, first = this.seen - hist;
    const all = new Float32Array((hist + B) * D);
    all.set(this.prev, 0);
    all.set(P, hist * D);
    // the graphs run at the root (the same float32 numbers wherever the character stands); collisions are resolved
    // there, the cloth stage steps in world coordinates in float64, and the translation is added last (atTranslation:
    // as Python's segadeform.runtime.translation)
    for (let lo = 0; lo < B; lo += this.batch) {
      const hi = Math.min(lo + this.batch, B), n = hi - lo, tr = Tr.subarray(3 * lo, 3 * hi);
      const rel = frames.subarray(lo * N * 3, hi * N * 3), zero = new Float32Array(3 * n);
      let t0 = performance.now();
      const x = await this.#deform(all, first, this.seen + lo, n, zero);
      rel.set(this.G.carry ? carryFrames(x, n, this.G.M, this.G.carry) : x);
      this.msDeform += performance.now() - t0;
      if (!this.poser || !this.stages) {
        rel.set(atTranslation(rel, tr, n));
        if (!this.poser) continue;
      }
      t0 = performance.now();
      let b;
      if (body) { // the joints too
        const j = await this.poser.joints(P.subarray(lo * D, hi * D), zero, n);
        b = j.vertices;
        body.set(atTranslation(b, tr, n), lo * V * 3);
        joints.set(atTranslation(j.joints, tr, n), lo * this.S * 3);
        this.restJoints = j.restJoints;
      } else {
        b = await this.poser.pose(P.subarray(lo * D, hi * D), zero, n);
      }
      this.msBody += performance.now() - t0;
      if (!this.stages) continue;
      t0 = performance.now();
      if (this.stage) {
        clothStep(this.stage, frames, N, lo, hi, b, tr);
      } else {
        if (this.effects.collisions) {
          this.collider ||= new BodyCollider(this.rest.vertices, this.rest.faces);
          const c = pushOutFrames(rel, n, N, b, V, this.poser.faces(),
            { margin: this.margin, iterations: 3, batch: n, collider: this.collider, carry: this.carry });
          this.collider = c.collider;
          this.moved += c.moved;
        }
        rel.set(atTranslation(rel, tr, n));
      }
      this.msAfter += performance.now() - t0;
    }
    this.seen += B;
    this.broken = false;
    const keep = Math.min(this.window - 1, hist + B);
    this.prev = all.slice((hist + B - keep) * D);
    this.frames += B;
    return { frames, body, joints, T: B };
  }

  // B frames from global frame `g0`: the window of frame t is t, t-1, ... t-window+1 (before 0: frame 0)
  async #deform(all, first, g0, B, trans) {
    const { ort, D, S, nb, window } = this;
    const win = new Float32Array(B * window * D);
    for (let b = 0; b < B; b++) {
      for (let k = 0; k < window; k++) {
        const src = Math.max(g0 + b - k, 0) - first;
        win.set(all.subarray(src * D, src * D + D), (b * window + k) * D);
      }
    }
    const betas = new Float32Array(B * nb);
    const joints = new Float32Array(B * S * 3);
    for (let b = 0; b < B; b++) {
      betas.set(this.betasRow, b * nb);
      joints.set(this.G.joints, b * S * 3);
    }
    const out = await this.dec.run({
      ...this.fixed, window: new ort.Tensor("float32", win, [B, window, D]),
      betas: new ort.Tensor("float32", betas, [B, nb]), joints: new ort.Tensor("float32", joints, [B, S, 3]),
      trans: new ort.Tensor("float32", Float32Array.from(trans), [B, 3]),
    });
    return out[this.decSpec.outputs[0].name].getData();
  }

  /** What the stages did so far: { contacts, pushed, traced, resets, firstReset } of the cloth stage, or { moved }. */
  get counts() {
    const s = this.stage;
    if (s) return { contacts: s.contacts, pushed: s.pushed, traced: s.traced, resets: s.resets, firstReset: s.firstReset };
    return { moved: this.moved };
  }
}

/** A number as C's and Python's "%.9g" print it (JavaScript's own printing turns to exponents elsewhere: 7.54e-5 was
 * -0.0000754 in Node's rest OBJ, -7.54e-05 in Python's and C++'s). */
export function formatG9(x) {
  if (!Number.isFinite(x)) return String(x);
  if (x === 0) return Object.is(x, -0) ? "-0" : "0";
  const a = Math.abs(x);
  // nine significant digits, rounded half to even as C rounds the exact binary value (toExponential rounds a tie
  // away from zero: 976885.0625 was ...063 here, ...062 in Python and C++); the exact digits show a tie
  let [m, e] = a.toExponential(8).split("e");
  let digits = m.replace(".", ""), exp = Number(e);
  const [em, ee] = a.toExponential(Math.min(100, 48)).split("e");
  const exact = em.replace(".", "");
  if (exact[9] === "5" && /^0*$/.test(exact.slice(10)) && Number(exact[8]) % 2 === 0) {
    digits = exact.slice(0, 9);
    exp = Number(ee);
  }
  const sign = x < 0 ? "-" : "";
  const trim = (s) => (s.includes(".") ? s.replace(/0+$/, "").replace(/\.$/, "") : s);
  if (exp < -4 || exp >= 9) {
    return `${sign}${trim(`${digits[0]}.${digits.slice(1)}`)}e${exp < 0 ? "-" : "+"}${String(Math.abs(exp)).padStart(2, "0")}`;
  }
  const fixed = exp >= 0 ? `${digits.slice(0, exp + 1)}.${digits.slice(exp + 1)}` : `0.${"0".repeat(-exp - 1)}${digits}`;
  return sign + trim(fixed);
}

/**
 * A triangle mesh as OBJ text, as segadeform.io.obj.write_obj writes it (9 significant digits, 1-based faces):
 * vertices (V*3), faces (F*3, 0-based) -> a Uint8Array.
 */
export function objText(vertices, faces) {
  const V = vertices.length / 3, F = faces.length / 3, g = formatG9;
  const lines = [`# segadeform OBJ: ${V} vertices, ${F} triangles`];
  for (let i = 0; i < V; i++) lines.push(`v ${g(vertices[3 * i])} ${g(vertices[3 * i + 1])} ${g(vertices[3 * i + 2])}`);
  for (let i = 0; i < F; i++) lines.push(`f ${faces[3 * i] + 1} ${faces[3 * i + 1] + 1} ${faces[3 * i + 2] + 1}`);
  return new TextEncoder().encode(lines.join("\n") + "\n");
}

/**
 * Frames computed at the root moved to the translation: B frames of any number of points (B*K*3) and trans (B*3)
 * -> a new Float32Array, each coordinate rounded from the float64 sum (Python's segadeform.runtime.translation).
 */
export function atTranslation(frames, trans, B) {
  const out = new Float32Array(frames.length), K = frames.length / (3 * B);
  for (let b = 0; b < B; b++) {
    for (let c = 0; c < 3; c++) {
      const t = trans[3 * b + c];
      for (let k = 0; k < K; k++) out[(b * K + k) * 3 + c] = frames[(b * K + k) * 3 + c] + t;
    }
  }
  return out;
}

/**
 * Animate a source with a package's graphs: a scene bundle, or { asset, motion } (parsed .sgda and .sgdm): the
 * deformer alone (a Player without its stages, the whole motion pushed).  `session(spec)` returns an onnxruntime
 * InferenceSession for a graph's manifest entry.
 * Returns { frames: Float32Array (T*N*3), T, N, msPerFrame, variant, effects, faces, fps, warnings }.
 * options: { effects (default: the bundle's, else defaultEffects), collisionMargin (checked), batch (8), force
 * (false: a motion retargeted onto another body or shape than the asset's is refused; true: played, with a
 * warning) }.  With effects.collisions the frames are the deformer's: the host pushes them out of the posed body
 * afterwards; playWith runs them.
 */
export async function animateWith(ort, manifest, source, session, options = {}) {
  const { force, ...rest } = checkOptions(options, ["effects", "collisionMargin", "batch", "force"], "animateWith");
  return playWith(ort, manifest, source, session, { ...rest, force, stages: false });
}

/**
 * Animate a source with a package's graphs and run the stages its effects name (collisions, the cloth stage) a batch
 * of frames at a time: the posed body is never held whole unless options.body asks for it.  options: Player.open's
 * and force (animateWith's).  Returns animateWith's result, and body ({ vertices (T*V*3), joints (T*S*3), restJoints,
 * faces, V, T, msPerFrame, graph }, with options.body), collisions ({ moved, msPerFrame, margin }) or cloth ({ contacts, pushed, traced,
 * resets, firstReset, msPerFrame, settings, margin }).
 */
export async function playWith(ort, manifest, source, session, options = {}) {
  const { force, ...rest } = checkOptions(options, PLAYER_OPTIONS, "playWith");
  const I = sceneInputs(source);
  // a motion made for another body or shape is refused, as `segadeform run` and the command lines refuse it (the
  // API played it with a warning); options.force plays it, the warning kept
  const other = I.warnings.find((w) => w.startsWith("the motion was retargeted onto another"));
  if (other && !force) {
    throw new Error(`${other} (expected a motion exported for the asset's body and betas: segadeform motion export ` +
      "... --betas ..., or the option force: true)");
  }
  const p = await Player.open(ort, manifest, source, session, { ...rest, force, fps: I.fps });
  const r = await p.push(I.poses, I.trans);
  const T = I.T, perFrame = (ms) => ms / Math.max(T, 1);
  const out = { frames: r.frames, T, N: I.N, batch: p.batch, msPerFrame: perFrame(p.msDeform), variant: p.variant,
    effects: p.effects, faces: I.faces, fps: I.fps, warnings: [...new Set([...p.warnings, ...I.warnings])] };
  if (options.body) {
    out.body = { vertices: r.body, joints: r.joints, restJoints: p.restJoints, rest: (await p.poser.rest()).vertices,
      V: p.V, T, faces: p.poser.faces(),
      msPerFrame: perFrame(p.msBody), graph: p.poser.name };
  }
  if (p.stages && p.effects.cloth) {
    out.cloth = { ...p.counts, msPerFrame: perFrame(p.msAfter), settings: p.settings, margin: p.margin };
  } else if (p.stages && p.effects.collisions) {
    out.collisions = { moved: p.moved, msPerFrame: perFrame(p.msAfter), margin: p.margin };
  }
  return out;
}

/**
 * The package's body graph for `skinning` over a garment's body shape (`inputs`: garmentInputs' or sceneInputs'),
 * run a batch of frames at a time.  Returns { name, V, S, pose(poses, trans, B) -> vertices (B*V*3), joints(poses,
 * trans, B) -> { vertices, joints (B*S*3), restJoints (S*3) }, rest() -> { vertices (V*3), faces } (zero pose, no
 * translation), faces() }.  Throws when the package has no body graph or the garment asset was prepared for another
 * body.
 */
export async function bodyPoserWith(ort, manifest, inputs, session, { skinning = "lbs" } = {}) {
  const I = inputs;
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
  let faces = null;
  // the graph runs at the root; the translation is added after it (atTranslation: the same numbers wherever the
  // character stands, as in Python)
  const run = async (poses, B) => {
    const out = await sess.run({
      betas, poses: new ort.Tensor("float32", Float32Array.from(poses), [B, S, 3]),
      trans: new ort.Tensor("float32", new Float32Array(3 * B), [B, 3]),
    });
    if (!faces) faces = Int32Array.from(await out.faces.getData());
    return out;
  };
  const joints = async (poses, trans, B) => {
    const out = await run(poses, B);
    return { vertices: atTranslation(await out.vertices.getData(), trans, B),
      joints: atTranslation(await out.joints.getData(), trans, B),
      restJoints: Float32Array.from(await out.rest_joints.getData()) };
  };
  const pose = async (poses, trans, B) => atTranslation(await (await run(poses, B)).vertices.getData(), trans, B);
  const rest = async () => ({ vertices: await pose(new Float32Array(S * 3), new Float32Array(3), 1),
    faces });
  return { name, V, S, pose, joints, rest, faces: () => faces };
}

/** A collision margin must be in [0, 1) metres, as a scene's collision_margin. */
export function checkMargin(margin) {
  if (!(typeof margin === "number" && margin >= 0 && margin < 1)) {
    throw new Error(`the collision margin must be in [0, 1) metres (got ${margin})`);
  }
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

/** The 32-byte header of a PC2 point cache of T frames of N points. */
export function pc2Header(T, N, { startFrame = 0, sampleRate = 1 } = {}) {
  const out = new Uint8Array(32);
  const dv = new DataView(out.buffer);
  const sig = "POINTCACHE2\0";
  for (let i = 0; i < sig.length; i++) out[i] = sig.charCodeAt(i);
  dv.setInt32(12, 1, true);
  dv.setInt32(16, N, true);
  dv.setFloat32(20, startFrame, true);
  dv.setFloat32(24, sampleRate, true);
  dv.setInt32(28, T, true);
  return out;
}

/** A PC2 point cache of frames (T*N*3 float32, little-endian) as [header, the frames' bytes] (no copy: what the
 * Node CLI writes part by part). */
export function pc2Parts(frames, T, N, opts = {}) {
  return [pc2Header(T, N, opts), new Uint8Array(frames.buffer, frames.byteOffset, frames.byteLength)];
}

/** PC2 point-cache bytes (header + T*N*3 float32 little-endian) for frames, in one buffer. */
export function pc2Bytes(frames, T, N, opts = {}) {
  const out = new Uint8Array(32 + frames.byteLength);
  out.set(pc2Header(T, N, opts), 0);
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
