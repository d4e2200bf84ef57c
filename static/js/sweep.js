// The sweep section: a sweep request edited as JSON (or loaded from the server's presets), run
// through POST /api/v1/studies/sweep as an NDJSON stream with a progress bar and Cancel; the
// answer drawn as a heatmap of any metric of any run (a method in a chart) over the sweep's one or
// two axes — log10 of the magnitude for errors and drifts, linear over 0 to t_end for divergence
// times — or as the difference between two runs (log10 of the ratio of their values: blue where
// the first is smaller, red where it is larger). A caption says what the colour bar shows and on
// which scale; a legend names the cells without a value (NO_VALUE). A readout gives the cell
// under the pointer (or the keyboard cursor); the sweep downloads as JSON and as a
// Rerun recording. A chaos map's indicators open on their own scales (MEGNO's ⟨Y⟩ from 0 to 8
// with 2, regular motion, marked; λ_max from 0), and the reader may set the colour range. A map
// over two components of the initial state is drawn in the axes' true aspect, the axes named by
// the system's coordinates (`y (q0[1])`), and its cells outside the energy surface are light
// grey. The chaos map of a Phase-space plane launches a clicked cell's orbit on that section.
// The section's state is `data-sweep-state` (idle, running, done, cancelled, error), for tests.

import { ApiError, sweepPresets, sweepRrd, sweepStream } from './api.js';
import { StudyStream, OUTCOME, showRequest } from './study-stream.js';
import { jobStream } from './jobs.js';
import { downloadRecording, el, fmt, plural, saveBlob } from './common.js';
import { GridMap, RATIO_RANGE, bindCursor, drawScaleBar, ratioColour } from './heatmap.js';
import { chaosMeaning, chaosMetrics, chaosScale } from './chaos.js';
import { stateNames } from './phasespace.js';

/**
 * The colours of cells without a value on the scale, and what the legend says of them. On an
 * error map a cell whose run diverged has no error (black); on the divergence map a run that
 * never diverged has no time (white, the opposite end from "diverged early"); anywhere, a cell
 * that did not run (refused, or stopped by the server's time limit) or whose value a log scale
 * cannot show (0) is grey.
 */
export const NO_VALUE = {
  diverged: { rgb: [0, 0, 0], text: 'diverged: no error to show' },
  never: { rgb: [255, 255, 255], text: 'did not diverge before t_end' },
  none: { rgb: [143, 143, 143], text: 'no value: the cell did not run, the time limit stopped it, or its value is 0 (no logarithm)' },
  outside: { rgb: [212, 212, 212], text: 'outside the energy surface: no value of the solved momentum gives H = E there, so no orbit starts' },
  noRatio: { rgb: [143, 143, 143], text: 'no ratio: a run has no value there, or a value is 0' },
};
/** The error of a cell whose initial state is not on the energy surface (the core's words). */
const OUTSIDE_SURFACE = /no state here has H = /;
/** The readout before a cell is chosen. */
const READOUT_PROMPT = 'Point at the map, or focus it and use the arrow keys, to read a cell.';
/** Anchors of the value scale, least to most (the recording's ramp). */
const RAMP = [[68, 1, 84], [59, 82, 139], [33, 145, 140], [94, 201, 98], [253, 231, 37]];

