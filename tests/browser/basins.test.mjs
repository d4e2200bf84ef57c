// Browser test of the page's Basins section: headless Chromium (Debian's package, driven by
// playwright-core) against the geomint server in GEOMINT_URL. The presets come from the server;
// the damped double well on a 9 × 9 grid streams its progress to every cell, shows the API's own
// answer, draws every cell in its attractor's colour (two minima and the saddle at the centre
// cell), names them in the legend with their shares, reads a cell's attractor and decision time
// under the pointer and by keyboard, and draws a clicked cell's orbit, which ends in the well its
// label names; cut short, the map's undecided cells are grey and say why; the Hénon–Heiles escape
// map names its exits up, left and right, and its cells off the energy surface say so; the forced
// Duffing oscillator's two period-1 orbits get names of their own; the forced pendulum's rotating
// orbits, one given by name in the request, are listed with what each is; a full-size map shows its
// progress and Cancel stops it. Screenshots at desktop and phone widths go to artifacts/.

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
let presets;

async function settled(states, timeout = 60_000) {
  await page.waitForFunction((wanted) => wanted.includes(document.querySelector('#basins').dataset.basinsState),
    states, { timeout });
  return page.getAttribute('#basins', 'data-basins-state');
}

/** Waits until the map is laid out (a redraw lays it out in the next animation frame). */
async function laidOut() {
  await page.waitForFunction(() => window.geomint.basins.map?.cssWidth > 0 && !window.geomint.basins.pending);
}

/** Points at cell (col, row) of the map and returns the readout's data and text. */
async function readAt(col, row) {
  await laidOut();
  await page.locator('#ba-canvas').scrollIntoViewIfNeeded();
  const [x, y] = await page.evaluate(([c, r]) => window.geomint.basins.map.cellCentre(c, r), [col, row]);
  const box = await page.locator('#ba-canvas').boundingBox();
  await page.mouse.move(0, 0);
  await page.mouse.move(box.x + x, box.y + y);
  return page.$eval('#ba-readout', (n) => ({ ...n.dataset, text: n.textContent }));
}

/** The colour drawn at cell units (u, v) of the map (a cell's centre is (c + 0.5, r + 0.5)). */
async function pixelAt(u, v) {
  await laidOut();
  return page.evaluate(([uu, vv]) => {
    const { map } = window.geomint.basins;
    const ctx = map.canvas.getContext('2d');
    const dpr = map.canvas.width / map.cssWidth;
    const [x, y] = map.px(uu, vv);
    return [...ctx.getImageData(Math.round(x * dpr), Math.round(y * dpr), 1, 1).data].slice(0, 3);
  }, [u, v]);
}

/** The legend's entries: label, kind, name, share (in %) and the whole text. */
async function legend() {
  return page.$$eval('#ba-legend li', (lis) => lis.map((li) => ({
    label: Number(li.dataset.label), kind: li.dataset.kind, name: li.querySelector('.attractor-name').textContent,
    share: Number(li.querySelector('.share').textContent.replace(' %', '')), text: li.textContent,
  })));
}

/** Runs `request` in the section; returns the document it shows. */
async function runRequest(request) {
  await page.fill('#ba-spec', JSON.stringify(request));
  await page.locator('#ba-run').scrollIntoViewIfNeeded();
  await page.click('#ba-run');
  assert.equal(await settled(['done', 'error']), 'done', await page.textContent('#err-ba-spec'));
  return page.evaluate(() => window.geomint.basins.last.doc);
}

/** A preset's request on an n × n grid. */
function smallPreset(id, n) {
  const request = structuredClone(presets.find((p) => p.id === id).request);
  for (const axis of request.axes) axis.n = n;
  return request;
}

before(async () => {
  assert.ok(base, 'set GEOMINT_URL to the server under test (scripts/test-browser does)');
  await waitForServer();
  presets = await (await fetch(`${base}/api/v1/studies/basins/presets`)).json();
  ({ context, page, profile } = await launch({ width: 1280, height: 900 }, consoleErrors));
  await page.goto(`${base}/`);
  await page.waitForSelector('body[data-run-state="idle"]', { timeout: 15_000 });
  await page.waitForFunction(() => !document.querySelector('#ba-run').disabled, null, { timeout: 15_000 });
  await openSection(page, 'basins');
});

after(async () => {
  await context?.close();
  if (profile) await rm(profile, { recursive: true, force: true });
});

