// Loading a bake into a three.js scene, and playing it frame by frame.
//
// A bake is either a glTF/GLB (morph cache, morph basis with a weights animation, quantised,
// meshopt-compressed, or a skinned rig) played by three.js's AnimationMixer, or a VAT
// (FILE.json, or FILE.exr with its FILE.json beside it): the glTF named in the JSON gives the
// mesh (indices, UVs, material), and the VAT shader (vat.js) moves its vertices.
import * as THREE from 'three';
import { GLTFLoader } from 'three/addons/loaders/GLTFLoader.js';
import { MeshoptDecoder } from 'three/addons/libs/meshopt_decoder.module.js';
import { capturePositions, loadVat, vatMaterial, vatUniforms } from './vat.js';

/** glTF node index → the three.js object made from it. */
function nodeObjects(gltf) {
  const out = new Map();
  gltf.scene.traverse((o) => {
    const a = gltf.parser.associations.get(o);
    if (a && a.nodes !== undefined && !out.has(a.nodes)) out.set(a.nodes, o);
  });
  return out;
}

/** A mesh's evaluated vertices (morph targets, skin, world transform): vertex count × 3. */
function evaluatedPositions(mesh) {
  const count = mesh.geometry.attributes.position.count;
  const out = new Float32Array(count * 3);
  const v = new THREE.Vector3();
  for (let i = 0; i < count; i++) {
    mesh.getVertexPosition(i, v);
    v.applyMatrix4(mesh.matrixWorld);
    out[3 * i] = v.x;
    out[3 * i + 1] = v.y;
    out[3 * i + 2] = v.z;
  }
  return out;
}

async function loadGltf(url) {
  const loader = new GLTFLoader();
  loader.setMeshoptDecoder(MeshoptDecoder);
  return loader.loadAsync(url);
}

/** What a glTF holds, in words (for the info line). */
function describe(gltf) {
  let skinned = 0;
  let targets = 0;
  let quantised = false;
  gltf.scene.traverse((o) => {
    if (o.isSkinnedMesh) skinned++;
    if (o.isMesh) {
      targets = Math.max(targets, o.geometry.morphAttributes.position?.length ?? 0);
      const p = o.geometry.attributes.position;
      quantised ||= p.normalized || !(p.array instanceof Float32Array);
    }
  });
  const used = gltf.parser.json.extensionsUsed ?? [];
  const parts = [];
  if (targets) parts.push(`${targets} morph targets`);
  if (skinned) parts.push(`${skinned} skinned mesh${skinned > 1 ? 'es' : ''}`);
  if (quantised) parts.push('quantised');
  if (used.includes('EXT_meshopt_compression')) parts.push('meshopt');
  return parts.join(', ') || 'static';
}

/**
 * Loads the bake at `url` (absolute). Returns
 * `{ kind, root, fps, frameStart, frameEnd, info, setFrame(f), positions() }` where `setFrame`
 * shows frame `f` (fractions interpolate) and `positions()` returns the evaluated world-space
 * vertices of every mesh node at the current frame, `{ node, name, positions: number[] }`.
 */
