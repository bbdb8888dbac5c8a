// segadeform's Node runtime: a model package (docs/package.md) and a garment asset (.sgda) with a motion file
// (.sgdm) -- or a scene bundle (.sgdb) -- in, frames out; the package's body graph poses the body.
// The logic is core.js (shared with the browser runtime, runtimes/web); this file adds files and hashes.
import { readFileSync, writeFileSync, renameSync, existsSync, unlinkSync } from "node:fs";
import { createHash } from "node:crypto";
import { join } from "node:path";
import * as ort from "onnxruntime-node";
import {
  animateWith, BodyCollider, clothWith, collideWith, compareFrames, DEFAULT_CLOTH, DEFAULT_COLLISION_MARGIN,
  defaultEffects, parseBundle, parseCloth, parseEffects, pc2Bytes, pickBody, pickVariant, poseBodyWith, pushOutFrames,
  readAsset as checkAsset, readManifest, readMotion as checkMotion, restBodyWith,
} from "./core.js";

export { parseBundle, readBundle } from "./bundle.js";
export {
  BodyCollider, compareFrames, DEFAULT_CLOTH, DEFAULT_COLLISION_MARGIN, defaultEffects, parseCloth, parseEffects,
  pickBody, pickVariant, pushOutFrames,
};

/** Read a model package's manifest (docs/package.md) and check every file against its sha256. */
export function loadManifest(dir) {
  const path = join(dir, "manifest.json");
  if (!existsSync(path)) throw new Error(`${dir}: no manifest.json (not a model package)`);
  const m = readManifest(JSON.parse(readFileSync(path, "utf8")), path);
  for (const [name, g] of Object.entries(m.graphs)) checkHash(dir, g.file, g.sha256, `graph '${name}'`);
  if (m.weights) checkHash(dir, m.weights.file, m.weights.sha256, "the weights file");
  return m;
}

function checkHash(dir, file, sha256, what) {
  const path = join(dir, file);
  if (!existsSync(path)) throw new Error(`${path}: ${what} file is missing`);
  const h = createHash("sha256").update(readFileSync(path)).digest("hex");
  if (sha256 && h !== sha256) throw new Error(`${path}: ${what} does not match its manifest hash`);
}

function readContainer(path) {
  if (!existsSync(path)) throw new Error(`${path}: no such file`);
  return parseBundle(readFileSync(path), path);
}

/** Read and check a garment asset (.sgda). */
export function readAsset(path) {
  return checkAsset(readContainer(path), path);
}

/** Read and check a motion file (.sgdm). */
export function readMotion(path) {
  return checkMotion(readContainer(path), path);
}

function sessions(dir, options) {
  const so = { intraOpNumThreads: options.threads || 1, interOpNumThreads: 1, executionProviders: ["cpu"] };
  const made = new Map();
  // sessions from the file path: graphs may keep their weights in the package's shared weights.bin
  return (spec) => {
    if (!made.has(spec.file)) made.set(spec.file, ort.InferenceSession.create(join(dir, spec.file), so));
    return made.get(spec.file);
  };
}

/**
 * Animate a garment with a package:
 *   animate(dir, garment, motion, options)  garment: a .sgda path or readAsset(...); motion: a .sgdm path or readMotion(...)
 *   animate(dir, bundle, options)           bundle: a .sgdb path or readBundle(...) (the Python runtime's scene)
 * Returns { frames: Float32Array (T*N*3), T, N, msPerFrame, variant, effects, faces, fps, warnings } and, with
 * options.body, body: { vertices (T*V*3), joints, restJoints, faces, V, T, msPerFrame, graph } (the package's body
 * graph, with the garment's skinning); with collisions in the effects, the frames pushed out of that body and
 * collisions: { moved (vertex-frames moved), msPerFrame, margin }; with cloth in the effects, the cloth stage's frames
 * instead (cloth.js; contact included, no push-out) and cloth: { contacts, pushed, traced, resets, firstReset, msPerFrame }.
 * options: { effects (an object or "dqs,dynamics,wrinkles,collisions[,cloth]"; default: a bundle's, else the model's
 * own and collisions when the package has a body graph), collisionMargin (metres, 0.004), cloth (the stage's knobs:
 * an object or "iterations=8,..."; DEFAULT_CLOTH), batch (8), threads (1), body (false), force (false: a motion
 * retargeted onto another body or shape than the asset's is refused, as `segadeform run` refuses it) }.
 */
export async function animate(dir, garment, motion, options = {}) {
  let source;
  if (typeof garment === "string" && !garment.endsWith(".sgdb")) garment = readAsset(garment);
  if (typeof garment === "string") garment = readContainer(garment);
  if (garment.meta && garment.meta.kind === "segadeform-garment-asset") {
    if (typeof motion === "string") motion = readMotion(motion);
    else if (!motion || !motion.arrays) throw new Error("a garment asset needs a motion (a .sgdm path or readMotion(...))");
    else checkMotion(motion);
    source = { asset: checkAsset(garment), motion };
  } else {
    if (motion && !motion.arrays) options = motion;
    source = garment;
  }
  const manifest = loadManifest(dir);
  // signed changes ("+cloth", "-wrinkles") are to the run's default effects, as in `segadeform run`
  if (typeof options.effects === "string") {
    options = { ...options, effects: parseEffects(options.effects, defaultEffects(manifest)) };
  }
  const session = sessions(dir, options);
  const r = await animateWith(ort, manifest, source, session, options);
  if (source.motion) r.motionMeta = source.motion.meta;
  else if (source.meta && Number.isInteger(source.meta.start_frame)) r.motionMeta = { start_frame: source.meta.start_frame };
  if (options.body || r.effects.collisions || r.effects.cloth) {
    const body = await poseBodyWith(ort, manifest, source, session, { skinning: r.effects.skinning, batch: options.batch });
    if (options.body) r.body = body;
    if (r.effects.cloth) {
      const rest = await restBodyWith(ort, manifest, source, session, { skinning: r.effects.skinning });
      const settings = typeof options.cloth === "string" ? parseCloth(options.cloth) : options.cloth || DEFAULT_CLOTH;
      r.cloth = clothWith(r, body, rest, source, { settings, margin: options.collisionMargin ?? DEFAULT_COLLISION_MARGIN,
        batch: options.batch });
    } else if (r.effects.collisions) {
      r.collisions = collideWith(r, body, { margin: options.collisionMargin ?? DEFAULT_COLLISION_MARGIN,
        batch: options.batch });
    }
  }
  return r;
}

/** Write frames (T*N*3 float32) as a PC2 point cache, atomically. */
export function writePC2(path, frames, T, N, opts = {}) {
  const tmp = `${path}.tmp-${process.pid}`;
  try {
    writeFileSync(tmp, pc2Bytes(frames, T, N, opts));
    renameSync(tmp, path);
  } catch (e) {
    if (existsSync(tmp)) unlinkSync(tmp);
    throw e;
  }
}

export { ort };
