// The cloth stage in JavaScript: a line-for-line port of src/segadeform/body/_cloth.c (the compiled kernel the
// Python and C++ runtimes call), shared by the Node runtime and the browser page (plain ES module, no Node or DOM
// APIs).  The method, the order of its constraints and why each is there are in that file's header: position-based
// dynamics with strain limiting, tethers to the nearest attached vertex, smoothing of the deviation from the network's frame, max-distance attachments and
// contact planes at vertices and edge middles against the posed body, then the collision stage's exact push-out (collide.js).  This port keeps the
// C file's functions, their order of operations and its float64 arithmetic (only + - * / and Math.sqrt, which
// JavaScript rounds as C does), so on the same inputs it gives the kernel's frames bit for bit
// (tests/runtimes/test_cloth.py holds it to Python's ClothStage on shared vectors).

import { BodyCollider } from "./collide.js";

const CONTACT_BAND = 0.005; // metres beyond the margin within which a vertex gets a contact plane (SCL_CONTACT_BAND)
const EDGE_DEEP = 0.02; // metres: an edge middle found deeper inside gets no contact plane (SCL_EDGE_DEEP)
const PASSES = 3; // the final push-out's passes (SCL_PASSES)
const TINY = 1e-300;
const MOVED = 1e-6; // metres: a final push-out move counted as one (SCL_MOVED)
const TRACE = 8; // the backstop's sphere-tracing steps (SCL_TRACE)
const LOOSE = 0.007; // the backstop traces vertices whose attachment radius is at least this (SCL_LOOSE)
const OVERSHOOT = 0.001; // metres past the margin each tracing step aims (SCL_OVERSHOOT)
const REACH = 0.2; // metres: a backstop trace longer than this went through the torso: dropped (SCL_REACH)
const SPREAD = 40; // Jacobi sweeps spreading the traced moves (SCL_SPREAD)
const SPREAD_RADIUS = 0.2; // metres along the garment from a traced vertex that its move spreads to (SCL_SPREAD_RADIUS)
const AGREE = 0.5; // cosine: contact normals within 60 degrees are on the same side of the body (SCL_AGREE)

/** The cloth stage's knobs when none are given: segadeform.cloth_settings.ClothSettings' defaults. */
export const DEFAULT_CLOTH = Object.freeze({
  iterations: 4, stiffness: 1.0, stretch: 0.03, compress: 0.3, bending: 0.9, damping: 0.1, follow: 0.5, gravity: 9.81,
  attachment: 0.02, max_distance: 0.05, reset: 0.25, backstop: 0.03,
});

/** knob -> [integer?, lowest, highest] (segadeform.cloth_settings.CLOTH_KNOBS) */
const KNOBS = {
  iterations: [true, 1, 64], stiffness: [false, 0, 1], stretch: [false, 0, 1], compress: [false, 0, 1],
  bending: [false, 0, 1], damping: [false, 0, 1], follow: [false, 0, 1], gravity: [false, 0, 100],
  attachment: [false, 0, 1], max_distance: [false, 0, 1], reset: [false, 1e-6, 1e3], backstop: [false, 0, 1],
};

/** One knob's value checked (finite, in range, iterations an integer); `shown`: what the error quotes. */
function checkKnob(name, v, shown = String(v)) {
  const [int, lo, hi] = KNOBS[name];
  if (!(typeof v === "number" && Number.isFinite(v) && v >= lo && v <= hi && (!int || Number.isInteger(v)))) {
    throw new Error(`cloth ${name} must be ${int ? "an integer" : "a number"} in [${lo}, ${hi}] (got ${shown})`);
  }
}

/** The knobs from "NAME=VALUE,..." over `base` (DEFAULT_CLOTH), checked as ClothSettings checks them. */
export function parseCloth(text, base = DEFAULT_CLOTH) {
  const out = { ...base };
  for (const item of String(text || "").split(",").map((s) => s.trim()).filter(Boolean)) {
    const [name, value] = item.split("=").map((s) => s.trim());
    if (!(name in KNOBS) || value === undefined) {
      throw new Error(`unknown cloth setting (expected NAME=VALUE with NAME one of ${Object.keys(KNOBS).join(", ")}, got '${item}')`);
    }
    // the text as typed in the error: Number("abc") is NaN, and Number("") is 0
    checkKnob(name, value === "" ? NaN : Number(value), `'${value}'`);
    out[name] = Number(value);
  }
  return checkCloth(out);
}

/** Check every knob (finite, in range, iterations an integer); returns the settings. */
export function checkCloth(s) {
  for (const name of Object.keys(KNOBS)) checkKnob(name, s[name]);
  return s;
}

// ---- per garment ---------------------------------------------------------------------------------------------
/**
 * The per-garment data (scl_setup) from the rest garment rest (N*3, Float64Array), faces (F*3 indices) and each
 * vertex's signed distance from the body at rest restSd (N): { edges (Int32Array 2E, a < b, sorted by (a, b)),
 * restLen (E), nptr (Int32Array N + 1), nidx (Int32Array 2E: each vertex's neighbours, ascending), radius (N),
 * anchor (Int32Array N: each free vertex's tether anchor, -1 for none), tether (N: its path's rest length), faces
 * (Int32Array 3F: the garment's faces, the backstop's normals through weld), weld (Int32Array N: the lowest index of
 * the vertices at exactly each one's rest position: a seam's two sides are one point of cloth, the C file's scl_weld) }.
 * The edges are those of the faces through weld.
 */
