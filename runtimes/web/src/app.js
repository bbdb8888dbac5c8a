// The viewer page: run a garment asset (.sgda) and a motion (.sgdm) -- or a scene bundle -- through a model
// package (onnxruntime-web), with the body posed by the package's body graph, or play dropped OBJ + PC2 files,
// with three.js.  Query: ?garment=G.sgda&motion=M.sgdm (or ?bundle=URL) &package=URL&ep=wasm|webgpu&batch=8
// &effects=dqs,dynamics,wrinkles,collisions&margin=M (the collision margin, metres; 0.004) &frame=N&paused=1
// &check=VEC.sgdb (the Python runtime's frames, `expected` and `body`, to compare with) &body=BODY.pc2
// &bodyMesh=BODY.obj (a posed body from `segadeform run --body-out`).  Without `effects`: the model's own and
// collisions when the package has a body graph (the garment pushed out of the posed body, as `segadeform run`).
// &cloth=1 (or the stage's knobs, &cloth=iterations=8,stiffness=0.5) turns the cloth stage on, as the page's "cloth"
// switch does (it runs the scene again with the stage on or off).
// Dropping files works as well: a package's files or folder, a .sgda and a .sgdm, a .sgdb, OBJ + PC2.
import * as THREE from "three";
import { OrbitControls } from "three/addons/controls/OrbitControls.js";
import { defaultEffects, parseEffects, parseOBJ, parsePC2 } from "../../node/src/core.js";
import { animate, compareFrames, loadOrt, loadPackage, openContainer, packageFromFiles } from "./runtime.js";

const q = new URLSearchParams(location.search);
const statusEl = document.getElementById("status");
const clothSwitch = document.getElementById("cloth");
clothSwitch.checked = q.has("cloth") && q.get("cloth") !== "0";
let lastScene = null; // [source, expected] of the last run: what the cloth switch runs again
const say = (s) => { statusEl.textContent = s; };

// ---- the scene -------------------------------------------------------------------------------------
const renderer = new THREE.WebGLRenderer({ antialias: true, preserveDrawingBuffer: true });
renderer.setPixelRatio(window.devicePixelRatio);
document.getElementById("view").appendChild(renderer.domElement);
const scene = new THREE.Scene();
scene.background = new THREE.Color(0xf4f4f2);
const camera = new THREE.PerspectiveCamera(35, 1, 0.01, 100);
camera.position.set(1.6, 1.3, 2.6);
const controls = new OrbitControls(camera, renderer.domElement);
controls.target.set(0, 1.0, 0);
scene.add(new THREE.HemisphereLight(0xffffff, 0x808070, 1.6));
const sun = new THREE.DirectionalLight(0xffffff, 1.8);
sun.position.set(2, 4, 3);
scene.add(sun);
const grid = new THREE.GridHelper(4, 20, 0xbbbbbb, 0xdddddd);
scene.add(grid);
function resize() {
  const w = window.innerWidth, h = window.innerHeight;
  renderer.setSize(w, h);
  camera.aspect = w / h;
  camera.updateProjectionMatrix();
}
window.addEventListener("resize", resize);
resize();

// tracks: { mesh, frames (T*N*3), N }; every track plays the same frame index
const tracks = [];
let T = 0, frame = 0, playing = q.get("paused") !== "1", fps = 30, last = 0;
const slider = document.getElementById("frame"), fno = document.getElementById("fno"), playBtn = document.getElementById("play");

function addTrack(faces, frames, N, nFrames, color) {
  const g = new THREE.BufferGeometry();
  g.setAttribute("position", new THREE.BufferAttribute(new Float32Array(N * 3), 3));
  g.setIndex(new THREE.BufferAttribute(faces, 1));
  const m = new THREE.Mesh(g, new THREE.MeshStandardMaterial({ color, roughness: 0.8, side: THREE.DoubleSide }));
  scene.add(m);
  tracks.push({ mesh: m, frames, N });
  T = Math.max(T, nFrames);
  slider.max = String(Math.max(T - 1, 0));
  show(Math.min(frame, T - 1));
  frameCamera();
}

