// Body collisions in JavaScript: a line-for-line port of src/segadeform/body/_collide.c (the compiled kernel the
// Python and C++ runtimes call), shared by the Node runtime and the browser page (plain ES module, no Node or DOM
// APIs).  The algorithm, its rules and why it is exact are in that file's header; this port keeps its functions,
// their order of operations and its float64 arithmetic (JavaScript numbers are IEEE doubles and V8 fuses no
// multiply-adds), so on the same inputs it gives the kernel's results: the same closest points, signed distances,
// normals and push-out positions, bit for bit (its acos is the kernel's sdc_acos, not Math.acos, which differs
// from a C library's in the last bit; tests/runtimes/test_collisions.py holds it to Python's BodyCollider on
// shared vectors).
//
//   closest point  the exact nearest point over every triangle, ties broken by the lowest face index;
//   sign           the angle-weighted pseudo-normal of the feature (face, edge, vertex) the closest point lies on;
//   buried         a point the closest feature's side calls outside but the body's winding number inside (in the
//                  torso next to an arm's skin buried in it) takes the nearest point that is not buried, in the
//                  push-out only within PINCH times the body's size (deeper, it stays pinched);
//   push-out       p' = closest + margin * n for points with signed distance < margin, again for the points moved,
//                  up to `iterations` passes (segadeform.body.collision.push_out's rule).
//
// Indices are Int32Array (the C file's int64_t: bodies have far fewer than 2^31 vertices and faces), coordinates
// Float64Array.  Differences from the C file that do not change a result: no out-of-memory paths, the qsort of
// the (edge key, slot) pairs is a sort of the slots by the same order, and the traversal stacks grow when needed.

const STACK = 256; // traversal stack; the median split keeps the depth under log2(F) + 1
const TINY = 1e-300;
const FEATURE = 1e-9; // a barycentric weight at or under this is zero (the reference's rule)
// a surface point is buried if the point this far out along its face's normal (times the posed body's size) is inside
// the body
const BURY = 1e-6;
const BURY_TRIES = 512; // at most this many faces tested for one point (nearestOpen)
// a point inside by its winding number but outside by its closest surface goes to the nearest skin that is not buried
// only within this distance (times the posed body's size); deeper in the crease it stays pinched (the C file's SDC_PINCH)
const PINCH = 0.012;
// the carried push-out (carryPoint): another exit is taken only if its move is at most CARRY_LIMB times the
// closest exit's plus PINCH * scale, and at most the frame before's plus CARRY_GROW * PINCH * scale (the C file's
// SDC_CARRY_LIMB, SDC_CARRY_GROW)
const CARRY_LIMB = 1.5;
const CARRY_GROW = 0.25;

// ---- small vector helpers (on 3-vectors stored at an offset of a Float64Array) -------------------------------
function dot3(a, ia, b, ib) { return a[ia] * b[ib] + a[ia + 1] * b[ib + 1] + a[ia + 2] * b[ib + 2]; }

function sub3(a, ia, b, ib, out, io) {
  out[io] = a[ia] - b[ib];
  out[io + 1] = a[ia + 1] - b[ib + 1];
  out[io + 2] = a[ia + 2] - b[ib + 2];
}

function cross3(a, ia, b, ib, out, io) {
  const x = a[ia + 1] * b[ib + 2] - a[ia + 2] * b[ib + 1];
  const y = a[ia + 2] * b[ib] - a[ia] * b[ib + 2];
  const z = a[ia] * b[ib + 1] - a[ia + 1] * b[ib];
  out[io] = x; out[io + 1] = y; out[io + 2] = z;
}

function norm3(a, ia) { return Math.sqrt(a[ia] * a[ia] + a[ia + 1] * a[ia + 1] + a[ia + 2] * a[ia + 2]); }

function normalize3(a, ia) {
  let n = norm3(a, ia);
  if (n < TINY) n = TINY;
  a[ia] /= n;
  a[ia + 1] /= n;
  a[ia + 2] /= n;
}

// ---- build --------------------------------------------------------------------------------------------------
/* Reorder idx[lo:hi] so that idx[mid] has the median key, smaller keys before it, larger after (quickselect,
 * ties broken by the face index so that the tree is the same on every platform). */
function lessKey(key, a, b) { return key[a] < key[b] || (key[a] === key[b] && a < b); }

function selectMedian(idx, key, lo, hi, mid) {
  while (hi - lo > 1) {
    let a = idx[lo], b = idx[lo + Math.floor((hi - lo) / 2)], c = idx[hi - 1], t, i;
    // median of three as the pivot
    if (lessKey(key, b, a)) { t = a; a = b; b = t; }
    if (lessKey(key, c, b)) { t = b; b = c; c = t; }
    if (lessKey(key, b, a)) { t = a; a = b; b = t; }
    const pivot = b;
    // three-way-free Lomuto partition with the pivot moved to the end
    for (i = lo; i < hi; i++) {
      if (idx[i] === pivot) { idx[i] = idx[hi - 1]; idx[hi - 1] = pivot; break; }
    }
    let j = lo;
    for (i = lo; i < hi - 1; i++) {
      if (lessKey(key, idx[i], pivot)) { t = idx[i]; idx[i] = idx[j]; idx[j] = t; j++; }
    }
    idx[hi - 1] = idx[j];
    idx[j] = pivot;
    if (j === mid) return;
    if (mid < j) hi = j; else lo = j + 1;
  }
}

/* The tree over the faces, from vertices (V, 3) of one pose: nodes in depth-first order (a parent before its
 * children), each leaf holding at most leafSize faces. */
