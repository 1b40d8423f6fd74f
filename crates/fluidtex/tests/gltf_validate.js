// Runs the Khronos glTF validator on one file and prints its issue counts
// and messages as JSON. Usage: node gltf_validate.js VALIDATOR_DIR FILE.glb
const fs = require('fs');
const validator = require(process.argv[2]);
const data = new Uint8Array(fs.readFileSync(process.argv[3]));
validator.validateBytes(data, { uri: process.argv[3], maxIssues: 50 }).then(
  (report) => {
    const i = report.issues;
    console.log(JSON.stringify({
      errors: i.numErrors, warnings: i.numWarnings, infos: i.numInfos, hints: i.numHints,
      messages: i.messages.map((m) => `${m.code} ${m.pointer || ''}: ${m.message}`),
    }));
  },
  (err) => { console.error(String(err)); process.exit(2); });
