// Maps drawn on a canvas (uPlot has no heatmap): a generic grid of cells (`GridMap`) with labelled
// axes, overlays in cell units, a cursor cell moved by the pointer or the arrow keys, and a colour
// scale bar; and its use for the stability section's spectral-radius maps (`Heatmap`): one cell per
// (γ, h) grid point, γ across and h upwards, coloured on a log scale of the spectral radius ρ —
// blues where the method is stable (ρ ≤ 1), oranges to reds where it is not, grey where it is
// undefined — with the analytic stability boundaries drawn along the cell edges where a
// relation's verdict changes; and the colours of ratio maps (`ratioColour`). The energy-error map
// (energymap.js) and the sweeps (sweep.js) are GridMaps too.

import { el, fmt } from './common.js';

/** Margins of the plot area inside the canvas, in CSS pixels. */
const MARGIN = { left: 48, right: 10, top: 8, bottom: 38 };
const FONT = '11px system-ui, sans-serif';
/** The tallest plot area of a map drawn in its axes' true aspect, in CSS pixels. */
const ASPECT_MAX_HEIGHT = 560;
const LABEL_FONT = 'italic 13px system-ui, sans-serif';

const STABLE_STOPS = ['#c6dbef', '#9ecae1', '#6baed6', '#3182bd', '#08519c', '#08306b'];
const UNSTABLE_STOPS = ['#fdae6b', '#fd8d3c', '#e6550d', '#c2410c', '#a63603', '#67000d'];
export const UNDEFINED_COLOUR = '#8f8f8f';
export const BOUNDARY_COLOUR = '#111111';
export const PRINTED_COLOUR = '#7b2cbf';

function hexRgb(hex) {
  const n = parseInt(hex.slice(1), 16);
  return [(n >> 16) & 255, (n >> 8) & 255, n & 255];
}
const STABLE_RGB = STABLE_STOPS.map(hexRgb);
const UNSTABLE_RGB = UNSTABLE_STOPS.map(hexRgb);

/** The colour at `t` ∈ [0, 1] along `stops` (linear in RGB between them). */
function ramp(stops, t) {
  const x = Math.min(1, Math.max(0, t)) * (stops.length - 1);
  const i = Math.min(stops.length - 2, Math.floor(x));
  const f = x - i;
  const a = stops[i];
  const b = stops[i + 1];
  return [0, 1, 2].map((k) => Math.round(a[k] + (b[k] - a[k]) * f));
}

/**
 * The colour scale of a set of maps: log10 of the smallest and largest finite spectral radius,
 * at least ±0.1 decade around ρ = 1.
 */
export function colourScale(maps) {
  let lo = Infinity;
  let hi = -Infinity;
  for (const map of maps) {
    for (const row of map.spectral_radius) {
      for (const rho of row) {
        if (rho == null || !(rho > 0)) continue;
        if (rho < lo) lo = rho;
        if (rho > hi) hi = rho;
      }
    }
  }
  return {
    lo: Math.min(-0.1, Number.isFinite(lo) ? Math.log10(lo) : -1),
    hi: Math.max(0.1, Number.isFinite(hi) ? Math.log10(hi) : 1),
  };
}

/** Ratio maps (energy map, sweep comparisons) saturate at a factor 10^RATIO_RANGE either way. */
export const RATIO_RANGE = 2;

/**
 * The colour of `e`, the log₁₀ of a ratio of two errors: white at 1, blue below, red above,
 * saturated at ±`range` (decades; RATIO_RANGE unless given).
 */
export function ratioColour(e, range = RATIO_RANGE) {
  const ratio = Math.min(1, Math.max(-1, e / range));
  const fade = Math.round(255 * (1 - Math.abs(ratio)));
  return ratio < 0 ? [fade, fade, 255] : [255, fade, fade];
}

/** The share of a ratio map's cells its scale holds; the others take the deepest colours. */
export const RATIO_SHARE = 0.98;