export function clothSetup(rest, faces, restSd, attachment, maxDistance) {
  const n = Math.floor(rest.length / 3), nf = Math.floor(faces.length / 3);
  for (let i = 0; i < 3 * nf; i++) {
    if (!(faces[i] >= 0 && faces[i] < n)) throw new Error(`garment face index out of range (expected 0..${n - 1}, got ${faces[i]})`);
  }
  const weld = weldOf(rest, n);
  // the distinct edges (a < b) sorted by (a, b): the C file's qsort of pairs, as one sort of keys a * n + b
  const keys = new Float64Array(3 * nf);
  let ne = 0;
  for (let i = 0; i < nf; i++) {
    for (let k = 0; k < 3; k++) {
      const x = weld[faces[3 * i + k]], y = weld[faces[3 * i + (k + 1) % 3]];
      if (x === y) continue;
      keys[ne++] = x < y ? x * n + y : y * n + x;
    }
  }
  const sorted = keys.subarray(0, ne).sort();
  let m = 0;
  for (let i = 0; i < ne; i++) if (m === 0 || sorted[i] !== sorted[m - 1]) sorted[m++] = sorted[i];
  ne = m;
  const edges = new Int32Array(2 * ne), restLen = new Float64Array(ne);
  for (let i = 0; i < ne; i++) {
    const a = Math.floor(sorted[i] / n), b = sorted[i] - a * n;
    const dx = rest[3 * b] - rest[3 * a], dy = rest[3 * b + 1] - rest[3 * a + 1], dz = rest[3 * b + 2] - rest[3 * a + 2];
    edges[2 * i] = a;
    edges[2 * i + 1] = b;
    restLen[i] = Math.sqrt(dx * dx + dy * dy + dz * dz);
  }
  const nptr = new Int32Array(n + 1), nidx = new Int32Array(2 * ne);
  for (let i = 0; i < ne; i++) {
    nptr[edges[2 * i] + 1]++;
    nptr[edges[2 * i + 1] + 1]++;
  }
  for (let i = 0; i < n; i++) nptr[i + 1] += nptr[i];
  const fill = nptr.slice(0, n);
  // edges sorted by (a, b): a vertex meets its smaller neighbours (as b) before its larger ones (as a)
  for (let i = 0; i < ne; i++) {
    nidx[fill[edges[2 * i]]++] = edges[2 * i + 1];
    nidx[fill[edges[2 * i + 1]]++] = edges[2 * i];
  }
  const radius = new Float64Array(n);
  for (let i = 0; i < n; i++) {
    const d = restSd[i] - attachment;
    radius[i] = d > 0 ? (d < maxDistance ? d : maxDistance) : 0.0;
  }
  const { anchor, tether } = tethers(rest, n, nptr, nidx, radius);
  return { edges, restLen, nptr, nidx, radius, anchor, tether, faces: Int32Array.from(faces), weld, n, ne, nf };
}

/* Each vertex's weld (the C file's scl_weld): the lowest index of the vertices at exactly its rest position. */
function weldOf(rest, n) {
  const order = new Int32Array(n);
  for (let i = 0; i < n; i++) order[i] = i;
  order.sort((i, j) => {
    for (let c = 0; c < 3; c++) {
      const a = rest[3 * i + c], b = rest[3 * j + c];
      if (a !== b) return a < b ? -1 : 1;
    }
    return i - j;
  });
  const weld = new Int32Array(n);
  let first = 0;
  for (let k = 0; k < n; k++) {
    const i = order[k], p = order[first];
    if (k > 0 && !(rest[3 * i] === rest[3 * p] && rest[3 * i + 1] === rest[3 * p + 1] && rest[3 * i + 2] === rest[3 * p + 2])) first = k;
    weld[i] = order[first];
  }
  return weld;
}

/* the heap's order: by distance, then by vertex (a total order: every heap pops the same sequence) */
function itemLess(hd, hv, i, d, v) { return hd[i] < d || (hd[i] === d && hv[i] < v); }

function heapPush(h, d, v) {
  let c = h.len++;
  while (c > 0) {
    const up = (c - 1) >> 1;
    if (!(d < h.d[up] || (d === h.d[up] && v < h.v[up]))) break;
    h.d[c] = h.d[up];
    h.v[c] = h.v[up];
    c = up;
  }
  h.d[c] = d;
  h.v[c] = v;
}

function heapPop(h) {
  const topD = h.d[0], topV = h.v[0];
  h.len--;
  const lastD = h.d[h.len], lastV = h.v[h.len];
  let c = 0;
  for (;;) {
    const l = 2 * c + 1, r = l + 1;
    let s = c, bd = lastD, bv = lastV;
    if (l < h.len && itemLess(h.d, h.v, l, bd, bv)) { s = l; bd = h.d[l]; bv = h.v[l]; }
    if (r < h.len && itemLess(h.d, h.v, r, bd, bv)) s = r;
    if (s === c) break;
    h.d[c] = h.d[s];
    h.v[c] = h.v[s];
    c = s;
  }
  if (h.len > 0) {
    h.d[c] = lastD;
    h.v[c] = lastV;
  }
  return [topD, topV];
}

/* The tethers (scl_tethers): Dijkstra from every attached vertex at once over the edges' rest lengths, a vertex
 * settled in (distance, index) order; a neighbour takes the settled vertex's anchor when its path is shorter, or as
 * short with a smaller anchor. */
function tethers(rest, n, nptr, nidx, radius) {
  const cap = n + nptr[n];
  const h = { d: new Float64Array(cap), v: new Int32Array(cap), len: 0 };
  const done = new Uint8Array(n), anchor = new Int32Array(n), tether = new Float64Array(n);
  for (let i = 0; i < n; i++) {
    anchor[i] = radius[i] > 0 ? -1 : i;
    if (anchor[i] >= 0) heapPush(h, 0.0, i);
  }
  while (h.len > 0) {
    const [d, v] = heapPop(h);
    if (done[v] || d > tether[v]) continue; // settled, or a longer path found before a shorter one
    done[v] = 1;
    for (let j = nptr[v]; j < nptr[v + 1]; j++) {
      const w = nidx[j], a = v < w ? v : w, b = v < w ? w : v;
      if (done[w]) continue;
      const dx = rest[3 * b] - rest[3 * a], dy = rest[3 * b + 1] - rest[3 * a + 1], dz = rest[3 * b + 2] - rest[3 * a + 2];
      const c = d + Math.sqrt(dx * dx + dy * dy + dz * dz);
      if (anchor[w] < 0 || c < tether[w]) {
        tether[w] = c;
        anchor[w] = anchor[v];
        heapPush(h, c, w);
      } else if (c === tether[w] && anchor[v] < anchor[w]) {
        anchor[w] = anchor[v];
      }
    }
  }
  for (let i = 0; i < n; i++) if (!(radius[i] > 0)) anchor[i] = -1; // attached: no tether (its distance is 0)
  return { anchor, tether };
}

