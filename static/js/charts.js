// The result plots, drawn with uPlot: energy against time, the energy error on a log axis, a
// phase portrait per degree of freedom (in the run's chart), the trajectory in Cartesian
// coordinates whatever the chart, so that runs in different charts compare (q(t); for planar
// systems also the x–y plane, for 3-D systems the x–y and x–z projections; for a system that
// places its bodies itself, the bodies where it puts them), the invariants and the dissipation
// drift. Every chosen method is one series in its own colour. Time plots share the sample times
// (uPlot's aligned mode); phase portraits and projections draw each method's points in time order
// (uPlot's faceted mode 2). The studies' log–log diagrams (LogLogPlot) draw one polyline with dots
// per series.

import uPlot from '../vendor/uPlot.esm.js';
import { el } from './common.js';
import { chaosSection } from './chaos.js';

/** What the energy error is measured against (plot-options.js): its symbol and caption. */
export const ENERGY_ERROR = {
  exact: { symbol: 'H_exact', caption: 'against the exact solution' },
  ref: { symbol: 'H_ref', caption: 'against the adaptive DOP853 reference run' },
  initial: { symbol: 'H₀', caption: 'against the initial energy H₀: nothing damps this run, so H is conserved' },
};

/** Where a run has no energy error, what to do for one. */
const NO_ENERGY_ERROR = 'No energy error: this system is damped and has no exact solution. Tick “Compare to the ' +
  'reference” and run again to measure it against an adaptive DOP853 run.';

/** One colour per method (Okabe–Ito, then Tol's muted set), readable on white. */
export const COLOURS = [
  '#0072B2', '#D55E00', '#009E73', '#CC79A7', '#E69F00', '#56B4E9', '#222222', '#882255',
  '#44AA99', '#999933', '#AA4499', '#332288', '#117733', '#DDCC77', '#661100', '#6699CC',
];

export function colour(i) {
  return COLOURS[i % COLOURS.length];
}

/**
 * Draws a faceted series as one polyline in data order (x need not be monotone). Points closer
 * than half a pixel to the last drawn one are skipped, so long runs stroke quickly.
 */
export function polyline(u, seriesIdx) {
  const series = u.series[seriesIdx];
  const [xs, ys] = u.data[seriesIdx];
  const xKey = series.facets[0].scale;
  const yKey = series.facets[1].scale;
  const stroke = new Path2D();
  const near = 0.5 * (window.devicePixelRatio || 1);
  let drawing = false;
  let lastX = 0;
  let lastY = 0;
  let skipped = false;
  for (let i = 0; i < xs.length; i++) {
    const x = xs[i];
    const y = ys[i];
    if (x == null || y == null || !Number.isFinite(x) || !Number.isFinite(y)) {
      if (skipped) stroke.lineTo(lastX, lastY);
      drawing = false;
      skipped = false;
      continue;
    }
    const px = u.valToPos(x, xKey, true);
    const py = u.valToPos(y, yKey, true);
    if (!drawing) {
      stroke.moveTo(px, py);
      drawing = true;
    } else if (Math.abs(px - lastX) < near && Math.abs(py - lastY) < near && i < xs.length - 1) {
      skipped = true;
      continue;
    } else {
      stroke.lineTo(px, py);
    }
    lastX = px;
    lastY = py;
    skipped = false;
  }
  return { stroke, fill: null, clip: null, band: null, gaps: null, flags: 0 };
}

/**
 * A linear axis range: uPlot's padded range, except that a constant series (a coordinate that
 * stays 0, a conserved invariant) gets a band around its value instead of [0, 100].
 */
function linearRange(u, min, max) {
  if (min == null || max == null) return [0, 1];
  if (min === max) {
    const pad = Math.abs(min) * 0.1 || 1;
    return [min - pad, max + pad];
  }
  return uPlot.rangeNum(min, max, 0.1, true);
}

/** Compact tick labels. */
function ticks(u, values) {
  return values.map((v) => {
    if (v == null) return '';
    const a = Math.abs(v);
    if (a !== 0 && (a < 1e-3 || a >= 1e5)) return v.toExponential(0).replace('e+', 'e');
    return String(+v.toPrecision(6));
  });
}

