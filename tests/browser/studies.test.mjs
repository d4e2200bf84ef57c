// Browser test of the page's study sections: headless Chromium (Debian's package, driven by
// playwright-core) against a running geomint server whose address is in GEOMINT_URL (see
// scripts/test-browser, which starts one). It computes the stability maps and the ½tr error plot
// and compares them with the API, runs a work–precision and a convergence study (paper 001
// Fig. 9) and compares their plots with the API, draws an energy-error map with its progress,
// readout, summary and downloads, checks that the console stays free of errors, checks the phone
// layout of the simulation and of these sections, and saves screenshots to artifacts/.

import { test, before, after } from 'node:test';
import assert from 'node:assert/strict';
import { readFile, rm } from 'node:fs/promises';
import { join } from 'node:path';
import { LOGGED_422, artifacts, base, launchOnPage, openSection, postJson } from './harness.mjs';

/** The stability section's defaults, as the page sends them. */
const STABILITY = {
  methods: ['cimp', 'csv1', 'csv2'],
  omega: 3.51,
  gamma: { min: 0, max: 3.5, n: 141 },
  h: { min: 0.025, max: 1, n: 40 },
};

let context;
let page;
let profile;
const consoleErrors = [];
const failedRequests = [];

before(async () => {
  assert.ok(base, 'set GEOMINT_URL to the server under test (scripts/test-browser does)');
  ({ context, page, profile } = await launchOnPage({ width: 1280, height: 800 }, consoleErrors, failedRequests));
});

after(async () => {
  await context?.close();
  if (profile) await rm(profile, { recursive: true, force: true });
});

