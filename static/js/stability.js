// The stability section: a form (methods, ω, the γ and h axes, a γ for the ½tr error), the
// spectral-radius maps of POST /api/v1/stability as heatmaps with the analytic boundaries, a
// shared cursor readout (γ, h, ρ, verdicts) driven by the pointer or the arrow keys, each map's
// disagreement counts, and the ½tr error of POST /api/v1/stability/point at log-spaced step sizes
// on log–log axes (uPlot). API errors appear beside the input their `field` names. The section's
// state is `data-stab-state` (idle, running, done, error), for tests.

import uPlot from '../vendor/uPlot.esm.js';
import { stabilityMaps, stabilityPoint, stabilityRrd, ApiError } from './api.js';
import { downloadRecording, el, fmt, parseCount, parseNumber } from './common.js';
import { StudyStream } from './study-stream.js';
import { colour, logSplits, logTicks } from './charts.js';
import { Heatmap, bindCursor, colourScale, drawColourScale, scaleLegend } from './heatmap.js';

/** Methods mapped by default, in this order (paper 003's three schemes). */
const DEFAULT_METHODS = ['cimp', 'csv1', 'csv2'];
/** The thesis's equation of each printed relation. */
const PRINTED_EQUATION = { cimp: '3.12', csv1: '3.17', csv2: '3.22' };
/** Step sizes of the ½tr error plot: `n` log-spaced values from `from` to `to`. */
const HALF_TRACE_H = { from: 0.005, to: 0.5, n: 12 };

/** The step sizes of the ½tr error plot. */
export function halfTraceSteps({ from, to, n } = HALF_TRACE_H) {
  return Array.from({ length: n }, (_, k) => +(from * (to / from) ** (k / (n - 1))).toPrecision(12));
}

/** Least-squares slope of log10 y against log10 x over the positive pairs; null with < 2. */
function logSlope(xs, ys) {
  const pts = xs.map((x, i) => [x, ys[i]]).filter(([x, y]) => x > 0 && y > 0);
  if (pts.length < 2) return null;
  const lx = pts.map(([x]) => Math.log10(x));
  const ly = pts.map(([, y]) => Math.log10(y));
  const mx = lx.reduce((a, b) => a + b, 0) / lx.length;
  const my = ly.reduce((a, b) => a + b, 0) / ly.length;
  let num = 0;
  let den = 0;
  for (let i = 0; i < lx.length; i++) {
    num += (lx[i] - mx) * (ly[i] - my);
    den += (lx[i] - mx) ** 2;
  }
  return den > 0 ? num / den : null;
}

const verdictText = (v) => (v ? 'stable' : 'unstable');

/** The stability section. */
export class StabilityPanel {
  /**
   * @param {HTMLElement} root the section
   * @param {object[]} methods the method catalogue
   */
  constructor(root, methods) {
    this.root = root;
    this.form = root.querySelector('#stab-form');
    this.status = root.querySelector('#stab-status');
    this.mapsBox = root.querySelector('#stab-maps');
    this.scaleBox = root.querySelector('#stab-scale');
    this.scaleBar = root.querySelector('#stab-scale-bar');
    this.printedToggle = root.querySelector('#stab-printed');
    this.generalError = root.querySelector('#err-stab-form');
    this.halfTraceBox = root.querySelector('#halftrace');
    this.methods = methods.filter((m) => m.kind !== 'adaptive');
    /** Chosen method ids in the order they were ticked (the request's order). */
    this.order = [];
    /** @type {Heatmap[]} */
    this.heatmaps = [];
    this.cursor = null;
    this.plot = null;
    this.runner = new StudyStream({ root, stateKey: 'stabState', status: this.status });
    /** The last answers, for tests: {document, halfTrace}. */
    this.last = null;

    const field = (id, error) => ({ input: root.querySelector('#' + id), error: root.querySelector('#' + error) });
    this.fields = new Map([
      ['methods', { input: null, error: root.querySelector('#err-stab-methods') }],
      ['omega', field('stab-omega', 'err-stab-omega')],
      ['point.gamma', field('stab-point-gamma', 'err-stab-point-gamma')],
    ]);
    for (const axis of ['gamma', 'h']) {
      for (const key of ['min', 'max', 'n']) {
        this.fields.set(`${axis}.${key}`, field(`stab-${axis}-${key}`, `err-stab-${axis}`));
      }
    }
    this.buildMethods();

    this.form.addEventListener('submit', (event) => {
      event.preventDefault();
      this.compute();
    });
    this.printedToggle.addEventListener('change', () => {
      for (const hm of this.heatmaps) {
        hm.showPrinted = this.printedToggle.checked;
        hm.draw();
      }
    });
    this.scaleBox.append(scaleLegend());
    this.resize = new ResizeObserver(() => this.layout());
    this.resize.observe(this.mapsBox);
    this.resize.observe(this.halfTraceBox);
    this.pending = false;
    this.downloadButton = root.querySelector('#stab-download-rrd');
    this.downloadError = root.querySelector('#err-stab-rrd');
    /** The body of the maps shown, which the .rrd download records. */
    this.shownBody = null;
    this.downloadButton.addEventListener('click', () => this.download());
    this.form.querySelector('#stab-run').disabled = false;
  }

