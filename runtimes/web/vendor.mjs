#!/usr/bin/env node
// Copy what a page of your own needs to run segadeform into DEST/segadeform/ (one folder to serve beside the page):
//   runtime.js          the browser API (loadOrt, loadPackage, openContainer, animate, packageSessions, Player)
//   core.js, cloth.js, collide.js   the shared JavaScript core it imports (the Node runtime's, as is)
//   ort/                onnxruntime-web's build and WebAssembly for the execution providers asked for
//   VENDORED.json       what was copied, from which versions (a later `vendor` replaces only these files)
//     node vendor.mjs DEST [--ep wasm|webgpu|both]          (npm run vendor -- DEST)
// Nothing is written over a file this script did not write: an existing DEST/segadeform without VENDORED.json is
// refused.  The model package (manifest.json, the graphs, weights.bin) is served as it is, from anywhere the page
// can fetch (another origin needs CORS headers).
import { copyFileSync, existsSync, mkdirSync, readFileSync, rmSync, writeFileSync } from "node:fs";
import { dirname, join, resolve } from "node:path";
import { fileURLToPath } from "node:url";

const HERE = dirname(fileURLToPath(import.meta.url));
const ORT_DIST = join(HERE, "node_modules", "onnxruntime-web", "dist");
const ORT_FILES = {
  wasm: ["ort.wasm.min.mjs", "ort-wasm-simd-threaded.mjs", "ort-wasm-simd-threaded.wasm"],
  webgpu: ["ort.webgpu.min.mjs", "ort-wasm-simd-threaded.asyncify.mjs", "ort-wasm-simd-threaded.asyncify.wasm"],
};
const CORE = ["core.js", "cloth.js", "collide.js"];

/** Vendor into `dest`; returns the list of files written (relative to dest). */
export function vendor(dest, { ep = "wasm" } = {}) {
  const eps = ep === "both" ? ["wasm", "webgpu"] : [ep];
  if (!eps.every((e) => ORT_FILES[e])) throw new Error(`--ep must be wasm, webgpu or both (got ${ep})`);
  if (!existsSync(ORT_DIST)) throw new Error(`${ORT_DIST} is missing: run \`npm ci\` in runtimes/web first`);
  const out = join(resolve(dest), "segadeform");
  const record = join(out, "VENDORED.json");
  let before = [];
  if (existsSync(out)) {
    if (!existsSync(record)) {
      throw new Error(`${out} exists and was not written by vendor.mjs (no VENDORED.json): nothing is written over it; ` +
        "choose another DEST or remove it yourself");
    }
    before = JSON.parse(readFileSync(record, "utf8")).files || [];
  }
  const files = [];
  const put = (src, rel, text = null) => {
    mkdirSync(dirname(join(out, rel)), { recursive: true });
    if (text === null) copyFileSync(src, join(out, rel));
    else writeFileSync(join(out, rel), text);
    files.push(rel);
  };
  for (const f of CORE) put(join(HERE, "..", "node", "src", f), f);
  const runtime = readFileSync(join(HERE, "src", "runtime.js"), "utf8");
  if (!runtime.includes('from "../../node/src/core.js"')) throw new Error("runtime.js no longer imports core.js as vendor.mjs expects");
  put(null, "runtime.js", runtime.replace('from "../../node/src/core.js"', 'from "./core.js"'));
  for (const e of eps) for (const f of ORT_FILES[e]) put(join(ORT_DIST, f), `ort/${f}`);
  for (const old of before) {
    if (!files.includes(old) && !old.includes("..")) rmSync(join(out, old), { force: true }); // ours, no longer needed
  }
  const version = (p) => JSON.parse(readFileSync(p, "utf8")).version;
  writeFileSync(record, JSON.stringify({
    vendored_by: "segadeform runtimes/web/vendor.mjs", segadeform_web: version(join(HERE, "package.json")),
    onnxruntime_web: version(join(ORT_DIST, "..", "package.json")), ep: eps, files,
  }, null, 1) + "\n");
  return files;
}

if (process.argv[1] === fileURLToPath(import.meta.url)) {
  const args = process.argv.slice(2);
  const at = args.indexOf("--ep");
  const ep = at >= 0 ? args.splice(at, 2)[1] : "wasm";
  if (args.length !== 1 || args[0].startsWith("-")) {
    console.error("usage: node vendor.mjs DEST [--ep wasm|webgpu|both]");
    process.exit(2);
  }
  try {
    const files = vendor(args[0], { ep });
    console.log(`${files.length} files -> ${join(resolve(args[0]), "segadeform")} (import ./segadeform/runtime.js; ` +
      "loadOrt(ep) finds ./segadeform/ort/ beside it; examples/embed.html, and embed-worker.* for a Web Worker)");
  } catch (e) {
    console.error(`error: ${e.message}`);
    process.exit(1);
  }
}
