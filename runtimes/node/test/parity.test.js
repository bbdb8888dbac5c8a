// Parity with the Python runtime on a shared test vector (a bundle with `expected`).
// SEGADEFORM_PACKAGE and SEGADEFORM_BUNDLE name them (tests/runtimes/test_node.py sets both).
import { test } from "node:test";
import assert from "node:assert/strict";
import { readBundle, animate, parseBundle } from "../src/index.js";

const pkg = process.env.SEGADEFORM_PACKAGE;
const bundlePath = process.env.SEGADEFORM_BUNDLE;

test("bundle header errors are clear", () => {
  assert.throws(() => parseBundle(new TextEncoder().encode("hello")), /not a segadeform bundle/);
});

test("frames match the Python runtime", { skip: !pkg || !bundlePath ? "set SEGADEFORM_PACKAGE and SEGADEFORM_BUNDLE" : false }, async () => {
  const b = readBundle(bundlePath);
  const r = await animate(pkg, b, { batch: 4 });
  const exp = b.arrays.expected.data;
  assert.equal(r.frames.length, exp.length);
  let maxAbs = 0, maxRef = 0;
  for (let i = 0; i < exp.length; i++) {
    maxAbs = Math.max(maxAbs, Math.abs(r.frames[i] - exp[i]));
    maxRef = Math.max(maxRef, Math.abs(exp[i]));
  }
  const rel = maxAbs / maxRef;
  console.log(`PARITY ${JSON.stringify({ maxAbs, rel, msPerFrame: r.msPerFrame })}`);
  assert.ok(rel <= 1e-5, `relative error ${rel}`);
});
