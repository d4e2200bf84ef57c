// The run as a Rerun recording. "Download the run as .rrd" posts the shown run's request to
// POST /api/v1/simulate?format=rrd and saves the bytes; "View in Rerun" stores the recording
// (POST /api/v1/recordings) and opens its URL in the Rerun web viewer embedded in the page
// (@rerun-io/web-viewer 0.33, served from vendor/rerun/ like uPlot). Where the viewer is not
// installed or cannot start (it needs WebGL 2 or WebGPU), the page says how to open the file in
// the Rerun app instead. The panel's state is `data-viewer-state` on its section (for tests):
// closed, creating, loading, ready, unavailable (viewer files missing), failed (could not start),
// error (the API refused).

import { simulateRrd, createRecording, ApiError } from './api.js';
import { el } from './form.js';

/** The viewer's ES module, relative to this file (copied there by scripts/vendor.mjs). */
const VIEWER_MODULE = '../vendor/rerun/index.js';

/** The Rerun release the server writes and the viewer reads. */
const RERUN_VERSION = '0.33';

/** Offers `blob` as a file download named `name`. */
export function saveBlob(blob, name) {
  const url = URL.createObjectURL(blob);
  const link = el('a', { href: url, download: name });
  document.body.append(link);
  link.click();
  link.remove();
  setTimeout(() => URL.revokeObjectURL(url), 10_000);
}

export function sizeText(bytes) {
  if (bytes >= 1024 * 1024) return `${(bytes / (1024 * 1024)).toFixed(1)} MiB`;
  return `${Math.max(1, Math.round(bytes / 1024))} KiB`;
}

/** The .rrd download, the embedded viewer and its fallback. */
export class RerunPanel {
  /**
   * @param {object} ui
   * @param {HTMLButtonElement} ui.download "Download the run as .rrd"
   * @param {HTMLButtonElement} ui.view "View in Rerun"
   * @param {HTMLElement} ui.status status line beside the buttons
   * @param {HTMLElement} ui.error error slot beside the buttons
   * @param {HTMLElement} ui.section the viewer's section (hidden while closed)
   * @param {HTMLElement} ui.box the element the viewer's canvas goes into
   * @param {HTMLElement} ui.fallback where the Rerun app instructions go
   * @param {HTMLButtonElement} ui.close "Close the viewer"
   * @param {(error: ApiError) => boolean} showFieldError shows an error beside the simulation
   *   form's field it names; false when the form has no such field
   */
  constructor(ui, showFieldError) {
    this.ui = ui;
    this.showFieldError = showFieldError;
    /** The run store whose request the buttons use (a finished run), or null. */
    this.store = null;
    this.viewer = null;
    /** Bumped by every view() and close(), so that a superseded one stops where it is. */
    this.generation = 0;
    this.controller = null;
    this.busy = false;
    ui.download.addEventListener('click', () => this.download());
    ui.view.addEventListener('click', () => this.view());
    ui.close.addEventListener('click', () => {
      this.close();
      ui.view.focus();
    });
    // The viewer's canvas keeps Tab for its own widgets; Esc leaves it for the Close button.
    ui.box.addEventListener('keydown', (event) => {
      if (event.key !== 'Escape') return;
      event.preventDefault();
      event.stopPropagation();
      ui.close.focus();
    }, { capture: true });
    this.setState('closed');
  }

  setState(state) {
    this.ui.section.dataset.viewerState = state;
  }

  /** Uses `store` (a finished run) for the buttons; null disables them. */
  setRun(store) {
    this.store = store && store.outcome === 'done' ? store : null;
    this.updateButtons();
  }

  updateButtons() {
    const off = !this.store || this.busy;
    this.ui.download.disabled = off;
    this.ui.view.disabled = off;
  }

  /** geomint-<system id>.rrd: a built-in system's name, or a definition's `sys-…` id. */
  fileName() {
    return `geomint-${this.store.header.system.id}.rrd`;
  }

  clearMessages() {
    this.ui.status.textContent = '';
    this.ui.error.textContent = '';
  }

  /** Shows an API error beside the form field it names, and beside the buttons. */
  showError(error, what) {
    const message = error?.message || String(error);
    if (error instanceof ApiError && error.field) this.showFieldError(error);
    this.ui.error.textContent = `${what}: ${message}`;
  }

