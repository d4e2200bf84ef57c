// The sweep section: a sweep request edited as JSON (or loaded from the server's presets), run
// through POST /api/v1/studies/sweep as an NDJSON stream with a progress bar and Cancel; the
// answer drawn as a heatmap of any metric of any run (a method in a chart) over the sweep's one or
// two axes — log10 of the magnitude for errors and drifts, linear for divergence times, black
// where a run diverged or could not start — or as the difference between two runs (log10 of the
// ratio of their values: blue where the first is smaller, red where it is larger). A readout
// gives the cell under the pointer (or the keyboard cursor); the sweep downloads as JSON and as a
// Rerun recording. The section's state is `data-sweep-state` (idle, running, done, cancelled,
// error), for tests.

import { ApiError, sweepPresets, sweepRrd, sweepStream } from './api.js';
import { chaosMetrics } from './chaos.js';
import { el } from './form.js';
import { GridMap, bindCursor, drawScaleBar, fmt } from './heatmap.js';
import { saveBlob, sizeText } from './rerun.js';

/** Where a cell has no value. */
const EMPTY = [0, 0, 0];
/** The ratio view saturates at a factor 10^RATIO_RANGE. */
const RATIO_RANGE = 2;
/** Anchors of the value scale, least to most (the recording's ramp). */
const RAMP = [[68, 1, 84], [59, 82, 139], [33, 145, 140], [94, 201, 98], [253, 231, 37]];

/** The colour of t ∈ [0, 1] on RAMP. */
export function rampColour(t) {
  const x = Math.min(1, Math.max(0, t)) * (RAMP.length - 1);
  const i = Math.min(RAMP.length - 2, Math.floor(x));
  const f = x - i;
  return [0, 1, 2].map((k) => Math.round(RAMP[i][k] + (RAMP[i + 1][k] - RAMP[i][k]) * f));
}

function ratioColour(e) {
  const r = Math.min(1, Math.max(-1, e / RATIO_RANGE));
  const fade = Math.round(255 * (1 - Math.abs(r)));
  return r < 0 ? [fade, fade, 255] : [255, fade, fade];
}

/** The metrics of a run: key → {label, values, log}. */
export function metricsOf(run) {
  const out = {
    energy_error_max: { label: 'largest |energy error|', values: run.energy_error_max, log: true },
    energy_error_final: { label: '|energy error| at t_end', values: run.energy_error_final.map((v) => (v == null ? null : Math.abs(v))), log: true },
    energy_error_l2: { label: 'ℓ² energy error (eq. 50)', values: run.energy_error_l2, log: true },
    diverged_at: { label: 'time of divergence', values: run.diverged_at, log: false },
  };
  for (const [name, values] of Object.entries(run.invariant_drift)) {
    out[`drift_${name}`] = { label: `drift of ${name}`, values, log: true };
  }
  // A chaos map shows its indicators first.
  return { ...chaosMetrics(run), ...out };
}

/** What a cell shows: a value on the scale, or null. */
function shown(v, log) {
  if (v == null || !Number.isFinite(v)) return null;
  if (!log) return v;
  return v > 0 ? Math.log10(v) : null;
}

/** The heatmap of one metric (or of the ratio of two runs' values) over the sweep's grid. */
class SweepMap extends GridMap {
  constructor(canvas, doc, view) {
    const axis = (a, label) => (a.scale === 'log'
      ? { min: Math.log10(a.min), max: Math.log10(a.max), n: a.n, label: `log₁₀ ${label}` }
      : { min: a.min, max: a.max, n: a.n, label });
    const second = doc.axes[1] || { name: '', min: 0, max: 0, n: 1, scale: 'linear' };
    const colour = (c, r) => {
      const e = view.cellValue(r * doc.axes[0].n + c);
      if (e == null) return EMPTY;
      return view.compare ? ratioColour(e) : rampColour(view.hi > view.lo ? (e - view.lo) / (view.hi - view.lo) : 0.5);
    };
    super(canvas, { x: axis(doc.axes[0], doc.axes[0].name), y: axis(second, second.name), colour });
  }
}

/** The sweep section. */
export class SweepPanel {
  constructor(root) {
    this.root = root;
    const $ = (id) => root.querySelector(`#sw-${id}`);
    this.spec = $('spec');
    this.presetSelect = $('preset');
    this.runButton = $('run');
    this.cancelButton = $('cancel');
    this.progress = $('progress');
    this.status = $('status');
    this.error = root.querySelector('#err-sw-spec');
    this.view = $('view');
    this.runSelect = $('run-select');
    this.metricSelect = $('metric');
    this.compareSelect = $('compare');
    this.scaleBar = $('scale-bar');
    this.figure = $('figure');
    this.canvas = $('canvas');
    this.readout = $('readout');
    this.jsonButton = $('download-json');
    this.rrdButton = $('download-rrd');
    this.rrdError = root.querySelector('#err-sw-rrd');
    this.presets = [];
    this.last = null;
    this.lastProgress = null;
    this.map = null;
    this.cursor = null;
    this.controller = null;

    root.querySelector('#sw-form').addEventListener('submit', (event) => {
      event.preventDefault();
      this.run();
    });
    this.presetSelect.addEventListener('change', () => this.loadPreset(this.presetSelect.value));
    this.cancelButton.addEventListener('click', () => this.controller?.abort());
    for (const select of [this.runSelect, this.metricSelect, this.compareSelect]) {
      select.addEventListener('change', () => this.redraw());
    }
    this.jsonButton.addEventListener('click', () => this.downloadJson());
    this.rrdButton.addEventListener('click', () => this.downloadRrd());
    new ResizeObserver(() => this.layout()).observe(root.querySelector('#sw-results'));
  }