test('the stability section maps the methods and reads a cell under the pointer', async () => {
  const before = consoleErrors.length;
  const failedBefore = failedRequests.length;
  await openSection(page, 'stability');
  await page.locator('#stab-run').scrollIntoViewIfNeeded();
  await page.focus('#stab-run');
  await page.keyboard.press('Enter');
  await page.waitForSelector('#stability[data-stab-state="done"]', { timeout: 20_000 });
  const { status, body: api } = await postJson('/api/v1/stability', STABILITY);
  assert.equal(status, 200);
  // The page sent its defaults: the h axis starts above 0, where every method is the identity and
  // the printed relations' disagreements were nothing but that row (cimp's 141 of 141 columns).
  assert.deepEqual(await page.evaluate(() => window.geomint.stability.shownBody), STABILITY);
  const atZero = await postJson('/api/v1/stability', { ...STABILITY, h: { min: 0, max: 1, n: 41 } });
  assert.equal(atZero.body.maps[0].printed_disagreements - api.maps[0].printed_disagreements, STABILITY.gamma.n,
    'the h = 0 row alone made cimp’s printed count');

  // One heatmap per method with one cell per (γ, h) grid point, drawn at a real size.
  const maps = await page.$$eval('canvas.heatmap', (canvases) => canvases.map((c) => ({
    method: c.dataset.method, cells: Number(c.dataset.cells), columns: Number(c.dataset.columns),
    rows: Number(c.dataset.rows), width: c.width, height: c.height,
  })));
  assert.deepEqual(maps.map((m) => m.method), STABILITY.methods);
  for (const m of maps) {
    assert.equal(m.cells, STABILITY.gamma.n * STABILITY.h.n);
    assert.deepEqual([m.columns, m.rows], [STABILITY.gamma.n, STABILITY.h.n]);
    assert.ok(m.width > STABILITY.gamma.n && m.height > STABILITY.h.n, `canvas ${m.width}×${m.height}`);
  }

  // The disagreement counts shown are the API's, for the corrected and the printed relations.
  const counts = await page.$$eval('.map .disagreements', (ps) => ps.map((p) => ({
    data: [p.dataset.disagreements, p.dataset.printedDisagreements],
    shown: [p.querySelector('.count-corrected')?.textContent, p.querySelector('.count-printed')?.textContent],
  })));
  api.maps.forEach((map, i) => {
    const expected = [String(map.disagreements), String(map.printed_disagreements)];
    assert.deepEqual(counts[i].data, expected, `${map.method}: data attributes`);
    assert.deepEqual(counts[i].shown, expected, `${map.method}: counts shown`);
  });
  assert.ok(api.maps.some((m) => m.printed_disagreements > 0), 'the printed relations disagree somewhere');

  // Hovering a cell of the csv1 map updates the readout with that cell's API values.
  const canvas = page.locator('canvas.heatmap[data-method="csv1"]');
  await canvas.scrollIntoViewIfNeeded();
  const box = await canvas.boundingBox();
  const readout = page.locator('figure[data-map="csv1"] .readout');
  for (const [col, row] of [[100, 32], [20, 8]]) {
    const [x, y] = await page.evaluate(([c, r]) =>
      window.geomint.stability.heatmaps[1].cellCentre(c, r), [col, row]);
    await page.mouse.move(box.x + x, box.y + y);
    const shown = await readout.evaluate((p) => ({ ...p.dataset, text: p.textContent }));
    assert.deepEqual([Number(shown.col), Number(shown.row)], [col, row]);
    const rho = api.maps[1].spectral_radius[row][col];
    assert.equal(Number(shown.rho), rho);
    assert.equal(shown.stable, String(api.maps[1].stable[row][col]));
    assert.ok(Math.abs(Number(shown.gamma) - (3.5 * col) / 140) < 1e-12);
    assert.ok(Math.abs(Number(shown.h) - (row + 1) / 40) < 1e-12);
    assert.match(shown.text, new RegExp(`^γ = ${Number(shown.gamma).toPrecision(4).replace(/\.?0+$/, '')}, `));
  }
  // … and from the keyboard: the focused map's cursor moves with the arrow keys.
  await canvas.focus();
  await page.keyboard.press('ArrowUp');
  await page.keyboard.press('ArrowRight');
  assert.deepEqual(await readout.evaluate((p) => [p.dataset.col, p.dataset.row, p.getAttribute('aria-live')]), ['21', '9', 'polite']);

  // The ½tr error plot: one log–log series per method (and the h⁴ guide), the API's values.
  const plot = await page.evaluate(() => {
    const { plot, last } = window.geomint.stability;
    return { labels: plot.series.slice(1).map((s) => s.label), data: plot.data, hs: last.halfTrace.hs };
  });
  assert.deepEqual(plot.labels, [...STABILITY.methods, '∝ h⁴']);
  assert.equal(plot.hs.length, 12);
  assert.ok(Math.abs(plot.hs[0] - 0.005) < 1e-15 && Math.abs(plot.hs[11] - 0.5) < 1e-15);
  const k = 6;
  const point = await postJson('/api/v1/stability/point', { method: 'csv2', omega: 3.51, gamma: 0.5, h: plot.hs[k] });
  assert.equal(point.status, 200);
  assert.equal(plot.data[3][k], point.body.analysis.half_trace_error);
  for (const series of plot.data.slice(1, 4)) assert.ok(series.every((v) => v > 0), 'every ½tr error plotted');

  // The maps download as a Rerun recording.
  const [saved] = await Promise.all([page.waitForEvent('download'), page.click('#stab-download-rrd')]);
  assert.equal(saved.suggestedFilename(), 'geomint-stability.rrd');
  const rrd = await readFile(await saved.path());
  assert.equal(rrd.subarray(0, 4).toString('latin1'), 'RRF2', 'Rerun 0.33 files start with RRF2');
  assert.ok(rrd.length > 1000, `a recording of ${rrd.length} bytes`);

  assert.deepEqual(consoleErrors.slice(before), [], 'console errors in the stability section');
  assert.deepEqual(failedRequests.slice(failedBefore), [], 'failed requests in the stability section');
  await page.locator('#stability').screenshot({ path: join(artifacts, 'page-stability.png') });
});

test('a stability error is shown beside its field', async () => {
  const before = consoleErrors.length;
  await page.fill('#stab-gamma-max', '-1');
  await page.click('#stab-run');
  await page.waitForSelector('#stability[data-stab-state="error"]', { timeout: 10_000 });
  const { body } = await postJson('/api/v1/stability', { ...STABILITY, gamma: { ...STABILITY.gamma, max: -1 } });
  assert.equal(body.error.field, 'gamma.max');
  assert.equal((await page.textContent('#err-stab-gamma')).trim(), body.error.message);
  assert.equal(await page.getAttribute('#stab-gamma-max', 'aria-invalid'), 'true');
  assert.equal(await page.evaluate(() => document.activeElement?.id), 'stab-gamma-max');
  // Chromium logs the 422 answer itself; the page adds nothing.
  const fresh = consoleErrors.slice(before)
    .filter((text) => !/Failed to load resource: the server responded with a status of 422/.test(text));
  assert.deepEqual(fresh, [], 'console errors after the stability error');
  await page.fill('#stab-gamma-max', '3.5');
  await page.click('#stab-run');
  await page.waitForSelector('#stability[data-stab-state="done"]', { timeout: 20_000 });
  assert.equal(await page.textContent('#err-stab-gamma'), '');
});

