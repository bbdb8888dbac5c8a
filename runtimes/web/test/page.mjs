// Open the viewer page in headless Chromium, run a garment asset and a motion (or a bundle) through a package,
// print the result as `PAGE {json}` and save a screenshot.   Used by tests/runtimes/test_web.py and bench/runtimes.py:
//   node test/page.mjs --root REPO --package PATH_IN_ROOT (--garment G.sgda --motion M.sgdm [--check VEC.sgdb] |
//        --bundle PATH_IN_ROOT) --ep wasm|webgpu [--drop] [--effects dqs,dynamics,wrinkles,collisions]
//        [--margin M] [--cloth 1|K=V,..] [--screenshot OUT.png]
//        [--frame N] [--body B.pc2 --body-mesh B.obj] [--chromium /usr/bin/chromium]
// --drop: open the page bare and drop the package's files, the asset and the motion on it (a synthetic drop event
// carrying the files, as a user's drag and drop does), instead of naming them in the query.
import puppeteer from "puppeteer-core";
import { serve } from "../serve.mjs";

const args = process.argv.slice(2);
const opt = (name, dflt) => (args.includes(name) ? args[args.indexOf(name) + 1] : dflt);
const root = opt("--root"), ep = opt("--ep", "wasm"), shot = opt("--screenshot"), dropMode = args.includes("--drop");
const server = await serve(root, 0);
const port = server.address().port;
const query = { ep, batch: opt("--batch", "4"), frame: opt("--frame", "0"), paused: "1" };
if (!dropMode) query.package = `/${opt("--package")}/`;
if (opt("--effects")) query.effects = opt("--effects");
if (opt("--margin")) query.margin = opt("--margin");
if (opt("--cloth")) query.cloth = opt("--cloth"); // the cloth stage on (1: its default knobs)
if (args.includes("--check")) query.check = `/${opt("--check")}`;
if (!dropMode && args.includes("--garment")) {
  Object.assign(query, { garment: `/${opt("--garment")}`, motion: `/${opt("--motion")}` });
} else if (!dropMode) query.bundle = `/${opt("--bundle")}`;
if (args.includes("--body")) Object.assign(query, { body: `/${opt("--body")}`, bodyMesh: `/${opt("--body-mesh")}` });
const page_url = `http://127.0.0.1:${port}/runtimes/web/index.html?` + new URLSearchParams(query);
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
  if (dropMode) {
    // the package's files first (a drop of its own), then the asset and the motion together
    const pkgDir = `/${opt("--package")}/`;
    const manifest = await page.evaluate(async (u) => (await fetch(u)).json(), `${pkgDir}manifest.json`);
    const pkgFiles = ["manifest.json", ...Object.values(manifest.graphs).map((g) => g.file),
      ...(manifest.weights ? [manifest.weights.file] : [])].map((f) => pkgDir + f);
    for (const urls of [pkgFiles, [`/${opt("--garment")}`, `/${opt("--motion")}`]]) {
      await page.evaluate(async (list) => {
        window.segadeformResult = undefined;
        const dt = new DataTransfer();
        for (const u of list) {
          const r = await fetch(u);
          dt.items.add(new File([await r.arrayBuffer()], u.split("/").pop()));
        }
        window.dispatchEvent(new DragEvent("drop", { dataTransfer: dt, bubbles: true, cancelable: true }));
      }, urls);
      await page.waitForFunction("window.segadeformResult !== undefined", { timeout: 540000, polling: 250 });
    }
  } else {
    await page.waitForFunction("window.segadeformResult !== undefined", { timeout: 540000, polling: 250 });
  }
  const r = await page.evaluate("window.segadeformResult");
  r.webgpu = await page.evaluate("!!navigator.gpu && navigator.gpu.requestAdapter().then((a) => !!a)");
  r.browser = await browser.version();
  r.status = await page.evaluate("document.getElementById('status').textContent");
  if (shot) {
    await new Promise((ok) => setTimeout(ok, 500)); // a few animation frames to draw the mesh
    await page.screenshot({ path: shot });
  }
  console.log(`PAGE ${JSON.stringify(r)}`);
  if (!r || r.error) {
    console.error(logs.slice(-20).join("\n"));
    code = 1;
  }
} finally {
  await browser.close();
  server.close();
}
process.exit(code);
