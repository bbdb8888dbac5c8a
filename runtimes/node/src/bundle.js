// Scene bundles (.sgdb): see docs/package.md and src/segadeform/bundle.py, the format's reference.
import { readFileSync, statSync } from "node:fs";
import { parseBundle } from "./core.js";

export { parseBundle };

export function readBundle(path) {
  if (statSync(path, { throwIfNoEntry: false })?.isDirectory()) throw new Error(`${path}: is a directory, not a file`);
  return parseBundle(readFileSync(path), path);
}
