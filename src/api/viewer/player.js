// Plays a result: a BufferGeometry per body moved to each frame's positions, the colliders
// where the result puts them, an orbit camera, and play, pause, scrub, speed and hold.

import * as THREE from "three";
import { OrbitControls } from "three/addons/controls/OrbitControls.js";
import { CLOTH_COLOR, COLLIDER_COLOR, strainColor, surfaceMaterial } from "./shading.js";

/** @typedef {import("./api.js").Result} Result */
/** @typedef {import("./api.js").Frame} Frame */
/** @typedef {import("./api.js").ResultCollider} ResultCollider */
/** @typedef {import("./shading.js").Shading} Shading */

/**
 * One body drawn: its particle range, its triangles re-based to it, and its object.
 * @typedef {{offset: number, count: number, geometry: THREE.BufferGeometry, object: THREE.Mesh | THREE.Line, surface: boolean, restEdges: Float64Array | null, edges: Uint32Array | null}} DrawnBody
 */

export class Player {
    /** @param {HTMLElement} container */
    constructor(container) {
        this.container = container;
        this.renderer = new THREE.WebGLRenderer({ antialias: true, preserveDrawingBuffer: true });
        this.renderer.setPixelRatio(window.devicePixelRatio);
        container.append(this.renderer.domElement);
        this.scene = new THREE.Scene();
        this.scene.background = new THREE.Color(0xf0f0ee);
        this.camera = new THREE.PerspectiveCamera(45, 1, 0.01, 1000);
        this.camera.position.set(2, 2, 3);
        this.controls = new OrbitControls(this.camera, this.renderer.domElement);
        this.scene.add(new THREE.HemisphereLight(0xffffff, 0x8d8d8d, 1.6));
        const sun = new THREE.DirectionalLight(0xffffff, 2.2);
        sun.position.set(3, 5, 2);
        this.scene.add(sun);
        /** The result's objects, replaced with each result. */
        this.world = new THREE.Group();
        this.scene.add(this.world);
        /** @type {Result | null} */
        this.result = null;
        /** @type {Frame[]} */
        this.frames = [];
        /** @type {DrawnBody[]} */
        this.bodies = [];
        /** @type {{group: THREE.Group, entry: ResultCollider}[]} */
        this.colliders = [];
        /** @type {Shading} */
        this.shading = "smooth";
        this.frame = 0;
        this.time = 0;
        this.playing = false;
        this.speed = 1;
        this.hold = true;
        this.strainTop = 0;
        /** @type {(frame: number) => void} */
        this.onFrame = () => {};
        this.clock = new THREE.Clock();
        new ResizeObserver(() => this.resize()).observe(container);
        this.resize();
        this.renderer.setAnimationLoop(() => this.tick());
    }

    resize() {
        const { clientWidth: w, clientHeight: h } = this.container;
        if (w === 0 || h === 0) return;
        this.renderer.setSize(w, h);
        this.camera.aspect = w / h;
        this.camera.updateProjectionMatrix();
    }

    /** Shows `result` from its first frame. @param {Result} result */
    load(result) {
        this.clear();
        this.result = result;
        this.frames = result.frames ?? (result.final ? [result.final] : []);
        const triangles = result.mesh.triangles;
        for (const body of result.mesh.bodies) this.bodies.push(this.drawBody(body.offset, body.count, triangles));
        for (const entry of result.colliders ?? []) this.colliders.push(this.drawCollider(entry));
        this.strainTop = strainScale(this.frames, this.bodies);
        this.frame = 0;
        this.time = this.frames[0]?.t ?? 0;
        this.show(0);
        this.frameCamera();
    }

    clear() {
        for (const object of [...this.world.children]) {
            object.traverse((o) => {
                if (o instanceof THREE.Mesh || o instanceof THREE.Line) o.geometry.dispose();
            });
            this.world.remove(object);
        }
        this.bodies = [];
        this.colliders = [];
        this.result = null;
        this.frames = [];
        this.playing = false;
    }

