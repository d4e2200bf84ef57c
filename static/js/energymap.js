// The energy-error map section (paper 001 Fig. 6): a small form (a method that runs on the polar
// chart, the grid, h, t_max, g) whose map, POST /api/v1/studies/energy-map, streams as NDJSON with
// a progress bar and can be cancelled; the answer drawn as a heatmap of log10(ε(x,y)/ε(r,θ)) with
// the recording's colours (white at equal errors, blue where the Cartesian run is more accurate,
// red where the polar one is, saturating at the ratio 98 % of its cells stay within, black where a run
// diverged), y growing downwards along gravity, the analytic boundary r = 2l + 2mg/k·cos θ dashed over it, a colour
// legend, a readout of the cell under the pointer (or the keyboard cursor), the summary counts,
// and downloads of the map as JSON and as a Rerun recording. The section's state is
// `data-map-state` (idle, running, done, cancelled, error), for tests.

import { energyMapStream, energyMapRrd, ApiError } from './api.js';
import { StudyStream, OUTCOME } from './study-stream.js';
import { jobStream } from './jobs.js';
import { downloadRecording, el, fmt, parseCount, parseNumber, saveBlob } from './common.js';
import { GridMap, RATIO_SHARE, bindCursor, dataRatioRange, drawScaleBar, ratioColour, ratioTicks } from './heatmap.js';

/** Where a run diverged (or the pivot, where the polar chart does not exist). */
export const DIVERGED_COLOUR = [0, 0, 0];
const DIVERGED_CSS = `rgb(${DIVERGED_COLOUR.join(',')})`;
/** The method selected first. */
const DEFAULT_METHOD = 'symplectic_euler';

/**
 * The RGB colour of a cell from its two errors: white at equal errors, saturating to blue
 * (Cartesian better) or red (polar better) at a factor 10^`range` (the map's largest ratio
 * either way, see `ratioRangeOf`); black where either run diverged (an error is null).
 */
export function differenceColour(cartesian, polar, range) {
  if (cartesian == null || polar == null) return DIVERGED_COLOUR;
  return ratioColour(cartesian > 0 && polar > 0 ? Math.log10(cartesian / polar) : 0, range);
}

/** The scale of a map scaled to its data: the |log₁₀ ε(x,y)/ε(r,θ)| that 98 % of its cells stay within. */
export function ratioRangeOf(doc) {
  return dataRatioRange(doc.epsilon_cartesian.map((c, k) => {
    const p = doc.epsilon_polar[k];
    return c > 0 && p > 0 ? Math.log10(c / p) : null;
  }));
}

/** Whether a method runs on the polar chart's non-separable Hamiltonian with fixed steps. */
function runsInPolar(method) {
  return method.requirements.length === 0 && method.kind !== 'adaptive' && method.options.length === 0;
}

/** The map of one answer on a canvas: cells coloured by the error ratio, the boundary dashed. */
class EnergyMap extends GridMap {
  /** @param {HTMLCanvasElement} canvas @param {object} doc the API's map document */
  constructor(canvas, doc) {
    const nx = doc.xs.length;
    const axis = (values, label) => ({ min: values[0], max: values[values.length - 1], n: values.length, label });
    const range = ratioRangeOf(doc);
    super(canvas, {
      x: axis(doc.xs, 'x₀'),
      y: axis(doc.ys, 'y₀ ↓'),
      yDown: true,
      colour: (c, r) => differenceColour(doc.epsilon_cartesian[r * nx + c], doc.epsilon_polar[r * nx + c], range),
      // Equal scales on both axes, the plot area at most 560 px high.
      height: (width, area) => {
        const span = (a) => (a.n > 1 ? ((a.max - a.min) * a.n) / (a.n - 1) : 1);
        const ratio = span(axis(doc.ys)) / span(axis(doc.xs));
        return Math.round(Math.min(560, Math.max(120, area.w * ratio))) + 46;
      },
    });
    this.doc = doc;
    this.range = range;
    this.boundary = [doc.boundary.map(([x, y]) => this.cellUnits(x, y))];
  }

  drawOverlay(ctx) {
    // Dashes of black on a white line: visible on white, blue, red and black cells alike.
    this.strokeLines(ctx, this.boundary, { colour: '#ffffff', width: 2.5 });
    this.strokeLines(ctx, this.boundary, { colour: '#000000', width: 1.5, dash: [5, 4] });
  }

