// Browser test of the page's Your-system section: headless Chromium (Debian's package, driven by
// playwright-core) against the geomint server in GEOMINT_URL (scripts/test-browser starts one).
// It fills the definition from an example, breaks an entry of the damping matrix and a potential
// behind a character outside the Basic Multilingual Plane, and checks each error where the API
// puts it: the message beside that input, the input marked invalid, the character marked in the
// copy of the expression and selected in the input (positions count Unicode characters, the input
// counts UTF-16 units). Fixed, the definition checks: the facts and the methods offered are the
// service's. The run plots every sample the API returns for the same request, the invariant the
// damping keeps stays put, and a double pendulum's bobs are drawn where its positions put them. A
// copied link reproduces the definition and the run in a new tab; the run downloads as JSON and
// .rrd and opens in the Rerun viewer (or its fallback). Screenshots go to artifacts/.

import { test, before, after } from 'node:test';
import assert from 'node:assert/strict';
import { readFile, rm } from 'node:fs/promises';
import { join } from 'node:path';
import {
  HEADLESS_GPU_ERROR, LOGGED_422, artifacts, base, launch, openSection, postJson, waitForServer,
} from './harness.mjs';
import { EXAMPLES } from '../../static/js/examples.js';


const kepler = EXAMPLES.find((x) => x.id === 'kepler');
const pendulum = EXAMPLES.find((x) => x.id === 'double-pendulum');

let context;
let page;
let profile;
const consoleErrors = [];
/** The simulate request and the page's point counts of the Kepler run (for the link test). */
let keplerRun = null;

/** The section's state, once it is one of `states`. */
async function settled(p, states, timeout = 30_000) {
  await p.waitForFunction((wanted) => wanted.includes(document.querySelector('#your-system').dataset.systemState),
    states, { timeout });
  return p.getAttribute('#your-system', 'data-system-state');
}

/** Clicks `selector` and returns the JSON body of the next POST to `path` and its answer. */
async function clickAndCapture(p, selector, path) {
  const [request] = await Promise.all([
    p.waitForRequest((r) => new URL(r.url()).pathname === path && r.method() === 'POST'),
    p.click(selector),
  ]);
  const response = await request.response();
  return { body: request.postDataJSON(), status: response.status(), answer: await response.json().catch(() => null) };
}

/** The section's plots: per key the points of each series. */
function pointCounts(p) {
  return p.evaluate(() => Object.fromEntries(Object.entries(window.geomint.system.pointCounts())
    .map(([key, series]) => [key, series.map((s) => s.points)])));
}

/** The error shown for an input: its message, aria-invalid, selection, and the marked character. */
function shownError(p, id) {
  return p.evaluate((inputId) => {
    const input = document.getElementById(inputId);
    const where = document.querySelector(`#err-${inputId} + .expr-where`);
    return {
      message: document.getElementById(`err-${inputId}`).textContent.trim(),
      invalid: input.getAttribute('aria-invalid'),
      focused: document.activeElement === input,
      selection: [input.selectionStart, input.selectionEnd],
      position: where ? Number(where.dataset.position) : null,
      marked: where?.querySelector('mark').textContent ?? null,
      before: where ? where.querySelector('code').firstChild.textContent : null,
      caret: where?.querySelector('code.caret')?.textContent ?? null,
      others: [...document.querySelectorAll('#sys-form .field-error')]
        .filter((n) => n.id !== `err-${inputId}` && n.textContent.trim() !== '').map((n) => n.id),
    };
  }, id);
}

before(async () => {
  assert.ok(base, 'set GEOMINT_URL to the server under test (scripts/test-browser does)');
  await waitForServer();
  ({ context, page, profile } = await launch({ width: 1280, height: 900 }, consoleErrors));
  await page.goto(`${base}/`);
  await page.waitForSelector('body[data-run-state="idle"]', { timeout: 15_000 });
  await settled(page, ['idle'], 5_000);
  await openSection(page, 'your-system');
});