// ---- per frame -----------------------------------------------------------------------------------------------
/** The per-sweep stiffness that gives k after `sweeps` sweeps, by bisection with products only (scl_per_sweep). */
export function perSweep(k, sweeps) {
  if (!(k > 0)) return 0.0;
  if (k >= 1 || sweeps <= 1) return k >= 1 ? 1.0 : k;
  let lo = 0.0, hi = 1.0;
  for (let s = 0; s < 64; s++) {
    const mid = 0.5 * (lo + hi);
    let q = 1.0;
    for (let j = 0; j < sweeps; j++) q *= 1.0 - mid;
    if (1.0 - q < k) lo = mid; else hi = mid;
  }
  return 0.5 * (lo + hi);
}

function allFinite(a, off, n) {
  for (let i = off; i < off + n; i++) if (!(a[i] - a[i] === 0)) return false; // NaN and inf give NaN
  return true;
}

/* Keep x[ix..] within r of y[iy..] (r = 0: x = y). */
function attach(x, ix, y, iy, r) {
  const e0 = x[ix] - y[iy], e1 = x[ix + 1] - y[iy + 1], e2 = x[ix + 2] - y[iy + 2], l2 = e0 * e0 + e1 * e1 + e2 * e2;
  if (l2 > r * r) {
    const s = r > 0 ? r / Math.sqrt(l2) : 0.0;
    x[ix] = y[iy] + s * e0;
    x[ix + 1] = y[iy + 1] + s * e1;
    x[ix + 2] = y[iy + 2] + s * e2;
  }
}

/* One edge's strain limit: move the free ends of edge e along it (x at offset xo); `held` (optional, the settling
 * after the push-out: scl_step's settle_edge): ends that do not move either. */
function stretchEdge(x, xo, edges, restLen, radius, e, loF, hiF, k, held) {
  const a = edges[2 * e], b = edges[2 * e + 1];
  const p = xo + 3 * a, q = xo + 3 * b;
  const wa = radius[a] > 0 && !(held && held[a]) ? 1.0 : 0.0, wb = radius[b] > 0 && !(held && held[b]) ? 1.0 : 0.0;
  if (wa + wb === 0) return;
  const d0 = x[q] - x[p], d1 = x[q + 1] - x[p + 1], d2 = x[q + 2] - x[p + 2];
  const l2 = d0 * d0 + d1 * d1 + d2 * d2;
  const hi = hiF * restLen[e], lo = loF * restLen[e];
  if (l2 <= hi * hi && l2 >= lo * lo) return; // within the limits (most edges): no square root
  const len = Math.sqrt(l2);
  if (len < TINY) return; // no direction: left to the other constraints
  const c = l2 > hi * hi ? len - hi : len - lo; // the side decided as above (the root may round onto hi)
  const s = k * c / (len * (wa + wb));
  x[p] += wa * s * d0;
  x[p + 1] += wa * s * d1;
  x[p + 2] += wa * s * d2;
  x[q] -= wb * s * d0;
  x[q + 1] -= wb * s * d1;
  x[q + 2] -= wb * s * d2;
}

/* Whether vertex i at x may be inside the body or closer than the margin (scl_step's may_be_near): in contact or
 * found inside (sd, at xc), or farther from xc than its clearance. */
function mayBeNear(x, xc, sd, i, margin, band) {
  const d0 = x[3 * i] - xc[3 * i], d1 = x[3 * i + 1] - xc[3 * i + 1], d2 = x[3 * i + 2] - xc[3 * i + 2];
  const clear = (sd[i] < margin + band ? sd[i] : margin + band) - margin;
  return !(clear > 0) || sd[i] < margin + band || d0 * d0 + d1 * d1 + d2 * d2 >= clear * clear;
}

/* Vertex i appended to the push-out's list (scl_step's pick_vertex); returns the list's new length. */
function pickVertex(x, i, q, pick, moved, m) {
  pick[m] = i;
  q[3 * m] = x[3 * i];
  q[3 * m + 1] = x[3 * i + 1];
  q[3 * m + 2] = x[3 * i + 2];
  moved[m] = 0;
  return m + 1;
}

/* The attachment in the settling after the push-out (scl_step's settle_attach): x within r of its target y, or within
 * the distance from y at which the sweeps and the push-out left it (x0) if that is farther; all at offset p. */
function settleAttach(x, y, x0, p, r) {
  const e0 = x[p] - y[p], e1 = x[p + 1] - y[p + 1], e2 = x[p + 2] - y[p + 2], l2 = e0 * e0 + e1 * e1 + e2 * e2;
  const f0 = x0[p] - y[p], f1 = x0[p + 1] - y[p + 1], f2 = x0[p + 2] - y[p + 2], m2 = f0 * f0 + f1 * f1 + f2 * f2;
  if (l2 <= r * r || l2 <= m2) return;
  const s = (r * r >= m2 ? r : Math.sqrt(m2)) / Math.sqrt(l2);
  x[p] = y[p] + s * e0;
  x[p + 1] = y[p + 1] + s * e1;
  x[p + 2] = y[p + 2] + s * e2;
}

