// Browser test of what the Phase-space picture claims: it never disagrees with the form unsaid
// (the plane's ranges redraw at once; an edited energy is named as differing from the drawn one
// until the next click, which starts a new picture at the form's energy), and the part of the
// plane outside the energy surface is grey — the server's allowed region — with a click there
// answered in words and no orbit. Screenshots go to artifacts/.

import { test, before, after } from 'node:test';
import assert from 'node:assert/strict';
import { rm } from 'node:fs/promises';
import { join } from 'node:path';
import { artifacts, base, launch, openSection, waitForServer } from './harness.mjs';

let context;
let page;
let profile;
const consoleErrors = [];

async function settled(timeout = 60_000) {
  await page.waitForFunction(() => ['done', 'error'].includes(document.querySelector('#phase-space').dataset.psState),
    null, { timeout });
  return page.getAttribute('#phase-space', 'data-ps-state');
}

/** Waits until the grey region of the current settings has arrived. */
async function regionReady() {
  await page.waitForSelector('#phase-space[data-ps-region="ready"]', { timeout: 15_000 });
}

/** Clicks the plane at plane coordinates (x, y). */
async function clickAt(x, y) {
  const [cx, cy] = await page.evaluate(([a, b]) => window.geomint.phaseSpace.plot.px(a, b), [x, y]);
  const box = await page.locator('#ps-canvas').boundingBox();
  await page.mouse.click(box.x + cx, box.y + cy);
}

/** The colour of the canvas at plane point (x, y), as [r, g, b]. */
async function colourAt(x, y) {
  return page.evaluate(([a, b]) => {
    const plot = window.geomint.phaseSpace.plot;
    const [cx, cy] = plot.px(a, b);
    const dpr = window.devicePixelRatio || 1;
    const data = plot.canvas.getContext('2d').getImageData(Math.round(cx * dpr), Math.round(cy * dpr), 1, 1).data;
    return [data[0], data[1], data[2]];
  }, [x, y]);
}

before(async () => {
  assert.ok(base, 'set GEOMINT_URL to the server under test (scripts/test-browser does)');
  await waitForServer();
  ({ context, page, profile } = await launch({ width: 1400, height: 900 }, consoleErrors));
  await page.goto(`${base}/`);
  await page.waitForSelector('body[data-run-state="idle"]', { timeout: 15_000 });
  await openSection(page, 'phase-space');
});

after(async () => {
  await context?.close();
  if (profile) await rm(profile, { recursive: true, force: true });
});

test('edits to the form redraw the plane or are named until the next click applies them', async () => {
  await page.selectOption('#ps-example', 'henon_heiles');
  await page.fill('#ps-t-end', '300');
  await page.fill('#ps-points', '30');
  await page.click('#ps-clear');
  await clickAt(0.1, 0.05);
  assert.equal(await settled(), 'done');

  // The plane's range applies at once, with the orbit redrawn on it.
  await page.fill('#ps-x-min', '-0.35');
  const plane = await page.evaluate(() => window.geomint.phaseSpace.plot.plane.x.min);
  assert.equal(plane, -0.35);
  // An edited energy is named beside the one drawn.
  await page.fill('#ps-energy', '0.05');
  const stale = await page.locator('#ps-stale');
  assert.ok(await stale.isVisible());
  const note = await stale.textContent();
  assert.match(note, /drawn with E = 0\.125/);
  assert.match(note, /the form now says E = 0\.05/);
  assert.match(await page.textContent('#ps-drawn'), /E = 0\.125/);
  await page.screenshot({ path: join(artifacts, 'phase-space-stale.png'), fullPage: false });

  // The next click starts a new picture at the form's energy.
  await clickAt(0.1, 0.05);
  assert.equal(await settled(), 'done');
  const orbits = await page.evaluate(() => window.geomint.phaseSpace.orbits.map((o) => ({ request: o.request, energy: o.points.energy })));
  assert.equal(orbits.length, 1);
  assert.equal(orbits[0].request.energy.value, 0.05);
  assert.ok(orbits[0].energy.length > 5, `${orbits[0].energy.length} points`);
  for (const h of orbits[0].energy) assert.ok(Math.abs(h - 0.05) <= 1e-12, `H = ${h}`);
  assert.equal(await stale.isVisible(), false);
  assert.match(await page.textContent('#ps-drawn'), /E = 0\.05/);
  assert.equal(await page.evaluate(() => window.geomint.phaseSpace.settings.x.min), -0.35);

  // With nothing drawn, an edit applies at once.
  await page.click('#ps-clear');
  await page.fill('#ps-energy', '0.1');
  assert.equal(await page.evaluate(() => window.geomint.phaseSpace.settings.energy), 0.1);
  assert.match(await page.textContent('#ps-drawn'), /E = 0\.1\b/);
});

