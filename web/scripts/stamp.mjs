// Writes dist/bundle-hash.txt: the SHA-256 of the bundle's inputs, as
// server/src/console/bundle.rs computes it (the other implementation; keep both
// lists and the encoding the same). A Rust test compares the two, so a change to
// the console's sources or to the contract without a rebuild fails `cargo test`.
import { createHash } from "node:crypto";
import { readdirSync, readFileSync, writeFileSync } from "node:fs";
import { dirname, join } from "node:path";
import { fileURLToPath } from "node:url";

const root = join(dirname(fileURLToPath(import.meta.url)), "..", "..");
const FILES = [
  "web/index.html",
  "web/package.json",
  "web/package-lock.json",
  "web/tsconfig.json",
  "web/vite.config.ts",
  "web/buf.gen.yaml",
  "web/scripts/stamp.mjs",
];
const DIRS = ["web/src", "proto/proto"];
const GENERATED = "web/src/gen";

function collect(dir, out) {
  if (dir === GENERATED) return;
  for (const entry of readdirSync(join(root, dir), { withFileTypes: true })) {
    const path = `${dir}/${entry.name}`;
    if (entry.isDirectory()) collect(path, out);
    else out.push(path);
  }
}

const files = [...FILES];
for (const dir of DIRS) collect(dir, files);
// Byte order, as Rust sorts Strings.
files.sort((a, b) => Buffer.compare(Buffer.from(a), Buffer.from(b)));
const hash = createHash("sha256");
for (const file of files) {
  const bytes = readFileSync(join(root, file));
  hash.update(file);
  hash.update(Buffer.from([0]));
  hash.update(String(bytes.length));
  hash.update(Buffer.from([0]));
  hash.update(bytes);
}
const digest = hash.digest("hex");
writeFileSync(join(root, "web", "dist", "bundle-hash.txt"), digest + "\n");
console.log(`dist/bundle-hash.txt ${digest}`);
