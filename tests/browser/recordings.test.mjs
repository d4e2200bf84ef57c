// Browser test of the page's Recordings section: headless Chromium (Debian's package, driven by
// playwright-core) against the geomint server in GEOMINT_URL (scripts/test-browser starts one).
// Recordings are made through the API first; the test then finds them in the list, newest first,
// a page at a time and through the filters; opens one in the embedded Rerun viewer (checking that
// the viewer read it: its step range is the recording's) or, without a GPU, in the documented
// fallback; plots one with the page's charts and compares every point count with the recording's
// own rows, as the server decodes them and as the JSON answer of the same request has them;
// follows a copied link in a new page (and an unknown id); deletes one after a confirmation; opens
// a local .rrd from the file picker and by drag and drop without uploading it, then uploads it;
// refuses a file that is not a recording, and shows the server's refusal of a cut-short one;
// and checks the phone layout. Screenshots go to artifacts/.

import { test, before, after } from 'node:test';
import assert from 'node:assert/strict';
import { mkdtemp, rm, writeFile } from 'node:fs/promises';
import { tmpdir } from 'node:os';
import { join } from 'node:path';
import { artifacts, base, HEADLESS_GPU_ERROR, launch, openSection, waitForServer } from './harness.mjs';
import { EXAMPLES } from '../../static/js/examples.js';

/** The browser's log line for an answer the test asks for on purpose (404, 422). */
const EXPECTED_REFUSAL = /Failed to load resource: the server responded with a status of (404|422)/;

/** The recording the test views and plots: two methods, 101 samples each. */
const PENDULUM = {
  system: 'pendulum', params: { epsilon: 0.01 }, methods: ['modin_3s', 'heun'],
  h: 0.1, t_end: 20, output: { every: 2 },
};
/** A recording with an energy error (the oscillator has an exact solution). */
const OSCILLATOR = { system: 'harmonic_oscillator', method: 'csv1', h: 0.05, t_end: 10 };
/** Ten quick ones, so that the list has two pages. */
const FILLERS = Array.from({ length: 10 }, (_, i) => ({
  system: 'harmonic_oscillator', method: 'heun', h: 0.1, t_end: 1 + i,
}));

let context;
let page;
let profile;
let scratch;
const consoleErrors = [];
/** Every console message of the page, whatever its level (the viewer warns at `warning`). */
const consoleMessages = [];
const requests = [];
/** Ids of the recordings this test made, by name. */
const made = {};

async function api(path, init) {
  const response = await fetch(`${base}${path}`, init);
  const type = response.headers.get('content-type') || '';
  return { status: response.status, body: type.startsWith('application/json') ? await response.json() : await response.arrayBuffer() };
}

function createRecording(request) {
  return api('/api/v1/recordings', {
    method: 'POST', headers: { 'content-type': 'application/json' }, body: JSON.stringify(request),
  });
}

/** The stored recordings, newest first, as the API lists them. */
async function listed() {
  return (await api('/api/v1/recordings')).body;
}

/** The ids in the list's rows, top to bottom. */
function rowIds(p = page) {
  return p.$$eval('#rec-list tr', (trs) => trs.map((tr) => tr.dataset.id));
}

/** Waits for the library's viewer to settle; returns its state. */
async function viewerSettled(p, timeout = 60_000) {
  await p.waitForFunction(() => ['ready', 'failed', 'unavailable']
    .includes(document.querySelector('#rec-rerun').dataset.viewerState), null, { timeout });
  return p.getAttribute('#rec-rerun', 'data-viewer-state');
}

/** Opens a new tab of the same browser, collecting its console errors. */
async function newTab(url, errors) {
  const tab = await context.newPage();
  tab.on('console', (m) => { if (m.type() === 'error') errors.push(m.text()); });
  tab.on('pageerror', (e) => errors.push(`uncaught: ${e.message}`));
  await tab.goto(url);
  await tab.waitForSelector('#recordings[data-library-state="ready"]', { timeout: 15_000 });
  return tab;
}

