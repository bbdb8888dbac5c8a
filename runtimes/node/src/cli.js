#!/usr/bin/env node
// segadeform-node --package DIR --garment G.sgda --motion M.sgdm -o OUT.pc2 [--body-out BODY.pc2]
//                 [--effects lbs,dynamics,wrinkles,collisions,cloth] [--collision-margin M] [--cloth K=V,..]
//                 [--batch N] [--threads N]
// (without --effects: the model's own effects, and collisions when the package has a body graph; margin 0.004 m;
// cloth, the cloth stage, only when named; --cloth sets its knobs, as segadeform run --cloth)
// segadeform-node PACKAGE_DIR BUNDLE.sgdb -o OUT.pc2 [--batch N] [--threads N]      (a scene bundle)
import { closeSync, openSync, readFileSync, unlinkSync, writeFileSync, writeSync } from "node:fs";
import { join } from "node:path";
import * as os from "node:os";
import { animate, open, readAsset, readMotion } from "./index.js";
import {
  MAX_VERTEX_FRAMES, defaultEffects, effectsLabel, objText, otherTrainingBody, parseCloth, parseEffects, pc2Header,
  pc2Parts, readManifest, sceneInputs,
} from "./core.js";
import {
  claimOutputs, commitOutputs, commitTemporaries, makeFolders, removeEmptyFolders, temporaryOf,
} from "./outputs.js";

const USAGE = "usage: segadeform-node --package DIR --garment G.sgda --motion M.sgdm -o OUT.pc2 [--body-out BODY.pc2] " +
  "[--effects lbs|dqs,dynamics,wrinkles,collisions,cloth] [--collision-margin M] [--cloth K=V,..] [--batch N] " +
  "[--threads N] [--up y|z] [--output-units m|cm|mm|inch|..] [--force]\n" +
  "       segadeform-node PACKAGE_DIR BUNDLE.sgdb -o OUT.pc2 [--batch N] [--threads N] [--up y|z] [--output-units U]";
// --name=value is --name value (as click reads `segadeform run --effects=+cloth`)
const args = process.argv.slice(2).flatMap((a) => (/^--[a-z-]+=/.test(a) ? [a.slice(0, a.indexOf("=")), a.slice(a.indexOf("=") + 1)] : [a]));
if (args.includes("--help") || args.includes("-h")) {
  console.log(USAGE);
  process.exit(0);
}
const repeated = [], noValue = [];
const opt = (name, dflt) => {
  const i = args.indexOf(name);
  if (i < 0) return dflt;
  const [, value] = args.splice(i, 2);
  if (args.includes(name)) repeated.push(name);
  // a value may start with "-": a negative number, or an effect switched off ("-wrinkles")
  if (value === undefined || (value.startsWith("-") && !/^-\.?\d/.test(value) && !(name === "--effects" && /^-[a-z]/.test(value)))) {
    noValue.push(name);
  }
  return value;
};
const out = opt("-o");
// a whole decimal integer or NaN (parseInt read "8x" as 8 and "2.5" as 2: a user's trial)
const integer = (t) => (/^\s*[+]?\d+\s*$/.test(t) ? Number(t) : NaN);
const batch = integer(opt("--batch", "8"));
const threads = integer(opt("--threads", "1"));
const pkg = opt("--package"), garment = opt("--garment"), motion = opt("--motion");
const bodyOut = opt("--body-out"), effects = opt("--effects"), marginText = opt("--collision-margin");
const cloth = opt("--cloth");
// the written coordinates' axes and units, as `segadeform run --up --output-units` writes them (Maya and Unreal work
// in centimetres and take a point cache's numbers as they are)
const up = opt("--up", "y"), unitsText = opt("--output-units");
const UNIT_SCALES = { m: 1, dm: 0.1, cm: 0.01, mm: 0.001, inch: 0.0254, ft: 0.3048 };
function metresPerUnit(text) { // segadeform.io.writer.output_unit: a name or metres per unit in [1e-4, 1]
  const t = text.trim().toLowerCase();
  if (t in UNIT_SCALES) return UNIT_SCALES[t];
  const f = t === "" ? NaN : Number(t);
  return f >= 1e-4 && f <= 1 ? f : NaN;
}
const unit = unitsText === undefined ? 1 : metresPerUnit(unitsText);
/** Frames (float32, +Y up, metres) as written: turned to +Z up ((x, y, z) -> (x, -z, y)) and in `unit`, held as
 * `Type` (a copy; the frames themselves when neither changes them).  A rest mesh is written from float64, as
 * Python's. */