  /** Saves the run as geomint-<system>.rrd (the server runs it again and records it). */
  async download() {
    if (!this.store) return;
    const name = this.fileName();
    this.clearMessages();
    this.busy = true;
    this.updateButtons();
    this.ui.status.textContent = 'Recording the run…';
    try {
      const blob = await simulateRrd(this.store.request);
      saveBlob(blob, name);
      this.ui.status.textContent = `Saved ${name} (${sizeText(blob.size)}).`;
    } catch (error) {
      this.ui.status.textContent = '';
      this.showError(error, 'The recording could not be made');
    } finally {
      this.busy = false;
      this.updateButtons();
    }
  }

  /** Stores the run's recording on the server and opens it in the embedded viewer. */
  async view() {
    if (!this.store) return;
    this.close();
    const generation = this.generation;
    const stale = () => generation !== this.generation;
    const name = this.fileName();
    this.clearMessages();
    const { section, box, fallback } = this.ui;
    section.hidden = false;
    box.hidden = false;
    fallback.hidden = true;
    fallback.replaceChildren();
    this.setState('creating');
    this.ui.status.textContent = 'Storing the recording…';
    this.controller = new AbortController();

    let created;
    try {
      created = await createRecording(this.store.request, this.controller.signal);
    } catch (error) {
      if (stale()) return;
      section.hidden = true;
      this.ui.status.textContent = '';
      this.setState('error');
      this.showError(error, 'The recording could not be stored');
      return;
    }
    if (stale()) return;
    const url = new URL(created.url, window.location.origin).href;
    section.dataset.recordingUrl = url;
    this.ui.status.textContent = `Recording stored (${sizeText(created.bytes)}); starting the Rerun viewer…`;
    section.scrollIntoView({ behavior: 'smooth', block: 'start' });

    this.setState('loading');
    let WebViewer;
    try {
      ({ WebViewer } = await import(VIEWER_MODULE));
    } catch {
      if (stale()) return;
      this.showFallback(url, name, [
        'The Rerun web viewer is not installed on this server (',
        el('code', { text: 'static/vendor/rerun/' }), ' is missing; ', el('code', { text: 'npm ci' }),
        ' installs it).',
      ]);
      this.setState('unavailable');
      this.ui.status.textContent = 'Recording stored; open it in the Rerun app (see below).';
      return;
    }
    if (stale()) return;
    const viewer = new WebViewer();
    this.viewer = viewer;
    try {
      await viewer.start(url, box, {
        width: '100%', height: '100%', hide_welcome_screen: true, theme: 'light',
      });
    } catch (error) {
      if (stale()) return;
      this.viewer = null;
      this.showFallback(url, name, [
        `The Rerun web viewer could not start in this browser (it needs WebGL 2 or WebGPU): ${error?.message || error}`,
      ]);
      this.setState('failed');
      this.ui.status.textContent = 'Recording stored; open it in the Rerun app (see below).';
      return;
    }
    if (stale()) return;
    this.setState('ready');
    this.ui.status.textContent = `The recording is open in the Rerun viewer below (${sizeText(created.bytes)}).`;
  }

  /** Replaces the viewer with instructions for the Rerun app. */
  showFallback(url, name, reason) {
    const { box, fallback } = this.ui;
    box.replaceChildren();
    box.hidden = true;
    fallback.replaceChildren(
      el('p', {}, ...reason),
      el('p', { text: `Open the recording in the Rerun app (version ${RERUN_VERSION}) instead:` }),
      el('ol', {},
        el('li', {}, el('a', { href: url, download: name, text: `Download ${name}` }),
          ' (or use “Download the run as .rrd”).'),
        el('li', {}, 'Install the viewer: ', el('code', { text: `pip install "rerun-sdk==${RERUN_VERSION}.*"` })),
        el('li', {}, 'Open the file: ', el('code', { text: `rerun ${name}` }))));
    fallback.hidden = false;
  }

  /** Stops the viewer (freeing its memory) and hides its section. */
  close() {
    this.generation += 1;
    this.controller?.abort();
    this.controller = null;
    if (this.viewer) {
      try {
        this.viewer.stop();
      } catch (error) {
        console.warn('The Rerun viewer did not stop cleanly:', error);
      }
      this.viewer = null;
    }
    this.ui.box.replaceChildren();
    this.ui.fallback.replaceChildren();
    this.ui.section.hidden = true;
    delete this.ui.section.dataset.recordingUrl;
    if (this.ui.section.dataset.viewerState !== 'closed') this.ui.status.textContent = '';
    this.setState('closed');
  }
}
