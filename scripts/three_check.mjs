// What three.js plays, compared with an independent reading of the file.
//
//   npm ci --prefix scripts          # once: gltf-validator and three (exact versions)
//   node scripts/three_check.mjs [--frames N] [--tolerance D] [--shift S] FILE...
//
// For each .glb/.gltf, three's own GLTFLoader (three/addons, run in Node: parse() from an
// ArrayBuffer; images are not decoded, every texture is an empty THREE.Texture) builds the scene
// and an AnimationMixer plays the file's FIRST animation (`gltf.animations[0]`, what a three.js
// user gets), once, held at its end. At N frames spread over the bake (default 6: the first, the
// last, evenly between them, and one half-way between two frames so interpolation counts) each
// mesh's vertices are evaluated on the CPU the way three's shaders do (Mesh.getVertexPosition:
// base + sum of influence x morph delta, then SkinnedMesh.applyBoneTransform; then the object's
// matrixWorld) and compared with scripts/blender/gltf_eval.py's reading of the file (numpy, no
// three and no scenebake code) at the same time. The times come from asset.extras.scenebake
// (frame f at f / fps), or from the first animation's key range for a file without them.
//
// Also checked: a scenebake export names its bake in asset.extras.scenebake.animation and
// that is animations[0] (in the JSON and in three's gltf.animations); with several animations,
// every other clip is played and stopped before the bake plays again (a user switching clips),
// and the bake must still match.
//
// Prints one line per file: vertices, frames checked, largest distance. Exit status 1 when any
// distance exceeds the tolerance (default 1e-5 x max(1, the model's size), in the file's units),
// a file cannot be read, or the checks above fail. --shift S plays three S seconds later than the
// reference (a way to watch the check fail). The reference runs with $PYTHON (default python3),
// which needs numpy.

import { execFileSync } from 'node:child_process';
import { readFileSync } from 'node:fs';
import path from 'node:path';
import { fileURLToPath } from 'node:url';

import * as THREE from 'three';
import { GLTFLoader } from 'three/addons/loaders/GLTFLoader.js';

// three's FileLoader (a .gltf's buffers, inlined as data: URIs below) reports progress with the
// browser's ProgressEvent, which Node 20 lacks.
globalThis.ProgressEvent ??= class ProgressEvent extends Event {
    constructor(type, init = {}) {
        super(type);
        Object.assign(this, init);
    }
};

const here = path.dirname(fileURLToPath(import.meta.url));
const evaluator = path.join(here, 'blender', 'gltf_eval.py');

function usage(message) {
    console.error(`error: ${message}`);
    console.error('usage: node scripts/three_check.mjs [--frames N] [--tolerance D] [--shift S] FILE...');
    process.exit(2);
}

function parseArgs(argv) {
    const opts = { frames: 6, tolerance: null, shift: 0, files: [] };
    for (let i = 0; i < argv.length; i++) {
        const a = argv[i];
        const value = () => {
            if (i + 1 >= argv.length) usage(`${a} needs a value`);
            const v = Number(argv[++i]);
            if (!Number.isFinite(v)) usage(`${a} needs a number, got '${argv[i]}'`);
            return v;
        };
        if (a === '--frames') opts.frames = Math.max(2, Math.round(value()));
        else if (a === '--tolerance') opts.tolerance = value();
        else if (a === '--shift') opts.shift = value();
        else if (a.startsWith('--')) usage(`unknown option ${a}`);
        else opts.files.push(a);
    }
    if (opts.files.length === 0) usage('no file given');
    return opts;
}

/** The glTF JSON and an ArrayBuffer three can parse (a .gltf's external buffers inlined as data: URIs). */
function readGltf(file) {
    const bytes = readFileSync(file);
    if (bytes.subarray(0, 4).toString('latin1') === 'glTF') {
        const jsonLength = bytes.readUInt32LE(12);
        const json = JSON.parse(bytes.subarray(20, 20 + jsonLength).toString('utf8'));
        const data = bytes.buffer.slice(bytes.byteOffset, bytes.byteOffset + bytes.byteLength);
        return { json, data };
    }
    const json = JSON.parse(bytes.toString('utf8').replace(/^\uFEFF/, ''));
    for (const b of json.buffers ?? []) {
        if (b.uri && !b.uri.startsWith('data:')) {
            const bin = readFileSync(path.join(path.dirname(file), decodeURIComponent(b.uri)));
            b.uri = `data:application/octet-stream;base64,${bin.toString('base64')}`;
        }
    }
    return { json, data: JSON.stringify(json) };
}

