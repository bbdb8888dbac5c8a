// The JavaScript collider (src/collide.js) on a shared test vector made by Python's BodyCollider (the compiled
// kernel, src/segadeform/body/_collide.c): prints `COLLIDE {json}` with the largest differences.
//   node scripts/collide_vectors.mjs VEC.sgdb
// VEC.sgdb (tests/runtimes/test_collisions.py writes it): rest (V, 3) f64 and faces (F, 3) i32 of the body, posed
// (B, V, 3) f64, points (P, 3) f64 queried against posed[query_frame] with Python's sd (P), closest (P, 3),
// normal (P, 3) and face (P), and push_in (B, N, 3) pushed out of the B frames with meta.margin into push_out
// (B, N, 3), meta.moved points moved; near_sd (P), near_closest and near_normal (P, 3): the kernel's contact lookup
// (sdc_near) of the points against posed[query_frame] with radius meta.near_radius (sd = inf: not found);
// carry_in (T, N', 3) pushed out of carry_posed (T, V', 3) of the body carry_rest / carry_faces with the correction
// carried, in calls of meta.carry_batch frames, into carry_out (meta.carry_moved points moved).
import { readBundle } from "../src/bundle.js";
import { BodyCollider } from "../src/collide.js";

const { arrays: A, meta } = readBundle(process.argv[2]);
const maxDiff = (x, y) => {
  let m = 0;
  for (let i = 0; i < x.length; i++) m = Math.max(m, Math.abs(x[i] - y[i]));
  return m;
};
const [B, V] = A.posed.shape;
const col = new BodyCollider(A.rest.data, A.faces.data);
const f = meta.query_frame;
const q = col.query(A.posed.data.subarray(f * V * 3, (f + 1) * V * 3), A.points.data);
let faces = 0;
for (let i = 0; i < q.face.length; i++) if (q.face[i] !== A.face.data[i]) faces++;
const pts = new Float64Array(A.push_in.data);
const N = A.push_in.shape[1];
const t0 = performance.now();
const r = col.pushOut(A.posed.data, pts, B, N, meta.margin, meta.iterations);
const ms = performance.now() - t0;
let identical = 0;
for (let i = 0; i < pts.length; i++) if (pts[i] === A.push_out.data[i]) identical++;
// the cloth stage's contact lookup (sdc_near) of the same points, frame query_frame, radius meta.near_radius
let nearFound = 0, nearDiffer = 0;
if (A.near_sd) {
  const P = q.face.length, vf = A.posed.data.subarray(f * V * 3, (f + 1) * V * 3);
  const box = new Float64Array(6 * col.nNodes);
  col.refitInto(vf, box);
  const sd = new Float64Array(P), cl = new Float64Array(3 * P), nr = new Float64Array(3 * P);
  nearFound = col.near(vf, box, A.points.data, 0, P, meta.near_radius, sd, cl, nr);
  for (let i = 0; i < P; i++) {
    let same = sd[i] === A.near_sd.data[i] || (Number.isNaN(sd[i]) && Number.isNaN(A.near_sd.data[i]));
    if (same && Number.isFinite(sd[i])) {
      for (let k = 0; k < 3; k++) same = same && cl[3 * i + k] === A.near_closest.data[3 * i + k] && nr[3 * i + k] === A.near_normal.data[3 * i + k];
    }
    if (!same) nearDiffer++;
  }
}
// the push-out with the correction carried from frame to frame (sdc_push_out_carried), in calls of meta.carry_batch
// frames against carry_posed (T, V', 3) of the body carry_rest / carry_faces
let carryOut = 0, carryIdentical = 0, carryCoordinates = 0, carryMoved = 0;
if (A.carry_in) {
  const [T, N2] = A.carry_in.shape, V2 = A.carry_rest.shape[0];
  const c = new BodyCollider(A.carry_rest.data, A.carry_faces.data), carry = new Float64Array(3 * N2);
  const p = new Float64Array(A.carry_in.data);
  for (let lo = 0; lo < T; lo += meta.carry_batch) {
    const hi = Math.min(lo + meta.carry_batch, T), part = p.subarray(lo * N2 * 3, hi * N2 * 3);
    carryMoved += c.pushOut(A.carry_posed.data.subarray(lo * V2 * 3, hi * V2 * 3), part, hi - lo, N2, meta.carry_margin,
      meta.iterations, carry).moved;
  }
  carryOut = maxDiff(p, A.carry_out.data);
  carryCoordinates = p.length;
  for (let i = 0; i < p.length; i++) if (p[i] === A.carry_out.data[i]) carryIdentical++;
}
console.log(`COLLIDE ${JSON.stringify({
  closed: col.closed, nodes: col.nNodes, points: q.face.length, sd: maxDiff(q.signedDistance, A.sd.data),
  closest: maxDiff(q.closest, A.closest.data), normal: maxDiff(q.normal, A.normal.data), facesDiffer: faces,
  pushOut: maxDiff(pts, A.push_out.data), identical, coordinates: pts.length, moved: r.moved, pushMs: ms,
  nearFound, nearDiffer, carryOut, carryIdentical, carryCoordinates, carryMoved, carryMovedPy: meta.carry_moved,
})}`);
