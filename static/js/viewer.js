// An embedded Rerun web viewer (@rerun-io/web-viewer 0.33, served from vendor/rerun/) in a
// section of the page, with its fallback. It opens a recording either by URL — the viewer
// fetches the server's .rrd with one GET and decodes it as the bytes arrive, so a large recording
// streams — or from a local File, whose bytes are read piece by piece and pushed into a viewer
// channel (the viewer refuses blob: URLs), so nothing is uploaded. Where the viewer's files are
// missing or it cannot start (it needs WebGL 2 or WebGPU), the section says how to open the file
// in the Rerun app instead.
//
// For tests the section carries `data-viewer-state` (closed, loading, ready, unavailable, failed)
// and, once the viewer has read the recording's header, `data-recording-open="true"`.

import { el } from './common.js';

/** The viewer's ES module, relative to this file (copied there by scripts/vendor.mjs). */
const VIEWER_MODULE = '../vendor/rerun/index.js';

/** The Rerun release the server writes and the viewer reads. */
export const RERUN_VERSION = '0.33';

/** Bytes read from a local file per piece pushed into the viewer. */
const FILE_PIECE = 4 * 1024 * 1024;

/** The first bytes of every .rrd file the viewer reads. */
const RRD_MAGIC = 'RRF2';

/**
 * Why `file` is not an .rrd the viewer reads (judged by its first bytes), or null. The server
 * checks uploads in full; this only spares the viewer a file that is plainly something else.
 */
export async function notAnRrd(file) {
  const head = new Uint8Array(await file.slice(0, 4).arrayBuffer());
  const text = String.fromCharCode(...head);
  if (text === RRD_MAGIC) return null;
  if (head.length < 4) return `${file.name} is not a Rerun recording (.rrd): it has only ${file.size} bytes.`;
  const shown = /^[\x20-\x7e]{4}$/.test(text)
    ? `“${text}”`
    : `0x${[...head].map((b) => b.toString(16).padStart(2, '0').toUpperCase()).join('')}`;
  return `${file.name} is not a Rerun recording (.rrd): it starts with ${shown}, not the RRD header “RRF2”.`;
}

/** The tag in the last 12 bytes of a complete RRD stream (its footer). */
const RRD_FOOTER = 'RRF2FOOT';

/**
 * Why `file` (an .rrd, by its first bytes) may not be whole, or null: a complete stream ends with
 * its footer, and one cut short (an interrupted download or write) does not. The viewer shows
 * what it can read of such a file without a word; the library refuses to store it.
 */
export async function cutShort(file) {
  const tail = new Uint8Array(await file.slice(Math.max(0, file.size - 12)).arrayBuffer());
  if (file.size >= 24 && String.fromCharCode(...tail.slice(0, 8)) === RRD_FOOTER) return null;
  return `${file.name} looks cut short: its ${file.size} bytes do not end with the RRD stream footer ` +
    '(an interrupted download or write, say). The viewer shows only the part it can read, and the ' +
    'library refuses to store it.';
}

