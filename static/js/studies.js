// The work–precision section: a study spec (the body of POST /api/v1/studies/work-precision,
// editable JSON with a preset), run as an NDJSON stream with progress, drawn as a log–log
// diagram of wall time against the largest energy error — one line per method with its fitted
// slope — with a readout of the setting nearest the pointer, a table of every setting, and the
// study as a Rerun recording. The section's state is `data-wp-state` (idle, running, done, error).
// StudyPanel is what it shares with the convergence section (convergence.js).

import { workPrecisionStream, workPrecisionRrd, ApiError } from './api.js';
import { el } from './form.js';
import { colour, LogLogPlot } from './charts.js';
import { saveBlob, sizeText } from './rerun.js';

/** The preset: the elastic pendulum with weak damping, geometric compositions against RK4 and
 * the adaptive DOP853 (as in the long-horizon benchmark, at a shorter horizon). */
export const PRESET_STUDY = {
  system: 'elastic_pendulum_3d',
  params: { epsilon: 0.0001 },
  t_end: 2000,
  runs: [
    { method: { id: 'kahan_li_8', base: 'modin_3s' }, h: [0.8, 0.4, 0.2, 0.1] },
    { method: { id: 'triple_jump', base: 'modin_3s' }, h: [0.2, 0.1, 0.05, 0.025] },
    { method: 'rk4', h: [0.1, 0.05, 0.025, 0.0125] },
    { method: 'reference', tolerance: [1e-7, 1e-9, 1e-11] },
  ],
};

const fmtSetting = (p) => (p.h != null ? `h = ${p.h}` : `tol = ${p.tolerance.toExponential(0)}`);
/** An error as the study tables show it. */
export const fmtError = (e) => (e == null ? '—' : e.toExponential(2));

/**
 * What the study sections share: a spec (JSON in a text box) run as an NDJSON stream with a
 * progress bar and a status line, drawn as the settings arrive, a table of the result, a download
 * button, and the section's state in `data-{stateKey}` (idle, running, done, error). The elements
 * are found by `prefix`: #{prefix}-spec, -run, -status, -progress, -legend, -readout, -table,
 * -form and #err-{prefix}. A subclass gives `stream(body, onLine, signal)`, `describe(point)`
 * (the status line after a setting), `draw(points, result)` (result null while streaming),
 * `renderTable(result)` and `download()`.
 */
export class StudyPanel {
  /**
   * @param {HTMLElement} root the section
   * @param {string} prefix of the section's element ids
   * @param {string} stateKey dataset key of the state
   * @param {HTMLButtonElement} downloadButton enabled once a study is done
   */
  constructor(root, prefix, stateKey, downloadButton) {
    const $ = (id) => root.querySelector(`#${id}`);
    Object.assign(this, {
      root, stateKey, downloadButton,
      spec: $(`${prefix}-spec`), runButton: $(`${prefix}-run`), status: $(`${prefix}-status`),
      progress: $(`${prefix}-progress`), error: $(`err-${prefix}`), legend: $(`${prefix}-legend`),
      readout: $(`${prefix}-readout`), table: $(`${prefix}-table`),
    });
    this.controller = null;
    /** The last study's points, result and body (for tests and the download). */
    this.last = null;
    $(`${prefix}-form`).addEventListener('submit', (event) => {
      event.preventDefault();
      this.run();
    });
    downloadButton.addEventListener('click', () => this.download());
    this.runButton.disabled = false;
  }

  setState(state) {
    this.root.dataset[this.stateKey] = state;
  }

