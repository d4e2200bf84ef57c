// Copies the page's browser libraries from node_modules/ into static/vendor/, the only place the
// server's static file service can reach. Run by `npm ci` / `npm install` (postinstall).
// uPlot draws the plots; @rerun-io/web-viewer (its ES module, the wasm-bindgen glue and the
// viewer's .wasm) goes to static/vendor/rerun/, so that "View in Rerun" loads nothing from the
// internet.
import { copyFileSync, mkdirSync, existsSync, readFileSync, writeFileSync } from 'node:fs';
import { dirname, join } from 'node:path';
import { fileURLToPath } from 'node:url';

const root = join(dirname(fileURLToPath(import.meta.url)), '..');
const vendor = join(root, 'static', 'vendor');
const rerun = 'node_modules/@rerun-io/web-viewer';

/**
 * [from, to, edit]: `edit` rewrites the text on the way. The web viewer's index.js imports its
 * glue as "./re_viewer" (a bundler resolves the extension); a browser loading the module straight
 * from the server needs the file name, so the one import gets ".js".
 */
const files = [
  ['node_modules/uplot/dist/uPlot.esm.js', 'uPlot.esm.js'],
  ['node_modules/uplot/dist/uPlot.min.css', 'uPlot.min.css'],
  [`${rerun}/index.js`, 'rerun/index.js', (text) => replaceOnce(text, 'import("./re_viewer")', 'import("./re_viewer.js")')],
  [`${rerun}/re_viewer.js`, 'rerun/re_viewer.js'],
  [`${rerun}/re_viewer_bg.wasm`, 'rerun/re_viewer_bg.wasm'],
];

/** `text` with the single occurrence of `from` replaced; fails loudly if the package changed. */
function replaceOnce(text, from, to) {
  const count = text.split(from).length - 1;
  if (count !== 1) {
    throw new Error(`expected one ${from} in the web viewer's index.js, found ${count}`);
  }
  return text.replace(from, to);
}

for (const [from, to, edit] of files) {
  const source = join(root, from);
  if (!existsSync(source)) {
    console.error(`vendor: ${from} is missing; run npm ci first`);
    process.exit(1);
  }
  const target = join(vendor, to);
  mkdirSync(dirname(target), { recursive: true });
  if (edit) {
    writeFileSync(target, edit(readFileSync(source, 'utf8')));
  } else {
    copyFileSync(source, target);
  }
}
console.log(`vendor: copied ${files.length} files into static/vendor/`);