function buildTree(b, verts, leafSize) {
  const nf = b.nf, cap = 2 * nf + 1;
  const cen = new Float64Array(3 * nf), key = new Float64Array(nf);
  const sLo = new Int32Array(cap + 1), sHi = new Int32Array(cap + 1), sNode = new Int32Array(cap + 1),
    sDepth = new Int32Array(cap + 1);
  const left = new Int32Array(cap), right = new Int32Array(cap), first = new Int32Array(cap),
    count = new Int32Array(cap), leafFace = new Int32Array(nf);
  b.left = left;
  b.right = right;
  b.first = first;
  b.count = count;
  b.leafFace = leafFace;
  const faces = b.faces, lo = new Float64Array(3), hi = new Float64Array(3);
  for (let i = 0; i < nf; i++) {
    const f0 = faces[3 * i], f1 = faces[3 * i + 1], f2 = faces[3 * i + 2];
    for (let k = 0; k < 3; k++) cen[3 * i + k] = (verts[3 * f0 + k] + verts[3 * f1 + k] + verts[3 * f2 + k]) / 3.0;
    leafFace[i] = i;
  }
  // depth first; the two children of a node get consecutive numbers, after their parent's (the refit runs backwards)
  let depth = 0, top = 0, n = 1;
  sLo[top] = 0; sHi[top] = nf; sNode[top] = 0; sDepth[top] = 0;
  top++;
  while (top > 0) {
    --top;
    const tLo = sLo[top], tHi = sHi[top], node = sNode[top], tDepth = sDepth[top];
    if (tDepth > depth) depth = tDepth;
    first[node] = tLo;
    count[node] = tHi - tLo;
    left[node] = right[node] = -1;
    if (tHi - tLo > leafSize) {
      lo.fill(Infinity);
      hi.fill(-Infinity);
      let axis = 0;
      const mid = tLo + Math.floor((tHi - tLo) / 2);
      for (let i = tLo; i < tHi; i++) {
        for (let k = 0; k < 3; k++) {
          const c = cen[3 * leafFace[i] + k];
          if (c < lo[k]) lo[k] = c;
          if (c > hi[k]) hi[k] = c;
        }
      }
      if (hi[1] - lo[1] > hi[axis] - lo[axis]) axis = 1;
      if (hi[2] - lo[2] > hi[axis] - lo[axis]) axis = 2;
      for (let i = tLo; i < tHi; i++) key[leafFace[i]] = cen[3 * leafFace[i] + axis];
      selectMedian(leafFace, key, tLo, tHi, mid);
      count[node] = 0;
      left[node] = n;
      right[node] = n + 1;
      // the right child is pushed first so that the left one's subtree is numbered next
      sLo[top] = mid; sHi[top] = tHi; sNode[top] = n + 1; sDepth[top] = tDepth + 1;
      top++;
      sLo[top] = tLo; sHi[top] = mid; sNode[top] = n; sDepth[top] = tDepth + 1;
      top++;
      n += 2;
    }
  }
  b.depth = depth;
  b.nNodes = n;
  // each leaf's distinct vertices (for the refit)
  b.vptr = new Int32Array(n + 1);
  const leafVert = new Int32Array(3 * nf);
  const mark = new Int32Array(b.nv).fill(-1);
  let nvl = 0;
  for (let i = 0; i < n; i++) {
    b.vptr[i] = nvl;
    if (left[i] < 0) {
      for (let j = first[i]; j < first[i] + count[i]; j++) {
        for (let k = 0; k < 3; k++) {
          const v = faces[3 * leafFace[j] + k];
          if (mark[v] !== i) { mark[v] = i; leafVert[nvl++] = v; }
        }
      }
    }
  }
  b.vptr[n] = nvl;
  b.leafVert = leafVert.slice(0, nvl);
}

/* The edges (faces around each, for edge pseudo-normals), the corners around each vertex (vertex pseudo-normals)
 * and whether the mesh is closed. */
function buildAdjacency(b) {
  const nf = b.nf, nv = b.nv, ns = 3 * nf, faces = b.faces;
  // qsort of (key, slot) pairs: the slots ordered by their edge's key, then by slot
  const key = new Float64Array(ns), order = new Int32Array(ns);
  for (let i = 0; i < ns; i++) {
    const f = Math.floor(i / 3), c = i % 3;
    const x = faces[3 * f + (c + 1) % 3], y = faces[3 * f + (c + 2) % 3];
    const lo = x < y ? x : y, hi = x < y ? y : x;
    key[i] = lo * (nv + 1) + hi; // exact: below 2^53 for any body with fewer than 2^26 vertices
    order[i] = i;
  }
  order.sort((a, c) => (key[a] !== key[c] ? (key[a] < key[c] ? -1 : 1) : a - c));
  const keyOf = (i) => key[order[i]], slotOf = (i) => order[i];
  b.edgeOf = new Int32Array(Math.max(ns, 1));
  const eptr = new Int32Array(ns + 1);
  b.eslot = new Int32Array(Math.max(ns, 1));
  b.closed = ns > 0;
  let e = 0;
  for (let i = 0; i < ns;) {
    let j = i;
    const ki = keyOf(i);
    while (j < ns && keyOf(j) === ki) j++;
    eptr[e] = i;
    for (let k = i; k < j; k++) {
      b.eslot[k] = slotOf(k);
      b.edgeOf[slotOf(k)] = e;
    }
    if (j - i !== 2) {
      b.closed = false;
    } else {
      // the two faces must run along the edge in opposite directions: compare where each starts
      const s0 = slotOf(i), s1 = slotOf(i + 1);
      const a0 = faces[3 * Math.floor(s0 / 3) + (s0 % 3 + 1) % 3], a1 = faces[3 * Math.floor(s1 / 3) + (s1 % 3 + 1) % 3];
      if (a0 === a1) b.closed = false;
    }
    e++;
    i = j;
  }
  eptr[e] = ns;
  b.eptr = eptr.slice(0, e + 1);
  // corners per vertex, in ascending corner order (counting sort)
  b.vfptr = new Int32Array(nv + 1);
  b.vcorner = new Int32Array(Math.max(ns, 1));
  for (let i = 0; i < ns; i++) b.vfptr[faces[i] + 1]++;
  for (let i = 0; i < nv; i++) b.vfptr[i + 1] += b.vfptr[i];
  const fill = b.vfptr.slice(0, nv);
  for (let i = 0; i < ns; i++) b.vcorner[fill[faces[i]]++] = i;
}

// ---- refit ----------------------------------------------------------------------------------------------------
/* The boxes (nNodes, 6: lo xyz, hi xyz) of the tree at the posed vertices (V, 3) of one frame, written to
 * box[boxOff ...] from verts[vOff ...]. */