/** Log-axis gridlines at powers of ten only (every few powers when the range is wide). */
export function logSplits(u, axisIdx, min, max) {
  const lo = Math.floor(Math.log10(min));
  const hi = Math.ceil(Math.log10(max));
  const step = Math.max(1, Math.ceil((hi - lo) / 6));
  const out = [];
  for (let e = lo; e <= hi; e += step) {
    const v = 10 ** e;
    if (v >= min * (1 - 1e-9) && v <= max * (1 + 1e-9)) out.push(v);
  }
  return out.length >= 2 ? out : [min, max];
}

export function logTicks(u, values) {
  return values.map((v) => {
    if (v == null) return '';
    const e = Math.log10(v);
    return Math.abs(e - Math.round(e)) < 1e-6 ? `1e${Math.round(e)}` : v.toExponential(1).replace('e+', 'e');
  });
}

/** A y axis's width: room for its longest tick label (long energies like −0.18164 included). */
function yAxisSize(u, values) {
  const longest = Math.max(0, ...(values ?? []).map((v) => String(v ?? '').length));
  return Math.max(50, Math.ceil(20 + 6.5 * longest));
}

/**
 * `y` at the length `n` of the x column: itself when it has that length (uPlot then holds the
 * store's own array, no copy), else a copy padded with nulls (a run that is behind or stopped).
 */
function padded(y, n) {
  if (y.length === n) return y;
  const out = y.slice(0, n);
  while (out.length < n) out.push(null);
  return out;
}

/**
 * A plot definition: `key` (stable, used by tests), `title`, axis labels, `mode` (1: time on x,
 * 2: x–y pairs), `log` for a log y axis, and `series(store)` giving per method (and body) the
 * label, colour and values.
 */
function timePlot(key, title, yLabel, pick, { log = false, caption = '', against = null } = {}) {
  return { key, title, caption, xLabel: 't', yLabel, mode: 1, log, pick, against };
}

/** `perMethod`: how many x–y series each method has (one per body in projections); `yDown`
 * draws the y axis growing downwards. */
function pairPlot(key, title, xLabel, yLabel, pairs, { caption = '', perMethod = 1, yDown = false } = {}) {
  return { key, title, caption, xLabel, yLabel, mode: 2, pairs, perMethod, yDown };
}

/** A caption's parts joined, empty ones left out. */
function joined(...parts) {
  return parts.filter(Boolean).join('; ');
}

/**
 * The plots of `count` bodies of `dims` (2 or 3) coordinates each, whose columns `columns(run)`
 * holds body after body: the plane of 2-D bodies, the x–y and x–z projections of 3-D ones.
 * `names` are the axes' names; `note` goes into the captions.
 */
function bodyPlots(dims, count, columns, names, note) {
  const project = (a, b) => (r) => Array.from({ length: count }, (_, k) =>
    [columns(r)[dims * k + a] || [], columns(r)[dims * k + b] || []]);
  const caption = joined(count > 1 ? `${count} bodies, each in its method’s colour` : '', note);
  const [x, y, z] = names;
  if (dims === 2) {
    const title = count > 1 ? `Bodies in the ${x}–${y} plane` : `Trajectory in the ${x}–${y} plane`;
    return [pairPlot('trajectory:xy', title, x, y, project(0, 1), { caption, perMethod: count })];
  }
  return [
    pairPlot('trajectory:xy', `Trajectory, ${x}–${y} projection`, x, y, project(0, 1), { caption, perMethod: count }),
    pairPlot('trajectory:xz', `Trajectory, ${x}–${z} projection`, x, z, project(0, 2), { caption, perMethod: count }),
  ];
}

/** The charts of one simulation, built from its stream header. */
export class Charts {
  /** @param {HTMLElement} root the results area that holds the plot sections */
  constructor(root) {
    this.root = root;
    /** @type {Map<string, {def: object, plot: uPlot, figure: HTMLElement}>} */
    this.plots = new Map();
    this.resize = new ResizeObserver((entries) => {
      for (const entry of entries) {
        const item = entry.target.plotItem;
        if (!item) continue;
        const { width, height } = this.size(entry.target);
        if (Math.abs(item.plot.width - width) > 1) item.plot.setSize({ width, height });
      }
    });
  }

