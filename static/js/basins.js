// The basins section: a basin-map request edited as JSON (or loaded from the server's presets),
// run through POST /api/v1/studies/basins as an NDJSON stream with a progress bar and Cancel
// (study-stream.js); the answer drawn as a map of labels (a GridMap of heatmap.js) with one colour
// per attractor and undecided cells (label −1) grey with a white hatch; a legend naming each
// attractor, its kind and its share, and the undecided cells with their reasons; beside the map the
// metrics (basin entropy S_b, boundary basin entropy S_bb, the uncertainty exponent α and the
// fractions it was fitted to, how many cells each criterion decided). A readout gives the label and
// the decision time of the cell under the pointer (or the keyboard cursor). A click on a cell (or
// Enter on the cursor) runs that cell's orbit through POST /api/v1/simulate — to the time its
// outcome was decided, or to t_end — and draws it over the map in the map's plane.
// The section's state is `data-basins-state` (idle, running, done, cancelled, error), the orbit's
// `data-orbit-state` on #ba-orbit (idle, running, done, error), for tests.

import { ApiError, basinsPresets, basinsStream, simulateJson } from './api.js';
import { StudyStream, OUTCOME, showRequest } from './study-stream.js';
import { jobStream } from './jobs.js';
import { el, fmt, plural } from './common.js';
import { GridMap, bindCursor } from './heatmap.js';
import { stateNames } from './phasespace.js';
import { trueAspect } from './sweep.js';

/** One colour per attractor, by label (no grey: that is the undecided cells'). */
export const BASIN_COLOURS = [
  [0, 114, 178], [213, 94, 0], [0, 158, 115], [204, 121, 167], [230, 159, 0], [86, 180, 233],
  [136, 34, 85], [68, 170, 153], [153, 153, 51], [51, 34, 136], [17, 119, 51], [221, 204, 119],
];
/** The colour of an undecided cell (label −1), under a white hatch. */
export const UNDECIDED_RGB = [150, 150, 150];
/** The readout before a cell is chosen. */
const READOUT_PROMPT = 'Point at the map, or focus it and use the arrow keys, to read a cell; click (or Enter) to draw its orbit.';
/** A component of the initial state (`q0[1]`, `p0[0]`). */
const STATE_AXIS = /^([qp])0\[(\d+)\]$/;
/** The core's words for a start off the energy surface. */
const OUTSIDE_SURFACE = /no state here has H = /;
/** The most samples an orbit drawn over the map asks for. */
const ORBIT_SAMPLES = 4000;

/** The colour of `label` (−1: undecided). */
export function basinColour(label) {
  return label < 0 ? UNDECIDED_RGB : BASIN_COLOURS[label % BASIN_COLOURS.length];
}

/** Whether an equilibrium is a minimum of V (its Hessian's eigenvalues all positive). */
const isMinimum = (a) => a.equilibrium?.hessian_eigenvalues.every((e) => e > 0);

/** What an attractor is, in a few words: its kind and what it means. */
function kindText(a) {
  switch (a.kind) {
    case 'equilibrium': return isMinimum(a) ? 'equilibrium: the damped orbits settle here' : 'equilibrium: only a start on it stays there';
    case 'well': return 'well: below the lowest saddle the orbits stay in it';
    case 'periodic': return `periodic orbit of period ${a.period ?? '?'} on the stroboscopic map`;
    case 'exit': return 'exit: the orbits leave through it';
    case 'diverged': return 'diverged to infinity';
    case 'stayed': return 'stayed inside until t_end';
    case 'given': return `the request's attractor: orbits that come within ${fmt(a.radius, 3)} of it end there`;
    default: return a.kind;
  }
}

/** A percentage with three significant figures. */
const percent = (share) => `${fmt(100 * share, 3)} %`;

/** A point or vector as `(a, b)`, round-off below 1e-12 shown as 0 (a critical point found by Newton). */
const tuple = (xs) => {
  const text = (x) => fmt(Math.abs(x) < 1e-12 ? 0 : x, 4);
  return xs.length === 1 ? text(xs[0]) : `(${xs.map(text).join(', ')})`;
};