/** The colour of t ∈ [0, 1] on RAMP. */
export function rampColour(t) {
  const x = Math.min(1, Math.max(0, t)) * (RAMP.length - 1);
  const i = Math.min(RAMP.length - 2, Math.floor(x));
  const f = x - i;
  return [0, 1, 2].map((k) => Math.round(RAMP[i][k] + (RAMP[i + 1][k] - RAMP[i][k]) * f));
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

/** Decade ticks of a log₁₀ scale from `lo` to `hi`, at most about six, labelled as values. */
function decadeTicks(lo, hi) {
  const first = Math.ceil(lo);
  const last = Math.floor(hi);
  const step = Math.max(1, Math.ceil((last - first + 1) / 6));
  const ticks = [];
  for (let e = first; e <= last; e += step) ticks.push([e, `1e${e}`]);
  if (!ticks.length) ticks.push([lo, fmt(10 ** lo, 3)], [hi, fmt(10 ** hi, 3)]);
  return ticks;
}

/** What a cell shows: a value on the scale, or null. */
function shown(v, log) {
  if (v == null || !Number.isFinite(v)) return null;
  if (!log) return v;
  return v > 0 ? Math.log10(v) : null;
}

/** Whether a sweep axis is a component of the initial state (`q0[1]`, `p0[0]`). */
const STATE_AXIS = /^[qp]0\[(\d+)\]$/;

/**
 * The plot area's height over its width when both axes are components of the initial state on
 * linear scales (a section's plane: one unit both ways, cells drawn in their true shape); else null.
 */
export function trueAspect(axes) {
  if (axes.length !== 2 || !axes.every((a) => STATE_AXIS.test(a.name) && a.scale !== 'log' && a.n > 1 && a.max > a.min)) return null;
  // The plot reaches half a cell beyond the first and last values.
  const span = (a) => ((a.max - a.min) * a.n) / (a.n - 1);
  return span(axes[1]) / span(axes[0]);
}

/** The heatmap of one metric (or of the ratio of two runs' values) over the sweep's grid. */
class SweepMap extends GridMap {
  constructor(canvas, doc, view, labelOf) {
    const axis = (a, label) => (a.scale === 'log'
      ? { min: Math.log10(a.min), max: Math.log10(a.max), n: a.n, label: `log₁₀ ${label}` }
      : { min: a.min, max: a.max, n: a.n, label });
    const second = doc.axes[1] || { name: '', min: 0, max: 0, n: 1, scale: 'linear' };
    const colour = (c, r) => {
      const k = r * doc.axes[0].n + c;
      const e = view.cellValue(k);
      if (e == null) return NO_VALUE[view.cellKind(k)].rgb;
      return view.compare ? ratioColour(e) : rampColour(view.hi > view.lo ? (e - view.lo) / (view.hi - view.lo) : 0.5);
    };
    super(canvas, {
      x: axis(doc.axes[0], labelOf(doc.axes[0].name)), y: axis(second, labelOf(second.name)), colour,
      aspect: trueAspect(doc.axes),
    });
  }
}

/** The sweep section. */
export class SweepPanel {
  /**
   * @param {HTMLElement} root the section
   * @param {object[]} [systems] the system catalogue, for the names of the initial state's components
   */
  constructor(root, systems = []) {
    this.root = root;
    this.systems = systems;
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
    this.scaleCaption = $('scale-caption');
    this.scaleLegend = $('scale-legend');
    this.figure = $('figure');
    this.canvas = $('canvas');
    this.readout = $('readout');
    this.jsonButton = $('download-json');
    this.rrdButton = $('download-rrd');
    this.rrdError = root.querySelector('#err-sw-rrd');
    this.presets = [];
    this.last = null;
    this.map = null;
    this.cursor = null;
    this.runner = new StudyStream({
      root, stateKey: 'sweepState', progress: this.progress, status: this.status, cancel: this.cancelButton,
    });

    root.querySelector('#sw-form').addEventListener('submit', (event) => {
      event.preventDefault();
      this.planeLaunch = null;
      this.run();
    });
    this.jobButton = $('run-job');
    this.jobButton.addEventListener('click', () => {
      this.planeLaunch = null;
      this.run({ asJob: true });
    });
    /** With a chaos map of a Phase-space plane: launches the orbit of a clicked cell there. */
    this.planeLaunch = null;
    this.presetSelect.addEventListener('change', () => this.loadPreset(this.presetSelect.value));
    for (const select of [this.runSelect, this.metricSelect, this.compareSelect]) {
      select.addEventListener('change', () => {
        this.scaleEdited = false;
        this.redraw();
      });
    }
    this.scaleLo = $('scale-lo');
    this.scaleHi = $('scale-hi');
    for (const input of [this.scaleLo, this.scaleHi]) {
      input.addEventListener('input', () => {
        this.scaleEdited = true;
        this.redraw();
      });
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
    this.jobButton.disabled = false;
  }

  loadPreset(id) {
    const preset = this.presets.find((p) => p.id === id);
    if (preset) this.spec.value = JSON.stringify(preset.request, null, 2);
  }

  /**
   * Runs the request in the text box (a new run supersedes a running one); `asJob` submits it as
   * a job and draws the job's document when it is done.
   */
  async run({ asJob = false } = {}) {
    this.error.textContent = '';
    this.spec.removeAttribute('aria-invalid');
    let body;
    try {
      body = JSON.parse(this.spec.value);
    } catch (e) {
      this.runner.abort();
      this.error.textContent = `The request is not JSON: ${e.message}`;
      this.spec.setAttribute('aria-invalid', 'true');
      this.runner.setState('error');
      return;
    }
    const stream = asJob ? jobStream('sweep') : sweepStream;
    const { outcome, result: doc, error } = await this.runner.stream(stream, body);
    if (outcome === OUTCOME.superseded) return;
    if (outcome === OUTCOME.cancelled) {
      this.status.textContent = 'Cancelled.';
      return;
    }
    if (outcome === OUTCOME.error) {
      const where = error instanceof ApiError && error.field ? ` (at \`${error.field}\`)` : '';
      this.error.textContent = `${error?.message || error}${where}`;
      this.spec.setAttribute('aria-invalid', 'true');
      this.status.textContent = 'The server refused the sweep.';
      this.spec.focus();
      return;
    }
    this.finish(body, doc);
  }

  /** Shows a done job's sweep: its request in the text box and its document drawn. */
  show(body, doc) {
    showRequest(this, body);
    this.planeLaunch = null;
    this.finish(body, doc);
  }

  /** Draws the sweep `doc` of the request `body`. */
  finish(body, doc) {
    this.last = { body, doc };
    this.runner.showProgress(doc.cells, doc.cells);
    this.showViews(doc);
    this.status.textContent = `Done: ${plural(doc.cells, 'cell')} × ${plural(doc.runs.length, 'run')} of ${doc.system}, ` +
      `${doc.steps.toLocaleString('en')} steps in ${fmt(doc.wall_ms / 1000, 3)} s.` +
      (doc.stop === 'time_limit'
        ? ` The server's time limit stopped ${doc.unfinished_cells.length} cells (left blank).`
        : '');
    this.runner.setState('done');
  }

  /**
   * Runs `body`, the chaos map of a Phase-space section's plane; a click on a cell of its map
   * then calls `launch(x, y)` with the cell's values of the two axes.
   */
  async runFromPlane(body, launch) {
    this.spec.value = JSON.stringify(body, null, 2);
    this.planeLaunch = launch;
    this.planeBody = this.spec.value;
    await this.run();
  }

  /** Whether the map on show is a Phase-space plane's, whose cells launch orbits there. */
  get launchesOrbits() {
    return Boolean(this.planeLaunch && this.last && JSON.stringify(this.last.body, null, 2) === this.planeBody);
  }

  /** The last progress line of the last run (for tests). */
  get lastProgress() {
    return this.runner.lastProgress;
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
    // The cursor, the readout and a colour range set by hand belonged to the last sweep.
    this.cursor = null;
    this.scaleEdited = false;
    this.readout.textContent = READOUT_PROMPT;
    for (const key of Object.keys(this.readout.dataset)) delete this.readout.dataset[key];
    this.redraw();
  }

  /** The current view: the metric, the runs, and per cell the value drawn. */
  currentView() {
    const doc = this.last.doc;
    const metric = this.metricSelect.value;
    const a = metricsOf(doc.runs[Number(this.runSelect.value)])[metric];
    const compare = this.compareSelect.value === '' ? null : Number(this.compareSelect.value);
    const b = compare == null ? null : metricsOf(doc.runs[compare])[metric];
    const run = doc.runs[Number(this.runSelect.value)];
    const view = { metric, a, b, compare: b != null };
    view.cellValue = (k) => {
      if (!b) return shown(a.values[k], a.log);
      const x = a.values[k];
      const y = b.values[k];
      return x > 0 && y > 0 && Number.isFinite(x) && Number.isFinite(y) ? Math.log10(x / y) : null;
    };
    const unfinished = new Set(doc.unfinished_cells ?? []);
    /** Why cell k has no value on the scale: a key of NO_VALUE. */
    view.cellKind = (k) => {
      if (OUTSIDE_SURFACE.test(run.errors[k] ?? '')) return 'outside';
      if (b) return 'noRatio';
      if (run.errors[k] || unfinished.has(k)) return 'none';
      if (metric === 'diverged_at') return 'never';
      return run.diverged_at[k] != null ? 'diverged' : 'none';
    };
    const values = a.values.map((_, k) => view.cellValue(k)).filter((v) => v != null);
    view.indicator = b ? null : chaosScale(metric, values);
    if (view.indicator) {
      view.lo = view.indicator.lo;
      view.hi = view.indicator.hi;
    } else if (metric === 'diverged_at' && !b) {
      // Times of divergence on the sweep's whole time span: runs found diverged at nearly the
      // same (sampled) time look alike instead of stretching the colours over a few steps.
      view.lo = 0;
      view.hi = Math.max(this.last.body.t_end ?? 0, ...values, 1e-300);
    } else {
      view.lo = values.length ? Math.min(...values) : 0;
      view.hi = values.length ? Math.max(...values) : 1;
    }
    // The colour range as the reader set it (in the metric's units), else the default's.
    if (!b) {
      const shownOf = (text) => shown(Number(text), a.log);
      const [lo, hi] = [shownOf(this.scaleLo.value), shownOf(this.scaleHi.value)];
      if (this.scaleEdited && lo != null && hi != null && hi > lo && this.scaleLo.value.trim() && this.scaleHi.value.trim()) {
        view.lo = lo;
        view.hi = hi;
      } else if (!this.scaleEdited) {
        const unit = (e) => (a.log ? 10 ** e : e);
        this.scaleLo.value = String(+unit(view.lo).toPrecision(3));
        this.scaleHi.value = String(+unit(view.hi).toPrecision(3));
      }
    }
    this.scaleLo.disabled = Boolean(b);
    this.scaleHi.disabled = Boolean(b);
    view.kinds = new Set(a.values.map((_, k) => k).filter((k) => view.cellValue(k) == null).map(view.cellKind));
    return view;
  }

  redraw() {
    if (!this.last) return;
    const doc = this.last.doc;
    this.currentViewState = this.currentView();
    const canvas = this.canvas.cloneNode(false);
    canvas.style.width = '';
    this.canvas.replaceWith(canvas);
    this.canvas = canvas;
    this.map = new SweepMap(canvas, doc, this.currentViewState, (name) => this.axisLabel(name));
    bindCursor(this.map, { get: () => this.cursor, set: (cell) => this.setCursor(cell) });
    const launch = (cell) => {
      if (!cell || !this.launchesOrbits) return;
      const [x, y] = doc.axes;
      this.planeLaunch(x.values[cell.col], y.values[cell.row]);
    };
    canvas.addEventListener('click', (event) => launch(this.map.cellAt(event.offsetX, event.offsetY)));
    canvas.addEventListener('keydown', (event) => {
      if (event.key === 'Enter') launch(this.cursor);
    });
    this.root.querySelector('#sw-plane-note').hidden = !this.launchesOrbits;
    this.canvas.setAttribute('aria-label', `Sweep heatmap of ${this.currentViewState.a.label}: ` +
      `${this.axisLabel(doc.axes[0].name)} across${doc.axes[1] ? `, ${this.axisLabel(doc.axes[1].name)} upwards` : ''}. ` +
      'Arrow keys move the cursor cell.');
    if (this.cursor && (this.cursor.col >= this.map.cols || this.cursor.row >= this.map.rows)) this.cursor = null;
    if (this.cursor) this.setCursor(this.cursor);
    this.layout();
  }

  /**
   * The names of the initial state's components in the sweep's system: the definition's, or the
   * catalogue's for the chart the initial state is given in.
   */
  stateNamesOf() {
    const { body, doc } = this.last;
    const system = body.system;
    if (typeof system !== 'string') return stateNames(system, this.systems);
    const entry = this.systems.find((x) => x.id === system);
    const run = doc.runs[Number(this.runSelect.value)] ?? doc.runs[0];
    const chart = body.initial_coordinates === 'cartesian' ? null : entry?.charts?.find((c) => c.id === run?.chart);
    if (chart?.coordinates) {
      return { coordinates: chart.coordinates, momenta: chart.coordinates.map((c) => `p_${c}`) };
    }
    return stateNames(system, this.systems);
  }

  /** An axis's label: `y (q0[1])` for a component of the initial state, else its name. */
  axisLabel(name) {
    const m = STATE_AXIS.exec(name);
    if (!m || !this.last) return name;
    const names = this.stateNamesOf();
    const word = (name.startsWith('q') ? names.coordinates : names.momenta)[Number(m[1])];
    return word ? `${word} (${name})` : name;
  }

  setCursor(cell) {
    if (!this.map) return;
    this.cursor = cell;
    this.map.cursor = cell;
    this.map.draw();
    const doc = this.last.doc;
    const view = this.currentViewState;
    const k = cell.row * doc.axes[0].n + cell.col;
    const where = doc.axes.map((a, i) => {
      const label = this.axisLabel(a.name);
      return `${STATE_AXIS.test(a.name) ? label.split(' (')[0] : label} = ${fmt(a.values[i === 0 ? cell.col : cell.row])}`;
    }).join(', ');
    const run = doc.runs[Number(this.runSelect.value)];
    const a = view.a.values[k];
    const kind = view.cellKind(k);
    const meaning = view.b ? '' : chaosMeaning(view.metric, a);
    let text;
    if (kind === 'outside') {
      text = `${where}: ${NO_VALUE.outside.text}`;
    } else {
      const value = a == null && view.cellValue(k) == null ? `— (${NO_VALUE[kind].text})` : fmt(a, 3);
      text = `${where}: ${view.a.label} ${value}${meaning ? ` (${meaning})` : ''}`;
      if (view.b) text += ` against ${fmt(view.b.values[k], 3)}, ratio ${fmt(view.cellValue(k) == null ? null : 10 ** view.cellValue(k), 3)}`;
      if (run.diverged_at[k] != null) text += `; diverged at t = ${fmt(run.diverged_at[k])}`;
      if (run.errors[k]) text += `; could not run: ${run.errors[k]}`;
    }
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
      drawScaleBar(this.scaleBar, this.scale(view));
      this.scaleCaption.textContent = this.scaleBar.getAttribute('aria-label').replace(/^Colour scale: /, '');
      this.scaleLegend.replaceChildren(...[...view.kinds].map((kind) => el('li', { 'data-kind': kind },
        el('span', { class: 'swatch block', style: `background:rgb(${NO_VALUE[kind].rgb.join(',')})`, 'aria-hidden': 'true' }),
        NO_VALUE[kind].text)));
    });
  }

  /** The colour bar of `view`: its colours, ticks and what it says (its accessible name and caption). */
  scale(view) {
    const { a } = view;
    if (view.compare) {
      return {
        lo: -RATIO_RANGE, hi: RATIO_RANGE, colourAt: ratioColour,
        ticks: [[-2, '1/100'], [-1, '1/10'], [0, '1'], [1, '10'], [2, '100']],
        label: `Colour scale: the ratio of ${a.label} of the two runs, on a log scale from 1/100 to 100: ` +
          'blue where the first run\'s value is smaller, white where they agree, red where it is larger.',
      };
    }
    const hi = view.hi > view.lo ? view.hi : view.lo + 1;
    const colourAt = (e) => rampColour((e - view.lo) / (hi - view.lo));
    if (view.indicator) {
      const marks = view.indicator.marks.filter(([v]) => v > view.lo && v < hi);
      const ticks = [[view.lo, fmt(view.lo, 3)], ...marks, [hi, `${view.indicator.clipped ? '≥ ' : ''}${fmt(hi, 3)}`]];
      const mark = marks.map(([v, text]) => ` ${fmt(v, 3)} is marked (${text.replace(/^\S+ /, '')} motion).`).join('');
      return {
        lo: view.lo, hi, colourAt, ticks,
        label: `Colour scale: ${a.label}, from ${fmt(view.lo, 3)} (dark blue) to ${fmt(hi, 3)} (yellow)` +
          `${view.indicator.clipped ? '; larger values take the top colour' : ''}.${mark}` +
          (view.metric === 'megno_mean' ? ' ⟨Y⟩ ≈ 2 on tori (regular), grows like λt/2 in chaos.' : '') +
          ' Set the range above the bar.',
      };
    }
    if (a.log) {
      return {
        lo: view.lo, hi, colourAt, ticks: decadeTicks(view.lo, hi),
        label: `Colour scale: ${a.label}, on a log scale from ${fmt(10 ** view.lo, 3)} (dark blue) ` +
          `to ${fmt(10 ** view.hi, 3)} (yellow).`,
      };
    }
    const every = this.last.body.every;
    return {
      lo: view.lo, hi, colourAt,
      ticks: [[view.lo, fmt(view.lo, 3)], [(view.lo + hi) / 2, fmt((view.lo + hi) / 2, 3)], [hi, fmt(hi, 3)]],
      label: `Colour scale: ${a.label}, from ${fmt(view.lo, 3)} (dark blue) to ${fmt(hi, 3)} (yellow)` +
        (view.metric === 'diverged_at'
          ? `; a divergence is found at the first sampled step after it${every ? ` (every ${every} steps)` : ''}, so times are upper bounds.`
          : '.'),
    };
  }

  downloadJson() {
    if (!this.last) return;
    const text = JSON.stringify({ request: this.last.body, ...this.last.doc });
    saveBlob(new Blob([text], { type: 'application/json' }), 'geomint-sweep.json');
  }

  /** Saves the sweep as geomint-sweep.rrd (the server runs and records it again). */
  downloadRrd() {
    if (!this.last) return null;
    const { body } = this.last;
    return downloadRecording({
      button: this.rrdButton, status: this.status, error: this.rrdError,
      name: 'geomint-sweep.rrd', fetchBlob: () => sweepRrd(body),
    });
  }
}