after(async () => {
  await context?.close();
  if (profile) await rm(profile, { recursive: true, force: true });
});

test('every input of the section has a label', async () => {
  const unlabelled = await page.evaluate(() =>
    [...document.querySelectorAll('#your-system input, #your-system select, #your-system textarea')]
      .filter((c) => c.labels.length === 0 && !c.getAttribute('aria-label'))
      .map((c) => c.id || c.name));
  assert.deepEqual(unlabelled, []);
});

test('an example fills the definition; expression errors are shown at their field and character', async () => {
  const before = consoleErrors.length;
  await page.locator('#your-system').scrollIntoViewIfNeeded();
  await page.selectOption('#sys-example', 'example:kepler');
  assert.equal(await page.inputValue('#sys-coordinates'), 'x, y');
  assert.equal(await page.inputValue('#sys-potential'), kepler.definition.potential);
  assert.equal(await page.isChecked('#sys-damping-rayleigh'), true);
  assert.equal(await page.isVisible('#sys-matrix'), true);
  assert.equal(await page.isVisible('#sys-gamma'), false);
  assert.equal(await page.inputValue('#sys-h'), String(kepler.run.h));

  // D(q)[1][0] loses an operand in the middle: the server names that entry and the `*` it found.
  const matrix = await page.inputValue('#sys-matrix');
  const [row0, row1] = matrix.split('\n');
  const broken = row1.replace('x*y/(x^2 + y^2)', 'x*y/(x^2 + * y^2)');
  assert.notEqual(broken, row1);
  await page.fill('#sys-matrix', `${row0}\n${broken}`);
  const refused = await clickAndCapture(page, '#sys-check', '/api/v1/systems');
  assert.equal(refused.status, 422);
  assert.equal(refused.answer.error.code, 'invalid_expression');
  assert.equal(refused.answer.error.field, 'damping.matrix[1][0]');
  const entry = refused.body.damping.matrix[1][0];
  assert.equal(entry, 'x*y/(x^2 + * y^2)');
  assert.equal(refused.answer.error.position, entry.indexOf('* y'));
  assert.equal(await settled(page, ['invalid']), 'invalid');

  let shown = await shownError(page, 'sys-matrix');
  // The server counts characters from 0, the page from 1 as people do, and draws a caret.
  const fromOne = (message) => message.replace(/at character (\d+)/, (_, n) => `at character ${Number(n) + 1}`);
  assert.match(refused.answer.error.message, new RegExp(`at character ${refused.answer.error.position}\\b`));
  assert.equal(shown.message, fromOne(refused.answer.error.message));
  assert.match(shown.message, new RegExp(`at character ${refused.answer.error.position + 1}\\b`));
  assert.equal(shown.caret, `${'\u00a0'.repeat(refused.answer.error.position)}^`);
  assert.equal(shown.invalid, 'true');
  assert.equal(shown.focused, true);
  assert.equal(shown.position, refused.answer.error.position);
  assert.equal(shown.marked, '*');
  assert.equal(shown.before, entry.slice(0, refused.answer.error.position));
  // In the text area: the second line, after the first entry and its comma, at the `*`.
  const at = row0.length + 1 + broken.indexOf('* y');
  assert.deepEqual(shown.selection, [at, at + 1]);
  assert.deepEqual(shown.others, []);
  await page.locator('#sys-matrix').scrollIntoViewIfNeeded();
  await page.locator('#sys-form').screenshot({ path: join(artifacts, 'system-error.png') });

  // Fixed, and then a potential with a parameter named 𝑎 (U+1D44E, two UTF-16 units) before an
  // unknown name: the server counts characters, the input counts units.
  await page.fill('#sys-matrix', matrix);
  await page.fill('#sys-parameters', 'k = 1\neps = 0.05\n𝑎 = 0');
  const potential = '-k/sqrt(x^2 + y^2) + 𝑎*x*z';
  await page.fill('#sys-potential', potential);
  const second = await clickAndCapture(page, '#sys-check', '/api/v1/systems');
  assert.equal(second.status, 422);
  assert.equal(second.answer.error.field, 'potential');
  const position = [...potential].indexOf('z');
  assert.equal(second.answer.error.position, position);
  await settled(page, ['invalid']);
  shown = await shownError(page, 'sys-potential');
  assert.equal(shown.message, fromOne(second.answer.error.message));
  assert.equal(shown.invalid, 'true');
  assert.equal(shown.position, position);
  assert.equal(shown.marked, 'z');
  assert.equal(shown.before, potential.slice(0, potential.indexOf('z')));
  assert.deepEqual(shown.selection, [potential.indexOf('z'), potential.indexOf('z') + 1]);
  assert.equal(potential.indexOf('z'), position + 1, 'the character outside the BMP counts once');
  assert.deepEqual(shown.others, []);
  // The matrix is fine again: its error and mark are gone.
  assert.equal((await shownError(page, 'sys-matrix')).invalid, null);

  assert.deepEqual(consoleErrors.slice(before).filter((t) => !LOGGED_422.test(t)), [], 'console errors');
});