/** Each attractor's name by its label (the server names each one uniquely). */
export function attractorNames(attractors) {
  return new Map(attractors.map((a) => [a.label, a.name]));
}

/**
 * The undecided cells' reasons grouped by their wording with the numbers left out (a start off the
 * energy surface gives each cell its own bound): [{reason (the first cell's), cells, outside}].
 */
export function reasonGroups(undecided) {
  const groups = new Map();
  for (const { reason } of undecided) {
    const key = reason.replace(/-?\d+(\.\d+)?(e[-+]?\d+)?/g, '#');
    const group = groups.get(key) ?? { reason, cells: 0, outside: OUTSIDE_SURFACE.test(reason) };
    group.cells += 1;
    groups.set(key, group);
  }
  return [...groups.values()].sort((a, b) => b.cells - a.cells);
}

/** The map of one run's labels. */
class BasinMap extends GridMap {
  constructor(canvas, doc, run, labelOf) {
    const axis = (a) => ({ min: a.min, max: a.max, n: a.n, label: labelOf(a.name) });
    const second = doc.axes[1] || { name: '', min: 0, max: 0, n: 1 };
    super(canvas, {
      x: axis(doc.axes[0]), y: axis(second), colour: (c, r) => basinColour(run.labels[r * doc.axes[0].n + c]),
      aspect: trueAspect(doc.axes),
    });
    this.undecidedCells = run.labels.map((label, k) => (label < 0 ? k : -1)).filter((k) => k >= 0);
    /** The orbit drawn over the map, in cell units, or null. */
    this.orbit = null;
  }

  /** A white hatch over each undecided cell, then the orbit of the last clicked cell. */
  drawOverlay(ctx) {
    const n = this.cols;
    const hatch = this.undecidedCells.map((k) => {
      const c = k % n;
      const r = Math.floor(k / n);
      return [[c, r], [c + 1, r + 1]];
    });
    this.strokeLines(ctx, hatch, { colour: '#ffffff', width: 1 });
    if (!this.orbit?.length) return;
    this.strokeLines(ctx, [this.orbit], { colour: '#ffffff', width: 3.5, cap: 'round' });
    this.strokeLines(ctx, [this.orbit], { colour: '#111111', width: 1.5, cap: 'round' });
    const [x, y] = this.px(...this.orbit[0]);
    ctx.beginPath();
    ctx.arc(x, y, 4, 0, 2 * Math.PI);
    ctx.fillStyle = '#ffffff';
    ctx.fill();
    ctx.lineWidth = 2;
    ctx.strokeStyle = '#111111';
    ctx.stroke();
  }
}

/** The basins section. */
export class BasinsPanel {
  /**
   * @param {HTMLElement} root the section
   * @param {object[]} [systems] the system catalogue, for the names of the initial state's components
   */
  constructor(root, systems = []) {
    this.root = root;
    this.systems = systems;
    const $ = (id) => root.querySelector(`#ba-${id}`);
    Object.assign(this, {
      spec: $('spec'), presetSelect: $('preset'), runButton: $('run'), progress: $('progress'),
      status: $('status'), view: $('view'), runSelect: $('run-select'), figure: $('figure'),
      canvas: $('canvas'), readout: $('readout'), legend: $('legend'), reasons: $('reasons'),
      metrics: $('metrics'), orbitNote: $('orbit'), error: root.querySelector('#err-ba-spec'),
    });
    this.presets = [];
    /** The last map: {body, doc}. */
    this.last = null;
    this.map = null;
    this.cursor = null;
    /** The orbit on show: {cell, run, points (cell units, or null off the map's plane), answer}, or null. */
    this.orbit = null;
    this.orbitController = null;
    this.runner = new StudyStream({
      root, stateKey: 'basinsState', progress: this.progress, status: this.status, cancel: $('cancel'),
    });
    $('form').addEventListener('submit', (event) => {
      event.preventDefault();
      this.run();
    });
    this.jobButton = $('run-job');
    this.jobButton.addEventListener('click', () => this.run({ asJob: true }));
    this.presetSelect.addEventListener('change', () => this.loadPreset(this.presetSelect.value));
    this.runSelect.addEventListener('change', () => {
      this.clearOrbit();
      this.redraw();
    });
    new ResizeObserver(() => this.layout()).observe($('results'));
  }