  /** Removes every plot. */
  clear() {
    for (const { plot, figure } of this.plots.values()) {
      this.resize.unobserve(figure);
      plot.destroy();
    }
    this.plots.clear();
    this.root.replaceChildren();
    this.header = null;
  }

  size(figure) {
    const width = Math.max(200, Math.floor(figure.querySelector('.plot-area').clientWidth));
    const height = Math.round(Math.min(260, Math.max(180, width * 0.55)));
    return { width, height };
  }

  /**
   * Creates the plots for a stream `header` (system, methods, invariants, schedule).
   * @param {object} header
   * @param {object} options
   * @param {string|null} options.energyErrorSource `exact`, `ref`, `initial` (a key of
   *   ENERGY_ERROR) or null (no error plot)
   * @param {string} [options.noEnergyErrorNote] what the energy section says without one
   * @param {boolean} options.drift whether to plot the dissipation drift
   * @param {string[]} [options.chartNames] the run's chart's coordinate names
   * @param {string|null} [options.chartNote] a caption for plots in chart coordinates (null in
   *   the Cartesian chart)
   * @param {string[]} [options.cartesianNames] the Cartesian coordinate names
   * @param {string|null} [options.cartesianNote] a caption for plots transformed to Cartesian
   *   coordinates (null in the Cartesian chart)
   * @param {boolean} [options.yDown] whether y points down (the x–y plane is drawn so)
   * @param {string[]} [options.momentumNames] the momenta's names (default p_<coordinate>)
   * @param {{dims: number, count: number, names: string[]}} [options.bodies] bodies the system
   *   places itself, `dims` coordinates each, in the runs' `bodyColumns`; drawn instead of the
   *   Cartesian coordinates, which are then the chart's
   */
  build(header, options) {
    this.clear();
    this.header = header;
    const dof = header.system.q0.length;
    const labels = header.methods;
    const sections = [];

    const energy = [timePlot('energy', 'Energy H(t)', 'H', (r) => r.energy)];
    const against = ENERGY_ERROR[options.energyErrorSource];
    if (against) {
      energy.push(timePlot('energy_error', `Energy error |H − ${against.symbol}|`, '|ΔH|',
        (r) => r.errorMagnitude, { log: true, caption: `${against.caption}; log axis`, against: options.energyErrorSource }));
    }
    sections.push({ id: 'energy', title: 'Energy', plots: energy,
      note: against ? null : options.noEnergyErrorNote ?? NO_ENERGY_ERROR });
    const chaos = chaosSection(header, timePlot);
    if (chaos) sections.push(chaos);

    const names = dof === 1 ? [''] : dof % 3 === 0 ? ['x', 'y', 'z'] : null;
    const coordinate = (i) => {
      if (dof === 1) return '';
      if (dof === 3) return names[i];
      if (dof % 3 === 0) return `${names[i % 3]}${Math.floor(i / 3) + 1}`;
      return String(i + 1);
    };
    // Axis labels of coordinate i and its momentum: the chart's names where they fit.
    const label = (chartNames, i) => {
      if (chartNames?.length === dof) {
        const n = chartNames[i];
        return { q: n, p: options.momentumNames?.[i] ?? (n === 'q' ? 'p' : `p_${n}`) };
      }
      const c = coordinate(i);
      return { q: c ? `q_${c}` : 'q', p: c ? `p_${c}` : 'p' };
    };
    const phase = [];
    for (let i = 0; i < dof; i++) {
      const { q, p } = label(options.chartNames, i);
      phase.push(pairPlot(`phase:${i}`, `Phase portrait (${q}, ${p})`, q, p,
        (r) => [[r.qColumns[i] || [], r.pColumns[i] || []]], { caption: options.chartNote }));
    }
    sections.push({ id: 'phase', title: 'Phase portraits', plots: phase });

    // Trajectories in Cartesian coordinates: the chart's own where it is Cartesian.
    const position = (r) => r.xColumns || r.qColumns;
    const cartesian = (i) => label(options.cartesianNames, i).q;
    const trajectory = [];
    if (options.bodies) {
      const { dims, count, names } = options.bodies;
      trajectory.push(...bodyPlots(dims, count, (r) => r.bodyColumns || [], names, ''));
      for (let i = 0; i < dof; i++) {
        const q = cartesian(i);
        trajectory.push(timePlot(`trajectory:${i}`, `Trajectory ${q}(t)`, q, (r) => r.qColumns[i] || []));
      }
    } else if (dof % 3 === 0) {
      trajectory.push(...bodyPlots(3, dof / 3, position, ['x', 'y', 'z'], options.cartesianNote));
    } else {
      if (dof === 2) {
        const [x, y] = [cartesian(0), cartesian(1)];
        trajectory.push(pairPlot('trajectory:xy', `Trajectory in the ${x}–${y} plane`, x, y,
          (r) => [[position(r)[0] || [], position(r)[1] || []]], {
            caption: joined(options.yDown ? `${y} points down, along gravity` : '', options.cartesianNote),
            yDown: options.yDown,
          }));
      }
      for (let i = 0; i < dof; i++) {
        const q = cartesian(i);
        trajectory.push(timePlot(`trajectory:${i}`, `Trajectory ${q}(t)`, q, (r) => position(r)[i] || [],
          { caption: options.cartesianNote }));
      }
    }
    sections.push({ id: 'trajectory', title: 'Trajectory', plots: trajectory });

    const invariants = header.invariants.map((name) =>
      timePlot(`invariant:${name}`, `Invariant ${name}(t)`, name, (r) => r.invariants[name] || []));
    if (options.drift) {
      invariants.push(pairPlot('drift', 'Dissipation drift d(t) = ln max|q| + γt', 't', 'd',
        (r) => [[(r.dissipation_drift || []).map((x) => x.t), (r.dissipation_drift || []).map((x) => x.d)]],
        { caption: 'paper 003 eq. 4.4; flat under the exact flow of the linear oscillator; drawn as each method ends' }));
    }
    sections.push({ id: 'invariants', title: 'Invariants', plots: invariants,
      note: invariants.length ? null : 'This system reports no invariants.' });

    // One grid for all plots, in the order of the sections; a section's note takes a cell.
    const grid = el('div', { class: 'plot-grid' });
    this.root.append(grid);
    for (const section of sections) {
      if (section.note) {
        grid.append(el('p', { class: 'plot-note', 'data-note': section.id },
          el('strong', { text: `${section.title}: ` }), section.note));
      }
      for (const def of section.plots) this.add(grid, def, labels);
    }
  }