test('the fixed definition checks, with the facts and the methods the service derives', async () => {
  await page.fill('#sys-potential', kepler.definition.potential);
  await page.fill('#sys-parameters', 'k = 1\neps = 0.05');
  const checked = await clickAndCapture(page, '#sys-check', '/api/v1/systems');
  assert.ok([200, 201].includes(checked.status), `status ${checked.status}`);
  assert.deepEqual(checked.body, kepler.definition, 'the page sends the example as written');
  assert.equal(await settled(page, ['checked']), 'checked');
  const { id, facts } = checked.answer;
  assert.match(id, /^sys-[0-9a-f]{16}$/);
  assert.deepEqual(facts, { ...facts, dimension: 2, separable: true, damping: 'rayleigh_projector' });

  const dl = await page.evaluate(() => {
    const facts = document.querySelector('#sys-facts');
    const dd = (key) => facts.querySelector(`[data-fact="${key}"]`).textContent.trim();
    return {
      hidden: facts.hidden, id: dd('id'), dimension: dd('dimension'), separable: dd('separable'),
      damping: dd('damping'), methods: [...facts.querySelectorAll('[data-fact="methods"] code')].map((c) => c.textContent),
      attributes: { ...facts.dataset },
    };
  });
  assert.equal(dl.hidden, false);
  assert.equal(dl.id, id);
  assert.equal(dl.dimension, '2');
  assert.match(dl.separable, /^separable/);
  assert.match(dl.damping, /^Rayleigh, D\(q\) an orthogonal projector/);
  assert.deepEqual(dl.attributes, { separable: 'true', damping: 'rayleigh_projector', dimension: '2' });
  assert.deepEqual(dl.methods, facts.methods);

  // The methods offered are exactly those that apply (no conformal scheme under Rayleigh damping);
  // the example's are chosen.
  const offered = await page.$$eval('#sys-methods input[type=checkbox]', (boxes) => boxes.map((b) => b.value));
  assert.deepEqual([...offered].sort(), [...facts.methods].sort());
  assert.ok(offered.includes('modin_3s') && !offered.includes('csv1'));
  const chosen = await page.$$eval('#sys-methods input[type=checkbox]:checked', (boxes) => boxes.map((b) => b.value));
  assert.deepEqual(chosen, kepler.run.methods);

  // The server keeps what the page stored.
  const stored = await fetch(`${base}/api/v1/systems/${id}`).then((r) => r.json());
  assert.deepEqual(stored.facts, facts);
  assert.deepEqual(stored.definition.invariants, kepler.definition.invariants);
});

