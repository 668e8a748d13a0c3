// The viewer page: wires the editor, the job's progress, the player, the statistics, the job
// list and the sweep panel together. `document.body.dataset.state` says where the page is
// (`idle`, `running`, `loaded`, `error`), and `dataset.job` and `dataset.frames` which result it
// shows, for people and tests alike.

import * as api from "./api.js";
import { holdsSweep, loadExamples, sceneText, showErrors, showProblem } from "./editor.js";
import { showJobs } from "./jobs.js";
import { Player } from "./player.js";
import { showStats } from "./stats.js";
import { showSweep } from "./sweeps.js";

/** @template {HTMLElement} T @param {string} id @param {new () => T} kind @returns {T} */
function element(id, kind) {
    const found = document.getElementById(id);
    if (!(found instanceof kind)) throw new Error(`no #${id}`);
    return found;
}

const token = element("token", HTMLInputElement);
const submit = element("submit", HTMLButtonElement);
const progress = element("progress", HTMLProgressElement);
const status = element("status", HTMLElement);
const playButton = element("play", HTMLButtonElement);
const scrub = element("scrub", HTMLInputElement);
const timeLabel = element("time", HTMLElement);
const speed = element("speed", HTMLSelectElement);
const hold = element("hold", HTMLInputElement);
const shading = element("shading", HTMLSelectElement);
const statsPanel = element("stats", HTMLElement);
const jobList = element("jobs", HTMLElement);
const sweepId = element("sweep-id", HTMLInputElement);
const sweepPanel = element("sweep", HTMLElement);

token.value = sessionStorage.getItem("drape-token") ?? "";
token.addEventListener("change", () => sessionStorage.setItem("drape-token", token.value));
api.useToken(() => token.value.trim());

const player = new Player(element("view", HTMLElement));
/** @type {(t: number) => void} */
let markEnergy = () => {};

/** @param {"idle" | "running" | "loaded" | "error"} state @param {string} message */
function setState(state, message) {
    document.body.dataset.state = state;
    status.textContent = message;
}

player.onFrame = (/** @type {number} */ k) => {
    const frame = player.frames[k];
    scrub.value = String(k);
    timeLabel.textContent = `${frame.t.toFixed(3)} s`;
    markEnergy(frame.t);
    playButton.textContent = player.playing ? "Pause" : "Play";
};

/** Plays the result of job `id`. @param {string} id */
async function open(id) {
    const result = await api.result(id);
    player.load(result);
    const frames = player.frames.length;
    scrub.max = String(Math.max(frames - 1, 0));
    scrub.disabled = playButton.disabled = frames < 2;
    markEnergy = showStats(statsPanel, result);
    player.show(0);
    document.body.dataset.frames = String(frames);
    document.body.dataset.job = id;
    setState("loaded", `job ${id}: ${result.stats.status}, ${frames} frames`);
}

/** Submits the editor's scene as a job, follows it to its end and plays its result. */
async function run() {
    showErrors([]);
    progress.value = 0;
    if (holdsSweep()) {
        const sweep = await api.submitSweep(sceneText());
        sweepId.value = sweep.id;
        setState("idle", `sweep ${sweep.id} queued`);
        await showSweep(sweepPanel, sweep.id);
        return;
    }
    const job = await api.submitJob(sceneText());
    setState("running", `job ${job.id} ${job.status}`);
    const ended = await api.follow(job.id, (p) => {
        progress.value = p.fraction;
        status.textContent = `job ${job.id}: step ${p.step} of ${p.steps}, t = ${p.t.toFixed(3)} s`;
    });
    progress.value = 1;
    if (ended.status === "succeeded" || ended.status === "diverged") {
        await open(job.id);
    } else {
        setState("error", `job ${job.id} ${ended.status}${ended.message ? `: ${ended.message}` : ""}`);
    }
    await showJobs(jobList, openChosen).catch(() => {});
}

/** @param {string} id */
function openChosen(id) {
    open(id).catch((e) => {
        showProblem(e);
        setState("error", `job ${id} has no result to show`);
    });
}

submit.addEventListener("click", () => {
    submit.disabled = true;
    run()
        .catch((e) => {
            showProblem(e);
            setState("error", "the server refused it");
        })
        .finally(() => (submit.disabled = false));
});
playButton.addEventListener("click", () => {
    if (player.playing) player.pause();
    else player.play();
    playButton.textContent = player.playing ? "Pause" : "Play";
});
scrub.addEventListener("input", () => {
    player.pause();
    player.seek(Number(scrub.value));
});
speed.addEventListener("change", () => (player.speed = Number(speed.value)));
hold.addEventListener("change", () => (player.hold = hold.checked));
shading.addEventListener("change", () => player.setShading(/** @type {import("./shading.js").Shading} */ (shading.value)));
element("refresh-jobs", HTMLButtonElement).addEventListener("click", () => showJobs(jobList, openChosen).catch(showProblem));
element("load-sweep", HTMLButtonElement).addEventListener("click", () => showSweep(sweepPanel, sweepId.value.trim()).catch(showProblem));

setState("idle", "");
loadExamples().catch(showProblem);
showJobs(jobList, openChosen).catch(() => {});
