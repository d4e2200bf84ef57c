// Browser test of the page's Sweeps section: headless Chromium (Debian's package, driven by
// playwright-core) against the geomint server in GEOMINT_URL. The presets come from the server;
// the csv1 stability preset, made smaller, runs as an NDJSON stream whose progress reaches every
// cell; the heatmap's readout gives, cell by cell, the numbers of the API's own answer for the
// same request; the difference view gives the ratio of two runs' values; a refused request shows
// the server's message with its field; the sweep downloads as JSON and .rrd. A screenshot goes to
// artifacts/.

import { test, before, after } from 'node:test';
import assert from 'node:assert/strict';
import { rm } from 'node:fs/promises';
import { join } from 'node:path';
import {
  LOGGED_422, artifacts, base, launch, openSection, postJson, waitForServer,
} from './harness.mjs';


let context;
let page;
let profile;
const consoleErrors = [];

async function settled(states, timeout = 60_000) {
  await page.waitForFunction((wanted) => wanted.includes(document.querySelector('#sweep').dataset.sweepState),
    states, { timeout });
  return page.getAttribute('#sweep', 'data-sweep-state');
}

/** Points at cell (col, row) of the map and returns the readout data. */
async function readAt(col, row) {
  // A redraw replaces the canvas and lays it out in the next animation frame: aim after that
  // frame, or the pointer may land where the old layout put the cell.
  await page.evaluate(() => new Promise((done) => requestAnimationFrame(() => requestAnimationFrame(done))));
  // The pointer reaches only what is in the window, and the map's lower rows may lie below it
  // (under a header whose links wrap onto another line).
  await page.locator('#sw-canvas').scrollIntoViewIfNeeded();
  const [x, y] = await page.evaluate(([c, r]) => window.geomint.sweep.map.cellCentre(c, r), [col, row]);
  const box = await page.locator('#sw-canvas').boundingBox();
  // From outside the map, so that the move reaches the new canvas even when it ends where the
  // pointer already was.
  await page.mouse.move(0, 0);
  await page.mouse.move(box.x + x, box.y + y);
  return page.$eval('#sw-readout', (n) => ({ ...n.dataset, text: n.textContent }));
}

before(async () => {
  assert.ok(base, 'set GEOMINT_URL to the server under test (scripts/test-browser does)');
  await waitForServer();
  ({ context, page, profile } = await launch({ width: 1280, height: 900 }, consoleErrors));
  await page.goto(`${base}/`);
  await page.waitForSelector('body[data-run-state="idle"]', { timeout: 15_000 });
  await page.waitForFunction(() => !document.querySelector('#sw-run').disabled, null, { timeout: 15_000 });
  await openSection(page, 'sweep');
});

after(async () => {
  await context?.close();
  if (profile) await rm(profile, { recursive: true, force: true });
});