function refit(b, verts, vOff, box, boxOff) {
  const left = b.left, right = b.right, vptr = b.vptr, lv = b.leafVert;
  for (let i = b.nNodes - 1; i >= 0; i--) {
    const o = boxOff + 6 * i;
    let x0, y0, z0, x1, y1, z1;
    if (left[i] < 0) {
      let p = vOff + 3 * lv[vptr[i]];
      x0 = x1 = verts[p];
      y0 = y1 = verts[p + 1];
      z0 = z1 = verts[p + 2];
      for (let j = vptr[i] + 1; j < vptr[i + 1]; j++) {
        p = vOff + 3 * lv[j];
        const x = verts[p], y = verts[p + 1], z = verts[p + 2];
        x0 = x < x0 ? x : x0;
        y0 = y < y0 ? y : y0;
        z0 = z < z0 ? z : z0;
        x1 = x > x1 ? x : x1;
        y1 = y > y1 ? y : y1;
        z1 = z > z1 ? z : z1;
      }
    } else {
      const l = boxOff + 6 * left[i], r = boxOff + 6 * right[i];
      x0 = box[l] < box[r] ? box[l] : box[r];
      y0 = box[l + 1] < box[r + 1] ? box[l + 1] : box[r + 1];
      z0 = box[l + 2] < box[r + 2] ? box[l + 2] : box[r + 2];
      x1 = box[l + 3] > box[r + 3] ? box[l + 3] : box[r + 3];
      y1 = box[l + 4] > box[r + 4] ? box[l + 4] : box[r + 4];
      z1 = box[l + 5] > box[r + 5] ? box[l + 5] : box[r + 5];
    }
    box[o] = x0;
    box[o + 1] = y0;
    box[o + 2] = z0;
    box[o + 3] = x1;
    box[o + 4] = y1;
    box[o + 5] = z1;
  }
}

// ---- geometry -------------------------------------------------------------------------------------------------
// scratch vectors of closestOnTriangle (one thread: module-level is safe)
const ab = new Float64Array(3), ac = new Float64Array(3), ap = new Float64Array(3), bp = new Float64Array(3),
  cp = new Float64Array(3), diffT = new Float64Array(3);

/* Closest point on triangle abc (vertices at offsets ia, ib, ic of V) to p (at ip of P) and its barycentric
 * weights (bary[0..2]), the point written to out[0..2], as closest_point_on_triangles (the reference): Voronoi
 * regions in its order, its guards, weights clipped to [0, 1] and renormalised.  Returns the squared distance. */
function closestOnTriangle(P, ip, V, ia, ib, ic, bary, out) {
  let u, v, w, t, den, s;
  sub3(V, ib, V, ia, ab, 0);
  sub3(V, ic, V, ia, ac, 0);
  sub3(P, ip, V, ia, ap, 0);
  const d1 = dot3(ab, 0, ap, 0);
  const d2 = dot3(ac, 0, ap, 0);
  sub3(P, ip, V, ib, bp, 0);
  const d3 = dot3(ab, 0, bp, 0);
  const d4 = dot3(ac, 0, bp, 0);
  sub3(P, ip, V, ic, cp, 0);
  const d5 = dot3(ab, 0, cp, 0);
  const d6 = dot3(ac, 0, cp, 0);
  const va = d3 * d6 - d5 * d4;
  const vb = d5 * d2 - d1 * d6;
  const vc = d1 * d4 - d3 * d2;
  if (d1 <= 0 && d2 <= 0) {
    u = 1; v = 0; w = 0;
  } else if (d3 >= 0 && d4 <= d3) {
    u = 0; v = 1; w = 0;
  } else if (vc <= 0 && d1 >= 0 && d3 <= 0) {
    den = Math.abs(d1 - d3) > TINY ? d1 - d3 : TINY;
    t = d1 / den;
    u = 1 - t; v = t; w = 0;
  } else if (d6 >= 0 && d5 <= d6) {
    u = 0; v = 0; w = 1;
  } else if (vb <= 0 && d2 >= 0 && d6 <= 0) {
    den = Math.abs(d2 - d6) > TINY ? d2 - d6 : TINY;
    t = d2 / den;
    u = 1 - t; v = 0; w = t;
  } else if (va <= 0 && (d4 - d3) >= 0 && (d5 - d6) >= 0) {
    den = (d4 - d3) + (d5 - d6);
    den = Math.abs(den) > TINY ? den : TINY;
    t = (d4 - d3) / den;
    u = 0; v = 1 - t; w = t;
  } else {
    s = va + vb + vc;
    s = Math.abs(s) > TINY ? s : TINY;
    u = va / s; v = vb / s; w = vc / s;
  }
  // clip to [0, 1] (NaN-free: the guards above keep every weight finite) and renormalise
  u = u < 0 ? 0 : (u > 1 ? 1 : u);
  v = v < 0 ? 0 : (v > 1 ? 1 : v);
  w = w < 0 ? 0 : (w > 1 ? 1 : w);
  s = u + v + w;
  if (s < TINY) { u = 1; v = 0; w = 0; s = 1; } // not reached for any triangle; a corner, never the origin
  u /= s; v /= s; w /= s;
  out[0] = u * V[ia] + v * V[ib] + w * V[ic];
  out[1] = u * V[ia + 1] + v * V[ib + 1] + w * V[ic + 1];
  out[2] = u * V[ia + 2] + v * V[ib + 2] + w * V[ic + 2];
  bary[0] = u; bary[1] = v; bary[2] = w;
  sub3(out, 0, P, ip, diffT, 0);
  return dot3(diffT, 0, diffT, 0);
}

const e1F = new Float64Array(3), e2F = new Float64Array(3);

/* Unit normal of face f (zero-area: the zero vector divided by 1e-300, i.e. zero), into n[io..]. */
function faceNormal(b, V, vOff, f, n, io) {
  const t0 = vOff + 3 * b.faces[3 * f], t1 = vOff + 3 * b.faces[3 * f + 1], t2 = vOff + 3 * b.faces[3 * f + 2];
  sub3(V, t1, V, t0, e1F, 0);
  sub3(V, t2, V, t0, e2F, 0);
  cross3(e1F, 0, e2F, 0, n, io);
  normalize3(n, io);
}

const g3 = new Float64Array(3), e1V = new Float64Array(3), e2V = new Float64Array(3), fnV = new Float64Array(3);