/**
 * The range of a ratio map scaled to its data: the |log₁₀ ratio| that RATIO_SHARE of the finite
 * `logs` stay within (a few outliers do not wash the rest out to white), symmetric about 1, at
 * least `floor` decades (a map of equal errors).
 */
export function dataRatioRange(logs, floor = 1e-3) {
  const sizes = logs.filter(Number.isFinite).map(Math.abs).sort((a, b) => a - b);
  if (!sizes.length) return floor;
  return Math.max(floor, sizes[Math.floor(RATIO_SHARE * (sizes.length - 1))]);
}

/**
 * About five ticks of a ratio scale of ±`range` decades: [log₁₀ r, text], the text the ratio
 * itself (`1.08`, `1/1.08`, `1`).
 */
export function ratioTicks(range) {
  const text = (e) => (e === 0 ? '1' : e > 0 ? fmt(10 ** e, 3) : `1/${fmt(10 ** -e, 3)}`);
  return [-range, -range / 2, 0, range / 2, range].map((e) => [e, text(e)]);
}

/** The RGB colour of a cell: its spectral radius and the numerical verdict. */
export function cellColour(rho, stable, scale) {
  if (rho == null || !Number.isFinite(rho)) return hexRgb(UNDEFINED_COLOUR);
  const e = Math.log10(Math.max(rho, 1e-300));
  return stable ? ramp(STABLE_RGB, e / scale.lo) : ramp(UNSTABLE_RGB, e / scale.hi);
}

/** About `count` round tick values within [a, b]. */
export function niceTicks(a, b, count = 5) {
  if (!(b > a)) return [a];
  const raw = (b - a) / count;
  const mag = 10 ** Math.floor(Math.log10(raw));
  const step = [1, 2, 2.5, 5, 10].map((m) => m * mag).find((s) => s >= raw) || 10 * mag;
  const out = [];
  for (let v = Math.ceil(a / step - 1e-9) * step; v <= b + step * 1e-9; v += step) {
    out.push(Math.abs(v) < step * 1e-9 ? 0 : +v.toPrecision(12));
  }
  return out;
}

/** The k-th of `n` evenly spaced values from `min` to `max` (the API's axis definition). */
export function axisValue(axis, k) {
  return axis.n > 1 ? axis.min + ((axis.max - axis.min) * k) / (axis.n - 1) : axis.min;
}

/** Sets a canvas's backing size for `width` × `height` CSS pixels; returns its 2-D context. */
function sized(canvas, width, height) {
  const dpr = window.devicePixelRatio || 1;
  const w = Math.round(width * dpr);
  const h = Math.round(height * dpr);
  if (canvas.width !== w || canvas.height !== h) {
    canvas.width = w;
    canvas.height = h;
  }
  canvas.style.height = `${height}px`;
  const ctx = canvas.getContext('2d');
  ctx.setTransform(dpr, 0, 0, dpr, 0, 0);
  return ctx;
}

/**
 * A grid of cells on a canvas. Column c sits at x.min + c·Δx and row r at y.min + r·Δy (the API's
 * axis definition); the axes reach half a cell beyond the first and last values. Rows grow upwards,
 * or downwards with `yDown`. Overlays are drawn in cell units: u counts column edges from the left,
 * v row edges from row 0's outer edge.
 */
export class GridMap {
  /**
   * @param {HTMLCanvasElement} canvas
   * @param {object} options
   * @param {{min: number, max: number, n: number, label: string}} options.x the columns
   * @param {{min: number, max: number, n: number, label: string}} options.y the rows
   * @param {(col: number, row: number) => number[]} options.colour a cell's RGB colour
   * @param {boolean} [options.yDown] row 0 at the top
   * @param {(width: number, area: {w: number}) => number} [options.height] CSS height for a width
   * @param {number|null} [options.aspect] the plot area's height over its width, when the axes
   *   share a unit and the cells are drawn in their true shape (the canvas then narrows if the
   *   height would pass ASPECT_MAX_HEIGHT)
   */
  constructor(canvas, { x, y, colour, yDown = false, height = null, aspect = null }) {
    this.canvas = canvas;
    this.xAxis = x;
    this.yAxis = y;
    this.cols = x.n;
    this.rows = y.n;
    this.yDown = yDown;
    this.colourOf = colour;
    this.aspect = aspect;
    this.heightFor = height || ((width) => Math.round(Math.min(340, Math.max(200, width * 0.66))));
    /** The cursor cell {col, row} or null. */
    this.cursor = null;
    this.cssWidth = 0;
    this.cssHeight = 0;
    canvas.dataset.columns = String(this.cols);
    canvas.dataset.rows = String(this.rows);
    canvas.dataset.cells = String(this.cols * this.rows);
    this.image = this.cellImage();
  }