function show(t) {
  frame = t;
  for (const tr of tracks) {
    const n3 = tr.N * 3, k = Math.min(t, tr.frames.length / n3 - 1);
    const pos = tr.mesh.geometry.attributes.position;
    pos.array.set(tr.frames.subarray(k * n3, (k + 1) * n3));
    pos.needsUpdate = true;
    tr.mesh.geometry.computeVertexNormals();
    tr.mesh.geometry.computeBoundingSphere();
  }
  slider.value = String(t);
  fno.textContent = `${t} / ${Math.max(T - 1, 0)}`;
}

function frameCamera() {
  const box = new THREE.Box3();
  for (const tr of tracks) box.expandByObject(tr.mesh);
  if (box.isEmpty()) return;
  const c = box.getCenter(new THREE.Vector3()), size = box.getSize(new THREE.Vector3()).length();
  controls.target.copy(c);
  camera.position.copy(c).add(new THREE.Vector3(0.55, 0.3, 1.0).multiplyScalar(size * 1.45));
  grid.position.y = box.min.y;
  controls.update();
}

function loop(now) {
  if (playing && T > 1 && now - last > 1000 / fps) {
    show((frame + 1) % T);
    last = now;
  }
  controls.update();
  renderer.render(scene, camera);
  requestAnimationFrame(loop);
}
requestAnimationFrame(loop);
slider.addEventListener("input", () => show(+slider.value));
playBtn.addEventListener("click", () => { playing = !playing; playBtn.textContent = playing ? "pause" : "play"; });

// ---- a garment asset and a motion (or a scene bundle) through a model package ------------------------
let ort = null, pkg = null;
const ep = q.get("ep") || "wasm";

async function getOrt() {
  if (!ort) ort = await loadOrt(ep, new URL("../node_modules/onnxruntime-web/dist/", import.meta.url).href);
  return ort;
}

async function getPackage() {
  if (!pkg) {
    const url = q.get("package") || "../../samples/models/default/";
    say(`loading ${url} ...`);
    pkg = await loadPackage(url);
  }
  return pkg;
}

function clearTracks() {
  for (const tr of tracks.splice(0)) {
    scene.remove(tr.mesh);
    tr.mesh.geometry.dispose();
  }
  T = 0;
  frame = 0;
}

/**
 * Run `source` (a parsed scene bundle, or { asset, motion }) and play it: the garment, and the body posed by the
 * package's body graph.  `expected`: arrays to compare with ({expected (T, N, 3), body (T, V, 3)}: the Python
 * runtime's frames); a bundle's own `expected` is used when none is given.
 */
