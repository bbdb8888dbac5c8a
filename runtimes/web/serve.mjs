#!/usr/bin/env node
// A static server for the viewer: serves the repository (the page, the shared JS core, packages and
// bundles) at http://localhost:PORT/runtimes/web/.   node serve.mjs [--port 8737] [--root DIR]
import { createServer } from "node:http";
import { readFile, stat } from "node:fs/promises";
import { extname, join, normalize, resolve, sep } from "node:path";
import { fileURLToPath } from "node:url";

const TYPES = {
  ".html": "text/html", ".js": "text/javascript", ".mjs": "text/javascript", ".json": "application/json",
  ".wasm": "application/wasm", ".css": "text/css", ".png": "image/png", ".onnx": "application/octet-stream",
  ".bin": "application/octet-stream", ".sgdb": "application/octet-stream", ".sgda": "application/octet-stream",
  ".sgdm": "application/octet-stream", ".obj": "text/plain",
};

/** Start serving `root`; resolves to the server (listening on `port`, 0: any free one). */
export function serve(root, port = 8737) {
  const base = resolve(root);
  const server = createServer(async (req, res) => {
    const path = normalize(join(base, decodeURIComponent(new URL(req.url, "http://x").pathname)));
    if (path !== base && !path.startsWith(base + sep)) {
      res.writeHead(403).end();
      return;
    }
    try {
      const p = (await stat(path)).isDirectory() ? join(path, "index.html") : path;
      const body = await readFile(p);
      res.writeHead(200, { "Content-Type": TYPES[extname(p)] || "application/octet-stream", "Cache-Control": "no-store" });
      res.end(body);
    } catch {
      res.writeHead(404).end(`not found: ${req.url}`);
    }
  });
  return new Promise((ok) => server.listen(port, "127.0.0.1", () => ok(server)));
}

if (process.argv[1] === fileURLToPath(import.meta.url)) {
  const args = process.argv.slice(2);
  const opt = (name, dflt) => (args.includes(name) ? args[args.indexOf(name) + 1] : dflt);
  const root = opt("--root", fileURLToPath(new URL("../..", import.meta.url)));
  const s = await serve(root, +opt("--port", "8737"));
  console.log(`serving ${root} at http://127.0.0.1:${s.address().port}/runtimes/web/`);
}
