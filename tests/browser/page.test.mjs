// Browser test of the page in static/: headless Chromium (Debian's package, driven by
// playwright-core) against a running geomint server whose address is in GEOMINT_URL (see
// scripts/test-browser, which starts one). It runs a preset with two methods, compares the points
// of every plotted series with the samples the API returns for the same request, downloads the
// run as .rrd and opens it in the embedded Rerun viewer (or its fallback), checks that the console
// stays free of errors, submits h = -1 and looks for the API's message beside the h field, cancels
// a long run, runs the planar elastic pendulum in the polar chart (Cartesian trajectories, the
// initial state converted between coordinates, a splitting refused beside its checkbox), and saves
// screenshots to artifacts/. The study sections and the phone layout are studies.test.mjs.

import { test, before, after } from 'node:test';
import assert from 'node:assert/strict';
import { readFile, rm } from 'node:fs/promises';
import { join } from 'node:path';
import {
  HEADLESS_GPU_ERROR, LOGGED_422, artifacts, base, launchOnPage, openSection, postJson,
} from './harness.mjs';
import { presetRequest } from '../../static/js/presets.js';

/** The preset the test runs: paper 000's pendulum, modin_3s against heun at h = 0.2. */
const PRESET = ['p000-pendulum', '3s-heun'];

let context;
let page;
let profile;
const consoleErrors = [];
const failedRequests = [];

/** POSTs a simulation request to the API as JSON; returns status and body. */
function simulate(request) {
  return postJson('/api/v1/simulate', request);
}

before(async () => {
  assert.ok(base, 'set GEOMINT_URL to the server under test (scripts/test-browser does)');
  ({ context, page, profile } = await launchOnPage({ width: 1280, height: 800 }, consoleErrors, failedRequests));
});

after(async () => {
  await context?.close();
  if (profile) await rm(profile, { recursive: true, force: true });
});

test('every form control has a label', async () => {
  const unlabelled = await page.evaluate(() =>
    [...document.querySelectorAll('#sim-form input, #sim-form select, #stability input, #stability select, #energy-map input, #energy-map select')]
      .filter((c) => c.labels.length === 0 && !c.getAttribute('aria-label'))
      .map((c) => c.id || c.name));
  assert.deepEqual(unlabelled, []);
});