test('a work–precision study streams into a log–log diagram with a readout, and records as .rrd', async () => {
  const before = consoleErrors.length;
  const failedBefore = failedRequests.length;
  const study = {
    system: 'pendulum', t_end: 50, samples: 10,
    runs: [
      { method: { id: 'kahan_li_8', base: 'modin_3s' }, h: [0.5, 0.25] },
      { method: 'rk4', h: [0.1, 0.05, 0.025] },
      { method: 'reference', tolerance: [1e-8, 1e-10] },
    ],
  };
  await openSection(page, 'work-precision');
  await page.locator('#wp-run').scrollIntoViewIfNeeded();
  // The preset is there; a shorter study replaces it.
  assert.equal(JSON.parse(await page.inputValue('#wp-spec')).system, 'elastic_pendulum_3d');
  await page.fill('#wp-spec', JSON.stringify(study));
  await page.click('#wp-run');
  await page.waitForSelector('#work-precision[data-wp-state="done"]', { timeout: 30_000 });
  const { status, body: api } = await postJson('/api/v1/studies/work-precision', study);
  assert.equal(status, 200);
  const shown = await page.evaluate(() => {
    const { plot, last } = window.geomint.workPrecision;
    return { labels: plot.series.slice(1).map((s) => s.label), data: plot.data.slice(1), points: last.result.points };
  });
  assert.deepEqual(shown.labels, ['kahan_li_8(modin_3s)', 'rk4', 'reference']);
  assert.deepEqual(shown.data.map(([xs]) => xs.length), [2, 3, 2]);
  // Errors do not depend on timing: the plotted x values are the API's, bit for bit.
  const apiErrors = (run) => api.points.filter((p) => p.run === run).map((p) => p.max_energy_error).sort((a, b) => a - b);
  for (const run of [0, 1, 2]) assert.deepEqual(shown.data[run][0], apiErrors(run));
  assert.equal(await page.locator('#wp-table tr').count(), 7);
  // The fitted exponent of each run is shown; its value comes from wall times of runs of a few
  // milliseconds, so its sign is not asserted here (the benchmarks measure speed).
  assert.match(
    await page.textContent('#wp-legend'),
    /^kahan_li_8\(modin_3s\): time ∝ error\^-?\d+\.\d+rk4: time ∝ error\^-?\d+\.\d+reference: time ∝ error\^-?\d+\.\d+$/,
  );

  // The readout names the setting under the pointer.
  const target = await page.evaluate(() => {
    const { plot, runs } = window.geomint.workPrecision;
    const p = runs[1].points[0];
    const box = plot.over.getBoundingClientRect();
    return { x: box.left + plot.valToPos(p.max_energy_error, 'x'), y: box.top + plot.valToPos(p.wall_ms, 'y'), h: p.h };
  });
  await page.mouse.move(target.x, target.y);
  assert.equal(await page.getAttribute('#wp-readout', 'data-method'), 'rk4');
  assert.equal(await page.getAttribute('#wp-readout', 'data-setting'), `h = ${target.h}`);

  const [saved] = await Promise.all([page.waitForEvent('download'), page.click('#wp-download-rrd')]);
  assert.equal(saved.suggestedFilename(), 'geomint-work-precision.rrd');
  const rrd = await readFile(await saved.path());
  assert.equal(rrd.subarray(0, 4).toString('latin1'), 'RRF2');
  assert.deepEqual(consoleErrors.slice(before), [], 'console errors in the work–precision section');
  assert.deepEqual(failedRequests.slice(failedBefore), [], 'failed requests in the work–precision section');
  await page.locator('#work-precision').screenshot({ path: join(artifacts, 'page-work-precision.png') });

  // A step size that does not divide t_end/samples: the error names the field.
  await page.fill('#wp-spec', JSON.stringify({ ...study, runs: [{ method: 'rk4', h: [0.3] }] }));
  await page.click('#wp-run');
  await page.waitForSelector('#work-precision[data-wp-state="error"]', { timeout: 10_000 });
  assert.match(await page.textContent('#err-wp'), /^runs\[0\]\.h\[0\]: must divide/);
  assert.equal(await page.getAttribute('#wp-spec', 'aria-invalid'), 'true');
});