before(async () => {
  assert.ok(base, 'set GEOMINT_URL to the server under test (scripts/test-browser does)');
  await waitForServer();
  for (const [name, request] of [['oscillator', OSCILLATOR], ...FILLERS.map((r, i) => [`filler${i}`, r]), ['pendulum', PENDULUM]]) {
    const { status, body } = await createRecording(request);
    assert.equal(status, 201, JSON.stringify(body));
    made[name] = body.id;
  }
  scratch = await mkdtemp(join(tmpdir(), 'geomint-recordings-'));
  ({ context, page, profile } = await launch({ width: 1280, height: 900 }, consoleErrors));
  await context.grantPermissions(['clipboard-read', 'clipboard-write'], { origin: base });
  // Without a GPU the viewer renders in software on the page's thread, which slows every action.
  context.setDefaultTimeout(60_000);
  page.on('request', (r) => requests.push(`${r.method()} ${new URL(r.url()).pathname}`));
  page.on('console', (m) => consoleMessages.push(m.text()));
  await page.goto(`${base}/`);
  await openSection(page, 'recordings');
  await page.waitForSelector('#recordings[data-library-state="ready"]', { timeout: 15_000 });
});

after(async () => {
  await context?.close();
  for (const dir of [profile, scratch]) if (dir) await rm(dir, { recursive: true, force: true });
});

test('the list shows the recordings made through the API, newest first, a page at a time', async () => {
  const all = await listed();
  assert.ok(all.length >= 12, `${all.length} recordings`);
  // Newest first: the pendulum was made last.
  assert.equal(all[0].id, made.pendulum);
  assert.deepEqual(await rowIds(), all.slice(0, 10).map((e) => e.id));
  const cells = await page.$$eval(`#rec-list tr[data-id="${made.pendulum}"] > *`, (cs) => cs.map((c) => c.textContent.trim()));
  assert.deepEqual(cells.slice(0, 4), ['pendulum', 'modin_3s, heun', '0.1', '20']);
  const total = all.length;
  assert.equal(await page.textContent('#rec-status'), `Recordings 1–10 of ${total}.`);

  // The second page, from the keyboard: the pager's Next button.
  await page.focus('#rec-next');
  await page.keyboard.press('Enter');
  assert.deepEqual(await rowIds(), all.slice(10, 20).map((e) => e.id));
  assert.match(await page.textContent('#rec-page'), /^Page 2 of \d+$/);
  await page.click('#rec-prev');
  assert.deepEqual(await rowIds(), all.slice(0, 10).map((e) => e.id));

  // The filters: by system, then by method.
  await page.selectOption('#rec-system', 'pendulum');
  const pendulums = all.filter((e) => e.spec?.system === 'pendulum').map((e) => e.id);
  assert.deepEqual(await rowIds(), pendulums.slice(0, 10));
  await page.selectOption('#rec-system', '');
  await page.selectOption('#rec-method', 'csv1');
  const csv1 = all.filter((e) => e.spec?.methods.some((m) => m.split('(')[0] === 'csv1')).map((e) => e.id);
  assert.ok(csv1.includes(made.oscillator));
  assert.deepEqual(await rowIds(), csv1.slice(0, 10));
  await page.selectOption('#rec-method', '');
  assert.equal((await rowIds()).length, 10);
  await page.locator('#recordings').screenshot({ path: join(artifacts, 'recordings.png') });
});

