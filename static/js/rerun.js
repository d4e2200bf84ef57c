// The run as a Rerun recording. "Download the run as .rrd" posts the shown run's request to
// POST /api/v1/simulate?format=rrd and saves the bytes; "View in Rerun" stores the recording
// (POST /api/v1/recordings) and opens its URL in the section's embedded viewer (viewer.js), which
// falls back to instructions for the Rerun app where the viewer is missing or cannot start. The
// viewer section's `data-viewer-state` (for tests) is the embedded viewer's (closed, loading,
// ready, unavailable, failed) plus creating (the recording is being stored) and error (the API
// refused).

import { simulateRrd, createRecording, ApiError } from './api.js';
import { el, saveBlob, sizeText } from './common.js';
import { EmbeddedViewer } from './viewer.js';

/** What the status line says of a recording the view stored, where it is and who sees it, then `after`. */
function storedMessage(created, after) {
  return [`Stored the recording (${sizeText(created.bytes)}) on this server, in the `,
    el('a', { href: `#recording=${created.id}`, text: 'Recordings section' }),
    ` for everyone who uses the server; ${after}`];
}

/** The .rrd download and the view of the run in the embedded viewer. */
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
    // Closing from its button also stops a recording still being stored, and hands the focus
    // back to "View in Rerun".
    this.viewer = new EmbeddedViewer(ui, () => {
      this.supersede();
      ui.view.focus();
    });
    /** Bumped by every view() and close(), so that a superseded one stops where it is. */
    this.generation = 0;
    this.controller = null;
    this.busy = false;
    ui.download.addEventListener('click', () => this.download());
    ui.view.addEventListener('click', () => this.view());
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

  /**
   * Stores the run's recording on the server and opens it in the embedded viewer. The help beside
   * the button says beforehand that the recording is stored on the shared server; the status
   * line says where it went.
   */
  async view() {
    if (!this.store) return;
    this.close();
    const generation = this.generation;
    const stale = () => generation !== this.generation;
    const name = this.fileName();
    this.clearMessages();
    const { section } = this.ui;
    section.hidden = false;
    this.viewer.setState('creating');
    this.ui.status.textContent = 'Storing the recording…';
    this.controller = new AbortController();

    let created;
    try {
      created = await createRecording(this.store.request, this.controller.signal);
    } catch (error) {
      if (stale()) return;
      section.hidden = true;
      this.ui.status.textContent = '';
      this.viewer.setState('error');
      this.showError(error, 'The recording could not be stored');
      return;
    }
    if (stale()) return;
    const url = new URL(created.url, window.location.origin).href;
    this.ui.status.replaceChildren(...storedMessage(created, 'starting the Rerun viewer…'));
    section.scrollIntoView({ behavior: 'smooth', block: 'start' });
    const state = await this.viewer.openUrl(url, { href: url, name });
    if (stale()) return;
    this.ui.status.replaceChildren(...storedMessage(created, state === 'ready'
      ? 'it is open in the Rerun viewer below.' : 'open it in the Rerun app (see below).'));
  }

  /** Stops a view in progress (a recording still being stored) and clears its message. */
  supersede() {
    this.generation += 1;
    this.controller?.abort();
    this.controller = null;
    this.ui.status.textContent = '';
  }

  /** Stops the viewer (freeing its memory) and hides its section. */
  close() {
    if (this.viewer.state === 'closed') return;
    this.supersede();
    this.viewer.close();
  }
}
