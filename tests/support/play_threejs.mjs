// Plays a drape GLB with three.js's own GLTFLoader and AnimationMixer (npm package `three`,
// installed by .ci/run into .ci/node) and checks it against the JSON result of the same run: at
// each keyframe time exactly that frame's morph target shows, fully, and the vertices three.js
// would draw are the frame's positions (within the f32 rounding of the morph deltas), and each
// collider's node (`collider:N`) stands where the result's `colliders` put it at that frame.
//
// usage: node play_threejs.mjs RESULT.glb RESULT.json
// Exits 0 when every frame matches, 1 on a mismatch, 2 if three.js cannot be loaded.
import fs from "fs";
import path from "path";
import { fileURLToPath, pathToFileURL } from "url";

const here = path.dirname(fileURLToPath(import.meta.url));
const threeDir = path.join(here, "..", "..", ".ci", "node", "node_modules", "three");
let THREE, GLTFLoader;
try {
    THREE = await import(pathToFileURL(path.join(threeDir, "build", "three.module.js")));
    ({ GLTFLoader } = await import(pathToFileURL(path.join(threeDir, "examples", "jsm", "loaders", "GLTFLoader.js"))));
} catch (e) {
    console.error(`three.js is not installed (npm ci --prefix .ci/node): ${e.message}`);
    process.exit(2);
}

const [glbPath, jsonPath] = process.argv.slice(2);
const result = JSON.parse(fs.readFileSync(jsonPath, "utf8"));
const frames = result.frames ?? [result.final];
const bytes = fs.readFileSync(glbPath);
const buffer = bytes.buffer.slice(bytes.byteOffset, bytes.byteOffset + bytes.byteLength);

function fail(message) {
    console.error(`mismatch: ${message}`);
    process.exit(1);
}

new GLTFLoader().parse(buffer, "", (gltf) => {
    const objects = [];
    const colliders = [];
    // three.js drops the ':' from object names; the glTF name stays in userData.
    gltf.scene.traverse((o) => {
        if (o.userData.name?.startsWith("collider:")) colliders.push(o);
        else if (o.isMesh || o.isLine) objects.push(o);
    });
    const recorded = result.colliders ?? [];
    if (colliders.length !== recorded.length) fail(`${colliders.length} collider nodes for ${recorded.length} colliders`);
    const bodies = result.mesh.bodies;
    if (objects.length !== bodies.length) fail(`${objects.length} objects for ${bodies.length} bodies`);
    if (gltf.animations.length !== 1) fail(`${gltf.animations.length} animations`);
    const clip = gltf.animations[0];
    const mixer = new THREE.AnimationMixer(gltf.scene);
    const action = mixer.clipAction(clip);
    action.setLoop(THREE.LoopOnce, 1);
    action.clampWhenFinished = true;
    action.play();
    const times = clip.tracks[0].times;
    if (times.length !== frames.length) fail(`${times.length} keyframes for ${frames.length} frames`);
    let checked = 0;
    for (let k = 0; k < frames.length; k++) {
        mixer.setTime(times[k]);
        for (const object of colliders) {
            const entry = recorded.find((c) => c.name === object.userData.name);
            if (!entry) fail(`no collider named ${object.userData.name}`);
            const transform = entry.frames ? entry.frames[k] : { translation: [0, 0, 0], rotation: [0, 0, 0, 1] };
            const q = transform.rotation;
            const length = Math.hypot(...q);
            const shown = [...object.position.toArray(), ...object.quaternion.toArray()];
            const expected = [...transform.translation, ...q.map((x) => x / length)].map(Math.fround);
            shown.forEach((x, i) => { if (x !== expected[i]) fail(`${object.name}: at frame ${k} shows ${shown}, the JSON has ${expected}`); });
        }
        for (const object of objects) {
            const body = bodies.find((b) => b.name === object.name);
            if (!body) fail(`no body named ${object.name}`);
            const influences = object.morphTargetInfluences;
            influences.forEach((w, j) => {
                if (w !== (j === k ? 1 : 0)) fail(`${object.name}: at frame ${k} target ${j} has weight ${w}`);
            });
            const geometry = object.geometry;
            const base = geometry.attributes.position.array;
            const targets = geometry.morphAttributes.position;
            if (!geometry.morphTargetsRelative) fail("morph targets are not relative");
            const expected = frames[k].positions;
            for (let i = 0; i < base.length; i++) {
                let shown = base[i];
                targets.forEach((t, j) => { shown += influences[j] * t.array[i]; });
                const x = result.stats.precision === "f32" ? Math.fround(expected[3 * body.offset + i]) : expected[3 * body.offset + i];
                const delta = targets[k].array[i];
                const tolerance = Math.abs(delta) * 2 ** -24 + Math.abs(x) * 2 ** -52 + 2 ** -150;
                if (Math.abs(shown - x) > tolerance) fail(`${object.name}: frame ${k}, scalar ${i}: shows ${shown}, the JSON has ${x}`);
                checked++;
            }
        }
    }
    console.log(`three.js ${THREE.REVISION} played ${frames.length} frames of ${objects.length} objects: ${checked} coordinates match, and ${colliders.length} colliders at ${frames.length} frames`);
}, (e) => fail(`GLTFLoader: ${e.message ?? e}`));
