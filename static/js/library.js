// The Recordings section: the recordings stored on the server (GET /api/v1/recordings), newest
// first, filtered by system and method and shown a page at a time; each can be viewed in the
// section's embedded Rerun viewer (viewer.js), plotted with the page's own charts from its
// samples as the server reads them back from the .rrd (GET /api/v1/recordings/{id}/samples;
// nothing is run again), downloaded, linked to (/#recording=<id> opens the page on it) and
// deleted after a confirmation. A .rrd file from this computer (file picker or drag and drop)
// opens in the viewer without being sent anywhere, and can then be uploaded to the library.
//
// For tests the section carries `data-library-state` (loading, ready, error) and
// `data-upload-state` (idle, uploading, done, error).

import {
  listRecordings, getRecording, recordingSamples, deleteRecording, uploadRecording, ApiError,
} from './api.js';
import { el, fmt, sizeText } from './common.js';
import { getSystem } from './api.js';
import { builtInPlotOptions, definitionPlotOptions } from './plot-options.js';
import { SimulationView } from './simulation.js';
import { EmbeddedViewer, cutShort, notAnRrd } from './viewer.js';

/** Recordings per page of the list. */
export const PAGE_SIZE = 10;

/** A recording id: 32 lowercase hexadecimal digits. */
const ID = /^[0-9a-f]{32}$/;

/** The method id of a method label: `modin_rks(rk4)` is a `modin_rks`. */
export function methodId(label) {
  const open = label.indexOf('(');
  return open < 0 ? label : label.slice(0, open);
}

/** The link that opens the page on recording `id`. */
export function recordingLink(id) {
  const { origin, pathname } = window.location;
  return `${origin}${pathname}#recording=${id}`;
}

/** The recording id a location hash names (`#recording=<id>`): {id} or {invalid: text}. */
export function linkedRecording(hash) {
  const match = /^#recording=(.*)$/.exec(hash || '');
  if (!match) return null;
  const id = decodeURIComponent(match[1]);
  return ID.test(id) ? { id } : { invalid: id };
}

/**
 * A short description of a recording, for labels and messages; `name` is its system's (a typed-in
 * system's own name rather than its `sys-…` id).
 */
export function describe(entry, name = entry.spec?.system) {
  const spec = entry.spec;
  if (!spec && entry.job) return `the recording of a ${entry.job.study} job`;
  if (!spec) return `an uploaded recording of ${entry.application_id || 'another application'}`;
  return `${name}: ${spec.methods.join(', ')}`;
}

/** When a recording was stored, in the reader's time zone. */
export function when(created) {
  const date = new Date(created);
  if (Number.isNaN(date.getTime())) return created;
  return date.toLocaleString(undefined, { dateStyle: 'medium', timeStyle: 'short' });
}

/**
 * The samples document of a recording as the lines of a simulation stream (header, one samples
 * chunk and one summary per method), which the page's run store and charts take.
 */
export function streamLines(doc) {
  const header = {
    type: 'header',
    system: doc.system,
    methods: doc.runs.map((r) => r.method),
    invariants: doc.invariants,
    energy_error: doc.runs.some((r) => Array.isArray(r.energy_error)),
    jacobian_defect: false,
    schedule: doc.schedule,
  };
  const samples = doc.runs.map((run, method) => ({
    type: 'samples', method, offset: 0, t: run.t, q: run.q, p: run.p,
    cartesian_q: run.cartesian_q, energy: run.energy, energy_error: run.energy_error,
    invariants: run.invariants,
  }));
  const summaries = doc.runs.map((run, method) => ({
    type: 'summary',
    method,
    label: run.method,
    samples: run.t.length,
    dissipation_drift: run.dissipation_drift ?? null,
    diverged_at: null,
    stop: run.last_step >= doc.schedule.steps
      ? { reason: 'finished' }
      : { reason: 'ended early', message: `the recording ends at step ${run.last_step} of ${doc.schedule.steps}` },
    stats: { steps: run.last_step, force_evaluations: run.force_evaluations ?? null, wall_time_ms: null },
  }));
  return { header, samples, summaries };
}