  /** Runs the study in the text box; a new run supersedes a running one. */
  async run() {
    this.controller?.abort();
    const controller = new AbortController();
    this.controller = controller;
    this.error.textContent = '';
    this.spec.removeAttribute('aria-invalid');
    this.downloadButton.disabled = true;
    let body;
    try {
      body = JSON.parse(this.spec.value);
    } catch (e) {
      this.fail(`The spec is not JSON: ${e.message}`);
      return;
    }
    const points = [];
    this.last = { body, points, result: null };
    this.setState('running');
    this.progress.hidden = false;
    this.progress.value = 0;
    this.status.textContent = 'Computing the reference…';
    this.draw(points, null);
    try {
      await this.stream(body, (line) => {
        if (controller !== this.controller) return;
        if (line.type === 'reference') {
          this.progress.max = line.total;
          this.status.textContent = `Errors against the ${line.reference}; ${line.total} settings to run…`;
        } else if (line.type === 'point') {
          points.push(line.point);
          this.progress.value = line.done;
          this.status.textContent = `${line.done} of ${line.total}: ${this.describe(line.point)}`;
          this.draw(points, null);
        } else if (line.type === 'result') {
          this.last.result = line;
        } else if (line.type === 'error') {
          throw new ApiError(line.error);
        }
      }, controller.signal);
    } catch (error) {
      if (controller !== this.controller) return;
      this.fail(error?.message || String(error), error instanceof ApiError ? error.field : null);
      return;
    }
    if (controller !== this.controller) return;
    const result = this.last.result;
    this.draw(result.points, result);
    this.renderTable(result);
    this.progress.hidden = true;
    this.status.textContent = `Done: ${result.points.length} settings of ${result.system.id} to t = ${result.t_end}, ` +
      `errors against the ${result.reference}.`;
    this.downloadButton.disabled = false;
    this.setState('done');
  }

  fail(message, field = null) {
    this.progress.hidden = true;
    this.error.textContent = field ? `${field}: ${message.replace(`${field}: `, '')}` : message;
    this.spec.setAttribute('aria-invalid', 'true');
    this.status.textContent = 'The study could not run.';
    this.setState('error');
  }
}

export class WorkPrecisionPanel extends StudyPanel {
  /** @param {HTMLElement} root the section */
  constructor(root) {
    super(root, 'wp', 'wpState', root.querySelector('#wp-download-rrd'));
    this.spec.value = JSON.stringify(PRESET_STUDY, null, 2);
    this.chart = new LogLogPlot(root.querySelector('#wp-plot'), 'max |energy error| over the samples',
      'wall time (ms)', (x, y) => this.hover(x, y));
  }

  stream(body, onLine, signal) {
    return workPrecisionStream(body, onLine, signal);
  }

  describe(p) {
    return `${p.method} ${fmtSetting(p)} took ${p.wall_ms.toFixed(2)} ms, max energy error ${fmtError(p.max_energy_error)}`;
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
    this.readout.textContent = `${p.method} ${fmtSetting(p)}: ${p.wall_ms.toFixed(3)} ms, ` +
      `${p.force_evaluations} force evaluations, max energy error ${fmtError(p.max_energy_error)}, ` +
      `final state error ${fmtError(p.final_state_error)}`;
    Object.assign(this.readout.dataset, { method: p.method, setting: fmtSetting(p) });
  }

  renderTable(result) {
    const drift = (p) => Object.entries(p.invariant_drift).map(([k, v]) => `${k} ${v.toExponential(1)}`).join(', ') || '—';
    this.table.replaceChildren(...result.points.map((p) => el('tr', {},
      el('td', { text: p.method }), el('td', { text: fmtSetting(p) }),
      el('td', { class: 'num', text: p.wall_ms.toFixed(3) }), el('td', { class: 'num', text: String(p.force_evaluations) }),
      el('td', { class: 'num', text: fmtError(p.max_energy_error) }), el('td', { class: 'num', text: fmtError(p.final_state_error) }),
      el('td', { text: drift(p) }), el('td', { text: p.stop }))));
  }

  async download() {
    if (!this.last?.body) return;
    this.downloadButton.disabled = true;
    try {
      const blob = await workPrecisionRrd(this.last.body);
      saveBlob(blob, 'geomint-work-precision.rrd');
      this.status.textContent = `Saved geomint-work-precision.rrd (${sizeText(blob.size)}).`;
    } catch (error) {
      this.error.textContent = `The recording could not be made: ${error?.message || error}`;
    } finally {
      this.downloadButton.disabled = false;
    }
  }
}
