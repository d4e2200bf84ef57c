// Browser test of jobs on the page: headless Chromium against the geomint server in GEOMINT_URL.
// "Run as a job" in the Sweeps section submits the sweep as a job, follows its progress and draws
// the job's document, which is the API's answer to the same sweep; the Jobs section lists it as
// done; after a reload (a closed tab) the list still has it and Show draws it again; a long job is
// cancelled by the section's Cancel on the server, then removed from the list; a refused job names
// its field as the section's own run does; every other study section has the button; the list
// fits a phone screen; an energy map submitted by another client is shown in its section with its
// request in the form. Screenshots go to artifacts/.

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

async function sweepSettled(states, timeout = 120_000) {
  await page.waitForFunction((wanted) => wanted.includes(document.querySelector('#sweep').dataset.sweepState),
    states, { timeout });
  return page.getAttribute('#sweep', 'data-sweep-state');
}

async function getJson(path) {
  const response = await fetch(`${base}${path}`, { headers: { accept: 'application/json' } });
  return { status: response.status, body: response.status === 204 ? null : await response.json() };
}

/** The sweep preset `csv1_stability`, smaller. */
async function smallSweep() {
  const presets = await (await fetch(`${base}/api/v1/studies/sweep/presets`)).json();
  const request = structuredClone(presets.find((p) => p.id === 'csv1_stability').request);
  request.axes[0].n = 6;
  request.axes[1].n = 5;
  return request;
}

async function openPage() {
  await page.goto(`${base}/`);
  await page.waitForSelector('body[data-run-state="idle"]', { timeout: 15_000 });
  await page.waitForFunction(() => !document.querySelector('#sw-run-job').disabled, null, { timeout: 15_000 });
}

before(async () => {
  assert.ok(base, 'set GEOMINT_URL to the server under test (scripts/test-browser does)');
  await waitForServer();
  ({ context, page, profile } = await launch({ width: 1280, height: 900 }, consoleErrors));
  await openPage();
});

after(async () => {
  await context?.close();
  if (profile) await rm(profile, { recursive: true, force: true });
});

test('a sweep run as a job draws the API’s answer, stays listed across a reload and is shown again', async () => {
  await openSection(page, 'sweep');
  const request = await smallSweep();
  await page.fill('#sw-spec', JSON.stringify(request));
  await page.locator('#sw-run-job').scrollIntoViewIfNeeded();
  await page.click('#sw-run-job');
  assert.equal(await sweepSettled(['done', 'error']), 'done', await page.textContent('#err-sw-spec'));
  const progress = await page.evaluate(() => window.geomint.sweep.lastProgress);
  assert.deepEqual({ ...progress, label: undefined }, { type: 'progress', done: 30, total: 30, label: undefined });
  assert.match(progress.label, /^Job [0-9a-f]{8}$/);
  const { status, body: api } = await postJson('/api/v1/studies/sweep', request);
  assert.equal(status, 200);
  delete api.wall_ms;
  const fromJob = await page.evaluate(() => window.geomint.sweep.last.doc);
  delete fromJob.wall_ms;
  assert.deepEqual(fromJob, api);

  // The Jobs section lists it as done, with every cell.
  const jobs = (await getJson('/api/v1/jobs')).body;
  const job = jobs.find((j) => j.id.startsWith(progress.label.slice(4)));
  assert.ok(job, JSON.stringify(jobs));
  assert.equal(job.state, 'done');
  await openSection(page, 'jobs');
  const row = page.locator(`#jobs-list tr[data-id="${job.id}"][data-state="done"]`);
  await row.waitFor({ timeout: 10_000 });
  assert.match(await row.textContent(), /30 of 30 cells \(100 %\)/);
  // Its recording is in the library too.
  assert.ok(job.recording, JSON.stringify(job));

  // A closed tab loses nothing: after a reload the list still has the job, and Show draws it.
  await openPage();
  await openSection(page, 'jobs');
  await page.locator(`#jobs-list tr[data-id="${job.id}"]`).waitFor({ timeout: 10_000 });
  await page.click(`#jobs-list tr[data-id="${job.id}"] button:text("Show")`);
  await page.waitForSelector('#sweep[data-view]:not([hidden])', { timeout: 5_000 });
  assert.equal(await sweepSettled(['done']), 'done');
  const shown = await page.evaluate(() => window.geomint.sweep.last);
  delete shown.doc.wall_ms;
  assert.deepEqual(shown.doc, api);
  assert.deepEqual(shown.body, request);
  assert.deepEqual(JSON.parse(await page.inputValue('#sw-spec')), request);
});

