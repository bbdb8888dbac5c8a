#!/usr/bin/env node
// segadeform-node PACKAGE_DIR BUNDLE.sgdb -o OUT.pc2 [--batch N] [--threads N]
import { readBundle, animate, writePC2 } from "./index.js";

const args = process.argv.slice(2);
const opt = (name, dflt) => {
  const i = args.indexOf(name);
  return i >= 0 ? args.splice(i, 2)[1] : dflt;
};
const out = opt("-o");
const batch = parseInt(opt("--batch", "8"), 10);
const threads = parseInt(opt("--threads", "1"), 10);
if (args.length !== 2 || !out) {
  console.error("usage: segadeform-node PACKAGE_DIR BUNDLE.sgdb -o OUT.pc2 [--batch N] [--threads N]");
  process.exit(2);
}
try {
  const bundle = readBundle(args[1]);
  const r = await animate(args[0], bundle, { batch, threads });
  writePC2(out, r.frames, r.T, r.N);
  console.log(`${r.T} frames, ${r.msPerFrame.toFixed(2)} ms/frame -> ${out}`);
} catch (e) {
  console.error(`Error: ${e.message}`);
  process.exit(1);
}