  /** Fetches the presets and shows the first. */
  async init() {
    this.presets = await sweepPresets();
    this.presetSelect.replaceChildren(...this.presets.map((p) => el('option', { value: p.id, text: p.title })));
    this.loadPreset(this.presets[0]?.id);
    this.runButton.disabled = false;
  }

  loadPreset(id) {
    const preset = this.presets.find((p) => p.id === id);
    if (preset) this.spec.value = JSON.stringify(preset.request, null, 2);
  }

  setState(state) {
    this.root.dataset.sweepState = state;
  }

  async run() {
    this.controller?.abort();
    const controller = new AbortController();
    this.controller = controller;
    this.error.textContent = '';
    this.spec.removeAttribute('aria-invalid');
    let body;
    try {
      body = JSON.parse(this.spec.value);
    } catch (e) {
      this.error.textContent = `The request is not JSON: ${e.message}`;
      this.spec.setAttribute('aria-invalid', 'true');
      this.setState('error');
      return;
    }
    let doc = null;
    this.setState('running');
    this.cancelButton.disabled = false;
    this.progress.removeAttribute('value');
    this.lastProgress = null;
    this.status.textContent = 'Starting…';
    try {
      await sweepStream(body, (line) => {
        if (controller !== this.controller) return;
        if (line.type === 'progress') {
          this.lastProgress = line;
          this.progress.max = line.total;
          this.progress.value = line.done;
          this.status.textContent = `Running: ${line.done} of ${line.total} cells.`;
        } else if (line.type === 'result') {
          const { type, ...rest } = line;
          doc = rest;
        } else if (line.type === 'error') {
          throw new ApiError(line.error);
        }
      }, controller.signal);
    } catch (error) {
      if (controller !== this.controller) return;
      this.cancelButton.disabled = true;
      if (!this.lastProgress) this.progress.value = 0;
      if (error?.name === 'AbortError') {
        this.status.textContent = 'Cancelled.';
        this.setState('cancelled');
        return;
      }
      const where = error instanceof ApiError && error.field ? ` (at \`${error.field}\`)` : '';
      this.error.textContent = `${error?.message || error}${where}`;
      this.spec.setAttribute('aria-invalid', 'true');
      this.status.textContent = 'The server refused the sweep.';
      this.setState('error');
      this.spec.focus();
      return;
    }
    if (controller !== this.controller) return;
    this.cancelButton.disabled = true;
    this.last = { body, doc };
    this.progress.max = Math.max(1, doc.cells);
    this.progress.value = doc.cells;
    this.showViews(doc);
    this.status.textContent = `Done: ${doc.cells} cells × ${doc.runs.length} runs of ${doc.system}, ` +
      `${doc.steps.toLocaleString('en')} steps in ${fmt(doc.wall_ms / 1000, 3)} s.` +
      (doc.stop === 'time_limit'
        ? ` The server's time limit stopped ${doc.unfinished_cells.length} cells (left blank).`
        : '');
    this.setState('done');
  }

  /** Fills the run, metric and comparison choices for `doc` and draws the first view. */
  showViews(doc) {
    const runLabel = (r) => `${r.method} (${r.chart})`;
    const options = (select, entries) => select.replaceChildren(...entries.map(([value, text]) => el('option', { value, text })));
    options(this.runSelect, doc.runs.map((r, i) => [String(i), runLabel(r)]));
    options(this.metricSelect, Object.entries(metricsOf(doc.runs[0])).map(([k, m]) => [k, m.label]));
    options(this.compareSelect, [['', 'nothing (values)'], ...doc.runs.map((r, i) => [String(i), `÷ ${runLabel(r)}`])]);
    this.view.hidden = false;
    this.figure.hidden = false;
    this.jsonButton.disabled = false;
    this.rrdButton.disabled = false;
    this.redraw();
  }

