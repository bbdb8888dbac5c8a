// embed.html's work in a module Web Worker, so that the page's thread only draws: the page makes it with
//   new Worker(new URL("./embed-worker.js", import.meta.url), { type: "module" })
// and posts { package, garment, motion, effects?, chunk?, force? } -- absolute URLs as strings (a worker resolves a
// relative URL against its own, and a URL object cannot be posted).  It posts back { type: "ready", N, T, faces },
// then { type: "frames", lo, hi, frames } a chunk at a time (frames: (hi - lo) * N * 3 floats, metres; their buffer
// is transferred, not copied), then { type: "done", result }, or { type: "error", message }.
// The whole pipeline lives here: onnxruntime-web, its sessions and the Player cannot be posted between threads.
import { loadOrt, loadPackage, openContainer, packageSessions, Player } from "./segadeform/runtime.js";

// a rejection no handler catches reaches the page as nothing at all (an async onmessage's error fires no error event
// on the Worker, and the page waits for ever): say every one
self.addEventListener("unhandledrejection", (e) => {
  self.postMessage({ type: "error", message: String(e.reason?.message ?? e.reason) });
});

self.onmessage = async ({ data: q }) => {
  try {
    const ort = await loadOrt("wasm");                             // ./segadeform/ort/, beside runtime.js
    const pkg = await loadPackage(q.package);                      // every file hash-checked
    const asset = (await openContainer(q.garment, undefined, { expect: "asset" })).parsed;
    const motion = (await openContainer(q.motion, undefined, { expect: "motion" })).parsed;
    const session = packageSessions(ort, pkg);
    const player = await Player.open(ort, pkg.manifest, { asset, motion }, session,
      { effects: q.effects, fps: motion.meta.fps, force: !!q.force });
    const { poses, trans } = motion.arrays, T = poses.shape[0], D = poses.shape[1] * 3, chunk = q.chunk || 8;
    self.postMessage({ type: "ready", N: player.N, T, faces: player.faces });
    let ms = 0;
    for (let lo = 0; lo < T; lo += chunk) {
      const hi = Math.min(lo + chunk, T), t0 = performance.now();
      const { frames } = await player.push(poses.data.subarray(lo * D, hi * D), trans.data.subarray(lo * 3, hi * 3));
      ms += performance.now() - t0;
      self.postMessage({ type: "frames", lo, hi, frames }, [frames.buffer]);  // a Float32Array of its own
    }
    const result = { T, N: player.N, chunk, variant: player.variant, effects: player.effects, counts: player.counts,
      warnings: player.warnings, msPerFrame: ms / T };
    await session.release();                                       // the sessions' WebAssembly memory
    self.postMessage({ type: "done", result });
  } catch (e) {
    self.postMessage({ type: "error", message: e.message });
  }
};
