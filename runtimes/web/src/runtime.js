// segadeform in the browser: a model package fetched over HTTP (or dropped on the page), its graphs run by
// onnxruntime-web (wasm or WebGPU).  The animation logic is the Node runtime's core.js, shared as is.
import {
  checkOptions, compareFrames, DEFAULT_COLLISION_MARGIN, effectsOf, hasBody, parseBundle, pickBody, pickVariant,
  Player, playWith, readAsset, readManifest, readMotion, releaseSessions,
} from "../../node/src/core.js";

export { compareFrames, parseBundle, pickBody, pickVariant, Player, readAsset, readMotion };

const ORT_BUILDS = { wasm: "ort.wasm.min.mjs", webgpu: "ort.webgpu.min.mjs" };

/**
 * Import onnxruntime-web for an execution provider ("wasm" or "webgpu"); `base` is the URL of its files (its dist/,
 * or the ort/ folder `npm run vendor` makes; default: the ort/ folder beside this file, where vendor puts it, so that
 * the same call works on a page, in a Web Worker and one folder down).  `threads` (1): WebAssembly threads, which need
 * a cross-origin isolated page (served with Cross-Origin-Opener-Policy: same-origin and Cross-Origin-Embedder-Policy:
 * require-corp); more than one on a page that is not is refused here rather than silently run on one.
 */
export async function loadOrt(ep, base = new URL("./ort/", import.meta.url), { threads = 1 } = {}) {
  const file = ORT_BUILDS[ep];
  if (!file) throw new Error(`unknown execution provider '${ep}' (expected wasm or webgpu)`);
  if (!(Number.isInteger(threads) && threads >= 1)) throw new Error(`threads must be an integer >= 1 (got ${threads})`);
  if (threads > 1 && !globalThis.crossOriginIsolated) {
    throw new Error(`${threads} threads need a cross-origin isolated page (COOP: same-origin, COEP: require-corp headers)`);
  }
  const ort = await import(new URL(file, base).href);
  ort.env.wasm.wasmPaths = base instanceof URL ? base.href : base;
  ort.env.wasm.numThreads = threads; // one thread works everywhere
  return ort;
}

export async function fetchBytes(url) {
  const r = await fetchOr(url);
  if (!r.ok) throw new Error(`${url}: ${r.status} ${r.statusText}`);
  return new Uint8Array(await r.arrayBuffer());
}

/* fetch(url), its network failure named with the URL and the likely cause (the browser says only "Failed to fetch"
 * for a server that is down and for another origin without CORS headers alike: a web developer's trial) */
async function fetchOr(url) {
  try {
    return await fetch(url);
  } catch (e) {
    // (in a blob: worker a relative URL has no base: new URL threw here and hid the fetch's error, a web developer's
    // trial of a worker)
    const here = typeof location !== "undefined" ? location.href : undefined;
    if (!URL.canParse(String(url), here)) {
      throw new Error(`${url}: a relative URL with no base here (${here ?? "no location"}; a blob: worker?): pass ` +
        "an absolute URL");
    }
    const other = here !== undefined && new URL(url, here).origin !== location.origin;
    throw new Error(`${url}: ${e.message} (${other ? "another origin than the page's: it must send CORS headers " +
      "(Access-Control-Allow-Origin), or serve it from the page's origin" : "is the server running?"})`);
  }
}

/* JSON.parse of a file's text, its error naming the file */
function parseJson(text, name) {
  try {
    return JSON.parse(text);
  } catch (e) {
    throw new Error(`${name}: not JSON (${e.message})`);
  }
}

async function sha256Hex(bytes) {
  const h = new Uint8Array(await crypto.subtle.digest("SHA-256", bytes));
  return Array.from(h, (b) => b.toString(16).padStart(2, "0")).join("");
}

/**
 * A package from its manifest and a function giving a file's bytes: { manifest, url, file(name) }.  file() gets a
 * file the manifest lists (a graph, the shared weights) when a run first needs it, checks it against the manifest's
 * SHA-256 and keeps it: a run fetches the two or three graphs it uses, not all of them.  `eager`: every file now
 * (dropped files, which are at hand: a bad one is said when dropped).
 */
async function packageFrom(manifest, where, bytesOf, { eager = false } = {}) {
  const want = new Map(Object.values(manifest.graphs).map((g) => [g.file, g.sha256]));
  if (manifest.weights) want.set(manifest.weights.file, manifest.weights.sha256);
  const got = new Map();
  const file = (name) => {
    if (!want.has(name)) throw new Error(`${where}${name}: not a file of the package's manifest`);
    if (!got.has(name)) {
      got.set(name, (async () => {
        const bytes = await bytesOf(name);
        const sha = want.get(name);
        if (sha && (await sha256Hex(bytes)) !== sha) throw new Error(`${where}${name}: does not match its manifest hash`);
        return bytes;
      })());
    }
    return got.get(name);
  };
  if (eager) for (const name of want.keys()) await file(name);
  return { manifest, url: where, file };
}

/**
 * A model package at `url`: its manifest now, its files (graphs, shared weights) fetched as runs need them, each
 * checked against the manifest's SHA-256.  Returns { manifest, url, file(name) -> Promise<Uint8Array> }.  A package
 * on another origin than the page needs CORS headers.
 */