/* Pseudo-normal of the feature of face f that the barycentric weights point at (the C file's header), into n. */
function featureNormal(b, V, vOff, f, bary, n) {
  const nz = (bary[0] > FEATURE ? 1 : 0) + (bary[1] > FEATURE ? 1 : 0) + (bary[2] > FEATURE ? 1 : 0);
  if (nz >= 3) {
    faceNormal(b, V, vOff, f, n, 0);
  } else if (nz === 2) {
    // the edge opposite the corner of least weight (the first of equal ones)
    let c = 0;
    if (bary[1] < bary[c]) c = 1;
    if (bary[2] < bary[c]) c = 2;
    const e = b.edgeOf[3 * f + c];
    n[0] = n[1] = n[2] = 0;
    for (let i = b.eptr[e]; i < b.eptr[e + 1]; i++) {
      faceNormal(b, V, vOff, Math.floor(b.eslot[i] / 3), g3, 0);
      n[0] += g3[0];
      n[1] += g3[1];
      n[2] += g3[2];
    }
    normalize3(n, 0);
  } else {
    // the vertex of greatest weight (the first of equal ones)
    let c = 0;
    if (bary[1] > bary[c]) c = 1;
    if (bary[2] > bary[c]) c = 2;
    const v = b.faces[3 * f + c];
    n[0] = n[1] = n[2] = 0;
    for (let i = b.vfptr[v]; i < b.vfptr[v + 1]; i++) {
      const corner = b.vcorner[i], g = Math.floor(corner / 3), k = corner % 3;
      const t = 3 * g;
      const tk = vOff + 3 * b.faces[t + k], t1 = vOff + 3 * b.faces[t + (k + 1) % 3],
        t2 = vOff + 3 * b.faces[t + (k + 2) % 3];
      sub3(V, t1, V, tk, e1V, 0);
      sub3(V, t2, V, tk, e2V, 0);
      const len = norm3(e1V, 0) * norm3(e2V, 0);
      let cosang = dot3(e1V, 0, e2V, 0) / (len > TINY ? len : TINY);
      cosang = cosang < -1 ? -1 : (cosang > 1 ? 1 : cosang);
      const ang = acos(cosang);
      faceNormal(b, V, vOff, g, fnV, 0);
      n[0] += ang * fnV[0];
      n[1] += ang * fnV[1];
      n[2] += ang * fnV[2];
    }
    normalize3(n, 0);
  }
}

/* acos from + - * / and Math.sqrt alone: the C file's sdc_acos, operation for operation (Math.acos differs from a C
 * library's acos in the last bit on about 7 % of inputs; this gives the kernel's bits). */
function asinR(z) {
  const p = z * (1.66666666666666657415e-01 +
    z * (-3.25565818622400915405e-01 +
      z * (2.01212532134862925881e-01 +
        z * (-4.00555345006794114027e-02 +
          z * (7.91534994289814532176e-04 + z * 3.47933107596021167570e-05)))));
  const q = 1.0 + z * (-2.40339491173441421878e+00 +
    z * (2.02094576023350569471e+00 +
      z * (-6.88283971605453293030e-01 + z * 7.70381505559019352791e-02)));
  return p / q;
}

export function acos(x) {
  if (x !== x) return x;
  if (x > 1) x = 1;
  if (x < -1) x = -1;
  if (x <= 0.5 && x >= -0.5) return 1.57079632679489655800e+00 - (x + x * asinR(x * x));
  let s = Math.sqrt((1.0 - (x < 0 ? -x : x)) * 0.5);
  s = 2.0 * (s + s * asinR(s * s));
  return x > 0 ? s : 3.14159265358979311600e+00 - s;
}

/* Squared distance from p (P at ip) to the box (box at o: lo xyz, hi xyz). */
function boxDist2(box, o, P, ip) {
  let d = 0, g;
  for (let k = 0; k < 3; k++) {
    g = box[o + k] - P[ip + k];
    if (P[ip + k] - box[o + 3 + k] > g) g = P[ip + k] - box[o + 3 + k];
    if (g > 0) d += g * g;
  }
  return d;
}

/* Per frame: the posed vertices (verts at vOff), the refitted boxes (box at boxOff) and the slack of the pruning
 * tests. */
function makeFrame(b, verts, vOff, box, boxOff) {
  let m = 0;
  for (let k = 0; k < 6; k++) {
    const x = Math.abs(box[boxOff + k]);
    if (x > m) m = x;
  }
  // scale: the posed body's size (its box's longest side: the same wherever the body stands), which the tolerances
  // of the rules for buried skin and the push-out's radius are measured in; slack: far above the rounding of a
  // distance at the largest coordinate magnitude
  let scale = 0;
  for (let k = 0; k < 3; k++) scale = Math.max(scale, box[boxOff + 3 + k] - box[boxOff + k]);
  return { b, verts, vOff, box, boxOff, scale, slack: 1e-12 * m + TINY };
}

// traversal stacks (grown if a tree is ever deeper than STACK allows)
function doubled(a) {
  const x = new a.constructor(2 * a.length);
  x.set(a);
  return x;
}
let stackN = new Int32Array(STACK), stackL = new Float64Array(STACK);
function grow() {
  stackN = doubled(stackN);
  stackL = doubled(stackL);
}

// nearestOpen's own traversal stacks: buried() walks the tree (rayCount, on the shared stacks) in the middle of it
let stackO = new Int32Array(STACK), stackOL = new Float64Array(STACK);
function growO() {
  stackO = doubled(stackO);
  stackOL = doubled(stackOL);
}
const tb = new Float64Array(3), tc = new Float64Array(3);

// the face found by the last nearest() (-1: none within the bound): the C function's *face
let nearestFace = -1;

/* The nearest triangle to p (P at ip) with squared distance under the bound: branch and bound over the tree.
 * ub: the distance bound (Infinity: none).  On return nearestFace is the winner (-1: none within the bound),
 * bary/closest its barycentric weights and point, and the squared distance is returned (Infinity: none).
 * open: only faces whose nearest point to p is not buried, at most BURY_TRIES of them tested (nearestOpen; it walks
 * its own stacks: buried() walks the tree on the shared ones in the middle of it). */
