// segadeform's Node runtime: a model package (docs/package.md) and a garment asset (.sgda) with a motion file
// (.sgdm) -- or a scene bundle (.sgdb) -- in, frames out; the package's body graph poses the body.
// The logic is core.js (shared with the browser runtime, runtimes/web); this file adds files and hashes.
import { readFileSync, writeFileSync, renameSync, existsSync, statSync, unlinkSync } from "node:fs";
import { createHash } from "node:crypto";
import { join } from "node:path";
import * as ort from "onnxruntime-node";
import {
  BodyCollider, checkOptions, compareFrames, DEFAULT_CLOTH, DEFAULT_COLLISION_MARGIN, defaultEffects, effectsLabel,
  parseBundle, parseCloth, parseEffects, pc2Bytes, pickBody, pickVariant, Player, PLAYER_OPTIONS, playWith,
  pushOutFrames, readAsset as checkAsset, readManifest, readMotion as checkMotion, releaseSessions,
} from "./core.js";

export { parseBundle, readBundle } from "./bundle.js";
export {
  BodyCollider, compareFrames, DEFAULT_CLOTH, Player, DEFAULT_COLLISION_MARGIN, defaultEffects, effectsLabel, parseCloth,
  parseEffects, pickBody, pickVariant, pushOutFrames,
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
  if (statSync(path).isDirectory()) throw new Error(`${path}: is a directory, not a file`);
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

// onnxruntime sessions of a package's graphs, each made once: session(spec) -> InferenceSession; release() frees
// them all (they hold native memory the garbage collector does not see: 150 animate() calls grew to 1.8 GB before)
// As segadeform run has them: the encoder (run once per garment) without onnxruntime's memory arena, which keeps a
// run's peak for the session's life (a 69k-vertex garment held 10 GB); over one thread, idle pool threads sleep
// instead of spinning (spinning took the cores the rest of the run needs: 2 threads ran slower than 1).
function sessions(dir, { threads = 1 } = {}) {
  const so = { intraOpNumThreads: threads, interOpNumThreads: 1, executionProviders: ["cpu"] };
  if (threads > 1) so.extra = { session: { intra_op: { allow_spinning: "0" } } };
  const made = new Map();
  // sessions from the file path: graphs may keep their weights in the package's shared weights.bin
  const session = (spec) => {
    if (!made.has(spec.file)) {
      const opts = { ...so, enableCpuMemArena: spec.role !== "encoder" };
      made.set(spec.file, ort.InferenceSession.create(join(dir, spec.file), opts));
    }
    return made.get(spec.file);
  };
  session.release = () => releaseSessions(made);
  return session;
}

function garmentSource(garment, motion, options) {
  if (typeof garment === "string" && !garment.endsWith(".sgdb")) garment = readAsset(garment);
  if (typeof garment === "string") garment = readContainer(garment);
  if (garment instanceof Uint8Array || garment === null || typeof garment !== "object") {
    throw new Error("expected a garment asset (a .sgda path or readAsset(...)) or a scene bundle (a .sgdb path or " +
      `readBundle(...)), got ${garment === null ? "null" : garment instanceof Uint8Array ? "bytes (parse them with " +
      "parseBundle first)" : typeof garment}`);
  }
  if (garment.meta && garment.meta.kind === "segadeform-garment-asset") {
    if (typeof motion === "string") motion = readMotion(motion);
    else if (!motion || !motion.arrays) throw new Error("a garment asset needs a motion (a .sgdm path or readMotion(...))");
    else checkMotion(motion);
    return { source: { asset: checkAsset(garment), motion }, options };
  }
  if (!garment.arrays || !garment.meta) throw new Error("expected a garment asset or a scene bundle (readAsset, readBundle)");
  return { source: garment, options: motion && !motion.arrays ? motion : options };
}

const ANIMATE_OPTIONS = ["effects", "collisionMargin", "cloth", "batch", "threads", "body", "force"];

/**
 * Animate a garment with a package:
 *   animate(dir, garment, motion, options)  garment: a .sgda path or readAsset(...); motion: a .sgdm path or readMotion(...)
 *   animate(dir, bundle, options)           bundle: a .sgdb path or readBundle(...) (the Python runtime's scene)
 * Returns { frames: Float32Array (T*N*3), T, N, msPerFrame, variant, effects, faces, fps, warnings } and, with
 * options.body, body: { vertices (T*V*3), joints, restJoints, faces, V, T, msPerFrame, graph } (the package's body graph, with the
 * garment's skinning); with collisions in the effects, the frames pushed out of that body and collisions: { moved
 * (vertex-frames moved), msPerFrame, margin }; with cloth in the effects, the cloth stage's frames instead (cloth.js;
 * contact included, no push-out) and cloth: { contacts, pushed, traced, resets, firstReset, msPerFrame }.
 * options: { effects (an object or "dqs,dynamics,wrinkles,collisions[,cloth]"; default: a bundle's, else the model's
 * own and collisions when the package has a body graph), collisionMargin (metres, 0.004), cloth (the stage's knobs:
 * an object or "iterations=8,..."; DEFAULT_CLOTH), batch (8), threads (1), body (false), force (false: a motion
 * retargeted onto another body or shape than the asset's is refused, as `segadeform run` refuses it) }; any other key
 * is refused.  The package is loaded and its sessions freed on every call: to play many clips or a motion that
 * arrives a chunk at a time, open() a Player once.  The posed body is held a batch of frames at a time (all of it
 * only with options.body).
 */
export async function animate(dir, garment, motion, options = {}) {
  const g = garmentSource(garment, motion, options);
  const { source } = g;
  const { threads, ...rest } = checkOptions(g.options, ANIMATE_OPTIONS, "animate");
  const manifest = loadManifest(dir);
  const session = sessions(dir, { threads });
  try {
    const r = await playWith(ort, manifest, source, session, rest);
    if (source.motion) r.motionMeta = source.motion.meta;
    else if (source.meta && Number.isInteger(source.meta.start_frame)) r.motionMeta = { start_frame: source.meta.start_frame };
    if (source.meta && Array.isArray(source.meta.left_out)) r.leftOut = source.meta.left_out; // a scene's stages not in it
    return r;
  } finally {
    await session.release();
  }
}

/**
 * A garment on a package, opened once and played a chunk of motion at a time (core.js Player: push(poses, trans) ->
 * { frames }, reset(), counts), for a game loop, a stream, or many clips without loading the package each time:
 *   const p = await open(dir, "skirt.sgda", { effects: "+cloth", fps: 30 });
 *   const { frames } = await p.push(poses, trans);   // B frames: poses (B*S*3), trans (B*3) -> frames (B*N*3)
 *   await p.close();                                 // frees the sessions
 * garment: a .sgda path or readAsset(...), or a .sgdb path or readBundle(...) (its garment).  options: Player.open's
 * (effects, collisionMargin, cloth, fps, batch, body, force), threads (1) and motion (a .sgdm path or readMotion(...):
 * the motion to be pushed, its body shape checked against the asset's, refused unless force when another).  A motion file's poses and fps fit as they are:
 * readMotion(path).arrays.poses.data, .trans.data and .meta.fps.
 */
export async function open(dir, garment, options = {}) {
  if (typeof garment === "string") garment = garment.endsWith(".sgdb") ? readContainer(garment) : readAsset(garment);
  if (garment === null || typeof garment !== "object" || !garment.meta) {
    throw new Error("expected a garment asset (a .sgda path or readAsset(...)) or a scene bundle (a .sgdb path or readBundle(...))");
  }
  const { threads, motion, ...rest } = checkOptions(options,
    [...PLAYER_OPTIONS.filter((k) => k !== "stages"), "threads", "motion"], "open");
  const source = garment.meta.kind === "segadeform-garment-asset" ? { asset: checkAsset(garment) } : garment;
  if (motion !== undefined) { // the motion to be pushed: its body shape checked against the asset's
    if (!source.asset) throw new Error("the option motion goes with a garment asset (a scene bundle holds its motion)");
    source.motion = typeof motion === "string" ? readMotion(motion) : motion;
  }
  const manifest = loadManifest(dir);
  const session = sessions(dir, { threads });
  try {
    const p = await Player.open(ort, manifest, source, session, rest);
    p.close = () => session.release();
    return p;
  } catch (e) {
    await session.release();
    throw e;
  }
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