  /** Creates one plot in `grid`. */
  add(grid, def, labels) {
    const titleId = `plot-${def.key.replace(/[^\w-]/g, '-')}`;
    const area = el('div', { class: 'plot-area' });
    const figure = el('figure', { class: 'plot', 'data-plot': def.key, 'data-against': def.against, 'aria-labelledby': titleId },
      el('figcaption', { id: titleId }, el('span', { class: 'plot-title', text: def.title }),
        def.caption ? el('small', { text: def.caption }) : null),
      def.log ? el('p', { class: 'plot-empty', hidden: true, text: 'Nothing to draw on a log axis: every error so far is zero.' }) : null,
      area);
    grid.append(figure);
    const { width, height } = this.size(figure);
    const axis = (label, log = false, x = false) => ({
      label, labelSize: 14, size: x ? 28 : yAxisSize, labelGap: 0, values: log ? logTicks : ticks,
      splits: log ? logSplits : undefined, filter: log ? (u, splits) => splits : undefined,
      stroke: '#333', grid: { stroke: '#e4e4e4', width: 1 }, ticks: { stroke: '#ccc', width: 1 },
      font: '11px system-ui, sans-serif', labelFont: '12px system-ui, sans-serif',
    });
    let opts;
    if (def.mode === 1) {
      const tEnd = this.header.schedule.t_end;
      opts = {
        width, height, mode: 1,
        legend: { show: false },
        cursor: { sync: { key: 'geomint-time' }, points: { size: 5 } },
        scales: {
          x: { time: false, range: () => [0, tEnd] },
          y: def.log ? { distr: 3 } : { auto: true, range: linearRange },
        },
        axes: [axis(def.xLabel, false, true), axis(def.yLabel, def.log)],
        series: [{ label: 't' }, ...labels.map((label, i) => ({
          label, stroke: colour(i), width: 1.25, points: { show: false }, spanGaps: false,
        }))],
      };
    } else {
      const series = [{}];
      labels.forEach((label, i) => {
        for (let k = 0; k < def.perMethod; k++) {
          series.push({
            label: def.perMethod > 1 ? `${label}, body ${k + 1}` : label,
            stroke: colour(i), width: 1.25, paths: polyline, points: { show: false },
            facets: [{ scale: 'x', auto: true }, { scale: 'y', auto: true }],
          });
        }
      });
      opts = {
        width, height, mode: 2,
        legend: { show: false },
        cursor: { points: { show: false }, drag: { x: true, y: true } },
        scales: {
          x: { time: false, auto: true, range: linearRange },
          y: { auto: true, range: linearRange, dir: def.yDown ? -1 : 1 },
        },
        axes: [axis(def.xLabel, false, true), axis(def.yLabel)],
        series,
      };
    }
    const initial = def.mode === 1
      ? [[], ...labels.map(() => [])]
      : [null, ...labels.flatMap(() => Array.from({ length: def.perMethod }, () => [[], []]))];
    const plot = new uPlot(opts, initial, area);
    const item = { def, plot, figure, empty: figure.querySelector('.plot-empty') };
    figure.plotItem = item;
    this.plots.set(def.key, item);
    this.resize.observe(figure);
  }