  /** Fetches the presets and shows the first. */
  async init() {
    this.presets = await basinsPresets();
    this.presetSelect.replaceChildren(...this.presets.map((p) => el('option', { value: p.id, text: p.title })));
    this.loadPreset(this.presets[0]?.id);
    this.runButton.disabled = false;
    this.jobButton.disabled = false;
  }

  loadPreset(id) {
    const preset = this.presets.find((p) => p.id === id);
    if (preset) this.spec.value = JSON.stringify(preset.request, null, 2);
  }

  /** The last progress line of the last map (for tests). */
  get lastProgress() {
    return this.runner.lastProgress;
  }

  /** The run on show. */
  get currentRun() {
    return this.last?.doc.runs[Number(this.runSelect.value) || 0];
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
    const stream = asJob ? jobStream('basins') : basinsStream;
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
      this.status.textContent = 'The server refused the basin map.';
      this.spec.focus();
      return;
    }
    this.finish(body, doc);
  }

  /** Shows a done job's basin map: its request in the text box and its document drawn. */
  show(body, doc) {
    showRequest(this, body);
    this.finish(body, doc);
  }

  /** Draws the basin map `doc` of the request `body`. */
  finish(body, doc) {
    this.last = { body, doc };
    this.runner.showProgress(doc.cells, doc.cells);
    this.runSelect.replaceChildren(...doc.runs.map((r, i) => el('option', { value: String(i), text: `${r.label.method} (${r.label.chart})` })));
    this.view.hidden = doc.runs.length < 2;
    this.figure.hidden = false;
    this.cursor = null;
    this.clearOrbit();
    this.readout.textContent = READOUT_PROMPT;
    for (const key of Object.keys(this.readout.dataset)) delete this.readout.dataset[key];
    const steps = doc.runs.reduce((sum, r) => sum + (r.steps ?? 0), 0);
    this.status.textContent = `Done: ${plural(doc.cells, 'cell')} × ${plural(doc.runs.length, 'run')}, ` +
      `${steps.toLocaleString('en')} steps in ${fmt(doc.wall_ms / 1000, 3)} s.` +
      (doc.stop === 'time_limit' ? ` The server's time limit stopped ${doc.unfinished_cells.length} cells.` : '');
    this.redraw();
    this.runner.setState('done');
  }

  /** The names of the initial state's components in the map's system. */
  stateNamesOf() {
    const system = this.last.body.system;
    const names = stateNames(system, this.systems);
    const chartId = this.currentRun?.label.chart;
    if (typeof system === 'string' && this.last.body.initial_coordinates !== 'cartesian') {
      const chart = this.systems.find((x) => x.id === system)?.charts?.find((c) => c.id === chartId);
      if (chart?.coordinates) return { coordinates: chart.coordinates, momenta: chart.coordinates.map((c) => `p_${c}`) };
    }
    return names;
  }

  /** An axis's label: `y (q0[1])` for a component of the initial state, else its name. */
  axisLabel(name) {
    const m = STATE_AXIS.exec(name);
    if (!m || !this.last) return name;
    const names = this.stateNamesOf();
    const word = (m[1] === 'q' ? names.coordinates : names.momenta)[Number(m[2])];
    return word ? `${word} (${name})` : name;
  }

  /** Draws the run on show: map, legend, reasons and metrics. */
  redraw() {
    if (!this.last) return;
    const { doc } = this.last;
    const run = this.currentRun;
    const canvas = this.canvas.cloneNode(false);
    canvas.style.width = '';
    this.canvas.replaceWith(canvas);
    this.canvas = canvas;
    this.map = new BasinMap(canvas, doc, run, (name) => this.axisLabel(name));
    this.map.orbit = this.orbit?.run === run ? this.orbit.points : null;
    bindCursor(this.map, { get: () => this.cursor, set: (cell) => this.setCursor(cell) });
    canvas.addEventListener('click', (event) => {
      const cell = this.map.cellAt(event.offsetX, event.offsetY);
      if (cell) this.showOrbit(cell);
    });
    canvas.addEventListener('keydown', (event) => {
      if (event.key === 'Enter' && this.cursor) this.showOrbit(this.cursor);
    });
    const names = attractorNames(run.attractors);
    canvas.setAttribute('aria-label', `Basin map: ${this.axisLabel(doc.axes[0].name)} across` +
      `${doc.axes[1] ? `, ${this.axisLabel(doc.axes[1].name)} upwards` : ''}; ` +
      `${run.attractors.map((a) => `${names.get(a.label)} ${percent(run.fractions[a.label])}`).join(', ')}` +
      `${run.undecided.length ? `, undecided ${percent(run.undecided_fraction)}` : ''}. Arrow keys move the cursor cell; Enter draws its orbit.`);
    this.renderLegend(run, names);
    this.renderReasons(run);
    this.renderMetrics(doc, run);
    if (this.cursor && (this.cursor.col >= this.map.cols || this.cursor.row >= this.map.rows)) this.cursor = null;
    if (this.cursor) this.setCursor(this.cursor);
    this.layout();
  }

  /** One entry per attractor (colour, name, kind, share, cells, where), and one for the undecided cells. */
  renderLegend(run, names) {
    const swatch = (label) => el('span', {
      class: 'swatch block', 'aria-hidden': 'true',
      style: label < 0
        ? `background: repeating-linear-gradient(45deg, rgb(${UNDECIDED_RGB.join(',')}) 0 3px, #fff 3px 4px)`
        : `background: rgb(${basinColour(label).join(',')})`,
    });
    const { coordinates } = this.stateNamesOf();
    const q = coordinates.length === 1 ? coordinates[0] : coordinates.length ? `(${coordinates.join(', ')})` : 'q';
    const where = (a) => {
      if (a.equilibrium) return `at ${q} = ${tuple(a.equilibrium.q)}, V = ${tuple([a.equilibrium.energy])}`;
      const point = a.kind === 'given' ? 'point' : 'stroboscopic point';
      if (a.points?.length) return `${point}${a.points.length > 1 ? 's' : ''} ${a.points.map(tuple).join(', ')}`;
      return '';
    };
    const items = run.attractors.map((a) => el('li', { 'data-label': String(a.label), 'data-kind': a.kind },
      swatch(a.label),
      el('span', {},
        el('strong', { class: 'attractor-name', text: names.get(a.label) }),
        ` — ${kindText(a)}; `,
        el('span', { class: 'share', text: percent(run.fractions[a.label]) }),
        ` (${plural(a.cells, 'cell')})`,
        where(a) ? el('small', { text: where(a) }) : null)));
    if (run.undecided.length) {
      items.push(el('li', { 'data-label': '-1', 'data-kind': 'undecided' }, swatch(-1),
        el('span', {}, el('strong', { class: 'attractor-name', text: 'undecided' }),
          ' — no criterion decided these cells (reasons below); ',
          el('span', { class: 'share', text: percent(run.undecided_fraction) }),
          ` (${plural(run.undecided.length, 'cell')})`)));
    }
    this.legend.replaceChildren(...items);
  }

  /** The undecided cells' reasons, grouped. */
  renderReasons(run) {
    const groups = reasonGroups(run.undecided);
    this.reasons.hidden = !groups.length;
    this.reasons.replaceChildren(
      el('h4', { text: `Why ${plural(run.undecided.length, 'cell is', 'cells are')} undecided` }),
      el('ul', {}, groups.map((g) => el('li', { 'data-cells': String(g.cells) },
        el('strong', { text: `${plural(g.cells, 'cell')}: ` }),
        g.outside ? 'the start is off the energy surface, so no orbit starts there — ' : '',
        el('q', { text: g.reason }),
        g.cells > 1 ? ` (the first such cell's words; the others differ only in their numbers)` : ''))));
  }

  /** The metrics beside the map. */
  renderMetrics(doc, run) {
    const row = (key, term, value, note = '') => [
      el('dt', { text: term }),
      el('dd', { 'data-metric': key }, el('strong', { text: value }), note ? el('small', { text: note }) : null),
    ];
    const ln2 = Math.log(2);
    const bb = run.boundary_basin_entropy;
    const decided = Object.entries(run.decided_by).filter(([, n]) => n > 0).map(([how, n]) => `${how} ${n}`).join(', ');
    const fractions = (run.uncertain_fractions ?? []).map((f) => `f(${f.epsilon_cells}) = ${fmt(f.fraction, 3)}`).join(', ');
    this.metrics.replaceChildren(
      ...row('basin_entropy', 'Basin entropy S_b', fmt(run.basin_entropy, 4), `over ${plural(run.boxes, 'box', 'boxes')} of 5 × 5 cells`),
      ...row('boundary_basin_entropy', 'Boundary basin entropy S_bb', fmt(bb, 4),
        bb > ln2 ? `> ln 2 = ${fmt(ln2, 4)}: the boundary is fractal` : `≤ ln 2 = ${fmt(ln2, 4)}: this test cannot tell whether the boundary is fractal`),
      ...row('uncertainty_exponent', 'Uncertainty exponent α', fmt(run.uncertainty_exponent, 3),
        `fitted to f(ε), the share of cells with another label ε cells away${fractions ? ` (${fractions})` : ''}; near 0: a fractal boundary, 1: a smooth one`),
      // The Wada test needs three basins at least; the document gives no shares otherwise.
      ...((run.wada ?? []).length ? row('wada', 'Wada test W_k',
        run.wada.map((w) => `${run.attractors[w.label]?.name ?? `label ${w.label}`} ${fmt(w.share, 3)}`).join(', '),
        'per basin k, the share of the boundary within a cell of k\'s boundary against the rest merged; all near 1: a Wada boundary at this resolution') : []),
      ...row('decided_by', 'Decided by', decided || '—', '(cells per criterion)'),
      // A driven system has no critical points searched (`equilibria` null): nothing to say.
      ...(doc.equilibria ? row('lowest_saddle_energy', 'Lowest saddle', doc.lowest_saddle_energy == null ? 'none found' : `E = ${fmt(doc.lowest_saddle_energy, 6)}`,
        `(${plural(doc.equilibria.length, 'critical point')} of V)`) : []),
      ...row('steps', 'Steps', (run.steps ?? 0).toLocaleString('en'), '(each cell stops once decided)'),
    );
  }

  /** Moves the cursor to `cell` and says its label and decision time. */
  setCursor(cell) {
    if (!this.map) return;
    this.cursor = cell;
    this.map.cursor = cell;
    this.map.draw();
    const { doc } = this.last;
    const run = this.currentRun;
    const k = cell.row * doc.axes[0].n + cell.col;
    const label = run.labels[k];
    const decidedAt = run.decided_at[k];
    const name = label < 0 ? 'undecided' : attractorNames(run.attractors).get(label);
    const attractor = run.attractors.find((a) => a.label === label);
    let text = `${this.where(cell)}: `;
    if (label < 0) {
      const reason = run.undecided.find((u) => u.cell === k)?.reason ?? 'no reason given';
      text += `undecided — ${reason}`;
    } else {
      text += `${name} — ${attractor.kind}, decided at t = ${fmt(decidedAt, 4)}`;
    }
    this.readout.textContent = `${text}.`;
    Object.assign(this.readout.dataset, {
      col: String(cell.col), row: String(cell.row), cell: String(k), label: String(label),
      name, decidedAt: decidedAt == null ? '' : String(decidedAt),
    });
  }

  /** Where `cell` is: `x = 0.5, p_x = −1`. */
  where(cell) {
    return this.last.doc.axes.map((a, i) => {
      const label = this.axisLabel(a.name);
      return `${STATE_AXIS.test(a.name) ? label.split(' (')[0] : label} = ${fmt(a.values[i === 0 ? cell.col : cell.row])}`;
    }).join(', ');
  }

  /** The simulation request of `cell`'s orbit: its start, the run's method, to its decision time. */
  orbitRequest(cell) {
    const { body, doc } = this.last;
    const index = Number(this.runSelect.value) || 0;
    const run = this.currentRun;
    const k = cell.row * doc.axes[0].n + cell.col;
    const names = stateNames(body.system, this.systems);
    const dimension = Math.max(names.coordinates.length, body.q0?.length ?? 0, doc.equilibria?.[0]?.q.length ?? 0, 1);
    const q0 = [...(body.q0 ?? [])];
    const p0 = [...(body.p0 ?? [])];
    while (q0.length < dimension) q0.push(0);
    while (p0.length < dimension) p0.push(0);
    doc.axes.forEach((a, i) => {
      const m = STATE_AXIS.exec(a.name);
      if (m) (m[1] === 'q' ? q0 : p0)[Number(m[2])] = a.values[i === 0 ? cell.col : cell.row];
    });
    const decided = run.decided_at[k];
    const steps = Math.max(1, Math.ceil((decided ?? body.t_end) / body.h - 1e-9));
    const request = {
      system: body.system, method: body.methods[index], h: body.h, t_end: steps * body.h, q0, p0,
      output: { every: Math.max(1, Math.ceil(steps / ORBIT_SAMPLES)) },
    };
    for (const key of ['params', 'chart', 'initial_coordinates']) if (body[key] !== undefined) request[key] = body[key];
    if (run.label.chart && !request.chart) request.chart = run.label.chart;
    const surface = body.energy_surface;
    if (surface) {
      const m = STATE_AXIS.exec(surface.solve_for ?? '');
      const momentum = m && m[1] === 'p' ? names.momenta[Number(m[2])] : surface.solve_for;
      request.energy = { value: surface.energy, momentum };
    }
    return { request, k, run };
  }

  /** Runs and draws the orbit of `cell` over the map. */
  async showOrbit(cell) {
    if (!this.last) return;
    const { request, k, run } = this.orbitRequest(cell);
    this.orbitController?.abort();
    const controller = new AbortController();
    this.orbitController = controller;
    const note = this.orbitNote;
    note.hidden = false;
    note.dataset.orbitState = 'running';
    note.dataset.cell = String(k);
    note.textContent = `Running the orbit from ${this.where(cell)} to t = ${fmt(request.t_end, 4)}…`;
    let answer;
    try {
      answer = await simulateJson(request, controller.signal);
    } catch (error) {
      if (controller !== this.orbitController) return;
      note.dataset.orbitState = 'error';
      note.textContent = `The orbit from ${this.where(cell)} could not run: ${error?.message || error}`;
      return;
    }
    if (controller !== this.orbitController) return;
    const samples = answer.runs[0];
    const component = (name) => {
      const m = STATE_AXIS.exec(name);
      return m ? (i) => samples[m[1]][i][Number(m[2])] : null;
    };
    const [ax, ay] = this.last.doc.axes;
    const fx = component(ax.name);
    const fy = ay ? component(ay.name) : null;
    const points = fx && fy ? samples.t.map((_, i) => this.map.cellUnits(fx(i), fy(i))) : null;
    this.orbit = { cell: k, run, points, answer };
    if (this.map) {
      this.map.orbit = points;
      this.map.draw();
    }
    const last = samples.t.length - 1;
    const label = run.labels[k];
    const name = label < 0 ? 'undecided' : attractorNames(run.attractors).get(label);
    note.dataset.orbitState = 'done';
    note.dataset.samples = String(samples.t.length);
    const start = this.last.body.energy_surface ? ` (q = ${tuple(answer.system.q0)}, p = ${tuple(answer.system.p0)} on the energy surface)` : '';
    note.textContent = `Orbit from ${this.where(cell)}${start}, ` +
      `${samples.method} to t = ${fmt(samples.t[last], 4)}: ends at q = ${tuple(samples.q[last])}, p = ${tuple(samples.p[last])}; ` +
      `the map says ${name}${run.decided_at[k] == null ? '' : `, decided at t = ${fmt(run.decided_at[k], 4)}`}.` +
      (points ? ' Drawn over the map in its plane (white dot: the start).' : '');
  }

  /** Takes the orbit off the map. */
  clearOrbit() {
    this.orbitController?.abort();
    this.orbitController = null;
    this.orbit = null;
    this.orbitNote.hidden = true;
    this.orbitNote.textContent = '';
    this.orbitNote.dataset.orbitState = 'idle';
    if (this.map) this.map.orbit = null;
  }

  layout() {
    if (!this.map || this.pending) return;
    this.pending = true;
    requestAnimationFrame(() => {
      this.pending = false;
      this.map.resize();
    });
  }
}
