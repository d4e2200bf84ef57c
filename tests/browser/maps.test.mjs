// Browser test of how the maps read: a chaos map (the Hénon–Heiles MEGNO preset, made smaller) is
// drawn in its axes' true aspect with the coordinates' names, ⟨Y⟩ on a 0–8 scale with 2 marked
// (regular and chaotic cells far apart in colour) that the reader can change, cells outside the
// energy surface named as such, and readouts in words; the energy map's colour bar spans the
// ratios 98 % of its cells stay within, symmetric about 1. Screenshots go to artifacts/.

import { test, before, after } from 'node:test';
import assert from 'node:assert/strict';
import { rm } from 'node:fs/promises';
import { join } from 'node:path';
import { artifacts, base, launch, openSection, postJson, waitForServer } from './harness.mjs';

let context;
let page;
let profile;
const consoleErrors = [];

before(async () => {
  assert.ok(base, 'set GEOMINT_URL to the server under test (scripts/test-browser does)');
  await waitForServer();
  ({ context, page, profile } = await launch({ width: 1400, height: 900 }, consoleErrors));
  await page.goto(`${base}/`);
  await page.waitForSelector('body[data-run-state="idle"]', { timeout: 15_000 });
  await page.waitForFunction(() => !document.querySelector('#sw-run').disabled, null, { timeout: 15_000 });
});

after(async () => {
  await context?.close();
  if (profile) await rm(profile, { recursive: true, force: true });
});

/** Points at cell (col, row) of the sweep map; the readout's text. */
async function readAt(col, row) {
  await page.evaluate(() => new Promise((done) => requestAnimationFrame(() => requestAnimationFrame(done))));
  await page.locator('#sw-canvas').scrollIntoViewIfNeeded();
  const [x, y] = await page.evaluate(([c, r]) => window.geomint.sweep.map.cellCentre(c, r), [col, row]);
  const box = await page.locator('#sw-canvas').boundingBox();
  await page.mouse.move(0, 0);
  await page.mouse.move(box.x + x, box.y + y);
  return page.textContent('#sw-readout');
}

/** The colour of the sweep map's cell (col, row), as [r, g, b]. */
async function cellColour(col, row) {
  return page.evaluate(([c, r]) => {
    const { map } = window.geomint.sweep;
    const [x, y] = map.cellCentre(c, r);
    const dpr = map.canvas.width / map.cssWidth;
    return [...map.canvas.getContext('2d').getImageData(Math.round(x * dpr), Math.round(y * dpr), 1, 1).data].slice(0, 3);
  }, [col, row]);
}