/** A short work–precision study: three runs of a few settings each. */
const QUICK_STUDY = {
  system: 'pendulum', t_end: 50, samples: 10,
  runs: [{ method: 'rk4', h: [0.1, 0.05, 0.025] }, { method: 'modin_3s', h: [0.1, 0.05] }],
};

/** What the page draws for a work–precision point: the dot's time and its bar's ends. */
function drawnTimings() {
  return page.evaluate(() => {
    const { chart, last } = window.geomint.workPrecision;
    return {
      series: chart.series.map((s) => ({ ys: s.ys, lows: s.lows, highs: s.highs })),
      points: last.result.points,
      note: document.querySelector('#wp-timing').textContent,
      runs: document.querySelector('#wp-timing').dataset.runs,
      table: [...document.querySelectorAll('#wp-table tr td:nth-child(3)')].map((td) => td.textContent),
    };
  });
}

test('work–precision: the spec shows its samples, and the panel says what each dot’s time is', async () => {
  // The preset (in a fresh tab) names `samples`, the field the server's "must divide
  // t_end/samples" is about; it asks for repeated timings only where the server's OpenAPI
  // document offers them.
  const offers = Boolean((await (await fetch(`${base}/api/v1/openapi.json`)).json())
    .components.schemas.WorkPrecisionRequest.properties.repeats);
  const fresh = await context.newPage();
  try {
    await fresh.goto(`${base}/#work-precision`);
    await fresh.waitForSelector('body[data-run-state="idle"]', { timeout: 15_000 });
    // The preset is settled once the page has asked the OpenAPI document.
    await fresh.waitForFunction(() => window.geomint && document.querySelector('#wp-spec').value !== '');
    await fresh.waitForLoadState('networkidle');
    const preset = JSON.parse(await fresh.inputValue('#wp-spec'));
    assert.equal(preset.samples, 50);
    assert.equal(preset.repeats, offers ? 5 : undefined);
  } finally {
    await fresh.close();
  }

  await openSection(page, 'work-precision');
  await page.fill('#wp-spec', JSON.stringify(QUICK_STUDY));
  await page.click('#wp-run');
  await page.waitForSelector('#work-precision[data-wp-state="done"]', { timeout: 30_000 });
  const shown = await drawnTimings();
  const repeated = shown.points.some((p) => p.timings_ms?.length > 1);
  for (const p of shown.points) {
    if (!p.timings_ms) continue;
    // Fastest first, the median in wall_ms.
    const sorted = [...p.timings_ms].sort((a, b) => a - b);
    assert.deepEqual(p.timings_ms, sorted);
    const mid = sorted.length >> 1;
    const median = sorted.length % 2 ? sorted[mid] : (sorted[mid - 1] + sorted[mid]) / 2;
    assert.ok(Math.abs(p.wall_ms - median) <= 1e-9 * median, `wall_ms ${p.wall_ms} is the median of ${sorted}`);
  }
  if (repeated) {
    assert.match(shown.note, /^Each dot is the median wall time of \d+/);
  } else {
    // A server that times each setting once: single runs, and the panel says so; no bars.
    assert.equal(shown.runs, '1');
    assert.match(shown.note, /^Each dot is one timed run of its setting/);
    for (const s of shown.series) assert.deepEqual(s.lows, s.ys);
  }
});

