// The work–precision section: a study spec (the body of POST /api/v1/studies/work-precision,
// editable JSON with a preset), run as an NDJSON stream with progress, drawn as a log–log
// diagram of wall time against the largest energy error — one line per method with its fitted
// slope — with a readout of the setting nearest the pointer, a table of every setting, and the
// study as a Rerun recording. The section's state is `data-wp-state` (idle, running, done, error).

import uPlot from '../vendor/uPlot.esm.js';
import { workPrecisionStream, workPrecisionRrd, ApiError } from './api.js';
import { el } from './form.js';
import { colour, logSplits, logTicks, polyline } from './charts.js';
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
const fmtError = (e) => (e == null ? '—' : e.toExponential(2));

export class WorkPrecisionPanel {
  /** @param {HTMLElement} root the section */
  constructor(root) {
    this.root = root;
    this.spec = root.querySelector('#wp-spec');
    this.runButton = root.querySelector('#wp-run');
    this.status = root.querySelector('#wp-status');
    this.progress = root.querySelector('#wp-progress');
    this.error = root.querySelector('#err-wp');
    this.legend = root.querySelector('#wp-legend');
    this.area = root.querySelector('#wp-plot');
    this.readout = root.querySelector('#wp-readout');
    this.table = root.querySelector('#wp-table');
    this.downloadButton = root.querySelector('#wp-download-rrd');
    this.spec.value = JSON.stringify(PRESET_STUDY, null, 2);
    this.plot = null;
    this.controller = null;
    /** The last study's points, result and body (for tests and the download). */
    this.last = null;
    root.querySelector('#wp-form').addEventListener('submit', (event) => {
      event.preventDefault();
      this.run();
    });
    this.downloadButton.addEventListener('click', () => this.download());
    this.resize = new ResizeObserver(() => this.layout());
    this.resize.observe(this.area);
    this.runButton.disabled = false;
  }

  setState(state) {
    this.root.dataset.wpState = state;
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
      await workPrecisionStream(body, (line) => {
        if (controller !== this.controller) return;
        if (line.type === 'reference') {
          this.progress.max = line.total;
          this.status.textContent = `Errors against the ${line.reference}; ${line.total} settings to run…`;
        } else if (line.type === 'point') {
          points.push(line.point);
          this.progress.value = line.done;
          this.status.textContent = `${line.done} of ${line.total}: ${line.point.method} ${fmtSetting(line.point)} ` +
            `took ${line.point.wall_ms.toFixed(2)} ms, max energy error ${fmtError(line.point.max_energy_error)}`;
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
    this.draw(result.points, result.fits);
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
  draw(points, fits) {
    const runs = this.series(points);
    this.runs = runs;
    this.legend.replaceChildren(...runs.map((r) => {
      const fit = fits?.find((f) => f.run === r.run);
      const slope = fit?.slope == null ? '' : `: time ∝ error^${fit.slope.toFixed(3)}`;
      return el('li', { 'data-method': r.label },
        el('span', { class: 'swatch', style: `background:${colour(r.run)}`, 'aria-hidden': 'true' }),
        `${r.label}${slope}`);
    }));
    const data = [null, ...runs.map((r) => [r.points.map((p) => p.max_energy_error), r.points.map((p) => p.wall_ms)])];
    if (!runs.length) {
      // Nothing to draw yet (uPlot's faceted mode needs a series).
      this.plot?.destroy();
      this.plot = null;
      return;
    }
    const same = this.plot && this.plot.series.length === data.length
      && runs.every((r, i) => this.plot.series[i + 1].label === r.label);
    if (same) {
      this.plot.setData(data);
      return;
    }
    this.plot?.destroy();
    const axis = (label) => ({
      label, labelSize: 14, size: 56, labelGap: 0, values: logTicks, splits: logSplits,
      filter: (u, splits) => splits, stroke: '#333', grid: { stroke: '#e4e4e4', width: 1 },
      ticks: { stroke: '#ccc', width: 1 }, font: '11px system-ui, sans-serif', labelFont: '12px system-ui, sans-serif',
    });
    const dotted = (u, seriesIdx) => {
      const path = polyline(u, seriesIdx);
      const [xs, ys] = u.data[seriesIdx];
      const r = 3 * (window.devicePixelRatio || 1);
      for (let i = 0; i < xs.length; i++) {
        const px = u.valToPos(xs[i], 'x', true);
        const py = u.valToPos(ys[i], 'y', true);
        path.stroke.moveTo(px + r, py);
        path.stroke.arc(px, py, r, 0, 2 * Math.PI);
      }
      return path;
    };
    const { width, height } = this.size();
    this.plot = new uPlot({
      width, height, mode: 2,
      legend: { show: false },
      cursor: { points: { show: false }, drag: { x: false, y: false } },
      scales: { x: { time: false, distr: 3, auto: true }, y: { distr: 3, auto: true } },
      axes: [axis('max |energy error| over the samples'), axis('wall time (ms)')],
      series: [{}, ...runs.map((r) => ({
        label: r.label, stroke: colour(r.run), width: 1.5, paths: dotted, points: { show: false },
        facets: [{ scale: 'x', auto: true }, { scale: 'y', auto: true }],
      }))],
    }, data, this.area);
    this.plot.over.addEventListener('pointermove', (event) => this.hover(event.offsetX, event.offsetY));
  }

  /** The readout: the setting nearest to (x, y) in CSS pixels of the plot area, within 24 px. */
  hover(x, y) {
    if (!this.plot) return;
    let best = null;
    for (const r of this.runs ?? []) {
      for (const p of r.points) {
        const dx = this.plot.valToPos(p.max_energy_error, 'x') - x;
        const dy = this.plot.valToPos(p.wall_ms, 'y') - y;
        const d = Math.hypot(dx, dy);
        if (d < 24 && (!best || d < best.d)) best = { d, p };
      }
    }
    if (!best) return;
    const p = best.p;
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

  size() {
    const width = Math.max(240, Math.floor(this.area.clientWidth));
    return { width, height: Math.round(Math.min(420, Math.max(240, width * 0.55))) };
  }

  layout() {
    if (!this.plot) return;
    const { width, height } = this.size();
    if (Math.abs(this.plot.width - width) > 1) this.plot.setSize({ width, height });
  }
}