  /** The values of cell (col, row), for the readout. */
  cell(col, row) {
    const d = this.doc;
    const k = row * d.xs.length + col;
    const cartesian = d.epsilon_cartesian[k];
    const polar = d.epsilon_polar[k];
    let winner = null;
    if (cartesian != null && polar != null) {
      winner = cartesian < polar ? 'cartesian' : polar < cartesian ? 'polar' : 'tie';
    }
    return {
      col,
      row,
      x: d.xs[col],
      y: d.ys[row],
      cartesian,
      polar,
      winner,
      polarDivergedAt: d.polar_diverged_at[k],
      cartesianDivergedAt: d.cartesian_diverged_at?.[k] ?? null,
      predicted: d.predicted_divergent[k],
      energy: d.energy[k],
    };
  }
}

/** The text of a cell's readout. */
function readoutText(v) {
  const where = `x₀ = ${fmt(v.x)}, y₀ = ${fmt(v.y)} (r₀ = ${fmt(Math.hypot(v.x, v.y))})`;
  const errors = `ε(x,y) = ${v.cartesian == null ? '—' : fmt(v.cartesian, 3)}, ε(r,θ) = ${v.polar == null ? '—' : fmt(v.polar, 3)}`;
  const prediction = v.predicted ? 'inside the region predicted to diverge' : 'outside the region predicted to diverge';
  let verdict;
  if (v.x === 0 && v.y === 0) {
    verdict = 'the pivot, where the spring has no direction: no run there';
  } else if (v.cartesianDivergedAt != null) {
    verdict = `the Cartesian run diverged at t = ${fmt(v.cartesianDivergedAt)}`;
  } else if (v.polarDivergedAt != null) {
    verdict = `the polar run diverged at t = ${fmt(v.polarDivergedAt)}, ${prediction}`;
  } else if (v.polar == null) {
    verdict = 'the pivot: no polar coordinates there';
  } else if (v.winner === 'tie') {
    verdict = 'equal errors';
  } else {
    const factor = v.winner === 'cartesian' ? v.polar / v.cartesian : v.cartesian / v.polar;
    verdict = `${v.winner === 'cartesian' ? 'Cartesian' : 'polar'} better by a factor ${fmt(factor, 3)}` +
      (v.predicted ? `; ${prediction}` : '');
  }
  return `${where}: ${errors}; ${verdict}.`;
}

/** The energy-error map section. */
export class EnergyMapPanel {
  /**
   * @param {HTMLElement} root the section
   * @param {object[]} methods the method catalogue
   */
  constructor(root, methods) {
    this.root = root;
    this.form = root.querySelector('#em-form');
    this.runButton = root.querySelector('#em-run');
    this.cancelButton = root.querySelector('#em-cancel');
    this.progress = root.querySelector('#em-progress');
    this.status = root.querySelector('#em-status');
    this.scaleBox = root.querySelector('#em-scale');
    this.scaleBar = root.querySelector('#em-scale-bar');
    this.figure = root.querySelector('#em-figure');
    this.canvas = root.querySelector('#em-canvas');
    this.readout = root.querySelector('#em-readout');
    this.summary = root.querySelector('#em-summary');
    this.jsonButton = root.querySelector('#em-download-json');
    this.rrdButton = root.querySelector('#em-download-rrd');
    this.rrdError = root.querySelector('#err-em-rrd');
    this.generalError = root.querySelector('#err-em-form');
    const field = (id) => ({ input: root.querySelector(`#em-${id}`), error: root.querySelector(`#err-em-${id}`) });
    /** API field path → input and error slot. */
    this.fields = new Map([
      ['method', field('method')], ['nx', field('nx')], ['ny', field('ny')],
      ['h', field('h')], ['t_max', field('t-max')], ['params.g', field('g')],
    ]);
    const select = this.fields.get('method').input;
    select.replaceChildren(...methods.filter(runsInPolar).map((m) => el('option', { value: m.id, text: `${m.id} — ${m.name}` })));
    select.value = DEFAULT_METHOD;

    /** @type {EnergyMap|null} */
    this.map = null;
    this.cursor = null;
    this.runner = new StudyStream({
      root, stateKey: 'mapState', progress: this.progress, status: this.status, cancel: this.cancelButton,
    });
    /** The last map: {body, doc} (for tests and the downloads). */
    this.last = null;
    this.scaleBox.append(el('ul', { class: 'legend scale-legend' },
      el('li', {}, el('span', { class: 'swatch block', style: `background:${DIVERGED_CSS}`, 'aria-hidden': 'true' }),
        'a run diverged (or the pivot, where polar coordinates do not exist)'),
      el('li', {}, el('span', { class: 'swatch line dashed', style: 'border-top-color:#000', 'aria-hidden': 'true' }),
        'r = 2l + 2mg/k·cos θ: beyond it the polar run is predicted to diverge')));

    this.form.addEventListener('submit', (event) => {
      event.preventDefault();
      this.run();
    });
    this.jobButton = root.querySelector('#em-run-job');
    this.jobButton.addEventListener('click', () => this.run({ asJob: true }));
    this.jsonButton.addEventListener('click', () => this.downloadJson());
    this.rrdButton.addEventListener('click', () => this.downloadRrd());
    this.pending = false;
    this.resize = new ResizeObserver(() => this.layout());
    this.resize.observe(this.root.querySelector('#em-results'));
    this.runButton.disabled = false;
    this.jobButton.disabled = false;
  }