test('the presets are the server’s and a sweep reads back the API’s numbers cell by cell', async () => {
  const presets = await (await fetch(`${base}/api/v1/studies/sweep/presets`)).json();
  assert.deepEqual(await page.$$eval('#sw-preset option', (os) => os.map((o) => o.value)), presets.map((p) => p.id));
  await page.selectOption('#sw-preset', 'csv1_stability');
  const request = JSON.parse(await page.inputValue('#sw-spec'));
  assert.deepEqual(request, presets.find((p) => p.id === 'csv1_stability').request);
  // Smaller, and with a second method to compare.
  request.axes[0].n = 6;
  request.axes[1].n = 5;
  request.methods = ['csv1', 'csv2'];
  await page.fill('#sw-spec', JSON.stringify(request));
  await page.locator('#sw-run').scrollIntoViewIfNeeded();
  await page.click('#sw-run');
  assert.equal(await settled(['done', 'error']), 'done');
  assert.deepEqual(await page.evaluate(() => window.geomint.sweep.lastProgress), { type: 'progress', done: 30, total: 30 });
  const { status, body: api } = await postJson('/api/v1/studies/sweep', request);
  assert.equal(status, 200);
  const shown = await page.evaluate(() => window.geomint.sweep.last.doc);
  delete shown.wall_ms;
  delete api.wall_ms;
  assert.deepEqual(shown, api);
  assert.deepEqual(await page.$$eval('#sw-metric option', (os) => os.map((o) => o.value)),
    ['energy_error_max', 'energy_error_final', 'energy_error_l2', 'diverged_at']);

  // Every cell's readout is the API's value of the chosen metric and run.
  for (const [run, metric] of [['0', 'energy_error_max'], ['1', 'diverged_at']]) {
    await page.selectOption('#sw-run-select', run);
    await page.selectOption('#sw-metric', metric);
    for (let row = 0; row < 5; row++) {
      for (let col = 0; col < 6; col++) {
        const d = await readAt(col, row);
        const k = row * 6 + col;
        assert.equal(Number(d.cell), k);
        const expected = api.runs[Number(run)][metric][k];
        assert.equal(d.value, expected == null ? '' : String(expected), `${metric} at cell ${k}`);
      }
    }
  }
  // Some cells diverge and some do not: the map is not one colour.
  const diverged = api.runs[0].diverged_at;
  assert.ok(diverged.some((t) => t == null) && diverged.some((t) => t != null));

  // The difference view: csv1 against csv2, the ratio in the readout.
  await page.selectOption('#sw-metric', 'energy_error_max');
  await page.selectOption('#sw-run-select', '0');
  await page.selectOption('#sw-compare', '1');
  const k = api.runs[0].energy_error_max.findIndex((e, i) => e != null && api.runs[1].energy_error_max[i] != null);
  const d = await readAt(k % 6, Math.floor(k / 6));
  assert.equal(Number(d.cell), k);
  assert.equal(d.other, String(api.runs[1].energy_error_max[k]));
  const ratio = api.runs[0].energy_error_max[k] / api.runs[1].energy_error_max[k];
  assert.match(d.text, /ratio /);
  const shownRatio = Number(d.text.match(/ratio ([^;.]+(\.\d+)?(e[-+]?\d+)?)/)[1]);
  assert.ok(Math.abs(shownRatio / ratio - 1) < 1e-2, `${shownRatio} vs ${ratio}`);

  const [json] = await Promise.all([page.waitForEvent('download'), page.click('#sw-download-json')]);
  assert.equal(json.suggestedFilename(), 'geomint-sweep.json');
  const [rrd] = await Promise.all([page.waitForEvent('download'), page.click('#sw-download-rrd')]);
  assert.equal(rrd.suggestedFilename(), 'geomint-sweep.rrd');
  await page.locator('#sweep').screenshot({ path: join(artifacts, 'page-sweep.png') });
});

test('a refused sweep shows the server’s message and field', async () => {
  const request = JSON.parse(await page.inputValue('#sw-spec'));
  request.axes[0].n = 1000;
  await page.fill('#sw-spec', JSON.stringify(request));
  await page.click('#sw-run');
  assert.equal(await settled(['done', 'error']), 'error');
  const message = await page.textContent('#err-sw-spec');
  assert.match(message, /axes\[0\]\.n/);
  assert.equal(await page.getAttribute('#sw-spec', 'aria-invalid'), 'true');
  await page.fill('#sw-spec', '{"system": ');
  await page.click('#sw-run');
  assert.equal(await settled(['error']), 'error');
  assert.match(await page.textContent('#err-sw-spec'), /not JSON/);
  assert.deepEqual(consoleErrors.filter((e) => !LOGGED_422.test(e)), []);
});

/** The colour of cell (col, row) of the sweep's map, as drawn. */
async function cellPixel(col, row) {
  // A redraw lays the new map out in the next animation frame.
  await page.waitForFunction(() => window.geomint.sweep.map?.cssWidth > 0 && !window.geomint.sweep.pending);
  return page.evaluate(([c, r]) => {
    const { map } = window.geomint.sweep;
    const ctx = map.canvas.getContext('2d');
    const dpr = map.canvas.width / map.cssWidth;
    const [x, y] = map.cellCentre(c, r);
    return [...ctx.getImageData(Math.round(x * dpr), Math.round(y * dpr), 1, 1).data].slice(0, 3);
  }, [col, row]);
}