export class RecordingsPanel {
  /**
   * @param {HTMLElement} root the Recordings section
   * @param {object[]} systems the system catalogue: the built-in systems and the definitions
   *   stored when the page loaded
   */
  constructor(root, systems) {
    const $ = (id) => root.querySelector(`#${id}`);
    this.root = root;
    this.systems = systems;
    /** Stored systems' entries by id (their names and definitions), as fetched. */
    this.storedSystems = new Map(systems.filter((s) => s.definition).map((s) => [s.id, s]));
    /** How the recording on show in the plots is drawn (set before each plot). */
    this.plotOptions = null;
    this.plots = new SimulationView($('rec-plot'), {
      chartOptions: (header, request) => this.plotOptions(header, request),
      showError: () => null,
      setState: (state) => { $('rec-plot').dataset.plotState = state; },
    });
    this.ui = {
      system: $('rec-system'), method: $('rec-method'), refresh: $('rec-refresh'),
      status: $('rec-status'), error: $('rec-error'), list: $('rec-list'), empty: $('rec-empty'),
      prev: $('rec-prev'), next: $('rec-next'), page: $('rec-page'),
      linkBox: $('rec-link-box'), link: $('rec-link'),
      drop: $('rec-drop'), file: $('rec-file'), upload: $('rec-upload'),
      fileStatus: $('rec-file-status'), fileError: $('rec-file-error'), fileWarning: $('rec-file-warning'),
      confirm: $('rec-confirm'), confirmText: $('rec-confirm-text'),
    };
    this.viewer = new EmbeddedViewer({
      section: $('rec-rerun'), box: $('rec-rerun-viewer'), fallback: $('rec-rerun-fallback'),
      close: $('rec-rerun-close'),
    }, () => this.afterClose());
    /** Every stored recording, newest first, as last listed. */
    this.entries = [];
    this.page = 0;
    /** The recording on show in the viewer: {id} for a stored one, {file} for a local file. */
    this.showing = null;
    /** The local file opened last (offered for upload). */
    this.localFile = null;
    /** Where the focus returns when the viewer closes. */
    this.returnFocus = null;

    const { system, method, refresh, prev, next, file, upload, drop } = this.ui;
    system.addEventListener('change', () => this.filterChanged());
    method.addEventListener('change', () => this.filterChanged());
    refresh.addEventListener('click', () => this.refresh());
    prev.addEventListener('click', () => this.turn(-1));
    next.addEventListener('click', () => this.turn(1));
    file.addEventListener('change', () => {
      if (file.files?.[0]) this.openLocal(file.files[0]);
    });
    upload.addEventListener('click', () => this.uploadLocal());
    for (const type of ['dragenter', 'dragover']) {
      drop.addEventListener(type, (event) => {
        event.preventDefault();
        drop.classList.add('dragging');
      });
    }
    drop.addEventListener('dragleave', () => drop.classList.remove('dragging'));
    drop.addEventListener('drop', (event) => {
      event.preventDefault();
      drop.classList.remove('dragging');
      const dropped = event.dataTransfer?.files?.[0];
      if (!dropped) return;
      // The picker no longer names the file on show.
      file.value = '';
      this.openLocal(dropped);
    });
    window.addEventListener('hashchange', () => this.followLink());
    this.setUploadState('idle');
  }

  setState(state) {
    this.root.dataset.libraryState = state;
  }

  setUploadState(state) {
    this.root.dataset.uploadState = state;
  }

  say(text) {
    this.ui.status.textContent = text;
  }

  /** Shows an error in the section's alert (empty text hides it). */
  alert(text) {
    this.ui.error.textContent = text || '';
    this.ui.error.hidden = !text;
  }

  /** The name of system `id`: a typed-in system's own name where it has one, else its id. */
  systemName(id) {
    return this.storedSystems.get(id)?.name || id;
  }

  describe(entry) {
    return describe(entry, this.systemName(entry.spec?.system));
  }

  /**
   * The stored system `id` (`sys-…`): its entry from GET /api/v1/systems/{id}, fetched once; null
   * for a built-in system, or one the server no longer has.
   */
  async storedSystem(id) {
    if (!id?.startsWith('sys-')) return null;
    if (!this.storedSystems.has(id)) {
      try {
        this.storedSystems.set(id, await getSystem(id));
      } catch {
        return null;
      }
    }
    return this.storedSystems.get(id);
  }

  /** Lists the recordings again; keeps the page when it still exists. */
  async refresh() {
    this.setState('loading');
    try {
      this.entries = await listRecordings();
      // The names of systems stored since the page loaded (by this page or another).
      await Promise.all([...new Set(this.entries.map((e) => e.spec?.system))].map((id) => this.storedSystem(id)));
    } catch (error) {
      this.setState('error');
      this.alert(`The recordings could not be listed: ${error.message}`);
      return;
    }
    this.fillFilters();
    this.render();
    this.setState('ready');
  }