    /**
     * @param {number} offset @param {number} count @param {number[]} triangles all triangles, flat
     * @returns {DrawnBody}
     */
    drawBody(offset, count, triangles) {
        const indices = [];
        for (let k = 0; k < triangles.length; k += 3) {
            if (triangles[k] >= offset && triangles[k] < offset + count) {
                indices.push(triangles[k] - offset, triangles[k + 1] - offset, triangles[k + 2] - offset);
            }
        }
        const geometry = new THREE.BufferGeometry();
        geometry.setAttribute("position", new THREE.BufferAttribute(new Float32Array(3 * count), 3));
        const surface = indices.length > 0;
        /** @type {THREE.Mesh | THREE.Line} */
        let object;
        let edges = null;
        let restEdges = null;
        if (surface) {
            geometry.setIndex(indices);
            geometry.setAttribute("color", new THREE.BufferAttribute(new Float32Array(3 * count), 3));
            const first = this.frames[0]?.positions;
            if (first) geometry.setAttribute("uv", planarUv(first, offset, count));
            edges = uniqueEdges(indices);
            restEdges = first ? edgeLengths(first, offset, edges) : null;
            object = new THREE.Mesh(geometry, surfaceMaterial(this.shading));
        } else {
            object = new THREE.Line(geometry, new THREE.LineBasicMaterial({ color: CLOTH_COLOR }));
            object.add(new THREE.Points(geometry, new THREE.PointsMaterial({ color: CLOTH_COLOR, size: 6, sizeAttenuation: false })));
        }
        object.frustumCulled = false;
        this.world.add(object);
        return { offset, count, geometry, object, surface, edges, restEdges };
    }

    /** @param {ResultCollider} entry */
    drawCollider(entry) {
        // Pushed back in depth, so that cloth lying on a collider is drawn over it rather than
        // through it where their triangles cut each other.
        const material = new THREE.MeshPhongMaterial({
            color: COLLIDER_COLOR, side: THREE.DoubleSide, shininess: 10,
            polygonOffset: true, polygonOffsetFactor: 4, polygonOffsetUnits: 16,
        });
        const group = new THREE.Group();
        group.name = entry.name;
        const mesh = new THREE.Mesh(colliderGeometry(entry, this.reach()), material);
        const at = entry.center ?? entry.point;
        if (at) mesh.position.set(at[0], at[1], at[2]);
        if (entry.type === "plane" && entry.normal) {
            const normal = new THREE.Vector3(...entry.normal);
            if (normal.lengthSq() > 0) mesh.quaternion.setFromUnitVectors(new THREE.Vector3(0, 0, 1), normal.normalize());
        }
        group.add(mesh);
        this.world.add(group);
        return { group, entry };
    }

    /** The farthest a particle of the first frame is from the origin, at least 5 m. */
    reach() {
        const positions = this.frames[0]?.positions ?? [];
        let far = 0;
        for (let i = 0; i < positions.length; i += 3) far = Math.max(far, Math.hypot(positions[i], positions[i + 1], positions[i + 2]));
        return Math.max(5, 2 * far);
    }

    /** Shows frame `k`. @param {number} k */
    show(k) {
        const frame = this.frames[k];
        if (!frame) return;
        this.frame = k;
        const positions = frame.positions ?? [];
        const normals = frame.normals;
        const color = new THREE.Color();
        for (const body of this.bodies) {
            const position = /** @type {THREE.BufferAttribute} */ (body.geometry.getAttribute("position"));
            position.array.set(positions.slice(3 * body.offset, 3 * (body.offset + body.count)));
            position.needsUpdate = true;
            if (body.surface) {
                if (normals) {
                    body.geometry.setAttribute("normal", new THREE.BufferAttribute(new Float32Array(normals.slice(3 * body.offset, 3 * (body.offset + body.count))), 3));
                } else {
                    body.geometry.computeVertexNormals();
                }
                if (this.shading === "strain") this.paintStrain(body, positions, color);
            }
            body.geometry.computeBoundingSphere();
        }
        for (const { group, entry } of this.colliders) {
            const transform = entry.frames?.[k];
            if (transform) {
                const [tx, ty, tz] = transform.translation;
                group.position.set(tx, ty, tz);
                const [x, y, z, w] = transform.rotation;
                group.quaternion.set(x, y, z, w).normalize();
            }
        }
        this.onFrame(k);
    }

