// Parity with the Python runtime on shared test vectors: a scene bundle with `expected`, and a garment asset with
// a motion file and `segadeform run`'s frames (garment `expected` and posed `body`, in a check container).
// SEGADEFORM_PACKAGE and SEGADEFORM_BUNDLE name the first; SEGADEFORM_GARMENT, SEGADEFORM_MOTION, SEGADEFORM_CHECK
// and SEGADEFORM_EFFECTS the second (tests/runtimes/test_engines.py sets them).
import { test } from "node:test";
import assert from "node:assert/strict";
import { readBundle, animate, parseBundle, compareFrames, parseEffects } from "../src/index.js";

const env = process.env;
const pkg = env.SEGADEFORM_PACKAGE;
const bundlePath = env.SEGADEFORM_BUNDLE;

test("bundle header errors are clear", () => {
  assert.throws(() => parseBundle(new TextEncoder().encode("hello")), /not a segadeform bundle/);
});

test("effects lists read as `segadeform run --effects` reads them", () => {
  const off = { collisions: false, cloth: false };
  assert.deepEqual(parseEffects("dqs,dynamics"), { ...off, skinning: "dqs", wrinkles: false, dynamics: true });
  assert.deepEqual(parseEffects("wrinkles"), { ...off, skinning: "lbs", wrinkles: true, dynamics: false });
  assert.deepEqual(parseEffects("lbs,collisions"), { ...off, skinning: "lbs", wrinkles: false, dynamics: false, collisions: true });
  assert.deepEqual(parseEffects("lbs,cloth"), { ...off, skinning: "lbs", wrinkles: false, dynamics: false, cloth: true });
  assert.throws(() => parseEffects("lbs,dqs"), /one skinning/);
  assert.throws(() => parseEffects("lbs,wind"), /unknown effect 'wind'/);
  // signed changes to the run's defaults, and none, as `segadeform run --effects` reads them
  const base = { skinning: "dqs", wrinkles: true, dynamics: true, collisions: true, cloth: false };
  assert.deepEqual(parseEffects("+cloth", base), { ...base, cloth: true });
  assert.deepEqual(parseEffects("lbs,-wrinkles", base), { ...base, skinning: "lbs", wrinkles: false });
  assert.deepEqual(parseEffects("none", base), { ...off, skinning: "lbs", wrinkles: false, dynamics: false });
  assert.throws(() => parseEffects("+cloth,dynamics", base), /mix a complete list with changes/);
  assert.throws(() => parseEffects("+cloth"), /need the run's default effects/);
  assert.throws(() => parseEffects("+wind", base), /unknown effect '\+wind'/);
  // one effect named twice: which is meant? (Python, Node and C++ refuse it alike)
  assert.throws(() => parseEffects("+wrinkles,-wrinkles", base), /effects name wrinkles twice/);
  assert.throws(() => parseEffects("cloth,cloth"), /effects name cloth twice/);
});

test("bundle frames match the Python runtime", { skip: !pkg || !bundlePath ? "set SEGADEFORM_PACKAGE and SEGADEFORM_BUNDLE" : false }, async () => {
  const b = readBundle(bundlePath);
  const r = await animate(pkg, b, { batch: 4 });
  const c = compareFrames(r.frames, b.arrays.expected.data);
  console.log(`PARITY ${JSON.stringify({ maxAbs: c.maxAbs, rel: c.rel, msPerFrame: r.msPerFrame })}`);
  assert.ok(c.sameLength && c.finite && c.rel <= 1e-5, `relative error ${c.rel}`);
});

test("asset + motion frames and the posed body match `segadeform run`", { skip: !pkg || !env.SEGADEFORM_GARMENT ? "set SEGADEFORM_GARMENT, SEGADEFORM_MOTION, SEGADEFORM_CHECK" : false }, async () => {
  const check = readBundle(env.SEGADEFORM_CHECK).arrays;
  const r = await animate(pkg, env.SEGADEFORM_GARMENT, env.SEGADEFORM_MOTION,
    { batch: 3, effects: env.SEGADEFORM_EFFECTS, body: true });
  const g = compareFrames(r.frames, check.expected.data);
  const b = compareFrames(r.body.vertices, check.body.data);
  console.log(`PARITY_ASSET ${JSON.stringify({ garment: g, body: b })}`);
  assert.ok(g.sameLength && g.finite && g.rel <= 1e-5, `garment relative error ${g.rel}`);
  assert.ok(b.sameLength && b.finite && b.rel <= 1e-5, `body relative error ${b.rel}`);
  assert.equal(r.body.faces.length % 3, 0);
  assert.equal(r.body.restJoints.length, 72);
});
