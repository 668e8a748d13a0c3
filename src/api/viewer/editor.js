// The scene editor: an example to start from, the JSON text, and the server's objections to it,
// each at the JSON Pointer the problem body names.

import * as api from "./api.js";

/** @param {string} id @returns {HTMLElement} */
function element(id) {
    const found = document.getElementById(id);
    if (!found) throw new Error(`no #${id}`);
    return found;
}

const text = /** @type {HTMLTextAreaElement} */ (element("scene"));
const picker = /** @type {HTMLSelectElement} */ (element("examples"));
const errors = element("errors");

/** Fills the example list; choosing one puts its scene in the editor. */
export async function loadExamples() {
    const list = await api.examples();
    for (const example of list) {
        const option = document.createElement("option");
        option.value = example.name;
        option.textContent = example.name;
        picker.append(option);
    }
    picker.addEventListener("change", () => {
        const chosen = list.find((e) => e.name === picker.value);
        if (chosen) text.value = JSON.stringify(chosen.scene, null, 2);
        showErrors([]);
    });
}

/** The editor's text. */
export function sceneText() {
    return text.value;
}

/** Puts `scene` in the editor. @param {string} scene */
export function setSceneText(scene) {
    text.value = scene;
}

/** Whether the editor holds a sweep (a document with `scene` and `vary`) rather than a scene. */
export function holdsSweep() {
    try {
        const document = JSON.parse(text.value);
        return document !== null && typeof document === "object" && "scene" in document && "vary" in document;
    } catch {
        return false;
    }
}

/**
 * Lists the problems: each field's pointer and what is wrong with it, or the problem's detail.
 * @param {{pointer: string, detail: string}[]} list
 */
export function showErrors(list) {
    errors.replaceChildren(
        ...list.map(({ pointer, detail }) => {
            const item = document.createElement("li");
            const code = document.createElement("code");
            code.textContent = pointer === "" ? "(document)" : pointer;
            item.append(code, `: ${detail}`);
            item.addEventListener("click", () => select(pointer));
            return item;
        }),
    );
}

/** Shows the problem a request met. @param {unknown} error */
export function showProblem(error) {
    if (error instanceof api.ProblemError) {
        showErrors(error.problem.errors?.length ? error.problem.errors : [{ pointer: "", detail: error.problem.detail }]);
    } else {
        showErrors([{ pointer: "", detail: String(error) }]);
    }
}

/** Selects in the text the key the pointer's last token names, as a hint of where it is. @param {string} pointer */
function select(pointer) {
    const last = pointer.split("/").pop()?.replaceAll("~1", "/").replaceAll("~0", "~");
    if (!last) return;
    const at = text.value.indexOf(`"${last}"`);
    if (at >= 0) {
        text.focus();
        text.setSelectionRange(at, at + last.length + 2);
    }
}