export async function loadPackage(url) {
  const rel = url.endsWith("/") ? url : `${url}/`;
  if (!URL.canParse(rel, location.href)) {  // a blob: worker's location is no base for a relative URL
    throw new Error(`${url}: a relative URL, and ${location.href} is no base for it (a blob: worker?): pass an ` +
      "absolute URL (new URL(url, page's location).href, posted from the page)");
  }
  const base = new URL(rel, location.href);
  const where = new URL("manifest.json", base).href;
  const r = await fetchOr(where);
  if (!r.ok) throw new Error(`${base}: no manifest.json (not a model package)`);
  const manifest = readManifest(parseJson(await r.text(), where), where);
  return packageFrom(manifest, base.href, (file) => fetchBytes(new URL(file, base)));
}

/** A package from dropped files ({name: Uint8Array}: manifest.json, the graphs, weights.bin), every file checked now. */
export async function packageFromFiles(files) {
  if (!files["manifest.json"]) throw new Error("the dropped files have no manifest.json (expected a model package's files)");
  const manifest = readManifest(parseJson(new TextDecoder().decode(files["manifest.json"]), "manifest.json"),
    "manifest.json");
  return packageFrom(manifest, "dropped package: ", async (file) => {
    if (!files[file]) throw new Error(`dropped package: ${file} is missing (the manifest lists it)`);
    return files[file];
  }, { eager: true });
}

const KINDS = { asset: "a garment asset (.sgda)", motion: "a motion file (.sgdm)", bundle: "a scene bundle (.sgdb)" };

/** Parse a container (bytes or a URL) as a garment asset, a motion file or a scene bundle, by its meta.kind.
 * `expect` ("asset", "motion" or "bundle"): another kind is an error naming the file (a garment and a motion given
 * the other way round were read as they came: a web developer's trial). */
export async function openContainer(src, name = String(src), { expect } = {}) {
  const bytes = typeof src === "string" ? await fetchBytes(src) : src;
  const parsed = parseBundle(bytes, name);
  const kind = parsed.meta.kind === "segadeform-garment-asset" ? "asset"
    : parsed.meta.kind === "segadeform-motion" ? "motion" : "bundle";
  if (expect !== undefined && kind !== expect) throw new Error(`${name}: expected ${KINDS[expect]}, got ${KINDS[kind]}`);
  if (kind === "asset") return { kind, parsed: readAsset(parsed, name) };
  if (kind === "motion") return { kind, parsed: readMotion(parsed, name) };
  return { kind, parsed };
}

/**
 * onnxruntime-web sessions of a loaded package's graphs, each made once: session(spec) -> InferenceSession;
 * release() frees them (WebAssembly memory the garbage collector does not see: 25 animate() calls grew a page from
 * 145 to 464 MB before).
 */
export function packageSessions(ort, pkg, { ep = "wasm" } = {}) {
  const w = pkg.manifest.weights;
  const made = new Map();
  const session = (spec) => {
    if (!made.has(spec.file)) {
      made.set(spec.file, (async () => ort.InferenceSession.create(await pkg.file(spec.file), {
        executionProviders: [ep], externalData: w ? [{ path: w.file, data: await pkg.file(w.file) }] : [],
        graphOptimizationLevel: "all",
      }))());
    }
    return made.get(spec.file);
  };
  session.release = () => releaseSessions(made);
  return session;
}

/**
 * Animate a scene bundle (parsed, or a URL) or { asset, motion } (parsed) with a loaded package on `ort` (from
 * loadOrt), and pose the body when the package has a body graph (options.body !== false) or collisions need it.
 * Returns core.playWith's result plus the execution provider and `body` (its posed body, or { error } when the body
 * cannot be posed: another body; null without a body graph).  With collisions in the effects (named, or by default
 * when the package has a body graph) the frames are pushed out of that body (the Node runtime's collide.js) and
 * `collisions` is { moved, msPerFrame, margin }.  `effects`: an object or text as `segadeform run --effects` reads it
 * ("dqs,dynamics", "+cloth").  `cloth` (true, or the stage's knobs as "iterations=8,..." or an object) turns the cloth
 * stage on over the effects (the model's own when none are named): the frames are then the stage's (contact
 * included: no push-out) and `cloth` is its counts.  Sessions are made and freed on each call; to play chunks of a
 * motion as they come, open a core.Player on packageSessions(ort, pkg).
 */
export async function animate(ort, pkg, source, options = {}) {
  checkOptions(options, ["ep", "batch", "effects", "body", "collisionMargin", "cloth", "force"], "animate");
  const { ep = "wasm", batch = 8, body = true, collisionMargin = DEFAULT_COLLISION_MARGIN, cloth = null,
    force = false } = options;
  if (typeof source === "string") source = parseBundle(await fetchBytes(source), source);
  let effects = effectsOf(pkg.manifest, source, options.effects);
  if (cloth) effects = { ...effects, cloth: true };
  const session = packageSessions(ort, pkg, { ep });
  const knobs = typeof cloth === "string" || (cloth && typeof cloth === "object") ? cloth : null;
  const run = (withBody) => playWith(ort, pkg.manifest, source, session, { batch, effects, collisionMargin,
    cloth: knobs, force, body: withBody });
  try {
    const need = effects.collisions || effects.cloth;
    const showBody = body && hasBody(pkg.manifest);
    let r, bodyError = null;
    try {
      r = await run(showBody);
    } catch (e) {
      // collisions and the cloth stage cannot do without the body; a body only shown is left out, with why
      if (need || !showBody || !/another body/.test(e.message)) throw e;
      bodyError = e.message;
      r = await run(false);
    }
    return { ...r, ep, source, body: bodyError ? { error: bodyError } : r.body || null };
  } finally {
    await session.release();
  }
}
