// The command line's output rule (src/outputs.js), on files alone: claims before any work, all-or-none commits,
// and the manifest Python's `segadeform run` keeps (tests/runtimes/test_output_rule.py runs the command lines).
import { test } from "node:test";
import assert from "node:assert/strict";
import { mkdtempSync, readFileSync, writeFileSync, existsSync, readdirSync, appendFileSync } from "node:fs";
import { tmpdir } from "node:os";
import { join } from "node:path";
import { claimOutputs, commitOutputs, MANIFEST_NAME, writtenByRun } from "../src/outputs.js";

const fresh = () => mkdtempSync(join(tmpdir(), "sgd-out-"));

test("a new path is written, recorded, and replaced by the next run; a user's file never", () => {
  const d = fresh();
  const out = join(d, "a.pc2");
  claimOutputs([out], []);
  commitOutputs([{ path: out, bytes: Buffer.from("one") }]);
  assert.ok(writtenByRun(out));
  const text = readFileSync(join(d, MANIFEST_NAME), "utf8");
  assert.match(text, /"mtime_ns": \d{16,}\n/); // every digit, unquoted, as Python writes it
  claimOutputs([out], []);
  commitOutputs([{ path: out, bytes: Buffer.from("two") }]);
  assert.equal(readFileSync(out, "utf8"), "two");
  appendFileSync(out, "!"); // edited since: a user's file now
  assert.throws(() => claimOutputs([out], []), /it changed since segadeform wrote it \(its size or modification time: edited, or touched\)/);
  const mine = join(d, "mine.pc2");
  writeFileSync(mine, "mine");
  assert.throws(() => claimOutputs([mine], []), /mine\.pc2: exists and segadeform did not write it/);
  assert.equal(readFileSync(mine, "utf8"), "mine");
});

test("inputs, one path twice, other extensions and paths inside a file are refused", () => {
  const d = fresh();
  const input = join(d, "in.pc2");
  writeFileSync(input, "input");
  assert.throws(() => claimOutputs([input], [input]), /is an input of this run/);
  assert.throws(() => claimOutputs([join(d, "x.pc2"), join(d, "x.pc2")], []), /two outputs of this run/);
  assert.throws(() => claimOutputs([join(d, "x.obj")], []), /expected \.pc2, got \.obj/);
  assert.throws(() => claimOutputs([join(input, "b.pc2")], []), /is a path inside a file/);
  writeFileSync(join(d, MANIFEST_NAME), "not json");
  assert.throws(() => claimOutputs([join(d, "y.pc2")], []), /not a segadeform outputs manifest/);
  assert.equal(readFileSync(join(d, MANIFEST_NAME), "utf8"), "not json");
});

test("a commit that fails leaves no output and no temporary", () => {
  const d = fresh();
  writeFileSync(join(d, "file"), "x");
  const items = [{ path: join(d, "a.pc2"), bytes: Buffer.from("a") }, { path: join(d, "file", "b.pc2"), bytes: Buffer.from("b") }];
  assert.throws(() => commitOutputs(items));
  assert.ok(!existsSync(join(d, "a.pc2")));
  assert.deepEqual(readdirSync(d).sort(), ["file"]);
});