async function runScene(source, expected = null) {
  const o = await getOrt();
  const p = await getPackage();
  say(`running ${p.url} on ${ep} ...`);
  // signed changes ("+cloth", "-wrinkles") are to the package's default effects, as in `segadeform run`
  const effects = q.get("effects") ? parseEffects(q.get("effects"), defaultEffects(p.manifest)) : undefined;
  const collisionMargin = q.has("margin") ? Number(q.get("margin")) : undefined;
  lastScene = [source, expected];
  if (effects && effects.cloth) clothSwitch.checked = true;
  const cloth = clothSwitch.checked ? (q.get("cloth") && q.get("cloth") !== "1" ? q.get("cloth") : true) : null;
  const r = await animate(o, p, source, { ep, batch: +(q.get("batch") || 8), effects: effects && { ...effects, cloth: false },
    collisionMargin, cloth, force: q.has("force") });
  clearTracks();
  const faces = r.faces ? Uint32Array.from(r.faces) : new Uint32Array(0);
  addTrack(faces, r.frames, r.N, r.T, 0x3b64d8);
  if (r.body && !r.body.error) addTrack(Uint32Array.from(r.body.faces), r.body.vertices, r.body.V, r.body.T, 0xd9b99b);
  if (r.fps) fps = r.fps;
  const result = { ep, T: r.T, N: r.N, msPerFrame: r.msPerFrame, variant: r.variant, ort: o.env.versions?.web,
    warnings: r.warnings, effects: r.effects, collisions: r.collisions, cloth: r.cloth };
  const want = expected || (source.arrays && source.arrays.expected ? { expected: source.arrays.expected } : null);
  if (want && want.expected) Object.assign(result, compareFrames(r.frames, want.expected.data));
  if (r.body) {
    result.body = r.body.error ? { error: r.body.error }
      : { V: r.body.V, msPerFrame: r.body.msPerFrame, graph: r.body.graph };
    if (!r.body.error && want && want.body) Object.assign(result.body, compareFrames(r.body.vertices, want.body.data));
  }
  if (q.has("frame")) show(Math.min(+q.get("frame"), T - 1));
  const bodyLine = r.body ? (r.body.error ? `\nbody not shown: ${r.body.error}`
    : `\nbody: ${r.body.V} vertices, ${r.body.msPerFrame.toFixed(1)} ms/frame (${r.body.graph})`) : "";
  const colLine = r.collisions ? `\ncollisions: ${r.collisions.moved} vertex-frames pushed out of the body (margin ` +
    `${r.collisions.margin} m), ${r.collisions.msPerFrame.toFixed(1)} ms/frame` : "";
  const clothLine = r.cloth ? `\ncloth: ${r.cloth.contacts} vertex-frames in contact, ${r.cloth.pushed} pushed out after ` +
    `the sweeps, ${r.cloth.traced} traced out by the backstop, ${r.cloth.resets} reset(s), ` +
    `${r.cloth.msPerFrame.toFixed(1)} ms/frame` : "";
  say(`${r.T} frames x ${r.N} vertices, ${r.msPerFrame.toFixed(1)} ms/frame on ${ep} (${r.variant})${bodyLine}${colLine}` +
      clothLine +
      (result.rel !== undefined ? `\nagainst Python: max abs ${result.maxAbs.toExponential(2)}, rel ${result.rel.toExponential(2)}` : "") +
      (r.warnings && r.warnings.length ? `\nwarning: ${r.warnings.join("; ")}` : ""));
  return result;
}

async function runFromQuery() {
  let result;
  if (q.has("garment") && q.has("motion")) {
    const [a, m] = await Promise.all([openContainer(q.get("garment")), openContainer(q.get("motion"))]);
    if (a.kind !== "asset") throw new Error(`${q.get("garment")}: not a garment asset (.sgda)`);
    if (m.kind !== "motion") throw new Error(`${q.get("motion")}: not a motion file (.sgdm)`);
    const check = q.has("check") ? (await openContainer(q.get("check"))).parsed.arrays : null;
    result = await runScene({ asset: a.parsed, motion: m.parsed }, check);
  } else {
    const b = await openContainer(q.get("bundle"));
    result = await runScene(b.parsed);
  }
  if (q.has("body") && q.has("bodyMesh")) { // a posed body from `segadeform run --body-out` (OBJ + PC2)
    const [pc2, obj] = await Promise.all([fetch(q.get("body")), fetch(q.get("bodyMesh"))]);
    if (!pc2.ok || !obj.ok) throw new Error(`cannot fetch the body (${q.get("body")}, ${q.get("bodyMesh")})`);
    const b = parsePC2(new Uint8Array(await pc2.arrayBuffer()), q.get("body"));
    addTrack(parseOBJ(await obj.text(), q.get("bodyMesh")).faces, b.frames, b.N, b.T, 0xd9b99b);
  }
  return result;
}

// ---- dropped files ----------------------------------------------------------------------------------
const drop = document.getElementById("drop");
window.addEventListener("dragover", (e) => { e.preventDefault(); drop.style.display = "flex"; });
window.addEventListener("dragleave", () => { drop.style.display = "none"; });
window.addEventListener("drop", async (e) => {
  e.preventDefault();
  drop.style.display = "none";
  try {
    window.segadeformResult = await openFiles(await droppedFiles(e.dataTransfer));
  } catch (err) {
    say(`error: ${err.message}`);
    window.segadeformResult = { error: err.message };
  }
});

