// The statistics of a result: status, dt beside the stable dt, the stages that ran, the error
// estimate beside the wall time, and the energy over time when it was recorded.

/** @typedef {import("./api.js").Result} Result */
/** @typedef {import("./api.js").Stats} Stats */

/** @param {number | null | undefined} x */
function number(x) {
    if (x === null) return "not finite";
    if (x === undefined) return "–";
    return Math.abs(x) >= 1e4 || (Math.abs(x) < 1e-3 && x !== 0) ? x.toExponential(3) : x.toPrecision(4);
}

/** @param {[string, string][]} rows */
function table(rows) {
    const element = document.createElement("table");
    for (const [name, value] of rows) {
        const row = element.insertRow();
        row.insertCell().textContent = name;
        row.insertCell().textContent = value;
    }
    return element;
}

/** @param {Stats} stats @returns {[string, string][]} */
function rows(stats) {
    /** @type {[string, string][]} */
    const list = [
        ["status", stats.status],
        ["integrator", `${stats.integrator} (${stats.precision})`],
        ["dt", `${number(stats.dt)} s (${stats.dt_source})`],
        ["stable dt", stats.stable_dt === undefined ? "–" : `${number(stats.stable_dt)} s`],
        ["steps", String(stats.steps)],
        ["wall time", `${number(stats.wall_time_s)} s`],
    ];
    const error = stats.error;
    if (error) {
        const estimate = error.unavailable ?? `max ${number(error.max)} m, rms ${number(error.rms)} m (${error.method}, +${number(error.extra_wall_time_s)} s)`;
        list.push(["error estimate", estimate]);
    }
    if (stats.max_strain !== undefined) list.push(["max strain", number(stats.max_strain)]);
    if (stats.stopped_at_rest !== undefined) list.push(["at rest at", `${number(stats.stopped_at_rest)} s`]);
    if (stats.diverged) list.push(["diverged", `step ${stats.diverged.step}: ${stats.diverged.reason}`]);
    if (stats.failure) list.push(["failure", stats.failure]);
    list.push(["stages", stats.stages.join(", ")]);
    return list;
}

/**
 * Draws each energy and their sum over time, with a mark at the frame shown.
 * @param {Result} result @returns {{canvas: HTMLCanvasElement, mark: (t: number) => void} | null}
 */
function energyPlot(result) {
    const frames = result.frames ?? [];
    const energies = frames.filter((f) => f.energy);
    if (energies.length < 2) return null;
    const canvas = document.createElement("canvas");
    canvas.width = 360;
    canvas.height = 150;
    canvas.title = "energy over time: kinetic, gravitational, spring, total";
    const context = canvas.getContext("2d");
    if (!context) return null;
    /** @type {[string, (e: import("./api.js").Schemas["Energy"]) => number][]} */
    const series = [
        ["#d33", (e) => e.kinetic ?? NaN],
        ["#36c", (e) => e.gravitational ?? NaN],
        ["#3a3", (e) => e.spring ?? NaN],
        ["#222", (e) => (e.kinetic ?? NaN) + (e.gravitational ?? NaN) + (e.spring ?? NaN)],
    ];
    const values = series.flatMap(([, pick]) => energies.map((f) => pick(/** @type {import("./api.js").Schemas["Energy"]} */ (f.energy)))).filter(Number.isFinite);
    const low = Math.min(...values);
    const high = Math.max(...values);
    const t0 = energies[0].t;
    const t1 = energies[energies.length - 1].t;
    const x = (/** @type {number} */ t) => 30 + ((t - t0) / (t1 - t0 || 1)) * (canvas.width - 40);
    const y = (/** @type {number} */ e) => canvas.height - 15 - ((e - low) / (high - low || 1)) * (canvas.height - 25);
    const draw = (/** @type {number | null} */ at) => {
        context.clearRect(0, 0, canvas.width, canvas.height);
        context.font = "10px sans-serif";
        context.fillStyle = "#555";
        context.fillText(`${high.toPrecision(3)} J`, 0, 10);
        context.fillText(`${low.toPrecision(3)} J`, 0, canvas.height - 15);
        context.fillText(`${t1.toPrecision(3)} s`, canvas.width - 35, canvas.height - 2);
        for (const [color, pick] of series) {
            context.strokeStyle = color;
            context.beginPath();
            energies.forEach((f, k) => {
                const e = pick(/** @type {import("./api.js").Schemas["Energy"]} */ (f.energy));
                if (k === 0) context.moveTo(x(f.t), y(e));
                else context.lineTo(x(f.t), y(e));
            });
            context.stroke();
        }
        if (at !== null) {
            context.strokeStyle = "#999";
            context.beginPath();
            context.moveTo(x(at), 0);
            context.lineTo(x(at), canvas.height - 15);
            context.stroke();
        }
    };
    draw(null);
    return { canvas, mark: draw };
}

/**
 * Shows `result`'s statistics in `container`; gives what marks the frame shown on the energy plot.
 * @param {HTMLElement} container @param {Result} result @returns {(t: number) => void}
 */
export function showStats(container, result) {
    const plot = energyPlot(result);
    container.replaceChildren(table(rows(result.stats)), ...(plot ? [plot.canvas] : []));
    return plot ? plot.mark : () => {};
}
