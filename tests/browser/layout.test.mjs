// Browser test of the page's reach: on a phone the header leaves the screen to the section (its
// height measured at 390 × 844), Run is two Tab presses away from the top of the page at
// 1400 × 900, and the token field says what it is for. Screenshots go to artifacts/.

import { test, after } from 'node:test';
import assert from 'node:assert/strict';
import { rm } from 'node:fs/promises';
import { join } from 'node:path';
import { artifacts, base, launchOnPage } from './harness.mjs';

const opened = [];

after(async () => {
  for (const { context, profile } of opened) {
    await context.close();
    await rm(profile, { recursive: true, force: true });
  }
});

test('a phone’s header takes at most an eighth of the screen, and its section links scroll in one row', async () => {
  const errors = [];
  const launched = await launchOnPage({ width: 390, height: 844 }, errors, []);
  opened.push(launched);
  const { page } = launched;
  const header = await page.evaluate(() => {
    const box = document.querySelector('header.site').getBoundingClientRect();
    const links = [...document.querySelectorAll('nav.sections a')].map((a) => a.getBoundingClientRect().top);
    return { height: box.height, rows: new Set(links.map(Math.round)).size };
  });
  assert.ok(header.height <= 844 / 8, `the header is ${header.height} px high`);
  assert.equal(header.rows, 1);
  await page.screenshot({ path: join(artifacts, 'phone-header.png') });
  assert.deepEqual(errors, []);
});

test('Run is two Tab presses from the top of the page, and the token field says what it is for', async () => {
  const errors = [];
  const launched = await launchOnPage({ width: 1400, height: 900 }, errors, []);
  opened.push(launched);
  const { page } = launched;
  await page.keyboard.press('Tab');
  await page.keyboard.press('Tab');
  assert.equal(await page.evaluate(() => document.activeElement.textContent), 'Skip to Run');
  await page.keyboard.press('Enter');
  await page.waitForFunction(() => window.location.hash === '#run');
  const run = await page.evaluate(() => {
    const box = document.querySelector('#run').getBoundingClientRect();
    return { top: box.top, bottom: box.bottom };
  });
  assert.ok(run.top >= 0 && run.bottom <= 900, `Run at ${run.top}–${run.bottom} px`);
  await page.waitForFunction(() => document.activeElement?.id === 'run');
  // The focus is on Run: Enter runs.
  await page.keyboard.press('Enter');
  await page.waitForFunction(() => ['running', 'done'].includes(document.body.dataset.runState), null, { timeout: 15_000 });

  const token = await page.evaluate(() => ({
    title: document.querySelector('label.token').title,
    placeholder: document.querySelector('#api-token').placeholder,
  }));
  assert.match(token.title, /only by a server started with a tokens file/);
  assert.equal(token.placeholder, 'only if the server asks');
  assert.deepEqual(errors, []);
});