test('the double well: two minima and the saddle in their colours and the legend, with the API’s shares', async () => {
  assert.deepEqual(await page.$$eval('#ba-preset option', (os) => os.map((o) => o.value)), presets.map((p) => p.id));
  await page.selectOption('#ba-preset', 'double_well');
  assert.deepEqual(JSON.parse(await page.inputValue('#ba-spec')), presets.find((p) => p.id === 'double_well').request);
  const request = smallPreset('double_well', 9);
  const shown = await runRequest(request);
  assert.deepEqual(await page.evaluate(() => window.geomint.basins.lastProgress), { type: 'progress', done: 81, total: 81 });
  const { status, body: api } = await postJson('/api/v1/studies/basins', request);
  assert.equal(status, 200);
  delete shown.wall_ms;
  delete api.wall_ms;
  assert.deepEqual(shown, api);
  const run = api.runs[0];

  // The legend: two minima and the saddle (the centre cell starts at rest on it), each with its
  // share of the grid as the API gives it.
  const entries = await legend();
  assert.equal(entries.length, 3, JSON.stringify(entries));
  assert.equal(entries.filter((e) => /minimum/.test(e.name)).length, 2);
  assert.equal(entries.filter((e) => /saddle/.test(e.name)).length, 1);
  for (const e of entries) {
    assert.equal(e.kind, 'equilibrium');
    assert.ok(Math.abs(e.share - 100 * run.fractions[e.label]) < 0.05, `${e.name}: ${e.share} % against ${run.fractions[e.label]}`);
    assert.match(e.text, new RegExp(`\\(${run.attractors.find((a) => a.label === e.label).cells} cells?\\)`));
  }
  const minima = entries.filter((e) => /minimum/.test(e.name));
  assert.ok(minima.every((e) => e.share > 40), 'the minima share the grid about evenly');

  // Every cell is drawn in its attractor's colour: the two minima in two colours, the saddle's one
  // cell in a third.
  const colours = new Map();
  for (let k = 0; k < 81; k++) {
    const rgb = await pixelAt((k % 9) + 0.5, Math.floor(k / 9) + 0.5);
    const key = rgb.join(',');
    colours.set(key, new Set([...(colours.get(key) ?? []), run.labels[k]]));
  }
  assert.equal(colours.size, 3, [...colours.keys()].join(' '));
  for (const labels of colours.values()) assert.equal(labels.size, 1, 'one colour, one attractor');

  // The metrics beside the map are the run's.
  const metric = (key) => page.textContent(`#ba-metrics [data-metric="${key}"] strong`);
  assert.equal(Number(await metric('basin_entropy')), Number(run.basin_entropy.toPrecision(4)));
  assert.equal(Number(await metric('boundary_basin_entropy')), Number(run.boundary_basin_entropy.toPrecision(4)));
  assert.match(await metric('decided_by'), new RegExp(`^energy ${run.decided_by.energy}$`));
  assert.ok(await page.isHidden('#ba-reasons'), 'nothing is undecided');

  // The readout under the pointer: the cell's attractor and decision time.
  for (const [col, row] of [[0, 0], [7, 2], [4, 4]]) {
    const d = await readAt(col, row);
    const k = row * 9 + col;
    assert.equal(Number(d.cell), k);
    assert.equal(Number(d.label), run.labels[k]);
    assert.equal(d.name, entries.find((e) => e.label === run.labels[k]).name);
    assert.equal(Number(d.decidedAt), run.decided_at[k]);
    assert.ok(d.text.includes(`: ${d.name} — equilibrium, decided at t = `), d.text);
  }
  // And by keyboard: the arrow keys move the cursor from the cell last read.
  await page.focus('#ba-canvas');
  await page.keyboard.press('ArrowLeft');
  await page.keyboard.press('ArrowUp');
  const moved = await page.$eval('#ba-readout', (n) => ({ ...n.dataset }));
  assert.equal(Number(moved.cell), 5 * 9 + 3);
  assert.equal(Number(moved.label), run.labels[5 * 9 + 3]);

  // A click draws the cell's orbit to its decision time; it ends in the well its label names
  // (below the saddle's energy, x keeps the sign of its minimum).
  const k = run.labels.findIndex((label, i) => i !== 40 && label >= 0);
  const [cx, cy] = await page.evaluate(([c, r]) => window.geomint.basins.map.cellCentre(c, r), [k % 9, Math.floor(k / 9)]);
  const box = await page.locator('#ba-canvas').boundingBox();
  await page.mouse.click(box.x + cx, box.y + cy);
  await page.waitForFunction(() => ['done', 'error'].includes(document.querySelector('#ba-orbit').dataset.orbitState));
  assert.equal(await page.getAttribute('#ba-orbit', 'data-orbit-state'), 'done', await page.textContent('#ba-orbit'));
  const orbit = await page.evaluate(() => {
    const { orbit: o } = window.geomint.basins;
    return { cell: o.cell, answer: o.answer, points: o.points.length };
  });
  assert.equal(orbit.cell, k);
  const samples = orbit.answer.runs[0];
  assert.ok(Math.abs(samples.t.at(-1) - run.decided_at[k]) < request.h, `${samples.t.at(-1)} against ${run.decided_at[k]}`);
  const minimum = run.attractors.find((a) => a.label === run.labels[k]).equilibrium.q[0];
  assert.equal(Math.sign(samples.q.at(-1)[0]), Math.sign(minimum));
  assert.equal(orbit.points, samples.t.length);
  assert.match(await page.textContent('#ba-orbit'), /the map says equilibrium \d \(minimum\), decided at t = /);
  await page.locator('#basins').screenshot({ path: join(artifacts, 'basins-double-well.png') });
  assert.deepEqual(consoleErrors, []);
});

