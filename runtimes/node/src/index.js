// segadeform's Node runtime: a model package (docs/package.md) and a scene bundle in, frames out.
import { readFileSync, writeFileSync, renameSync, existsSync } from "node:fs";
import { createHash } from "node:crypto";
import { join } from "node:path";
import * as ort from "onnxruntime-node";

export { parseBundle, readBundle } from "./bundle.js";

/** Read a model package's manifest and check every graph file against its sha256. */
export function loadManifest(dir) {
  const path = join(dir, "manifest.json");
  if (!existsSync(path)) throw new Error(`${dir}: no manifest.json (not a model package)`);
  const m = JSON.parse(readFileSync(path, "utf8"));
  if (m.format !== "segadeform-model-package") throw new Error(`${path}: not a segadeform model package`);
  return m;
}

/** The deformer graph for a set of effects: the manifest's variant whose effects match. */
export function pickVariant(manifest, effects) {
  for (const [name, v] of Object.entries(manifest.variants || {})) {
    const e = v.effects;
    if (e.skinning === effects.skinning && e.wrinkles === effects.wrinkles && e.dynamics === effects.dynamics) {
      return { name, spec: v };
    }
  }
  throw new Error(`no deformer graph for effects ${JSON.stringify(effects)}`);
}

function checkHash(dir, spec) {
  const bytes = readFileSync(join(dir, spec.file));
  const h = createHash("sha256").update(bytes).digest("hex");
  if (spec.sha256 && h !== spec.sha256) throw new Error(`${join(dir, spec.file)}: does not match its manifest hash`);
  return bytes;
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
  const enc = await ort.InferenceSession.create(checkHash(dir, encSpec), so);
  const dec = await ort.InferenceSession.create(checkHash(dir, decSpec), so);
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
  const encOut = await enc.run({
    features: feed(inEnc.features, A.features.data, [1, N, A.features.shape[1]]),
    nbr: feed(inEnc.nbr, A.nbr.data, [N, K]),
    mask: feed(inEnc.mask, A.mask.data, [N, K]),
    descriptor: feed(inEnc.descriptor, A.descriptor.data, [1, A.descriptor.shape[0]]),
    betas: feed(inEnc.betas, A.betas.data, [1, nb]),
  });
  const P = encOut[encSpec.outputs[0].name]; // (1, N, S, F)
  const F = P.dims[3];
  const Pd = tensor("float32", P.data, [N, S, F]);
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
      P: Pd, window: tensor("float32", win, [B, window, D]), betas: tensor("float32", betas, [B, nb]), rest,
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