test('a chaos map reads: true aspect, named axes, ⟨Y⟩ on its own scale, the energy surface named', async () => {
  await openSection(page, 'sweep');
  await page.selectOption('#sw-preset', 'henon_heiles_megno');
  const request = JSON.parse(await page.inputValue('#sw-spec'));
  request.axes[0].n = 23;
  request.axes[1].n = 21;
  request.t_end = 400;
  await page.fill('#sw-spec', JSON.stringify(request));
  await page.click('#sw-run');
  await page.waitForFunction(() => ['done', 'error'].includes(document.querySelector('#sweep').dataset.sweepState),
    null, { timeout: 120_000 });
  assert.equal(await page.getAttribute('#sweep', 'data-sweep-state'), 'done');
  await page.evaluate(() => new Promise((done) => requestAnimationFrame(() => requestAnimationFrame(done))));
  const doc = await page.evaluate(() => window.geomint.sweep.last.doc);
  assert.equal(await page.inputValue('#sw-metric'), 'megno_mean');

  // The cells in their true shape: the plot area's height over its width is the axes' spans'.
  const map = await page.evaluate(() => {
    const m = window.geomint.sweep.map;
    return { area: m.area, x: m.xAxis.label, y: m.yAxis.label };
  });
  const span = (a) => ((a.max - a.min) * a.n) / (a.n - 1);
  const aspect = span(request.axes[1]) / span(request.axes[0]);
  assert.ok(Math.abs(map.area.h / map.area.w / aspect - 1) < 0.02, `${map.area.w} × ${map.area.h}, aspect ${aspect}`);
  assert.equal(map.x, 'y (q0[1])');
  assert.equal(map.y, 'p_y (p0[1])');

  // ⟨Y⟩ from 0 to 8 with 2 marked; a regular cell and a chaotic one far apart in colour.
  assert.equal(await page.inputValue('#sw-scale-lo'), '0');
  assert.equal(await page.inputValue('#sw-scale-hi'), '8');
  const caption = await page.textContent('#sw-scale-caption');
  assert.match(caption, /from 0 .* to 8 .*2 is marked/);
  const values = doc.runs[0].megno_mean;
  const nx = request.axes[0].n;
  const regular = values.findIndex((v) => v != null && Math.abs(v - 2) < 0.1);
  const chaotic = values.findIndex((v) => v != null && v > 5);
  assert.ok(regular >= 0 && chaotic >= 0, 'the map has a regular and a chaotic cell');
  const [a, b] = [await cellColour(regular % nx, Math.floor(regular / nx)), await cellColour(chaotic % nx, Math.floor(chaotic / nx))];
  const distance = Math.hypot(a[0] - b[0], a[1] - b[1], a[2] - b[2]);
  assert.ok(distance > 150, `⟨Y⟩ ${values[regular]} is ${a}, ⟨Y⟩ ${values[chaotic]} is ${b}`);
  const words = await readAt(regular % nx, Math.floor(regular / nx));
  assert.match(words, /^y = [-\d.e]+, p_y = [-\d.e]+: MEGNO ⟨Y⟩ [\d.]+ \(about 2: regular, on a torus\)\.$/);
  await page.locator('#sweep').screenshot({ path: join(artifacts, 'sweep-megno.png') });

  // Cells outside the energy surface: named so in the legend and the readout.
  const outside = doc.runs[0].errors.findIndex((e) => e != null);
  assert.ok(outside >= 0, 'the plane reaches beyond the energy surface');
  assert.match(await page.textContent('#sw-scale-legend li[data-kind="outside"]'), /outside the energy surface/);
  const there = await readAt(outside % nx, Math.floor(outside / nx));
  assert.match(there, /: outside the energy surface: no value of the solved momentum gives H = E there/);
  assert.doesNotMatch(there, /q0\[|energy_surface/);
  assert.deepEqual(await cellColour(outside % nx, Math.floor(outside / nx)), [212, 212, 212]);

  // The reader sets the range: the bar and the cells follow.
  await page.fill('#sw-scale-hi', '4');
  await page.evaluate(() => new Promise((done) => requestAnimationFrame(() => requestAnimationFrame(done))));
  assert.match(await page.textContent('#sw-scale-caption'), /to 4 /);
  const top = await cellColour(chaotic % nx, Math.floor(chaotic / nx));
  assert.deepEqual(top, [253, 231, 37], 'a value above the range takes the top colour');
  assert.deepEqual(consoleErrors, []);
});

test('the energy map’s colour bar spans its own ratios, symmetric about 1', async () => {
  await openSection(page, 'energy-map');
  await page.fill('#em-nx', '9');
  await page.fill('#em-ny', '9');
  await page.fill('#em-t-max', '200');
  const posted = page.waitForRequest((r) => new URL(r.url()).pathname === '/api/v1/studies/energy-map');
  await page.click('#em-run');
  const body = JSON.parse((await posted).postData());
  await page.waitForSelector('#energy-map[data-map-state="done"]', { timeout: 60_000 });
  await page.evaluate(() => new Promise((done) => requestAnimationFrame(() => requestAnimationFrame(done))));
  const { body: api } = await postJson('/api/v1/studies/energy-map', body);
  // The scale holds 98 % of the cells: one outlier (a cell near the pivot) does not wash the map out.
  const sizes = [];
  api.epsilon_cartesian.forEach((c, k) => {
    const p = api.epsilon_polar[k];
    if (c > 0 && p > 0) sizes.push(Math.abs(Math.log10(c / p)));
  });
  sizes.sort((a, b) => a - b);
  const most = sizes[Math.floor(0.98 * (sizes.length - 1))];
  assert.ok(most > 0, `98 % within 10^${most}, largest 10^${sizes[sizes.length - 1]}`);
  const range = Number(await page.getAttribute('#em-scale-bar', 'data-range'));
  assert.equal(range, most);
  const label = await page.getAttribute('#em-scale-bar', 'aria-label');
  const ratio = (10 ** most).toPrecision(3);
  assert.ok(label.includes(`from 1/${+ratio} to ${+ratio}`), label);
  assert.match(await page.textContent('#em-scale-caption'), /scaled to this map's cells, symmetric about 1.*holds 98 % of the cells/);
  await page.locator('#energy-map').screenshot({ path: join(artifacts, 'energy-map-scaled.png') });
  assert.deepEqual(consoleErrors, []);
});