test('cut short, the undecided cells are grey and hatched, and say why', async () => {
  const request = { ...smallPreset('double_well', 9), t_end: 3 };
  const doc = await runRequest(request);
  const run = doc.runs[0];
  const k = run.labels.findIndex((label) => label < 0);
  assert.ok(k >= 0, 'some cells are undecided by t = 3');
  const reason = run.undecided.find((u) => u.cell === k).reason;
  assert.match(reason, /above the lowest saddle/);
  const d = await readAt(k % 9, Math.floor(k / 9));
  assert.equal(d.label, '-1');
  assert.equal(d.decidedAt, '');
  assert.equal(d.text, `${d.text.split(':')[0]}: undecided — ${reason}.`);
  // Grey off the hatch line, white on it (the diagonal through the centre).
  assert.deepEqual(await pixelAt((k % 9) + 0.2, Math.floor(k / 9) + 0.8), [150, 150, 150]);
  const entries = await legend();
  const undecided = entries.find((e) => e.kind === 'undecided');
  assert.ok(Math.abs(undecided.share - 100 * run.undecided_fraction) < 0.05);
  const groups = await page.$$eval('#ba-reasons li', (lis) => lis.map((li) => ({ cells: Number(li.dataset.cells), text: li.textContent })));
  assert.equal(groups.reduce((sum, g) => sum + g.cells, 0), run.undecided.length);
  assert.ok(groups.some((g) => g.text.includes(reason)), JSON.stringify(groups));
});

test('Hénon–Heiles escapes: the legend names the exits up, left and right; off the energy surface says so', async () => {
  await page.selectOption('#ba-preset', 'henon_heiles_escapes');
  const doc = await runRequest(smallPreset('henon_heiles_escapes', 15));
  const run = doc.runs[0];
  const entries = await legend();
  const exits = entries.filter((e) => e.kind === 'exit');
  assert.deepEqual(exits.map((e) => e.name).sort(), ['left', 'right', 'up']);
  for (const e of exits) assert.ok(Math.abs(e.share - 100 * run.fractions[e.label]) < 0.05 && e.share > 5, `${e.name} ${e.share}`);
  // The grid's corners lie off the energy surface: undecided, and the reason says so.
  const d = await readAt(0, 0);
  assert.equal(d.label, '-1');
  assert.match(d.text, /^y = -0\.6, p_y = -0\.6: undecided — .*no state here has H = 0\.25/);
  assert.match(await page.textContent('#ba-reasons'), /off the energy surface/);
  assert.match(await page.getAttribute('#ba-canvas', 'aria-label'), /y \(q0\[1\]\) across, p_y \(p0\[1\]\) upwards/);
  // Three exits: the Wada test's share per exit, named, as the document has them.
  assert.equal(run.wada.length, 3);
  const wada = await page.textContent('#ba-metrics [data-metric="wada"] strong');
  assert.equal(wada, run.wada.map((w) => `${run.attractors[w.label].name} ${+w.share.toPrecision(3)}`).join(', '));
  // An exit's orbit ends at its decision time, the momentum solved from the energy.
  const k = run.labels.findIndex((label) => label >= 0);
  await page.evaluate(([c, r]) => window.geomint.basins.showOrbit({ col: c, row: r }), [k % 15, Math.floor(k / 15)]);
  await page.waitForFunction(() => ['done', 'error'].includes(document.querySelector('#ba-orbit').dataset.orbitState));
  assert.equal(await page.getAttribute('#ba-orbit', 'data-orbit-state'), 'done', await page.textContent('#ba-orbit'));
  const answer = await page.evaluate(() => window.geomint.basins.orbit.answer);
  const [q, p] = [answer.system.q0, answer.system.p0];
  const energy = (p[0] ** 2 + p[1] ** 2 + q[0] ** 2 + q[1] ** 2) / 2 + q[0] ** 2 * q[1] - q[1] ** 3 / 3;
  assert.ok(Math.abs(energy - 0.25) < 1e-12, `H = ${energy}`);
  await page.locator('#basins').screenshot({ path: join(artifacts, 'basins-henon-heiles.png') });
  assert.deepEqual(consoleErrors.filter((e) => !LOGGED_422.test(e)), []);
});