function toOutput(a, Type = Float32Array) {
  if (up === "y" && unit === 1) return a;
  const out = new Type(a.length);
  for (let i = 0; i < a.length; i += 3) {
    const x = a[i], y = a[i + 1], z = a[i + 2];
    if (up === "z") {
      out[i] = x / unit; out[i + 1] = -z / unit; out[i + 2] = y / unit;
    } else {
      out[i] = x / unit; out[i + 1] = y / unit; out[i + 2] = z / unit;
    }
  }
  return out;
}
// a motion made for another body or shape: played, with a warning (a flag given twice is the flag, as click reads it)
const force = args.includes("--force");
for (let at = args.indexOf("--force"); at >= 0; at = args.indexOf("--force")) args.splice(at, 1);
// as Python's float() reads it: "" is no number (Number("") is 0: an empty margin ran with 0)
const margin = marginText === undefined ? undefined : marginText.trim() === "" ? NaN : Number(marginText);
const flagForm = pkg || garment || motion;
// what parseCloth refuses in --cloth, or null
function clothProblem(text) {
  try {
    parseCloth(text);
    return null;
  } catch (e) {
    return e.message;
  }
}
// the run's effects as animate resolves them (--effects over the package's defaults), or null when they cannot be
// told here (a package or an effects list animate refuses, saying why)
function resolvedEffects() {
  let base = null;
  try {
    base = defaultEffects(readManifest(JSON.parse(readFileSync(join(pkg, "manifest.json"), "utf8"))));
  } catch {
    // a complete list needs no defaults; otherwise animate names the package's problem
  }
  try {
    return (effects === undefined ? base : parseEffects(effects, base)) || null;
  } catch {
    return null;
  }
}
// whether the run's effects have neither collisions nor the cloth stage (false when they cannot be told here)
function marginUnused() {
  const e = resolvedEffects();
  return !!e && !e.collisions && !e.cloth;
}
// whether the cloth stage is off in the run's effects ("cloth,-cloth" too, as C++ and `segadeform run` read it);
// without --effects it is off (a package's defaults never name it)
function clothOff() {
  if (effects === undefined) return true;
  const e = resolvedEffects();
  return !!e && !e.cloth;
}
// an --effects list's own mistake (an unknown effect, a name twice, a mix of a list and changes), told without the
// package: a command-line mistake, exit 2, as `segadeform run` says it (it exited 1: a QA trial)
function effectsProblem() {
  if (effects === undefined) return null;
  try {
    parseEffects(effects, parseEffects("lbs", null));
    return null;
  } catch (e) {
    return e.message;
  }
}
// what is wrong, in one line before the usage (a misspelled flag printed the usage alone)
const problem =
  repeated.length ? `${repeated[0]} is given more than once`
  : noValue.length ? `${noValue[0]} needs a value`
  : up !== "y" && up !== "z" ? `--up must be y or z (got ${up})`
  : !(unit > 0) ? `--output-units must be m, dm, cm, mm, inch, ft or metres per unit (0.0001..1; centimetres are cm or 0.01), got ${unitsText}`
  : args.find((a) => a.startsWith("-")) !== undefined ? `unknown option ${args.find((a) => a.startsWith("-"))}`
  : !out ? "-o OUT.pc2 is missing"
  : !(batch >= 1) ? "--batch must be an integer >= 1"
  : !(threads >= 1) ? "--threads must be an integer >= 1"
  : flagForm && !pkg ? "--package is missing"
  : flagForm && !garment ? "--garment is missing"
  : flagForm && !motion ? "--motion is missing"
  : flagForm && args.length ? `unexpected argument ${args[0]}`
  : !flagForm && args.length !== 2 ? "give PACKAGE_DIR BUNDLE.sgdb, or --package, --garment and --motion"
  : !flagForm && (bodyOut || effects || cloth || marginText !== undefined || force)
    ? "--body-out, --effects, --cloth, --collision-margin and --force go with --package/--garment/--motion"
  : marginText !== undefined && !Number.isFinite(margin) ? `--collision-margin must be a number, got ${marginText}`
  : effectsProblem() ? `--effects: ${effectsProblem()}`
  // a knob of a stage that will not run, or out of its range, is a command-line mistake, as `segadeform run` says it
  // (its value as the user wrote it)
  : cloth && clothOff()
    ? "--cloth sets the cloth stage's knobs, but the stage is off (name cloth in --effects)"
  : cloth && clothProblem(cloth) ? `--cloth: ${clothProblem(cloth)}`
  : marginText !== undefined && marginUnused() ? "--collision-margin sets the push-out's margin, but neither " +
    "collisions nor the cloth stage is on"
  : marginText !== undefined && !(margin >= 0 && margin < 1)
    ? `--collision-margin must be in [0, 1) metres (got ${marginText.trim()})`
  : null;