  /** Sets every plot's data from the run store. */
  update(store) {
    for (const item of this.plots.values()) {
      const { def, plot } = item;
      if (def.mode === 1) {
        let x = [];
        for (const run of store.runs) if (run.t.length > x.length) x = run.t;
        const n = x.length;
        const ys = store.runs.map((run) => padded(def.pick(run), n));
        if (def.log) {
          // A log plot with nothing positive to draw says so instead.
          const none = !ys.some((y) => y.some((v) => v != null));
          item.empty.hidden = !none || store.received === 0;
          if (none) continue;
        }
        plot.setData([x, ...ys]);
      } else {
        const data = [null];
        for (const run of store.runs) data.push(...def.pairs(run));
        if (!data.slice(1).some(([xs]) => xs.length > 0)) continue;
        plot.setData(data);
      }
    }
  }

  /** Per plot, per series: the label and how many points it holds (for tests and the page). */
  pointCounts() {
    const out = {};
    for (const [key, { plot }] of this.plots) {
      out[key] = plot.series.slice(1).map((s, i) => {
        const data = plot.mode === 2 ? plot.data[i + 1]?.[0] ?? [] : plot.data[i + 1] ?? [];
        const points = plot.mode === 2 ? data.length : data.filter((v) => v != null).length;
        return { label: s.label, points };
      });
    }
    return out;
  }
}

/** A log axis labelled `label`, with gridlines at powers of ten. */
export function logAxis(label) {
  return {
    label, labelSize: 14, size: 56, labelGap: 0, values: logTicks, splits: logSplits,
    filter: (u, splits) => splits, stroke: '#333', grid: { stroke: '#e4e4e4', width: 1 },
    ticks: { stroke: '#ccc', width: 1 }, font: '11px system-ui, sans-serif', labelFont: '12px system-ui, sans-serif',
  };
}

/**
 * A faceted series drawn as a polyline through its points with a dot at each, and, where `spread`
 * gives each point's `lows` and `highs` (of y), a bar with end ticks from one to the other.
 */
