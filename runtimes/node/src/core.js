// segadeform's JavaScript core, shared by the Node runtime (index.js) and the browser runtime
// (runtimes/web): no Node or DOM APIs here, the onnxruntime module is passed in.
// The package format is docs/package.md; scene bundles are src/segadeform/bundle.py.

export const FORMAT = "segadeform-model-package";
const MAGIC = "SEGADEFORM-BUNDLE 1\n";
const DTYPES = {
  f32: [Float32Array, 4], f64: [Float64Array, 8], i32: [Int32Array, 4], i64: [BigInt64Array, 8], u8: [Uint8Array, 1],
};

/** Parse a bundle from bytes: { arrays: {name: {dtype, shape, data}}, meta }. */
export function parseBundle(bytes, where = "bundle") {
  const buf = bytes instanceof Uint8Array ? bytes : new Uint8Array(bytes);
  const head = new TextDecoder().decode(buf.subarray(0, Math.min(buf.length, 1 << 20)));
  if (!head.startsWith(MAGIC)) throw new Error(`${where}: not a segadeform bundle`);
  const end = head.indexOf("\nEND\n");
  if (end < 0) throw new Error(`${where}: bundle header has no END line`);
  const lines = head.slice(MAGIC.length, end).split("\n");
  const n = parseInt(lines[0], 10);
  if (!(n >= 0) || lines.length !== n + 2 || !lines[n + 1].startsWith("meta ")) {
    throw new Error(`${where}: malformed bundle header`);
  }
  const headerBytes = new TextEncoder().encode(head.slice(0, end + 5)).length;
  const start = Math.ceil(headerBytes / 64) * 64;
  const meta = JSON.parse(lines[n + 1].slice(5));
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
 * Check a parsed manifest and return it in schema-2 form (schema 1 upgraded: `graphs` holds every graph
 * once, each deformer with its `effects`; `default_deformer` names the model's own).
 */
export function readManifest(m, where = "manifest.json") {
  if (m.format !== FORMAT && m.schema_version !== 1) throw new Error(`${where}: not a segadeform model package`);
  if (m.schema_version === 1) m = upgradeManifest(m);
  else if (m.schema_version !== 2) {
    throw new Error(`${where}: unsupported manifest schema version (expected 1 or 2, got ${m.schema_version})`);
  }
  if (!m.graphs || !m.graphs.garment_encoder) throw new Error(`${where}: manifest has no garment_encoder`);
  return m;
}

/** Schema 1 -> 2 (segadeform.package_spec.upgrade_manifest): one name per graph. */
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
  return { ...rest, format: FORMAT, schema_version: 2, graphs, default_deformer: dflt, upgraded_from: 1 };
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
  throw new Error(`no deformer graph for effects ${JSON.stringify(effects)}`);
}

/** Feed for an input spec from a typed array (int32 bundle indices become int64 when the graph wants it). */
function feed(ort, spec, arr, dims) {
  if (spec.dtype === "int64") {
    const out = new BigInt64Array(arr.length);
    for (let i = 0; i < arr.length; i++) out[i] = BigInt(arr[i]);
    return new ort.Tensor("int64", out, dims);
  }
  if (spec.dtype === "int32") return new ort.Tensor("int32", Int32Array.from(arr), dims);
  if (spec.dtype === "bool") return new ort.Tensor("bool", Uint8Array.from(arr), dims);
  return new ort.Tensor("float32", arr instanceof Float32Array ? arr : Float32Array.from(arr), dims);
}

/**
 * Animate a bundle with a package's graphs.  `session(spec)` returns an onnxruntime InferenceSession for a
 * graph's manifest entry.  Returns { frames: Float32Array (T*N*3), T, N, msPerFrame, variant }.
 * options: { effects (default: the bundle's), batch (8) }.
 */
export async function animateWith(ort, manifest, bundle, session, options = {}) {
  const { arrays: A, meta } = bundle;
  const effects = options.effects || meta.effects;
  const batch = options.batch || 8;
  const encSpec = manifest.graphs.garment_encoder;
  const { name: variant, spec: decSpec } = pickVariant(manifest, effects);
  const enc = await session(encSpec);
  const dec = await session(decSpec);
  const N = A.rest.shape[0];
  const K = A.nbr.shape[1];
  const S = A.joints.shape[0];
  const T = A.poses.shape[0];
  const D = A.poses.shape[1];
  const inDec = Object.fromEntries(decSpec.inputs.map((i) => [i.name, i]));
  const window = decSpec.inputs.find((i) => i.name === "window").shape[1];
  const nb = A.betas.shape[0];
  const t0 = performance.now();
  // the encoder's inputs, fed by name (older encoders also take betas)
  const encArrays = {
    features: [A.features.data, [1, N, A.features.shape[1]]], nbr: [A.nbr.data, [N, K]], mask: [A.mask.data, [N, K]],
    descriptor: [A.descriptor.data, [1, A.descriptor.shape[0]]], betas: [A.betas.data, [1, nb]],
  };
  const encFeeds = {};
  for (const i of encSpec.inputs) {
    if (!encArrays[i.name]) throw new Error(`the garment encoder takes '${i.name}', which this runtime cannot feed`);
    encFeeds[i.name] = feed(ort, i, ...encArrays[i.name]);
  }
  const encOut = await enc.run(encFeeds);
  // its one output, without the batch axis, is a deformer input of the same name: g (N, S) (older: P (N, S, F_enc))
  const codeName = encSpec.outputs[0].name;
  const code = encOut[codeName];
  const codeT = new ort.Tensor("float32", await code.getData(), code.dims.slice(1));
  const nbr = feed(ort, inDec.nbr, A.nbr.data, [N, K]);
  const mask = feed(ort, inDec.mask, A.mask.data, [N, K]);
  const rest = feed(ort, inDec.rest, A.rest.data, [N, 3]);
  const lw = inDec.log_wbody ? feed(ort, inDec.log_wbody, A.log_wbody.data, [N, S]) : null;
  const frames = new Float32Array(T * N * 3);
  for (let lo = 0; lo < T; lo += batch) {
    const hi = Math.min(lo + batch, T);
    const B = hi - lo;
    // the motion window: frame t, t-1, ... t-window+1, frames before the first repeat the first
    const win = new Float32Array(B * window * D);
    for (let b = 0; b < B; b++) {
      for (let k = 0; k < window; k++) {
        const src = Math.max(lo + b - k, 0);
        win.set(A.poses.data.subarray(src * D, src * D + D), (b * window + k) * D);
      }
    }
    const betas = new Float32Array(B * nb);
    const joints = new Float32Array(B * S * 3);
    for (let b = 0; b < B; b++) {
      betas.set(A.betas.data, b * nb);
      joints.set(A.joints.data, b * S * 3);
    }
    const feeds = {
      [codeName]: codeT, window: new ort.Tensor("float32", win, [B, window, D]),
      betas: new ort.Tensor("float32", betas, [B, nb]), rest, nbr, mask,
      joints: new ort.Tensor("float32", joints, [B, S, 3]),
      trans: new ort.Tensor("float32", A.trans.data.slice(lo * 3, hi * 3), [B, 3]),
    };
    if (lw) feeds.log_wbody = lw;
    const out = await dec.run(feeds);
    frames.set(await out[decSpec.outputs[0].name].getData(), lo * N * 3);
  }
  const ms = (performance.now() - t0) / T;
  return { frames, T, N, msPerFrame: ms, variant };
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