test('rowlands offers its processors, cheap by default', async () => {
  const select = await page.$eval('#m-rowlands-processor', (s) => ({ value: s.value, options: [...s.options].map((o) => o.value) }));
  assert.deepEqual(select, { value: 'cheap', options: ['cheap', 'original', 'none'] });
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

test('chaos indicators are plotted beside the energy when asked for', async () => {
  const before = consoleErrors.length;
  const request = { ...presetRequest(...PRESET), indicators: ['lyapunov', 'megno', 'fli', 'sali'] };
  await page.check('#chaos');
  await page.click('#run');
  // Done, and drawn with the indicators (the state may read done before the new run starts).
  await page.waitForFunction(() => document.body.dataset.runState === 'done'
    && 'chaos:megno_mean' in window.geomint.pointCounts(), null, { timeout: 30_000 });
  const { status, body } = await simulate(request);
  assert.equal(status, 200);
  const positive = (values) => values.filter((v) => v > 0 && Number.isFinite(v)).length;
  const expected = {
    'chaos:megno_mean': body.runs.map((r) => r.megno_mean.length),
    'chaos:lyapunov': body.runs.map((r) => r.lyapunov.length),
    'chaos:fli': body.runs.map((r) => r.fli.length),
    'chaos:sali': body.runs.map((r) => positive(r.sali)),
  };
  const plotted = await page.evaluate(() => window.geomint.pointCounts());
  for (const [key, counts] of Object.entries(expected)) {
    assert.deepEqual(plotted[key].map((s) => s.points), counts, `${key}: points per series`);
  }
  // The preset's run again, without them, for the tests that follow.
  await page.uncheck('#chaos');
  await page.click('#run');
  await page.waitForFunction(() => document.body.dataset.runState === 'done'
    && !Object.keys(window.geomint.pointCounts()).some((k) => k.startsWith('chaos:')), null, { timeout: 30_000 });
  assert.deepEqual(consoleErrors.slice(before), [], 'console errors during the runs');
});

test('the run downloads as .rrd and opens in the Rerun viewer', async () => {
  const before = consoleErrors.length;
  const failedBefore = failedRequests.length;
  assert.equal(await page.getAttribute('body', 'data-run-state'), 'done');

  // The .rrd download: the same request, recorded by the server.
  const [download] = await Promise.all([page.waitForEvent('download'), page.click('#download-rrd')]);
  assert.equal(download.suggestedFilename(), 'geomint-pendulum.rrd');
  const rrd = await readFile(await download.path());
  assert.ok(rrd.length > 1000, `the .rrd has ${rrd.length} bytes`);
  assert.equal(rrd.subarray(0, 4).toString('latin1'), 'RRF2', 'Rerun 0.33 files start with RRF2');
  await page.waitForSelector('#rrd-status:has-text("Saved geomint-pendulum.rrd")');

  // Before it is clicked, the page says that "View in Rerun" stores the recording on this server,
  // where everyone who uses it sees it.
  assert.match(await page.textContent('#help-rrd'), /“View in Rerun”, which stores the\s+recording on this server: it joins the Recordings section, where everyone/);
  assert.match(await page.getAttribute('#view-rerun', 'aria-describedby'), /\bhelp-rrd\b/);

  // View in Rerun: the recording is stored (201) and the viewer opens its absolute URL.
  const posted = page.waitForResponse((r) =>
    new URL(r.url()).pathname === '/api/v1/recordings' && r.request().method() === 'POST');
  await page.click('#view-rerun');
  const response = await posted;
  assert.equal(response.status(), 201);
  const created = await response.json();
  assert.match(created.id, /^[0-9a-f]{32}$/);
  assert.equal(created.url, `/api/v1/recordings/${created.id}.rrd`);
  assert.deepEqual(JSON.parse(response.request().postData()), presetRequest(...PRESET));
  const stored = await fetch(`${base}${created.url}`);
  assert.equal(stored.status, 200);
  const storedBytes = Buffer.from(await stored.arrayBuffer());
  assert.equal(storedBytes.length, created.bytes);
  assert.equal(storedBytes.subarray(0, 4).toString('latin1'), 'RRF2');

  await page.waitForSelector('#rerun:not([hidden])', { timeout: 5_000 });
  assert.equal(await page.getAttribute('#rerun', 'data-recording-url'), `${base}${created.url}`);
  // Whether the viewer renders depends on the GPU; the test waits only for start() to settle.
  await page.waitForFunction(() => ['ready', 'failed', 'unavailable']
    .includes(document.querySelector('#rerun').dataset.viewerState), null, { timeout: 30_000 });
  const state = await page.getAttribute('#rerun', 'data-viewer-state');
  // … and once it has, where it went, with a link to it in the Recordings section.
  assert.match(await page.textContent('#rrd-status'), /^Stored the recording \(\d+ KiB\) on this server, in the Recordings section for everyone who uses the server;/);
  assert.equal(await page.getAttribute('#rrd-status a', 'href'), `#recording=${created.id}`);
  if (state === 'ready') {
    assert.equal(await page.isVisible('#rerun-viewer'), true);
    assert.equal(await page.locator('#rerun-viewer canvas').count(), 1);
    // The viewer keeps Tab for its own controls; Esc hands the focus back to the page.
    await page.focus('#rerun-viewer canvas');
    await page.keyboard.press('Escape');
    assert.equal(await page.evaluate(() => document.activeElement?.id), 'rerun-close');
  } else {
    const fallback = await page.textContent('#rerun-fallback');
    assert.match(fallback, /rerun geomint-pendulum\.rrd/);
    assert.match(fallback, /pip install "rerun-sdk==0\.33\.\*"/);
    assert.equal(await page.getAttribute('#rerun-fallback a[download]', 'href'), `${base}${created.url}`);
  }

  const fresh = consoleErrors.slice(before);
  const gpu = fresh.filter((text) => HEADLESS_GPU_ERROR.test(text));
  if (gpu.length) assert.equal(state, 'failed', 'a GPU error must leave the page on its fallback');
  assert.deepEqual(fresh.filter((text) => !HEADLESS_GPU_ERROR.test(text)), [], 'console errors with the Rerun viewer');
  assert.deepEqual(failedRequests.slice(failedBefore), [], 'failed requests with the Rerun viewer');
  await page.locator('#rerun').scrollIntoViewIfNeeded();
  await page.screenshot({ path: join(artifacts, 'page-rerun.png') });

  // Closing stops the viewer; a new run closes it too (not needed here: Close is the same call).
  await page.click('#rerun-close');
  assert.equal(await page.isHidden('#rerun'), true);
  assert.equal(await page.getAttribute('#rerun', 'data-viewer-state'), 'closed');
  assert.equal(await page.locator('#rerun-viewer canvas').count(), 0);
  assert.equal(await page.evaluate(() => document.activeElement?.id), 'view-rerun');
  assert.equal((await fetch(`${base}/api/v1/recordings/${created.id}`, { method: 'DELETE' })).status, 204);
});

test('without the viewer files the page explains how to open the recording in the Rerun app', async () => {
  // A second tab where the viewer's files answer 404, as on a server without `npm ci`.
  const other = await context.newPage();
  const errors = [];
  other.on('console', (message) => {
    if (message.type() === 'error') errors.push(message.text());
  });
  other.on('pageerror', (error) => errors.push(`uncaught: ${error.message}`));
  await other.route('**/vendor/rerun/**', (route) => route.fulfill({ status: 404, body: 'not found' }));
  try {
    await other.goto(`${base}/`);
    await other.waitForSelector('body[data-run-state="idle"]', { timeout: 15_000 });
    await other.click('[data-preset="p000-pendulum/3s-heun"]');
    await other.waitForSelector('body[data-run-state="done"]', { timeout: 30_000 });
    const posted = other.waitForResponse((r) =>
      new URL(r.url()).pathname === '/api/v1/recordings' && r.request().method() === 'POST');
    await other.click('#view-rerun');
    const response = await posted;
    assert.equal(response.status(), 201);
    const created = await response.json();
    await other.waitForSelector('#rerun[data-viewer-state="unavailable"]', { timeout: 10_000 });
    assert.equal(await other.isHidden('#rerun-viewer'), true);
    const fallback = await other.textContent('#rerun-fallback');
    assert.match(fallback, /not installed/);
    assert.match(fallback, /pip install "rerun-sdk==0\.33\.\*"/);
    assert.match(fallback, /rerun geomint-pendulum\.rrd/);
    assert.equal(await other.getAttribute('#rerun-fallback a[download]', 'href'), `${base}${created.url}`);
    assert.equal(await other.getAttribute('#rerun-fallback a[download]', 'download'), 'geomint-pendulum.rrd');
    // Chromium logs the missing module's 404 itself; the page adds nothing.
    assert.deepEqual(errors.filter((text) => !/Failed to load resource: the server responded with a status of 404/.test(text)), []);
    await other.locator('#rerun').scrollIntoViewIfNeeded();
    await other.screenshot({ path: join(artifacts, 'page-rerun-fallback.png') });
    assert.equal((await fetch(`${base}/api/v1/recordings/${created.id}`, { method: 'DELETE' })).status, 204);
  } finally {
    await other.close();
  }
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
  const failedBefore = failedRequests.length;
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
  assert.deepEqual(failedRequests.slice(failedBefore), ['/api/v1/simulate net::ERR_ABORTED']);
  assert.deepEqual(consoleErrors.slice(before), [], 'console errors after Cancel');
  await page.fill('#every', '');
});

test('a run in the polar chart plots the Cartesian trajectory, and a splitting there is refused beside it', async () => {
  const before = consoleErrors.length;
  const failedBefore = failedRequests.length;
  await openSection(page, 'simulation');
  await page.locator('#sim-form').scrollIntoViewIfNeeded();
  await page.selectOption('#system', 'elastic_pendulum_2d');
  assert.equal(await page.isVisible('#chart'), true, 'a system with two charts offers the select');
  assert.deepEqual(await page.$$eval('#chart option', (os) => os.map((o) => o.value)), ['cartesian', 'polar']);
  assert.equal(await page.isHidden('#state-coordinates'), true, 'no coordinate switch in the Cartesian chart');
  await page.selectOption('#chart', 'polar');
  assert.match(await page.textContent('#chart-description'), /x = r sin θ/);
  assert.equal(await page.isVisible('#state-coordinates'), true);
  // The catalogue's Cartesian start, labelled x and y.
  assert.deepEqual([await page.inputValue('#q0-0'), await page.inputValue('#q0-1')], ['0.6', '1.2']);
  assert.equal(await page.textContent('label[for="q0-1"]'), 'q₀,y');

  // Switching the inputs to the chart's coordinates converts them on the server, and back.
  await page.check('#state-chart');
  await page.waitForFunction(() => document.querySelector('label[for="q0-0"]').textContent === 'q₀,r', null, { timeout: 10_000 });
  const polar = [Number(await page.inputValue('#q0-0')), Number(await page.inputValue('#q0-1'))];
  assert.ok(Math.abs(polar[0] - Math.hypot(0.6, 1.2)) < 1e-12 && Math.abs(polar[1] - Math.atan2(0.6, 1.2)) < 1e-12, `r, θ = ${polar}`);
  await page.check('#state-cartesian');
  await page.waitForFunction(() => document.querySelector('label[for="q0-0"]').textContent === 'q₀,x', null, { timeout: 10_000 });
  const back = [Number(await page.inputValue('#q0-0')), Number(await page.inputValue('#q0-1'))];
  assert.ok(Math.abs(back[0] - 0.6) < 1e-12 && Math.abs(back[1] - 1.2) < 1e-12, `x, y = ${back}`);

  // Symplectic Euler alone, from the Cartesian start (the method groups fold; open them first).
  for (const group of await page.$$('#methods details.method-group:not([open]) > summary')) await group.click();
  for (const box of await page.$$('#methods input[type=checkbox]:checked')) await box.uncheck();
  await page.check('#m-symplectic_euler');
  await page.fill('#h', '0.1');
  await page.fill('#t_end', '20');
  await page.fill('#every', '');
  await page.uncheck('#compare');
  const posted = page.waitForRequest((r) => new URL(r.url()).pathname === '/api/v1/simulate' && r.method() === 'POST');
  await page.click('#run');
  const request = JSON.parse((await posted).postData());
  assert.equal(request.chart, 'polar');
  assert.equal(request.initial_coordinates, 'cartesian');
  assert.deepEqual([request.q0, request.p0], [[0.6, 1.2], [0, 0]]);
  await page.waitForSelector('body[data-run-state="done"]', { timeout: 30_000 });

  const { status, body } = await simulate(request);
  assert.equal(status, 200);
  assert.equal(body.system.chart, 'polar');
  const run = body.runs[0];
  const counts = await page.evaluate(() => window.geomint.pointCounts());
  for (const key of ['phase:0', 'phase:1', 'trajectory:xy', 'trajectory:0', 'trajectory:1']) {
    assert.deepEqual(counts[key].map((c) => c.points), [run.t.length], `${key}: points`);
  }
  // The x–y plot holds the Cartesian image of the run, the phase portraits its (r, p_r).
  const plotted = await page.evaluate(() => {
    const get = (key) => window.geomint.charts.get(key).plot.data[1];
    return { xy: get('trajectory:xy'), phase: get('phase:0') };
  });
  assert.deepEqual(plotted.xy, [run.cartesian_q.map((x) => x[0]), run.cartesian_q.map((x) => x[1])]);
  assert.deepEqual(plotted.phase, [run.q.map((q) => q[0]), run.p.map((p) => p[0])]);
  assert.deepEqual(await page.$$eval('[data-plot="trajectory:xy"] figcaption small', (n) => n.map((x) => x.textContent)),
    ['y points down, along gravity; Cartesian coordinates (x, y) of the run in the polar chart']);
  assert.deepEqual(consoleErrors.slice(before), [], 'console errors in the polar run');
  await page.locator('#results').screenshot({ path: join(artifacts, 'page-polar.png') });

  // Störmer–Verlet needs a separable H: the server refuses it, and the page says so beside it.
  assert.match(await page.textContent('.method[data-method="velocity_verlet"] .method-note'), /needs a separable H/);
  await page.check('#m-velocity_verlet');
  await page.click('#run');
  await page.waitForSelector('body[data-run-state="error"]', { timeout: 10_000 });
  const refused = await simulate({ ...request, methods: ['symplectic_euler', 'velocity_verlet'] });
  assert.equal(refused.status, 422);
  assert.equal(refused.body.error.field, 'methods[1]');
  assert.equal(refused.body.error.code, 'unmet_requirement');
  const message = page.locator('.method[data-method="velocity_verlet"] .field-error');
  assert.equal((await message.textContent()).trim(), refused.body.error.message);
  assert.equal(await page.getAttribute('#m-velocity_verlet', 'aria-invalid'), 'true');
  assert.deepEqual(consoleErrors.slice(before).filter((t) => !LOGGED_422.test(t)), [], 'console errors after the refusal');
  assert.deepEqual(failedRequests.slice(failedBefore), [], 'failed requests in the polar runs');
  await page.uncheck('#m-velocity_verlet');
});
