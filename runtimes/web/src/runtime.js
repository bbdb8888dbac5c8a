// segadeform in the browser: a model package fetched over HTTP, its graphs run by onnxruntime-web
// (wasm or WebGPU).  The animation logic is the Node runtime's core.js, shared as is.
import { animateWith, parseBundle, pickVariant, readManifest } from "../../node/src/core.js";

export { parseBundle, pickVariant };

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

async function fetchBytes(url) {
  const r = await fetch(url);
  if (!r.ok) throw new Error(`${url}: ${r.status} ${r.statusText}`);
  return new Uint8Array(await r.arrayBuffer());
}

async function sha256Hex(bytes) {
  const h = new Uint8Array(await crypto.subtle.digest("SHA-256", bytes));
  return Array.from(h, (b) => b.toString(16).padStart(2, "0")).join("");
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
  const files = {};
  const want = Object.values(manifest.graphs).map((g) => [g.file, g.sha256]);
  if (manifest.weights) want.push([manifest.weights.file, manifest.weights.sha256]);
  for (const [file, sha] of want) {
    const bytes = await fetchBytes(new URL(file, base));
    if (sha && (await sha256Hex(bytes)) !== sha) throw new Error(`${base}${file}: does not match its manifest hash`);
    files[file] = bytes;
  }
  return { manifest, files, url: base.href };
}

/**
 * Animate a bundle (parsed, or a URL) with a loaded package on `ort` (from loadOrt).
 * Returns core.animateWith's result plus the execution provider.
 */
export async function animate(ort, pkg, bundle, { ep = "wasm", batch = 8, effects } = {}) {
  if (typeof bundle === "string") bundle = parseBundle(await fetchBytes(bundle), bundle);
  const external = pkg.manifest.weights
    ? [{ path: pkg.manifest.weights.file, data: pkg.files[pkg.manifest.weights.file] }] : [];
  const session = (spec) => ort.InferenceSession.create(pkg.files[spec.file], {
    executionProviders: [ep], externalData: external, graphOptimizationLevel: "all",
  });
  const r = await animateWith(ort, pkg.manifest, bundle, session, { batch, effects });
  return { ...r, ep, bundle };
}
