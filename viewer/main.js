// The viewer page: index.html?file=URL[&frame=N].
//
// Without `frame`, the bake plays in a loop (Play/Pause, scrub with the slider, space toggles).
// With `frame=N` it shows frame N only and stays paused, for scripted checks, which read
// `window.scenebake`:
//   ready      true once frame N is drawn (or `error` is set)
//   error      the message shown when loading failed
//   kind, fps, frameStart, frameEnd, info
//   setFrame(f)   shows frame f and draws it
//   positions()   [{ node, name, positions: [x0, y0, z0, x1, …] }] evaluated at the current
//                 frame, world space: three.js's morph/skin evaluation for a glTF, the VAT
//                 shader's own output (read back from a float render target) for a VAT
//   pixels()      the drawn picture, RGBA bytes bottom row first, base64
import * as THREE from 'three';
import { OrbitControls } from 'three/addons/controls/OrbitControls.js';
import { loadBake } from './bake.js';

const params = new URLSearchParams(location.search);
const api = { ready: false, error: null };
window.scenebake = api;

const view = document.getElementById('view');
const info = document.getElementById('info');
const playButton = document.getElementById('play');
const scrub = document.getElementById('scrub');
const frameLabel = document.getElementById('frame');

function fail(message) {
  const box = document.getElementById('error');
  box.textContent = message;
  box.hidden = false;
  api.error = message;
  api.ready = true;
}

const renderer = new THREE.WebGLRenderer({ antialias: false, preserveDrawingBuffer: true });
renderer.setPixelRatio(params.has('frame') ? 1 : window.devicePixelRatio);
view.appendChild(renderer.domElement);
const scene = new THREE.Scene();
scene.background = new THREE.Color(0xe8e8e8);
scene.add(new THREE.HemisphereLight(0xffffff, 0x606060, 1.6));
const sun = new THREE.DirectionalLight(0xffffff, 2.0);
sun.position.set(2, 4, 3);
scene.add(sun);
const camera = new THREE.PerspectiveCamera(35, 1, 0.01, 1000);
const controls = new OrbitControls(camera, renderer.domElement);

// A resize clears the canvas: draw again, or a paused view (`frame=N`) stays blank.
function resize() {
  const { clientWidth: w, clientHeight: h } = view;
  renderer.setSize(w, h, false);
  camera.aspect = w / Math.max(h, 1);
  camera.updateProjectionMatrix();
  renderer.render(scene, camera);
}
window.addEventListener('resize', resize);
resize();

/** Points the camera at the evaluated vertices of the shown frame. */
function frame(points) {
  const box = new THREE.Box3();
  const v = new THREE.Vector3();
  for (const { positions } of points) {
    for (let i = 0; i < positions.length; i += 3) box.expandByPoint(v.fromArray(positions, i));
  }
  if (box.isEmpty()) box.set(new THREE.Vector3(-1, -1, -1), new THREE.Vector3(1, 1, 1));
  const center = box.getCenter(new THREE.Vector3());
  const radius = Math.max(box.getSize(new THREE.Vector3()).length() / 2, 1e-3);
  const distance = radius / Math.sin(THREE.MathUtils.degToRad(camera.fov / 2)) * 1.05;
  camera.position.copy(center).add(new THREE.Vector3(1, 0.7, 1.6).normalize().multiplyScalar(distance));
  camera.near = distance / 100;
  camera.far = distance * 100;
  camera.updateProjectionMatrix();
  controls.target.copy(center);
  controls.update();
}

async function main() {
  const file = params.get('file');
  if (!file) {
    fail('no bake to show: open index.html?file=PATH (a .glb/.gltf, or a VAT .json/.exr), ' +
      'or run `scenebake view FILE`');
    return;
  }
  const url = new URL(file, location.href).href;
  const bake = await loadBake(url, renderer);
  scene.add(bake.root);
  const fixed = params.has('frame') ? Number(params.get('frame')) : null;
  if (fixed !== null && !(Number.isInteger(fixed) && fixed >= bake.frameStart && fixed <= bake.frameEnd)) {
    throw new Error(`frame=${params.get('frame')}: the bake has frames ${bake.frameStart}..${bake.frameEnd}`);
  }
  let current = fixed ?? bake.frameStart;
  let playing = fixed === null;
  const name = decodeURIComponent(new URL(url).pathname.split('/').pop());
  info.textContent = `${name}: ${bake.info}; frames ${bake.frameStart}..${bake.frameEnd} at ${bake.fps} fps`;
  scrub.min = String(bake.frameStart);
  scrub.max = String(bake.frameEnd);
  scrub.disabled = false;
  playButton.disabled = false;

  const show = (f) => {
    current = f;
    bake.setFrame(f);
    scrub.value = String(Math.round(f));
    frameLabel.textContent = `frame ${Math.round(f)} / ${bake.frameEnd}`;
    renderer.render(scene, camera);
  };
  const setPlaying = (p) => {
    playing = p;
    playButton.textContent = p ? 'Pause' : 'Play';
  };
  playButton.onclick = () => setPlaying(!playing);
  scrub.oninput = () => { setPlaying(false); show(Number(scrub.value)); };
  window.addEventListener('keydown', (e) => {
    if (e.code === 'Space') { e.preventDefault(); setPlaying(!playing); }
  });
  controls.addEventListener('change', () => renderer.render(scene, camera));

  // Frame the camera on the first, middle and last frames (the same for a VAT and its glTF).
  const framing = [];
  const middle = Math.round((bake.frameStart + bake.frameEnd) / 2);
  for (const f of new Set([bake.frameStart, middle, bake.frameEnd])) {
    bake.setFrame(f);
    framing.push(...bake.positions());
  }
  frame(framing);
  show(current);
  setPlaying(playing);

  Object.assign(api, {
    kind: bake.kind, fps: bake.fps, frameStart: bake.frameStart, frameEnd: bake.frameEnd,
    info: bake.info,
    setFrame: (f) => show(f),
    positions: () => bake.positions(),
    pixels: () => {
      const gl = renderer.getContext();
      const { width, height } = renderer.domElement;
      const bytes = new Uint8Array(width * height * 4);
      gl.readPixels(0, 0, width, height, gl.RGBA, gl.UNSIGNED_BYTE, bytes);
      let text = '';
      for (let i = 0; i < bytes.length; i += 0x8000) {
        text += String.fromCharCode.apply(null, bytes.subarray(i, i + 0x8000));
      }
      return { width, height, rgba: btoa(text) };
    },
    ready: true,
  });

  let last = performance.now();
  const tick = (now) => {
    const dt = (now - last) / 1000;
    last = now;
    if (playing) {
      const span = bake.frameEnd - bake.frameStart + 1;
      show(bake.frameStart + ((current - bake.frameStart + dt * bake.fps) % span));
    }
    requestAnimationFrame(tick);
  };
  requestAnimationFrame(tick);
}

main().catch((e) => fail(`cannot show ${params.get('file')}: ${e.message ?? e}`));