test('the plane outside the energy surface is grey, and a click there starts nothing and says why', async () => {
  // The example afresh (selecting the option on show may not count as a change).
  await page.selectOption('#ps-example', 'duffing');
  await page.selectOption('#ps-example', 'henon_heiles');
  await regionReady();
  const region = await page.evaluate(() => window.geomint.phaseSpace.plot.region);
  // On y = 0 at E = 1/8 the allowed points are those with (x² + p_x²)/2 ≤ E.
  region.y.forEach((px, j) => region.x.forEach((x, i) => {
    const h = (x * x + px * px) / 2;
    if (Math.abs(h - 0.125) > 1e-9) assert.equal(region.allowed[j][i], h < 0.125, `(${x}, ${px})`);
  }));
  // The example's plane holds the whole allowed region: its edges are all outside.
  const rows = region.allowed;
  const edges = [...rows[0], ...rows[rows.length - 1], ...rows.map((r) => r[0]), ...rows.map((r) => r[r.length - 1])];
  assert.ok(edges.every((ok) => !ok), 'the allowed region reaches the edge of the plane');
  const legend = await page.textContent('#ps-region');
  assert.match(legend, /Grey: outside the energy surface at E = 0\.125/);
  // Grey where forbidden, white where allowed.
  assert.deepEqual(await colourAt(-0.5, 0.4), [0xd4, 0xd4, 0xd4]);
  assert.deepEqual(await colourAt(0.0, -0.3), [0xff, 0xff, 0xff]);
  await page.screenshot({ path: join(artifacts, 'phase-space-region.png'), fullPage: false });

  // A click in the grey starts no orbit and says so in words.
  const before = await page.evaluate(() => window.geomint.phaseSpace.orbits.length);
  await clickAt(-0.5, 0.4);
  assert.equal(await page.evaluate(() => window.geomint.phaseSpace.orbits.length), before);
  const status = await page.textContent('#ps-status');
  assert.match(status, /outside the energy surface/);
  assert.match(status, /above E = 0\.125/);
  assert.doesNotMatch(status + (await page.textContent('#ps-orbits')), /energy\.value|must be finite/);

  // A stroboscopic section has no energy surface: nothing is grey.
  await page.selectOption('#ps-example', 'duffing');
  assert.equal(await page.evaluate(() => window.geomint.phaseSpace.plot.region), null);
  assert.equal(await page.textContent('#ps-region'), '');
  assert.deepEqual(consoleErrors, []);
});

test('each orbit lists its ⟨Y⟩ and λ_max, the API’s, and can be coloured by ⟨Y⟩', async () => {
  await page.selectOption('#ps-example', 'duffing');
  await page.selectOption('#ps-example', 'henon_heiles');
  await page.fill('#ps-t-end', '400');
  await page.fill('#ps-points', '40');
  await page.click('#ps-clear');
  await clickAt(0.0, 0.1);
  await clickAt(-0.3, 0.0);
  assert.equal(await settled(), 'done');
  const orbits = await page.evaluate(() => window.geomint.phaseSpace.orbits.map((o) => o.request));
  const items = await page.$$eval('#ps-orbits li', (li) => li.map((n) => ({ text: n.textContent, megno: n.dataset.megno })));
  assert.equal(items.length, 2);
  for (const [k, request] of orbits.entries()) {
    assert.deepEqual(request.indicators, ['megno', 'lyapunov']);
    const response = await fetch(`${base}/api/v1/simulate`, {
      method: 'POST', headers: { 'content-type': 'application/json' }, body: JSON.stringify(request),
    });
    const run = (await response.json()).runs[0];
    assert.equal(Number(items[k].megno), run.indicators.megno_mean);
    const y = run.indicators.megno_mean;
    assert.match(items[k].text, new RegExp(`⟨Y⟩ = ${String(+y.toPrecision(3)).replace('.', '\\.')} \\((about 2|below 2|above 2)`));
    assert.match(items[k].text, /λ_max = [-\d.e]+$/);
  }
  // Coloured by ⟨Y⟩: the list's markers take the scale's colours.
  await page.selectOption('#ps-colour-by', 'megno');
  const markers = await page.$$eval('#ps-orbits li', (li) => li.map((n) => n.style.getPropertyValue('--orbit-colour')));
  const expected = await page.evaluate(() => window.geomint.phaseSpace.orbits.map((_, k) => window.geomint.phaseSpace.orbitColour(k)));
  assert.deepEqual(markers, expected);
  assert.ok(markers.every((m) => m.startsWith('rgb(')), markers.join(' '));
  await page.selectOption('#ps-colour-by', 'orbit');
});

