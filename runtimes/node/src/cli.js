#!/usr/bin/env node
// segadeform-node --package DIR --garment G.sgda --motion M.sgdm -o OUT.pc2 [--body-out BODY.pc2]
//                 [--effects lbs,dynamics,wrinkles,collisions,cloth] [--collision-margin M] [--cloth K=V,..]
//                 [--batch N] [--threads N]
// (without --effects: the model's own effects, and collisions when the package has a body graph; margin 0.004 m;
// cloth, the cloth stage, only when named; --cloth sets its knobs, as segadeform run --cloth)
// segadeform-node PACKAGE_DIR BUNDLE.sgdb -o OUT.pc2 [--batch N] [--threads N]      (a scene bundle)
import { readFileSync } from "node:fs";
import { join } from "node:path";
import * as os from "node:os";
import { animate, readAsset } from "./index.js";
import {
  MAX_VERTEX_FRAMES, defaultEffects, effectsLabel, objText, otherTrainingBody, parseCloth, parseEffects, pc2Parts,
  readManifest,
} from "./core.js";
import { claimOutputs, commitOutputs } from "./outputs.js";

const USAGE = "usage: segadeform-node --package DIR --garment G.sgda --motion M.sgdm -o OUT.pc2 [--body-out BODY.pc2] " +
  "[--effects lbs|dqs,dynamics,wrinkles,collisions,cloth] [--collision-margin M] [--cloth K=V,..] [--batch N] " +
  "[--threads N] [--force]\n" +
  "       segadeform-node PACKAGE_DIR BUNDLE.sgdb -o OUT.pc2 [--batch N] [--threads N]";
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
const forceAt = args.indexOf("--force"); // a motion made for another body or shape: played, with a warning
const force = forceAt >= 0;
if (force) args.splice(forceAt, 1);
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
// what is wrong, in one line before the usage (a misspelled flag printed the usage alone)
const problem =
  repeated.length ? `${repeated[0]} is given more than once`
  : noValue.length ? `${noValue[0]} needs a value`
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
    // force: the API's own refusal is this command's, below, naming the motion file
    ? await animate(pkg, garment, motion, { batch, threads: usedThreads, effects, body: !!bodyOut, collisionMargin: margin, cloth,
      force: true })
    : await animate(args[0], args[1], { batch, threads: usedThreads });
  // a motion made for another body or shape is refused, as `segadeform run` refuses it (nothing is written)
  const other = (r.warnings || []).find((w) => w.startsWith("the motion was retargeted onto another"));
  if (other && !force) {
    console.error(`Error: ${motion}: ${other} (expected a motion exported for the asset's body and --betas: ` +
      "segadeform motion export ... --betas ..., or --force)");
    process.exit(1);
  }
  for (const w of r.warnings || []) console.error(`warning: ${w}`);
  // PC2 in frames, as `segadeform run` writes it: start 0, one sample per frame
  // a motion file cut from a longer one (motion export --frames 10:70) starts at its first frame's number, as run's
  const startFrame = (r.motionMeta && Number.isInteger(r.motionMeta.start_frame)) ? r.motionMeta.start_frame : 0;
  const items = [{ path: out, bytes: pc2Parts(r.frames, r.T, r.N, { startFrame }) }];
  if (bodyOut) {
    items.push({ path: bodyOut, bytes: pc2Parts(r.body.vertices, r.body.T, r.body.V, { startFrame }) });
    items.push({ path: restObj, bytes: objText(r.body.rest, r.body.faces) });
  }
  commitOutputs(items, inputs); // all or none
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
