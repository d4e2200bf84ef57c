// The work–precision section: a study spec (the body of POST /api/v1/studies/work-precision,
// editable JSON with a preset), run as an NDJSON stream with progress, drawn as a log–log
// diagram of wall time against the largest energy error — one line per method with its fitted
// slope — with a readout of the setting nearest the pointer, a table of every setting, and the
// study as a Rerun recording. The section's state is `data-wp-state` (idle, running, done, error).
//
// A timing on a shared machine is noisy. A server that repeats each setting (the request's
// `repeats`) sends every timing of a point, fastest first, as `timings_ms`, with `wall_ms` their
// median: the diagram then draws the median with a bar from the fastest to the slowest, and the
// panel says how many runs each dot is. From a server that times each setting once the dots are
// single runs, and the panel says that instead. The preset asks for repeats only from a server
// whose OpenAPI document offers them (an older one refuses the field).

import { workPrecisionStream, workPrecisionRrd, serverOffers } from './api.js';
import { downloadRecording, el, fmtError } from './common.js';
import { colour, LogLogPlot } from './charts.js';
import { StudyPanel } from './study-panel.js';

/** The preset: the elastic pendulum with weak damping, geometric compositions against RK4 and
 * the adaptive DOP853 (as in the long-horizon benchmark, at a shorter horizon). */
export const PRESET_STUDY = {
  system: 'elastic_pendulum_3d',
  params: { epsilon: 0.0001 },
  t_end: 2000,
  // The errors are measured at `samples` times, so every h must divide t_end/samples (here 40).
  samples: 50,
  runs: [
    { method: { id: 'kahan_li_8', base: 'modin_3s' }, h: [0.8, 0.4, 0.2, 0.1] },
    { method: { id: 'triple_jump', base: 'modin_3s' }, h: [0.2, 0.1, 0.05, 0.025] },
    { method: 'rk4', h: [0.1, 0.05, 0.025, 0.0125] },
    { method: 'reference', tolerance: [1e-7, 1e-9, 1e-11] },
  ],
};

/** Timings per setting that the preset asks for, where the server repeats them. */
const PRESET_REPEATS = 5;

const fmtSetting = (p) => (p.h != null ? `h = ${p.h}` : `tol = ${p.tolerance.toExponential(0)}`);

/** A point's timings: {median, fastest, slowest, runs}, from its `timings_ms` if it has them. */
export function timingsOf(p) {
  const all = p.timings_ms;
  if (!all?.length) return { median: p.wall_ms, fastest: p.wall_ms, slowest: p.wall_ms, runs: 1 };
  return { median: p.wall_ms, fastest: Math.min(...all), slowest: Math.max(...all), runs: all.length };
}

/** A point's time as the table and readout show it: the median, and the spread of repeats. */
function timeText(p) {
  const t = timingsOf(p);
  return t.runs > 1 ? `${t.median.toFixed(3)} (${t.fastest.toFixed(3)}–${t.slowest.toFixed(3)}, ${t.runs} runs)` : t.median.toFixed(3);
}

export class WorkPrecisionPanel extends StudyPanel {
  /** @param {HTMLElement} root the section */
  constructor(root) {
    super(root, 'wp', 'wpState', root.querySelector('#wp-download-rrd'), 'work-precision');
    this.spec.value = JSON.stringify(PRESET_STUDY, null, 2);
    this.timingNote = root.querySelector('#wp-timing');
    this.chart = new LogLogPlot(root.querySelector('#wp-plot'), 'max |energy error| over the samples',
      'wall time (ms)', (x, y) => this.hover(x, y));
  }

  /** Asks for repeated timings in the preset where the server offers them. */
  async init() {
    if (!(await serverOffers('WorkPrecisionRequest', 'repeats'))) return;
    if (this.spec.value !== JSON.stringify(PRESET_STUDY, null, 2)) return;
    const { runs, ...rest } = PRESET_STUDY;
    this.spec.value = JSON.stringify({ ...rest, repeats: PRESET_REPEATS, runs }, null, 2);
  }