  /** The method checkboxes: the three conformal schemes first, the others folded away. */
  buildMethods() {
    const main = this.root.querySelector('#stab-method-main');
    const more = this.root.querySelector('#stab-method-more');
    const row = (m) => {
      const id = `stab-m-${m.id}`;
      const box = el('input', { type: 'checkbox', id, value: m.id, 'data-method': m.id, 'aria-describedby': 'err-stab-methods' });
      box.addEventListener('change', () => {
        this.order = this.order.filter((x) => x !== m.id);
        if (box.checked) this.order.push(m.id);
      });
      if (DEFAULT_METHODS.includes(m.id)) box.checked = true;
      const name = m.name.replace(/\s*\([^)]*\)$/, '');
      return el('div', { class: 'stab-method' }, box,
        el('label', { for: id }, el('code', { text: m.id }), ' ', el('small', { text: name })));
    };
    const first = DEFAULT_METHODS.map((id) => this.methods.find((m) => m.id === id)).filter(Boolean);
    main.replaceChildren(...first.map(row));
    more.replaceChildren(...this.methods.filter((m) => !DEFAULT_METHODS.includes(m.id)).map(row));
    this.order = first.map((m) => m.id);
    this.fields.get('methods').input = main.querySelector('input');
  }

  /** The two request bodies the form describes (bad numbers as null: the API names them). */
  read() {
    const value = (id) => this.root.querySelector('#' + id).value;
    const axis = (name) => ({
      min: parseNumber(value(`stab-${name}-min`)),
      max: parseNumber(value(`stab-${name}-max`)),
      n: parseCount(value(`stab-${name}-n`)),
    });
    return {
      map: { methods: [...this.order], omega: parseNumber(value('stab-omega')), gamma: axis('gamma'), h: axis('h') },
      pointGamma: parseNumber(value('stab-point-gamma')),
    };
  }

  clearErrors() {
    for (const node of this.root.querySelectorAll('.field-error')) node.textContent = '';
    for (const node of this.root.querySelectorAll('[aria-invalid]')) node.removeAttribute('aria-invalid');
  }

  /**
   * Shows an API error beside its input. `scope` is `map` or `point`: a point request's `gamma`
   * is the ½tr error's γ, its `method` one of the methods.
   */
  showError(error, scope) {
    let key = error instanceof ApiError ? error.field : null;
    if (key && /^methods?\b/.test(key)) key = 'methods';
    if (scope === 'point' && key === 'gamma') key = 'point.gamma';
    const target = key ? this.fields.get(key) : null;
    const slot = target?.error || this.generalError;
    slot.textContent = error?.message || String(error);
    if (target?.input) target.input.setAttribute('aria-invalid', 'true');
    return target?.input || null;
  }

  /** Computes the maps and the ½tr errors (a new computation supersedes a running one). */
  async compute() {
    const run = this.runner.begin();
    this.clearErrors();
    const { map, pointGamma } = this.read();
    this.shownBody = null;
    this.downloadButton.disabled = true;
    this.status.textContent = 'Computing…';

    const [maps, points] = await Promise.allSettled([
      stabilityMaps(map, run.signal),
      this.halfTraceErrors(map.methods, map.omega, pointGamma, run.signal),
    ]);
    if (!run.current()) return;

    const errors = [];
    let focus = null;
    if (maps.status === 'fulfilled') {
      this.renderMaps(maps.value);
      this.shownBody = map;
      this.downloadButton.disabled = false;
    } else {
      this.clearMaps();
      errors.push(maps.reason);
      focus = this.showError(maps.reason, 'map');
    }
    if (points.status === 'fulfilled' && points.value) {
      this.renderHalfTrace(points.value);
    } else {
      this.clearHalfTrace();
      if (points.status === 'rejected' && (!errors.length || points.reason?.message !== errors[0]?.message)) {
        errors.push(points.reason);
        focus ||= this.showError(points.reason, 'point');
      }
    }
    this.last = {
      document: maps.status === 'fulfilled' ? maps.value : null,
      halfTrace: points.status === 'fulfilled' ? points.value : null,
    };
    if (errors.length) {
      this.status.textContent = `The server refused the request: ${errors.map((e) => e?.message || e).join('; ')}`;
      this.runner.setState('error');
      focus?.focus();
    } else {
      const doc = maps.value;
      this.status.textContent = `Done: ${doc.maps.length} map${doc.maps.length > 1 ? 's' : ''} of ` +
        `${doc.gamma.n} γ × ${doc.h.n} h values at ω = ${fmt(doc.omega)}; ½tr error at ${points.value.hs.length} step sizes.` +
        (doc.stop === 'time_limit'
          ? ` The server's time limit stopped ${map.methods.length - doc.maps.length} of ${map.methods.length} maps.`
          : '');
      this.runner.setState('done');
    }
  }

  /** Saves the shown maps as geomint-stability.rrd (the server computes and records them). */
  download() {
    if (!this.shownBody) return null;
    const body = this.shownBody;
    return downloadRecording({
      button: this.downloadButton, status: this.status, error: this.downloadError,
      name: 'geomint-stability.rrd', fetchBlob: () => stabilityRrd(body),
    });
  }

  /**
   * |½tr error| of every method at the plot's step sizes. A step size where a method is undefined
   * (csv2 at γh = 2; the API names `h`) becomes a gap; any other error rejects.
   */
  async halfTraceErrors(methods, omega, gamma, signal) {
    if (!methods.length) return null;
    const hs = halfTraceSteps();
    const runs = await Promise.all(methods.map(async (method) => {
      const answers = await Promise.all(hs.map((h) => stabilityPoint({ method, omega, gamma, h }, signal)
        .catch((error) => {
          if (error instanceof ApiError && error.field === 'h') return { error };
          throw error;
        })));
      const label = answers.find((a) => a.method)?.method ?? method;
      const values = answers.map((a) => {
        const e = a.analysis?.half_trace_error;
        return e != null && e > 0 ? e : null;
      });
      const gaps = answers.filter((a) => a.error).map((a) => a.error.message);
      return { method: label, values, gaps, slope: logSlope(hs, values) };
    }));
    return { hs, omega, gamma, runs };
  }

  clearMaps() {
    this.heatmaps = [];
    this.cursor = null;
    this.mapsBox.replaceChildren();
    this.scaleBox.hidden = true;
  }

  /** Draws one heatmap per map of the answer `doc`. */
  renderMaps(doc) {
    this.clearMaps();
    const scale = colourScale(doc.maps);
    this.scale = scale;
    this.scaleBox.hidden = false;
    const anyPrinted = doc.maps.some((m) => m.printed);
    this.scaleBox.querySelector('[data-legend="printed"]').hidden = !anyPrinted;
    this.printedToggle.closest('.field').hidden = !anyPrinted;
    drawColourScale(this.scaleBar, scale);

    doc.maps.forEach((map, i) => {
      const titleId = `stab-map-title-${i}`;
      const readoutId = `stab-readout-${i}`;
      const canvas = el('canvas', {
        class: 'heatmap', tabindex: '0', role: 'img', 'data-method': map.method,
        'aria-label': `Spectral-radius map of ${map.method}: ${doc.gamma.n} γ values across, ${doc.h.n} h values up. ` +
          'Arrow keys move the cursor cell; the readout below gives its values.',
        'aria-describedby': readoutId,
      });
      const readout = el('p', { class: 'readout', id: readoutId, 'aria-live': 'off' },
        'Point at the map, or focus it and use the arrow keys, to read a cell.');
      const id = map.method.replace(/\(.*$/, '');
      const equation = PRINTED_EQUATION[id];
      const counts = map.disagreements == null
        ? el('p', { class: 'disagreements', 'data-disagreements': '' }, 'No analytic relation for this method.')
        : el('p', {
          class: 'disagreements',
          'data-disagreements': String(map.disagreements),
          'data-printed-disagreements': String(map.printed_disagreements),
        }, 'Cells where a relation disagrees with the numerical verdict (not counting cells next to the boundary): corrected ',
        el('strong', { class: 'count-corrected', text: String(map.disagreements) }),
        `, printed (eq. ${equation ?? '—'}) `,
        el('strong', { class: 'count-printed', text: String(map.printed_disagreements) }), '.');
      const figure = el('figure', { class: 'map', 'data-map': map.method, 'aria-labelledby': titleId },
        el('figcaption', { id: titleId }, el('span', { class: 'plot-title', text: map.method }),
          el('small', { text: map.analytic ? 'numerical ρ with the analytic boundary' : 'numerical ρ' })),
        el('div', { class: 'map-area' }, canvas),
        readout, counts);
      this.mapsBox.append(figure);
      const hm = new Heatmap(canvas, map, doc, scale);
      hm.showPrinted = this.printedToggle.checked;
      hm.readout = readout;
      this.heatmaps.push(hm);
      bindCursor(hm, { get: () => this.cursor, set: (cell) => this.setCursor(cell, hm) });
    });
    this.layout();
  }

  /** Moves the cursor of every map to `cell`; the readout of `source` is announced. */
  setCursor(cell, source) {
    this.cursor = cell;
    for (const hm of this.heatmaps) {
      hm.cursor = cell;
      hm.draw();
      const v = hm.cell(cell.col, cell.row);
      const relations = v.analytic == null ? ''
        : `; corrected relation ${verdictText(v.analytic)}, printed ${verdictText(v.printed)}`;
      hm.readout.textContent = `γ = ${fmt(v.gamma)}, h = ${fmt(v.h)}: ρ = ${v.rho == null ? 'undefined' : fmt(v.rho, 5)}, ` +
        `${v.rho == null ? 'no verdict' : verdictText(v.stable)}${relations}`;
      Object.assign(hm.readout.dataset, {
        col: String(v.col), row: String(v.row), gamma: String(v.gamma), h: String(v.h),
        rho: v.rho == null ? '' : String(v.rho), stable: String(v.stable),
      });
      hm.readout.setAttribute('aria-live', hm === source ? 'polite' : 'off');
    }
  }

  /** Resizes the heatmaps, the colour scale and the ½tr plot to their boxes. */
  layout() {
    if (this.pending) return;
    this.pending = true;
    requestAnimationFrame(() => {
      this.pending = false;
      for (const hm of this.heatmaps) hm.resize();
      if (!this.scaleBox.hidden && this.scale) drawColourScale(this.scaleBar, this.scale);
      if (this.plot) {
        const { width, height } = this.plotSize();
        if (Math.abs(this.plot.width - width) > 1) this.plot.setSize({ width, height });
      }
    });
  }

  plotSize() {
    const area = this.halfTraceBox.querySelector('.plot-area');
    const width = Math.max(200, Math.floor(area.clientWidth));
    return { width, height: Math.round(Math.min(300, Math.max(200, width * 0.5))) };
  }

  clearHalfTrace() {
    this.plot?.destroy();
    this.plot = null;
    this.halfTraceBox.hidden = true;
  }

  /** The ½tr error plot: one series per method and a dashed h⁴ guide, log–log. */
  renderHalfTrace(result) {
    this.clearHalfTrace();
    this.halfTraceBox.hidden = false;
    const { hs, runs } = result;
    this.halfTraceBox.querySelector('#halftrace-caption').textContent =
      `|½ tr M − ½ tr M_exact| at ω = ${fmt(result.omega)}, γ = ${fmt(result.gamma)}, h from ${hs[0]} to ${hs[hs.length - 1]}; log–log axes.`;
    // The guide ∝ h⁴ runs a factor 4 below the first method's error at the largest h.
    const anchor = runs.map((r) => r.values.map((v, k) => [v, k]).filter(([v]) => v != null).pop()).find(Boolean);
    const guide = anchor ? hs.map((h) => (anchor[0] / 4) * (h / hs[anchor[1]]) ** 4) : hs.map(() => null);
    const legend = this.halfTraceBox.querySelector('#halftrace-legend');
    legend.replaceChildren(
      ...runs.map((r, i) => el('li', { 'data-method': r.method },
        el('span', i % 2
          ? { class: 'swatch line dashed', style: `border-top-color:${colour(i)}`, 'aria-hidden': 'true' }
          : { class: 'swatch', style: `background:${colour(i)}`, 'aria-hidden': 'true' }),
        `${r.method}${r.slope == null ? '' : `: slope ${r.slope.toFixed(2)}`}`)),
      el('li', {}, el('span', { class: 'swatch line dashed', style: 'border-top-color:#777', 'aria-hidden': 'true' }), '∝ h⁴'));
    const gaps = runs.filter((r) => r.gaps.length).map((r) => `${r.method}: ${r.gaps[0]}`);
    this.halfTraceBox.querySelector('#halftrace-note').textContent = gaps.length ? `Gaps: ${gaps.join('; ')}` : '';

    const axis = (label) => ({
      label, labelSize: 14, size: 50, labelGap: 0, values: logTicks, splits: logSplits,
      filter: (u, splits) => splits, stroke: '#333', grid: { stroke: '#e4e4e4', width: 1 },
      ticks: { stroke: '#ccc', width: 1 }, font: '11px system-ui, sans-serif', labelFont: '12px system-ui, sans-serif',
    });
    const { width, height } = this.plotSize();
    const opts = {
      width, height, mode: 1,
      legend: { show: false },
      cursor: { points: { size: 6 } },
      scales: {
        x: { time: false, distr: 3, range: () => [hs[0] / 1.25, hs[hs.length - 1] * 1.25] },
        y: { distr: 3 },
      },
      axes: [{ ...axis('h'), size: 32 }, axis('|½tr error|')],
      series: [
        { label: 'h' },
        // Methods whose errors nearly coincide (csv1 and csv2) stay visible both: every second
        // method is dashed with hollow points, so the line drawn first shows through its gaps,
        // and earlier methods' points are larger.
        ...runs.map((r, i) => ({
          label: r.method, stroke: colour(i), width: i % 2 ? 2 : 2.5, dash: i % 2 ? [7, 5] : [], spanGaps: false,
          points: { show: true, size: Math.max(5, 10 - 2 * i), fill: i % 2 ? '#ffffff' : colour(i), width: 1.5 },
        })),
        { label: '∝ h⁴', stroke: '#777', width: 1, dash: [5, 4], points: { show: false } },
      ],
    };
    const area = this.halfTraceBox.querySelector('#halftrace-plot');
    area.replaceChildren();
    this.plot = new uPlot(opts, [hs, ...runs.map((r) => r.values), guide], area);
  }
}
