// Validate a .glb with the Khronos glTF validator; print its report as JSON on stdout.
// usage: node validate.cjs FILE.glb
const fs = require("fs");
const validator = require("gltf-validator");

const data = new Uint8Array(fs.readFileSync(process.argv[2]));
validator
  .validateBytes(data, { maxIssues: 1000, writeTimestamp: false })
  .then((report) => console.log(JSON.stringify(report)))
  .catch((error) => {
    console.error(String(error));
    process.exit(2);
  });