  /** The filter options: the systems and method ids the stored recordings hold. */
  fillFilters() {
    const fill = (select, values, all, text = (v) => v) => {
      const chosen = select.value;
      const options = [...new Set(values)].sort((a, b) => text(a).localeCompare(text(b)));
      select.replaceChildren(el('option', { value: '', text: all }),
        ...options.map((v) => el('option', { value: v, text: text(v) })));
      select.value = options.includes(chosen) ? chosen : '';
    };
    const specs = this.entries.map((e) => e.spec).filter(Boolean);
    fill(this.ui.system, specs.map((s) => s.system), 'all systems', (id) => this.systemName(id));
    fill(this.ui.method, specs.flatMap((s) => s.methods.map(methodId)), 'all methods');
  }

  /** The recordings the filters let through, newest first. */
  filtered() {
    const system = this.ui.system.value;
    const method = this.ui.method.value;
    return this.entries.filter((e) => (!system || e.spec?.system === system)
      && (!method || (e.spec?.methods ?? []).some((label) => methodId(label) === method)));
  }

  filterChanged() {
    this.page = 0;
    this.render();
  }

  turn(by) {
    this.page += by;
    this.render();
    // Keep the focus on the pager, or move it into the list once this end is reached.
    const button = by < 0 ? this.ui.prev : this.ui.next;
    (button.disabled ? this.ui.list.querySelector('button') ?? this.ui.refresh : button).focus();
  }

  /** Draws the current page of the list, its pager and its status. */
  render() {
    const shown = this.filtered();
    const pages = Math.max(1, Math.ceil(shown.length / PAGE_SIZE));
    this.page = Math.min(Math.max(0, this.page), pages - 1);
    const first = this.page * PAGE_SIZE;
    const page = shown.slice(first, first + PAGE_SIZE);
    this.ui.list.replaceChildren(...page.map((entry) => this.row(entry)));
    this.ui.prev.disabled = this.page === 0;
    this.ui.next.disabled = this.page >= pages - 1;
    this.ui.page.textContent = `Page ${this.page + 1} of ${pages}`;
    const filteredOut = this.entries.length - shown.length;
    this.say(shown.length
      ? `Recordings ${first + 1}–${first + page.length} of ${shown.length}` +
        (filteredOut ? ` (${filteredOut} more hidden by the filters).` : '.')
      : this.entries.length ? 'No recording matches the filters.' : 'No recordings are stored yet.');
  }

  /** One row of the list: what the recording holds and its actions. */
  row(entry) {
    const spec = entry.spec;
    const what = this.describe(entry);
    const action = (text, label, onclick, extra = {}) => el('button', {
      type: 'button', class: 'secondary small', 'aria-label': `${label} ${what}`, onclick, ...extra,
    }, text);
    const url = `api/v1/recordings/${entry.id}.rrd`;
    const current = this.showing?.id === entry.id;
    return el('tr', { 'data-id': entry.id, 'aria-current': current ? 'true' : null },
      el('th', { scope: 'row', 'data-label': 'System', title: spec ? spec.system : null },
        spec ? this.systemName(spec.system) : entry.job ? `a ${entry.job.study} study` : '—',
        entry.origin === 'upload' ? el('span', { class: 'tag', text: 'uploaded' }) : null,
        entry.origin === 'job' ? el('span', { class: 'tag', text: 'job', title: `The result of job ${entry.job?.id}` }) : null),
      el('td', { 'data-label': 'Methods' }, spec ? spec.methods.join(', ') : entry.application_id || '—'),
      el('td', { 'data-label': 'h' }, spec ? fmt(spec.h, 6) : '—'),
      el('td', { 'data-label': 't_end' }, spec ? fmt(spec.t_end, 6) : '—'),
      el('td', { 'data-label': 'Stored' }, el('time', { datetime: entry.created, text: when(entry.created) })),
      el('td', { 'data-label': 'Size' }, sizeText(entry.bytes)),
      el('td', { class: 'row-actions-cell', 'data-label': 'Actions' }, el('div', { class: 'row-actions' },
        action('View', 'View in the Rerun viewer:', () => this.view(entry)),
        action('Plot', 'Plot with the page’s charts:', () => this.plot(entry), spec ? {} : {
          disabled: true, title: 'Not a recording of a geomint simulation: it can be viewed, not plotted',
        }),
        el('a', { class: 'button secondary small', href: url, download: `geomint-${entry.id}.rrd`,
          'aria-label': `Download ${what}` }, 'Download'),
        action('Copy link', 'Copy a link to', () => this.copyLink(entry)),
        // The server says whether the user may delete it (its owner, or an admin token).
        action('Delete', 'Delete', () => this.confirmDelete(entry), entry.may_delete !== false ? {} : {
          disabled: true,
          title: `Stored by ${entry.owner ?? 'an earlier version of the server'}: only its owner or an admin token deletes it`,
        }))));
  }