function nearestIn(fr, P, ip, ub, open, bary, closest) {
  const b = fr.b, V = fr.verts, vOff = fr.vOff, box = fr.box, boxOff = fr.boxOff;
  const left = b.left, right = b.right, first = b.first, count = b.count, leafFace = b.leafFace, faces = b.faces;
  let top = 0, best = Infinity, slack = fr.slack, bestf = -1, tries = 0;
  let sN = open ? stackO : stackN, sL = open ? stackOL : stackL;
  for (let k = 0; k < 3; k++) { // a point far from the body rounds at its own magnitude
    if (1e-12 * Math.abs(P[ip + k]) > slack) slack = 1e-12 * Math.abs(P[ip + k]);
  }
  let bound2 = (ub + slack) * (ub + slack); // Infinity stays Infinity
  sN[top] = 0;
  sL[top++] = boxDist2(box, boxOff, P, ip);
  while (top > 0) {
    top--;
    if (sL[top] > bound2) continue;
    const node = sN[top];
    if (left[node] < 0) {
      for (let j = first[node]; j < first[node] + count[node]; j++) {
        const f = leafFace[j];
        const d2 = closestOnTriangle(P, ip, V, vOff + 3 * faces[3 * f], vOff + 3 * faces[3 * f + 1],
          vOff + 3 * faces[3 * f + 2], tb, tc);
        if (!(d2 < best || (d2 === best && f < bestf) || bestf < 0)) continue; // (bestf < 0: d2 overflowed)
        if (open) {
          if (++tries > BURY_TRIES) { // bounded: the point keeps its closest surface
            nearestFace = -1;
            return Infinity;
          }
          if (buried(fr, tc, 0, f)) continue;
        }
        best = d2;
        bestf = f;
        bary[0] = tb[0]; bary[1] = tb[1]; bary[2] = tb[2];
        closest[0] = tc[0]; closest[1] = tc[1]; closest[2] = tc[2];
        const r = Math.sqrt(best) + slack;
        if (r * r < bound2) bound2 = r * r;
      }
    } else {
      const l = left[node], r = right[node];
      const dl = boxDist2(box, boxOff + 6 * l, P, ip), dr = boxDist2(box, boxOff + 6 * r, P, ip);
      if (top + 2 > sN.length) {
        if (open) growO(); else grow();
        sN = open ? stackO : stackN;
        sL = open ? stackOL : stackL;
      }
      // the nearer child is popped first
      if (dl <= dr) {
        if (dr <= bound2) { sN[top] = r; sL[top++] = dr; }
        if (dl <= bound2) { sN[top] = l; sL[top++] = dl; }
      } else {
        if (dl <= bound2) { sN[top] = l; sL[top++] = dl; }
        if (dr <= bound2) { sN[top] = r; sL[top++] = dr; }
      }
    }
  }
  nearestFace = bestf;
  return best;
}

function nearest(fr, P, ip, ub, bary, closest) { return nearestIn(fr, P, ip, ub, false, bary, closest); }

// what the last rayCount() found besides its count: the C function's *graze and *first
let rayGraze = false, rayFirst = Infinity;

/* A ray from p along +axis (dir 1) or -axis (dir -1) through the mesh: the signed count of its crossings (0 outside
 * a closed mesh), whether it passed exactly through an edge or a vertex or started on a triangle's plane (rayGraze:
 * the count is then not trusted), and the distance to its first crossing (rayFirst, Infinity: none). */
function rayCount(fr, P, ip, axis, dir) {
  const b = fr.b, V = fr.verts, vOff = fr.vOff, box = fr.box, boxOff = fr.boxOff;
  const u = (axis + 1) % 3, v = (axis + 2) % 3;
  const pu = P[ip + u], pv = P[ip + v], pa = P[ip + axis];
  const left = b.left, right = b.right, first = b.first, count = b.count, leafFace = b.leafFace, faces = b.faces;
  let top = 0, wind = 0, graze = false, firstHit = Infinity;
  stackN[top++] = 0;
  while (top > 0) {
    const node = stackN[--top];
    const bx = boxOff + 6 * node;
    if (pu < box[bx + u] || pu > box[bx + 3 + u] || pv < box[bx + v] || pv > box[bx + 3 + v]) continue;
    if (dir > 0 ? box[bx + 3 + axis] < pa : box[bx + axis] > pa) continue;
    if (left[node] >= 0) {
      if (top + 2 > stackN.length) grow();
      stackN[top++] = right[node];
      stackN[top++] = left[node];
      continue;
    }
    for (let j = first[node]; j < first[node] + count[node]; j++) {
      const t = 3 * leafFace[j];
      const a = vOff + 3 * faces[t], bb = vOff + 3 * faces[t + 1], c = vOff + 3 * faces[t + 2];
      const au = V[a + u] - pu, av = V[a + v] - pv, bu = V[bb + u] - pu, bv = V[bb + v] - pv;
      const cu = V[c + u] - pu, cv = V[c + v] - pv;
      // 2-D edge functions: the same edge seen from its other face gives exactly the negative
      const ea = bu * cv - bv * cu, eb = cu * av - cv * au, ec = au * bv - av * bu;
      const pos = (ea > 0 ? 1 : 0) + (eb > 0 ? 1 : 0) + (ec > 0 ? 1 : 0);
      const neg = (ea < 0 ? 1 : 0) + (eb < 0 ? 1 : 0) + (ec < 0 ? 1 : 0);
      if (pos && neg) continue; // p's line misses the triangle
      const s = ea + eb + ec;
      if (s === 0) { // the triangle is edge-on to the ray: a graze if the ray meets its own box
        let loU = au < bu ? au : bu, hiU = au > bu ? au : bu, loV = av < bv ? av : bv;
        let hiV = av > bv ? av : bv;
        const ea_ = V[a + axis], eb_ = V[bb + axis], ec_ = V[c + axis];
        let far = dir > 0 ? (ea_ > eb_ ? ea_ : eb_) : (ea_ < eb_ ? ea_ : eb_);
        loU = cu < loU ? cu : loU; hiU = cu > hiU ? cu : hiU;
        loV = cv < loV ? cv : loV; hiV = cv > hiV ? cv : hiV;
        far = dir > 0 ? (ec_ > far ? ec_ : far) : (ec_ < far ? ec_ : far);
        if (loU <= 0 && hiU >= 0 && loV <= 0 && hiV >= 0 && (dir > 0 ? far >= pa : far <= pa)) graze = true;
        continue;
      }
      const num = ea * (V[a + axis] - pa) + eb * (V[bb + axis] - pa) + ec * (V[c + axis] - pa);
      const depth = dir * num / s;
      if (depth < 0) continue;
      if ((pos === 3 || neg === 3) && depth > 0) {
        wind += (s > 0 ? 1 : -1) * dir;
        if (depth < firstHit) firstHit = depth;
      } else {
        graze = true; // through an edge or a vertex, or from the triangle's plane
      }
    }
  }
  rayGraze = graze;
  rayFirst = firstHit;
  return wind;
}

// the winding number found by the last windingAt() that returned true: the C function's *w
let windW = 0;

/* The body's winding number at p when a ray decides it: the six axis directions, the shortest way out of the root box
 * first, until one does not graze.  Returns true with windW = |signed crossings|, or false when all six graze or the
 * body is not closed. */
