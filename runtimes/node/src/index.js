// segadeform's Node runtime: a model package (docs/package.md) and a scene bundle in, frames out.
import { readFileSync, writeFileSync, renameSync, existsSync } from "node:fs";
import { createHash } from "node:crypto";
import { join } from "node:path";
import * as ort from "onnxruntime-node";

export { parseBundle, readBundle } from "./bundle.js";

const FORMAT = "segadeform-model-package";

/**
 * Read a model package's manifest (docs/package.md) and check every file against its sha256.
 * Schema-1 manifests are read in schema-2 form: `graphs` holds every graph once, each deformer with
 * its `effects`; `default_deformer` names the model's own.
 */
export function loadManifest(dir) {
  const path = join(dir, "manifest.json");
  if (!existsSync(path)) throw new Error(`${dir}: no manifest.json (not a model package)`);
  let m = JSON.parse(readFileSync(path, "utf8"));
  if (m.format !== FORMAT && m.schema_version !== 1) throw new Error(`${path}: not a segadeform model package`);
  if (m.schema_version === 1) m = upgradeManifest(m);
  else if (m.schema_version !== 2) {
    throw new Error(`${path}: unsupported manifest schema version (expected 1 or 2, got ${m.schema_version})`);
  }
  if (!m.graphs || !m.graphs.garment_encoder) throw new Error(`${path}: manifest has no garment_encoder`);
  for (const [name, g] of Object.entries(m.graphs)) checkHash(dir, g.file, g.sha256, `graph '${name}'`);
  if (m.weights) checkHash(dir, m.weights.file, m.weights.sha256, "the weights file");
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

function checkHash(dir, file, sha256, what) {
  const path = join(dir, file);
  if (!existsSync(path)) throw new Error(`${path}: ${what} file is missing`);
  const h = createHash("sha256").update(readFileSync(path)).digest("hex");
  if (sha256 && h !== sha256) throw new Error(`${path}: ${what} does not match its manifest hash`);
}

function tensor(type, data, dims) {
  return new ort.Tensor(type, data, dims);
}

/** Feed for an input spec from a typed array (int32 bundle indices become int64 when the graph wants it). */
function feed(spec, arr, dims) {
  if (spec.dtype === "int64") {
    const out = new BigInt64Array(arr.length);
    for (let i = 0; i < arr.length; i++) out[i] = BigInt(arr[i]);
    return tensor("int64", out, dims);
  }
  if (spec.dtype === "int32") return tensor("int32", Int32Array.from(arr), dims);
  if (spec.dtype === "bool") return tensor("bool", Uint8Array.from(arr), dims);
  return tensor("float32", arr instanceof Float32Array ? arr : Float32Array.from(arr), dims);
}

/**
 * Animate a bundle with a package.  Returns { frames: Float32Array (T*N*3), T, N, msPerFrame }.
 * options: { effects (default: the bundle's), batch (8), threads (1) }.
 */
export async function animate(dir, bundle, options = {}) {
  const manifest = loadManifest(dir);
  const { arrays: A, meta } = bundle;
  const effects = options.effects || meta.effects;
  const batch = options.batch || 8;
  const so = { intraOpNumThreads: options.threads || 1, interOpNumThreads: 1, executionProviders: ["cpu"] };
  const encSpec = manifest.graphs.garment_encoder;
  const { spec: decSpec } = pickVariant(manifest, effects);
  // sessions from the file path: graphs may keep their weights in the package's shared weights.bin
  const enc = await ort.InferenceSession.create(join(dir, encSpec.file), so);
  const dec = await ort.InferenceSession.create(join(dir, decSpec.file), so);
  const N = A.rest.shape[0];
  const K = A.nbr.shape[1];
  const S = A.joints.shape[0];
  const T = A.poses.shape[0];
  const D = A.poses.shape[1];
  const inEnc = Object.fromEntries(encSpec.inputs.map((i) => [i.name, i]));
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
    encFeeds[i.name] = feed(i, ...encArrays[i.name]);
  }
  const encOut = await enc.run(encFeeds);
  // its one output, without the batch axis, is a deformer input of the same name: g (N, S) (older: P (N, S, F_enc))
  const codeName = encSpec.outputs[0].name;
  const code = encOut[codeName];
  const codeT = tensor("float32", code.data, code.dims.slice(1));
  const nbr = feed(inDec.nbr, A.nbr.data, [N, K]);
  const mask = feed(inDec.mask, A.mask.data, [N, K]);
  const rest = feed(inDec.rest, A.rest.data, [N, 3]);
  const lw = inDec.log_wbody ? feed(inDec.log_wbody, A.log_wbody.data, [N, S]) : null;
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
      [codeName]: codeT, window: tensor("float32", win, [B, window, D]), betas: tensor("float32", betas, [B, nb]), rest,
      nbr, mask, joints: tensor("float32", joints, [B, S, 3]),
      trans: tensor("float32", A.trans.data.slice(lo * 3, hi * 3), [B, 3]),
    };
    if (lw) feeds.log_wbody = lw;
    const out = await dec.run(feeds);
    frames.set(out[decSpec.outputs[0].name].data, lo * N * 3);
  }
  const ms = (performance.now() - t0) / T;
  return { frames, T, N, msPerFrame: ms };
}

/** Write frames (T*N*3 float32) as a PC2 point cache, atomically. */
export function writePC2(path, frames, T, N, { startFrame = 0, sampleRate = 1 } = {}) {
  const header = Buffer.alloc(32);
  header.write("POINTCACHE2\0", 0, "latin1");
  header.writeInt32LE(1, 12);
  header.writeInt32LE(N, 16);
  header.writeFloatLE(startFrame, 20);
  header.writeFloatLE(sampleRate, 24);
  header.writeInt32LE(T, 28);
  const tmp = `${path}.tmp-${process.pid}`;
  writeFileSync(tmp, Buffer.concat([header, Buffer.from(frames.buffer, frames.byteOffset, frames.byteLength)]));
  renameSync(tmp, path);
}

export { ort };