test('a recording opens in the embedded viewer, from the keyboard', async () => {
  const before = consoleErrors.length;
  const id = made.pendulum;
  const fetched = requests.length;
  await page.focus(`#rec-list tr[data-id="${id}"] button:text-is("View")`);
  await page.keyboard.press('Enter');
  const state = await viewerSettled(page);
  assert.equal(await page.getAttribute('#rec-rerun', 'data-recording-id'), id);
  const url = `${base}/api/v1/recordings/${id}.rrd`;
  assert.equal(await page.getAttribute('#rec-rerun', 'data-recording-url'), url);
  assert.equal(await page.getAttribute(`#rec-list tr[data-id="${id}"]`, 'aria-current'), 'true');
  if (state === 'ready') {
    // The viewer read the recording from the server's URL: its step timeline ends at the last
    // step of the run (200 steps of h = 0.1 to t = 20).
    await page.waitForSelector('#rec-rerun[data-recording-open="true"]', { state: 'attached', timeout: 60_000 });
    await page.waitForFunction(() => window.geomint.library.viewer.stepRange()?.max === 200, null, { timeout: 60_000 });
    assert.deepEqual(await page.evaluate(() => window.geomint.library.viewer.stepRange()), { min: 0, max: 200 });
    // The recording was written by the Rerun SDK of the viewer's own version: the viewer does
    // not warn that its data is newer than itself.
    const versions = consoleMessages.filter((t) => /newer than the local Rerun version/.test(t));
    assert.deepEqual(versions, [], 'the viewer reads data of its own version');
    assert.equal(requests.slice(fetched).filter((r) => r === `GET /api/v1/recordings/${id}.rrd`).length, 1);
    // Esc hands the focus back from the viewer's canvas to its Close button.
    await page.focus('#rec-rerun-viewer canvas');
    await page.keyboard.press('Escape');
    assert.equal(await page.evaluate(() => document.activeElement?.id), 'rec-rerun-close');
  } else {
    assert.equal(state, 'failed');
    const fallback = await page.textContent('#rec-rerun-fallback');
    assert.match(fallback, /pip install "rerun-sdk==0\.33\.\*"/);
    assert.equal(await page.getAttribute('#rec-rerun-fallback a[download]', 'href'), url);
  }
  const fresh = consoleErrors.slice(before);
  if (fresh.some((t) => HEADLESS_GPU_ERROR.test(t))) assert.equal(state, 'failed');
  assert.deepEqual(fresh.filter((t) => !HEADLESS_GPU_ERROR.test(t)), [], 'console errors with the viewer');
  await page.locator('#rec-rerun').screenshot({ path: join(artifacts, 'recordings-viewer.png') });
  await page.click('#rec-rerun-close');
  assert.equal(await page.isHidden('#rec-rerun'), true);
  assert.equal(await page.getAttribute('#rec-rerun', 'data-viewer-state'), 'closed');
  assert.equal(await page.locator('#rec-rerun-viewer canvas').count(), 0);
  // The focus returns to the View button it came from.
  assert.equal(await page.evaluate(() => document.activeElement?.textContent), 'View');
});

test('a recording plots with the page’s charts, one point per recorded row', async () => {
  const id = made.pendulum;
  const before = requests.length;
  await page.click(`#rec-list tr[data-id="${id}"] button:text-is("Plot")`);
  // The plots are drawn below the list, in the Recordings section.
  await page.waitForSelector(`#recordings:not([hidden]) #rec-plot[data-source="recording:${id}"]`, { timeout: 15_000 });
  // Nothing was run again: the samples came from the stored recording.
  const asked = requests.slice(before);
  assert.deepEqual(asked, [`GET /api/v1/recordings/${id}/samples`]);

  const { body: samples } = await api(`/api/v1/recordings/${id}/samples`);
  const { body: answer } = await api('/api/v1/simulate', {
    method: 'POST', headers: { 'content-type': 'application/json' }, body: JSON.stringify(PENDULUM),
  });
  const rows = samples.runs.map((r) => r.energy.length);
  // The recording's rows: 101 samples per method, as the JSON answer of the same request has.
  assert.deepEqual(rows, [101, 101]);
  assert.deepEqual(answer.runs.map((r) => r.t.length), rows);
  const expected = {
    energy: rows,
    'phase:0': samples.runs.map((r) => r.q.length),
    'trajectory:0': samples.runs.map((r) => r.q.length),
    drift: samples.runs.map((r) => r.dissipation_drift.length),
  };
  assert.deepEqual(expected['phase:0'], rows);
  const plotted = await page.evaluate(() => window.geomint.library.plots.charts.pointCounts());
  assert.deepEqual(Object.keys(plotted).sort(), Object.keys(expected).sort());
  for (const [key, counts] of Object.entries(expected)) {
    assert.deepEqual(plotted[key].map((s) => s.label), ['modin_3s', 'heun'], key);
    assert.deepEqual(plotted[key].map((s) => s.points), counts, key);
  }
  // The energies drawn are the recording's, which are the JSON answer's.
  const energy = await page.evaluate(() => window.geomint.library.plots.charts.plots.get('energy').plot.data.slice(1));
  assert.deepEqual(energy, answer.runs.map((r) => r.energy));
  // The statistics: the recorded steps and force evaluations; no wall time in a recording.
  const stats = await page.$$eval('#rec-plot-stats-body tr', (trs) => trs.map((tr) => [...tr.children].map((c) => c.textContent.trim())));
  stats.forEach((cells, i) => {
    assert.equal(cells[1], String(answer.runs[i].stats.steps));
    assert.equal(cells[2], String(answer.runs[i].stats.force_evaluations));
    assert.equal(cells[3], '—');
    assert.equal(cells[4], '101');
    assert.equal(cells[6], 'finished');
  });
  assert.match(await page.textContent('#rec-plot-status'), /202 samples read back from the \.rrd file/);
  assert.equal(await page.isHidden('#rec-plot-view-rerun'), true, 'the results do not offer to run it again');
  assert.equal(await page.textContent('#rec-plot-results-title'), 'Recording: pendulum: modin_3s, heun');
  await page.locator('#rec-plot').screenshot({ path: join(artifacts, 'recordings-plot.png') });
});

