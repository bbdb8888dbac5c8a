// Parity with the Python runtime on shared test vectors: a scene bundle with `expected`, and a garment asset with
// a motion file and `segadeform run`'s frames (garment `expected` and posed `body`, in a check container).
// SEGADEFORM_PACKAGE and SEGADEFORM_BUNDLE name the first; SEGADEFORM_GARMENT, SEGADEFORM_MOTION, SEGADEFORM_CHECK
// and SEGADEFORM_EFFECTS the second (tests/runtimes/test_engines.py sets them).
import { test } from "node:test";
import assert from "node:assert/strict";
import {
  readBundle, animate, open, parseBundle, compareFrames, effectsLabel, parseEffects, readMotion,
} from "../src/index.js";

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
  assert.throws(() => parseEffects("dqs,dqs"), /effects name dqs twice/); // a skinning too (Python refused it first)
});

test("effects are named by `segadeform run`'s rule: the cloth stage in collisions' place", () => {
  // Effects.label (src/segadeform/settings/effects.py): with the cloth stage, collisions (its contact) is not named
  // apart -- the command line printed "lbs, dynamics, wrinkles, collisions, cloth" for --effects=+cloth
  const all = { skinning: "lbs", dynamics: true, wrinkles: true, collisions: true, cloth: false };
  assert.equal(effectsLabel(all), "lbs, dynamics, wrinkles, collisions");
  assert.equal(effectsLabel({ ...all, cloth: true }), "lbs, dynamics, wrinkles, cloth");
  assert.equal(effectsLabel({ ...all, collisions: false, cloth: true }), "lbs, dynamics, wrinkles, cloth");
  assert.equal(effectsLabel(parseEffects("dqs,collisions,cloth"), "+"), "dqs+cloth");
  assert.equal(effectsLabel(parseEffects("dqs,-dynamics", all)), "dqs, wrinkles, collisions");
  assert.equal(effectsLabel(parseEffects("none")), "lbs");
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

const assetSkip = !pkg || !env.SEGADEFORM_GARMENT ? "set SEGADEFORM_GARMENT, SEGADEFORM_MOTION, SEGADEFORM_CHECK" : false;

test("a Player fed the motion in chunks gives animate's frames, and the stages' counts", { skip: assetSkip }, async () => {
  const m = readMotion(env.SEGADEFORM_MOTION);
  const P = m.arrays.poses.data, Tr = m.arrays.trans.data, T = m.arrays.poses.shape[0], D = m.arrays.poses.shape[1] * 3;
  for (const effects of [env.SEGADEFORM_EFFECTS, `${env.SEGADEFORM_EFFECTS},collisions`, `${env.SEGADEFORM_EFFECTS},cloth`]) {
    const whole = await animate(pkg, env.SEGADEFORM_GARMENT, env.SEGADEFORM_MOTION, { batch: 4, effects });
    for (const chunk of [4, 8, 3, 1]) {
      const p = await open(pkg, env.SEGADEFORM_GARMENT, { batch: 4, effects, fps: m.meta.fps });
      const got = new Float32Array(T * p.N * 3);
      for (let lo = 0; lo < T; lo += chunk) {
        const hi = Math.min(lo + chunk, T);
        const r = await p.push(P.subarray(lo * D, hi * D), Tr.subarray(lo * 3, hi * 3));
        assert.equal(r.frames.length, (hi - lo) * p.N * 3);
        got.set(r.frames, lo * p.N * 3);
      }
      const c = compareFrames(got, whole.frames);
      // the same batches (chunks of a multiple of batch): bit for bit; others: onnxruntime's rounding of another
      // batch size (~1e-6 m), which a push-out in a crease of the body can turn into another face (millimetres)
      if (chunk % 4 === 0) assert.equal(c.maxAbs, 0, `${effects} in chunks of ${chunk}: ${c.maxAbs} m`);
      else if (effects === env.SEGADEFORM_EFFECTS) assert.ok(c.finite && c.maxAbs < 2e-5, `${effects} in chunks of ${chunk}: ${c.maxAbs} m`);
      else assert.ok(c.finite && c.maxAbs < 0.02, `${effects} in chunks of ${chunk}: ${c.maxAbs} m`);
      if (whole.collisions) assert.equal(p.counts.moved, whole.collisions.moved);
      if (whole.cloth && chunk % 4 === 0) assert.equal(p.counts.contacts, whole.cloth.contacts);
      // a new clip after reset(): its counts from 0 (they added up: a web developer's trial), the first chunk's frames
      p.reset();
      assert.equal(p.counts.moved ?? p.counts.contacts, 0);
      const again = await p.push(P.subarray(0, 4 * D), Tr.subarray(0, 12));
      assert.equal(compareFrames(again.frames, whole.frames.subarray(0, again.frames.length)).maxAbs, 0);
      await p.close();
    }
  }
});

test("a push that fails part-way leaves the Player refusing pushes until reset(), as the C++ Player", { skip: assetSkip }, async () => {
  // the collision stage's carried corrections (and the cloth stage) advance batch by batch: a push that throws after
  // its first batch leaves them ahead of the motion history, so the next push would give other frames
  const m = readMotion(env.SEGADEFORM_MOTION);
  const P = m.arrays.poses.data, Tr = m.arrays.trans.data, D = m.arrays.poses.shape[1] * 3;
  const effects = `${env.SEGADEFORM_EFFECTS},collisions`;
  const whole = await animate(pkg, env.SEGADEFORM_GARMENT, env.SEGADEFORM_MOTION, { batch: 4, effects });
  const p = await open(pkg, env.SEGADEFORM_GARMENT, { batch: 4, effects, fps: m.meta.fps });
  const pose = p.poser.pose.bind(p.poser);
  let calls = 0;
  p.poser.pose = async (...a) => { if (++calls === 2) throw new Error("the body graph failed"); return pose(...a); };
  await assert.rejects(p.push(P.subarray(0, 8 * D), Tr.subarray(0, 24)), /the body graph failed/);
  p.poser.pose = pose;
  await assert.rejects(p.push(P.subarray(0, 4 * D), Tr.subarray(0, 12)), /expected reset\(\) first/);
  p.reset();
  const again = await p.push(P.subarray(0, 4 * D), Tr.subarray(0, 12));
  assert.equal(compareFrames(again.frames, whole.frames.subarray(0, again.frames.length)).maxAbs, 0);
  await p.close();
});

test("a Player with batch 1 fed one frame at a time gives animate's frames with batch 1, stages included", { skip: assetSkip }, async () => {
  const m = readMotion(env.SEGADEFORM_MOTION);
  const P = m.arrays.poses.data, Tr = m.arrays.trans.data, T = m.arrays.poses.shape[0], D = m.arrays.poses.shape[1] * 3;
  for (const effects of [`${env.SEGADEFORM_EFFECTS},collisions`, `${env.SEGADEFORM_EFFECTS},cloth`]) {
    const whole = await animate(pkg, env.SEGADEFORM_GARMENT, env.SEGADEFORM_MOTION, { batch: 1, effects });
    const p = await open(pkg, env.SEGADEFORM_GARMENT, { batch: 1, effects, fps: m.meta.fps });
    const got = new Float32Array(T * p.N * 3);
    for (let t = 0; t < T; t++) got.set((await p.push(P.subarray(t * D, t * D + D), Tr.subarray(t * 3, t * 3 + 3))).frames, t * p.N * 3);
    await p.close();
    assert.equal(compareFrames(got, whole.frames).maxAbs, 0, effects);
  }
});

test("the API's options are checked: a typo or a wrong type is an error naming it", { skip: assetSkip }, async () => {
  const run = (o) => animate(pkg, env.SEGADEFORM_GARMENT, env.SEGADEFORM_MOTION, o);
  await assert.rejects(run({ efects: "lbs" }), /unknown option 'efects'/);
  await assert.rejects(run({ batch: 0 }), /option batch must be an integer >= 1 \(got 0\)/);
  await assert.rejects(run({ batch: 2.5 }), /option batch must be an integer/);
  await assert.rejects(run({ threads: "2" }), /option threads must be an integer/);
  await assert.rejects(run({ collisionMargin: "0.01" }), /collisionMargin must be a number of metres \(got string/);
  await assert.rejects(run({ effects: ["lbs"] }), /option effects must be a string/);
  await assert.rejects(run({ effects: { skinning: "lbs", wrinkle: true } }), /unknown effect 'wrinkle'/);
  await assert.rejects(run({ effects: "lbs", cloth: "iterations=2" }), /cloth stage's knobs, but the stage is off/);
  await assert.rejects(animate(pkg, new Uint8Array(8), env.SEGADEFORM_MOTION), /got bytes \(parse them with parseBundle/);
  await assert.rejects(open(pkg, env.SEGADEFORM_GARMENT, { effects: "+cloth" }), /needs the motion's frame rate/);
  // an effects object names what is on; what it leaves out is off (lbs unless dqs is named)
  const r = await run({ effects: { dynamics: true } });
  assert.deepEqual(r.effects, { skinning: "lbs", dynamics: true, wrinkles: false, collisions: false, cloth: false });
  const p = await open(pkg, env.SEGADEFORM_GARMENT, { effects: "lbs" });
  await assert.rejects(p.push(new Float32Array(71), new Float32Array(3)), /poses and trans do not fit/);
  await assert.rejects(p.push(new Float32Array(72).fill(NaN), new Float32Array(3)), /poses contain NaN/);
  await p.close();
});
