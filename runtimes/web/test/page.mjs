// Open the viewer page in headless Chromium, run a bundle through a package, print the result as
// `PAGE {json}` and save a screenshot.   Used by tests/runtimes/test_web.py:
//   node test/page.mjs --root REPO --package PATH_IN_ROOT --bundle PATH_IN_ROOT --ep wasm|webgpu
//        [--screenshot OUT.png] [--frame N] [--body B.pc2 --body-mesh B.obj] [--chromium /usr/bin/chromium]
import puppeteer from "puppeteer-core";
import { serve } from "../serve.mjs";

const args = process.argv.slice(2);
const opt = (name, dflt) => (args.includes(name) ? args[args.indexOf(name) + 1] : dflt);
const root = opt("--root"), ep = opt("--ep", "wasm"), shot = opt("--screenshot");
const server = await serve(root, 0);
const port = server.address().port;
const page_url = `http://127.0.0.1:${port}/runtimes/web/index.html?` + new URLSearchParams({
  package: `/${opt("--package")}/`, bundle: `/${opt("--bundle")}`, ep, batch: opt("--batch", "4"),
  frame: opt("--frame", "0"), paused: "1",
  ...(args.includes("--body") ? { body: `/${opt("--body")}`, bodyMesh: `/${opt("--body-mesh")}` } : {}),
});
const browser = await puppeteer.launch({
  executablePath: opt("--chromium", "/usr/bin/chromium"),
  headless: true,
  protocolTimeout: 600000, // WebGPU on a software GPU is slow: seconds per deformer call
  args: ["--no-sandbox", "--enable-unsafe-webgpu", "--enable-features=Vulkan", "--use-angle=swiftshader",
         "--use-webgpu-adapter=swiftshader", "--ignore-gpu-blocklist", "--window-size=960,720"],
});
let code = 0;
try {
  const page = await browser.newPage();
  await page.setViewport({ width: 960, height: 720 });
  const logs = [];
  page.on("console", (m) => logs.push(`${m.type()}: ${m.text()}`));
  page.on("pageerror", (e) => logs.push(`pageerror: ${e.message}`));
  await page.goto(page_url);
  await page.waitForFunction("window.segadeformResult !== undefined", { timeout: 540000, polling: 250 });
  const r = await page.evaluate("window.segadeformResult");
  r.webgpu = await page.evaluate("!!navigator.gpu && navigator.gpu.requestAdapter().then((a) => !!a)");
  r.browser = await browser.version();
  if (shot) {
    await new Promise((ok) => setTimeout(ok, 500)); // a few animation frames to draw the mesh
    await page.screenshot({ path: shot });
  }
  console.log(`PAGE ${JSON.stringify(r)}`);
  if (r.error) {
    console.error(logs.slice(-20).join("\n"));
    code = 1;
  }
} finally {
  await browser.close();
  server.close();
}
process.exit(code);