test('a typed-in system’s recording keeps its name, its coordinates’ names, its bodies and its energy error', async () => {
  const before = consoleErrors.length;
  // The double pendulum, stored on the server, recorded by its id: the recorded request names the
  // system only by that id, so the page takes its definition from the server (the catalogue it
  // loaded, or GET /api/v1/systems/{id} for one stored since).
  const { definition } = EXAMPLES.find((x) => x.id === 'double-pendulum');
  const stored = await api('/api/v1/systems', {
    method: 'POST', headers: { 'content-type': 'application/json' }, body: JSON.stringify(definition),
  });
  assert.ok([200, 201].includes(stored.status), JSON.stringify(stored.body));
  const systemId = stored.body.id;
  const request = { system: systemId, methods: ['implicit_midpoint', 'rk4'], h: 0.01, t_end: 2 };
  const { status, body: created } = await createRecording(request);
  assert.equal(status, 201, JSON.stringify(created));
  made.doublePendulum = created.id;

  await page.click('#rec-refresh');
  await page.waitForSelector(`#rec-list tr[data-id="${created.id}"]`);
  const row = `#rec-list tr[data-id="${created.id}"]`;
  // The row and the System filter name the system, not its id.
  assert.equal((await page.textContent(`${row} > th`)).trim(), 'Double pendulum');
  assert.equal(await page.getAttribute(`${row} > th`, 'title'), systemId);
  const option = await page.$eval(`#rec-system option[value="${systemId}"]`, (o) => o.textContent);
  assert.equal(option, 'Double pendulum');

  await page.click(`${row} button:text-is("Plot")`);
  await page.waitForSelector(`#rec-plot[data-source="recording:${created.id}"]`, { timeout: 15_000 });
  // The plots are in the Recordings section, titled with the recording; the Simulation section,
  // whose form shows another system, stays as it was.
  assert.equal(await page.isHidden('#simulation'), true);
  assert.equal(await page.textContent('#rec-plot-results-title'), 'Recording: Double pendulum: implicit_midpoint, rk4');
  const titles = await page.$$eval('#rec-plot figcaption .plot-title', (t) => t.map((n) => n.textContent));
  assert.deepEqual(titles.slice(0, 5), ['Energy H(t)', 'Energy error |H − H₀|', 'Phase portrait (a, p1)',
    'Phase portrait (b, p2)', 'Bodies in the x–y plane']);
  assert.ok(!titles.some((t) => /q_1|q_2/.test(t)), `titles: ${titles}`);

  // The bobs are where the definition's positions put the recorded angles: the simulate answer's
  // bodies, to the single precision of the recording.
  const { body: answer } = await api('/api/v1/simulate', {
    method: 'POST', headers: { 'content-type': 'application/json' }, body: JSON.stringify(request),
  });
  const bobs = await page.evaluate(() => window.geomint.library.plots.charts.plots.get('trajectory:xy').plot.data.slice(1));
  assert.equal(bobs.length, 4, 'two bobs for each of two methods');
  answer.runs.forEach((run, m) => {
    run.bodies.forEach((place, i) => {
      for (let body = 0; body < 2; body++) {
        const [x, y] = [bobs[2 * m + body][0][i], bobs[2 * m + body][1][i]];
        assert.ok(Math.abs(x - place[2 * body]) < 1e-5 && Math.abs(y - place[2 * body + 1]) < 1e-5,
          `bob ${body + 1} of ${run.method} at sample ${i}: (${x}, ${y}) against (${place.slice(2 * body, 2 * body + 2)})`);
      }
    });
  });
  // Undamped: the energy error against H₀ is drawn, as the caption says.
  assert.equal(await page.getAttribute('#rec-plot [data-plot="energy_error"]', 'data-against'), 'initial');
  assert.match(await page.textContent('#rec-plot [data-plot="energy_error"] figcaption small'), /initial energy H₀/);
  assert.equal(await page.locator('#rec-plot [data-note="energy"]').count(), 0);
  assert.deepEqual(consoleErrors.slice(before), [], 'console errors');
  await page.locator('#rec-plot').screenshot({ path: join(artifacts, 'recordings-plot-typed-in.png') });
});

