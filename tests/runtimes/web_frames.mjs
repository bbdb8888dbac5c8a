// The browser runtime's frames, every one of them (the viewer page reports only the largest error): in headless
// Chromium, on a bare page of the same server, runtimes/web/src/runtime.js's animate() -- what the page runs --
// animates a garment asset and a motion file with a package on onnxruntime-web (wasm, one thread), and the frames
// (after collisions or the cloth stage when the effects have them) are written as float32 little-endian to OUT.
//   node tests/runtimes/web_frames.mjs --root SITE --package PATH_IN_ROOT --garment G.sgda --motion M.sgdm
//        --effects lbs,dynamics,wrinkles,collisions [--margin M] [--batch B] -o OUT.f32 [--body-out BODY.f32]
//        [--chromium PATH]
// SITE holds runtimes/ (a link to the repository's) and the files named; --body-out: the body posed by the package's
// body graph (T, V, 3), as the page poses it.  Prints `FRAMES {json}` (T, N, V, moved, cloth (the stage's counts),
// msPerFrame, ort, browser).
import { writeFileSync } from "node:fs";
import { createRequire } from "node:module";
import { dirname, join, resolve } from "node:path";
import { fileURLToPath, pathToFileURL } from "node:url";

const WEB = resolve(dirname(fileURLToPath(import.meta.url)), "..", "..", "runtimes", "web");
const puppeteer = createRequire(join(WEB, "package.json"))("puppeteer-core");
const { serve } = await import(pathToFileURL(join(WEB, "serve.mjs")).href);

const args = process.argv.slice(2);
const opt = (name, dflt) => (args.includes(name) ? args[args.indexOf(name) + 1] : dflt);
const root = opt("--root"), out = opt("-o"), bodyOut = opt("--body-out");
if (!root || !out || !opt("--package") || !opt("--garment") || !opt("--motion")) {
  console.error("usage: web_frames.mjs --root SITE --package P --garment G.sgda --motion M.sgdm -o OUT.f32");
  process.exit(2);
}
writeFileSync(join(root, "frames.html"), "<!doctype html><meta charset=utf-8><title>frames</title>");
const server = await serve(root, 0);
const browser = await puppeteer.launch({
  executablePath: opt("--chromium", "/usr/bin/chromium"), headless: true, protocolTimeout: 900000,
  args: ["--no-sandbox"],
});
let code = 0;
try {
  const page = await browser.newPage();
  const logs = [];
  page.on("console", (m) => logs.push(`${m.type()}: ${m.text()}`));
  page.on("pageerror", (e) => logs.push(`pageerror: ${e.message}`));
  await page.goto(`http://127.0.0.1:${server.address().port}/frames.html`);
  const r = await page.evaluate(async (o) => {
    try {
      const rt = await import("/runtimes/web/src/runtime.js");
      const core = await import("/runtimes/node/src/core.js");
      const ort = await rt.loadOrt("wasm", new URL("/runtimes/web/node_modules/onnxruntime-web/dist/", location.href).href);
      const pkg = await rt.loadPackage(`/${o.package}/`);
      const [a, m] = await Promise.all([rt.openContainer(`/${o.garment}`), rt.openContainer(`/${o.motion}`)]);
      const res = await rt.animate(ort, pkg, { asset: a.parsed, motion: m.parsed }, {
        ep: "wasm", batch: o.batch, body: o.body, effects: core.parseEffects(o.effects),
        ...(o.margin !== null ? { collisionMargin: o.margin } : {}),
      });
      const b64 = (a) => {
        const bytes = new Uint8Array(a.buffer, a.byteOffset, a.byteLength);
        let bin = "";
        for (let i = 0; i < bytes.length; i += 0x8000) bin += String.fromCharCode(...bytes.subarray(i, i + 0x8000));
        return btoa(bin);
      };
      if (o.body && (!res.body || res.body.error)) throw new Error(`no posed body: ${res.body && res.body.error}`);
      return { T: res.T, N: res.N, V: o.body ? res.body.V : null, msPerFrame: res.msPerFrame,
        moved: res.collisions ? res.collisions.moved : null, cloth: res.cloth || null, ort: ort.env.versions?.web,
        frames: b64(res.frames),
        body: o.body ? b64(res.body.vertices) : null };
    } catch (e) {
      return { error: String(e && e.stack || e) };
    }
  }, { package: opt("--package"), garment: opt("--garment"), motion: opt("--motion"), effects: opt("--effects", "lbs"),
    margin: opt("--margin") === undefined ? null : Number(opt("--margin")), batch: Number(opt("--batch", "8")),
    body: !!bodyOut });
  if (r.error) {
    console.error(r.error + "\n" + logs.slice(-20).join("\n"));
    code = 1;
  } else {
    writeFileSync(out, Buffer.from(r.frames, "base64"));
    if (bodyOut) writeFileSync(bodyOut, Buffer.from(r.body, "base64"));
    delete r.frames;
    delete r.body;
    r.browser = await browser.version();
    console.log(`FRAMES ${JSON.stringify(r)}`);
  }
} finally {
  await browser.close();
  server.close();
}
process.exit(code);
