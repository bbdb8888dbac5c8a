// The JavaScript collider (src/collide.js, the port of src/segadeform/body/_collide.c) on small closed meshes,
// against brute force: every triangle's exact closest point, the sign from a point's side of the mesh.  The
// comparison with the C kernel itself on the posed body is tests/runtimes/test_collisions.py.
import { test } from "node:test";
import assert from "node:assert/strict";
import { BodyCollider, pushOutFrames } from "../src/collide.js";

/** A unit icosphere subdivided `levels` times (outward triangles), scaled and moved. */
function icosphere(levels, r = 1, c = [0, 0, 0]) {
  const t = (1 + Math.sqrt(5)) / 2;
  let v = [[-1, t, 0], [1, t, 0], [-1, -t, 0], [1, -t, 0], [0, -1, t], [0, 1, t], [0, -1, -t], [0, 1, -t],
    [t, 0, -1], [t, 0, 1], [-t, 0, -1], [-t, 0, 1]].map((p) => { const n = Math.hypot(...p); return p.map((x) => x / n); });
  let f = [[0, 11, 5], [0, 5, 1], [0, 1, 7], [0, 7, 10], [0, 10, 11], [1, 5, 9], [5, 11, 4], [11, 10, 2], [10, 7, 6],
    [7, 1, 8], [3, 9, 4], [3, 4, 2], [3, 2, 6], [3, 6, 8], [3, 8, 9], [4, 9, 5], [2, 4, 11], [6, 2, 10], [8, 6, 7], [9, 8, 1]];
  for (let l = 0; l < levels; l++) {
    const mid = new Map(), nf = [];
    const m = (a, b) => {
      const k = a < b ? `${a},${b}` : `${b},${a}`;
      if (!mid.has(k)) {
        const p = v[a].map((x, i) => (x + v[b][i]) / 2), n = Math.hypot(...p);
        v.push(p.map((x) => x / n));
        mid.set(k, v.length - 1);
      }
      return mid.get(k);
    };
    for (const [a, b, cc] of f) {
      const ab = m(a, b), bc = m(b, cc), ca = m(cc, a);
      nf.push([a, ab, ca], [b, bc, ab], [cc, ca, bc], [ab, bc, ca]);
    }
    f = nf;
  }
  v = v.map((p) => p.map((x, i) => r * x + c[i]));
  return { verts: Float64Array.from(v.flat()), faces: Int32Array.from(f.flat()) };
}

/** Brute force: the nearest point over every triangle (Ericson's closest point, by projection and edges). */
function bruteDistance(verts, faces, p) {
  let best = Infinity;
  const sub = (a, b) => [a[0] - b[0], a[1] - b[1], a[2] - b[2]];
  const dot = (a, b) => a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
  const at = (i) => [verts[3 * i], verts[3 * i + 1], verts[3 * i + 2]];
  const seg = (a, b) => {
    const ab = sub(b, a), t = Math.min(1, Math.max(0, dot(sub(p, a), ab) / dot(ab, ab)));
    const q = [a[0] + t * ab[0], a[1] + t * ab[1], a[2] + t * ab[2]];
    return Math.hypot(...sub(p, q));
  };
  for (let f = 0; f < faces.length / 3; f++) {
    const a = at(faces[3 * f]), b = at(faces[3 * f + 1]), c = at(faces[3 * f + 2]);
    const ab = sub(b, a), ac = sub(c, a), ap = sub(p, a);
    const d00 = dot(ab, ab), d01 = dot(ab, ac), d11 = dot(ac, ac), d20 = dot(ap, ab), d21 = dot(ap, ac);
    const den = d00 * d11 - d01 * d01, v = (d11 * d20 - d01 * d21) / den, w = (d00 * d21 - d01 * d20) / den;
    let d;
    if (v >= 0 && w >= 0 && v + w <= 1) {
      const q = [a[0] + v * ab[0] + w * ac[0], a[1] + v * ab[1] + w * ac[1], a[2] + v * ab[2] + w * ac[2]];
      d = Math.hypot(...sub(p, q));
    } else d = Math.min(seg(a, b), seg(b, c), seg(c, a));
    best = Math.min(best, d);
  }
  return best;
}

function rng(seed) {
  let s = seed >>> 0;
  return () => ((s = (s * 1664525 + 1013904223) >>> 0) / 2 ** 32);
}

