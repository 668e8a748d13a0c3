// The ways a body can be drawn: smooth Blinn-Phong, flat, a checker texture, the wireframe of
// its triangles, and a strain heat map.

import * as THREE from "three";

/** @typedef {"smooth" | "flat" | "checker" | "wireframe" | "strain"} Shading */

/** The cloth's colour: the browser tests look for it on screen. */
export const CLOTH_COLOR = 0xe8702a;
/** The colliders' colour. */
export const COLLIDER_COLOR = 0x8aa0b8;

/** A checker texture, 8 × 8 squares. */
function checker() {
    const canvas = document.createElement("canvas");
    canvas.width = canvas.height = 256;
    const context = canvas.getContext("2d");
    if (!context) throw new Error("no 2D canvas");
    for (let i = 0; i < 8; i++) {
        for (let j = 0; j < 8; j++) {
            context.fillStyle = (i + j) % 2 ? "#e8702a" : "#f6e3c8";
            context.fillRect(32 * i, 32 * j, 32, 32);
        }
    }
    const texture = new THREE.CanvasTexture(canvas);
    texture.colorSpace = THREE.SRGBColorSpace;
    return texture;
}

/** @type {THREE.Texture | undefined} */
let checkerTexture;

/** The material a surface is drawn with. @param {Shading} shading @returns {THREE.Material} */
export function surfaceMaterial(shading) {
    const side = THREE.DoubleSide;
    switch (shading) {
        case "flat":
            return new THREE.MeshPhongMaterial({ color: CLOTH_COLOR, flatShading: true, side });
        case "checker":
            checkerTexture ??= checker();
            return new THREE.MeshPhongMaterial({ map: checkerTexture, shininess: 20, side });
        case "wireframe":
            return new THREE.MeshBasicMaterial({ color: CLOTH_COLOR, wireframe: true });
        case "strain":
            return new THREE.MeshPhongMaterial({ vertexColors: true, shininess: 10, side });
        default:
            return new THREE.MeshPhongMaterial({ color: CLOTH_COLOR, shininess: 40, specular: 0x333333, side });
    }
}

/** The colour of strain `s` on a scale up to `top`: blue at 0 through green to red at `top`. */
export function strainColor(/** @type {number} */ s, /** @type {number} */ top, /** @type {THREE.Color} */ into) {
    const x = top > 0 ? Math.min(Math.max(s / top, 0), 1) : 0;
    return into.setHSL((1 - x) * 0.66, 0.9, 0.5);
}