test('a copied link opens the page on the recording; a deleted or unknown one says so', async () => {
  const id = made.oscillator;
  await page.locator('#recordings').scrollIntoViewIfNeeded();
  await page.selectOption('#rec-method', 'csv1');
  await page.click(`#rec-list tr[data-id="${id}"] button:text-is("Copy link")`);
  const link = await page.evaluate(() => navigator.clipboard.readText());
  assert.equal(link, `${base}/#recording=${id}`);
  assert.equal(await page.inputValue('#rec-link'), link);
  assert.match(await page.textContent('#rec-status'), /^Copied the link to harmonic_oscillator: csv1\.$/);
  await page.selectOption('#rec-method', '');

  const errors = [];
  const other = await newTab(link, errors);
  try {
    await other.waitForSelector(`#rec-rerun[data-recording-id="${id}"]`, { state: 'attached', timeout: 60_000 });
    const state = await viewerSettled(other);
    if (state === 'ready') {
      await other.waitForFunction(() => window.geomint.library.viewer.stepRange()?.max === 200, null, { timeout: 60_000 });
    }
    assert.equal(await other.getAttribute(`#rec-list tr[data-id="${id}"]`, 'aria-current'), 'true');
    assert.equal(await other.isHidden('#rec-error'), true);

    // An id that is not stored, and text that is not an id.
    const missing = '0123456789abcdef0123456789abcdef';
    await other.goto(`${base}/#recording=${missing}`);
    await other.reload();
    await other.waitForSelector('#rec-error:not([hidden])', { timeout: 15_000 });
    assert.match(await other.textContent('#rec-error'), new RegExp(`^There is no recording ${missing} on this server: it was deleted`));
    assert.equal(await other.getAttribute('#rec-rerun', 'data-viewer-state'), 'closed');
    await other.evaluate(() => { window.location.hash = '#recording=../etc'; });
    await other.waitForFunction(() => document.querySelector('#rec-error').textContent.includes('../etc'));
    assert.match(await other.textContent('#rec-error'), /names “\.\.\/etc”, which is not a recording id/);
  } finally {
    await other.close();
  }
  assert.deepEqual(errors.filter((t) => !HEADLESS_GPU_ERROR.test(t) && !EXPECTED_REFUSAL.test(t)), []);
});

