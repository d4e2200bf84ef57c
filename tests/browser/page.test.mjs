// Browser test of the page in static/: headless Chromium (Debian's package, driven by
// playwright-core) against a running geomint server whose address is in GEOMINT_URL (see
// scripts/test-browser, which starts one). It runs a preset with two methods, compares the points
// of every plotted series with the samples the API returns for the same request, checks that the
// console stays free of errors, submits h = -1 and looks for the API's message beside the h field,
// cancels a long run, checks the phone layout, and saves screenshots to artifacts/.

import { test, before, after } from 'node:test';
import assert from 'node:assert/strict';
import { mkdtemp, mkdir, readFile, rm } from 'node:fs/promises';
import { tmpdir } from 'node:os';
import { join, dirname } from 'node:path';
import { fileURLToPath } from 'node:url';
import { chromium } from 'playwright-core';
import { presetRequest } from '../../static/js/presets.js';

const root = join(dirname(fileURLToPath(import.meta.url)), '..', '..');
const artifacts = join(root, 'artifacts');
const base = (process.env.GEOMINT_URL || '').replace(/\/$/, '');
const chromiumPath = process.env.CHROMIUM_PATH || '/usr/bin/chromium';
const CHROMIUM_FLAGS = [
  '--headless', '--no-sandbox', '--disable-gpu', '--disable-quic', '--no-first-run',
  '--disable-background-networking', '--disable-component-update', '--disable-sync',
];
/** The preset the test runs: paper 000's pendulum, modin_3s against heun at h = 0.2. */
const PRESET = ['p000-pendulum', '3s-heun'];

let context;
let page;
let profile;
const consoleErrors = [];
const failedRequests = [];

/** POSTs a simulation request to the API as JSON; returns status and body. */
async function simulate(request) {
  const response = await fetch(`${base}/api/v1/simulate`, {
    method: 'POST',
    headers: { 'content-type': 'application/json' },
    body: JSON.stringify(request),
  });
  return { status: response.status, body: await response.json() };
}

async function waitForServer() {
  const deadline = Date.now() + 30_000;
  for (;;) {
    try {
      const response = await fetch(`${base}/healthz`);
      if (response.ok) return;
    } catch {
      // not listening yet
    }
    if (Date.now() > deadline) throw new Error(`no server answers at ${base}`);
    await new Promise((resolve) => setTimeout(resolve, 200));
  }
}

before(async () => {
  assert.ok(base, 'set GEOMINT_URL to the server under test (scripts/test-browser does)');
  await waitForServer();
  await mkdir(artifacts, { recursive: true });
  profile = await mkdtemp(join(tmpdir(), 'geomint-chromium-'));
  // A persistent context is how playwright takes an explicit, fresh --user-data-dir.
  context = await chromium.launchPersistentContext(profile, {
    executablePath: chromiumPath,
    headless: true,
    args: CHROMIUM_FLAGS,
    viewport: { width: 1280, height: 800 },
  });
  page = context.pages()[0] || (await context.newPage());
  page.on('console', (message) => {
    if (message.type() === 'error') consoleErrors.push(message.text());
  });
  page.on('pageerror', (error) => consoleErrors.push(`uncaught: ${error.message}`));
  page.on('requestfailed', (request) => {
    failedRequests.push(`${new URL(request.url()).pathname} ${request.failure()?.errorText}`);
  });
  await page.goto(`${base}/`);
  await page.waitForSelector('body[data-run-state="idle"]', { timeout: 15_000 });
});

after(async () => {
  await context?.close();
  if (profile) await rm(profile, { recursive: true, force: true });
});

test('every form control has a label', async () => {
  const unlabelled = await page.evaluate(() =>
    [...document.querySelectorAll('#sim-form input, #sim-form select')]
      .filter((c) => c.labels.length === 0 && !c.getAttribute('aria-label'))
      .map((c) => c.id || c.name));
  assert.deepEqual(unlabelled, []);
});