if (problem) {
  console.error(`error: ${problem}\n${USAGE}`);
  process.exit(2);
}
// more threads than the CPUs this process may use only contend (1000 took about 6 s a frame: a user's trial):
// lowered, and said, as `segadeform run` does
// (availableParallelism is Node >= 18.14; package.json allows 18)
const cpus = Math.max(1, os.availableParallelism ? os.availableParallelism() : os.cpus().length);
const usedThreads = Math.min(threads, cpus);
if (usedThreads < threads) console.log(`threads: ${usedThreads}, not ${threads} (the CPUs this process may use)`);
// the outputs are claimed before any work, as `segadeform run` claims them (outputs.js): never over a file
// segadeform did not write, an input, or each other
// the body's rest mesh beside its PC2 (what Blender's Mesh Cache and 3ds Max animate), as `segadeform run` writes it
const restObj = bodyOut ? bodyOut.replace(/\.pc2$/i, ".obj") : null;
const outputs = bodyOut ? [out, bodyOut, restObj] : [out];
const inputs = flagForm ? [pkg, garment, motion] : [args[0], args[1]];
try {
  claimOutputs(outputs, inputs);
} catch (e) {
  console.error(`Error: ${e.message}`);
  process.exit(1);
}
try {
  // an asset exported with --force for a body it does not sit on is refused, as `segadeform run` refuses it
  const unfit = flagForm && !force ? (readAsset(garment).meta.body || {}).unfit : undefined;
  if (typeof unfit === "string") {
    console.error(`Error: ${garment}: the garment asset was exported with --force although ${unfit} (expected a ` +
      "garment that sits on its body, or --force here too)");
    process.exit(1);
  }
  // a package whose body graph poses another body than its model was trained on, as `segadeform run` refuses it
  // (a manifest that cannot be read is animate's to name)
  const pkgDir = flagForm ? pkg : args[0];
  let otherBody = null;
  if (!force) {
    try {
      otherBody = otherTrainingBody(JSON.parse(readFileSync(join(pkgDir, "manifest.json"), "utf8")));
    } catch {
      otherBody = null;
    }
  }
  if (otherBody) {
    console.error(`Error: ${pkgDir}: ${otherBody}: the model never saw this body (segadeform export-body without ` +
      `--force gives the package its training body back; or ${flagForm ? "" : "--package/--garment/--motion with "}` +
      "--force)");
    process.exit(1);
  }
  const r = flagForm
    ? await playStreamed()
    : await animate(args[0], args[1], { batch, threads: usedThreads });
  if (!flagForm) { // a bundle: the frames it holds, written at once
    for (const w of r.warnings || []) console.error(`warning: ${w}`);
    const left = r.leftOut || [];
    if (left.length) {
      console.error(`warning: the scene's ${left.join(" and ")} are not in the bundle: these frames are the network's ` +
        "alone (segadeform garment export and motion export, then --package/--garment/--motion, run them)");
    }
    const startFrame = (r.motionMeta && Number.isInteger(r.motionMeta.start_frame)) ? r.motionMeta.start_frame : 0;
    commitOutputs([{ path: out, bytes: pc2Parts(toOutput(r.frames), r.T, r.N, { startFrame }) }], inputs); // all or none
  }
  const c = r.collisions, k = r.cloth;
  console.log(`${r.T} frames, ${r.msPerFrame.toFixed(2)} ms/frame (${r.variant}: ${effectsLabel(r.effects)}) -> ${out}` +
    (bodyOut ? `; body ${r.body.V} vertices, ${r.body.msPerFrame.toFixed(2)} ms/frame (${r.body.graph}) -> ${bodyOut}` : "") +
    (c ? `; collisions: ${c.moved} vertex-frames pushed out (margin ${c.margin} m), ${c.msPerFrame.toFixed(2)} ms/frame` : "") +
    (k ? `; cloth: ${k.contacts} vertex-frames in contact, ${k.pushed} pushed out after the sweeps, ${k.traced} traced ` +
      `out by the backstop, ${k.resets} reset(s), ` +
      `${k.msPerFrame.toFixed(2)} ms/frame` : ""));
  if (r.batch !== undefined && r.batch < batch) { // a big garment: fewer frames a call, as segadeform run says
    console.log(`batch: ${r.batch} frames a call, not ${batch} (at most ${MAX_VERTEX_FRAMES} vertex-frames a call)`);
  }
  if (k && k.resets) console.error(`cloth: the stage started again from the network's frame at frame ${k.firstReset} (the garment jumped)`);
} catch (e) {
  // the API's refusals of the garment asset name no file: this command names the one it was given
  const named = flagForm && e.message.startsWith("the garment asset ") ? `${garment}: ` : "";
  console.error(`Error: ${named}${e.message}`);
  process.exit(1);
}

