// Browser test of the page's Phase-space section: headless Chromium (Debian's package, driven by
// playwright-core) against the geomint server in GEOMINT_URL. A click on the Hénon–Heiles plane
// launches an orbit whose section points are the API's own answer to the same request, bit for
// bit, and whose energy is the chosen one; the readout names the crossing under the pointer; the
// driven Duffing oscillator's stroboscopic section grows at the drive's period; the link
// reproduces the picture; a refused surface shows the server's field; the orbits download as
// JSON and .rrd. A screenshot goes to artifacts/.

import { test, before, after } from 'node:test';
import assert from 'node:assert/strict';
import { rm } from 'node:fs/promises';
import { join } from 'node:path';
import { LOGGED_422, artifacts, base, launch, openSection, waitForServer } from './harness.mjs';


let context;
let page;
let profile;
const consoleErrors = [];

async function settled(timeout = 60_000) {
  await page.waitForFunction(() => ['done', 'error'].includes(document.querySelector('#phase-space').dataset.psState),
    null, { timeout });
  return page.getAttribute('#phase-space', 'data-ps-state');
}

/** Clicks the plane at plane coordinates (x, y). */
async function clickAt(x, y) {
  const [cx, cy] = await page.evaluate(([a, b]) => window.geomint.phaseSpace.plot.px(a, b), [x, y]);
  const box = await page.locator('#ps-canvas').boundingBox();
  await page.mouse.click(box.x + cx, box.y + cy);
}

/** Sets the form's field `id` and starts a fresh picture with the settings. */
async function settings(values) {
  for (const [id, value] of Object.entries(values)) await page.fill(`#ps-${id}`, String(value));
  await page.click('#ps-clear');
}

/** The orbits as the page holds them. */
async function orbits() {
  return page.evaluate(() => window.geomint.phaseSpace.orbits.map(({ start, request, points, state }) =>
    ({ start, request, points, state })));
}

async function simulate(request) {
  const response = await fetch(`${base}/api/v1/simulate`, {
    method: 'POST',
    headers: { 'content-type': 'application/json' },
    body: JSON.stringify(request),
  });
  assert.equal(response.status, 200);
  return response.json();
}

before(async () => {
  assert.ok(base, 'set GEOMINT_URL to the server under test (scripts/test-browser does)');
  await waitForServer();
  ({ context, page, profile } = await launch({ width: 1280, height: 900 }, consoleErrors));
  await page.goto(`${base}/`);
  await page.waitForSelector('body[data-run-state="idle"]', { timeout: 15_000 });
  await openSection(page, 'phase-space');
});

after(async () => {
  await context?.close();
  if (profile) await rm(profile, { recursive: true, force: true });
});

test('a click launches an orbit whose points are the API’s, on the energy chosen', async () => {
  await page.selectOption('#ps-example', 'henon_heiles');
  await settings({ 't-end': 600, points: 60 });
  await clickAt(0.1, 0.05);
  await clickAt(-0.2, 0.1);
  assert.equal(await settled(), 'done');
  const shown = await orbits();
  assert.equal(shown.length, 2);
  for (const orbit of shown) {
    assert.equal(orbit.state, 'done');
    const [x, px] = orbit.start;
    assert.deepEqual(orbit.request.q0, [x, 0]);
    assert.deepEqual(orbit.request.p0, [px, 0]);
    assert.deepEqual(orbit.request.energy, { value: 0.125, momentum: 'p_y' });
    const doc = await simulate(orbit.request);
    const section = doc.runs[0].section;
    assert.ok(section.t.length > 40, `${section.t.length} points`);
    assert.deepEqual(orbit.points, { t: section.t, q: section.q, p: section.p, energy: section.energy });
    for (const [k, h] of orbit.points.energy.entries()) {
      assert.ok(Math.abs(h - 0.125) <= 1e-12, `H = ${h}`);
      assert.ok(Math.abs(orbit.points.q[k][1]) <= 1e-13);
      assert.ok(orbit.points.p[k][1] > 0);
    }
  }
  // The readout names the crossing under the pointer.
  const [x, px] = [shown[0].points.q[3][0], shown[0].points.p[3][0]];
  const [cx, cy] = await page.evaluate(([a, b]) => window.geomint.phaseSpace.plot.px(a, b), [x, px]);
  const box = await page.locator('#ps-canvas').boundingBox();
  await page.mouse.move(box.x + cx, box.y + cy);
  const readout = await page.$eval('#ps-readout', (n) => ({ ...n.dataset, text: n.textContent }));
  assert.ok(readout.orbit !== undefined, readout.text);
  assert.match(readout.text, /^x = .*, p_x = .*crossing \d+: t = .*, H = 0\.12/);
  await page.screenshot({ path: join(artifacts, 'phase-space.png'), fullPage: true });

  // The link reproduces the picture: the same orbits, the same points.
  const link = await page.getAttribute('#ps-link', 'href');
  assert.match(link, /^#orbits=/);
  // A fresh load of the page at that address (not a hash change in the open page).
  await page.goto('about:blank');
  await page.goto(`${base}/${link}`);
  await page.waitForSelector('#phase-space:not([hidden])');
  await page.waitForFunction(() => window.geomint?.phaseSpace?.orbits.length === 2, null, { timeout: 15_000 });
  assert.equal(await settled(), 'done');
  const again = await orbits();
  assert.deepEqual(again.map((o) => o.request), shown.map((o) => o.request));
  assert.deepEqual(again.map((o) => o.points), shown.map((o) => o.points));

  // Downloads: the orbits as JSON, the last as a recording.
  const [json] = await Promise.all([page.waitForEvent('download'), page.click('#ps-download-json')]);
  assert.equal(json.suggestedFilename(), 'geomint-phase-space.json');
  const [rrd] = await Promise.all([page.waitForEvent('download'), page.click('#ps-download-rrd')]);
  assert.equal(rrd.suggestedFilename(), 'geomint-orbit.rrd');
});

test('the driven Duffing oscillator’s stroboscopic section grows at the drive’s period', async () => {
  await page.selectOption('#ps-example', 'duffing');
  await settings({ 't-end': 600, points: 500 });
  await clickAt(1.0, 0.0);
  assert.equal(await settled(), 'done');
  const [orbit] = await orbits();
  const period = (2 * Math.PI) / 1.2;
  assert.deepEqual(orbit.request.section, { period, phase: 0, max_points: 500 });
  const n = Math.floor(600 / period);
  assert.equal(orbit.points.t.length, n);
  orbit.points.t.forEach((t, k) => assert.equal(t, (k + 1) * period));
  const drawn = await page.evaluate(() => window.geomint.phaseSpace.plot.orbits[0].length);
  assert.equal(drawn, n);
});

test('a refused surface shows the server’s field and message', async () => {
  await page.selectOption('#ps-example', 'henon_heiles');
  await settings({ where: 'y +', 't-end': 100 });
  await clickAt(0.0, 0.0);
  assert.equal(await settled(), 'error');
  const message = await page.textContent('#err-ps-form');
  assert.match(message, /^section\.where: /);
  const unexpected = consoleErrors.filter((t) => !LOGGED_422.test(t));
  assert.deepEqual(unexpected, []);
});
