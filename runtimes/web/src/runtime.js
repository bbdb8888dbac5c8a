// segadeform in the browser: a model package fetched over HTTP (or dropped on the page), its graphs run by
// onnxruntime-web (wasm or WebGPU).  The animation logic is the Node runtime's core.js, shared as is.
import {
  animateWith, clothWith, collideWith, compareFrames, DEFAULT_CLOTH, DEFAULT_COLLISION_MARGIN, defaultEffects,
  parseBundle, parseCloth, pickBody, pickVariant, poseBodyWith, readAsset, readManifest, readMotion, restBodyWith,
} from "../../node/src/core.js";

export { compareFrames, parseBundle, pickBody, pickVariant, readAsset, readMotion };

const ORT_BUILDS = { wasm: "ort.wasm.min.mjs", webgpu: "ort.webgpu.min.mjs" };

/** Import onnxruntime-web for an execution provider ("wasm" or "webgpu"); `base` is its dist/ URL. */
export async function loadOrt(ep, base) {
  const file = ORT_BUILDS[ep];
  if (!file) throw new Error(`unknown execution provider '${ep}' (expected wasm or webgpu)`);
  const ort = await import(new URL(file, base).href);
  ort.env.wasm.wasmPaths = base;
  ort.env.wasm.numThreads = 1; // threads need cross-origin isolation; one thread works everywhere
  return ort;
}

export async function fetchBytes(url) {
  const r = await fetch(url);
  if (!r.ok) throw new Error(`${url}: ${r.status} ${r.statusText}`);
  return new Uint8Array(await r.arrayBuffer());
}

async function sha256Hex(bytes) {
  const h = new Uint8Array(await crypto.subtle.digest("SHA-256", bytes));
  return Array.from(h, (b) => b.toString(16).padStart(2, "0")).join("");
}

/** A package from its manifest and a function giving a file's bytes, every file checked against its SHA-256. */
async function packageFrom(manifest, where, bytesOf) {
  const files = {};
  const want = Object.values(manifest.graphs).map((g) => [g.file, g.sha256]);
  if (manifest.weights) want.push([manifest.weights.file, manifest.weights.sha256]);
  for (const [file, sha] of want) {
    const bytes = await bytesOf(file);
    if (sha && (await sha256Hex(bytes)) !== sha) throw new Error(`${where}${file}: does not match its manifest hash`);
    files[file] = bytes;
  }
  return { manifest, files, url: where };
}

/**
 * Fetch a model package (its manifest, the graphs and the shared weights), checking every file against
 * the manifest's SHA-256.  Returns { manifest, files: {name: Uint8Array}, url }.
 */
export async function loadPackage(url) {
  const base = new URL(url.endsWith("/") ? url : `${url}/`, location.href);
  const r = await fetch(new URL("manifest.json", base));
  if (!r.ok) throw new Error(`${base}: no manifest.json (not a model package)`);
  const manifest = readManifest(await r.json(), new URL("manifest.json", base).href);
  return packageFrom(manifest, base.href, (file) => fetchBytes(new URL(file, base)));
}

/** A package from dropped files ({name: Uint8Array}: manifest.json, the graphs, weights.bin). */
export async function packageFromFiles(files) {
  if (!files["manifest.json"]) throw new Error("the dropped files have no manifest.json (expected a model package's files)");
  const manifest = readManifest(JSON.parse(new TextDecoder().decode(files["manifest.json"])), "manifest.json");
  return packageFrom(manifest, "dropped package: ", async (file) => {
    if (!files[file]) throw new Error(`dropped package: ${file} is missing (the manifest lists it)`);
    return files[file];
  });
}

/** Parse a container (bytes or a URL) as a garment asset, a motion file or a scene bundle, by its meta.kind. */
export async function openContainer(src, name = String(src)) {
  const bytes = typeof src === "string" ? await fetchBytes(src) : src;
  const parsed = parseBundle(bytes, name);
  if (parsed.meta.kind === "segadeform-garment-asset") return { kind: "asset", parsed: readAsset(parsed, name) };
  if (parsed.meta.kind === "segadeform-motion") return { kind: "motion", parsed: readMotion(parsed, name) };
  return { kind: "bundle", parsed };
}

/**
 * Animate a scene bundle (parsed, or a URL) or { asset, motion } (parsed) with a loaded package on `ort` (from
 * loadOrt), and pose the body when the package has a body graph (options.body !== false) or collisions need it.
 * Returns core.animateWith's result plus the execution provider, `body` (core.poseBodyWith's result, or { error }
 * when the body cannot be posed: no body graph, another body) and, with collisions in the effects (named, or by
 * default when the package has a body graph), the frames pushed out of that body (the Node runtime's collide.js)
 * and `collisions` ({ moved, msPerFrame, margin }: core.collideWith's).  `cloth` (true, or the stage's knobs as
 * "iterations=8,..." or an object) turns the cloth stage on over the effects (the model's own when none are named):
 * the frames are then the stage's (core.clothWith, contact included: no push-out) and `cloth` is its counts.
 */
export async function animate(ort, pkg, source, { ep = "wasm", batch = 8, effects, body = true,
  collisionMargin = DEFAULT_COLLISION_MARGIN, cloth = null, force = false } = {}) {
  if (typeof source === "string") source = parseBundle(await fetchBytes(source), source);
  if (cloth) effects = { ...(effects || (source.asset ? defaultEffects(pkg.manifest) : source.meta.effects)), cloth: true };
  const external = pkg.manifest.weights
    ? [{ path: pkg.manifest.weights.file, data: pkg.files[pkg.manifest.weights.file] }] : [];
  const made = new Map();
  const session = (spec) => {
    if (!made.has(spec.file)) {
      made.set(spec.file, ort.InferenceSession.create(pkg.files[spec.file], {
        executionProviders: [ep], externalData: external, graphOptimizationLevel: "all",
      }));
    }
    return made.get(spec.file);
  };
  const r = await animateWith(ort, pkg.manifest, source, session, { batch, effects, collisionMargin, force });
  let posed = null;
  const need = r.effects.collisions || r.effects.cloth;
  if ((body || need) && Object.values(pkg.manifest.graphs).some((g) => g.role === "body")) {
    try {
      posed = await poseBodyWith(ort, pkg.manifest, source, session, { skinning: r.effects.skinning, batch });
    } catch (e) {
      if (need) throw e; // collisions and the cloth stage cannot do without the body
      posed = { error: e.message };
    }
  }
  let clothed = null, collisions = null;
  if (r.effects.cloth) {
    const rest = await restBodyWith(ort, pkg.manifest, source, session, { skinning: r.effects.skinning });
    const settings = typeof cloth === "string" ? parseCloth(cloth) : typeof cloth === "object" && cloth ? cloth : DEFAULT_CLOTH;
    clothed = clothWith(r, posed, rest, source, { settings, margin: collisionMargin, batch });
  } else if (r.effects.collisions) {
    collisions = collideWith(r, posed, { margin: collisionMargin, batch });
  }
  return { ...r, ep, source, body: body ? posed : null, collisions, cloth: clothed };
}
