// Refreshes viewer/vendor/ from node_modules/three (run `npm ci --prefix viewer` first, then
// `npm run vendor --prefix viewer`): copies three.js's ES modules that the viewer imports, and
// every module they import in turn (relative imports, followed recursively), plus three's LICENSE.
// The copies are committed so the viewer works offline and `scenebake view` can embed them.
import fs from 'node:fs';
import path from 'node:path';
import { fileURLToPath } from 'node:url';

const viewer = path.resolve(path.dirname(fileURLToPath(import.meta.url)), '..');
const three = path.join(viewer, 'node_modules', 'three');
const out = path.join(viewer, 'vendor', 'three');

// What the viewer imports (paths inside the three package).
const entries = [
  'build/three.module.js',
  'examples/jsm/loaders/GLTFLoader.js',
  'examples/jsm/loaders/EXRLoader.js',
  'examples/jsm/controls/OrbitControls.js',
  'examples/jsm/libs/meshopt_decoder.module.js',
];

const version = JSON.parse(fs.readFileSync(path.join(three, 'package.json'), 'utf8')).version;
fs.rmSync(out, { recursive: true, force: true });
const seen = new Set();
const queue = [...entries];
while (queue.length) {
  const rel = queue.pop();
  if (seen.has(rel)) continue;
  seen.add(rel);
  const text = fs.readFileSync(path.join(three, rel), 'utf8');
  fs.mkdirSync(path.dirname(path.join(out, rel)), { recursive: true });
  fs.writeFileSync(path.join(out, rel), text);
  for (const m of text.matchAll(/(?:from|import)\s*['"](\.{1,2}\/[^'"]+)['"]/g)) {
    queue.push(path.posix.normalize(path.posix.join(path.posix.dirname(rel), m[1])));
  }
}
fs.copyFileSync(path.join(three, 'LICENSE'), path.join(out, 'LICENSE'));
const files = [...seen].sort();
fs.writeFileSync(path.join(out, 'FILES.txt'),
  `three ${version} (npm), copied by viewer/scripts/vendor.mjs:\n${files.join('\n')}\nLICENSE\n`);
console.log(`vendored three ${version}: ${files.length} modules into ${path.relative(viewer, out)}/`);
