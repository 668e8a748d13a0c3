// The public HTTP API of drape, as the viewer calls it: every request carries the token the
// user gave, and every error is the server's problem body. Types come from drape-api.d.ts,
// generated from openapi/openapi.yaml.

/** @typedef {import("./drape-api").components["schemas"]} Schemas */
/** @typedef {Schemas["Result"]} Result */
/** @typedef {Schemas["ResultCollider"]} ResultCollider */
/** @typedef {Schemas["Frame"]} Frame */
/** @typedef {Schemas["Stats"]} Stats */
/** @typedef {Schemas["Job"]} Job */
/** @typedef {Schemas["Progress"]} Progress */
/** @typedef {Schemas["Problem"]} Problem */
/** @typedef {Schemas["Sweep"]} Sweep */
/** @typedef {import("./drape-api").operations["listJobs"]["responses"]["200"]["content"]["application/json"]} JobPage */
/** @typedef {{name: string, scene: unknown}} Example */

/** A request the server refused, with its problem body. */
export class ProblemError extends Error {
    /** @param {Problem} problem */
    constructor(problem) {
        super(`${problem.title}: ${problem.detail}`);
        this.problem = problem;
    }
}

/** @type {() => string} */
let tokenSource = () => "";

/** Where each request finds its bearer token. @param {() => string} source */
export function useToken(source) {
    tokenSource = source;
}

/** @param {Record<string, string>} [extra] @returns {Record<string, string>} */
function headers(extra = {}) {
    const token = tokenSource();
    return token ? { ...extra, Authorization: `Bearer ${token}` } : extra;
}

/**
 * Sends a request and gives the response, or throws the server's problem.
 * @param {string} path @param {RequestInit} [init] @returns {Promise<Response>}
 */
async function send(path, init = {}) {
    const response = await fetch(path, { ...init, headers: headers(/** @type {Record<string, string>} */ (init.headers ?? {})) });
    if (!response.ok) {
        const type = response.headers.get("content-type") ?? "";
        if (type.startsWith("application/problem+json")) throw new ProblemError(await response.json());
        throw new Error(`${response.status} ${response.statusText}`);
    }
    return response;
}

/** @returns {Promise<Example[]>} */
export async function examples() {
    const body = await (await send("/examples")).json();
    return body.examples;
}

/** Queues a scene. @param {string} scene JSON text @returns {Promise<Job>} */
export async function submitJob(scene) {
    const response = await send("/jobs", { method: "POST", body: scene, headers: { "Content-Type": "application/json" } });
    return response.json();
}

/** Queues a sweep. @param {string} sweep JSON text @returns {Promise<Sweep>} */
export async function submitSweep(sweep) {
    const response = await send("/sweeps", { method: "POST", body: sweep, headers: { "Content-Type": "application/json" } });
    return response.json();
}

/** @param {string} id @returns {Promise<Job>} */
export async function job(id) {
    return (await send(`/jobs/${encodeURIComponent(id)}`)).json();
}

/** @returns {Promise<JobPage>} */
export async function jobs() {
    return (await send("/jobs?limit=50")).json();
}

/** A job's result as JSON. @param {string} id @returns {Promise<Result>} */
export async function result(id) {
    return (await send(`/jobs/${encodeURIComponent(id)}/result?format=json`)).json();
}

/** @param {string} id @returns {Promise<Sweep>} */
export async function sweep(id) {
    return (await send(`/sweeps/${encodeURIComponent(id)}`)).json();
}

/** A sweep's table as CSV. @param {string} id @returns {Promise<string>} */
export async function sweepCsv(id) {
    return (await send(`/sweeps/${encodeURIComponent(id)}?format=csv`)).text();
}

/** A sweep's work-precision plot. @param {string} id @returns {Promise<Blob>} */
export async function sweepPlot(id) {
    return (await send(`/sweeps/${encodeURIComponent(id)}/plot.svg`)).blob();
}

/**
 * Follows a job's server-sent events until it ends (fetch rather than EventSource, which cannot
 * send a token), calling `onProgress` with each progress event; gives the ended job.
 * @param {string} id @param {(progress: Progress) => void} onProgress @returns {Promise<Job>}
 */
export async function follow(id, onProgress) {
    const response = await send(`/jobs/${encodeURIComponent(id)}/events`, { headers: { Accept: "text/event-stream" } });
    if (!response.body) throw new Error("the event stream has no body");
    const reader = response.body.pipeThrough(new TextDecoderStream()).getReader();
    let buffer = "";
    for (;;) {
        const { value, done } = await reader.read();
        if (done) break;
        buffer += value.replaceAll("\r\n", "\n");
        let end;
        while ((end = buffer.indexOf("\n\n")) >= 0) {
            const event = parseEvent(buffer.slice(0, end));
            buffer = buffer.slice(end + 2);
            if (event.name === "progress") onProgress(JSON.parse(event.data));
            else if (event.name === "end") return JSON.parse(event.data);
            else if (event.name === "error") throw new Error(JSON.parse(event.data).detail);
        }
    }
    return job(id);
}

/** One event's name and data. @param {string} text @returns {{name: string, data: string}} */
function parseEvent(text) {
    let name = "message";
    const data = [];
    for (const line of text.split("\n")) {
        if (line.startsWith("event:")) name = line.slice(6).trim();
        else if (line.startsWith("data:")) data.push(line.slice(5).replace(/^ /, ""));
    }
    return { name, data: data.join("\n") };
}