/* One free vertex's tether: pulled toward its anchor when farther from it than hiF times the tether's rest length. */
function tetherVertex(x, xo, anchor, tether, i, hiF, k) {
  const a = anchor[i];
  if (a < 0) return;
  const p = xo + 3 * i, o = xo + 3 * a, lim = hiF * tether[i];
  const d0 = x[p] - x[o], d1 = x[p + 1] - x[o + 1], d2 = x[p + 2] - x[o + 2];
  const l2 = d0 * d0 + d1 * d1 + d2 * d2;
  if (l2 <= lim * lim) return; // within (most vertices): no square root
  const s = k * (1.0 - lim / Math.sqrt(l2));
  x[p] -= s * d0;
  x[p + 1] -= s * d1;
  x[p + 2] -= s * d2;
}

/* One vertex's smoothing: its deviation from the target moved toward its neighbours' mean deviation. */
function smoothVertex(x, xo, y, yo, nptr, nidx, radius, i, k) {
  const deg = nptr[i + 1] - nptr[i];
  if (deg === 0 || !(radius[i] > 0)) return;
  let m0 = 0, m1 = 0, m2 = 0;
  for (let j = nptr[i]; j < nptr[i + 1]; j++) {
    const v = nidx[j];
    m0 += x[xo + 3 * v] - y[yo + 3 * v];
    m1 += x[xo + 3 * v + 1] - y[yo + 3 * v + 1];
    m2 += x[xo + 3 * v + 2] - y[yo + 3 * v + 2];
  }
  m0 /= deg;
  m1 /= deg;
  m2 /= deg;
  const p = xo + 3 * i, t = yo + 3 * i;
  x[p] += k * (m0 - (x[p] - y[t]));
  x[p + 1] += k * (m1 - (x[p + 1] - y[t + 1]));
  x[p + 2] += k * (m2 - (x[p + 2] - y[t + 2]));
}

/* u . v for the 3-vectors at offsets i of u and j of v, summed left to right (dot3 in _cloth.c). */
function dot3(u, i, v, j) {
  return u[i] * v[j] + u[i + 1] * v[j + 1] + u[i + 2] * v[j + 2];
}

/* Whether edge e gets a contact plane at its middle (1 or 0): an end in contact (sd within `near`) and an end free; or
 * both ends attached, both in contact, on the same side of the body (their contact normals cn within AGREE), where the
 * body may bulge into the middle by more than the ends' room and a quarter of the margin (edge_near in _cloth.c). */
function edgeNear(edges, e, x, sd, cn, radius, margin, near) {
  const a = edges[2 * e], b = edges[2 * e + 1];
  if (radius[a] > 0 || radius[b] > 0) return sd[a] < near || sd[b] < near ? 1 : 0;
  if (!(sd[a] < near && sd[b] < near)) return 0;
  const c = dot3(cn, 3 * a, cn, 3 * b);
  if (!(c > AGREE)) return 0;
  const d0 = x[3 * b] - x[3 * a], d1 = x[3 * b + 1] - x[3 * a + 1], d2 = x[3 * b + 2] - x[3 * a + 2];
  const room = 0.5 * ((sd[a] > margin ? sd[a] : margin) + (sd[b] > margin ? sd[b] : margin)) - margin + 0.25 * margin;
  return 0.25 * (d0 * d0 + d1 * d1 + d2 * d2) * (1.0 - c) > room * room * (1.0 + c) ? 1 : 0;
}

/* Whether the middle's contact normal (n at offset k) agrees with both ends' (edge_agrees in _cloth.c). */
function edgeAgrees(edges, e, cn, radius, n, k) {
  const a = edges[2 * e], b = edges[2 * e + 1];
  if (radius[a] > 0 || radius[b] > 0) return true;
  return dot3(n, k, cn, 3 * a) > AGREE && dot3(n, k, cn, 3 * b) > AGREE;
}

/* One edge's contact: both ends of edge e moved alike along the plane's normal until the edge's middle is margin
 * outside the plane (when the middle was found within margin + band of the body). */
function edgeContact(x, edges, e, sd, cp, cn, k, margin, band) {
  if (!(sd[k] < margin + band) || sd[k] < -EDGE_DEEP) return;
  const a = 3 * edges[2 * e], b = 3 * edges[2 * e + 1], c = 3 * k;
  const s = cn[c] * (0.5 * (x[a] + x[b]) - cp[c]) + cn[c + 1] * (0.5 * (x[a + 1] + x[b + 1]) - cp[c + 1]) +
    cn[c + 2] * (0.5 * (x[a + 2] + x[b + 2]) - cp[c + 2]) - margin;
  if (s < 0) {
    x[a] -= s * cn[c];
    x[a + 1] -= s * cn[c + 1];
    x[a + 2] -= s * cn[c + 2];
    x[b] -= s * cn[c];
    x[b + 1] -= s * cn[c + 1];
    x[b + 2] -= s * cn[c + 2];
  }
}

/*
 * The backstop (backstop in _cloth.c): when a loose vertex's target y (radius >= LOOSE) is deeper than `deep` inside
 * the body and its prediction x inside (sd, from the frame's contacts with normals cn), the deep targets traced out along the
 * garment's outward normal, the moves spread over the free vertices near them (attached ones keep theirs: 0);
 * yt = y + the spread move and x moved alike.  w: the stage's buffers.  Returns how many vertices were
 * traced out (0: yt and x are untouched).
 */