export class EmbeddedViewer {
  /**
   * @param {object} ui
   * @param {HTMLElement} ui.section the viewer's section (hidden while closed)
   * @param {HTMLElement} ui.box the element the viewer's canvas goes into
   * @param {HTMLElement} ui.fallback where the Rerun app instructions go
   * @param {HTMLButtonElement} ui.close "Close the viewer"
   * @param {() => void} [onClose] called after the Close button closed the viewer
   */
  constructor(ui, onClose = () => {}) {
    this.ui = ui;
    this.viewer = null;
    /** Bumped by every open and close, so that a superseded open stops where it is. */
    this.generation = 0;
    ui.close.addEventListener('click', () => {
      this.close();
      onClose();
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

  get state() {
    return this.ui.section.dataset.viewerState;
  }

  setState(state) {
    this.ui.section.dataset.viewerState = state;
  }

  /** Shows the section empty, ready for a new recording; returns a staleness check. */
  prepare(source) {
    this.close();
    const generation = this.generation;
    const { section, box, fallback } = this.ui;
    section.hidden = false;
    box.hidden = false;
    fallback.hidden = true;
    section.dataset.source = source;
    this.setState('loading');
    return () => generation !== this.generation;
  }

  /**
   * Starts the viewer on `url` (null: empty, for a channel). Resolves to the viewer, or to null
   * when it is unavailable, failed (the fallback is shown) or superseded.
   */
  async start(url, stale, download) {
    let WebViewer;
    try {
      ({ WebViewer } = await import(VIEWER_MODULE));
    } catch {
      if (stale()) return null;
      this.showFallback(download, [
        'The Rerun web viewer is not installed on this server (',
        el('code', { text: 'static/vendor/rerun/' }), ' is missing; ', el('code', { text: 'npm ci' }),
        ' installs it).',
      ]);
      this.setState('unavailable');
      return null;
    }
    if (stale()) return null;
    const viewer = new WebViewer();
    this.viewer = viewer;
    viewer.on('recording_open', () => {
      if (this.viewer === viewer) this.ui.section.dataset.recordingOpen = 'true';
    });
    try {
      await viewer.start(url, this.ui.box, {
        width: '100%', height: '100%', hide_welcome_screen: true, theme: 'light',
      });
    } catch (error) {
      if (stale()) return null;
      this.viewer = null;
      this.showFallback(download, [
        `The Rerun web viewer could not start in this browser (it needs WebGL 2 or WebGPU): ${error?.message || error}`,
      ]);
      this.setState('failed');
      return null;
    }
    if (stale()) return null;
    this.setState('ready');
    return viewer;
  }

  /**
   * Opens the recording at `url` (served by this server). `download` ({href, name}) is what the
   * fallback offers. Resolves to the state reached.
   */
  async openUrl(url, download) {
    const stale = this.prepare(url);
    this.ui.section.dataset.recordingUrl = url;
    await this.start(url, stale, download);
    return this.state;
  }

  /** Opens a local .rrd `file` without uploading it. Resolves to the state reached. */
  async openFile(file) {
    const stale = this.prepare(`file:${file.name}`);
    const viewer = await this.start(null, stale, null);
    if (!viewer) return this.state;
    const channel = viewer.open_channel(file.name);
    // Piece by piece, so that a large file never sits whole in the page's memory.
    for (let offset = 0; offset < file.size; offset += FILE_PIECE) {
      const piece = new Uint8Array(await file.slice(offset, offset + FILE_PIECE).arrayBuffer());
      if (stale() || !channel.ready) return this.state;
      channel.send_rrd(piece);
    }
    channel.close();
    return this.state;
  }

  /** The step range of the recording on show ({min, max}), or null. */
  stepRange() {
    const id = this.viewer?.get_active_recording_id?.();
    return id ? this.viewer.get_time_range(id, 'step') : null;
  }

  /** Replaces the viewer with instructions for the Rerun app. */
  showFallback(download, reason) {
    const { box, fallback } = this.ui;
    box.replaceChildren();
    box.hidden = true;
    const name = download?.name || 'recording.rrd';
    fallback.replaceChildren(
      el('p', {}, ...reason),
      el('p', { text: `Open the recording in the Rerun app (version ${RERUN_VERSION}) instead:` }),
      el('ol', {},
        download ? el('li', {}, el('a', { href: download.href, download: name, text: `Download ${name}` })) : null,
        el('li', {}, 'Install the viewer: ', el('code', { text: `pip install "rerun-sdk==${RERUN_VERSION}.*"` })),
        el('li', {}, 'Open the file: ', el('code', { text: `rerun ${name}` }))));
    fallback.hidden = false;
  }

  /** Stops the viewer (freeing its memory) and hides its section. */
  close() {
    this.generation += 1;
    if (this.viewer) {
      try {
        this.viewer.stop();
      } catch (error) {
        console.warn('The Rerun viewer did not stop cleanly:', error);
      }
      this.viewer = null;
    }
    const { section, box, fallback } = this.ui;
    box.replaceChildren();
    fallback.replaceChildren();
    section.hidden = true;
    delete section.dataset.recordingUrl;
    delete section.dataset.recordingOpen;
    delete section.dataset.source;
    this.setState('closed');
  }
}