test('the run plots every sample the API returns, and the damped orbit keeps L', async () => {
  const before = consoleErrors.length;
  const [request] = await Promise.all([
    page.waitForRequest((r) => new URL(r.url()).pathname === '/api/v1/simulate' && r.method() === 'POST'),
    page.click('#sys-run'),
  ]);
  assert.equal(await settled(page, ['done', 'error']), 'done');
  const sent = request.postDataJSON();
  assert.deepEqual(sent.system, kepler.definition);
  assert.deepEqual(sent.methods, kepler.run.methods);
  assert.equal(sent.h, kepler.run.h);
  assert.equal(sent.t_end, kepler.run.t_end);

  const { status, body } = await postJson('/api/v1/simulate', sent);
  assert.equal(status, 200);
  const runs = body.runs;
  assert.deepEqual(runs.map((r) => r.method), ['modin_3s', 'rk4']);
  assert.equal(body.system.id, (await page.textContent('#sys-facts [data-fact="id"]')).trim());
  for (const run of runs) assert.equal(run.t.length, Math.round(kepler.run.t_end / kepler.run.h / body.schedule.every) + 1);

  const samples = runs.map((r) => r.t.length);
  const plotted = await pointCounts(page);
  assert.deepEqual(plotted, {
    energy: samples,
    'phase:0': samples,
    'phase:1': samples,
    'trajectory:xy': samples,
    'trajectory:0': samples,
    'trajectory:1': samples,
    'invariant:L': samples,
  });
  // The plotted values are the API's: L per sample, and the orbit in the x–y plane.
  const drawn = await page.evaluate(() => {
    const plots = window.geomint.system.view.charts.plots;
    return { L: plots.get('invariant:L').plot.data.slice(1), xy: plots.get('trajectory:xy').plot.data.slice(1) };
  });
  assert.deepEqual(drawn.L, runs.map((r) => r.invariants.L));
  assert.deepEqual(drawn.xy, runs.map((r) => [r.q.map((q) => q[0]), r.q.map((q) => q[1])]));
  // Radial damping exerts no torque: the splitting keeps L = 1.2 while the energy falls to the
  // circular orbit's −k²/(2L²).
  const [split] = runs;
  assert.ok(Math.max(...split.invariants.L.map((l) => Math.abs(l - 1.2))) < 1e-9, 'L drifts');
  assert.ok(Math.abs(split.energy.at(-1) + 1 / (2 * 1.44)) < 2e-3, `final energy ${split.energy.at(-1)}`);

  const canvases = await page.evaluate(() =>
    [...window.geomint.system.view.charts.plots.values()].map(({ plot }) => [plot.ctx.canvas.width, plot.ctx.canvas.height]));
  assert.equal(canvases.length, 7);
  for (const [w, h] of canvases) assert.ok(w > 150 && h > 100, `canvas ${w}×${h}`);
  const rows = await page.$$eval('#sys-stats-body tr', (trs) => trs.map((tr) => [...tr.children].map((c) => c.textContent.trim())));
  assert.deepEqual(rows.map((cells) => [cells[1], cells[4]]), runs.map((r) => [String(r.stats.steps), String(r.t.length)]));
  assert.match(await page.textContent('#sys-status'), new RegExp(`^Done: ${samples[0] + samples[1]} samples from 2 methods`));

  // The JSON download holds the same samples.
  const [download] = await Promise.all([page.waitForEvent('download'), page.click('#sys-download-json')]);
  assert.match(download.suggestedFilename(), /^geomint-sys-[0-9a-f]{16}-.*\.json$/);
  const saved = JSON.parse(await readFile(await download.path(), 'utf8'));
  assert.deepEqual(saved.request, sent);
  assert.deepEqual(saved.runs.map((r) => r.energy), runs.map((r) => r.energy));

  keplerRun = { request: sent, plotted };
  assert.deepEqual(consoleErrors.slice(before), [], 'console errors during the run');
  await page.locator('#sys-results').scrollIntoViewIfNeeded();
  await page.locator('#your-system').screenshot({ path: join(artifacts, 'system.png') });
});