  /** Fills the form with the request `body` (as `read` reads it). */
  fill(body) {
    const set = (id, value) => {
      if (value !== undefined && value !== null) this.root.querySelector(`#em-${id}`).value = String(value);
    };
    set('method', body.method);
    set('g', body.params?.g);
    set('h', body.h);
    set('t-max', body.t_max);
    set('nx', body.nx);
    set('ny', body.ny);
  }

  /** The request body the form describes (bad numbers as null: the API names them). */
  read() {
    const value = (id) => this.root.querySelector(`#em-${id}`).value;
    return {
      method: value('method'),
      params: { g: parseNumber(value('g')) },
      h: parseNumber(value('h')),
      t_max: parseNumber(value('t-max')),
      nx: parseCount(value('nx')),
      ny: parseCount(value('ny')),
    };
  }

  clearErrors() {
    for (const node of this.root.querySelectorAll('.field-error')) node.textContent = '';
    for (const node of this.root.querySelectorAll('[aria-invalid]')) node.removeAttribute('aria-invalid');
  }

  /** Shows an API error beside the input its field names (else above Run); returns the input. */
  showError(error) {
    const target = error instanceof ApiError && error.field ? this.fields.get(error.field) : null;
    const slot = target?.error || this.generalError;
    slot.textContent = error?.message || String(error);
    if (target?.input) target.input.setAttribute('aria-invalid', 'true');
    return target?.input || null;
  }

  /**
   * Computes the map of the form (a new run supersedes a running one); `asJob` submits it as a
   * job and draws the job's document when it is done.
   */
  async run({ asJob = false } = {}) {
    this.clearErrors();
    const body = this.read();
    const stream = asJob ? jobStream('energy-map') : energyMapStream;
    const { outcome, result: doc, error } = await this.runner.stream(stream, body);
    if (outcome === OUTCOME.superseded) return;
    if (outcome === OUTCOME.cancelled) {
      this.status.textContent = 'Cancelled; the map shown (if any) is the last one.';
      return;
    }
    if (outcome === OUTCOME.error) {
      const focus = this.showError(error);
      this.status.textContent = error instanceof ApiError
        ? `The server refused the map: ${error.message}`
        : `The map failed: ${error?.message || error}`;
      focus?.focus();
      return;
    }
    this.finish(body, doc);
  }

  /** Shows a done job's map: its request in the form and its document drawn. */
  show(body, doc) {
    this.runner.abort();
    this.clearErrors();
    this.fill(body);
    this.finish(body, doc);
  }

  /** Draws the map `doc` of the request `body`. */
  finish(body, doc) {
    this.last = { body, doc };
    this.runner.showProgress(doc.summary.cells, doc.summary.cells);
    this.render(doc);
    this.status.textContent = `Done: ${doc.xs.length} × ${doc.ys.length} cells of ${doc.method}, h = ${fmt(doc.h)}, ` +
      `t_max = ${fmt(doc.t_max)}: ${doc.steps.toLocaleString('en')} steps in ${fmt(doc.wall_ms / 1000, 3)} s.` +
      (doc.stop === 'time_limit'
        ? ` The server's time limit stopped ${doc.unfinished_cells.length} cells (left blank).`
        : '');
    this.runner.setState('done');
  }

  cancel() {
    this.runner.cancelPressed();
  }

  /** The last progress line of the last run (for tests). */
  get lastProgress() {
    return this.runner.lastProgress;
  }