    /**
     * Colours each vertex by the largest strain of its triangles' edges against the first frame.
     * @param {DrawnBody} body @param {number[]} positions @param {THREE.Color} color
     */
    paintStrain(body, positions, color) {
        if (!body.edges || !body.restEdges) return;
        const strain = new Float64Array(body.count);
        const lengths = edgeLengths(positions, body.offset, body.edges);
        for (let e = 0; e < lengths.length; e++) {
            const rest = body.restEdges[e];
            const s = rest > 0 ? lengths[e] / rest - 1 : 0;
            for (const v of [body.edges[2 * e], body.edges[2 * e + 1]]) strain[v] = Math.max(strain[v], s);
        }
        const colors = /** @type {THREE.BufferAttribute} */ (body.geometry.getAttribute("color"));
        for (let v = 0; v < body.count; v++) {
            strainColor(strain[v], this.strainTop, color);
            colors.setXYZ(v, color.r, color.g, color.b);
        }
        colors.needsUpdate = true;
    }

    /** @param {Shading} shading */
    setShading(shading) {
        this.shading = shading;
        for (const body of this.bodies) {
            if (body.object instanceof THREE.Mesh) {
                /** @type {THREE.Material} */ (body.object.material).dispose();
                body.object.material = surfaceMaterial(shading);
            }
        }
        this.show(this.frame);
    }

    /** Moves to frame `k` and the time it was recorded at. @param {number} k */
    seek(k) {
        this.time = this.frames[k]?.t ?? 0;
        this.show(k);
    }

    play() {
        if (this.frames.length < 2) return;
        if (this.frame === this.frames.length - 1) this.seek(0);
        this.playing = true;
        this.clock.getDelta();
    }

    pause() {
        this.playing = false;
    }

    tick() {
        const elapsed = this.clock.getDelta();
        if (this.playing && this.frames.length > 1) {
            this.time += elapsed * this.speed;
            const last = this.frames[this.frames.length - 1].t;
            if (this.time >= last) {
                if (this.hold) {
                    this.time = last;
                    this.playing = false;
                } else {
                    this.time = this.frames[0].t + (this.time - last);
                }
            }
            let k = this.frame;
            if (this.frames[k].t > this.time) k = 0;
            while (k + 1 < this.frames.length && this.frames[k + 1].t <= this.time) k++;
            if (k !== this.frame) this.show(k);
        }
        this.controls.update();
        this.renderer.render(this.scene, this.camera);
    }

    /** Points the camera at the bodies over their first and last frames. */
    frameCamera() {
        const box = new THREE.Box3();
        for (const frame of [this.frames[0], this.frames[this.frames.length - 1]]) {
            const positions = frame?.positions ?? [];
            for (let i = 0; i < positions.length; i += 3) box.expandByPoint(new THREE.Vector3(positions[i], positions[i + 1], positions[i + 2]));
        }
        if (box.isEmpty()) return;
        const center = box.getCenter(new THREE.Vector3());
        const radius = Math.max(box.getSize(new THREE.Vector3()).length() / 2, 0.1);
        const distance = radius / Math.sin((this.camera.fov * Math.PI) / 360);
        this.camera.position.copy(center).add(new THREE.Vector3(0.55, 0.45, 0.7).normalize().multiplyScalar(distance * 1.1));
        this.camera.near = distance / 100;
        this.camera.far = distance * 100;
        this.camera.updateProjectionMatrix();
        this.controls.target.copy(center);
        this.controls.update();
    }
}

/**
 * A collider's shape as three.js geometry, centred on the origin (the mesh is placed at the
 * centre or point); a mesh collider is in the scene's coordinates as it is.
 * @param {ResultCollider} entry @param {number} planeSize
 * @returns {THREE.BufferGeometry}
 */