test("closest points and signs on a closed mesh are brute force's", () => {
  const { verts, faces } = icosphere(2, 0.3, [0.1, 1.0, -0.2]);
  const col = new BodyCollider(verts, faces);
  assert.equal(col.closed, true);
  const r = rng(7), pts = [];
  for (let i = 0; i < 300; i++) {
    const s = 0.3 * (0.2 + 1.3 * r()); // inside and outside
    const d = [r() - 0.5, r() - 0.5, r() - 0.5], n = Math.hypot(...d);
    pts.push(0.1 + (s * d[0]) / n, 1.0 + (s * d[1]) / n, -0.2 + (s * d[2]) / n);
  }
  const q = col.query(verts, Float64Array.from(pts));
  for (let i = 0; i < 300; i++) {
    const p = pts.slice(3 * i, 3 * i + 3);
    const want = bruteDistance(verts, faces, p);
    assert.ok(Math.abs(Math.abs(q.signedDistance[i]) - want) <= 1e-12, `point ${i}: ${q.signedDistance[i]} vs ${want}`);
    const inside = Math.hypot(p[0] - 0.1, p[1] - 1.0, p[2] + 0.2) < 0.29; // well inside the polyhedron
    const outside = Math.hypot(p[0] - 0.1, p[1] - 1.0, p[2] + 0.2) > 0.301;
    if (inside) assert.ok(q.signedDistance[i] < 0, `point ${i} is inside`);
    if (outside) assert.ok(q.signedDistance[i] > 0, `point ${i} is outside`);
    const nn = Math.hypot(q.normal[3 * i], q.normal[3 * i + 1], q.normal[3 * i + 2]);
    assert.ok(Math.abs(nn - 1) < 1e-12);
  }
});

test("push-out leaves every point at least the margin outside, and moves only those that were not", () => {
  const { verts, faces } = icosphere(2, 0.3);
  const col = new BodyCollider(verts, faces);
  const r = rng(3), N = 200, pts = new Float64Array(3 * N);
  for (let i = 0; i < 3 * N; i++) pts[i] = 0.8 * (r() - 0.5);
  const before = col.query(verts, pts).signedDistance;
  const moved = col.pushOut(verts, pts, 1, N, 0.01, 3);
  const after = col.query(verts, pts).signedDistance;
  let want = 0;
  for (let i = 0; i < N; i++) {
    if (before[i] < 0.01) want++;
    assert.ok(after[i] >= 0.01 - 1e-12, `point ${i} left at ${after[i]}`);
    assert.equal(moved.mask[i], before[i] < 0.01 ? 1 : 0);
  }
  assert.equal(moved.moved, want);
});

test("frames of float32 vertices are pushed per frame against their own posed body", () => {
  const a = icosphere(1, 0.3), b = icosphere(1, 0.3, [0.5, 0, 0]);
  const body = new Float32Array([...a.verts, ...b.verts]); // two frames: the sphere moves by 0.5 along x
  const frames = new Float32Array([0.0, 0.0, 0.0, 0.5, 0.0, 0.0]); // N = 1: the centre of each frame's sphere
  const r = pushOutFrames(frames, 2, 1, body, a.verts.length / 3, a.faces, { margin: 0.01 });
  assert.equal(r.moved, 2);
  // each frame's point now lies the margin outside that frame's sphere (to float32 rounding)
  const sd0 = r.collider.query(a.verts, Float64Array.from(frames.subarray(0, 3))).signedDistance[0];
  const sd1 = r.collider.query(b.verts, Float64Array.from(frames.subarray(3, 6))).signedDistance[0];
  assert.ok(Math.abs(sd0 - 0.01) < 1e-7 && Math.abs(sd1 - 0.01) < 1e-7, `${sd0} ${sd1}`);
});

test("bad input is refused with what was expected", () => {
  const { verts, faces } = icosphere(0);
  assert.throws(() => new BodyCollider(verts, Int32Array.from([0, 1, 99])), /face index out of range/);
  assert.throws(() => new BodyCollider(new Float64Array(0), faces), /expected V, F >= 1/);
  const col = new BodyCollider(verts, faces);
  assert.throws(() => col.pushOut(verts, new Float64Array(3), 1, 1, -1), /margin must be finite and >= 0/);
  assert.throws(() => col.pushOut(verts.subarray(3), new Float64Array(3), 1, 1, 0.01), /posed body/);
});
