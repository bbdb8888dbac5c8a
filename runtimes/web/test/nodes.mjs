// Per-node comparison of one ONNX graph on onnxruntime-web (WebGPU or wasm) against reference values, in headless
// Chromium: every intermediate the graph's outputs expose is compared with the reference's array of the same name.
// Used by bench/webgpu_nodes.py (which writes the graph with its intermediates as outputs and the reference).
//   node test/nodes.mjs --root DIR --model PATH_IN_ROOT --data PATH_IN_ROOT.sgdb --ep webgpu|wasm [--chromium ...]
// Prints `NODES {name: [max abs, max |ref|], ...}`.
import puppeteer from "puppeteer-core";
import { serve } from "../serve.mjs";

const args = process.argv.slice(2);
const opt = (name, dflt) => (args.includes(name) ? args[args.indexOf(name) + 1] : dflt);
const server = await serve(opt("--root"), 0);
const port = server.address().port;
const browser = await puppeteer.launch({
  executablePath: opt("--chromium", "/usr/bin/chromium"), headless: true, protocolTimeout: 900000,
  args: ["--no-sandbox", "--enable-unsafe-webgpu", "--enable-features=Vulkan", "--use-angle=swiftshader",
         "--use-webgpu-adapter=swiftshader", "--ignore-gpu-blocklist"],
});
let code = 0;
try {
  const page = await browser.newPage();
  const logs = [];
  page.on("console", (m) => logs.push(`${m.type()}: ${m.text()}`));
  await page.goto(`http://127.0.0.1:${port}/runtimes/web/index.html`);
  const r = await page.evaluate(async (model, data, ep, level) => {
    const base = "/runtimes/web/node_modules/onnxruntime-web/dist/";
    const ort = await import(`${base}${ep === "webgpu" ? "ort.webgpu.min.mjs" : "ort.wasm.min.mjs"}`);
    ort.env.wasm.wasmPaths = base;
    ort.env.wasm.numThreads = 1;
    const { parseBundle } = await import("/runtimes/node/src/core.js");
    const bytes = async (u) => new Uint8Array(await (await fetch(u)).arrayBuffer());
    const { arrays, meta } = parseBundle(await bytes(data), data);
    const sess = await ort.InferenceSession.create(await bytes(model), { executionProviders: [ep], graphOptimizationLevel: level });
    const feeds = {};
    for (const name of meta.inputs) {
      const a = arrays[`in__${name}`];
      const type = a.dtype === "f32" ? "float32" : a.dtype === "i32" ? "int32" : a.dtype === "i64" ? "int64" : "bool";
      feeds[name] = new ort.Tensor(type, a.data, a.shape);
    }
    const out = await sess.run(feeds);
    const res = {};
    for (const name of meta.outputs) {
      const ref = arrays[`out__${meta.keys[name]}`];
      if (!ref || !out[name]) continue;
      const got = await out[name].getData();
      let d = 0, m = 0;
      for (let i = 0; i < ref.data.length; i++) {
        d = Math.max(d, Math.abs(Number(got[i]) - Number(ref.data[i])));
        m = Math.max(m, Math.abs(Number(ref.data[i])));
      }
      res[name] = [d, m, got.length === ref.data.length];
    }
    return res;
  }, `/${opt("--model")}`, `/${opt("--data")}`, opt("--ep", "webgpu"), opt("--opt", "disabled"));
  console.log(`NODES ${JSON.stringify(r)}`);
} catch (e) {
  console.error(`${e.message}\n${logs.slice(-20).join("\n")}`);
  code = 1;
} finally {
  await browser.close();
  server.close();
}
process.exit(code);