  /** The cells as an image, one pixel per cell. */
  cellImage() {
    const image = document.createElement('canvas');
    image.width = this.cols;
    image.height = this.rows;
    const ctx = image.getContext('2d');
    const data = ctx.createImageData(this.cols, this.rows);
    for (let r = 0; r < this.rows; r++) {
      const y = this.yDown ? r : this.rows - 1 - r;
      for (let c = 0; c < this.cols; c++) {
        const [R, G, B] = this.colourOf(c, r);
        const o = 4 * (y * this.cols + c);
        data.data[o] = R;
        data.data[o + 1] = G;
        data.data[o + 2] = B;
        data.data[o + 3] = 255;
      }
    }
    ctx.putImageData(data, 0, 0);
    return image;
  }

  /** The plot area in CSS pixels. */
  get area() {
    return {
      x: MARGIN.left,
      y: MARGIN.top,
      w: Math.max(10, this.cssWidth - MARGIN.left - MARGIN.right),
      h: Math.max(10, this.cssHeight - MARGIN.top - MARGIN.bottom),
    };
  }

  /** Sets the size from the canvas's CSS width and draws. */
  resize() {
    if (this.aspect) {
      const room = Math.max(160, Math.floor(this.canvas.parentElement.clientWidth)) - MARGIN.left - MARGIN.right;
      const h = Math.min(ASPECT_MAX_HEIGHT, room * this.aspect);
      const w = h / this.aspect;
      this.cssWidth = Math.round(w + MARGIN.left + MARGIN.right);
      this.cssHeight = Math.round(h + MARGIN.top + MARGIN.bottom);
      this.canvas.style.width = `${this.cssWidth}px`;
      this.draw();
      return;
    }
    const width = Math.max(160, Math.floor(this.canvas.clientWidth || this.canvas.parentElement.clientWidth));
    this.cssWidth = width;
    this.cssHeight = this.heightFor(width, { w: width - MARGIN.left - MARGIN.right });
    this.draw();
  }

  /** Cell-unit coordinates to CSS pixels. */
  px(u, v) {
    const a = this.area;
    const down = (v / this.rows) * a.h;
    return [a.x + (u / this.cols) * a.w, this.yDown ? a.y + down : a.y + a.h - down];
  }

  /** Axis values (x, y) to cell units. */
  cellUnits(x, y) {
    const unit = (axis, value) => (axis.n > 1 && axis.max > axis.min
      ? ((value - axis.min) / (axis.max - axis.min)) * (axis.n - 1) + 0.5
      : 0.5);
    return [unit(this.xAxis, x), unit(this.yAxis, y)];
  }

  /** The cell under CSS pixel (x, y), or null outside the plot area. */
  cellAt(x, y) {
    const a = this.area;
    if (x < a.x || x > a.x + a.w || y < a.y || y > a.y + a.h) return null;
    const down = (y - a.y) / a.h;
    const col = Math.min(this.cols - 1, Math.max(0, Math.floor(((x - a.x) / a.w) * this.cols)));
    const row = Math.min(this.rows - 1, Math.max(0, Math.floor((this.yDown ? down : 1 - down) * this.rows)));
    return { col, row };
  }

  /** The centre of a cell in CSS pixels (for tests and keyboard focus). */
  cellCentre(col, row) {
    return this.px(col + 0.5, row + 0.5);
  }