function backstop(col, bv, box, n, nf, faces, weld, nptr, nidx, radius, y, x, sd, cn, margin, band, deep, w) {
  let nd = 0, nt = 0, vote = 0;
  if (!(deep > 0)) return 0; // off
  // the loose vertices whose target is deeper than `deep` inside and whose prediction is inside: the network's depth
  // decides, not the prediction's (which follows the frame before's output: deep one frame, traced out, shallow the
  // next and left to its closest exit on the other side of the limb)
  for (let i = 0; i < n; i++) {
    if (radius[i] >= LOOSE) {
      w.deep[nd] = i;
      w.pts[3 * nd] = y[3 * i];
      w.pts[3 * nd + 1] = y[3 * i + 1];
      w.pts[3 * nd + 2] = y[3 * i + 2];
      nd++;
    }
  }
  if (nd === 0) return 0;
  col.near(bv, box, w.pts, 0, nd, 0.0, w.tsd, w.tcp, w.tcn);
  const nl = nd;
  nd = 0;
  for (let j = 0; j < nl; j++) if (w.tsd[j] < -deep && sd[w.deep[j]] < 0) w.deep[nd++] = w.deep[j];
  if (nd === 0) return 0;
  // the target's vertex normals (area-weighted face normals) and their orientation: outward where the vertices just
  // outside the body agree with the body's normal
  const vn = w.vn;
  vn.fill(0);
  for (let j = 0; j < nf; j++) {
    const a = 3 * weld[faces[3 * j]], b = 3 * weld[faces[3 * j + 1]], c = 3 * weld[faces[3 * j + 2]];
    const u0 = y[b] - y[a], u1 = y[b + 1] - y[a + 1], u2 = y[b + 2] - y[a + 2];
    const v0 = y[c] - y[a], v1 = y[c + 1] - y[a + 1], v2 = y[c + 2] - y[a + 2];
    const f0 = u1 * v2 - u2 * v1, f1 = u2 * v0 - u0 * v2, f2 = u0 * v1 - u1 * v0;
    for (const k of [a, b, c]) {
      vn[k] += f0;
      vn[k + 1] += f1;
      vn[k + 2] += f2;
    }
  }
  for (let i = 0; i < n; i++) {
    if (sd[i] >= 0 && sd[i] < margin + band) vote += vn[3 * i] * cn[3 * i] + vn[3 * i + 1] * cn[3 * i + 1] + vn[3 * i + 2] * cn[3 * i + 2];
  }
  const sign = vote < 0 ? -1.0 : 1.0;
  const { g, pts, fixed, tsd, tcp, tcn } = w;
  // sphere-trace each deep target along its unit outward normal
  for (let j = 0; j < nd; j++) {
    const q = 3 * w.deep[j];
    const l2 = vn[q] * vn[q] + vn[q + 1] * vn[q + 1] + vn[q + 2] * vn[q + 2], s = l2 > TINY ? sign / Math.sqrt(l2) : 0.0;
    g[3 * j] = s * vn[q];
    g[3 * j + 1] = s * vn[q + 1];
    g[3 * j + 2] = s * vn[q + 2];
    pts[3 * j] = y[q];
    pts[3 * j + 1] = y[q + 1];
    pts[3 * j + 2] = y[q + 2];
    fixed[j] = 0; // 1 once traced out of the body
  }
  let k = 0;
  for (; k < TRACE; k++) {
    let left = 0;
    col.near(bv, box, pts, 0, nd, margin, tsd, tcp, tcn, true);
    for (let j = 0; j < nd; j++) {
      if (fixed[j]) continue;
      if (tsd[j] >= margin) {
        fixed[j] = 1;
        continue;
      }
      const step = margin - tsd[j] + OVERSHOOT;
      pts[3 * j] += step * g[3 * j];
      pts[3 * j + 1] += step * g[3 * j + 1];
      pts[3 * j + 2] += step * g[3 * j + 2];
      left++;
    }
    if (left === 0) break;
  }
  if (k === TRACE) { // the last step's points: out or not
    col.near(bv, box, pts, 0, nd, margin, tsd, tcp, tcn, true);
    for (let j = 0; j < nd; j++) if (tsd[j] >= margin) fixed[j] = 1;
  }
  // a trace longer than REACH went through the torso, not out of a limb: dropped
  for (let j = 0; j < nd; j++) {
    const t = 3 * j, o = 3 * w.deep[j];
    const e0 = pts[t] - y[o], e1 = pts[t + 1] - y[o + 1], e2 = pts[t + 2] - y[o + 2];
    if (fixed[j] && e0 * e0 + e1 * e1 + e2 * e2 > REACH * REACH) fixed[j] = 0;
  }
  // the moves of the traced-out ones (with a normal), held; spread to the others
  const d = w.d, d2 = w.d2;
  const held = w.held;
  d.fill(0);
  held.fill(0);
  for (let j = 0; j < nd; j++) {
    if (!fixed[j] || (g[3 * j] === 0 && g[3 * j + 1] === 0 && g[3 * j + 2] === 0)) continue;
    const i = 3 * w.deep[j];
    d[i] = pts[3 * j] - y[i];
    d[i + 1] = pts[3 * j + 1] - y[i + 1];
    d[i + 2] = pts[3 * j + 2] - y[i + 2];
    held[w.deep[j]] = 1;
    nt++;
  }
  if (nt === 0) return 0;
  // the region the moves spread over: the vertices within SPREAD_RADIUS of a held one along the target's edges
  // (Dijkstra from every held vertex at once); outside it the move is 0
  const { dist, done, region, heap } = w;
  heap.len = 0;
  for (let i = 0; i < n; i++) {
    dist[i] = held[i] ? 0.0 : Infinity;
    done[i] = 0;
    if (held[i]) heapPush(heap, 0.0, i);
  }
  let nr = 0;
  while (heap.len > 0) {
    const [dv, v] = heapPop(heap);
    if (done[v] || dv > dist[v]) continue;
    done[v] = 1;
    if (!held[v] && radius[v] > 0 && nptr[v + 1] > nptr[v]) region[nr++] = v;
    for (let j = nptr[v]; j < nptr[v + 1]; j++) {
      const u = nidx[j];
      const e0 = y[3 * u] - y[3 * v], e1 = y[3 * u + 1] - y[3 * v + 1], e2 = y[3 * u + 2] - y[3 * v + 2];
      const c = dv + Math.sqrt(e0 * e0 + e1 * e1 + e2 * e2);
      if (done[u] || !(c <= SPREAD_RADIUS) || !(c < dist[u])) continue;
      dist[u] = c;
      heapPush(heap, c, u);
    }
  }
  w.nr = nr;
  // Jacobi sweeps over the region: each move the mean of its neighbours' (held ones and those outside fixed)
  for (let s = 0; s < SPREAD; s++) {
    for (let r = 0; r < nr; r++) {
      const i = region[r], deg = nptr[i + 1] - nptr[i];
      let m0 = 0, m1 = 0, m2 = 0;
      for (let j = nptr[i]; j < nptr[i + 1]; j++) {
        m0 += d[3 * nidx[j]];
        m1 += d[3 * nidx[j] + 1];
        m2 += d[3 * nidx[j] + 2];
      }
      d2[3 * r] = m0 / deg;
      d2[3 * r + 1] = m1 / deg;
      d2[3 * r + 2] = m2 / deg;
    }
    for (let r = 0; r < nr; r++) {
      const i = region[r];
      d[3 * i] = d2[3 * r];
      d[3 * i + 1] = d2[3 * r + 1];
      d[3 * i + 2] = d2[3 * r + 2];
    }
  }
  for (let i = 0; i < 3 * n; i++) {
    w.yt[i] = y[i] + d[i];
    x[i] += d[i];
  }
  return nt;
}