  /** Turns the list to the page that holds recording `id` (clearing filters that hide it). */
  reveal(id) {
    let index = this.filtered().findIndex((e) => e.id === id);
    if (index < 0) {
      this.ui.system.value = '';
      this.ui.method.value = '';
      index = this.filtered().findIndex((e) => e.id === id);
    }
    if (index < 0) return;
    this.page = Math.floor(index / PAGE_SIZE);
    this.render();
  }

  /** Marks the row of the recording on show. */
  markCurrent() {
    for (const tr of this.ui.list.querySelectorAll('tr')) {
      if (tr.dataset.id === this.showing?.id) tr.setAttribute('aria-current', 'true');
      else tr.removeAttribute('aria-current');
    }
  }

  /** Opens a stored recording in the section's viewer. */
  async view(entry) {
    this.alert('');
    this.returnFocus = document.activeElement;
    this.showing = { id: entry.id };
    this.markCurrent();
    const href = new URL(`api/v1/recordings/${entry.id}.rrd`, window.location.href).href;
    const section = this.viewer.ui.section;
    const opening = this.viewer.openUrl(href, { href, name: `geomint-${entry.id}.rrd` });
    section.dataset.recordingId = entry.id;
    section.scrollIntoView({ behavior: 'smooth', block: 'start' });
    const state = await opening;
    if (this.showing?.id !== entry.id) return;
    this.say(state === 'ready'
      ? `Viewing ${this.describe(entry)} (${sizeText(entry.bytes)}) in the Rerun viewer below.`
      : `${this.describe(entry)} could not be shown here; the viewer section says how to open it in the Rerun app.`);
  }

  afterClose() {
    this.showing = null;
    delete this.viewer.ui.section.dataset.recordingId;
    this.markCurrent();
    const back = this.returnFocus;
    this.returnFocus = null;
    (back?.isConnected ? back : this.ui.file).focus();
  }

  /**
   * Plots a stored simulation recording with the page's charts, below the list: a typed-in
   * system's with its definition (GET /api/v1/systems/{id}, or the one in the recorded request),
   * so that its plots keep the definition's names and bodies.
   */
  async plot(entry) {
    this.alert('');
    this.say(`Reading the samples of ${this.describe(entry)} back from its recording…`);
    let doc;
    try {
      doc = await recordingSamples(entry.id);
    } catch (error) {
      this.say('');
      this.alert(error instanceof ApiError && error.status === 404
        ? `${this.describe(entry)} is no longer stored (deleted, or evicted to stay under the size cap).`
        : `${this.describe(entry)} cannot be plotted: ${error.message}`);
      return;
    }
    const id = doc.system.id;
    const stored = await this.storedSystem(id);
    const inline = typeof doc.request?.system === 'object' ? doc.request.system : null;
    const definition = stored?.definition ?? inline;
    const builtIn = this.systems.find((s) => s.id === id);
    const noEnergyErrorNote = 'No energy error: this recording holds none (its system is damped, has no exact ' +
      'solution, and the run was not compared to the reference).';
    this.plotOptions = (header, request) => ({
      ...(definition
        ? definitionPlotOptions(definition, header, request, { evaluate: true })
        : builtInPlotOptions(builtIn, header, request)),
      noEnergyErrorNote,
    });
    const section = this.root.querySelector('#rec-plot');
    section.hidden = false;
    const lines = streamLines(doc);
    const samples = lines.samples.reduce((n, chunk) => n + chunk.t.length, 0);
    await this.plots.present(lines, doc.request, `recording:${entry.id}`,
      `Recording ${this.describe(entry)}, stored ${when(entry.created)}: ${samples} samples read back from the ` +
      '.rrd file (positions and momenta as recorded, in single precision).');
    section.querySelector('#rec-plot-results-title').textContent = `Recording: ${this.describe(entry)}`;
    section.dataset.recordingId = entry.id;
    section.scrollIntoView({ behavior: 'smooth', block: 'start' });
    section.focus({ preventScroll: true });
    this.say(`Plotted ${this.describe(entry)} below: ${samples} samples read back from the recording.`);
  }

  /** Copies the recording's link (and shows it, for browsers that do not allow copying). */
  async copyLink(entry) {
    const link = recordingLink(entry.id);
    this.ui.link.value = link;
    this.ui.linkBox.hidden = false;
    try {
      await navigator.clipboard.writeText(link);
      this.say(`Copied the link to ${this.describe(entry)}.`);
    } catch {
      this.ui.link.focus();
      this.ui.link.select();
      this.say('This browser did not let the page copy: the link is selected below, copy it from there.');
    }
  }