  draw() {
    if (!this.cssWidth) return;
    const ctx = sized(this.canvas, this.cssWidth, this.cssHeight);
    const a = this.area;
    ctx.clearRect(0, 0, this.cssWidth, this.cssHeight);
    ctx.imageSmoothingEnabled = false;
    ctx.drawImage(this.image, a.x, a.y, a.w, a.h);
    this.drawOverlay(ctx);
    this.drawAxes(ctx, a);
    if (this.cursor) {
      const [x0, y0] = this.px(this.cursor.col, this.cursor.row);
      const [x1, y1] = this.px(this.cursor.col + 1, this.cursor.row + 1);
      const w = Math.max(4, Math.abs(x1 - x0));
      const h = Math.max(4, Math.abs(y1 - y0));
      const cx = (x0 + x1) / 2 - w / 2;
      const cy = (y0 + y1) / 2 - h / 2;
      ctx.lineWidth = 3;
      ctx.strokeStyle = '#ffffff';
      ctx.strokeRect(cx - 1, cy - 1, w + 2, h + 2);
      ctx.lineWidth = 1.5;
      ctx.strokeStyle = '#000000';
      ctx.strokeRect(cx - 1, cy - 1, w + 2, h + 2);
    }
  }

  /** Draws what lies over the cells (boundaries); nothing here. */
  drawOverlay() {}

  /**
   * Strokes polylines given in cell units, clipped to the plot area.
   * @param {CanvasRenderingContext2D} ctx
   * @param {number[][][]} lines each a list of [u, v] points
   * @param {{colour: string, width: number, dash?: number[], cap?: CanvasLineCap}} style
   */
  strokeLines(ctx, lines, { colour, width, dash = [], cap = 'butt' }) {
    if (!lines?.length) return;
    const a = this.area;
    ctx.save();
    ctx.beginPath();
    ctx.rect(a.x, a.y, a.w, a.h);
    ctx.clip();
    ctx.beginPath();
    for (const line of lines) {
      line.forEach(([u, v], i) => (i ? ctx.lineTo(...this.px(u, v)) : ctx.moveTo(...this.px(u, v))));
    }
    ctx.strokeStyle = colour;
    ctx.lineWidth = width;
    ctx.setLineDash(dash);
    ctx.lineCap = cap;
    ctx.lineJoin = 'round';
    ctx.stroke();
    ctx.restore();
  }

  drawAxes(ctx, a) {
    ctx.strokeStyle = '#333';
    ctx.lineWidth = 1;
    ctx.setLineDash([]);
    ctx.strokeRect(a.x - 0.5, a.y - 0.5, a.w + 1, a.h + 1);
    ctx.fillStyle = '#333';
    ctx.font = FONT;
    const { xAxis, yAxis } = this;
    const xTicks = niceTicks(xAxis.min, xAxis.max, Math.max(2, Math.floor(a.w / 60)));
    ctx.textAlign = 'center';
    ctx.textBaseline = 'top';
    for (const value of xTicks) {
      const [x] = this.px(this.cellUnits(value, yAxis.min)[0], 0);
      ctx.fillRect(Math.round(x) - 0.5, a.y + a.h, 1, 4);
      ctx.fillText(fmt(value), x, a.y + a.h + 6);
    }
    const yTicks = niceTicks(yAxis.min, yAxis.max, Math.max(2, Math.floor(a.h / 40)));
    ctx.textAlign = 'right';
    ctx.textBaseline = 'middle';
    for (const value of yTicks) {
      const [, y] = this.px(0, this.cellUnits(xAxis.min, value)[1]);
      ctx.fillRect(a.x - 4, Math.round(y) - 0.5, 4, 1);
      ctx.fillText(fmt(value), a.x - 6, y);
    }
    ctx.font = LABEL_FONT;
    ctx.textAlign = 'center';
    ctx.textBaseline = 'bottom';
    ctx.fillText(xAxis.label, a.x + a.w / 2, this.cssHeight - 2);
    ctx.save();
    ctx.translate(12, a.y + a.h / 2);
    ctx.rotate(-Math.PI / 2);
    ctx.textBaseline = 'middle';
    ctx.fillText(yAxis.label, 0, 0);
    ctx.restore();
  }
}