test('work–precision: repeated timings are drawn as their median with a bar from fastest to slowest', async () => {
  // The server's answer with five timings per point put in (a server that repeats sends them so):
  // what the page makes of them does not depend on which server answered.
  const factors = [0.7, 0.9, 1, 1.5, 3];
  await page.route('**/api/v1/studies/work-precision', async (route) => {
    const response = await route.fetch();
    const lines = (await response.text()).split('\n').filter(Boolean).map((line) => JSON.parse(line));
    const repeat = (p) => ({ ...p, timings_ms: factors.map((f) => f * p.wall_ms) });
    const body = lines.map((line) => {
      if (line.type === 'point') return { ...line, point: repeat(line.point) };
      if (line.type === 'result') return { ...line, points: line.points.map(repeat) };
      return line;
    }).map((line) => JSON.stringify(line)).join('\n') + '\n';
    await route.fulfill({ response, body });
  });
  try {
    await page.fill('#wp-spec', JSON.stringify(QUICK_STUDY));
    await page.click('#wp-run');
    await page.waitForSelector('#work-precision[data-wp-state="done"]', { timeout: 30_000 });
  } finally {
    await page.unroute('**/api/v1/studies/work-precision');
  }
  const shown = await drawnTimings();
  assert.equal(shown.runs, '5');
  assert.match(shown.note, /^Each dot is the median wall time of 5 timed runs of its setting; its bar spans the fastest to the slowest/);
  // Per series, sorted by error as drawn: the dot at the median, the bar from 0.7 to 3 times it.
  for (const s of shown.series) {
    s.ys.forEach((median, i) => {
      assert.ok(Math.abs(s.lows[i] - 0.7 * median) < 1e-12 * median && Math.abs(s.highs[i] - 3 * median) < 1e-12 * median,
        `bar ${s.lows[i]}–${s.highs[i]} around ${median}`);
    });
  }
  // The plot's time axis holds every bar.
  const [min, max] = await page.evaluate(() => {
    const { scales } = window.geomint.workPrecision.plot;
    return [scales.y.min, scales.y.max];
  });
  const lows = shown.series.flatMap((s) => s.lows);
  const highs = shown.series.flatMap((s) => s.highs);
  assert.ok(min <= Math.min(...lows) && max >= Math.max(...highs), `axis ${min}–${max}`);
  assert.ok(shown.table.every((text) => /^\d+\.\d{3} \(\d+\.\d{3}–\d+\.\d{3}, 5 runs\)$/.test(text)), shown.table.join(' | '));
  await page.locator('#wp-results').screenshot({ path: join(artifacts, 'work-precision-repeats.png') });
});

test('a convergence study streams into a log–log plot of error against h with the fitted orders', async () => {
  const before = consoleErrors.length;
  const failedBefore = failedRequests.length;
  await openSection(page, 'convergence');
  await page.locator('#cv-run').scrollIntoViewIfNeeded();
  // The paper 001 Fig. 9 preset fills the spec and the error choice, and runs.
  await page.click('[data-cv-preset="fig9"]');
  await page.waitForSelector('#convergence[data-cv-state="done"]', { timeout: 30_000 });
  const study = JSON.parse(await page.inputValue('#cv-spec'));
  assert.deepEqual(study.charts, ['cartesian', 'compensating']);
  assert.equal(await page.inputValue('#cv-error'), 'max_energy_error');
  const { status, body: api } = await postJson('/api/v1/studies/convergence', study);
  assert.equal(status, 200);
  const byH = (series) => api.points.filter((p) => p.series === series).sort((a, b) => a.h - b.h);
  const plotted = () => page.evaluate(() => {
    const { plot } = window.geomint.convergence;
    return { labels: plot.series.slice(1).map((s) => s.label), data: plot.data.slice(1) };
  });
  let shown = await plotted();
  assert.deepEqual(shown.labels, ['symplectic_euler [cartesian]', 'symplectic_euler [compensating]']);
  // Two lines of six settings: the API's step sizes and errors, bit for bit.
  for (const series of [0, 1]) {
    assert.deepEqual(shown.data[series][0], byH(series).map((p) => p.h));
    assert.deepEqual(shown.data[series][1], byH(series).map((p) => p.max_energy_error));
  }
  // The legend gives the fitted orders: first order in Cartesian coordinates, second in the
  // compensating chart.
  const legend = () => page.$$eval('#cv-legend li', (items) => items.map((li) => li.textContent));
  assert.deepEqual(await legend(), api.series.map((s) => `${s.label}: order ${s.max_energy.order.toFixed(2)}`));
  assert.ok(Math.abs(api.series[0].max_energy.order - 1) < 0.05, JSON.stringify(api.series[0]));
  assert.ok(Math.abs(api.series[1].max_energy.order - 2) < 0.2, JSON.stringify(api.series[1]));
  assert.equal(await page.locator('#cv-table tr').count(), 12);

  // Another error redraws the plot and the legend.
  await page.selectOption('#cv-error', 'state_error');
  shown = await plotted();
  assert.deepEqual(shown.data[1][1], byH(1).map((p) => p.state_error));
  assert.deepEqual(await legend(), api.series.map((s) => `${s.label}: order ${s.state.order.toFixed(2)}`));

  // The readout names the setting under the pointer.
  await page.locator('#cv-plot').scrollIntoViewIfNeeded();
  const target = await page.evaluate(() => {
    const { plot, shown: series } = window.geomint.convergence;
    const p = series[1].points[2];
    const box = plot.over.getBoundingClientRect();
    return { x: box.left + plot.valToPos(p.h, 'x'), y: box.top + plot.valToPos(p.state_error, 'y'), h: p.h };
  });
  await page.mouse.move(target.x, target.y);
  assert.equal(await page.getAttribute('#cv-readout', 'data-series'), 'symplectic_euler [compensating]');
  assert.equal(await page.getAttribute('#cv-readout', 'data-h'), String(target.h));

  // The JSON download is the route's answer.
  const [saved] = await Promise.all([page.waitForEvent('download'), page.click('#cv-download-json')]);
  assert.equal(saved.suggestedFilename(), 'geomint-convergence-harmonic_oscillator.json');
  assert.deepEqual(JSON.parse(await readFile(await saved.path(), 'utf8')), api);
  assert.deepEqual(consoleErrors.slice(before), [], 'console errors in the convergence section');
  assert.deepEqual(failedRequests.slice(failedBefore), [], 'failed requests in the convergence section');
  await page.locator('#convergence').screenshot({ path: join(artifacts, 'page-convergence.png') });

  // 001 Sec. 2.3: explicit Euler is exact in the transformed variable, so that line has no order.
  await page.click('[data-cv-preset="sec23"]');
  await page.waitForSelector('#convergence[data-cv-state="done"]', { timeout: 30_000 });
  const sec23 = await legend();
  assert.match(sec23[0], /^explicit_euler \[original\]: order 0\.9\d|^explicit_euler \[original\]: order 1\.0\d/);
  assert.equal(sec23[1], 'explicit_euler [transformed]: no order (errors at round-off)');

  // A step size that does not divide t_end: the error names the field.
  await page.fill('#cv-spec', JSON.stringify({ ...study, h: [0.04, 0.03] }));
  await page.click('#cv-run');
  await page.waitForSelector('#convergence[data-cv-state="error"]', { timeout: 10_000 });
  assert.match(await page.textContent('#err-cv'), /^h\[1\]: must divide t_end = 10 into a whole number of steps/);
  assert.equal(await page.getAttribute('#cv-spec', 'aria-invalid'), 'true');
  // Chromium logs the 422 answer itself; the page adds nothing.
  const fresh = consoleErrors.slice(before)
    .filter((text) => !/Failed to load resource: the server responded with a status of 422/.test(text));
  assert.deepEqual(fresh, [], 'console errors after the convergence error');
});