const distW = new Float64Array(6), usedW = new Uint8Array(6);
function windingAt(fr, P, ip) {
  if (!fr.b.closed) return false;
  for (let k = 0; k < 3; k++) {
    distW[2 * k] = fr.box[fr.boxOff + 3 + k] - P[ip + k]; // +axis
    distW[2 * k + 1] = P[ip + k] - fr.box[fr.boxOff + k]; // -axis
  }
  usedW.fill(0);
  for (let tried = 0; tried < 6; tried++) {
    let best = -1;
    for (let k = 0; k < 6; k++) if (!usedW[k] && (best < 0 || distW[k] < distW[best])) best = k;
    usedW[best] = 1;
    const c = rayCount(fr, P, ip, (best / 2) | 0, best % 2 ? -1 : 1);
    if (!rayGraze) {
      windW = c < 0 ? -c : c;
      return true;
    }
  }
  return false;
}

const nB = new Float64Array(3), qB = new Float64Array(3);

/* Whether the point c (C at ic) of face f is buried: the point BURY * scale out from it along the face's normal is
 * inside the body by its winding number (undecided: not buried; a face of zero area: buried, never taken). */
function buried(fr, C, ic, f) {
  const h = BURY * fr.scale;
  faceNormal(fr.b, fr.verts, fr.vOff, f, nB, 0);
  if (nB[0] === 0 && nB[1] === 0 && nB[2] === 0) return true; // zero area: never open (its edges are its neighbours')
  qB[0] = C[ic] + h * nB[0];
  qB[1] = C[ic + 1] + h * nB[1];
  qB[2] = C[ic + 2] + h * nB[2];
  return windingAt(fr, qB, 0) && windW !== 0;
}

/* As nearest within ub, over the faces whose nearest point to p is not buried: the minimum of (squared distance,
 * face index) over them (one past ub may be returned; the caller checks).  nearestFace = -1 when every one is buried or more than BURY_TRIES faces were tested (the
 * C file's nearest_open). */
function nearestOpen(fr, P, ip, ub, bary, closest) { return nearestIn(fr, P, ip, ub, true, bary, closest); }

const diffS = new Float64Array(3);

/* Signed distance at the closest point found (face f, weights bary, point closest) and the normal (into n). */
function signedAt(fr, P, ip, f, bary, closest, n) {
  featureNormal(fr.b, fr.verts, fr.vOff, f, bary, n);
  sub3(P, ip, closest, 0, diffS, 0);
  const d = norm3(diffS, 0);
  return dot3(diffS, 0, n, 0) < 0 ? -d : d;
}

const baryN = new Float64Array(3), baryU = new Float64Array(3), cU = new Float64Array(3);

/* A point whose closest feature's side says outside (nearSd > BURY * scale) but whose winding number (wind, -1: not
 * known yet) says inside: its closest point becomes the nearest point that is not buried within ub, nearSd = minus the
 * distance to it and n that feature's pseudo-normal.  Otherwise (deeper in the crease too) unchanged.  ub: PINCH *
 * scale for the push-out, Infinity for the backstop's traces (the C file's unbury). */
function unbury(fr, P, ip, wind, ub, closest, n) {
  if (wind < 0) {
    if (!windingAt(fr, P, ip)) return;
    wind = windW;
  }
  if (wind === 0) return;
  const d2 = nearestOpen(fr, P, ip, ub, baryU, cU);
  if (nearestFace < 0 || d2 > ub * ub) return; // pinched deeper: left
  nearFace = nearestFace;
  closest[0] = cU[0]; closest[1] = cU[1]; closest[2] = cU[2];
  featureNormal(fr.b, fr.verts, fr.vOff, nearFace, baryU, n);
  nearSd = -Math.sqrt(d2);
}

// the signed distance and face found by the last nearOrInside() that returned true: the C function's *sd and *face
let nearSd = 0, nearFace = -1;

/* The exact closest point of p if it is inside the body or within `radius` of it.  Returns true with the signed
 * distance and face in nearSd and nearFace and the closest point and normal written to closest and n, or false
 * when p is outside and farther than radius (a farther point inside by the winding number is found, with its closest
 * surface).  The rule for buried skin by `check`: 2 every point (the push-out), 1 the points farther than radius
 * only (the cloth stage's backstop traces), 0 none (its contact lookups; the C function's comment says why). */
function nearOrInside(fr, P, ip, radius, check, closest, n) {
  const b = fr.b;
  let bound = Infinity;
  const d2 = nearest(fr, P, ip, radius, baryN, closest);
  if (nearestFace >= 0 && d2 < radius * radius) {
    nearFace = nearestFace;
    nearSd = signedAt(fr, P, ip, nearFace, baryN, closest, n);
    if (check === 2 && nearSd > BURY * fr.scale) unbury(fr, P, ip, -1, PINCH * fr.scale, closest, n);
    return true;
  }
  let wind = -1; // -1: not known
  if (b.closed) {
    // the shortest way out of the root box, along an axis
    let axis = 0, dir = 1, best = Infinity;
    for (let k = 0; k < 3; k++) {
      const up = fr.box[fr.boxOff + 3 + k] - P[ip + k], down = P[ip + k] - fr.box[fr.boxOff + k];
      if (up < best) { best = up; axis = k; dir = 1; }
      if (down < best) { best = down; axis = k; dir = -1; }
    }
    wind = rayCount(fr, P, ip, axis, dir);
    if (wind === 0 && !rayGraze) return false;
    wind = rayGraze ? -1 : (wind < 0 ? -wind : wind); // |signed crossings|; -1: not known
    bound = rayFirst;
  }
  nearest(fr, P, ip, bound, baryN, closest);
  // none within the bound: the ray's first hit, measured on a nearly edge-on triangle, came out short
  if (nearestFace < 0) nearest(fr, P, ip, Infinity, baryN, closest);
  nearFace = nearestFace;
  nearSd = signedAt(fr, P, ip, nearFace, baryN, closest, n);
  if (check >= 1 && nearSd > BURY * fr.scale) {
    unbury(fr, P, ip, wind, check === 2 ? PINCH * fr.scale : Infinity, closest, n);
  }
  return true;
}

const cP = new Float64Array(3), nP = new Float64Array(3);

/* The push-out of the point at pts[ip ...] (moved in place), up to `iterations` passes; whether it moved (the C
 * file's push_point). */
