// Vertex-animation textures (VAT) as scenebake writes them (src/export/vat.rs, docs/vat.md):
// FILE.exr holds, for frame f and vertex v, the position (RGB = x, y, z, object space, scene
// units) at row f * rows_per_frame + floor(v / width), column v % width, row 0 at the top of
// the image; FILE.normals.exr the unit normal in the same layout; FILE.json the layout.
//
// The vertex shader below fetches both by vertex index (gl_VertexID: the glTF's vertex order)
// and frame. docs/vat.md has the same shader for Godot, Unity and Unreal.
import * as THREE from 'three';
import { EXRLoader } from 'three/addons/loaders/EXRLoader.js';

/** GLSL ES 3.0 (WebGL2): the VAT look-up, shared by the drawn material and the capture pass. */
export const VAT_GLSL = /* glsl */ `
uniform highp sampler2D vatPositions;
uniform highp sampler2D vatNormals;
uniform ivec3 vatLayout;     // width, height, rows_per_frame (FILE.json "layout")
uniform int vatFrameCount;   // FILE.json "frames"
uniform float vatFrame;      // the frame to show; fractions blend two frames linearly
uniform bool vatOffset;      // FILE.json "mode" == "offset": the texel is added to the base mesh
uniform bool vatHasNormals;
attribute vec3 vatBase;      // offset mode: the base mesh (frame 0), object space, scene units

// The texel of vertex v in frame f. three.js's EXRLoader stores the image bottom-up (row 0 of
// the file is the texture's last row), hence height - 1 - row.
vec3 vatTexel(highp sampler2D image, int v, int f) {
  int row = f * vatLayout.z + v / vatLayout.x;
  return texelFetch(image, ivec2(v % vatLayout.x, vatLayout.y - 1 - row), 0).rgb;
}

vec3 vatPosition(int v) {
  float f = clamp(vatFrame, 0.0, float(vatFrameCount - 1));
  int f0 = int(floor(f));
  int f1 = min(f0 + 1, vatFrameCount - 1);
  vec3 p = mix(vatTexel(vatPositions, v, f0), vatTexel(vatPositions, v, f1), f - float(f0));
  return vatOffset ? vatBase + p : p;
}

vec3 vatNormal(int v, vec3 baseNormal) {
  if (!vatHasNormals) return baseNormal;
  float f = clamp(vatFrame, 0.0, float(vatFrameCount - 1));
  int f0 = int(floor(f));
  int f1 = min(f0 + 1, vatFrameCount - 1);
  return normalize(mix(vatTexel(vatNormals, v, f0), vatTexel(vatNormals, v, f1), f - float(f0)));
}
`;

/** Loads a 32-bit float EXR as a float texture read texel by texel (no filtering, no mips). */
async function loadExr(url) {
  const loader = new EXRLoader();
  loader.setDataType(THREE.FloatType); // the default, HalfFloat, would round positions
  const texture = await loader.loadAsync(url);
  texture.magFilter = THREE.NearestFilter;
  texture.minFilter = THREE.NearestFilter;
  texture.generateMipmaps = false;
  texture.needsUpdate = true;
  return texture;
}

/** Reads FILE.json and its images. `jsonUrl` is absolute; file names resolve beside it. */
export async function loadVat(jsonUrl) {
  const response = await fetch(jsonUrl);
  if (!response.ok) throw new Error(`${jsonUrl}: HTTP ${response.status}`);
  const manifest = await response.json();
  if (manifest.format !== 'scenebake-vat') {
    throw new Error(`${jsonUrl}: not a scenebake VAT layout (format "${manifest.format}")`);
  }
  const near = (name) => new URL(name, jsonUrl).href;
  const positions = await loadExr(near(manifest.positions));
  const normals = manifest.normals ? await loadExr(near(manifest.normals)) : null;
  const { width, height } = manifest.layout;
  if (positions.image.width !== width || positions.image.height !== height) {
    throw new Error(`${manifest.positions}: ${positions.image.width}×${positions.image.height} ` +
      `pixels, the JSON says ${width}×${height}`);
  }
  return { manifest, positions, normals, gltfUrl: near(manifest.gltf) };
}

