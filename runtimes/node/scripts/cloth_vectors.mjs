// The JavaScript cloth stage (src/cloth.js) on a shared test vector made by Python's ClothStage (the compiled kernel,
// src/segadeform/body/_cloth.c): prints `CLOTH {json}` with the largest differences and the counts.
//   node scripts/cloth_vectors.mjs VEC.sgdb
// VEC.sgdb (tests/runtimes/test_cloth.py writes it): the garment's rest (N, 3) f64 and faces (F, 3) i32, the body at
// rest (V, 3) f64 and its faces (F', 3) i32, targets (T, N, 3) and posed bodies (T, V, 3) f64, Python's setup
// (edges (E, 2) i32, rest_len, nptr, nidx, radius, anchor, tether, weld) and frames `expected` (T, N, 3) f64; meta: settings, margin, dt,
// batch, and Python's contacts, pushed, resets.
import { readBundle } from "../src/bundle.js";
import { clothSetup, ClothStage } from "../src/cloth.js";
import { BodyCollider } from "../src/collide.js";

const { arrays: A, meta } = readBundle(process.argv[2]);
const maxDiff = (x, y) => {
  let m = x.length === y.length ? 0 : Infinity;
  for (let i = 0; i < x.length; i++) m = Math.max(m, Math.abs(x[i] - y[i]));
  return m;
};
const [T, N] = A.targets.shape, V = A.rest_body.shape[0];
const col = new BodyCollider(A.rest_body.data, A.body_faces.data);
const restSd = col.query(A.rest_body.data, A.rest.data).signedDistance;
const s = meta.settings;
const setup = clothSetup(A.rest.data, A.faces.data, restSd, s.attachment, s.max_distance);
const stage = new ClothStage(setup, col, s, { margin: meta.margin, dt: meta.dt });
const out = new Float64Array(T * N * 3);
const t0 = performance.now();
for (let lo = 0; lo < T; lo += meta.batch) {
  const hi = Math.min(lo + meta.batch, T);
  out.set(stage.step(A.targets.data.subarray(lo * N * 3, hi * N * 3), A.posed.data.subarray(lo * V * 3, hi * V * 3),
    hi - lo), lo * N * 3);
}
const ms = (performance.now() - t0) / T;
let identical = 0;
for (let i = 0; i < out.length; i++) if (out[i] === A.expected.data[i]) identical++;
console.log(`CLOTH ${JSON.stringify({
  edges: maxDiff(setup.edges, A.edges.data), restLen: maxDiff(setup.restLen, A.rest_len.data),
  nptr: maxDiff(setup.nptr, A.nptr.data), nidx: maxDiff(setup.nidx, A.nidx.data), radius: maxDiff(setup.radius, A.radius.data),
  anchor: maxDiff(setup.anchor, A.anchor.data), tether: maxDiff(setup.tether, A.tether.data),
  weld: maxDiff(setup.weld, A.weld.data),
  frames: maxDiff(out, A.expected.data), identical, coordinates: out.length, contacts: stage.contacts,
  pushed: stage.pushed, resets: stage.resets, traced: stage.traced, msPerFrame: ms,
})}`);