test('a recording is deleted only after its confirmation', async () => {
  const id = made.filler0;
  const count = (await listed()).length;
  await page.selectOption('#rec-system', 'harmonic_oscillator');
  await page.selectOption('#rec-method', 'heun');
  const row = `#rec-list tr[data-id="${id}"]`;
  await page.click(`${row} button:text-is("Delete")`);
  await page.waitForSelector('#rec-confirm[open]');
  assert.match(await page.textContent('#rec-confirm-text'), /^harmonic_oscillator: heun, stored .* will be deleted from the server/);
  // Esc keeps it (the dialog's cancel), and so does "Keep it".
  await page.keyboard.press('Escape');
  assert.equal(await page.isHidden('#rec-confirm'), true);
  assert.equal((await api(`/api/v1/recordings/${id}`)).status, 200);
  await page.click(`${row} button:text-is("Delete")`);
  await page.click('#rec-confirm button:text-is("Keep it")');
  assert.equal((await api(`/api/v1/recordings/${id}`)).status, 200);
  assert.equal((await listed()).length, count);

  await page.click(`${row} button:text-is("Delete")`);
  await page.click('#rec-confirm-delete');
  await page.waitForSelector(row, { state: 'detached', timeout: 10_000 });
  assert.equal((await api(`/api/v1/recordings/${id}`)).status, 404);
  assert.equal((await listed()).length, count - 1);
  assert.match(await page.textContent('#rec-status'), /^Deleted harmonic_oscillator: heun\./);
  await page.selectOption('#rec-system', '');
  await page.selectOption('#rec-method', '');
});

test('a local .rrd opens in the viewer without an upload, by picker and by drop, and then uploads', async () => {
  const before = consoleErrors.length;
  const { body: bytes } = await api(`/api/v1/recordings/${made.oscillator}.rrd`);
  const file = join(scratch, 'local-run.rrd');
  await writeFile(file, Buffer.from(bytes));
  const sent = requests.length;
  await page.setInputFiles('#rec-file', file);
  const state = await viewerSettled(page);
  assert.equal(await page.getAttribute('#rec-rerun', 'data-source'), 'file:local-run.rrd');
  if (state === 'ready') {
    // The viewer read the file's bytes: 200 steps of h = 0.05 to t = 10.
    await page.waitForFunction(() => window.geomint.library.viewer.stepRange()?.max === 200, null, { timeout: 60_000 });
    assert.match(await page.textContent('#rec-file-status'), /^Opened local-run\.rrd \(\d+ KiB\) from this computer .* it was not uploaded\.$/);
  }
  // A whole recording opens without a warning.
  assert.equal(await page.isHidden('#rec-file-warning'), true);
  // Opening sent nothing to the server.
  assert.deepEqual(requests.slice(sent).filter((r) => r.includes('/api/')), []);

  // Dropped on the box: the same, from a File the page gets by drag and drop.
  await page.evaluate(async (url) => {
    const blob = await (await fetch(url)).blob();
    const transfer = new DataTransfer();
    transfer.items.add(new File([blob], 'dropped.rrd'));
    const box = document.querySelector('#rec-drop');
    box.dispatchEvent(new DragEvent('dragover', { dataTransfer: transfer, bubbles: true, cancelable: true }));
    box.dispatchEvent(new DragEvent('drop', { dataTransfer: transfer, bubbles: true, cancelable: true }));
  }, `${base}/api/v1/recordings/${made.pendulum}.rrd`);
  await page.waitForSelector('#rec-rerun[data-source="file:dropped.rrd"]');
  if ((await viewerSettled(page)) === 'ready') {
    await page.waitForFunction(() => window.geomint.library.viewer.stepRange()?.max === 200, null, { timeout: 60_000 });
  }

  // Uploaded on request: a new entry of the library, of the dropped file's size.
  const idsBefore = new Set((await listed()).map((e) => e.id));
  await page.click('#rec-upload');
  await page.waitForSelector('#recordings[data-upload-state="done"]', { timeout: 15_000 });
  const added = (await listed()).filter((e) => !idsBefore.has(e.id));
  assert.equal(added.length, 1);
  const [entry] = added;
  assert.equal(entry.origin, 'upload');
  assert.equal(entry.spec.system, 'pendulum');
  const { body: pendulumFile } = await api(`/api/v1/recordings/${made.pendulum}.rrd`);
  assert.equal(entry.bytes, pendulumFile.byteLength);
  assert.equal(await page.getAttribute(`#rec-list tr[data-id="${entry.id}"]`, 'data-uploaded'), 'true');
  assert.match(await page.textContent('#rec-file-status'), new RegExp(`with the link ${base}/#recording=${entry.id}\\.$`));
  const fresh = consoleErrors.slice(before);
  assert.deepEqual(fresh.filter((t) => !HEADLESS_GPU_ERROR.test(t)), [], 'console errors with local files');
  await page.locator('#rec-drop').screenshot({ path: join(artifacts, 'recordings-upload.png') });
  await page.click('#rec-rerun-close');
});

