// The convergence section: a study spec (the body of POST /api/v1/studies/convergence, editable
// JSON, with presets from paper 001), run as an NDJSON stream with progress, drawn as a log–log
// plot of the error at t_end against the step size h — one line per method and chart, its fitted
// order in the legend — for the error chosen (the state error in Cartesian coordinates, the
// energy error at t_end, or the largest energy error over the samples), with a readout of the
// setting nearest the pointer, a table of every setting, and the result as a JSON download. The
// section's state is `data-cv-state` (idle, running, done, error).

import { convergenceStream } from './api.js';
import { colour, LogLogPlot } from './charts.js';
import { StudyPanel } from './study-panel.js';
import { el, fmtError, saveBlob, sizeText } from './common.js';

/** The errors a study measures: the point's field, the series' fit, the axis label. */
export const ERRORS = {
  state_error: { fit: 'state', label: 'state error at t_end (Cartesian)' },
  energy_error: { fit: 'energy', label: '|energy error| at t_end' },
  max_energy_error: { fit: 'max_energy', label: 'max |energy error| over the samples' },
};

/** Step sizes from `h` down by halves, `n` of them. */
const halving = (h, n) => Array.from({ length: n }, (_, k) => h / 2 ** k);

/** The presets: a spec and the error that shows its point. */
export const PRESETS = [
  {
    id: 'fig9', label: '001 Fig. 9', error: 'max_energy_error',
    note: 'Symplectic Euler on the harmonic oscillator: first order in energy in Cartesian coordinates, second order in the compensating chart (eq. 82).',
    spec: {
      system: 'harmonic_oscillator', params: { omega: 1, gamma: 0 }, charts: ['cartesian', 'compensating'],
      q0: [1], p0: [0], t_end: 10, methods: ['symplectic_euler'], h: halving(0.04, 6),
    },
  },
  {
    id: 'sec23', label: '001 Sec. 2.3', error: 'state_error',
    note: 'Explicit Euler on y′ = −y: first order in y, exact (to round-off, no order) in the transformed variable ȳ = ln y.',
    spec: {
      system: 'exponential_decay', params: { alpha: 1 }, charts: ['original', 'transformed'],
      q0: [1], p0: [0], t_end: 3, methods: ['explicit_euler'], h: halving(0.3, 5),
    },
  },
  {
    id: 'damped', label: 'Damped oscillator', error: 'state_error',
    note: 'RK4, the composition triple_jump(csv1) and csv1 against the exact solution: orders 4, 4 and 2.',
    spec: {
      system: 'harmonic_oscillator', params: { omega: 2, gamma: 0.1 }, q0: [1], p0: [0], t_end: 10,
      methods: ['rk4', { id: 'triple_jump', base: 'csv1' }, 'csv1'], h: halving(0.1, 5),
    },
  },
  {
    id: 'polar', label: 'Elastic pendulum, two charts', error: 'state_error',
    note: 'The implicit midpoint rule and symplectic Euler in Cartesian and polar coordinates against the DOP853 reference.',
    spec: {
      system: 'elastic_pendulum_2d', charts: ['cartesian', 'polar'], t_end: 4,
      methods: ['implicit_midpoint', 'symplectic_euler'], h: halving(0.1, 4),
    },
  },
];

/** A series' label while its study streams (the result gives the same). */
function seriesLabel(point, body) {
  return (body?.charts?.length ?? 0) > 1 ? `${point.method} [${point.chart}]` : point.method;
}

export class ConvergencePanel extends StudyPanel {
  /** @param {HTMLElement} root the section */
  constructor(root) {
    super(root, 'cv', 'cvState', root.querySelector('#cv-download-json'), 'convergence');
    this.errorChoice = root.querySelector('#cv-error');
    this.note = root.querySelector('#cv-note');
    this.chart = new LogLogPlot(root.querySelector('#cv-plot'), 'step size h', ERRORS.state_error.label,
      (x, y) => this.hover(x, y));
    this.errorChoice.addEventListener('change', () => this.redraw());
    root.querySelector('#cv-presets').replaceChildren(...PRESETS.map((p) => el('button', {
      type: 'button', class: 'secondary small', 'data-cv-preset': p.id, title: p.note,
      onclick: () => this.usePreset(p.id, true),
    }, p.label)));
    this.usePreset(PRESETS[0].id, false);
  }

