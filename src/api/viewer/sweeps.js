// A sweep: its table (the CSV the server makes) and its work-precision plot (the server's SVG).

import * as api from "./api.js";

/** Splits CSV text into rows of fields (RFC 4180 quoting). @param {string} text */
export function parseCsv(text) {
    /** @type {string[][]} */
    const rows = [];
    let row = [];
    let field = "";
    let quoted = false;
    for (let i = 0; i < text.length; i++) {
        const c = text[i];
        if (quoted) {
            if (c === '"' && text[i + 1] === '"') {
                field += '"';
                i++;
            } else if (c === '"') quoted = false;
            else field += c;
        } else if (c === '"') quoted = true;
        else if (c === ",") {
            row.push(field);
            field = "";
        } else if (c === "\n") {
            row.push(field.replace(/\r$/, ""));
            rows.push(row);
            row = [];
            field = "";
        } else field += c;
    }
    if (field !== "" || row.length > 0) rows.push([...row, field]);
    return rows;
}

/**
 * Shows sweep `id` in `container`: its progress, table and plot.
 * @param {HTMLElement} container @param {string} id
 */
export async function showSweep(container, id) {
    const sweep = await api.sweep(id);
    const heading = document.createElement("p");
    heading.textContent = `${sweep.progress.finished ?? 0} of ${sweep.progress.runs ?? sweep.variants} runs ended${sweep.complete ? "" : " (still running)"}`;
    const [head, ...body] = parseCsv(await api.sweepCsv(id));
    const table = document.createElement("table");
    const header = table.createTHead().insertRow();
    for (const name of head ?? []) {
        const cell = document.createElement("th");
        cell.textContent = name;
        header.append(cell);
    }
    const rows = table.createTBody();
    for (const fields of body) {
        const row = rows.insertRow();
        for (const value of fields) row.insertCell().textContent = value;
    }
    const plot = document.createElement("img");
    plot.alt = "work-precision plot";
    plot.src = URL.createObjectURL(await api.sweepPlot(id));
    container.replaceChildren(heading, table, plot);
}
