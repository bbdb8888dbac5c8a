// The viewer page: run a scene bundle through a model package (onnxruntime-web) or play dropped
// OBJ + PC2 files, with three.js.  Query: ?bundle=URL&package=URL&ep=wasm|webgpu&batch=8&frame=N&paused=1
// &body=BODY.pc2&bodyMesh=BODY.obj (the posed body, from `segadeform run --body-out`, shown beside the garment)
import * as THREE from "three";
import { OrbitControls } from "three/addons/controls/OrbitControls.js";
import { parseOBJ, parsePC2 } from "../../node/src/core.js";
import { animate, loadOrt, loadPackage } from "./runtime.js";

const q = new URLSearchParams(location.search);
const statusEl = document.getElementById("status");
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

// ---- a scene bundle through a model package ---------------------------------------------------------
async function runBundle(bundle) {
  const ep = q.get("ep") || "wasm";
  const pkgUrl = q.get("package") || "../../samples/models/default/";
  say(`loading onnxruntime-web (${ep}) and ${pkgUrl} ...`);
  const ort = await loadOrt(ep, new URL("../node_modules/onnxruntime-web/dist/", import.meta.url).href);
  const pkg = await loadPackage(pkgUrl);
  say(`running ${pkgUrl} on ${ep} ...`);
  const r = await animate(ort, pkg, bundle, { ep, batch: +(q.get("batch") || 8) });
  const A = r.bundle.arrays;
  const faces = A.faces ? Uint32Array.from(A.faces.data) : new Uint32Array(0);
  addTrack(faces, r.frames, r.N, r.T, 0x3b64d8);
  const result = { ep, T: r.T, N: r.N, msPerFrame: r.msPerFrame, variant: r.variant, ort: ort.env.versions?.web };
  if (A.expected) { // a test vector: compare with the Python runtime's frames
    const exp = A.expected.data;
    let maxAbs = 0, maxRef = 0, finite = true;
    for (let i = 0; i < exp.length; i++) {
      const d = Math.abs(r.frames[i] - exp[i]);
      if (!Number.isFinite(r.frames[i])) finite = false;
      maxAbs = Math.max(maxAbs, d);
      maxRef = Math.max(maxRef, Math.abs(exp[i]));
    }
    Object.assign(result, { maxAbs, rel: maxAbs / maxRef, finite, sameLength: exp.length === r.frames.length });
  }
  if (q.has("body") && q.has("bodyMesh")) {
    const [pc2, obj] = await Promise.all([fetch(q.get("body")), fetch(q.get("bodyMesh"))]);
    if (!pc2.ok || !obj.ok) throw new Error(`cannot fetch the body (${q.get("body")}, ${q.get("bodyMesh")})`);
    const b = parsePC2(new Uint8Array(await pc2.arrayBuffer()), q.get("body"));
    addTrack(parseOBJ(await obj.text(), q.get("bodyMesh")).faces, b.frames, b.N, b.T, 0xd9b99b);
  }
  if (q.has("frame")) show(Math.min(+q.get("frame"), T - 1));
  say(`${r.T} frames x ${r.N} vertices, ${r.msPerFrame.toFixed(1)} ms/frame on ${ep} (${r.variant})` +
      (result.rel !== undefined ? `\nagainst Python: max abs ${result.maxAbs.toExponential(2)}, rel ${result.rel.toExponential(2)}` : ""));
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
    await openFiles([...e.dataTransfer.files]);
  } catch (err) {
    say(`error: ${err.message}`);
  }
});

/** OBJ + PC2 pairs (matched by vertex count; the first pair is the garment), or one .sgdb bundle. */
export async function openFiles(files) {
  const objs = [], caches = [];
  for (const f of files) {
    const name = f.name.toLowerCase();
    if (name.endsWith(".sgdb")) {
      const { parseBundle } = await import("./runtime.js");
      return runBundle(parseBundle(new Uint8Array(await f.arrayBuffer()), f.name));
    }
    if (name.endsWith(".obj")) objs.push({ name: f.name, ...parseOBJ(await f.text(), f.name) });
    else if (name.endsWith(".pc2")) caches.push({ name: f.name, ...parsePC2(new Uint8Array(await f.arrayBuffer()), f.name) });
    else throw new Error(`${f.name}: expected .obj, .pc2 or .sgdb`);
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
}

window.segadeform = { openFiles, show };
if (q.has("bundle")) {
  runBundle(q.get("bundle")).then((r) => { window.segadeformResult = r; },
    (err) => { say(`error: ${err.message}`); window.segadeformResult = { error: err.message }; });
}