test('a copied link reproduces the definition and the run in a new tab', async () => {
  assert.ok(keplerRun, 'needs the Kepler run');
  await page.click('#sys-copy-link');
  await page.waitForSelector('#sys-link-box:not([hidden])');
  const link = await page.inputValue('#sys-link');
  assert.match(link, new RegExp(`^${base}/#system=[A-Za-z0-9_-]+$`));

  const errors = [];
  const tab = await context.newPage();
  tab.on('console', (m) => { if (m.type() === 'error') errors.push(m.text()); });
  tab.on('pageerror', (e) => errors.push(`uncaught: ${e.message}`));
  try {
    const [request] = await Promise.all([
      tab.waitForRequest((r) => new URL(r.url()).pathname === '/api/v1/simulate' && r.method() === 'POST', { timeout: 20_000 }),
      tab.goto(link),
    ]);
    assert.equal(await settled(tab, ['done', 'error']), 'done');
    assert.deepEqual(request.postDataJSON(), keplerRun.request);
    assert.equal(await tab.inputValue('#sys-potential'), kepler.definition.potential);
    assert.equal(await tab.inputValue('#sys-invariants'), 'L = x*p_y - y*p_x');
    assert.deepEqual(await pointCounts(tab), keplerRun.plotted);
    assert.deepEqual(errors, [], 'console errors in the linked tab');
  } finally {
    await tab.close();
  }
});

test('the run downloads as .rrd and opens in the Rerun viewer', async () => {
  const before = consoleErrors.length;
  const id = (await page.textContent('#sys-facts [data-fact="id"]')).trim();
  const [download] = await Promise.all([page.waitForEvent('download'), page.click('#sys-download-rrd')]);
  assert.equal(download.suggestedFilename(), `geomint-${id}.rrd`);
  const rrd = await readFile(await download.path());
  assert.equal(rrd.subarray(0, 4).toString('latin1'), 'RRF2');

  const posted = page.waitForResponse((r) => new URL(r.url()).pathname === '/api/v1/recordings' && r.request().method() === 'POST');
  await page.click('#sys-view-rerun');
  const response = await posted;
  assert.equal(response.status(), 201);
  assert.deepEqual(JSON.parse(response.request().postData()), keplerRun.request);
  const created = await response.json();
  await page.waitForFunction(() => ['ready', 'failed', 'unavailable']
    .includes(document.querySelector('#sys-rerun').dataset.viewerState), null, { timeout: 30_000 });
  const state = await page.getAttribute('#sys-rerun', 'data-viewer-state');
  if (state === 'ready') {
    assert.equal(await page.locator('#sys-rerun-viewer canvas').count(), 1);
  } else {
    assert.match(await page.textContent('#sys-rerun-fallback'), new RegExp(`rerun geomint-${id}\\.rrd`));
  }
  const fresh = consoleErrors.slice(before);
  if (fresh.some((t) => HEADLESS_GPU_ERROR.test(t))) assert.equal(state, 'failed');
  assert.deepEqual(fresh.filter((t) => !HEADLESS_GPU_ERROR.test(t)), [], 'console errors with the Rerun viewer');
  await page.click('#sys-rerun-close');
  assert.equal(await page.getAttribute('#sys-rerun', 'data-viewer-state'), 'closed');
  assert.equal((await fetch(`${base}/api/v1/recordings/${created.id}`, { method: 'DELETE' })).status, 204);
});