/**
 * The flag form: the motion pushed through a Player about 256 frames at a time (whole batches: the frames of one push
 * of the whole motion, bit for bit) and written to the outputs' temporaries as it comes, then committed all or none:
 * neither the frames nor the posed body are held whole (a 4,593-frame capture with --body-out held 963 MB: a
 * developer's trial).  A signal (Ctrl-C, kill) removes the temporaries.  Returns what the summary line says.
 */
async function playStreamed() {
  const A = readAsset(garment), M = readMotion(motion);
  const I = sceneInputs({ asset: A, motion: M });
  // a motion made for another body or shape is refused, as `segadeform run` refuses it (nothing is written)
  const other = I.warnings.find((w) => w.startsWith("the motion was retargeted onto another"));
  if (other && !force) {
    console.error(`Error: ${motion}: ${other} (expected a motion exported for the asset's body and --betas: ` +
      "segadeform motion export ... --betas ..., or --force)");
    process.exit(1);
  }
  // force: the API's own refusals (the motion's) are this command's, above
  const p = await open(pkg, A, { batch, threads: usedThreads, effects, body: !!bodyOut, collisionMargin: margin, cloth,
    fps: I.fps, force: true });
  const temps = [];
  const made = makeFolders(outputs); // made for the outputs: removed again, where empty, when the run fails
  const removeTemps = () => {
    for (const t of temps) {
      try {
        unlinkSync(t);
      } catch {
        // already gone
      }
    }
    removeEmptyFolders(made);
  };
  const signals = { SIGINT: 130, SIGTERM: 143, SIGHUP: 129 };
  for (const [sig, code] of Object.entries(signals)) process.on(sig, () => { removeTemps(); process.exit(code); });
  const fds = [];
  try {
    for (const w of [...p.warnings, ...I.warnings]) console.error(`warning: ${w}`);
    // PC2 in frames, as `segadeform run` writes it: one sample per frame, from the motion file's first frame number
    // (motion export --frames 10:70 starts at 10, as run's output)
    const startFrame = Number.isInteger(M.meta.start_frame) ? M.meta.start_frame : 0;
    const T = I.T, D = I.D;
    const openOut = (path, header) => {
      const t = temporaryOf(path);
      temps.push(t);
      const fd = openSync(t, "w");
      fds.push(fd);
      writeSync(fd, header);
      return fd;
    };
    const bytes = (a) => new Uint8Array(a.buffer, a.byteOffset, a.byteLength);
    const fg = openOut(out, pc2Header(T, p.N, { startFrame }));
    const fb = bodyOut ? openOut(bodyOut, pc2Header(T, p.V, { startFrame })) : null;
    const step = p.batch * Math.max(1, Math.floor(256 / p.batch));
    for (let lo = 0; lo < T; lo += step) {
      const hi = Math.min(lo + step, T);
      const c = await p.push(I.poses.subarray(lo * D, hi * D), I.trans.subarray(lo * 3, hi * 3));
      writeSync(fg, bytes(toOutput(c.frames)));
      if (fb !== null) writeSync(fb, bytes(toOutput(c.body)));
    }
    while (fds.length) closeSync(fds.pop());
    if (bodyOut) {
      const rest = await p.poser.rest();
      temps.push(temporaryOf(restObj));
      writeFileSync(temps[temps.length - 1], objText(toOutput(rest.vertices, Float64Array), p.poser.faces()));
    }
    commitTemporaries(outputs, inputs); // all or none
    const perFrame = (ms) => ms / Math.max(T, 1);
    const r = { T, N: p.N, batch: p.batch, msPerFrame: perFrame(p.msDeform), variant: p.variant, effects: p.effects };
    if (bodyOut) r.body = { V: p.V, msPerFrame: perFrame(p.msBody), graph: p.poser.name };
    if (p.effects.cloth) r.cloth = { ...p.counts, msPerFrame: perFrame(p.msAfter) };
    else if (p.effects.collisions) r.collisions = { moved: p.moved, msPerFrame: perFrame(p.msAfter), margin: p.margin };
    return r;
  } catch (e) {
    while (fds.length) closeSync(fds.pop());
    removeTemps();
    throw e;
  } finally {
    await p.close();
  }
}
