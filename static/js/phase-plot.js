// The plane of the Phase-space section: a canvas with two labelled axes over the ranges the form
// gives, the section's points of every orbit drawn as dots in the orbit's colour, a cursor the
// arrow keys move, and the conversions between pointer pixels and plane coordinates. It draws
// incrementally: new points are added to the picture without redrawing the old ones. Behind the
// points, the part of the plane outside the energy surface (where no orbit can start) is grey.

import { colour } from './charts.js';
import { fmt } from './common.js';
import { niceTicks } from './heatmap.js';

/** Space around the plot area for the axes, in CSS pixels. */
const MARGIN = { left: 58, right: 12, top: 10, bottom: 40 };
/** The shade of the plane's points outside the energy surface. */
export const FORBIDDEN = '#d4d4d4';

/** A value taken into [-period/2, period/2) (an angle's axis), or as it is. */
export function wrap(value, period) {
  if (!period) return value;
  return value - period * Math.floor(value / period + 0.5);
}

export class PhasePlot {
  /**
   * @param {HTMLCanvasElement} canvas
   * @param {{x: {name: string, min: number, max: number, period?: number},
   *          y: {name: string, min: number, max: number}}} plane
   */
  constructor(canvas, plane) {
    this.canvas = canvas;
    this.plane = plane;
    /** The keyboard cursor in plane coordinates, or null. */
    this.cursor = null;
    this.cssWidth = 0;
    this.cssHeight = 0;
    /** Every orbit's plane points, to redraw after a resize. */
    this.orbits = [];
    /**
     * The allowed region ({x, y, allowed} of POST /api/v1/simulate/allowed-region), or null: its
     * forbidden points are shaded grey behind the orbits.
     */
    this.region = null;
    /** The colour of orbit k, when not the palette's k-th. */
    this.colourOf = null;
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

  /** Plane coordinates to CSS pixels. */
  px(x, y) {
    const a = this.area;
    const { x: X, y: Y } = this.plane;
    return [a.x + ((x - X.min) / (X.max - X.min)) * a.w, a.y + a.h - ((y - Y.min) / (Y.max - Y.min)) * a.h];
  }

  /** CSS pixels (relative to the canvas) to plane coordinates, or null outside the plot area. */
  value(cx, cy) {
    const a = this.area;
    if (cx < a.x || cx > a.x + a.w || cy < a.y || cy > a.y + a.h) return null;
    const { x: X, y: Y } = this.plane;
    return [X.min + ((cx - a.x) / a.w) * (X.max - X.min), Y.min + ((a.y + a.h - cy) / a.h) * (Y.max - Y.min)];
  }

  /** Sets the size from the canvas's CSS width and redraws everything. */
  resize() {
    const width = Math.max(200, Math.floor(this.canvas.clientWidth || this.canvas.parentElement.clientWidth));
    this.cssWidth = width;
    this.cssHeight = Math.round(Math.min(560, Math.max(260, width * 0.75)));
    const dpr = window.devicePixelRatio || 1;
    this.canvas.width = Math.round(width * dpr);
    this.canvas.height = Math.round(this.cssHeight * dpr);
    this.canvas.style.height = `${this.cssHeight}px`;
    this.draw();
  }

  context() {
    const ctx = this.canvas.getContext('2d');
    const dpr = window.devicePixelRatio || 1;
    ctx.setTransform(dpr, 0, 0, dpr, 0, 0);
    return ctx;
  }

  /** Draws the axes, every orbit's points and the cursor. */
  draw() {
    const ctx = this.context();
    ctx.clearRect(0, 0, this.cssWidth, this.cssHeight);
    const a = this.area;
    ctx.fillStyle = '#ffffff';
    ctx.fillRect(a.x, a.y, a.w, a.h);
    this.shadeForbidden(ctx);
    ctx.strokeStyle = '#8a8a8a';
    ctx.lineWidth = 1;
    ctx.strokeRect(a.x + 0.5, a.y + 0.5, a.w - 1, a.h - 1);
    ctx.fillStyle = '#222222';
    ctx.font = '12px system-ui, sans-serif';
    const { x: X, y: Y } = this.plane;
    ctx.textAlign = 'center';
    ctx.textBaseline = 'top';
    for (const t of niceTicks(X.min, X.max)) {
      const [x] = this.px(t, Y.min);
      ctx.fillRect(x, a.y + a.h, 1, 4);
      ctx.fillText(fmt(t, 3), x, a.y + a.h + 6);
    }
    ctx.fillText(X.name, a.x + a.w / 2, a.y + a.h + 22);
    ctx.textAlign = 'right';
    ctx.textBaseline = 'middle';
    for (const t of niceTicks(Y.min, Y.max)) {
      const [, y] = this.px(X.min, t);
      ctx.fillRect(a.x - 4, y, 4, 1);
      ctx.fillText(fmt(t, 3), a.x - 6, y);
    }
    ctx.save();
    ctx.translate(12, a.y + a.h / 2);
    ctx.rotate(-Math.PI / 2);
    ctx.textAlign = 'center';
    ctx.fillText(Y.name, 0, 0);
    ctx.restore();
    this.orbits.forEach((points, k) => this.dots(ctx, k, points, 0));
    if (this.cursor) {
      const [x, y] = this.px(...this.cursor);
      ctx.strokeStyle = '#000000';
      ctx.strokeRect(x - 5.5, y - 5.5, 11, 11);
    }
  }

  /**
   * Shades the grid points of the region where no orbit can start, each as the cell around it
   * (half a grid step to either side), clipped to the plot area.
   */
  shadeForbidden(ctx) {
    const r = this.region;
    if (!r) return;
    const a = this.area;
    // The grid is even: half a step across and up.
    const dx = (r.x[r.x.length - 1] - r.x[0]) / (r.x.length - 1) / 2;
    const dy = (r.y[r.y.length - 1] - r.y[0]) / (r.y.length - 1) / 2;
    ctx.save();
    ctx.beginPath();
    ctx.rect(a.x, a.y, a.w, a.h);
    ctx.clip();
    ctx.fillStyle = FORBIDDEN;
    r.allowed.forEach((row, j) => {
      row.forEach((ok, i) => {
        if (ok) return;
        const [x0, y0] = this.px(r.x[i] - dx, r.y[j] + dy);
        const [x1, y1] = this.px(r.x[i] + dx, r.y[j] - dy);
        ctx.fillRect(x0, y0, x1 - x0 + 0.5, y1 - y0 + 0.5);
      });
    });
    ctx.restore();
  }

  /**
   * Whether plane point (x, y) lies inside the shaded region: {forbidden, i, j} of the nearest
   * grid point, or null off the grid. Near the boundary (an allowed grid point next to the
   * nearest) the grid cannot tell, and the point does not count as forbidden: the server decides.
   */
  regionAt(x, y) {
    const r = this.region;
    if (!r || r.x.length < 2 || r.y.length < 2) return null;
    const nearest = (v, t) => Math.round(((t - v[0]) / (v[v.length - 1] - v[0])) * (v.length - 1));
    const i = nearest(r.x, x);
    const j = nearest(r.y, y);
    if (i < 0 || j < 0 || i >= r.x.length || j >= r.y.length) return null;
    let forbidden = true;
    for (let dj = -1; dj <= 1; dj++) {
      for (let di = -1; di <= 1; di++) {
        if (r.allowed[j + dj]?.[i + di]) forbidden = false;
      }
    }
    return { forbidden, i, j };
  }

  /** Draws points `from…` of orbit `k`, clipped to the plot area. */
  dots(ctx, k, points, from) {
    const a = this.area;
    ctx.save();
    ctx.beginPath();
    ctx.rect(a.x, a.y, a.w, a.h);
    ctx.clip();
    ctx.fillStyle = this.colourOf ? this.colourOf(k) : colour(k);
    for (let i = from; i < points.length; i++) {
      const [x, y] = this.px(...points[i]);
      ctx.fillRect(x - 1, y - 1, 2.2, 2.2);
    }
    ctx.restore();
  }

  /** Adds plane points to orbit `k` and draws them. */
  add(k, points) {
    const list = (this.orbits[k] ??= []);
    const from = list.length;
    list.push(...points);
    this.dots(this.context(), k, list, from);
  }

  /** Forgets every orbit. */
  clear() {
    this.orbits = [];
    this.draw();
  }

  /** The point nearest to (cx, cy) within `radius` CSS pixels: {orbit, index} or null. */
  nearest(cx, cy, radius = 6) {
    let best = null;
    let bestDistance = radius * radius;
    this.orbits.forEach((points, orbit) => {
      points.forEach((p, index) => {
        const [x, y] = this.px(...p);
        const d = (x - cx) ** 2 + (y - cy) ** 2;
        if (d <= bestDistance) {
          bestDistance = d;
          best = { orbit, index };
        }
      });
    });
    return best;
  }
}