test('a preset with two methods plots every sample the API returns', async () => {
  const request = presetRequest(...PRESET);
  assert.equal(request.methods.length, 2);

  // From the keyboard: Tab from the top of the page to the preset's button, then Enter.
  const target = PRESET.join('/');
  let tabs = 0;
  while ((await page.evaluate(() => document.activeElement?.dataset?.preset)) !== target) {
    assert.ok(++tabs <= 40, `the preset button ${target} is not reachable with Tab`);
    await page.keyboard.press('Tab');
  }
  await page.keyboard.press('Enter');
  await page.waitForSelector('body[data-run-state="done"]', { timeout: 30_000 });

  // The same request, answered as one JSON document, is what the page should have drawn.
  const { status, body } = await simulate(request);
  assert.equal(status, 200);
  const runs = body.runs;
  assert.deepEqual(runs.map((r) => r.method), ['modin_3s', 'heun']);
  for (const run of runs) assert.ok(run.t.length > 100, `${run.method}: ${run.t.length} samples`);

  const nonzero = (values) => values.filter((v) => v !== 0 && Number.isFinite(v)).length;
  const expected = {
    energy: runs.map((r) => r.t.length),
    energy_error: runs.map((r) => nonzero(r.energy_error)),
    'phase:0': runs.map((r) => r.t.length),
    'trajectory:0': runs.map((r) => r.t.length),
    drift: runs.map((r) => r.dissipation_drift.length),
  };
  const plotted = await page.evaluate(() => window.geomint.pointCounts());
  assert.deepEqual(Object.keys(plotted).sort(), Object.keys(expected).sort());
  for (const [key, counts] of Object.entries(expected)) {
    assert.deepEqual(plotted[key].map((s) => s.label), runs.map((r) => r.method), `${key}: series labels`);
    assert.deepEqual(plotted[key].map((s) => s.points), counts, `${key}: points per series`);
  }

  // Each plot is a drawn uPlot canvas of a real size.
  const canvases = await page.evaluate(() =>
    [...window.geomint.charts.values()].map(({ plot }) => [plot.ctx.canvas.width, plot.ctx.canvas.height]));
  assert.equal(canvases.length, Object.keys(expected).length);
  for (const [w, h] of canvases) assert.ok(w > 150 && h > 100, `canvas ${w}×${h}`);

  // Stats table: one row per method with the API's step and force-evaluation counts.
  const rows = await page.$$eval('#stats-body tr', (trs) =>
    trs.map((tr) => [...tr.children].map((cell) => cell.textContent.trim())));
  assert.equal(rows.length, 2);
  rows.forEach((cells, i) => {
    assert.ok(cells[0].endsWith(runs[i].method));
    assert.equal(cells[1], String(runs[i].stats.steps));
    assert.equal(cells[2], String(runs[i].stats.force_evaluations));
    assert.equal(cells[4], String(runs[i].t.length));
  });

  // The JSON download holds the same samples.
  const [download] = await Promise.all([page.waitForEvent('download'), page.click('#download-json')]);
  assert.match(download.suggestedFilename(), /^geomint-pendulum-.*\.json$/);
  const saved = JSON.parse(await readFile(await download.path(), 'utf8'));
  assert.deepEqual(saved.request, request);
  assert.deepEqual(saved.runs.map((r) => r.t.length), runs.map((r) => r.t.length));
  assert.deepEqual(saved.runs.map((r) => r.energy), runs.map((r) => r.energy));
  assert.deepEqual(saved.runs.map((r) => r.stats.steps), runs.map((r) => r.stats.steps));

  assert.deepEqual(consoleErrors, [], 'console errors during the run');
  assert.deepEqual(failedRequests, [], 'failed requests during the run');
  await page.screenshot({ path: join(artifacts, 'page.png'), fullPage: true });
});

test('an API validation error is shown beside its field', async () => {
  const before = consoleErrors.length;
  const request = { ...presetRequest(...PRESET), h: -1 };
  const { status, body } = await simulate(request);
  assert.equal(status, 422);
  assert.equal(body.error.field, 'h');

  await page.fill('#h', '-1');
  await page.click('#run');
  await page.waitForSelector('body[data-run-state="error"]', { timeout: 10_000 });
  const message = page.locator('.field:has(#h) #err-h');
  await message.waitFor({ state: 'visible', timeout: 5_000 });
  assert.equal((await message.textContent()).trim(), body.error.message);
  assert.equal(await page.getAttribute('#h', 'aria-invalid'), 'true');
  assert.equal(await page.evaluate(() => document.activeElement?.id), 'h');
  // No other field shows an error.
  const others = await page.$$eval('.field-error', (nodes) =>
    nodes.filter((n) => n.id !== 'err-h' && n.textContent.trim() !== '').map((n) => n.id));
  assert.deepEqual(others, []);

  // Chromium itself logs the 422 response of the fetch as a console error; the page adds none.
  const fresh = consoleErrors.slice(before)
    .filter((text) => !/Failed to load resource: the server responded with a status of 422/.test(text));
  assert.deepEqual(fresh, [], 'console errors after the validation error');

  await page.locator('#h').scrollIntoViewIfNeeded();
  await page.screenshot({ path: join(artifacts, 'page-error.png') });
});

test('Cancel stops a long run, on the page and on the server', async () => {
  const before = consoleErrors.length;
  // 10⁷ steps per method with the DOP853 reference first: tens of seconds if not cancelled.
  await page.fill('#h', '0.001');
  await page.fill('#t_end', '10000');
  await page.fill('#every', '25');
  await page.check('#compare');
  await page.click('#run');
  await page.waitForSelector('#status:has-text("Computing the reference")', { timeout: 10_000 });
  assert.equal(await page.isEnabled('#cancel'), true);
  await page.click('#cancel');
  await page.waitForSelector('body[data-run-state="cancelled"]', { timeout: 5_000 });
  assert.match(await page.textContent('#status'), /^Cancelled/);
  assert.equal(await page.isEnabled('#cancel'), false);
  // The server notices the closed stream and frees its simulation threads.
  const deadline = Date.now() + 5_000;
  let load;
  do {
    await new Promise((resolve) => setTimeout(resolve, 100));
    load = await (await fetch(`${base}/healthz`)).json();
  } while (load.runs_in_progress > 0 && Date.now() < deadline);
  assert.equal(load.runs_in_progress, 0, 'simulation threads still busy after Cancel');
  assert.deepEqual(failedRequests, ['/api/v1/simulate net::ERR_ABORTED']);
  assert.deepEqual(consoleErrors.slice(before), [], 'console errors after Cancel');
  await page.fill('#every', '');
});

test('the page fits a phone screen', async () => {
  await page.setViewportSize({ width: 390, height: 844 });
  await page.fill('#h', '0.2');
  await page.click('[data-preset="p000-pendulum/3s-heun"]');
  await page.waitForSelector('body[data-run-state="done"]', { timeout: 30_000 });
  const overflow = await page.evaluate(() => document.documentElement.scrollWidth - window.innerWidth);
  assert.ok(overflow <= 0, `the page is ${overflow}px wider than the screen`);
  const widths = await page.evaluate(() =>
    [...window.geomint.charts.values()].map(({ plot }) => plot.width));
  for (const w of widths) assert.ok(w <= 390, `plot ${w}px wide on a 390px screen`);
  await page.screenshot({ path: join(artifacts, 'page-phone.png'), fullPage: true });
});