/** The uniforms of a VAT (shared by every material drawing it; set `vatFrame` to play). */
export function vatUniforms(vat) {
  const { width, height, rows_per_frame: rows } = vat.manifest.layout;
  return {
    vatPositions: { value: vat.positions },
    vatNormals: { value: vat.normals ?? vat.positions },
    vatLayout: { value: new THREE.Vector3(width, height, rows) },
    vatFrameCount: { value: vat.manifest.frames },
    vatFrame: { value: 0 },
    vatOffset: { value: vat.manifest.mode === 'offset' },
    vatHasNormals: { value: vat.normals !== null },
  };
}

/**
 * `material` (a three.js built-in material, e.g. the glTF's MeshStandardMaterial) with its
 * vertex positions and normals taken from the VAT instead of the geometry.
 */
export function vatMaterial(material, uniforms) {
  const m = material.clone();
  m.onBeforeCompile = (shader) => {
    Object.assign(shader.uniforms, uniforms);
    shader.vertexShader = shader.vertexShader
      .replace('#include <common>', `#include <common>\n${VAT_GLSL}`)
      .replace('#include <beginnormal_vertex>',
        'vec3 objectNormal = vatNormal(gl_VertexID, normal);')
      .replace('#include <begin_vertex>',
        'vec3 transformed = vatPosition(gl_VertexID);');
  };
  m.customProgramCacheKey = () => 'scenebake-vat';
  return m;
}

/**
 * Evaluates the VAT's positions on the GPU with the same shader code: one point per vertex,
 * drawn into pixel (v % 256, v / 256) of a float render target, read back.
 * Returns a Float32Array of vertex_count × 3 (object space, scene units).
 */
export function capturePositions(renderer, uniforms, vertexCount, base) {
  const width = Math.min(vertexCount, 256);
  const height = Math.ceil(vertexCount / width);
  const target = new THREE.WebGLRenderTarget(width, height, {
    type: THREE.FloatType, format: THREE.RGBAFormat,
    magFilter: THREE.NearestFilter, minFilter: THREE.NearestFilter, depthBuffer: false,
  });
  const geometry = new THREE.BufferGeometry();
  geometry.setAttribute('position', base);
  geometry.setAttribute('vatBase', base);
  const material = new THREE.ShaderMaterial({
    glslVersion: THREE.GLSL3,
    uniforms: { ...uniforms, captureSize: { value: new THREE.Vector2(width, height) } },
    vertexShader: `${VAT_GLSL}
      uniform vec2 captureSize;
      flat out vec3 vPosition;
      void main() {
        vPosition = vatPosition(gl_VertexID);
        vec2 pixel = vec2(gl_VertexID % int(captureSize.x), gl_VertexID / int(captureSize.x));
        gl_Position = vec4((pixel + 0.5) / captureSize * 2.0 - 1.0, 0.0, 1.0);
        gl_PointSize = 1.0;
      }`,
    fragmentShader: `
      flat in vec3 vPosition;
      layout(location = 0) out highp vec4 capture;
      void main() { capture = vec4(vPosition, 1.0); }`,
  });
  const points = new THREE.Points(geometry, material);
  points.frustumCulled = false;
  const scene = new THREE.Scene();
  scene.add(points);
  const camera = new THREE.OrthographicCamera();
  const previous = renderer.getRenderTarget();
  renderer.setRenderTarget(target);
  renderer.render(scene, camera);
  const pixels = new Float32Array(width * height * 4);
  renderer.readRenderTargetPixels(target, 0, 0, width, height, pixels);
  renderer.setRenderTarget(previous);
  target.dispose();
  material.dispose();
  // The geometry shares the mesh's vatBase attribute: disposing it would free that buffer.
  const out = new Float32Array(vertexCount * 3);
  for (let v = 0; v < vertexCount; v++) {
    out.set(pixels.subarray(4 * v, 4 * v + 3), 3 * v);
  }
  return out;
}
