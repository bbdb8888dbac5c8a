// The browser-safe core's parsers (the page reads dropped OBJ and PC2 files with them).
import { test } from "node:test";
import assert from "node:assert/strict";
import { parseOBJ, parsePC2, pc2Bytes } from "../../node/src/core.js";

test("OBJ: polygons fan into triangles, negative indices count from the end, bad indices are errors", () => {
  const m = parseOBJ("v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nf 1/1 2/2 3/3 4/4\nf -4 -3 -1\n");
  assert.deepEqual(Array.from(m.faces), [0, 1, 2, 0, 2, 3, 0, 1, 3]);
  assert.equal(m.vertices.length, 12);
  assert.throws(() => parseOBJ("v 0 0 0\nf 1 2 3\n", "x.obj"), /x.obj:2: face index out of range/);
  assert.throws(() => parseOBJ("# nothing\n", "e.obj"), /e.obj: no vertices/);
});

test("PC2 round trip and a short file", () => {
  const frames = Float32Array.from({ length: 2 * 3 * 3 }, (_, i) => i * 0.5);
  const bytes = pc2Bytes(frames, 2, 3);
  const r = parsePC2(bytes);
  assert.equal(r.T, 2);
  assert.equal(r.N, 3);
  assert.deepEqual(Array.from(r.frames), Array.from(frames));
  assert.throws(() => parsePC2(bytes.subarray(0, 40), "c.pc2"), /c.pc2: PC2 header does not fit the file/);
  assert.throws(() => parsePC2(new Uint8Array(40), "z.pc2"), /not a PC2 point cache/);
});