/**
 * Pointer and keyboard control of a map's cursor: the pointer picks the cell under it; a focused
 * map moves the cursor with the arrow keys (Shift: ten columns), Page Up/Down (ten rows), Home and
 * End. Up is up on the screen whichever way the rows grow. `set(cell)` moves the cursor; `get()`
 * returns it (or null).
 * @param {GridMap} map
 * @param {{get: () => ({col: number, row: number}|null), set: (cell: {col: number, row: number}) => void}} cursor
 */
export function bindCursor(map, { get, set }) {
  const canvas = map.canvas;
  const fromPointer = (event) => {
    const cell = map.cellAt(event.offsetX, event.offsetY);
    if (cell) set(cell);
  };
  canvas.addEventListener('pointermove', fromPointer);
  canvas.addEventListener('pointerdown', fromPointer);
  canvas.addEventListener('focus', () => {
    set(get() || { col: Math.floor(map.cols / 2), row: Math.floor(map.rows / 2) });
  });
  canvas.addEventListener('keydown', (event) => {
    const c = get() || { col: 0, row: 0 };
    const moves = {
      ArrowLeft: [-1, 0], ArrowRight: [1, 0], ArrowUp: [0, 1], ArrowDown: [0, -1],
      PageUp: [0, 10], PageDown: [0, -10], Home: [-map.cols, 0], End: [map.cols, 0],
    };
    const move = moves[event.key];
    if (!move) return;
    event.preventDefault();
    const step = event.shiftKey && move[0] !== 0 && Math.abs(move[0]) === 1 ? 10 : 1;
    const up = map.yDown ? -1 : 1;
    set({
      col: Math.min(map.cols - 1, Math.max(0, c.col + move[0] * step)),
      row: Math.min(map.rows - 1, Math.max(0, c.row + up * move[1])),
    });
  });
}

/** One method's spectral-radius map. */
export class Heatmap extends GridMap {
  /**
   * @param {HTMLCanvasElement} canvas
   * @param {object} map one entry of the API's `maps`
   * @param {{gamma: object, h: object}} axes the answer's axes (columns γ, rows h)
   * @param {{lo: number, hi: number}} scale
   */
  constructor(canvas, map, axes, scale) {
    super(canvas, {
      x: { ...axes.gamma, label: 'γ' },
      y: { ...axes.h, label: 'h' },
      colour: (c, r) => cellColour(map.spectral_radius[r][c], map.stable[r][c], scale),
    });
    this.map = map;
    this.gamma = axes.gamma;
    this.h = axes.h;
    this.scale = scale;
    this.showPrinted = true;
    this.boundaries = {
      analytic: map.analytic ? this.boundary(map.analytic) : null,
      printed: map.printed ? this.boundary(map.printed) : null,
    };
  }

  /**
   * The cell edges across which `verdict` (rows × columns of booleans) changes, as segments in
   * cell units: [[u0, v0], [u1, v1]] with u the column edge and v the row edge.
   */
  boundary(verdict) {
    const segments = [];
    for (let r = 0; r < this.rows; r++) {
      for (let c = 0; c < this.cols; c++) {
        if (c + 1 < this.cols && verdict[r][c] !== verdict[r][c + 1]) segments.push([[c + 1, r], [c + 1, r + 1]]);
        if (r + 1 < this.rows && verdict[r][c] !== verdict[r + 1][c]) segments.push([[c, r + 1], [c + 1, r + 1]]);
      }
    }
    return segments;
  }

  drawOverlay(ctx) {
    if (this.showPrinted) this.strokeLines(ctx, this.boundaries.printed, { colour: PRINTED_COLOUR, width: 1.5, dash: [4, 3], cap: 'square' });
    this.strokeLines(ctx, this.boundaries.analytic, { colour: BOUNDARY_COLOUR, width: 2, cap: 'square' });
  }