test('an energy-error map streams its progress, draws the map and reads a cell', async () => {
  const before = consoleErrors.length;
  const failedBefore = failedRequests.length;
  const body = { method: 'symplectic_euler', params: { g: 0.02 }, h: 0.2, t_max: 200, nx: 9, ny: 9 };
  await openSection(page, 'energy-map');
  await page.locator('#em-run').scrollIntoViewIfNeeded();
  assert.deepEqual(await page.$$eval('#em-method option', (os) => os.map((o) => o.value).sort()),
    ['explicit_euler', 'heun', 'implicit_midpoint', 'rk3', 'rk4', 'symplectic_euler', 'symplectic_euler_adjoint']);
  await page.fill('#em-nx', '9');
  await page.fill('#em-ny', '9');
  await page.fill('#em-t-max', '200');
  const posted = page.waitForRequest((r) => new URL(r.url()).pathname === '/api/v1/studies/energy-map');
  await page.click('#em-run');
  assert.deepEqual(JSON.parse((await posted).postData()), body);
  await page.waitForSelector('#energy-map[data-map-state="done"]', { timeout: 60_000 });

  // The progress bar reached every cell; the last progress line said so.
  assert.deepEqual(await page.$eval('#em-progress', (p) => [p.value, p.max]), [81, 81]);
  assert.deepEqual(await page.evaluate(() => window.geomint.energyMap.lastProgress), { type: 'progress', done: 81, total: 81 });

  const { status, body: api } = await postJson('/api/v1/studies/energy-map', body);
  assert.equal(status, 200);
  // The summary shows the API's counts.
  const shown = await page.$$eval('#em-summary dd', (dds) => Object.fromEntries(dds.map((d) => [d.dataset.count, d.querySelector('strong').textContent])));
  for (const [key, value] of Object.entries(shown)) assert.equal(value, String(api.summary[key]), key);
  assert.equal(shown.cells, '81');

  // The canvas is drawn: cells of several colours, black in the top-left corner (x₀ = y₀ = −1.5,
  // beyond the boundary: the polar run diverged), not black halfway down the left edge.
  const canvas = page.locator('#em-canvas');
  await canvas.scrollIntoViewIfNeeded();
  const pixels = await page.evaluate(() => {
    const { map } = window.geomint.energyMap;
    const c = map.canvas;
    const ctx = c.getContext('2d');
    const dpr = c.width / map.cssWidth;
    const at = (col, row) => {
      const [x, y] = map.cellCentre(col, row);
      return [...ctx.getImageData(Math.round(x * dpr), Math.round(y * dpr), 1, 1).data];
    };
    const all = ctx.getImageData(0, 0, c.width, c.height).data;
    const colours = new Set();
    let drawn = 0;
    for (let i = 0; i < all.length; i += 4) {
      if (all[i + 3] === 0) continue;
      drawn += 1;
      colours.add(`${all[i]},${all[i + 1]},${all[i + 2]}`);
    }
    return { corner: at(0, 0), middle: at(0, 4), drawn, colours: colours.size, size: [c.width, c.height] };
  });
  assert.equal(api.epsilon_polar[0], null);
  assert.deepEqual(pixels.corner, [0, 0, 0, 255], 'a diverged cell is black');
  assert.notDeepEqual(pixels.middle.slice(0, 3), [0, 0, 0], 'a finite cell is not black');
  assert.ok(pixels.drawn > 0.3 * pixels.size[0] * pixels.size[1], `${pixels.drawn} pixels drawn of ${pixels.size}`);
  assert.ok(pixels.colours > 10, `${pixels.colours} colours`);

  // The readout under the pointer: a finite cell and a diverged one, the API's values.
  const box = await canvas.boundingBox();
  const readout = page.locator('#em-readout');
  for (const [col, row] of [[6, 2], [0, 0]]) {
    const [x, y] = await page.evaluate(([c, r]) => window.geomint.energyMap.map.cellCentre(c, r), [col, row]);
    await page.mouse.move(box.x + x, box.y + y);
    const data = await readout.evaluate((p) => ({ ...p.dataset, text: p.textContent }));
    const k = row * 9 + col;
    assert.deepEqual([Number(data.col), Number(data.row)], [col, row]);
    assert.equal(Number(data.x), api.xs[col]);
    assert.equal(Number(data.y), api.ys[row]);
    assert.equal(data.cartesian, api.epsilon_cartesian[k] == null ? '' : String(api.epsilon_cartesian[k]));
    assert.equal(data.polar, api.epsilon_polar[k] == null ? '' : String(api.epsilon_polar[k]));
    assert.equal(data.diverged, String(api.polar_diverged_at[k] != null || api.cartesian_diverged_at[k] != null));
    if (api.difference[k] != null) {
      assert.equal(data.winner, api.difference[k] < 0 ? 'cartesian' : 'polar');
      assert.match(data.text, /better by a factor/);
    } else {
      assert.match(data.text, /diverged/);
    }
  }

  // Downloads: the JSON document and the recording.
  const [json] = await Promise.all([page.waitForEvent('download'), page.click('#em-download-json')]);
  assert.equal(json.suggestedFilename(), 'geomint-energy-map.json');
  const saved = JSON.parse(await readFile(await json.path(), 'utf8'));
  assert.deepEqual(saved.request, body);
  assert.deepEqual(saved.epsilon_cartesian, api.epsilon_cartesian);
  const [rrdFile] = await Promise.all([page.waitForEvent('download'), page.click('#em-download-rrd')]);
  assert.equal(rrdFile.suggestedFilename(), 'geomint-energy-map.rrd');
  const rrd = await readFile(await rrdFile.path());
  assert.equal(rrd.subarray(0, 4).toString('latin1'), 'RRF2');

  assert.deepEqual(consoleErrors.slice(before), [], 'console errors in the energy map');
  assert.deepEqual(failedRequests.slice(failedBefore), [], 'failed requests in the energy map');
  await page.locator('#energy-map').screenshot({ path: join(artifacts, 'page-energy-map.png') });
});

