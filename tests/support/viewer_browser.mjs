// Drives drape's viewer page in Chromium with playwright-core (both pinned in .ci/node): the
// page loads with no console error; a screenshot of the empty view is the control; then each
// example named is picked, run through the page to its last frame (played at 4×, held), and
// screenshotted, and the scrubber is moved back to the first frame and screenshotted again.
// Pixels of the cloth's colour are counted in each screenshot (decoded here from the PNG).
//
// usage: node viewer_browser.mjs BASE_URL SCREENSHOT_DIR EXAMPLE...
// Prints one JSON line per example and one for the control; exits 1 on a page error, 2 if
// playwright-core or Chromium cannot be started.
import fs from "fs";
import path from "path";
import zlib from "zlib";
import { fileURLToPath, pathToFileURL } from "url";

const here = path.dirname(fileURLToPath(import.meta.url));
let chromium;
try {
    ({ chromium } = await import(pathToFileURL(path.join(here, "..", "..", ".ci", "node", "node_modules", "playwright-core", "index.mjs"))));
} catch (e) {
    console.error(`playwright-core is not installed (npm ci --prefix .ci/node): ${e.message}`);
    process.exit(2);
}

const [base, shots, ...examples] = process.argv.slice(2);
fs.mkdirSync(shots, { recursive: true });

/** RGBA pixels of an 8-bit, non-interlaced PNG (what Chromium's screenshots are). */
function decodePng(bytes) {
    let offset = 8;
    let width = 0, height = 0, channels = 0;
    const data = [];
    while (offset < bytes.length) {
        const length = bytes.readUInt32BE(offset);
        const type = bytes.toString("ascii", offset + 4, offset + 8);
        const body = bytes.subarray(offset + 8, offset + 8 + length);
        if (type === "IHDR") {
            width = body.readUInt32BE(0);
            height = body.readUInt32BE(4);
            if (body[8] !== 8 || body[12] !== 0) throw new Error("not an 8-bit non-interlaced PNG");
            channels = { 2: 3, 6: 4 }[body[9]];
            if (!channels) throw new Error(`PNG colour type ${body[9]}`);
        } else if (type === "IDAT") data.push(body);
        offset += 12 + length;
    }
    const raw = zlib.inflateSync(Buffer.concat(data));
    const stride = width * channels;
    const out = Buffer.alloc(width * height * 4);
    let previous = Buffer.alloc(stride);
    for (let y = 0; y < height; y++) {
        const filter = raw[y * (stride + 1)];
        const line = Buffer.from(raw.subarray(y * (stride + 1) + 1, (y + 1) * (stride + 1)));
        for (let i = 0; i < stride; i++) {
            const a = i >= channels ? line[i - channels] : 0;
            const b = previous[i];
            const c = i >= channels ? previous[i - channels] : 0;
            let add = 0;
            if (filter === 1) add = a;
            else if (filter === 2) add = b;
            else if (filter === 3) add = (a + b) >> 1;
            else if (filter === 4) {
                const p = a + b - c, pa = Math.abs(p - a), pb = Math.abs(p - b), pc = Math.abs(p - c);
                add = pa <= pb && pa <= pc ? a : pb <= pc ? b : c;
            }
            line[i] = (line[i] + add) & 255;
        }
        for (let x = 0; x < width; x++) {
            for (let k = 0; k < 4; k++) out[4 * (y * width + x) + k] = k < channels ? line[x * channels + k] : 255;
        }
        previous = line;
    }
    return { width, height, pixels: out };
}

/** Whether a pixel has the cloth's orange (0xe8702a, lit or shaded): red well above green and blue. */
function isCloth(r, g, b) {
    return r - b > 60 && r - g > 30;
}

function clothPixels(png) {
    const { pixels } = decodePng(png);
    let count = 0;
    for (let i = 0; i < pixels.length; i += 4) if (isCloth(pixels[i], pixels[i + 1], pixels[i + 2])) count++;
    return count;
}

/** Pixels of a strong colour (the cloth in any shading; not the grey background or colliders). */
function colouredPixels(png) {
    const { pixels } = decodePng(png);
    let count = 0;
    for (let i = 0; i < pixels.length; i += 4) {
        const [r, g, b] = [pixels[i], pixels[i + 1], pixels[i + 2]];
        if (Math.max(r, g, b) - Math.min(r, g, b) > 80) count++;
    }
    return count;
}

function changedPixels(a, b) {
    const [x, y] = [decodePng(a).pixels, decodePng(b).pixels];
    let count = 0;
    for (let i = 0; i < x.length; i += 4) if (x[i] !== y[i] || x[i + 1] !== y[i + 1] || x[i + 2] !== y[i + 2]) count++;
    return count;
}

