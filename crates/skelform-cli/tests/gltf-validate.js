// Runs the Khronos glTF validator (the npm package gltf-validator) on .glb files and
// prints one JSON line per file: its error, warning and info counts and every message of
// severity error or warning. Exits 1 if any file has an error.
//
// usage: node gltf-validate.js PATH/TO/node_modules/gltf-validator FILE.glb...
'use strict';
const fs = require('fs');
const [validatorDir, ...files] = process.argv.slice(2);
const validator = require(validatorDir);

(async () => {
    let errors = 0;
    for (const file of files) {
        const report = await validator.validateBytes(new Uint8Array(fs.readFileSync(file)), {
            uri: file,
            maxIssues: 200,
        });
        const issues = report.issues;
        console.log(JSON.stringify({
            file,
            errors: issues.numErrors,
            warnings: issues.numWarnings,
            infos: issues.numInfos,
            messages: issues.messages.filter((m) => m.severity <= 1),
        }));
        errors += issues.numErrors;
    }
    process.exit(errors > 0 ? 1 : 0);
})().catch((e) => {
    console.error(`gltf-validator failed: ${e}`);
    process.exit(2);
});
