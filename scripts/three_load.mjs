// Load time and memory of glTF files in three.js (Node, GLTFLoader.parse, MeshoptDecoder for
// EXT_meshopt_compression), one file per process so the figures do not mix:
//
//     node --expose-gc scripts/three_load.mjs FILE.glb [--max-texture-size 16384]
//
// Prints the parse time, the growth of the JS heap plus ArrayBuffers after parsing (the CPU-side
// geometry and animation; the file's own bytes excluded), and the float32 morph texture three's
// WebGLRenderer would upload for it (src/renderers/webgl/WebGLMorphtargets.js: width =
// vertices × (1 + normals), wrapped at the GPU's max texture size, 4 floats a texel, one layer
// per target) and the length of the morphTargetInfluences array the shader gets.
import { readFileSync } from 'node:fs';
import { performance } from 'node:perf_hooks';
import { GLTFLoader } from 'three/addons/loaders/GLTFLoader.js';
import { MeshoptDecoder } from 'three/addons/libs/meshopt_decoder.module.js';

globalThis.ProgressEvent ??= class ProgressEvent extends Event {
    constructor(type, init = {}) {
        super(type);
        Object.assign(this, init);
    }
};

const args = process.argv.slice(2);
const file = args[0];
const i = args.indexOf('--max-texture-size');
const maxTextureSize = i >= 0 ? Number(args[i + 1]) : 16384;
if (!file) {
    console.error('usage: node --expose-gc scripts/three_load.mjs FILE.glb [--max-texture-size N]');
    process.exit(2);
}
const bytes = readFileSync(file);
const data = bytes.buffer.slice(bytes.byteOffset, bytes.byteOffset + bytes.byteLength);
const mem = () => {
    globalThis.gc?.();
    const m = process.memoryUsage();
    return m.heapUsed + m.arrayBuffers;
};
await MeshoptDecoder.ready;
const before = mem();
const t0 = performance.now();
const loader = new GLTFLoader().setMeshoptDecoder(MeshoptDecoder);
const gltf = await new Promise((resolve, reject) => loader.parse(data, '', resolve, reject));
const ms = performance.now() - t0;
const grown = mem() - before;
let texture = 0;
let influences = 0;
gltf.scene.traverse((o) => {
    const g = o.geometry;
    if (!g || !g.morphAttributes.position) return;
    const targets = g.morphAttributes.position.length;
    const perVertex = g.morphAttributes.normal ? 2 : 1;
    let width = g.attributes.position.count * perVertex;
    let height = 1;
    if (width > maxTextureSize) {
        height = Math.ceil(width / maxTextureSize);
        width = maxTextureSize;
    }
    texture += width * height * 4 * 4 * targets;
    influences = Math.max(influences, targets);
});
const mb = (b) => (b / 1e6).toFixed(1);
console.log(
    `${file}: ${mb(bytes.length)} MB file, parsed in ${ms.toFixed(0)} ms, ` +
        `+${mb(grown)} MB JS heap + ArrayBuffers, morph texture ${mb(texture)} MB ` +
        `(max texture size ${maxTextureSize}), morphTargetInfluences[${influences}]`,
);