test('the chaos map of the plane runs in Sweeps, and a click on a cell launches its orbit on the section', async () => {
  await page.selectOption('#ps-example', 'duffing');
  await page.selectOption('#ps-example', 'henon_heiles');
  await page.fill('#ps-method', '"velocity_verlet"');
  await page.fill('#ps-t-end', '100');
  await page.click('#ps-clear');
  await page.click('#ps-chaos-map');
  await page.waitForSelector('#sweep:not([hidden])', { timeout: 5_000 });
  await page.waitForFunction(() => ['done', 'error'].includes(document.querySelector('#sweep').dataset.sweepState),
    null, { timeout: 120_000 });
  assert.equal(await page.getAttribute('#sweep', 'data-sweep-state'), 'done');
  const body = await page.evaluate(() => window.geomint.sweep.last.body);
  assert.deepEqual(body.energy_surface, { energy: 0.125, solve_for: 'p0[1]' });
  assert.deepEqual(body.axes.map((a) => [a.name, a.min, a.max]), [['q0[0]', -0.55, 0.55], ['p0[0]', -0.55, 0.55]]);
  assert.equal(await page.isVisible('#sw-plane-note'), true);
  assert.equal(await page.inputValue('#sw-metric'), 'megno_mean');

  // A cell inside the energy surface: its orbit starts on the section from the cell's values.
  const doc = await page.evaluate(() => window.geomint.sweep.last.doc);
  const nx = doc.axes[0].n;
  const k = doc.runs[0].megno_mean.findIndex((v, i) => v != null && Math.abs(doc.axes[0].values[i % nx]) < 0.3
    && Math.abs(doc.axes[1].values[Math.floor(i / nx)]) < 0.3);
  const [col, row] = [k % nx, Math.floor(k / nx)];
  await page.evaluate(() => new Promise((done) => requestAnimationFrame(() => requestAnimationFrame(done))));
  await page.locator('#sw-canvas').scrollIntoViewIfNeeded();
  const [cx, cy] = await page.evaluate(([c, r]) => window.geomint.sweep.map.cellCentre(c, r), [col, row]);
  const box = await page.locator('#sw-canvas').boundingBox();
  await page.mouse.click(box.x + cx, box.y + cy);
  await page.waitForSelector('#phase-space:not([hidden])', { timeout: 5_000 });
  assert.equal(await settled(), 'done');
  const orbits = await page.evaluate(() => window.geomint.phaseSpace.orbits.map((o) => o.start));
  assert.deepEqual(orbits.at(-1), [doc.axes[0].values[col], doc.axes[1].values[row]]);
  await page.fill('#ps-method', JSON.stringify({ id: 'kahan_li_8', base: 'velocity_verlet' }));
});

test('an orbit with fewer points than asked says why', async () => {
  await page.selectOption('#ps-example', 'duffing');
  await page.fill('#ps-t-end', '600');
  await page.fill('#ps-points', '500');
  await page.click('#ps-clear');
  await clickAt(1.0, 0.0);
  assert.equal(await settled(), 'done');
  const n = Math.floor(600 / ((2 * Math.PI) / 1.2));
  const text = await page.textContent('#ps-orbits li');
  assert.match(text, new RegExp(`: ${n} points — fewer than the 500 asked: t_end = 600 holds ${n} drive periods; raise t_end for more`));
});