test('an energy map can be cancelled, and a bad grid size is shown beside its field', async () => {
  const before = consoleErrors.length;
  const failedBefore = failedRequests.length;
  await page.locator('#em-run').scrollIntoViewIfNeeded();
  // 201 × 201 cells to t = 20 000: minutes if not cancelled.
  await page.fill('#em-nx', '201');
  await page.fill('#em-ny', '201');
  await page.fill('#em-t-max', '20000');
  await page.click('#em-run');
  await page.waitForSelector('#energy-map[data-map-state="running"]', { timeout: 5_000 });
  assert.equal(await page.isEnabled('#em-cancel'), true);
  await page.click('#em-cancel');
  await page.waitForSelector('#energy-map[data-map-state="cancelled"]', { timeout: 5_000 });
  assert.equal(await page.isEnabled('#em-cancel'), false);
  const deadline = Date.now() + 10_000;
  let load;
  do {
    await new Promise((resolve) => setTimeout(resolve, 100));
    load = await (await fetch(`${base}/healthz`)).json();
  } while (load.runs_in_progress > 0 && Date.now() < deadline);
  assert.equal(load.runs_in_progress, 0, 'map threads still busy after Cancel');
  assert.deepEqual(failedRequests.slice(failedBefore), ['/api/v1/studies/energy-map net::ERR_ABORTED']);

  await page.fill('#em-nx', '0');
  await page.click('#em-run');
  await page.waitForSelector('#energy-map[data-map-state="error"]', { timeout: 10_000 });
  const { status, body } = await postJson('/api/v1/studies/energy-map', { nx: 0 });
  assert.equal(status, 422);
  assert.equal(body.error.field, 'nx');
  assert.equal((await page.textContent('#err-em-nx')).trim(), body.error.message);
  assert.equal(await page.getAttribute('#em-nx', 'aria-invalid'), 'true');
  assert.equal(await page.evaluate(() => document.activeElement?.id), 'em-nx');
  assert.deepEqual(consoleErrors.slice(before).filter((t) => !LOGGED_422.test(t)), [], 'console errors');
  // The last map stays on the page.
  assert.equal(await page.isVisible('#em-canvas'), true);
  await page.fill('#em-nx', '9');
  await page.fill('#em-ny', '9');
  await page.fill('#em-t-max', '200');
});