let browser;
try {
    browser = await chromium.launch({
        executablePath: process.env.CHROMIUM ?? "/usr/bin/chromium",
        args: ["--no-sandbox", "--use-angle=swiftshader", "--enable-unsafe-swiftshader"],
    });
} catch (e) {
    console.error(`Chromium cannot be started: ${e.message}`);
    process.exit(2);
}
const problems = [];
const page = await browser.newPage({ viewport: { width: 1280, height: 800 } });
// Chromium logs a refused request as a console error: expected only for the scene refused on purpose.
let refusing = false;
page.on("console", (message) => {
    if (message.type() !== "error") return;
    if (refusing && /status of 422/.test(message.text())) return;
    problems.push(`console: ${message.text()}`);
});
page.on("pageerror", (error) => problems.push(`page error: ${error.message}`));
page.on("requestfailed", (request) => problems.push(`request failed: ${request.url()}`));

const view = page.locator("#view");
try {
    await page.goto(`${base}/`);
    await page.waitForFunction(() => document.querySelectorAll("#examples option").length > 1, null, { timeout: 20000 });
    const control = await view.screenshot({ path: path.join(shots, "control-empty.png") });
    console.log(JSON.stringify({ control: true, clothPixels: clothPixels(control), title: await page.title() }));
    for (const name of examples) {
        const previous = await page.evaluate(() => document.body.dataset.job ?? "");
        await page.selectOption("#examples", name);
        await page.click("#submit");
        await page.waitForFunction(
            (previous) => document.body.dataset.state === "error" || (document.body.dataset.state === "loaded" && document.body.dataset.job !== previous),
            previous,
            { timeout: 60000 },
        );
        const state = await page.evaluate(() => ({ state: document.body.dataset.state, status: document.getElementById("status")?.textContent, frames: Number(document.body.dataset.frames) }));
        if (state.state !== "loaded") {
            problems.push(`${name}: ${state.status} ${await page.locator("#errors").textContent()}`);
            continue;
        }
        await page.selectOption("#speed", "4");
        await page.click("#play");
        await page.waitForFunction(() => {
            const scrub = /** @type {HTMLInputElement} */ (document.getElementById("scrub"));
            return scrub.value === scrub.max && document.getElementById("play")?.textContent === "Play";
        }, null, { timeout: 60000 });
        await page.waitForTimeout(100);
        const last = await view.screenshot({ path: path.join(shots, `${name}-final.png`) });
        await page.locator("#scrub").fill("0");
        await page.waitForTimeout(100);
        const first = await view.screenshot({ path: path.join(shots, `${name}-first.png`) });
        const shown = await page.evaluate(() => document.getElementById("time")?.textContent);
        console.log(JSON.stringify({ example: name, frames: state.frames, status: state.status, clothPixels: clothPixels(last), firstFrameClothPixels: clothPixels(first), scrubbedPixelsChanged: changedPixels(last, first), timeShownAfterScrub: shown }));
    }
    // Every shading of the last result shown draws the cloth, at its final frame.
    await page.locator("#scrub").fill(await page.locator("#scrub").getAttribute("max") ?? "0");
    for (const shading of ["flat", "checker", "wireframe", "strain", "smooth"]) {
        await page.selectOption("#shading", shading);
        await page.waitForTimeout(100);
        const shot = await view.screenshot({ path: path.join(shots, `shading-${shading}.png`) });
        console.log(JSON.stringify({ shading, clothPixels: clothPixels(shot), colouredPixels: colouredPixels(shot) }));
    }
    // A scene the server refuses: its problems are listed at their JSON Pointers.
    await page.fill("#scene", JSON.stringify({ duration: -1, bodies: [{ type: "cloth", mass: 0 }] }));
    refusing = true;
    await page.click("#submit");
    await page.waitForFunction(() => document.body.dataset.state === "error", null, { timeout: 20000 });
    refusing = false;
    const errors = await page.locator("#errors li").allTextContents();
    console.log(JSON.stringify({ refused: true, errors }));
    // A sweep pasted in the editor: its table and plot once every run has ended.
    await page.fill("#scene", fs.readFileSync(path.join(here, "..", "..", "examples", "sweeps", "tiny.json"), "utf8"));
    await page.click("#submit");
    await page.waitForFunction(() => document.querySelector("#sweep table") !== null, null, { timeout: 20000 });
    for (let tries = 0; tries < 100 && (await page.locator("#sweep p").textContent())?.includes("still running"); tries++) {
        await page.waitForTimeout(200);
        await page.click("#load-sweep");
        await page.waitForTimeout(100);
    }
    await page.waitForFunction(() => {
        const plot = document.querySelector("#sweep img");
        return plot instanceof HTMLImageElement && plot.complete && plot.naturalWidth > 0;
    }, null, { timeout: 20000 });
    const sweep = await page.evaluate(() => ({
        heading: document.querySelector("#sweep p")?.textContent,
        rows: document.querySelectorAll("#sweep tbody tr").length,
        columns: [...document.querySelectorAll("#sweep thead th")].map((th) => th.textContent),
        plotWidth: /** @type {HTMLImageElement} */ (document.querySelector("#sweep img")).naturalWidth,
    }));
    console.log(JSON.stringify({ sweep }));
    await page.screenshot({ path: path.join(shots, "page-sweep.png") });
} catch (e) {
    problems.push(`driver: ${e.message}`);
}
await browser.close();
for (const problem of problems) console.log(`problem: ${problem}`);
process.exit(problems.length ? 1 : 0);
