// Scene bundles (.sgdb): see docs/package.md and src/segadeform/bundle.py, the format's reference.
import { readFileSync } from "node:fs";
import { parseBundle } from "./core.js";

export { parseBundle };

export function readBundle(path) {
  return parseBundle(readFileSync(path), path);
}