  /** The current view: the metric, the runs, and per cell the value drawn. */
  currentView() {
    const doc = this.last.doc;
    const metric = this.metricSelect.value;
    const a = metricsOf(doc.runs[Number(this.runSelect.value)])[metric];
    const compare = this.compareSelect.value === '' ? null : Number(this.compareSelect.value);
    const b = compare == null ? null : metricsOf(doc.runs[compare])[metric];
    const view = { metric, a, b, compare: b != null };
    view.cellValue = (k) => {
      if (!b) return shown(a.values[k], a.log);
      const x = a.values[k];
      const y = b.values[k];
      return x > 0 && y > 0 && Number.isFinite(x) && Number.isFinite(y) ? Math.log10(x / y) : null;
    };
    const values = a.values.map((_, k) => view.cellValue(k)).filter((v) => v != null);
    view.lo = values.length ? Math.min(...values) : 0;
    view.hi = values.length ? Math.max(...values) : 1;
    return view;
  }

  redraw() {
    if (!this.last) return;
    const doc = this.last.doc;
    this.currentViewState = this.currentView();
    const canvas = this.canvas.cloneNode(false);
    this.canvas.replaceWith(canvas);
    this.canvas = canvas;
    this.map = new SweepMap(canvas, doc, this.currentViewState);
    bindCursor(this.map, { get: () => this.cursor, set: (cell) => this.setCursor(cell) });
    this.canvas.setAttribute('aria-label', `Sweep heatmap of ${this.currentViewState.a.label}: ` +
      `${doc.axes[0].name} across${doc.axes[1] ? `, ${doc.axes[1].name} upwards` : ''}. Arrow keys move the cursor cell.`);
    if (this.cursor && (this.cursor.col >= this.map.cols || this.cursor.row >= this.map.rows)) this.cursor = null;
    if (this.cursor) this.setCursor(this.cursor);
    this.layout();
  }

  setCursor(cell) {
    if (!this.map) return;
    this.cursor = cell;
    this.map.cursor = cell;
    this.map.draw();
    const doc = this.last.doc;
    const view = this.currentViewState;
    const k = cell.row * doc.axes[0].n + cell.col;
    const where = doc.axes.map((a, i) => `${a.name} = ${fmt(a.values[i === 0 ? cell.col : cell.row])}`).join(', ');
    const run = doc.runs[Number(this.runSelect.value)];
    const a = view.a.values[k];
    let text = `${where}: ${view.a.label} ${fmt(a, 3)}`;
    if (view.b) text += ` against ${fmt(view.b.values[k], 3)}, ratio ${fmt(view.cellValue(k) == null ? null : 10 ** view.cellValue(k), 3)}`;
    if (run.diverged_at[k] != null) text += `; diverged at t = ${fmt(run.diverged_at[k])}`;
    if (run.errors[k]) text += `; could not run: ${run.errors[k]}`;
    this.readout.textContent = `${text}.`;
    Object.assign(this.readout.dataset, {
      col: String(cell.col), row: String(cell.row), cell: String(k),
      value: a == null ? '' : String(a), other: view.b ? String(view.b.values[k] ?? '') : '',
    });
  }

  layout() {
    if (!this.map || this.pending) return;
    this.pending = true;
    requestAnimationFrame(() => {
      this.pending = false;
      this.map.resize();
      const view = this.currentViewState;
      const what = view.compare ? `log₁₀ of the ratio of ${view.a.label}` : `${view.a.log ? 'log₁₀ ' : ''}${view.a.label}`;
      drawScaleBar(this.scaleBar, view.compare
        ? { lo: -RATIO_RANGE, hi: RATIO_RANGE, colourAt: ratioColour,
          ticks: [[-2, '1/100'], [-1, '1/10'], [0, '1'], [1, '10'], [2, '100']],
          label: `Colour scale: ${what}, blue where the first run's value is smaller, red where it is larger; black: no value.` }
        : { lo: view.lo, hi: view.hi > view.lo ? view.hi : view.lo + 1,
          colourAt: (e) => rampColour(view.hi > view.lo ? (e - view.lo) / (view.hi - view.lo) : 0.5),
          ticks: [[view.lo, fmt(view.lo, 3)], [view.hi, fmt(view.hi, 3)]],
          label: `Colour scale: ${what} from ${fmt(view.lo, 3)} (dark blue) to ${fmt(view.hi, 3)} (yellow); black: no value.` });
    });
  }

  downloadJson() {
    if (!this.last) return;
    const text = JSON.stringify({ request: this.last.body, ...this.last.doc });
    saveBlob(new Blob([text], { type: 'application/json' }), 'geomint-sweep.json');
  }

  async downloadRrd() {
    if (!this.last) return;
    this.rrdError.textContent = '';
    this.rrdButton.disabled = true;
    try {
      const blob = await sweepRrd(this.last.body);
      saveBlob(blob, 'geomint-sweep.rrd');
      this.status.textContent = `Saved geomint-sweep.rrd (${sizeText(blob.size)}).`;
    } catch (error) {
      this.rrdError.textContent = `The recording could not be made: ${error?.message || error}`;
    } finally {
      this.rrdButton.disabled = false;
    }
  }
}
