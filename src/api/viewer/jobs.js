// The job list: recent jobs, newest first; choosing one that ended plays its result.

import * as api from "./api.js";

/**
 * Lists the server's recent jobs in `list`; `open` is called with the id of one chosen.
 * @param {HTMLElement} list @param {(id: string) => void} open
 */
export async function showJobs(list, open) {
    const page = await api.jobs();
    list.replaceChildren(
        ...page.jobs.map((job) => {
            const item = document.createElement("li");
            const when = job.created_at.replace("T", " ").slice(0, 19);
            item.textContent = `${job.status} · ${job.particles} particles · ${when}`;
            item.title = job.id;
            item.dataset.id = job.id;
            item.addEventListener("click", () => open(job.id));
            return item;
        }),
    );
}