function dotted(u, seriesIdx, spread = null) {
  const path = polyline(u, seriesIdx);
  const [xs, ys] = u.data[seriesIdx];
  const r = 3 * (window.devicePixelRatio || 1);
  for (let i = 0; i < xs.length; i++) {
    const px = u.valToPos(xs[i], 'x', true);
    const py = u.valToPos(ys[i], 'y', true);
    path.stroke.moveTo(px + r, py);
    path.stroke.arc(px, py, r, 0, 2 * Math.PI);
    const [low, high] = [spread?.lows?.[i], spread?.highs?.[i]];
    if (low > 0 && high > low) {
      const [top, bottom] = [u.valToPos(high, 'y', true), u.valToPos(low, 'y', true)];
      path.stroke.moveTo(px, top);
      path.stroke.lineTo(px, bottom);
      path.stroke.moveTo(px - r, top);
      path.stroke.lineTo(px + r, top);
      path.stroke.moveTo(px - r, bottom);
      path.stroke.lineTo(px + r, bottom);
    }
  }
  return path;
}

/**
 * A log–log diagram of a study in `area`: one polyline with dots per series, sized to the area.
 * `show` replaces the series (the plot is kept, and only its data set, while the labels stay the
 * same); `onHover(x, y)` gets pointer moves over the plot in CSS pixels; `nearest` finds the
 * dot under the pointer.
 */
export class LogLogPlot {
  /**
   * @param {HTMLElement} area
   * @param {string} xLabel
   * @param {string} yLabel
   * @param {(x: number, y: number) => void} onHover
   */
  constructor(area, xLabel, yLabel, onHover) {
    Object.assign(this, { area, xLabel, yLabel, onHover });
    /** The uPlot instance, once there is something to draw. */
    this.plot = null;
    /** The series shown: {label, colour, xs, ys}. */
    this.series = [];
    this.resize = new ResizeObserver(() => this.layout());
    this.resize.observe(area);
  }

  /**
   * Shows `series` ({label, colour, xs, ys} with positive values, and optionally `lows` and
   * `highs`: each point's spread in y, drawn as a bar).
   */
  show(series) {
    this.series = series;
    const data = [null, ...series.map((s) => [s.xs, s.ys])];
    if (!series.length) {
      // Nothing to draw yet (uPlot's faceted mode needs a series).
      this.plot?.destroy();
      this.plot = null;
      return;
    }
    const same = this.plot && this.plot.series.length === data.length
      && series.every((s, i) => this.plot.series[i + 1].label === s.label);
    if (same) {
      this.plot.setData(data);
      return;
    }
    this.plot?.destroy();
    const { width, height } = this.size();
    this.plot = new uPlot({
      width, height, mode: 2,
      legend: { show: false },
      cursor: { points: { show: false }, drag: { x: false, y: false } },
      scales: {
        x: { time: false, distr: 3, auto: true },
        // The bars of the spreads stay inside the plot.
        y: { distr: 3, auto: true, range: (u, min, max) => this.yRange(min, max) },
      },
      axes: [logAxis(this.xLabel), logAxis(this.yLabel)],
      series: [{}, ...series.map((s) => ({
        label: s.label, stroke: s.colour, width: 1.5, points: { show: false },
        paths: (u, i) => dotted(u, i, this.series[i - 1]),
        facets: [{ scale: 'x', auto: true }, { scale: 'y', auto: true }],
      }))],
    }, data, this.area);
    this.plot.over.addEventListener('pointermove', (event) => this.onHover(event.offsetX, event.offsetY));
  }

  /** The y range of the plot: the dots' `min` to `max`, widened to the spreads, in whole decades. */
  yRange(min, max) {
    const lows = this.series.flatMap((s) => s.lows ?? []).filter((v) => v > 0);
    const highs = this.series.flatMap((s) => s.highs ?? []).filter((v) => v > 0);
    const lo = Math.min(min ?? Infinity, ...lows);
    const hi = Math.max(max ?? -Infinity, ...highs);
    if (!(lo > 0 && hi >= lo)) return [min ?? 1, max ?? 10];
    return uPlot.rangeLog(lo, hi, 10, true);
  }

  /** The dot nearest to (x, y) in CSS pixels of the plot area, within 24 px: {series, index}. */
  nearest(x, y) {
    if (!this.plot) return null;
    let best = null;
    this.series.forEach((s, series) => s.xs.forEach((v, index) => {
      const d = Math.hypot(this.plot.valToPos(v, 'x') - x, this.plot.valToPos(s.ys[index], 'y') - y);
      if (d < 24 && (!best || d < best.d)) best = { d, series, index };
    }));
    return best;
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
