// Open a page of a site in headless Chromium and print what it leaves in window.segadeformResult as `PAGE {json}`
// (tests/runtimes/test_web.py, for runtimes/web/examples/embed.html on a vendored folder):
//   node test/embed.mjs --root SITE --page PATH?QUERY [--chromium /usr/bin/chromium]
import puppeteer from "puppeteer-core";
import { serve } from "../serve.mjs";

const args = process.argv.slice(2);
const opt = (name, dflt) => (args.includes(name) ? args[args.indexOf(name) + 1] : dflt);
const server = await serve(opt("--root"), 0);
const browser = await puppeteer.launch({ executablePath: opt("--chromium", "/usr/bin/chromium"), headless: true,
  args: ["--no-sandbox"] });
let code = 0;
try {
  const page = await browser.newPage();
  const logs = [];
  page.on("console", (m) => logs.push(`${m.type()}: ${m.text()}`));
  page.on("pageerror", (e) => logs.push(`pageerror: ${e.message}`));
  page.on("requestfailed", (r) => logs.push(`requestfailed: ${r.url()}`));
  const fetched = []; // the package's files the page fetched (a run needs two or three graphs, not every one)
  page.on("response", (r) => {
    if (r.status() >= 400) logs.push(`${r.status()}: ${r.url()}`);
    else if (/\.(onnx|bin)$/.test(new URL(r.url()).pathname)) fetched.push(new URL(r.url()).pathname.split("/").pop());
  });
  await page.goto(`http://127.0.0.1:${server.address().port}/${opt("--page")}`);
  await page.waitForFunction("window.segadeformResult !== undefined", { timeout: 540000, polling: 250 });
  const r = await page.evaluate(() => window.segadeformResult);
  console.log(`PAGE ${JSON.stringify({ ...r, fetched, logs })}`);
} catch (e) {
  console.error(`error: ${e.message}`);
  code = 1;
} finally {
  await browser.close();
  server.close();
}
process.exit(code);
