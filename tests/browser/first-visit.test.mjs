// Browser test of the page as a reader meets it the first time: headless Chromium (Debian's
// package, driven by playwright-core) against the geomint server in GEOMINT_URL. A fresh page's
// own Run works without a preset, a few Tab presses from the top, and stays in sight at the foot of
// the form; the header's links show one section at a time, each much shorter than the whole page
// was, while the hashes the page always understood (#results, #system=…, #recording=…) still lead
// to their section and Back returns to the one before. Screenshots go to artifacts/.

import { test, before, after } from 'node:test';
import assert from 'node:assert/strict';
import { rm } from 'node:fs/promises';
import { join } from 'node:path';
import { artifacts, base, launch, openSection, waitForServer } from './harness.mjs';

/** The page's sections, in the order of the header's links. */
const SECTIONS = ['simulation', 'your-system', 'recordings', 'jobs', 'stability', 'work-precision', 'convergence', 'energy-map', 'sweep',
  'basins', 'phase-space'];

let context;
let page;
let profile;
const consoleErrors = [];

before(async () => {
  assert.ok(base, 'set GEOMINT_URL to the server under test (scripts/test-browser does)');
  await waitForServer();
  ({ context, page, profile } = await launch({ width: 1280, height: 880 }, consoleErrors));
  await page.goto(`${base}/`);
  await page.waitForSelector('body[data-run-state="idle"]', { timeout: 15_000 });
});

after(async () => {
  await context?.close();
  if (profile) await rm(profile, { recursive: true, force: true });
});

test('a fresh page’s own Run runs, a few Tab presses from the top, with no preset', async () => {
  // Methods are chosen to start with, and each group's summary names them.
  const chosen = await page.$$eval('#methods input[type=checkbox]:checked', (boxes) => boxes.map((b) => b.value));
  assert.ok(chosen.length >= 1, 'no method is chosen on a fresh page');
  assert.ok(chosen.includes('rk4'), `chosen: ${chosen}`);
  const summaries = await page.$$eval('#methods details.method-group > summary', (ss) => ss.map((s) => s.textContent));
  for (const id of chosen) assert.ok(summaries.some((s) => s.includes(id)), `${id} is named in a group's summary`);

  // From the top of the page, Tab reaches Run within the form's own fields (not past every method).
  await page.evaluate(() => document.activeElement?.blur());
  let tabs = 0;
  while ((await page.evaluate(() => document.activeElement?.id)) !== 'run') {
    assert.ok(++tabs <= 60, 'Run is not reachable with Tab');
    await page.keyboard.press('Tab');
  }
  const presets = await page.$$eval('#preset-list button', (bs) => bs.length);
  // Besides the presets: the header's links (eleven sections, three API links) and API token
  // field, and the form's own fields (system, parameters, state, step, chaos indicators) — about
  // 30, against 83 when Run came after every method card.
  const formStops = tabs - presets;
  assert.ok(formStops <= 34, `Run is ${tabs} Tab presses from the top (${formStops} past the ${presets} preset buttons)`);
  // Run is on the screen when it has the focus, without scrolling the form's panel to its end.
  const box = await page.locator('#run').boundingBox();
  assert.ok(box.y >= 0 && box.y + box.height <= 880, `Run at y = ${box.y}`);

  const [request] = await Promise.all([
    page.waitForRequest((r) => new URL(r.url()).pathname === '/api/v1/simulate' && r.method() === 'POST'),
    page.keyboard.press('Enter'),
  ]);
  await page.waitForSelector('body[data-run-state="done"]', { timeout: 30_000 });
  assert.deepEqual(request.postDataJSON().methods, chosen);
  assert.match(await page.textContent('#status'), /^Done: \d+ samples from 2 methods/);
  assert.equal(await page.textContent('#err-methods'), '');
  assert.deepEqual(consoleErrors, []);
  console.log(`# Tab presses from the top to Run: ${tabs} (${formStops} after the ${presets} preset buttons)`);
  await page.screenshot({ path: join(artifacts, 'first-visit-run.png') });
});

test('Run stays in sight at the foot of the form while the form scrolls', async () => {
  // Every method group open: the form is far taller than its panel.
  for (const group of await page.$$('#methods details.method-group:not([open]) > summary')) await group.click();
  const form = page.locator('#sim-form');
  const [panel, content] = await form.evaluate((f) => [f.clientHeight, f.scrollHeight]);
  assert.ok(content > 2 * panel, `the open form is ${content}px in a ${panel}px panel`);
  for (const top of [0, content / 2]) {
    await form.evaluate((f, y) => { f.scrollTop = y; }, top);
    const [formBox, runBox] = [await form.boundingBox(), await page.locator('#run').boundingBox()];
    assert.ok(runBox.y >= formBox.y && runBox.y + runBox.height <= formBox.y + formBox.height,
      `Run at y = ${runBox.y} outside the panel (${formBox.y}–${formBox.y + formBox.height}) scrolled to ${top}`);
  }
  await page.screenshot({ path: join(artifacts, 'first-visit-form-open.png') });
  for (const group of await page.$$('#methods details.method-group[open] > summary')) await group.click();
  await form.evaluate((f) => { f.scrollTop = 0; });
});

test('the header shows one section at a time; old links still lead to theirs', async () => {
  const heights = {};
  for (const id of SECTIONS) {
    await openSection(page, id);
    const shown = await page.$$eval('[data-view]', (views) => views.filter((v) => !v.hidden).map((v) => v.id));
    assert.deepEqual(shown, [id]);
    assert.equal(await page.getAttribute(`nav.sections a[href="#${id}"]`, 'aria-current'), 'page');
    assert.equal(await page.evaluate(() => window.location.hash), `#${id}`);
    heights[id] = await page.evaluate(() => document.documentElement.scrollHeight);
  }
  console.log(`# page height per section: ${JSON.stringify(heights)}`);
  // Back returns to the section before.
  await page.goBack();
  await page.waitForSelector('#basins:not([hidden])');
  // Hashes of elements inside a section, as the page's older links wrote them.
  for (const [hash, id] of [['#results', 'simulation'], ['#sim-form', 'simulation'], ['#stab-results', 'stability']]) {
    await page.evaluate((h) => { window.location.hash = h; }, hash);
    await page.waitForSelector(`#${id}:not([hidden])`);
  }
  // A link to a recording that is not stored opens the Recordings section and says so there.
  await page.evaluate(() => { window.location.hash = '#recording=0123456789abcdef0123456789abcdef'; });
  await page.waitForSelector('#recordings:not([hidden]) #rec-error:not([hidden])', { timeout: 10_000 });
  await openSection(page, 'simulation');
  assert.deepEqual(consoleErrors.filter((t) => !/status of 404/.test(t)), []);
});
