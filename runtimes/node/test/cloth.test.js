// The cloth stage's JavaScript port (cloth.js) on its own: knobs, the per-garment setup and its invariants, the
// per-sweep stiffness, a stage that keeps its state between calls.  Parity with Python's ClothStage on shared vectors
// is tests/runtimes/test_cloth.py.
import { test } from "node:test";
import assert from "node:assert/strict";
import { BodyCollider } from "../src/collide.js";
import { checkCloth, clothSetup, ClothStage, DEFAULT_CLOTH, parseCloth, perSweep } from "../src/cloth.js";

test("knobs parse over the defaults and are checked", () => {
  assert.deepEqual(parseCloth("iterations=8, stiffness=0.5"), { ...DEFAULT_CLOTH, iterations: 8, stiffness: 0.5 });
  assert.deepEqual(parseCloth(""), { ...DEFAULT_CLOTH });
  assert.throws(() => parseCloth("iterations=0"), /cloth iterations must be an integer in \[1, 64\]/);
  assert.throws(() => parseCloth("iterations=2.5"), /an integer/);
  assert.throws(() => parseCloth("wind=1"), /unknown cloth setting/);
  assert.throws(() => parseCloth("stretch=x"), /cloth stretch must be a number/);
  // what was typed, not NaN (a user's trial)
  assert.throws(() => parseCloth("iterations=abc"), /must be an integer in \[1, 64\] \(got 'abc'\)/);
  assert.throws(() => parseCloth("stretch="), /\(got ''\)/);
  assert.throws(() => checkCloth({ ...DEFAULT_CLOTH, gravity: NaN }), /cloth gravity/);
});

test("the per-sweep stiffness gives the stiffness after the sweeps", () => {
  for (const [k, n] of [[0.9, 4], [0.5, 16], [0.3, 1], [1, 8], [0, 3]]) {
    const kp = perSweep(k, n);
    assert.ok(Math.abs(1 - (1 - kp) ** n - k) < 1e-12, `${k} ${n}: ${kp}`);
  }
});

test("setup: distinct sorted edges, ascending neighbours, radii from the rest distance, tethers", () => {
  // two triangles sharing an edge, a repeated-vertex face and a duplicate face
  const rest = new Float64Array([0, 0, 0, 1, 0, 0, 0, 1, 0, 1, 1, 0]);
  const faces = new Int32Array([0, 1, 2, 1, 3, 2, 2, 1, 0, 3, 3, 1]);
  const s = clothSetup(rest, faces, new Float64Array([0.0, 0.03, 0.5, -1]), 0.02, 0.05);
  assert.deepEqual(Array.from(s.edges), [0, 1, 0, 2, 1, 2, 1, 3, 2, 3]);
  assert.deepEqual(Array.from(s.restLen), [1, 1, Math.SQRT2, 1, 1]);
  assert.deepEqual(Array.from(s.nptr), [0, 2, 5, 8, 10]);
  assert.deepEqual(Array.from(s.nidx), [1, 2, 0, 2, 3, 0, 1, 3, 1, 2]);
  assert.ok(Math.abs(s.radius[1] - 0.01) < 1e-15);
  assert.deepEqual([s.radius[0], s.radius[2], s.radius[3]], [0, 0.05, 0]);
  // tethers: each free vertex to the nearest attached one along the edges (a tie: the smaller index)
  assert.deepEqual(Array.from(s.anchor), [-1, 0, 0, -1]);
  assert.deepEqual(Array.from(s.tether), [0, 1, 1, 0]);
  assert.throws(() => clothSetup(rest, new Int32Array([0, 1, 7]), new Float64Array(4), 0.02, 0.05), /out of range/);
});

test("a stage far from the body: the first frame is its target, batches give the frames of one call", () => {
  // a small body (a tetrahedron) far away; a strip of cloth whose target moves
  const body = new Float64Array([10, 0, 0, 11, 0, 0, 10, 1, 0, 10, 0, 1]);
  const bf = new Int32Array([0, 2, 1, 0, 1, 3, 0, 3, 2, 1, 2, 3]);
  const rest = new Float64Array([0, 0, 0, 0.1, 0, 0, 0, 0.1, 0, 0.1, 0.1, 0]);
  const faces = new Int32Array([0, 1, 2, 1, 3, 2]);
  const setup = clothSetup(rest, faces, new Float64Array([0.01, 0.1, 0.1, 0.1]), 0.02, 0.05);
  const T = 6, n = 4;
  const targets = new Float64Array(T * n * 3), bodies = new Float64Array(T * 12);
  for (let t = 0; t < T; t++) {
    for (let i = 0; i < 3 * n; i++) targets[t * 3 * n + i] = rest[i] + (i % 3 === 0 ? 0.02 * t : 0);
    bodies.set(body, t * 12);
  }
  const one = new ClothStage(setup, new BodyCollider(body, bf), DEFAULT_CLOTH).step(targets, bodies, T);
  assert.deepEqual(Array.from(one.subarray(0, 3 * n)), Array.from(targets.subarray(0, 3 * n)));
  const st = new ClothStage(setup, new BodyCollider(body, bf), DEFAULT_CLOTH);
  const parts = [st.step(targets.slice(0, 2 * 3 * n), bodies.slice(0, 24), 2), st.step(targets.slice(2 * 3 * n), bodies.slice(24), 4)];
  assert.deepEqual(Array.from(parts[0]).concat(Array.from(parts[1])), Array.from(one));
  assert.equal(st.frames, T);
  // vertex 0 lies on the body at rest (radius 0): it follows its target exactly
  for (let t = 0; t < T; t++) for (let k = 0; k < 3; k++) assert.equal(one[t * 3 * n + k], targets[t * 3 * n + k]);
  // a NaN from upstream is refused
  const bad = targets.slice(0, 3 * n);
  bad[4] = NaN;
  assert.throws(() => st.step(bad, bodies.slice(0, 12), 1), /NaN or inf/);
  // and takes nothing, even when the bad frame is not the call's first: the stage goes on as if it had not been made
  const st2 = new ClothStage(setup, new BodyCollider(body, bf), DEFAULT_CLOTH);
  const first = st2.step(targets.slice(0, 2 * 3 * n), bodies.slice(0, 24), 2);
  const late = targets.slice(2 * 3 * n, 4 * 3 * n);
  late[3 * n + 4] = Infinity;
  assert.throws(() => st2.step(late, bodies.slice(24, 48), 2), /NaN or inf at frame 3/);
  assert.equal(st2.frames, 2);
  const after = st2.step(targets.slice(2 * 3 * n), bodies.slice(24), 4);
  assert.deepEqual(Array.from(first).concat(Array.from(after)), Array.from(one));
});