  /** Draws the map of `doc` with its scale, readout and summary. */
  render(doc) {
    this.scaleBox.hidden = false;
    this.figure.hidden = false;
    this.summary.hidden = false;
    // A fresh canvas per map: the cursor's listeners belong to that map.
    const canvas = this.canvas.cloneNode(false);
    this.canvas.replaceWith(canvas);
    this.canvas = canvas;
    this.map = new EnergyMap(canvas, doc);
    this.cursor = null;
    bindCursor(this.map, { get: () => this.cursor, set: (cell) => this.setCursor(cell) });
    this.canvas.setAttribute('aria-label',
      `Energy-error map of ${doc.method}: ${doc.xs.length} x₀ values across, ${doc.ys.length} y₀ values downwards. ` +
      'Arrow keys move the cursor cell; the readout below gives its values.');
    this.readout.textContent = 'Point at the map, or focus it and use the arrow keys, to read a cell.';
    this.renderSummary(doc);
    this.jsonButton.disabled = false;
    this.rrdButton.disabled = false;
    this.layout();
  }

  renderSummary(doc) {
    const s = doc.summary;
    const item = (key, term, value, note = '') => [
      el('dt', { text: term }),
      el('dd', { 'data-count': key }, el('strong', { text: String(value) }), note),
    ];
    this.summary.replaceChildren(
      ...item('cells', 'cells', s.cells),
      ...item('cartesian_better', 'Cartesian more accurate', s.cartesian_better),
      ...item('polar_better', 'polar more accurate', s.polar_better),
      ...item('polar_diverged', 'polar run diverged', s.polar_diverged,
        ` (${s.diverged_outside_prediction} outside the predicted region)`),
      ...item('predicted_divergent', 'predicted to diverge', s.predicted_divergent),
      ...item('cartesian_diverged', 'Cartesian run diverged', s.cartesian_diverged),
    );
  }

  /** Moves the cursor to `cell` and reads it out. */
  setCursor(cell) {
    if (!this.map) return;
    this.cursor = cell;
    this.map.cursor = cell;
    this.map.draw();
    const v = this.map.cell(cell.col, cell.row);
    this.readout.textContent = readoutText(v);
    const text = (x) => (x == null ? '' : String(x));
    Object.assign(this.readout.dataset, {
      col: String(v.col), row: String(v.row), x: String(v.x), y: String(v.y),
      cartesian: text(v.cartesian), polar: text(v.polar), winner: text(v.winner),
      diverged: String(v.polarDivergedAt != null || v.cartesianDivergedAt != null),
    });
  }

  /** Redraws the map and the scale bar at the width of their boxes. */
  layout() {
    if (this.pending) return;
    this.pending = true;
    requestAnimationFrame(() => {
      this.pending = false;
      if (!this.map) return;
      this.map.resize();
      const range = this.map.range;
      const ticks = ratioTicks(range);
      drawScaleBar(this.scaleBar, {
        lo: -range,
        hi: range,
        colourAt: (e) => ratioColour(e, range),
        ticks,
        label: `Colour scale of ε(x,y)/ε(r,θ) on a log axis scaled to this map: from ${ticks[0][1]} to ${ticks[4][1]}, ` +
          `which holds ${Math.round(100 * RATIO_SHARE)} % of its cells (the others take the deepest colours). Blue where ` +
          'the Cartesian run is more accurate, white where the errors agree, red where the polar run is more accurate.',
      });
      this.scaleBar.dataset.range = String(range);
      this.root.querySelector('#em-scale-caption').textContent = `ε(x,y)/ε(r,θ), log scale scaled to this map's ` +
        `cells, symmetric about 1: from ${ticks[0][1]} (deepest blue: the Cartesian run more accurate) to ` +
        `${ticks[4][1]} (deepest red: the polar run more accurate), white where they agree; the range holds ` +
        `${Math.round(100 * RATIO_SHARE)} % of the cells, the rest take the deepest colours.`;
    });
  }

  downloadJson() {
    if (!this.last) return;
    const text = JSON.stringify({ request: this.last.body, ...this.last.doc });
    saveBlob(new Blob([text], { type: 'application/json' }), 'geomint-energy-map.json');
  }

  /** Saves the shown map as geomint-energy-map.rrd (the server computes and records it again). */
  downloadRrd() {
    if (!this.last) return null;
    const { body } = this.last;
    return downloadRecording({
      button: this.rrdButton, status: this.status, error: this.rrdError,
      name: 'geomint-energy-map.rrd', fetchBlob: () => energyMapRrd(body),
    });
  }
}