test('a general H(q, p) runs with the methods that apply, its bobs where its positions put them', async () => {
  const before = consoleErrors.length;
  await page.selectOption('#sys-example', 'example:double-pendulum');
  assert.equal(await page.isChecked('#sys-energy-general'), true);
  assert.equal(await page.isVisible('#sys-hamiltonian'), true);
  assert.equal(await page.isVisible('#sys-potential'), false);
  assert.equal(await settled(page, ['idle']), 'idle');
  assert.equal(await page.isHidden('#sys-facts'), true);

  // Run checks the definition first.
  const [request] = await Promise.all([
    page.waitForRequest((r) => new URL(r.url()).pathname === '/api/v1/simulate' && r.method() === 'POST'),
    page.click('#sys-run'),
  ]);
  assert.equal(await settled(page, ['done', 'error']), 'done');
  assert.equal(await page.getAttribute('#sys-facts', 'data-separable'), 'false');
  const offered = await page.$$eval('#sys-methods input[type=checkbox]', (boxes) => boxes.map((b) => b.value));
  assert.ok(offered.includes('implicit_midpoint') && !offered.includes('modin_3s') && !offered.includes('velocity_verlet'),
    `methods offered for a general H: ${offered}`);
  const sent = request.postDataJSON();
  assert.deepEqual(sent.system, pendulum.definition);

  const { body } = await postJson('/api/v1/simulate', sent);
  const samples = body.runs.map((r) => r.t.length);
  const plotted = await pointCounts(page);
  // Two bobs per method in the plane, each a series of every sample.
  assert.deepEqual(plotted['trajectory:xy'], samples.flatMap((n) => [n, n]));
  assert.deepEqual(plotted.energy, samples);
  assert.equal(plotted['invariant:L'], undefined);
  const bobs = await page.evaluate(() => window.geomint.system.view.charts.plots.get('trajectory:xy').plot.data.slice(1));
  body.runs.forEach((run, m) => {
    const [first, second] = [bobs[2 * m], bobs[2 * m + 1]];
    run.q.forEach(([a, b], i) => {
      assert.ok(Math.abs(first[0][i] - Math.sin(a)) < 1e-12 && Math.abs(first[1][i] + Math.cos(a)) < 1e-12, `bob 1 of ${run.method} at ${i}`);
      assert.ok(Math.abs(second[0][i] - Math.sin(a) - Math.sin(b)) < 1e-12
        && Math.abs(second[1][i] + Math.cos(a) + Math.cos(b)) < 1e-12, `bob 2 of ${run.method} at ${i}`);
    });
  });
  // Undamped, no exact solution, not compared to the reference: the energy error is measured
  // against H₀ (sent by the server, or taken by the page from the same energies), and said so.
  assert.equal(await page.getAttribute('#sys-plots [data-plot="energy_error"]', 'data-against'), 'initial');
  assert.match(await page.textContent('#sys-plots [data-plot="energy_error"] figcaption'), /\|H − H₀\|.*initial energy H₀/);
  assert.equal(await page.locator('#sys-plots [data-note="energy"]').count(), 0);
  const errors = await page.evaluate(() => window.geomint.system.view.charts.plots.get('energy_error').plot.data.slice(1));
  body.runs.forEach((run, m) => {
    const expected = run.energy_error ?? run.energy.map((e) => e - run.energy[0]);
    expected.forEach((e, i) => {
      const drawn = errors[m][i];
      if (e === 0) assert.equal(drawn, null, `${run.method} at ${i}: a zero error is a gap on the log axis`);
      else assert.ok(Math.abs(drawn - Math.abs(e)) <= 1e-12 * Math.max(1, Math.abs(e)), `${run.method} at ${i}: ${drawn} against ${e}`);
    });
  });
  // The phase portraits are labelled with the definition's own names.
  assert.deepEqual(await page.$$eval('#sys-plots figcaption .plot-title', (t) => t.map((n) => n.textContent).slice(0, 5)),
    ['Energy H(t)', 'Energy error |H − H₀|', 'Phase portrait (a, p1)', 'Phase portrait (b, p2)', 'Bodies in the x–y plane']);

  assert.deepEqual(consoleErrors.slice(before), [], 'console errors during the run');
  await page.locator('#sys-results').screenshot({ path: join(artifacts, 'system-pendulum.png') });
});

