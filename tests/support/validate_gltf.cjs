// Validates glTF binaries with the Khronos glTF-Validator (npm package `gltf-validator`,
// installed by .ci/run into .ci/node). Prints each file's issue counts and messages; exits 1 if
// any file has an error, 2 if the validator cannot be loaded.
"use strict";
const fs = require("fs");
const path = require("path");

let validator;
try {
    validator = require(path.join(__dirname, "..", "..", ".ci", "node", "node_modules", "gltf-validator"));
} catch (e) {
    try {
        validator = require("gltf-validator");
    } catch (e2) {
        console.error("gltf-validator is not installed: npm ci --prefix .ci/node");
        process.exit(2);
    }
}

async function main(files) {
    let failed = false;
    for (const file of files) {
        const report = await validator.validateBytes(new Uint8Array(fs.readFileSync(file)), {
            maxIssues: 0,
            format: "glb",
        });
        const issues = report.issues;
        console.log(`${file}: ${issues.numErrors} errors, ${issues.numWarnings} warnings, ` +
            `${issues.numInfos} infos, ${issues.numHints} hints (validator ${report.validatorVersion})`);
        for (const m of issues.messages) {
            console.log(`  [${["error", "warning", "info", "hint"][m.severity]}] ${m.code} ${m.pointer || ""}: ${m.message}`);
        }
        if (issues.numErrors > 0) failed = true;
    }
    process.exit(failed ? 1 : 0);
}

main(process.argv.slice(2)).catch((e) => {
    console.error(e);
    process.exit(2);
});
