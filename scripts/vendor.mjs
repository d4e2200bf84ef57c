// Copies the page's browser libraries from node_modules/ into static/vendor/, the only place the
// server's static file service can reach. Run by `npm ci` / `npm install` (postinstall).
import { copyFileSync, mkdirSync, existsSync } from 'node:fs';
import { dirname, join } from 'node:path';
import { fileURLToPath } from 'node:url';

const root = join(dirname(fileURLToPath(import.meta.url)), '..');
const vendor = join(root, 'static', 'vendor');
const files = [
  ['node_modules/uplot/dist/uPlot.esm.js', 'uPlot.esm.js'],
  ['node_modules/uplot/dist/uPlot.min.css', 'uPlot.min.css'],
];

mkdirSync(vendor, { recursive: true });
for (const [from, to] of files) {
  const source = join(root, from);
  if (!existsSync(source)) {
    console.error(`vendor: ${from} is missing; run npm ci first`);
    process.exit(1);
  }
  copyFileSync(source, join(vendor, to));
}
console.log(`vendor: copied ${files.length} files into static/vendor/`);