  /** The values at a cell, for the readout. */
  cell(col, row) {
    const verdict = (grid) => (grid ? grid[row][col] : null);
    return {
      col,
      row,
      gamma: axisValue(this.gamma, col),
      h: axisValue(this.h, row),
      rho: this.map.spectral_radius[row][col],
      stable: this.map.stable[row][col],
      analytic: verdict(this.map.analytic),
      printed: verdict(this.map.printed),
    };
  }
}

/**
 * Draws a horizontal colour bar on `canvas`, as wide as its parent: the colour `colourAt(e)` for e
 * from `lo` to `hi`, with a tick and label at each of `ticks` ([e, text] pairs); `label` becomes
 * the canvas's accessible name.
 */
export function drawScaleBar(canvas, { lo, hi, colourAt, ticks, label }) {
  const width = Math.max(200, Math.floor(canvas.parentElement.clientWidth));
  const height = 40;
  const ctx = sized(canvas, width, height);
  const left = 12;
  const right = width - 16;
  const barTop = 2;
  const barHeight = 14;
  const span = hi - lo;
  const xOf = (e) => left + ((e - lo) / span) * (right - left);
  ctx.clearRect(0, 0, width, height);
  for (let x = left; x < right; x++) {
    const [R, G, B] = colourAt(lo + ((x + 0.5 - left) / (right - left)) * span);
    ctx.fillStyle = `rgb(${R},${G},${B})`;
    ctx.fillRect(x, barTop, 1, barHeight);
  }
  ctx.strokeStyle = '#333';
  ctx.lineWidth = 1;
  ctx.strokeRect(left - 0.5, barTop - 0.5, right - left + 1, barHeight + 1);
  ctx.fillStyle = '#333';
  ctx.font = FONT;
  ctx.textBaseline = 'top';
  for (const [e, text] of ticks) {
    const x = xOf(e);
    ctx.fillRect(Math.round(x) - 0.5, barTop + barHeight, 1, 4);
    // Labels near the ends stay inside the canvas.
    const half = ctx.measureText(text).width / 2;
    ctx.textAlign = 'center';
    ctx.fillText(text, Math.min(width - half - 1, Math.max(half + 1, x)), barTop + barHeight + 6);
  }
  canvas.setAttribute('aria-label', label);
}

/** Draws the colour scale bar of `scale` on `canvas` (log ρ: stable left of 1, unstable right). */
export function drawColourScale(canvas, scale) {
  const decades = [];
  const step = Math.max(1, Math.ceil((scale.hi - scale.lo) / 8));
  for (let e = Math.ceil(scale.lo); e <= Math.floor(scale.hi); e += step) decades.push(e);
  if (!decades.includes(0)) decades.push(0);
  drawScaleBar(canvas, {
    lo: scale.lo,
    hi: scale.hi,
    colourAt: (e) => cellColour(10 ** e, e <= 0, scale),
    ticks: decades.map((e) => [e, e === 0 ? '1' : `1e${e}`]),
    label: `Colour scale of the spectral radius ρ on a log axis from ${fmt(10 ** scale.lo, 2)} to ${fmt(10 ** scale.hi, 2)}: ` +
      'light to dark blue for stable cells (ρ ≤ 1), orange to dark red for unstable ones, grey where the method is undefined.',
  });
}

/** The legend entries below the colour scale. */
export function scaleLegend() {
  return el('ul', { class: 'legend scale-legend' },
    el('li', {}, el('span', { class: 'swatch block', style: `background:${UNDEFINED_COLOUR}`, 'aria-hidden': 'true' }), 'undefined (csv2 at γh = 2)'),
    el('li', {}, el('span', { class: 'swatch line', style: `border-top-color:${BOUNDARY_COLOUR}`, 'aria-hidden': 'true' }), 'analytic boundary (corrected relation)'),
    el('li', { 'data-legend': 'printed' }, el('span', { class: 'swatch line dashed', style: `border-top-color:${PRINTED_COLOUR}`, 'aria-hidden': 'true' }), 'boundary of the printed relation'));
}