test('a file that is not a recording is refused with a clear error, here and by the server', async () => {
  const before = consoleErrors.length;
  const count = (await listed()).length;
  await page.setInputFiles('#rec-file', { name: 'notes.txt', mimeType: 'text/plain', buffer: Buffer.from('hello, world') });
  await page.waitForFunction(() => document.querySelector('#rec-file-error').textContent !== '');
  assert.equal(await page.textContent('#rec-file-error'),
    'notes.txt is not a Rerun recording (.rrd): it starts with “hell”, not the RRD header “RRF2”.');
  assert.equal(await page.isDisabled('#rec-upload'), true);
  assert.equal(await page.getAttribute('#rec-rerun', 'data-viewer-state'), 'closed');

  // A recording cut in half starts like one; the server's check finds the missing end.
  const { body: bytes } = await api(`/api/v1/recordings/${made.oscillator}.rrd`);
  const half = Buffer.from(bytes).subarray(0, Math.floor(bytes.byteLength / 2));
  await page.setInputFiles('#rec-file', { name: 'cut.rrd', mimeType: 'application/octet-stream', buffer: half });
  await page.waitForSelector('#rec-upload:enabled', { state: 'attached' });
  // The page opens it (the viewer shows what it can read) but says it is cut short, before any
  // upload.
  await page.waitForSelector('#rec-file-warning:not([hidden])');
  assert.match(await page.textContent('#rec-file-warning'),
    new RegExp(`^cut\\.rrd looks cut short: its ${half.length} bytes do not end with the RRD stream footer`));
  await page.locator('#rec-drop').screenshot({ path: join(artifacts, 'recordings-cut-short.png') });
  // The upload needs no viewer: closing it spares the page's thread the software rendering.
  await page.evaluate(() => window.geomint.library.viewer.close());
  await page.click('#rec-upload');
  await page.waitForSelector('#recordings[data-upload-state="error"]', { timeout: 30_000 });
  assert.match(await page.textContent('#rec-file-error'),
    /^The server refused cut\.rrd: the upload is not a recording the viewer reads: cut short: the \d+ bytes do not end with the RRD stream footer/);
  assert.equal((await listed()).length, count);
  const fresh = consoleErrors.slice(before).filter((t) => !HEADLESS_GPU_ERROR.test(t) && !EXPECTED_REFUSAL.test(t));
  assert.deepEqual(fresh, [], 'console errors with refused files');
});

test('the recordings fit a phone screen', async () => {
  const errors = [];
  const phone = await newTab(`${base}/#recordings`, errors);
  try {
    await phone.setViewportSize({ width: 390, height: 844 });
    await phone.locator('#recordings').scrollIntoViewIfNeeded();
    const overflow = await phone.evaluate(() => document.documentElement.scrollWidth - window.innerWidth);
    assert.ok(overflow <= 0, `the page is ${overflow}px wider than the screen`);
    // Each recording is a card: its actions sit inside the screen.
    const rights = await phone.$$eval('#rec-list tr:first-child .row-actions > *', (as) => as.map((a) => a.getBoundingClientRect().right));
    assert.equal(rights.length, 5);
    for (const right of rights) assert.ok(right <= 390, `an action ends at ${right}px`);
    await phone.locator('#recordings').screenshot({ path: join(artifacts, 'recordings-phone.png') });
  } finally {
    await phone.close();
  }
  assert.deepEqual(errors, []);
});