/** Images are not decoded in Node: every texture is an empty Texture (geometry is what is checked). */
const noImages = () => ({
    name: 'scenebake_no_images',
    loadTexture: () => Promise.resolve(new THREE.Texture()),
});

function loadThree(data) {
    const loader = new GLTFLoader();
    loader.register(noImages);
    return new Promise((resolve, reject) => loader.parse(data, '', resolve, reject));
}

/** Times (s) to check and how they were chosen. */
function checkTimes(json, frames) {
    const bake = json.asset?.extras?.scenebake;
    if (bake) {
        const { fps, frame_start: a, frame_end: b } = bake;
        const fs = [];
        for (let k = 0; k < frames - 1; k++) fs.push(Math.round(a + ((b - a) * k) / (frames - 2)));
        fs.push(Math.min(b, Math.floor((a + b) / 2) + 0.5));
        const unique = [...new Set(fs)].sort((x, y) => x - y);
        return unique.map((f) => ({ frame: f, t: f / fps }));
    }
    const anim = json.animations?.[0];
    if (!anim) return [{ frame: null, t: 0 }];
    // Without a record: the key range of the first animation's first sampler.
    const input = json.accessors[anim.samplers[0].input];
    const lo = input.min?.[0] ?? 0;
    const hi = input.max?.[0] ?? 0;
    const out = [];
    for (let k = 0; k < frames; k++) out.push({ frame: null, t: lo + ((hi - lo) * k) / (frames - 1) });
    return out;
}

function reference(file, times) {
    const python = process.env.PYTHON || 'python3';
    const out = execFileSync(python, [evaluator, '--positions', file, ...times.map((x) => String(x.t))], {
        maxBuffer: 1 << 30,
        encoding: 'utf8',
    });
    return JSON.parse(out);
}

/** three's objects made from glTF node `nodeIndex`'s primitives (Mesh, Line, Points), in primitive order. */
function meshesOfNode(gltf, json, nodeIndex) {
    const assoc = gltf.parser.associations;
    let node = null;
    gltf.scene.traverse((o) => {
        if (node === null && assoc.get(o)?.nodes === nodeIndex) node = o;
    });
    if (node === null) return null;
    const meshIndex = json.nodes[nodeIndex].mesh;
    const found = [];
    const visit = (o) => {
        const a = assoc.get(o);
        if (o !== node && a?.nodes !== undefined) return; // another glTF node's subtree
        if ((o.isMesh || o.isLine || o.isPoints) && a?.meshes === meshIndex) found.push({ mesh: o, primitive: a.primitives ?? 0 });
        for (const c of o.children) visit(c);
    };
    visit(node);
    return found.sort((x, y) => x.primitive - y.primitive).map((x) => x.mesh);
}

/** World positions of `meshes` (concatenated) as three evaluates them now. */
function threePositions(meshes) {
    const out = [];
    const v = new THREE.Vector3();
    for (const mesh of meshes) {
        const n = mesh.geometry.attributes.position.count;
        for (let i = 0; i < n; i++) {
            // Lines and points have no CPU morph/skin path in three: their positions as stored.
            if (mesh.isMesh) mesh.getVertexPosition(i, v);
            else v.fromBufferAttribute(mesh.geometry.attributes.position, i);
            v.applyMatrix4(mesh.matrixWorld);
            out.push(v.x, v.y, v.z);
        }
    }
    return out;
}

function maxDistance(a, b) {
    let worst = 0;
    for (let i = 0; i < a.length; i += 3) {
        const d = Math.hypot(a[i] - b[i], a[i + 1] - b[i + 1], a[i + 2] - b[i + 2]);
        if (!(d <= worst)) worst = d; // NaN counts as worst
    }
    return worst;
}

function extent(flat) {
    const lo = [Infinity, Infinity, Infinity];
    const hi = [-Infinity, -Infinity, -Infinity];
    for (let i = 0; i < flat.length; i += 3) {
        for (let k = 0; k < 3; k++) {
            lo[k] = Math.min(lo[k], flat[i + k]);
            hi[k] = Math.max(hi[k], flat[i + k]);
        }
    }
    return Math.hypot(hi[0] - lo[0], hi[1] - lo[1], hi[2] - lo[2]);
}

