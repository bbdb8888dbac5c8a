// segadeform's Node runtime: a model package (docs/package.md) and a scene bundle in, frames out.
// The logic is core.js (shared with the browser runtime, runtimes/web); this file adds files and hashes.
import { readFileSync, writeFileSync, renameSync, existsSync } from "node:fs";
import { createHash } from "node:crypto";
import { join } from "node:path";
import * as ort from "onnxruntime-node";
import { animateWith, pc2Bytes, pickVariant, readManifest } from "./core.js";

export { parseBundle, readBundle } from "./bundle.js";
export { pickVariant };

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

/**
 * Animate a bundle with a package.  Returns { frames: Float32Array (T*N*3), T, N, msPerFrame }.
 * options: { effects (default: the bundle's), batch (8), threads (1) }.
 */
export async function animate(dir, bundle, options = {}) {
  const manifest = loadManifest(dir);
  const so = { intraOpNumThreads: options.threads || 1, interOpNumThreads: 1, executionProviders: ["cpu"] };
  // sessions from the file path: graphs may keep their weights in the package's shared weights.bin
  return animateWith(ort, manifest, bundle, (spec) => ort.InferenceSession.create(join(dir, spec.file), so), options);
}

/** Write frames (T*N*3 float32) as a PC2 point cache, atomically. */
export function writePC2(path, frames, T, N, opts = {}) {
  const tmp = `${path}.tmp-${process.pid}`;
  writeFileSync(tmp, pc2Bytes(frames, T, N, opts));
  renameSync(tmp, path);
}

export { ort };
