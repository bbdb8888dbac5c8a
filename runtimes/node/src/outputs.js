// The output rule of `segadeform run` (src/segadeform/io/output_guard.py), for this runtime's command line: no run
// deletes or overwrites a file segadeform did not write.
//
// * Every output is claimed before any work: a new path is written; a file an earlier `run` wrote (the folder's
//   manifest, .segadeform-outputs.json, lists it with its size and modification time, unchanged since) is replaced;
//   anything else -- a file segadeform did not write or that changed since, another command's output, an input of
//   this run, a folder, a second output at the same path, an extension this runtime does not write -- is refused.
// * The outputs are written to hidden temporaries beside them and renamed only once every one is written, so a run
//   that fails leaves none of them; then the manifest records them (the same format and kind as Python's `run`, so
//   either runtime may replace the other's output).
import {
  closeSync, existsSync, lstatSync, mkdirSync, openSync, readFileSync, renameSync, rmdirSync, statSync, unlinkSync, writeFileSync, writeSync,
} from "node:fs";
import { basename, dirname, join, resolve } from "node:path";

export const MANIFEST_NAME = ".segadeform-outputs.json";
const KIND = "run";
const VERSION = 1;
const NOTE = "files segadeform wrote here (name: command, size, mtime); see segadeform.io.output_guard";

export class OutputRefused extends Error {}

const refuse = (path, problem, expected, got) =>
  new OutputRefused(`${path}: ${problem} (expected ${expected}, got ${got})`);

// modification times are nanoseconds since 1970 (~1.8e18), past what a JSON number keeps exactly in JavaScript: read
// and written as digit strings
function parseManifest(text) {
  return JSON.parse(text.replace(/("mtime_ns"\s*:\s*)(\d+)/g, '$1"$2"'));
}

/** The manifest of `folder` ({files: {name: {kind, size, mtime_ns}}}); an empty one when there is none. */
export function readManifest(folder) {
  const p = join(folder, MANIFEST_NAME);
  let text;
  try {
    text = readFileSync(p, "utf8");
  } catch (e) {
    if (e.code === "ENOENT" || e.code === "ENOTDIR") return { files: {} };
    throw refuse(p, `cannot read the outputs manifest (${e.code || e.message})`, "a readable manifest", "an error");
  }
  let m;
  try {
    m = parseManifest(text);
  } catch {
    m = null;
  }
  const ok = m && typeof m === "object" && m.segadeform_outputs === VERSION && m.files && typeof m.files === "object" &&
    Object.values(m.files).every((v) => v && typeof v === "object" && typeof v.kind === "string");
  if (!ok) {
    throw refuse(p, "not a segadeform outputs manifest, and segadeform does not overwrite it",
      `JSON with "segadeform_outputs": ${VERSION}`, JSON.stringify(text.slice(0, 40)));
  }
  return m;
}

const statOf = (p) => {
  try {
    return lstatSync(p, { bigint: true });
  } catch (e) {
    if (e.code === "ENOENT" || e.code === "ENOTDIR") return null;
    throw e;
  }
};

const unchanged = (entry, st) =>
  st !== null && st.isFile() && String(entry.size) === String(st.size) && String(entry.mtime_ns) === String(st.mtimeNs);

const samePath = (a, b) => {
  try {
    const sa = statSync(a, { bigint: true }), sb = statSync(b, { bigint: true });
    return sa.dev === sb.dev && sa.ino === sb.ino;
  } catch {
    return resolve(a) === resolve(b);
  }
};

/**
 * Claim `outputs` (paths) for this run before any work; `inputs` are the files and folders it reads.  Throws
 * OutputRefused naming the path and why.
 */
export function claimOutputs(outputs, inputs) {
  const seen = [];
  // the body's rest mesh (.obj) beside a body PC2 of the same run, as `segadeform run` writes it
  const restMesh = (p) => /\.obj$/i.test(p) && outputs.some((o) => /\.pc2$/i.test(o) && samePath(o, p.slice(0, -4) + o.slice(-4)));
  for (const out of outputs) {
    if (!out.toLowerCase().endsWith(".pc2") && !restMesh(out)) {
      const ext = out.includes(".") ? out.slice(out.lastIndexOf(".")) : "none";
      throw refuse(out, "this runtime writes PC2 point caches only", ".pc2", ext);
    }
    if (seen.some((s) => resolve(s) === resolve(out))) {
      throw refuse(out, "two outputs of this run would be written to this one path", "one path per output", out);
    }
    seen.push(out);
    for (let a = dirname(resolve(out)); a !== dirname(a); a = dirname(a)) {
      const s = statOf(a);
      if (s !== null && !s.isDirectory() && !(s.isSymbolicLink() && statSync(a).isDirectory())) {
        throw refuse(out, "is a path inside a file", "a path in a folder", `${a} (a file)`);
      }
    }
    for (const inp of inputs) {
      if (!inp) continue;
      if (samePath(out, inp) || resolve(out).startsWith(resolve(inp) + "/")) {
        throw refuse(out, "is an input of this run, and a run never writes over its inputs",
          "an output path that is not an input", inp);
      }
    }
    const files = readManifest(dirname(out)).files; // a manifest that is not one is refused before any work
    const st = statOf(out);
    if (st === null) continue;
    if (st.isDirectory()) throw refuse(out, "is a folder", "a file path for this output", "a folder");
    const entry = files[basename(out)];
    if (!entry || !unchanged(entry, st)) {
      const why = !entry ? "segadeform did not write it" : "it changed since segadeform wrote it (its size or modification time: edited, or touched)";
      throw refuse(out, `exists and ${why}; segadeform never overwrites such a file`,
        "a new path, or remove the file yourself", "an existing file");
    }
    if (entry.kind !== KIND) {
      throw refuse(out, `exists, written by \`segadeform ${entry.kind}\`; a run does not replace another command's output`,
        "another path", `an output of segadeform ${entry.kind}`);
    }
  }
}