/** The files of a drop, folders (a model package folder) read through. */
async function droppedFiles(dt) {
  const entries = [...(dt.items || [])].map((it) => it.webkitGetAsEntry && it.webkitGetAsEntry()).filter(Boolean);
  if (!entries.some((en) => en.isDirectory)) return [...dt.files];
  const out = [];
  const walk = async (en) => {
    if (en.isFile) out.push(await new Promise((ok, bad) => en.file(ok, bad)));
    else {
      const reader = en.createReader();
      for (;;) {
        const batch = await new Promise((ok, bad) => reader.readEntries(ok, bad));
        if (!batch.length) break;
        for (const child of batch) await walk(child);
      }
    }
  };
  for (const en of entries) await walk(en);
  return out;
}

// what the drops so far have given: a garment asset and a motion wait for each other
const dropped = { asset: null, motion: null };

/**
 * Open dropped files: a model package's files (manifest.json, the .onnx graphs, weights.bin, or its folder),
 * a garment asset (.sgda) and a motion (.sgdm) -- run as soon as both are there, with the dropped package or the
 * page's --, a scene bundle (.sgdb), or OBJ + PC2 pairs to play (matched by vertex count; the first pair is the
 * garment).  Returns the run's result, or null when it waits for more files.
 */
export async function openFiles(files) {
  const objs = [], caches = [], pkgFiles = {};
  let bundle = null;
  for (const f of files) {
    const name = f.name.toLowerCase();
    if (name === "manifest.json" || name.endsWith(".onnx") || name.endsWith(".bin")) {
      pkgFiles[f.name] = new Uint8Array(await f.arrayBuffer());
    } else if (name.endsWith(".sgda") || name.endsWith(".sgdm") || name.endsWith(".sgdb")) {
      const c = await openContainer(new Uint8Array(await f.arrayBuffer()), f.name);
      if (c.kind === "bundle") bundle = c.parsed;
      else dropped[c.kind] = c.parsed;
    } else if (name.endsWith(".obj")) objs.push({ name: f.name, ...parseOBJ(await f.text(), f.name) });
    else if (name.endsWith(".pc2")) caches.push({ name: f.name, ...parsePC2(new Uint8Array(await f.arrayBuffer()), f.name) });
    else if (!name.endsWith(".md")) throw new Error(`${f.name}: expected .sgda, .sgdm, .sgdb, a package's files, .obj or .pc2`);
  }
  if (Object.keys(pkgFiles).length) {
    pkg = await packageFromFiles(pkgFiles);
    say(`package ${Object.keys(pkg.manifest.graphs).length} graphs loaded`);
  }
  if (bundle) return runScene(bundle);
  if (dropped.asset && dropped.motion) {
    const check = q.has("check") ? (await openContainer(q.get("check"))).parsed.arrays : null;
    return runScene({ asset: dropped.asset, motion: dropped.motion }, check);
  }
  if (dropped.asset || dropped.motion) {
    say(`${dropped.asset ? "garment asset" : "motion"} loaded; drop a ${dropped.asset ? "motion (.sgdm)" : "garment asset (.sgda)"} to run`);
    return null;
  }
  const colors = [0x3b64d8, 0xd9b99b];
  let k = 0;
  for (const c of caches) {
    const o = objs.find((x) => x.vertices.length === c.N * 3);
    if (!o) throw new Error(`${c.name}: no dropped OBJ has its ${c.N} vertices`);
    addTrack(o.faces, c.frames, c.N, c.T, colors[Math.min(k++, 1)]);
  }
  for (const o of objs.filter((x) => !caches.some((c) => c.N * 3 === x.vertices.length))) {
    addTrack(o.faces, o.vertices, o.vertices.length / 3, 1, colors[Math.min(k++, 1)]); // a still mesh
  }
  say(`${tracks.length} meshes, ${T} frames`);
  return { T, meshes: tracks.length };
}

// the cloth switch: the scene run again with the stage on or off
clothSwitch.addEventListener("change", () => {
  if (!lastScene) return;
  window.segadeformResult = undefined;
  runScene(...lastScene).then((r) => { window.segadeformResult = r; },
    (err) => { say(`error: ${err.message}`); window.segadeformResult = { error: err.message }; });
});

window.segadeform = { openFiles, show };
if (q.has("bundle") || (q.has("garment") && q.has("motion"))) {
  runFromQuery().then((r) => { window.segadeformResult = r; },
    (err) => { say(`error: ${err.message}`); window.segadeformResult = { error: err.message }; });
}