/**
 * The cloth stage for one garment on one body, keeping its state between calls (scl_step):
 *   new ClothStage(setup (clothSetup), collider (a BodyCollider over the body's faces), settings, { margin, dt })
 *   stage.step(targets (B*N*3), body (B*V*3), B) -> Float64Array (B*N*3)
 * Counters: frames, resets (the state reset because the garment jumped more than settings.reset on average),
 * contacts (vertex-frames given a contact plane), pushed (vertex-frames moved by the final push-out, more than 1 um),
 * traced (vertex-frames whose deep target the backstop traced out of the body).
 */
export class ClothStage {
  constructor(setup, collider, settings = DEFAULT_CLOTH, { margin = 0.004, dt = 1 / 30 } = {}) {
    checkCloth(settings);
    if (!(Number.isFinite(margin) && margin >= 0 && margin < 1)) throw new Error(`the collision margin must be in [0, 1) metres (got ${margin})`);
    if (!(Number.isFinite(dt) && dt > 0 && dt <= 10)) throw new Error(`the time step must be in (0, 10] seconds (got ${dt})`);
    this.setup = setup;
    this.collider = collider;
    this.settings = settings;
    this.margin = margin;
    this.dt = dt;
    const n = setup.n;
    this.state = new Float64Array(9 * n); // the last output, the one before it, the last target
    this.have = 0;
    this.resets = 0;
    this.contacts = 0;
    this.pushed = 0;
    this.traced = 0;
    this.frames = 0;
    this.firstReset = -1; // the first frame (counted from the stage's start) that reset the state
    this.box = new Float64Array(6 * collider.nNodes);
    this.sd = new Float64Array(n);
    this.cp = new Float64Array(3 * n);
    this.cn = new Float64Array(3 * n);
    this.q = new Float64Array(3 * n);
    this.xc = new Float64Array(3 * n); // the positions the contacts were found at
    this.pick = new Int32Array(n);
    this.moved = new Uint8Array(n);
    this.held = new Uint8Array(n); // moved by this frame's final push-out: held by the settling
    this.work = { // the backstop's buffers
      vn: new Float64Array(3 * n), d: new Float64Array(3 * n), d2: new Float64Array(3 * n), yt: new Float64Array(3 * n),
      pts: new Float64Array(3 * n), g: new Float64Array(3 * n), tsd: new Float64Array(n), tcp: new Float64Array(3 * n),
      tcn: new Float64Array(3 * n), deep: new Int32Array(n), fixed: new Uint8Array(n), held: new Uint8Array(n),
      dist: new Float64Array(n), done: new Uint8Array(n), region: new Int32Array(n),
      heap: { d: new Float64Array(n + setup.nptr[n]), v: new Int32Array(n + setup.nptr[n]), len: 0 },
    };
    this.growEdges(0); // the edge contacts' buffers, grown to the most edges near the body in one frame
  }

  growEdges(count) {
    const c = Math.max(count, 1);
    this.eidx = new Int32Array(c);
    this.mid = new Float64Array(3 * c);
    this.esd = new Float64Array(c);
    this.ecp = new Float64Array(3 * c);
    this.ecn = new Float64Array(3 * c);
  }