async function checkFile(file, opts) {
    const failures = [];
    const { json, data } = readGltf(file);
    const gltf = await loadThree(data);
    const times = checkTimes(json, opts.frames);
    const ref = reference(file, times);

    // animations[0] is the bake.
    const bake = json.asset?.extras?.scenebake;
    if (bake) {
        const first = json.animations?.[0]?.name;
        if (first !== bake.animation) {
            failures.push(`animations[0] is '${first}', not the bake '${bake.animation}' (asset.extras.scenebake.animation)`);
        }
        if (gltf.animations[0]?.name !== bake.animation) {
            failures.push(`three's gltf.animations[0] is '${gltf.animations[0]?.name}', not the bake '${bake.animation}'`);
        }
    }

    const targets = ref.nodes.map((r) => ({ ...r, meshes: meshesOfNode(gltf, json, r.node) }));
    for (const t of targets) {
        if (!t.meshes || t.meshes.length === 0) failures.push(`node ${t.node} (${t.name}): three made no mesh of it`);
    }
    const size = Math.max(1, ...targets.map((t) => extent(t.positions[0])));
    const tolerance = opts.tolerance ?? 1e-5 * size;

    const mixer = new THREE.AnimationMixer(gltf.scene);
    const play = (clip) => {
        const action = mixer.clipAction(clip);
        action.setLoop(THREE.LoopOnce, 1);
        action.clampWhenFinished = true;
        action.reset().play();
        return action;
    };
    let bakeAction = gltf.animations.length > 0 ? play(gltf.animations[0]) : null;

    let worst = 0;
    let vertices = 0;
    const compare = (label, indices) => {
        for (const k of indices) {
            if (bakeAction) mixer.setTime(times[k].t + opts.shift);
            gltf.scene.updateMatrixWorld(true);
            for (const t of targets) {
                if (!t.meshes || t.meshes.length === 0) continue;
                const got = threePositions(t.meshes);
                const want = t.positions[k];
                if (got.length !== want.length) {
                    failures.push(`node ${t.node} (${t.name}): three has ${got.length / 3} vertices, the file ${want.length / 3}`);
                    continue;
                }
                const d = maxDistance(got, want);
                worst = Math.max(worst, Number.isNaN(d) ? Infinity : d);
                if (!(d <= tolerance)) {
                    const at = times[k].frame === null ? `t=${times[k].t}s` : `frame ${times[k].frame} (t=${times[k].t.toFixed(4)}s)`;
                    failures.push(`${label}node ${t.node} (${t.name}) at ${at}: three is ${d.toExponential(2)} from the file (tolerance ${tolerance.toExponential(1)})`);
                }
            }
        }
    };
    vertices = targets.reduce((n, t) => n + t.positions[0].length / 3, 0);
    compare('', times.map((_, k) => k));

    // A user switching clips: every other clip played and stopped, then the bake again.
    if (gltf.animations.length > 1) {
        bakeAction.stop();
        for (const clip of gltf.animations.slice(1)) {
            const other = play(clip);
            mixer.setTime(clip.duration / 2);
            other.stop();
        }
        bakeAction = play(gltf.animations[0]);
        compare(`after playing the other ${gltf.animations.length - 1} clip(s), `, [Math.floor(times.length / 2)]);
    }

    return { failures, worst, vertices, frames: times.length, tolerance, animations: gltf.animations.length };
}

const opts = parseArgs(process.argv.slice(2));
let failed = 0;
for (const file of opts.files) {
    let result;
    try {
        result = await checkFile(file, opts);
    } catch (e) {
        console.error(`${file}: FAIL: cannot check: ${e.message ?? e}`);
        failed++;
        continue;
    }
    const { failures, worst, vertices, frames, tolerance, animations } = result;
    const status = failures.length === 0 ? 'ok' : 'FAIL';
    console.log(`${file}: ${status}: three ${THREE.REVISION}, ${vertices} vertices, ${animations} animation(s), ` +
        `${frames} frames, largest distance ${worst.toExponential(2)} (tolerance ${tolerance.toExponential(1)})`);
    for (const f of failures.slice(0, 10)) console.log(`  ${f}`);
    if (failures.length > 10) console.log(`  ... and ${failures.length - 10} more`);
    if (failures.length > 0) failed++;
}
if (failed > 0) {
    console.error(`three_check: ${failed} of ${opts.files.length} file(s) failed`);
    process.exit(1);
}