test('the forced Duffing oscillator: two period-1 orbits, each named and placed by its stroboscopic point', async () => {
  await page.selectOption('#ba-preset', 'forced_duffing');
  const doc = await runRequest(smallPreset('forced_duffing', 7));
  const run = doc.runs[0];
  assert.equal(doc.equilibria, null, 'a driven system has no critical points searched');
  const entries = await legend();
  assert.equal(entries.length, 2, JSON.stringify(entries));
  for (const e of entries) {
    const a = run.attractors.find((x) => x.label === e.label);
    assert.equal(e.kind, 'periodic');
    // Named as the API names it (`period-1 orbit 1`, `… 2`).
    assert.match(a.name, /^period-1 orbit [12]$/);
    assert.equal(e.name, a.name);
    assert.ok(Math.abs(e.share - 100 * run.fractions[e.label]) < 0.05);
  }
  assert.notEqual(entries[0].name, entries[1].name);
  assert.equal(await page.$('#ba-metrics [data-metric="lowest_saddle_energy"]'), null);
  assert.match(await page.textContent('#ba-metrics [data-metric="decided_by"] strong'), new RegExp(`recurrence ${run.decided_by.recurrence}`));
});

test('the forced pendulum: two rotating orbits, one of them given by name, in the legend', async () => {
  await page.selectOption('#ba-preset', 'forced_pendulum');
  const request = smallPreset('forced_pendulum', 7);
  assert.deepEqual(request.recognition.angles, ['theta']);
  request.attractors = [{ name: 'forwards', points: [[-0.8162, 1.7592]], radius: 0.05 }];
  const doc = await runRequest(request);
  const run = doc.runs[0];
  assert.equal(run.undecided_fraction, 0);
  const entries = await legend();
  assert.deepEqual(entries.map((e) => e.kind), ['given', 'periodic'], JSON.stringify(entries));
  // The given attractor keeps its name and says what it is; the other is found on the fly.
  assert.equal(entries[0].name, 'forwards');
  assert.match(entries[0].text, /the request's attractor: orbits that come within 0\.05 of it end there/);
  assert.match(entries[0].text, /point \(-0\.8162, 1\.759/);
  assert.equal(entries[1].name, run.attractors[1].name);
  for (const e of entries) assert.ok(Math.abs(e.share - 100 * run.fractions[e.label]) < 0.05);
  assert.match(await page.textContent('#ba-metrics [data-metric="decided_by"] strong'),
    new RegExp(`proximity ${run.decided_by.proximity}`));
});

test('a running map shows its progress and Cancel stops it', async () => {
  await page.selectOption('#ba-preset', 'henon_heiles_escapes');
  const request = { ...smallPreset('henon_heiles_escapes', 101), t_end: 2000 };
  await page.fill('#ba-spec', JSON.stringify(request));
  await page.click('#ba-run');
  await page.waitForFunction(() => (window.geomint.basins.lastProgress?.done ?? 0) > 0, null, { timeout: 30_000 });
  const bar = await page.$eval('#ba-progress', (p) => ({ value: p.value, max: p.max, hidden: p.hidden }));
  assert.equal(bar.max, 101 * 101);
  assert.ok(!bar.hidden && bar.value > 0, JSON.stringify(bar));
  assert.match(await page.textContent('#ba-status'), /^Running: \d+ of 10201 cells/);
  await page.click('#ba-cancel');
  assert.equal(await settled(['cancelled', 'done']), 'cancelled');
  assert.equal(await page.textContent('#ba-status'), 'Cancelled.');
});

test('on a phone the map, legend and metrics stack within the screen', async () => {
  await page.setViewportSize({ width: 390, height: 844 });
  await laidOut();
  await page.evaluate(() => new Promise((done) => requestAnimationFrame(() => requestAnimationFrame(done))));
  const widths = await page.evaluate(() => ['#ba-canvas', '#ba-legend', '#ba-metrics'].map((s) => {
    const box = document.querySelector(s).getBoundingClientRect();
    return [s, box.left, box.right];
  }));
  for (const [selector, left, right] of widths) assert.ok(left >= 0 && right <= 390, `${selector} at ${left}–${right} px`);
  await page.locator('#ba-results').screenshot({ path: join(artifacts, 'basins-phone.png') });
  await page.setViewportSize({ width: 1280, height: 900 });
});