function colliderGeometry(entry, planeSize) {
    switch (entry.type) {
        case "sphere":
            return new THREE.SphereGeometry(entry.radius ?? 0, 48, 24);
        case "box": {
            const [x, y, z] = entry.half_extents ?? [0, 0, 0];
            return new THREE.BoxGeometry(2 * x, 2 * y, 2 * z);
        }
        case "cylinder":
            return new THREE.CylinderGeometry(entry.radius ?? 0, entry.radius ?? 0, entry.height ?? 0, 48);
        case "plane":
            return new THREE.PlaneGeometry(2 * planeSize, 2 * planeSize);
        default: {
            const geometry = new THREE.BufferGeometry();
            geometry.setAttribute("position", new THREE.BufferAttribute(new Float32Array(entry.vertices ?? []), 3));
            geometry.setIndex(entry.triangles ?? []);
            geometry.computeVertexNormals();
            return geometry;
        }
    }
}

/**
 * Texture coordinates from the first frame, projected on the two axes along which the body
 * spreads most.
 * @param {number[]} positions @param {number} offset @param {number} count
 */
function planarUv(positions, offset, count) {
    const min = [Infinity, Infinity, Infinity];
    const max = [-Infinity, -Infinity, -Infinity];
    for (let v = 0; v < count; v++) {
        for (let a = 0; a < 3; a++) {
            min[a] = Math.min(min[a], positions[3 * (offset + v) + a]);
            max[a] = Math.max(max[a], positions[3 * (offset + v) + a]);
        }
    }
    const axes = [0, 1, 2].sort((a, b) => max[b] - min[b] - (max[a] - min[a]));
    const [u, w] = axes;
    const uv = new Float32Array(2 * count);
    for (let v = 0; v < count; v++) {
        uv[2 * v] = (positions[3 * (offset + v) + u] - min[u]) / (max[u] - min[u] || 1);
        uv[2 * v + 1] = (positions[3 * (offset + v) + w] - min[w]) / (max[w] - min[w] || 1);
    }
    return new THREE.BufferAttribute(uv, 2);
}

/** Each edge of the triangles once, as vertex pairs. @param {number[]} indices */
function uniqueEdges(indices) {
    const seen = new Set();
    const edges = [];
    for (let k = 0; k < indices.length; k += 3) {
        for (const [a, b] of [[indices[k], indices[k + 1]], [indices[k + 1], indices[k + 2]], [indices[k + 2], indices[k]]]) {
            const key = a < b ? `${a},${b}` : `${b},${a}`;
            if (!seen.has(key)) {
                seen.add(key);
                edges.push(a, b);
            }
        }
    }
    return Uint32Array.from(edges);
}

/** @param {number[]} positions @param {number} offset @param {Uint32Array} edges */
function edgeLengths(positions, offset, edges) {
    const lengths = new Float64Array(edges.length / 2);
    for (let e = 0; e < lengths.length; e++) {
        const a = 3 * (offset + edges[2 * e]);
        const b = 3 * (offset + edges[2 * e + 1]);
        lengths[e] = Math.hypot(positions[a] - positions[b], positions[a + 1] - positions[b + 1], positions[a + 2] - positions[b + 2]);
    }
    return lengths;
}

/**
 * The top of the strain colour scale: the largest spring strain the run recorded, else the
 * largest edge strain of the frames.
 * @param {Frame[]} frames @param {DrawnBody[]} bodies
 */
function strainScale(frames, bodies) {
    let top = 0;
    for (const frame of frames) for (const s of frame.strain ?? []) if (s !== null) top = Math.max(top, s);
    if (top > 0) return top;
    for (const frame of frames) {
        for (const body of bodies) {
            if (!body.edges || !body.restEdges || !frame.positions) continue;
            const lengths = edgeLengths(frame.positions, body.offset, body.edges);
            lengths.forEach((l, e) => { if (body.restEdges && body.restEdges[e] > 0) top = Math.max(top, l / body.restEdges[e] - 1); });
        }
    }
    return top || 0.01;
}