test('Cancel cancels a job on the server, and Remove removes it', async () => {
  await openSection(page, 'sweep');
  const request = await smallSweep();
  // About 10^10 steps: far longer than the test waits.
  request.t_end = 1_000_000;
  request.axes = [
    { name: 'params.gamma', min: 0, max: 0.1, n: 40 },
    { name: 'h', min: 0.1, max: 0.2, n: 40 },
  ];
  await page.fill('#sw-spec', JSON.stringify(request));
  await page.click('#sw-run-job');
  await page.waitForFunction(() => /^Job /.test(document.querySelector('#sw-status').textContent), null,
    { timeout: 30_000 });
  const label = (await page.textContent('#sw-status')).match(/^Job ([0-9a-f]{8})/)[1];
  await page.click('#sw-cancel');
  assert.equal(await sweepSettled(['cancelled', 'error']), 'cancelled');
  const find = async () => (await getJson('/api/v1/jobs')).body.find((j) => j.id.startsWith(label));
  let job = await find();
  for (let i = 0; i < 100 && job.state !== 'cancelled'; i++) {
    await new Promise((done) => setTimeout(done, 100));
    job = await find();
  }
  assert.equal(job.state, 'cancelled');
  assert.ok(job.cells_done < job.cells, JSON.stringify(job));

  await openSection(page, 'jobs');
  await page.click('#jobs-refresh');
  const row = page.locator(`#jobs-list tr[data-id="${job.id}"][data-state="cancelled"]`);
  await row.waitFor({ timeout: 10_000 });
  await page.locator('#jobs').screenshot({ path: join(artifacts, 'page-jobs.png') });
  await row.locator('button:text("Remove")').click();
  await row.waitFor({ state: 'detached', timeout: 10_000 });
  assert.equal((await getJson(`/api/v1/jobs/${job.id}`)).status, 404);
});

test('a refused job names its field as the section’s own run does; every study section offers jobs', async () => {
  await openSection(page, 'sweep');
  const request = await smallSweep();
  request.axes[0].n = 1000;
  await page.fill('#sw-spec', JSON.stringify(request));
  await page.click('#sw-run-job');
  assert.equal(await sweepSettled(['done', 'error']), 'error');
  const message = await page.textContent('#err-sw-spec');
  assert.match(message, /\(at `axes\[0\]\.n`\)/);
  assert.doesNotMatch(message, /request\./);
  for (const id of ['wp', 'cv', 'em', 'ba']) {
    assert.equal(await page.$eval(`#${id}-run-job`, (b) => b.disabled), false, id);
  }

  // The list fits a phone screen.
  await page.setViewportSize({ width: 390, height: 844 });
  await openSection(page, 'jobs');
  await page.locator('#jobs-list tr').first().waitFor({ timeout: 10_000 });
  const overflow = await page.evaluate(() => document.documentElement.scrollWidth - window.innerWidth);
  assert.ok(overflow <= 0, `the page is ${overflow}px wider than the screen`);
  await page.locator('#jobs').screenshot({ path: join(artifacts, 'page-jobs-phone.png') });
  assert.deepEqual(consoleErrors.filter((e) => !LOGGED_422.test(e)), []);
});

test('a job submitted elsewhere is shown in its section with its request in the form', async () => {
  await page.setViewportSize({ width: 1280, height: 900 });
  await openSection(page, 'energy-map');
  await page.fill('#em-nx', '7');
  await page.fill('#em-ny', '6');
  await page.fill('#em-t-max', '50');
  const request = await page.evaluate(() => window.geomint.energyMap.read());
  // Submitted by another client, with the form then changed.
  const { status, body: submitted } = await postJson('/api/v1/jobs', { study: 'energy-map', request });
  assert.equal(status, 202, JSON.stringify(submitted));
  await page.fill('#em-nx', '11');
  await openSection(page, 'jobs');
  await page.click('#jobs-refresh');
  const row = page.locator(`#jobs-list tr[data-id="${submitted.id}"][data-state="done"]`);
  await row.waitFor({ timeout: 60_000 });
  await row.locator('button:text("Show")').click();
  await page.waitForSelector('#energy-map[data-view]:not([hidden])', { timeout: 5_000 });
  await page.waitForSelector('#energy-map[data-map-state="done"]', { timeout: 10_000 });
  const { body: doc } = await getJson(`/api/v1/jobs/${submitted.id}/result`);
  assert.deepEqual(await page.evaluate(() => window.geomint.energyMap.last.doc), doc);
  assert.equal(await page.inputValue('#em-nx'), '7');
  assert.deepEqual(await page.evaluate(() => window.geomint.energyMap.read()), request);
});
