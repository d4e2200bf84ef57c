// What the browser tests share: where the page is served and the wait for it, the Chromium they
// drive and its flags, where screenshots go, and the one console error a machine without WebGPU or
// WebGL 2 shows.

import { mkdir, mkdtemp } from 'node:fs/promises';
import { tmpdir } from 'node:os';
import { join, dirname } from 'node:path';
import { fileURLToPath } from 'node:url';
import { chromium } from 'playwright-core';

/** The repository's root. */
export const root = join(dirname(fileURLToPath(import.meta.url)), '..', '..');
/** Where screenshots go. */
export const artifacts = join(root, 'artifacts');
/** The server under test (scripts/test-browser sets GEOMINT_URL). */
export const base = (process.env.GEOMINT_URL || '').replace(/\/$/, '');
/** Debian's chromium, or CHROMIUM_PATH. */
export const chromiumPath = process.env.CHROMIUM_PATH || '/usr/bin/chromium';
/** Headless, without the network traffic of a desktop browser. */
export const CHROMIUM_FLAGS = [
  '--headless', '--no-sandbox', '--disable-gpu', '--disable-quic', '--no-first-run',
  '--disable-background-networking', '--disable-component-update', '--disable-sync',
];
/**
 * The one console error of a machine whose Chromium offers neither WebGPU nor WebGL 2: the Rerun
 * viewer then fails to start and the page shows its fallback, which the tests require whenever
 * this error is filtered out.
 */
export const HEADLESS_GPU_ERROR = /^WebViewer failure: Failed to start failed to create wgpu surface: .*(webgl2 not available|adapter)/;

/** POSTs a JSON body to an API path of the server under test; its status and parsed body. */
export async function postJson(path, body) {
  const response = await fetch(`${base}${path}`, {
    method: 'POST',
    headers: { 'content-type': 'application/json' },
    body: JSON.stringify(body),
  });
  return { status: response.status, body: await response.json() };
}

/** The console line of an answer refused with 422, which some tests provoke on purpose. */
export const LOGGED_422 = /Failed to load resource: the server responded with a status of 422/;

/**
 * Waits (up to 30 s) until the server answers `/healthz`: every test file may be the first to talk
 * to it, whatever order the runner takes them in.
 */
export async function waitForServer() {
  const deadline = Date.now() + 30_000;
  for (;;) {
    try {
      const response = await fetch(`${base}/healthz`);
      if (response.ok) return;
    } catch {
      // not listening yet
    }
    if (Date.now() > deadline) throw new Error(`no server answers at ${base}`);
    await new Promise((resolve) => setTimeout(resolve, 200));
  }
}

/**
 * Headless Chromium with a fresh profile directory (a persistent context is how playwright takes
 * an explicit --user-data-dir) at `viewport`, and its first page, whose console errors and
 * uncaught exceptions are pushed to `errors`. The caller closes the context and removes `profile`.
 */
export async function launch(viewport, errors) {
  await mkdir(artifacts, { recursive: true });
  const profile = await mkdtemp(join(tmpdir(), 'geomint-chromium-'));
  const context = await chromium.launchPersistentContext(profile, {
    executablePath: chromiumPath,
    headless: true,
    args: CHROMIUM_FLAGS,
    viewport,
  });
  const page = context.pages()[0] || (await context.newPage());
  page.on('console', (message) => {
    if (message.type() === 'error') errors.push(message.text());
  });
  page.on('pageerror', (error) => errors.push(`uncaught: ${error.message}`));
  return { context, page, profile };
}

/**
 * `launch` on the page at `/`, once its form is idle (after the server answers), with the paths
 * of failed requests pushed to `failed`.
 */
export async function launchOnPage(viewport, errors, failed) {
  await waitForServer();
  const launched = await launch(viewport, errors);
  launched.page.on('requestfailed', (request) => {
    failed.push(`${new URL(request.url()).pathname} ${request.failure()?.errorText}`);
  });
  await launched.page.goto(`${base}/`);
  await launched.page.waitForSelector('body[data-run-state="idle"]', { timeout: 15_000 });
  return launched;
}

/**
 * Shows section `id` of the page the way a reader does, with its link in the header (the page
 * shows one section at a time), and waits until it is on show.
 */
export async function openSection(page, id) {
  await page.click(`nav.sections a[href="#${id}"]`);
  await page.waitForSelector(`#${id}[data-view]:not([hidden])`, { timeout: 5_000 });
}