test('a refused run setting is shown beside its input', async () => {
  const before = consoleErrors.length;
  await page.fill('#sys-h', '-1');
  const refused = await clickAndCapture(page, '#sys-run', '/api/v1/simulate');
  assert.equal(refused.status, 422);
  assert.equal(refused.answer.error.field, 'h');
  assert.equal(await settled(page, ['error']), 'error');
  const shown = await shownError(page, 'sys-h');
  assert.equal(shown.message, refused.answer.error.message);
  assert.equal(shown.invalid, 'true');
  assert.equal(shown.focused, true);
  assert.deepEqual(shown.others, []);
  // The last run stays on show.
  assert.ok((await pointCounts(page)).energy.every((n) => n > 0));
  assert.deepEqual(consoleErrors.slice(before).filter((t) => !LOGGED_422.test(t)), [], 'console errors');
  await page.fill('#sys-h', String(pendulum.run.h));
});

test('a damped system without exact solution says how to get an energy error, and gets one against the reference', async () => {
  const before = consoleErrors.length;
  await page.selectOption('#sys-example', 'example:duffing');
  await page.uncheck('#sys-compare');
  await page.click('#sys-run');
  assert.equal(await settled(page, ['done', 'error']), 'done');
  assert.equal(await page.locator('#sys-plots [data-plot="energy_error"]').count(), 0);
  const note = await page.textContent('#sys-plots [data-note="energy"]');
  assert.match(note, /damped and has no exact solution/);
  assert.match(note, /Tick “Compare to the reference”/);

  await page.check('#sys-compare');
  const [request] = await Promise.all([
    page.waitForRequest((r) => new URL(r.url()).pathname === '/api/v1/simulate' && r.method() === 'POST'),
    page.click('#sys-run'),
  ]);
  assert.equal(await settled(page, ['done', 'error']), 'done');
  assert.equal(request.postDataJSON().compare_to_reference, true);
  assert.equal(await page.getAttribute('#sys-plots [data-plot="energy_error"]', 'data-against'), 'ref');
  assert.match(await page.textContent('#sys-plots [data-plot="energy_error"] figcaption'), /\|H − H_ref\|.*DOP853 reference/);
  assert.equal(await page.locator('#sys-plots [data-note="energy"]').count(), 0);
  assert.ok((await pointCounts(page)).energy_error.every((n) => n > 0), 'the errors are drawn');
  assert.deepEqual(consoleErrors.slice(before), [], 'console errors');
  await page.locator('#sys-results').screenshot({ path: join(artifacts, 'system-duffing-reference.png') });
  await page.uncheck('#sys-compare');
});

test('a link is made only of a complete definition, and “Copied” gives way to a later failure', async () => {
  await context.grantPermissions(['clipboard-read', 'clipboard-write'], { origin: base });
  await page.selectOption('#sys-example', 'example:kepler');
  const potential = await page.inputValue('#sys-potential');
  // Without a potential: no link, the field named (a link would open on the server's refusal).
  await page.fill('#sys-potential', '');
  await page.click('#sys-copy-link');
  assert.equal(await page.isHidden('#sys-link-box'), true);
  assert.match(await page.textContent('#err-sys-potential'), /^potential: give V\(q\)/);
  assert.match(await page.textContent('#sys-status'), /^No link: the definition is not complete/);

  // Complete: copied; then a refused check takes the word back.
  await page.fill('#sys-potential', potential);
  await page.click('#sys-copy-link');
  await page.waitForSelector('#sys-link-box:not([hidden])');
  assert.equal(await page.textContent('#sys-status'), 'Copied the link to this system and run.');
  await page.fill('#sys-potential', `${potential} + *`);
  await page.click('#sys-check');
  await settled(page, ['invalid']);
  assert.notEqual(await page.textContent('#sys-status'), 'Copied the link to this system and run.');
  await page.fill('#sys-potential', potential);
});