  /** Says what a dot's time is: a median of repeated runs, or one run. */
  describeTimings(points) {
    const runs = [...new Set(points.map((p) => timingsOf(p).runs))].sort((a, b) => a - b);
    const repeated = runs.some((n) => n > 1);
    this.timingNote.dataset.runs = runs.join(',');
    this.timingNote.textContent = repeated
      ? `Each dot is the median wall time of ${runs.join(' or ')} timed runs of its setting; its bar spans the ` +
        'fastest to the slowest of them.'
      : 'Each dot is one timed run of its setting (this server times each setting once): on a busy machine ' +
        'a single timing can be far off, so read small differences with care.';
  }

  stream(body, onLine, signal) {
    return workPrecisionStream(body, onLine, signal);
  }

  describe(p) {
    return `${p.method} ${fmtSetting(p)} took ${timeText(p)} ms, max energy error ${fmtError(p.max_energy_error)}`;
  }

  /** Per run index: its label and its finished points with a positive error, by error. */
  series(points) {
    const runs = new Map();
    for (const p of points) {
      if (!runs.has(p.run)) runs.set(p.run, { label: p.method, points: [] });
      if (p.max_energy_error > 0 && p.wall_ms > 0) runs.get(p.run).points.push(p);
    }
    for (const r of runs.values()) r.points.sort((a, b) => a.max_energy_error - b.max_energy_error);
    return [...runs.entries()].sort((a, b) => a[0] - b[0]).map(([run, r]) => ({ run, ...r }));
  }

  /** Draws the diagram: one polyline with dots per method, log–log. */
  draw(points, result) {
    if (points.length) this.describeTimings(points);
    const runs = this.series(points);
    this.runs = runs;
    this.legend.replaceChildren(...runs.map((r) => {
      const fit = result?.fits.find((f) => f.run === r.run);
      const slope = fit?.slope == null ? '' : `: time ∝ error^${fit.slope.toFixed(3)}`;
      return el('li', { 'data-method': r.label },
        el('span', { class: 'swatch', style: `background:${colour(r.run)}`, 'aria-hidden': 'true' }),
        `${r.label}${slope}`);
    }));
    this.chart.show(runs.map((r) => ({
      label: r.label, colour: colour(r.run),
      xs: r.points.map((p) => p.max_energy_error), ys: r.points.map((p) => p.wall_ms),
      lows: r.points.map((p) => timingsOf(p).fastest), highs: r.points.map((p) => timingsOf(p).slowest),
    })));
  }

  /** The uPlot instance of the diagram (for tests). */
  get plot() {
    return this.chart.plot;
  }

  /** The readout: the setting nearest to (x, y) in CSS pixels of the plot area, within 24 px. */
  hover(x, y) {
    const near = this.chart.nearest(x, y);
    if (!near) return;
    const p = this.runs[near.series].points[near.index];
    this.readout.textContent = `${p.method} ${fmtSetting(p)}: ${timeText(p)} ms, ` +
      `${p.force_evaluations} force evaluations, max energy error ${fmtError(p.max_energy_error)}, ` +
      `final state error ${fmtError(p.final_state_error)}`;
    Object.assign(this.readout.dataset, { method: p.method, setting: fmtSetting(p) });
  }

  renderTable(result) {
    const drift = (p) => Object.entries(p.invariant_drift).map(([k, v]) => `${k} ${v.toExponential(1)}`).join(', ') || '—';
    this.table.replaceChildren(...result.points.map((p) => el('tr', {},
      el('td', { text: p.method }), el('td', { text: fmtSetting(p) }),
      el('td', { class: 'num', text: timeText(p) }), el('td', { class: 'num', text: String(p.force_evaluations) }),
      el('td', { class: 'num', text: fmtError(p.max_energy_error) }), el('td', { class: 'num', text: fmtError(p.final_state_error) }),
      el('td', { text: drift(p) }), el('td', { text: p.stop }))));
  }

  /** Saves the study as geomint-work-precision.rrd (the server runs and records it again). */
  download() {
    if (!this.last?.body) return null;
    const { body } = this.last;
    return downloadRecording({
      button: this.downloadButton, status: this.status, error: this.error,
      name: 'geomint-work-precision.rrd', fetchBlob: () => workPrecisionRrd(body),
    });
  }
}