  step(target, body, nb) {
    const { n, ne, nf, faces, edges, restLen, nptr, nidx, radius, anchor, tether, weld } = this.setup;
    const nv = this.collider.nv, st = this.settings, col = this.collider;
    if (target.length !== nb * n * 3 || body.length !== nb * nv * 3) {
      throw new Error(`the cloth stage takes ${nb} frames of ${n} garment and ${nv} body vertices (got ${target.length} ` +
        `and ${body.length} coordinates)`);
    }
    const iters = st.iterations < 1 ? 1 : st.iterations;
    const ks = perSweep(st.stiffness, iters), kb = perSweep(st.bending, iters);
    const hiF = 1.0 + st.stretch, loF = 1.0 - st.compress;
    const keep = 1.0 - st.damping, drop = st.gravity * this.dt * this.dt;
    const margin = this.margin, reset = st.reset, band = CONTACT_BAND, follow = st.follow;
    const S = this.state, x1 = 0, x0 = 3 * n, yp = 6 * n;
    const { box, sd, cp, cn, q, xc, pick, moved, held } = this;
    const y = target instanceof Float64Array ? target : new Float64Array(target);
    const B = body instanceof Float64Array ? body : new Float64Array(body);
    const out = new Float64Array(nb * n * 3);
    // every frame checked before any is stepped (as scl_step does): a refused call leaves the state as it was
    for (let f = 0; f < nb; f++) {
      if (!allFinite(y, 3 * n * f, 3 * n) || !allFinite(B, 3 * nv * f, 3 * nv)) {
        throw new Error(`the cloth stage got NaN or inf at frame ${this.frames + f} (expected finite coordinates from ` +
          "the deformer and the body)");
      }
    }
    for (let f = 0; f < nb; f++) {
      const yo = 3 * n * f, xo = 3 * n * f, bo = 3 * nv * f;
      let have = this.have;
      if (have > 0) { // a teleport: the target moved more than `reset` on average
        let s = 0;
        for (let i = 0; i < n; i++) {
          const d0 = y[yo + 3 * i] - S[yp + 3 * i], d1 = y[yo + 3 * i + 1] - S[yp + 3 * i + 1],
            d2 = y[yo + 3 * i + 2] - S[yp + 3 * i + 2];
          s += Math.sqrt(d0 * d0 + d1 * d1 + d2 * d2);
        }
        if (!(s / n <= reset)) {
          have = 0;
          this.resets++;
          if (this.firstReset < 0) this.firstReset = this.frames + f;
        }
      }
      // predict: inertia and gravity from the previous outputs, within the attachment
      for (let i = 0; i < n; i++) {
        const p = xo + 3 * i, t = yo + 3 * i;
        if (have === 0) {
          out[p] = y[t];
          out[p + 1] = y[t + 1];
          out[p + 2] = y[t + 2];
        } else {
          let v0 = 0, v1 = 0, v2 = 0;
          if (have >= 2) {
            v0 = S[x1 + 3 * i] - S[x0 + 3 * i];
            v1 = S[x1 + 3 * i + 1] - S[x0 + 3 * i + 1];
            v2 = S[x1 + 3 * i + 2] - S[x0 + 3 * i + 2];
          }
          out[p] = S[x1 + 3 * i] + keep * v0;
          out[p + 1] = S[x1 + 3 * i + 1] + keep * v1 - drop;
          out[p + 2] = S[x1 + 3 * i + 2] + keep * v2;
          out[p] += follow * (y[t] - out[p]);
          out[p + 1] += follow * (y[t + 1] - out[p + 1]);
          out[p + 2] += follow * (y[t + 2] - out[p + 2]);
        }
        attach(out, p, y, t, radius[i]);
      }
      // contacts: a plane for every vertex inside the body or near it
      const bv = B.subarray(bo, bo + 3 * nv), x = out.subarray(xo, xo + 3 * n), yr = y.subarray(yo, yo + 3 * n);
      col.refitInto(bv, box);
      col.near(bv, box, x, 0, n, margin + band, sd, cp, cn);
      // deep targets: traced out along the garment's normal (the backstop), then the contacts found again
      let yf = yr;
      const nt = backstop(col, bv, box, n, nf, faces, weld, nptr, nidx, radius, yr, x, sd, cn, margin, band,
        st.backstop, this.work);
      if (nt > 0) { // only the vertices it moved (held and in the region) are looked up again
        const w = this.work;
        let nm = 0;
        this.traced += nt;
        yf = w.yt;
        for (let i = 0; i < n; i++) if (w.held[i]) w.deep[nm++] = i;
        for (let r = 0; r < w.nr; r++) w.deep[nm++] = w.region[r];
        for (let r = 0; r < nm; r++) {
          const i = 3 * w.deep[r];
          w.pts[3 * r] = x[i];
          w.pts[3 * r + 1] = x[i + 1];
          w.pts[3 * r + 2] = x[i + 2];
        }
        col.near(bv, box, w.pts, 0, nm, margin + band, w.tsd, w.tcp, w.tcn);
        for (let r = 0; r < nm; r++) {
          const i = w.deep[r];
          sd[i] = w.tsd[r];
          for (let c = 0; c < 3; c++) {
            cp[3 * i + c] = w.tcp[3 * r + c];
            cn[3 * i + c] = w.tcn[3 * r + c];
          }
        }
      }
      // and for the middle of every edge with an end in contact and a free end, or both ends attached, in contact and
      // agreeing (edgeNear; only those)
      let nec = 0;
      for (let e = 0; e < ne; e++) nec += edgeNear(edges, e, x, sd, cn, radius, margin, margin + band);
      if (nec > this.eidx.length) this.growEdges(nec);
      const { eidx, mid, esd, ecp, ecn } = this;
      nec = 0;
      for (let e = 0; e < ne; e++) {
        const a = 3 * edges[2 * e], b = 3 * edges[2 * e + 1];
        if (!edgeNear(edges, e, x, sd, cn, radius, margin, margin + band)) continue;
        eidx[nec] = e;
        mid[3 * nec] = 0.5 * (x[a] + x[b]);
        mid[3 * nec + 1] = 0.5 * (x[a + 1] + x[b + 1]);
        mid[3 * nec + 2] = 0.5 * (x[a + 2] + x[b + 2]);
        nec++;
      }
      if (nec > 0) col.near(bv, box, mid, 0, nec, margin + band, esd, ecp, ecn);
      for (let e = 0; e < nec; e++) if (!edgeAgrees(edges, eidx[e], cn, radius, ecn, 3 * e)) esd[e] = Infinity;
      xc.set(x);
      // the sweeps, alternating direction
      for (let it = 0; it < iters; it++) {
        const fwd = it % 2 === 0;
        for (let e = 0; e < ne; e++) stretchEdge(x, 0, edges, restLen, radius, fwd ? e : ne - 1 - e, loF, hiF, ks);
        if (ks > 0) for (let i = 0; i < n; i++) tetherVertex(x, 0, anchor, tether, i, hiF, ks);
        if (kb > 0) for (let i = 0; i < n; i++) smoothVertex(x, 0, yf, 0, nptr, nidx, radius, fwd ? i : n - 1 - i, kb);
        for (let i = 0; i < n; i++) {
          const p = 3 * i;
          attach(x, p, yf, p, radius[i]);
          if (!(sd[i] < margin + band)) continue;
          const s = cn[p] * (x[p] - cp[p]) + cn[p + 1] * (x[p + 1] - cp[p + 1]) + cn[p + 2] * (x[p + 2] - cp[p + 2]) - margin;
          if (s < 0) {
            x[p] -= s * cn[p];
            x[p + 1] -= s * cn[p + 1];
            x[p + 2] -= s * cn[p + 2];
          }
        }
        for (let k = 0; k < nec; k++) edgeContact(x, edges, eidx[k], esd, ecp, ecn, k, margin, band);
      }
      // the exact push-out of every vertex that may be inside or closer than the margin: those found inside or
      // within it, those in contact (one may be inside the torso by a buried arm's skin, which only the push-out's
      // rule for buried skin tells), and those that moved farther than their clearance since the contacts were found
      let m = 0;
      for (let i = 0; i < n; i++) {
        if (sd[i] < margin + band) this.contacts++;
        if (mayBeNear(x, xc, sd, i, margin, band)) m = pickVertex(x, i, q, pick, moved, m);
      }
      let npushed = 0;
      held.fill(0);
      if (m > 0) {
        col.pushOutFrame(bv, box, q, 0, m, margin, PASSES, moved);
        for (let i = 0; i < m; i++) {
          const p = 3 * pick[i], d0 = q[3 * i] - x[p], d1 = q[3 * i + 1] - x[p + 1], d2 = q[3 * i + 2] - x[p + 2];
          if (d0 * d0 + d1 * d1 + d2 * d2 > MOVED * MOVED) {
            held[pick[i]] = 1;
            npushed++;
          }
          x[p] = q[3 * i];
          x[p + 1] = q[3 * i + 1];
          x[p + 2] = q[3 * i + 2];
        }
        this.pushed += npushed;
      }
      // settling: when the push-out moved a vertex, the stretch limits and attachment again (no contact planes) with
      // the vertices it moved held, then those these sweeps moved that may be inside or within the margin (the final
      // push-out's test, from where the contacts were found) pushed out again (scl_step)
      if (npushed > 0) {
        q.set(x);
        for (let it = 0; it < iters; it++) {
          const fwd = it % 2 === 0;
          for (let e = 0; e < ne; e++) {
            stretchEdge(x, 0, edges, restLen, radius, fwd ? e : ne - 1 - e, loF, hiF, ks, held);
          }
          for (let i = 0; i < n; i++) if (!held[i] && radius[i] > 0) settleAttach(x, yf, q, 3 * i, radius[i]);
        }
        m = 0;
        for (let i = 0; i < n; i++) {
          const d0 = x[3 * i] - q[3 * i], d1 = x[3 * i + 1] - q[3 * i + 1], d2 = x[3 * i + 2] - q[3 * i + 2];
          if (d0 * d0 + d1 * d1 + d2 * d2 > 0 && mayBeNear(x, xc, sd, i, margin, band)) {
            m = pickVertex(x, i, q, pick, moved, m);
          }
        }
        if (m > 0) {
          col.pushOutFrame(bv, box, q, 0, m, margin, PASSES, moved);
          for (let i = 0; i < m; i++) {
            const p = 3 * pick[i];
            x[p] = q[3 * i];
            x[p + 1] = q[3 * i + 1];
            x[p + 2] = q[3 * i + 2];
          }
        }
      }
      // a seam's sides: every vertex where its group's lowest one is (clothSetup's weld)
      for (let i = 0; i < n; i++) {
        const r = weld[i];
        if (r !== i) {
          x[3 * i] = x[3 * r];
          x[3 * i + 1] = x[3 * r + 1];
          x[3 * i + 2] = x[3 * r + 2];
        }
      }
      // the state: this frame, the one before, this target
      if (have === 0) S.set(x, x0);
      else S.copyWithin(x0, x1, x1 + 3 * n);
      S.set(x, x1);
      S.set(yr, yp);
      this.have = have === 0 ? 1 : 2;
    }
    this.frames += nb;
    return out;
  }
}