/**
 * Write `items` ([{path, bytes}]; bytes: a Uint8Array, or an array of them written one after another, so that a
 * large cache is not copied into one buffer first) after claimOutputs: each to a hidden temporary beside it (missing folders made),
 * then, once all are written, each renamed into place and the folders' manifests updated.  A failure before the
 * renames leaves no output; the claims are checked again just before them (a file that appeared meanwhile).
 */
export function commitOutputs(items, inputs = []) {
  const temps = [];
  try {
    for (const { path, bytes } of items) {
      const tmp = temporaryOf(path);
      temps.push(tmp);
      if (Array.isArray(bytes)) {
        const fd = openSync(tmp, "w");
        try {
          for (const part of bytes) writeSync(fd, part);
        } finally {
          closeSync(fd);
        }
      } else {
        writeFileSync(tmp, bytes);
      }
    }
  } catch (e) {
    for (const t of temps) if (existsSync(t)) unlinkSync(t);
    throw e;
  }
  commitTemporaries(items.map((i) => i.path), inputs);
}

/** Make the folders `paths` go in, one level at a time; returns those this call made, deepest first: what a run
 * that fails or is stopped removes again where they are still empty (removeEmptyFolders), as `segadeform run` does
 * (segadeform.io.atomic.make_folders).  A folder someone else made meanwhile is not counted. */
export function makeFolders(paths) {
  const made = [];
  for (const p of paths) {
    const missing = [];
    for (let d = dirname(resolve(p)); !existsSync(d) && dirname(d) !== d; d = dirname(d)) missing.push(d);
    for (const d of missing.reverse()) {
      try {
        mkdirSync(d);
        made.push(d);
      } catch (e) {
        if (e.code !== "EEXIST") throw e;
      }
    }
  }
  return made.reverse();
}

/** Remove each of `folders` (missingFolders) that is empty; a folder that is not is left, with what is in it. */
export function removeEmptyFolders(folders) {
  for (const d of folders) {
    try {
      rmdirSync(d);
    } catch {
      // not empty, or already gone: left as it is
    }
  }
}

/** The hidden temporary beside `path` an output is written to before it is committed (its folder made when
 * missing): what a command that writes its outputs a chunk at a time writes to, then commitTemporaries. */
export function temporaryOf(path) {
  mkdirSync(dirname(resolve(path)), { recursive: true });
  return join(dirname(path), `.${basename(path)}.tmp-${process.pid}`);
}

/** Rename the temporaries of `paths` (temporaryOf, every one written) into place after checking the claims again (a
 * file that appeared meanwhile), and record them in their folders' manifests.  On a refusal the temporaries are
 * removed and nothing is replaced. */
export function commitTemporaries(paths, inputs = []) {
  const temps = paths.map((p) => join(dirname(p), `.${basename(p)}.tmp-${process.pid}`));
  try {
    claimOutputs(paths, inputs);
  } catch (e) {
    for (const t of temps) if (existsSync(t)) unlinkSync(t);
    throw e;
  }
  const byFolder = new Map();
  paths.forEach((path, k) => {
    renameSync(temps[k], path);
    const st = lstatSync(path, { bigint: true });
    const folder = dirname(path);
    if (!byFolder.has(folder)) byFolder.set(folder, {});
    byFolder.get(folder)[basename(path)] = { kind: KIND, size: Number(st.size), mtime_ns: String(st.mtimeNs) };
  });
  for (const [folder, add] of byFolder) updateManifest(folder, add);
}

function updateManifest(folder, add) {
  const m = readManifest(folder);
  const files = { ...m.files, ...add };
  const out = { segadeform_outputs: VERSION, note: NOTE };
  if (m.folder) out.folder = m.folder;
  out.files = Object.fromEntries(Object.keys(files).sort().map((k) => [k, files[k]]));
  const text = JSON.stringify(out, null, 1).replace(/("mtime_ns": )"(\d+)"/g, "$1$2") + "\n";
  const p = join(folder, MANIFEST_NAME);
  const tmp = join(folder, `.${MANIFEST_NAME}.tmp-${process.pid}`);
  writeFileSync(tmp, text);
  renameSync(tmp, p);
}

// (for tests) whether `path` is listed as this runtime's output in its folder's manifest, unchanged since
export function writtenByRun(path) {
  const e = readManifest(dirname(path)).files[basename(path)];
  return !!e && e.kind === KIND && unchanged(e, statOf(path));
}
