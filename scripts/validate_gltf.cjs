// Validates glTF files with the Khronos glTF validator (the npm package `gltf-validator`)
// and prints one line of JSON per file: {"file", "errors", "warnings", "messages"}.
// Exits 1 when a file has errors or cannot be read.
//
// Install: npm install --prefix target/gltf-validator gltf-validator@2.0.0-dev.3.10
// Run:     NODE_PATH=target/gltf-validator/node_modules node scripts/validate_gltf.cjs FILE...
const fs = require("fs");
const path = require("path");
const validator = require("gltf-validator");

async function validate(file) {
  const bytes = new Uint8Array(fs.readFileSync(file));
  const dir = path.dirname(file);
  const report = await validator.validateBytes(bytes, {
    uri: file,
    maxIssues: 50,
    externalResourceFunction: (uri) =>
      new Promise((resolve, reject) => {
        fs.readFile(path.join(dir, decodeURIComponent(uri)), (err, data) =>
          err ? reject(err.toString()) : resolve(new Uint8Array(data)));
      }),
  });
  const messages = report.issues.messages
    .filter((m) => m.severity <= 1)
    .map((m) => `${m.severity === 0 ? "error" : "warning"} ${m.code} at ${m.pointer || ""}: ${m.message}`);
  return { file, errors: report.issues.numErrors, warnings: report.issues.numWarnings, messages };
}

(async () => {
  let failed = false;
  for (const file of process.argv.slice(2)) {
    try {
      const r = await validate(file);
      console.log(JSON.stringify(r));
      failed ||= r.errors > 0;
    } catch (e) {
      console.log(JSON.stringify({ file, errors: -1, warnings: 0, messages: [String(e)] }));
      failed = true;
    }
  }
  process.exit(failed ? 1 : 0);
})();