function pushPoint(fr, pts, ip, radius, margin, iterations) {
  let moved = false;
  for (let it = 0; it < iterations; it++) {
    if (!nearOrInside(fr, pts, ip, radius, 2, cP, nP) || !(nearSd < margin)) break;
    pts[ip] = cP[0] + margin * nP[0];
    pts[ip + 1] = cP[1] + margin * nP[1];
    pts[ip + 2] = cP[2] + margin * nP[2];
    moved = true;
  }
  return moved;
}

const qC = new Float64Array(3), kC = new Float64Array(3), dC = new Float64Array(3), aC = new Float64Array(3),
  kaC = new Float64Array(3), pickC = new Float64Array(3);
const GAIN = [1.0, 0.5];

/* The rule for the correction carried from the frame before, for the point at pts[ip ...] (already pushed out; q its
 * place before) with its carried correction carry[ic ...] (zero: none), both in place: the C file's carry_point --
 * where the correction jumps by more than PINCH * scale, the push-out again from q + k0 and q + k0 / 2, the exit
 * nearest k0 kept within the bounds; then carry = p - q. */
function carryPoint(fr, q, pts, ip, carry, ic, radius, margin, iterations) {
  const lim = PINCH * fr.scale;
  sub3(pts, ip, q, 0, kC, 0);
  if (carry[ic] !== 0.0 || carry[ic + 1] !== 0.0 || carry[ic + 2] !== 0.0) {
    sub3(kC, 0, carry, ic, dC, 0);
    let best = norm3(dC, 0);
    if (best > lim) {
      const kn = norm3(kC, 0), k0n = norm3(carry, ic);
      pickC[0] = pts[ip]; pickC[1] = pts[ip + 1]; pickC[2] = pts[ip + 2];
      for (let g = 0; g < 2; g++) {
        aC[0] = q[0] + GAIN[g] * carry[ic];
        aC[1] = q[1] + GAIN[g] * carry[ic + 1];
        aC[2] = q[2] + GAIN[g] * carry[ic + 2];
        pushPoint(fr, aC, 0, radius, margin, iterations);
        sub3(aC, 0, q, 0, kaC, 0);
        sub3(kaC, 0, carry, ic, dC, 0);
        const dn = norm3(dC, 0), an = norm3(kaC, 0);
        if (dn < best && an <= CARRY_LIMB * kn + lim && an <= k0n + CARRY_GROW * lim) {
          best = dn;
          pickC[0] = aC[0]; pickC[1] = aC[1]; pickC[2] = aC[2];
        }
      }
      pts[ip] = pickC[0]; pts[ip + 1] = pickC[1]; pts[ip + 2] = pickC[2];
    }
  }
  sub3(pts, ip, q, 0, carry, ic);
}

/* The push-out of points [i0, i1) of one frame fr: pts[3 * (off + i) ...] moved in place, mask[off + i] set to 1 for
 * every point moved (the C file's push_frames over one frame); with carry (n*3 Float64Array, in place) not null the
 * correction carried from the frame before (carryPoint) and a point counted as moved where its place changed.
 * Returns the number of points newly marked. */
function pushFrame(fr, pts, off, i0, i1, margin, iterations, mask, carry = null) {
  let total = 0;
  if (iterations < 1) iterations = 1;
  // a little over the margin: a point just pushed out to the margin is found again by the radius
  const radius = margin * (1.0 + 1e-3) + 1e-9 * fr.scale;
  for (let i = i0; i < i1; i++) {
    const ip = 3 * (off + i);
    qC[0] = pts[ip]; qC[1] = pts[ip + 1]; qC[2] = pts[ip + 2];
    let changed = pushPoint(fr, pts, ip, radius, margin, iterations);
    if (carry !== null) {
      carryPoint(fr, qC, pts, ip, carry, 3 * i, radius, margin, iterations);
      changed = pts[ip] !== qC[0] || pts[ip + 1] !== qC[1] || pts[ip + 2] !== qC[2];
    }
    if (changed && !mask[off + i]) {
      mask[off + i] = 1;
      total++;
    }
  }
  return total;
}

// ---- the collider ---------------------------------------------------------------------------------------------
/**
 * A collider for a body whose triangles stay the same while its vertices move (the posed body): the tree, built
 * once from any pose, refitted per frame (sdc_create / sdc_refit / sdc_query / sdc_push_out of the C file).
 *   new BodyCollider(vertices (V*3, any pose), faces (F*3 indices), { leafSize: 4 })
 */
export class BodyCollider {
  constructor(vertices, faces, { leafSize = 4 } = {}) {
    const nv = Math.floor(vertices.length / 3), nf = Math.floor(faces.length / 3);
    if (nv < 1 || nf < 1 || vertices.length !== 3 * nv || faces.length !== 3 * nf) {
      throw new Error(`the body must have vertices (V, 3) and faces (F, 3) (expected V, F >= 1, got ${vertices.length} ` +
        `coordinates and ${faces.length} face indices)`);
    }
    const f = new Int32Array(faces);
    for (let i = 0; i < f.length; i++) {
      if (!(f[i] >= 0 && f[i] < nv)) throw new Error(`body face index out of range (expected 0..${nv - 1}, got ${faces[i]})`);
    }
    if (!(leafSize >= 1)) leafSize = 1;
    this.nv = nv;
    this.nf = nf;
    this.faces = f;
    // every field set here first, in one order (one object shape for the hot loops)
    this.left = this.right = this.first = this.count = this.leafFace = this.vptr = this.leafVert = null;
    this.edgeOf = this.eptr = this.eslot = this.vfptr = this.vcorner = null;
    this.nNodes = this.depth = 0;
    this.closed = false;
    buildTree(this, new Float64Array(vertices), leafSize);
    buildAdjacency(this);
  }

  /** The tree's boxes for frames verts (B*V*3): Float64Array (B * nNodes * 6). */
  refit(verts, B = 1) {
    if (verts.length !== B * this.nv * 3) {
      throw new Error(`the posed body must have the body's vertices per frame (expected ${B * this.nv * 3} coordinates, got ${verts.length})`);
    }
    const box = new Float64Array(B * this.nNodes * 6);
    for (let f = 0; f < B; f++) refit(this, verts, 3 * this.nv * f, box, 6 * this.nNodes * f);
    return box;
  }

