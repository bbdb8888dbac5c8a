// Scene bundles (.sgdb): see docs/package.md and src/segadeform/bundle.py, the format's reference.
import { readFileSync } from "node:fs";

const MAGIC = "SEGADEFORM-BUNDLE 1\n";
const DTYPES = {
  f32: [Float32Array, 4], f64: [Float64Array, 8], i32: [Int32Array, 4], i64: [BigInt64Array, 8], u8: [Uint8Array, 1],
};

/** Parse a bundle from bytes: { arrays: {name: {dtype, shape, data}}, meta }. */
export function parseBundle(bytes, where = "bundle") {
  const buf = bytes instanceof Uint8Array ? bytes : new Uint8Array(bytes);
  const head = new TextDecoder().decode(buf.subarray(0, Math.min(buf.length, 1 << 20)));
  if (!head.startsWith(MAGIC)) throw new Error(`${where}: not a segadeform bundle`);
  const end = head.indexOf("\nEND\n");
  if (end < 0) throw new Error(`${where}: bundle header has no END line`);
  const lines = head.slice(MAGIC.length, end).split("\n");
  const n = parseInt(lines[0], 10);
  if (!(n >= 0) || lines.length !== n + 2 || !lines[n + 1].startsWith("meta ")) {
    throw new Error(`${where}: malformed bundle header`);
  }
  const headerBytes = new TextEncoder().encode(head.slice(0, end + 5)).length;
  const start = Math.ceil(headerBytes / 64) * 64;
  const meta = JSON.parse(lines[n + 1].slice(5));
  const arrays = {};
  for (const ln of lines.slice(1, n + 1)) {
    const t = ln.trim().split(/\s+/);
    const [name, dt] = t;
    const nd = parseInt(t[2], 10);
    const shape = t.slice(3, 3 + nd).map((x) => parseInt(x, 10));
    const off = parseInt(t[3 + nd], 10);
    const nbytes = parseInt(t[4 + nd], 10);
    const [Ctor, size] = DTYPES[dt] || [];
    const count = shape.reduce((a, b) => a * b, 1);
    if (!Ctor || count * size !== nbytes || start + off + nbytes > buf.length) {
      throw new Error(`${where}: bundle array ${name} does not fit the file`);
    }
    // copy into an aligned buffer of the right type
    const raw = buf.slice(start + off, start + off + nbytes);
    arrays[name] = { dtype: dt, shape, data: new Ctor(raw.buffer, raw.byteOffset, count) };
  }
  return { arrays, meta };
}

export function readBundle(path) {
  return parseBundle(readFileSync(path), path);
}
