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
import { artifacts, base, launch, waitForServer } from './harness.mjs';

/** The browser's log line for the refusal the test provokes on purpose. */
const LOGGED_422 = /Failed to load resource: the server responded with a status of 422/;

let context;
let page;
let profile;
const consoleErrors = [];

async function postJson(path, body) {
  const response = await fetch(`${base}${path}`, {
    method: 'POST',
    headers: { 'content-type': 'application/json' },
    body: JSON.stringify(body),
  });
  return { status: response.status, body: await response.json() };
}

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