/**
 * The cloth stage for one garment on one body, ready to step: the collider built on the body at rest (`restBody`
 * V*3, `faces` F*3), each garment vertex's rest distance from it, and the per-garment set-up (clothSetup) of the
 * garment's rest shape `rest` (N*3) and `garmentFaces`: the Node and browser runtimes' Player starts it and poses
 * the body a batch of frames at a time (core.js Player).
 */
export function clothStart(restBody, faces, rest, garmentFaces, { settings = DEFAULT_CLOTH, margin = 0.004, dt = 1 / 30 } = {}) {
  const rb = new Float64Array(restBody), rg = new Float64Array(rest);
  const col = new BodyCollider(rb, faces);
  const restSd = col.query(rb, rg).signedDistance;
  const setup = clothSetup(rg, garmentFaces, restSd, settings.attachment, settings.max_distance);
  return new ClothStage(setup, col, settings, { margin, dt });
}

/** Frames lo..hi-1 of `frames` (T*N*3 float32, changed in place) through `stage`; `bodyBatch`: the posed body of
 * those frames ((hi - lo)*V*3).  With `trans` ((hi - lo)*3), frames and body are at the root and the stage steps
 * them at that translation, added in float64 (core.js atTranslation). */
export function clothStep(stage, frames, N, lo, hi, bodyBatch, trans = null) {
  const B = hi - lo, y = new Float64Array(frames.subarray(lo * N * 3, hi * N * 3)), b = new Float64Array(bodyBatch);
  if (trans) {
    const V = b.length / (3 * B);
    for (let f = 0; f < B; f++) {
      for (let c = 0; c < 3; c++) {
        const t = trans[3 * f + c];
        for (let i = 0; i < N; i++) y[(f * N + i) * 3 + c] += t;
        for (let i = 0; i < V; i++) b[(f * V + i) * 3 + c] += t;
      }
    }
  }
  const out = stage.step(y, b, B);
  frames.set(out, lo * N * 3); // float64 -> float32, rounded to nearest
}