  /**
   * Exact signed distance (negative inside), closest point, outward normal and face of every point of pts (P*3)
   * against one frame verts (V*3) (sdc_query).  Returns { signedDistance (P), closest (P*3), normal (P*3), face (P) }.
   */
  query(verts, pts) {
    const V = new Float64Array(verts), P = new Float64Array(pts);
    const box = this.refit(V, 1);
    const fr = makeFrame(this, V, 0, box, 0);
    const n = Math.floor(P.length / 3);
    const sd = new Float64Array(n), closest = new Float64Array(3 * n), normal = new Float64Array(3 * n),
      face = new Int32Array(n);
    const bary = new Float64Array(3), c = new Float64Array(3), nrm = new Float64Array(3);
    for (let i = 0; i < n; i++) {
      nearest(fr, P, 3 * i, Infinity, bary, c);
      face[i] = nearestFace;
      sd[i] = signedAt(fr, P, 3 * i, nearestFace, bary, c, nrm);
      closest.set(c, 3 * i);
      normal.set(nrm, 3 * i);
    }
    return { signedDistance: sd, closest, normal, face };
  }

  /**
   * push_out of every point of B frames: pts (B*N*3, Float64Array, moved in place) against verts (B*V*3, the posed
   * body per frame) with `margin` (metres) and up to `iterations` passes (sdc_push_out).  With `carry` (N*3
   * Float64Array, zeros at a stream's start, updated in place) the frames are consecutive and each point's correction
   * is carried from frame to frame (sdc_push_out_carried; moved then counts the points whose place changed).  Returns
   * { moved: the number of (frame, point) pairs moved, mask: Uint8Array (B*N), 1 where moved }.
   */
  pushOut(verts, pts, B, N, margin, iterations = 3, carry = null) {
    if (!(Number.isFinite(margin) && margin >= 0)) throw new Error(`margin must be finite and >= 0 (got ${margin})`);
    if (!(pts instanceof Float64Array) || pts.length !== B * N * 3) {
      throw new Error(`points must be a Float64Array (B, N, 3) (expected ${B * N * 3} values, got ${pts.length})`);
    }
    if (carry !== null && !(carry instanceof Float64Array && carry.length === N * 3)) {
      throw new Error(`carry must be a Float64Array (N, 3) (expected ${N * 3} values, got ${carry.length})`);
    }
    const V = verts instanceof Float64Array ? verts : new Float64Array(verts);
    const box = this.refit(V, B);
    const mask = new Uint8Array(B * N);
    let total = 0;
    for (let f = 0; f < B; f++) {
      const fr = makeFrame(this, V, 3 * this.nv * f, box, 6 * this.nNodes * f);
      total += pushFrame(fr, pts, N * f, 0, N, margin, iterations, mask, carry);
    }
    return { moved: total, mask };
  }

  /** The boxes of one frame verts (V*3, Float64Array) written into box (nNodes*6, Float64Array) (sdc_refit). */
  refitInto(verts, box) {
    refit(this, verts, 0, box, 0);
  }

  /**
   * The exact signed distance, closest point and normal of every point of pts [i0, i1) (Float64Array) inside the
   * body or within `radius` of it, against one frame (verts with its boxes from refitInto), written to sd (P),
   * closest and normal (P*3); the others get sd = Infinity (sdc_near).  Returns how many were found.  `rule`: the
   * rule for buried skin for the points farther than radius (the cloth stage's backstop), else none (its contacts).
   */
  near(verts, box, pts, i0, i1, radius, sd, closest, normal, rule = false) {
    const fr = makeFrame(this, verts, 0, box, 0);
    const c = new Float64Array(3), nrm = new Float64Array(3);
    let found = 0;
    for (let i = i0; i < i1; i++) {
      if (nearOrInside(fr, pts, 3 * i, radius, rule ? 1 : 0, c, nrm)) {
        sd[i] = nearSd;
        closest[3 * i] = c[0]; closest[3 * i + 1] = c[1]; closest[3 * i + 2] = c[2];
        normal[3 * i] = nrm[0]; normal[3 * i + 1] = nrm[1]; normal[3 * i + 2] = nrm[2];
        found++;
      } else {
        sd[i] = Infinity;
      }
    }
    return found;
  }

  /** sdc_push_out of the points [i0, i1) of pts (n*3, moved in place) against one frame (verts with its boxes from
   * refitInto); moved (Uint8Array n) set to 1 where a point moved.  Returns how many moved. */
  pushOutFrame(verts, box, pts, i0, i1, margin, iterations, moved) {
    return pushFrame(makeFrame(this, verts, 0, box, 0), pts, 0, i0, i1, margin, iterations, moved);
  }

  /** Whether the mesh is closed (every edge has two faces running along it in opposite directions). */
  get isClosed() { return this.closed; }
}

/**
 * The push-out of garment frames (T*N*3 float32, as the deformer gives them) against the posed body (T*V*3 float32,
 * the body graph's) with the body's faces: what `segadeform run` does with collisions on (float64 arithmetic, the
 * result rounded to float32 as its writers round it).  The frames are changed in place; `collider` (a BodyCollider
 * for these faces) is built from the first frame when not given; `carry` (N*3 Float64Array, zeros at the clip's
 * start, kept by the caller between calls) carries each vertex's correction from frame to frame, as `segadeform run`
 * does (null: every frame stands alone).  Returns { moved, msPerFrame, collider }.
 */
export function pushOutFrames(frames, T, N, bodyVertices, V, faces, { margin = 0.004, iterations = 3, collider = null,
  batch = 8, carry = null } = {}) {
  if (frames.length !== T * N * 3 || bodyVertices.length !== T * V * 3) {
    throw new Error(`frames and the posed body do not fit (expected ${T * N * 3} and ${T * V * 3} values, got ` +
      `${frames.length} and ${bodyVertices.length})`);
  }
  const t0 = performance.now();
  const col = collider || new BodyCollider(bodyVertices.subarray(0, V * 3), faces);
  let moved = 0;
  for (let lo = 0; lo < T; lo += batch) {
    const hi = Math.min(lo + batch, T), B = hi - lo;
    const pts = new Float64Array(frames.subarray(lo * N * 3, hi * N * 3));
    const r = col.pushOut(new Float64Array(bodyVertices.subarray(lo * V * 3, hi * V * 3)), pts, B, N, margin, iterations,
      carry);
    moved += r.moved;
    frames.set(pts, lo * N * 3); // float64 -> float32, rounded to nearest
  }
  return { moved, msPerFrame: (performance.now() - t0) / Math.max(T, 1), collider: col };
}