  /** Asks before deleting; deletes on "Delete". */
  confirmDelete(entry) {
    const { confirm, confirmText } = this.ui;
    const opener = document.activeElement;
    confirmText.textContent = `${this.describe(entry)}, stored ${when(entry.created)} (${sizeText(entry.bytes)}), ` +
      'will be deleted from the server. Its links stop working.';
    confirm.returnValue = '';
    confirm.addEventListener('close', async () => {
      if (confirm.returnValue === 'delete') await this.remove(entry);
      else opener?.focus();
    }, { once: true });
    confirm.showModal();
  }

  async remove(entry) {
    this.alert('');
    try {
      const deleted = await deleteRecording(entry.id);
      this.say(deleted ? `Deleted ${this.describe(entry)}.` : `${this.describe(entry)} was already gone.`);
    } catch (error) {
      this.alert(`${this.describe(entry)} could not be deleted: ${error.message}`);
      return;
    }
    if (this.showing?.id === entry.id) {
      this.viewer.close();
      this.showing = null;
    }
    const status = this.ui.status.textContent;
    await this.refresh();
    this.say(`${status} ${this.ui.status.textContent}`);
    (this.ui.list.querySelector('button') || this.ui.file).focus();
  }

  /** Opens a local .rrd file in the viewer, without uploading it. */
  async openLocal(file) {
    this.ui.fileError.textContent = '';
    this.ui.fileStatus.textContent = '';
    this.ui.fileWarning.hidden = true;
    this.localFile = null;
    this.ui.upload.disabled = true;
    this.setUploadState('idle');
    const wrong = await notAnRrd(file);
    if (wrong) {
      this.ui.fileError.textContent = wrong;
      return;
    }
    // Opened all the same (the viewer shows what it can), with a warning.
    const partial = await cutShort(file);
    this.ui.fileWarning.textContent = partial ?? '';
    this.ui.fileWarning.hidden = !partial;
    this.localFile = file;
    this.ui.upload.disabled = false;
    this.showing = { file: file.name };
    this.markCurrent();
    this.viewer.ui.section.scrollIntoView({ behavior: 'smooth', block: 'start' });
    const state = await this.viewer.openFile(file);
    this.ui.fileStatus.textContent = state === 'ready'
      ? `Opened ${file.name} (${sizeText(file.size)}) from this computer in the viewer below` +
        `${partial ? ', as far as it goes' : ''}; it was not uploaded.`
      : `${file.name} could not be shown here; the viewer section says how to open it in the Rerun app.`;
  }

  /** Uploads the local file opened last to the library. */
  async uploadLocal() {
    const file = this.localFile;
    if (!file) return;
    this.ui.fileError.textContent = '';
    this.ui.upload.disabled = true;
    this.setUploadState('uploading');
    this.ui.fileStatus.textContent = `Uploading ${file.name} (${sizeText(file.size)})…`;
    let created;
    try {
      created = await uploadRecording(file);
    } catch (error) {
      this.setUploadState('error');
      this.ui.fileStatus.textContent = '';
      this.ui.fileError.textContent = `The server refused ${file.name}: ${error.message}`;
      this.ui.upload.disabled = false;
      return;
    }
    this.localFile = null;
    this.ui.fileStatus.textContent = `Uploaded ${file.name}: it is in the library now, ` +
      `with the link ${recordingLink(created.id)}.`;
    this.ui.system.value = '';
    this.ui.method.value = '';
    this.page = 0;
    await this.refresh();
    this.ui.list.querySelector(`tr[data-id="${created.id}"]`)?.setAttribute('data-uploaded', 'true');
    this.setUploadState('done');
  }

  /** Opens the recording the location hash names (`#recording=<id>`), or says why not. */
  async followLink() {
    const linked = linkedRecording(window.location.hash);
    if (!linked) return;
    this.root.scrollIntoView({ block: 'start' });
    if (linked.invalid !== undefined) {
      this.alert(`The link names “${linked.invalid}”, which is not a recording id (32 lowercase hexadecimal digits).`);
      return;
    }
    let entry;
    try {
      entry = await getRecording(linked.id);
    } catch (error) {
      this.alert(error instanceof ApiError && error.status === 404
        ? `There is no recording ${linked.id} on this server: it was deleted, evicted to keep the library under its size cap, or never stored.`
        : `The linked recording could not be looked up: ${error.message}`);
      return;
    }
    if (!this.entries.some((e) => e.id === entry.id)) await this.refresh();
    this.reveal(entry.id);
    await this.view(entry);
  }
}