  /** Fills the spec and the error choice from preset `id`, and runs it when `run`. */
  usePreset(id, run) {
    const preset = PRESETS.find((p) => p.id === id);
    this.spec.value = JSON.stringify(preset.spec, null, 2);
    this.errorChoice.value = preset.error;
    this.note.textContent = preset.note;
    if (run) this.run();
  }

  /** The error plotted: a key of ERRORS. */
  get errorKey() {
    return this.errorChoice.value;
  }

  stream(body, onLine, signal) {
    return convergenceStream(body, onLine, signal);
  }

  describe(p) {
    return `${seriesLabel(p, this.last?.body)} h = ${p.h}: state error ${fmtError(p.state_error)}, ` +
      `energy error ${fmtError(p.energy_error)}, max ${fmtError(p.max_energy_error)}`;
  }

  /** Per series: its label and its points with a positive error of the chosen kind, by h. */
  series(points, result) {
    const key = this.errorKey;
    const all = new Map();
    for (const p of points) {
      if (!all.has(p.series)) {
        all.set(p.series, { label: result?.series[p.series].label ?? seriesLabel(p, this.last?.body), points: [] });
      }
      const e = p[key];
      if (e > 0 && Number.isFinite(e)) all.get(p.series).points.push(p);
    }
    for (const s of all.values()) s.points.sort((a, b) => a.h - b.h);
    return [...all.entries()].sort((a, b) => a[0] - b[0]).map(([index, s]) => ({ index, ...s }));
  }

  /** Draws the plot of the chosen error against h, with the fitted orders in the legend. */
  draw(points, result) {
    const key = this.errorKey;
    const fitKey = ERRORS[key].fit;
    const series = this.series(points, result);
    this.shown = series;
    this.legend.replaceChildren(...series.map((s) => {
      const fit = result?.series[s.index][fitKey];
      let order = '';
      if (fit) order = fit.order == null ? ': no order (errors at round-off)' : `: order ${fit.order.toFixed(2)}`;
      return el('li', { 'data-series': s.label },
        el('span', { class: 'swatch', style: `background:${colour(s.index)}`, 'aria-hidden': 'true' }),
        `${s.label}${order}`);
    }));
    if (this.chart.yLabel !== ERRORS[key].label) {
      // A new axis label needs a new plot.
      this.chart.yLabel = ERRORS[key].label;
      this.chart.show([]);
    }
    this.chart.show(series.map((s) => ({
      label: s.label, colour: colour(s.index), xs: s.points.map((p) => p.h), ys: s.points.map((p) => p[key]),
    })));
  }

  /** Draws the last study again (another error chosen). */
  redraw() {
    if (this.last) this.draw(this.last.result?.points ?? this.last.points, this.last.result);
  }

  /** The uPlot instance of the plot (for tests). */
  get plot() {
    return this.chart.plot;
  }

  /** The readout: the setting nearest to (x, y) in CSS pixels of the plot area, within 24 px. */
  hover(x, y) {
    const near = this.chart.nearest(x, y);
    if (!near) return;
    const s = this.shown[near.series];
    const p = s.points[near.index];
    this.readout.textContent = `${s.label}, h = ${p.h} (${p.steps} steps): state error ${fmtError(p.state_error)}, ` +
      `energy error at t_end ${fmtError(p.energy_error)}, max energy error ${fmtError(p.max_energy_error)}`;
    Object.assign(this.readout.dataset, { series: s.label, h: String(p.h) });
  }

  renderTable(result) {
    this.table.replaceChildren(...result.points.map((p) => el('tr', {},
      el('td', { text: p.method }), el('td', { text: p.chart }), el('td', { class: 'num', text: String(p.h) }),
      el('td', { class: 'num', text: String(p.steps) }), el('td', { class: 'num', text: fmtError(p.state_error) }),
      el('td', { class: 'num', text: fmtError(p.energy_error) }), el('td', { class: 'num', text: fmtError(p.max_energy_error) }),
      el('td', { text: p.stop }))));
  }

  /** Saves the result (the answer of the JSON route) as a file. */
  download() {
    const result = this.last?.result;
    if (!result) return;
    const { type: _line, ...doc } = result;
    const blob = new Blob([JSON.stringify(doc, null, 2)], { type: 'application/json' });
    const name = `geomint-convergence-${doc.system.id}.json`;
    saveBlob(blob, name);
    this.status.textContent = `Saved ${name} (${sizeText(blob.size)}).`;
  }
}