test('the page fits a phone screen', async () => {
  await page.setViewportSize({ width: 390, height: 844 });
  await openSection(page, 'simulation');
  await page.fill('#h', '0.2');
  await page.click('[data-preset="p000-pendulum/3s-heun"]');
  await page.waitForSelector('body[data-run-state="done"]', { timeout: 30_000 });
  const overflow = await page.evaluate(() => document.documentElement.scrollWidth - window.innerWidth);
  assert.ok(overflow <= 0, `the page is ${overflow}px wider than the screen`);
  const widths = await page.evaluate(() =>
    [...window.geomint.charts.values()].map(({ plot }) => plot.width));
  for (const w of widths) assert.ok(w <= 390, `plot ${w}px wide on a 390px screen`);
  await page.screenshot({ path: join(artifacts, 'page-phone.png'), fullPage: true });

  // The stability section's heatmaps and ½tr plot shrink to the screen too.
  await openSection(page, 'stability');
  await page.locator('#stability').scrollIntoViewIfNeeded();
  await page.waitForFunction(() => [...document.querySelectorAll('canvas.heatmap')]
    .every((c) => c.getBoundingClientRect().right <= window.innerWidth));
  const stabilityOverflow = await page.evaluate(() => document.documentElement.scrollWidth - window.innerWidth);
  assert.ok(stabilityOverflow <= 0, `the page is ${stabilityOverflow}px wider than the screen`);
  assert.ok(await page.evaluate(() => window.geomint.stability.plot.width <= 390));
  await page.locator('#stability').screenshot({ path: join(artifacts, 'page-stability-phone.png') });

  // So does the energy map.
  await openSection(page, 'energy-map');
  await page.locator('#energy-map').scrollIntoViewIfNeeded();
  await page.waitForFunction(() => document.querySelector('#em-canvas').getBoundingClientRect().right <= window.innerWidth);
  const mapOverflow = await page.evaluate(() => document.documentElement.scrollWidth - window.innerWidth);
  assert.ok(mapOverflow <= 0, `the page is ${mapOverflow}px wider than the screen`);
  await page.locator('#energy-map').screenshot({ path: join(artifacts, 'page-energy-map-phone.png') });
});