test('the heatmap says its scale and what its colourless cells mean; a new sweep clears the readout', async () => {
  await page.selectOption('#sw-preset', 'csv1_stability');
  const request = JSON.parse(await page.inputValue('#sw-spec'));
  assert.equal(request.every, 100, 'the preset samples every 100 steps');
  await page.click('#sw-run');
  assert.equal(await settled(['done', 'error']), 'done');
  const doc = await page.evaluate(() => window.geomint.sweep.last.doc);
  assert.equal(doc.runs.length, 1);
  assert.match(await page.textContent('#sw-status'), / × 1 run of /);
  const [nx] = [doc.axes[0].n];
  const run = doc.runs[0];
  const diverged = run.diverged_at.findIndex((t) => t != null);
  const stable = run.diverged_at.findIndex((t, k) => t == null && !run.errors[k] && run.energy_error_max[k] > 0);
  assert.ok(diverged >= 0 && stable >= 0, 'the preset has cells that diverge and cells that do not');

  // The error map: a log scale, said in words under the bar; a diverged cell is black, and the
  // legend says so.
  await page.selectOption('#sw-metric', 'energy_error_max');
  await page.waitForFunction(() => document.querySelector('#sw-scale-caption').textContent.includes('largest'));
  assert.match(await page.textContent('#sw-scale-caption'), /^largest \|energy error\|, on a log scale from .+ \(dark blue\) to .+ \(yellow\)\.$/);
  const errorLegend = await page.$$eval('#sw-scale-legend li', (lis) => lis.map((li) => [li.dataset.kind, li.textContent]));
  assert.ok(errorLegend.some(([kind, text]) => kind === 'diverged' && /diverged/.test(text)), JSON.stringify(errorLegend));
  assert.deepEqual(await cellPixel(diverged % nx, Math.floor(diverged / nx)), [0, 0, 0]);
  // The ticks are values (powers of ten), not their logarithms.
  const ticks = await page.evaluate(() => window.geomint.sweep.scale(window.geomint.sweep.currentViewState).ticks.map(([, t]) => t));
  assert.ok(ticks.every((t) => /^1e-?\d+$/.test(t)), `ticks ${ticks}`);

  // The divergence map: a run that never diverged is white, the opposite end of the legend from
  // a diverged cell on the error map; the scale runs over the whole time span, so times found at
  // the sampled steps 200 to 203 are one colour band, not stripes.
  await page.selectOption('#sw-metric', 'diverged_at');
  await page.waitForFunction(() => document.querySelector('#sw-scale-caption').textContent.startsWith('time of divergence'));
  assert.match(await page.textContent('#sw-scale-caption'), /from 0 \(dark blue\).*every 100 steps.*upper bounds/);
  const legend = await page.$$eval('#sw-scale-legend li', (lis) => lis.map((li) => li.dataset.kind));
  assert.ok(legend.includes('never'), `legend ${legend}`);
  assert.match(await page.textContent('#sw-scale-legend [data-kind="never"]'), /did not diverge/);
  assert.deepEqual(await cellPixel(stable % nx, Math.floor(stable / nx)), [255, 255, 255]);
  const view = await page.evaluate(() => ({ lo: window.geomint.sweep.currentViewState.lo, hi: window.geomint.sweep.currentViewState.hi }));
  assert.equal(view.lo, 0);
  assert.ok(view.hi >= request.t_end, `the time scale ends at ${view.hi}`);
  const readout = await readAt(stable % nx, Math.floor(stable / nx));
  assert.match(readout.text, /did not diverge before t_end/);
  await page.locator('#sw-results').screenshot({ path: join(artifacts, 'sweep-divergence.png') });

  // A new sweep: the readout no longer describes a cell of the last one.
  await readAt(1, 1);
  assert.equal(await page.getAttribute('#sw-readout', 'data-cell'), String(nx + 1));
  const smaller = { ...request, axes: [{ ...request.axes[0], n: 3 }, { ...request.axes[1], n: 2 }] };
  await page.fill('#sw-spec', JSON.stringify(smaller));
  await page.click('#sw-run');
  assert.equal(await settled(['done', 'error']), 'done');
  assert.equal(await page.getAttribute('#sw-readout', 'data-cell'), null);
  assert.match(await page.textContent('#sw-readout'), /^Point at the map/);
  assert.deepEqual(consoleErrors.filter((e) => !LOGGED_422.test(e)), []);
});