export async function loadBake(url, renderer) {
  const path = new URL(url).pathname.toLowerCase();
  if (path.endsWith('.json') || path.endsWith('.exr')) {
    const json = path.endsWith('.exr')
      ? new URL(url.replace(/(\.normals)?\.exr(?=$|[?#])/i, '.json')).href
      : url;
    return loadVatBake(json, renderer);
  }
  return loadGltfBake(url);
}

async function loadGltfBake(url) {
  const gltf = await loadGltf(url);
  const extras = gltf.parser.json.asset?.extras?.scenebake ?? {};
  const clip = gltf.animations.find((a) => a.name === extras.animation) ?? gltf.animations[0];
  // Without asset.extras.scenebake: one frame per smallest key interval.
  const times = clip?.tracks[0]?.times ?? [];
  let step = Infinity;
  for (let i = 1; i < times.length; i++) step = Math.min(step, times[i] - times[i - 1]);
  const fps = extras.fps ?? (Number.isFinite(step) && step > 0 ? Math.round(1 / step) : 30);
  const frameStart = extras.frame_start ?? 0;
  const frameEnd = extras.frame_end ?? (clip ? Math.round(clip.duration * fps) : 0);
  const root = gltf.scene;
  const mixer = new THREE.AnimationMixer(root);
  const action = clip ? mixer.clipAction(clip) : null;
  if (action) {
    action.setLoop(THREE.LoopOnce, 1);
    action.clampWhenFinished = true;
    action.play();
  }
  const nodes = nodeObjects(gltf);
  return {
    kind: 'gltf',
    root,
    fps,
    frameStart,
    frameEnd,
    info: `${describe(gltf)}; animation "${clip?.name ?? 'none'}"`,
    setFrame(f) {
      if (action) {
        // Frame f plays at f / fps seconds (asset.extras.scenebake.fps); LoopOnce holds the
        // last key instead of wrapping to the first at the clip's end.
        action.enabled = true;
        action.paused = false;
        action.time = f / fps;
        mixer.update(0);
      }
      root.updateMatrixWorld(true);
    },
    positions() {
      root.updateMatrixWorld(true);
      const out = [];
      for (const [node, o] of [...nodes].sort((a, b) => a[0] - b[0])) {
        if (o.isMesh && !o.isPoints && !o.isLine) {
          out.push({ node, name: o.name, positions: Array.from(evaluatedPositions(o)) });
        }
      }
      return out;
    },
  };
}

async function loadVatBake(jsonUrl, renderer) {
  const vat = await loadVat(jsonUrl);
  const { manifest } = vat;
  const gltf = await loadGltf(vat.gltfUrl);
  const root = gltf.scene;
  root.updateMatrixWorld(true);
  // The VAT's mesh: the glTF mesh with the VAT's vertex count (the one with morph targets
  // first, in case a collider has as many vertices).
  const meshes = [];
  root.traverse((o) => {
    if (o.isMesh && o.geometry.attributes.position.count === manifest.vertex_count) meshes.push(o);
  });
  meshes.sort((a, b) => (b.geometry.morphAttributes.position ? 1 : 0) -
    (a.geometry.morphAttributes.position ? 1 : 0));
  const mesh = meshes[0];
  if (!mesh) {
    throw new Error(`${manifest.gltf}: no mesh with the VAT's ${manifest.vertex_count} vertices`);
  }
  // The VAT holds object-space positions in scene units: the mesh is drawn without its node
  // transform (for a quantised glTF, the dequantisation). Offset mode adds the texels to the
  // base mesh, frame 0: the glTF mesh at its default weights (frame 0's in every scenebake
  // cache) through its node transform, as three.js evaluates it.
  mesh.geometry.setAttribute('vatBase',
    new THREE.Float32BufferAttribute(evaluatedPositions(mesh), 3));
  const uniforms = vatUniforms(vat);
  mesh.geometry.morphAttributes = {};
  mesh.morphTargetInfluences = undefined;
  mesh.morphTargetDictionary = undefined;
  mesh.material = vatMaterial(mesh.material, uniforms);
  mesh.matrixAutoUpdate = false;
  mesh.matrix.identity();
  mesh.matrixWorldAutoUpdate = false;
  mesh.matrixWorld.identity();
  mesh.frustumCulled = false; // its geometry's bounds are the base mesh's, not the frame's
  const node = gltf.parser.associations.get(mesh)?.nodes;
  const others = nodeObjects(gltf);
  return {
    kind: 'vat',
    root,
    fps: manifest.fps,
    frameStart: 0,
    frameEnd: manifest.frames - 1,
    info: `VAT ${manifest.layout.width}×${manifest.layout.height} (${manifest.mode}` +
      `${vat.normals ? ', normals' : ''}), ${manifest.vertex_count} vertices, mesh of ${manifest.gltf}`,
    setFrame(f) {
      uniforms.vatFrame.value = f;
    },
    positions() {
      root.updateMatrixWorld(true);
      const out = [];
      for (const [n, o] of [...others].sort((a, b) => a[0] - b[0])) {
        if (o === mesh) {
          const p = capturePositions(renderer, uniforms, manifest.vertex_count,
            mesh.geometry.attributes.vatBase);
          out.push({ node: n, name: o.name, positions: Array.from(p) });
        } else if (o.isMesh && !o.isPoints && !o.isLine) {
          out.push({ node: n, name: o.name, positions: Array.from(evaluatedPositions(o)) });
        }
      }
      if (node === undefined) throw new Error('the VAT mesh has no glTF node');
      return out;
    },
  };
}
