// Drives headless Chromium (Debian's /usr/bin/chromium, through puppeteer-core) over the viewer
// and records what it shows, for scripts/viewer_check.py to compare with the files:
//
//   node viewer/scripts/capture.mjs --base URL --out OUT.json --frames 0,7,15 FILE...
//
// URL is where the viewer is served (`scenebake view FILE --no-open` prints it); FILE is a
// path the server serves (e.g. file/lab.glb). For each file it opens URL?file=FILE&frame=N
// (N the first of --frames), waits for window.scenebake.ready, then at each frame stores the
// evaluated positions (window.scenebake.positions()) and the picture
// (window.scenebake.pixels()). Exit status 1 when a page fails to load or reports an error.
import fs from 'node:fs';
import puppeteer from 'puppeteer-core';

function args(argv) {
  const out = { files: [], frames: [0], base: null, out: null, width: 320, height: 240 };
  for (let i = 0; i < argv.length; i++) {
    const a = argv[i];
    if (a === '--base') out.base = argv[++i];
    else if (a === '--out') out.out = argv[++i];
    else if (a === '--frames') out.frames = argv[++i].split(',').map(Number);
    else if (a === '--size') [out.width, out.height] = argv[++i].split('x').map(Number);
    else out.files.push(a);
  }
  if (!out.base || !out.out || out.files.length === 0) {
    console.error('usage: capture.mjs --base URL --out OUT.json [--frames 0,7] [--size WxH] FILE...');
    process.exit(2);
  }
  return out;
}

const opts = args(process.argv.slice(2));
const executablePath = process.env.CHROMIUM ?? '/usr/bin/chromium';
const browser = await puppeteer.launch({
  executablePath,
  headless: true,
  // No GPU here: WebGL2 through SwiftShader, Chromium's software renderer.
  args: ['--no-sandbox', '--use-angle=swiftshader', '--enable-unsafe-swiftshader',
    '--ignore-gpu-blocklist', '--disable-dev-shm-usage'],
});
const results = [];
let failures = 0;
try {
  const page = await browser.newPage();
  await page.setViewport({ width: opts.width, height: opts.height + 44 });
  const messages = [];
  page.on('console', (m) => messages.push(`${m.type()}: ${m.text()}`));
  page.on('pageerror', (e) => messages.push(`pageerror: ${e.message}`));
  for (const file of opts.files) {
    // The first frame through the URL (?file=F&frame=N, what scripted checks open), the others
    // through window.scenebake.setFrame on the same page (no reload of three.js for each).
    const url = `${opts.base}?file=${encodeURIComponent(file)}&frame=${opts.frames[0]}`;
    const started = Date.now();
    messages.length = 0;
    // Generous timeouts: CI's 2 cores may be busy, and WebGL runs in software here.
    for (let attempt = 1; ; attempt++) {
      try {
        await page.goto(url, { waitUntil: 'load', timeout: 120000 });
        await page.waitForFunction('window.scenebake && window.scenebake.ready',
          { timeout: 120000 });
        break;
      } catch (e) {
        if (attempt === 2) throw e;
        console.error(`${file}: ${e.message}; trying once more`);
      }
    }
    const loadMs = Date.now() - started;
    for (const [i, frame] of opts.frames.entries()) {
      const state = await page.evaluate((f, first) => {
        const s = window.scenebake;
        if (s.error) return { error: s.error };
        if (f > s.frameEnd) return { skipped: `the bake ends at frame ${s.frameEnd}` };
        if (!first) s.setFrame(f);
        return {
          kind: s.kind, fps: s.fps, frameStart: s.frameStart, frameEnd: s.frameEnd,
          info: s.info, meshes: s.positions(), picture: s.pixels(),
        };
      }, frame, i === 0);
      if (state.error) {
        failures++;
        console.error(`${file} frame ${frame}: ${state.error}\n  ${messages.join('\n  ')}`);
        break;
      }
      if (state.skipped) {
        console.log(`${file} frame ${frame}: skipped, ${state.skipped}`);
        continue;
      }
      console.log(`${file} frame ${frame}: ${state.kind}, ${state.info}` +
        (i === 0 ? ` (loaded and drawn in ${loadMs} ms)` : ''));
      results.push({ file, frame, loadMs, ...state });
    }
  }
} finally {
  await browser.close();
}
fs.writeFileSync(opts.out, JSON.stringify(results));
if (failures) {
  console.error(`${failures} page(s) failed`);
  process.exit(1);
}
