// Chaos indicators on the page: the request fields a run asks them with, their columns collected
// from the stream's chunks, and their plots beside the energy — MEGNO's mean ⟨Y⟩ (2 on tori, 0
// for isochronous motion, growing like λt/2 in chaos), the fast Lyapunov indicator, the largest
// finite-time Lyapunov exponent, SALI and GALI on log axes — one series per method.

/** The indicators a run asks for when the page's "chaos indicators" box is ticked. */
export const PAGE_INDICATORS = ['lyapunov', 'megno', 'fli', 'sali'];

/** Column names of the scalar indicators, as samples and summaries name them. */
const SCALARS = ['megno', 'megno_mean', 'fli', 'sali', 'gali'];

/** Adds `indicators` to `request` when `asked`. */
export function askIndicators(request, asked) {
  if (asked) request.indicators = [...PAGE_INDICATORS];
  return request;
}

/** Whether `request` asks for indicators (to fill a form from a preset or link). */
export function asksIndicators(request) {
  return Array.isArray(request?.indicators) && request.indicators.length > 0;
}

/** Appends the indicator columns of a `samples` chunk to `run` (lyapunovColumns: one per exponent). */
export function collectIndicators(run, chunk) {
  for (const name of SCALARS) {
    if (chunk[name]) (run[name] ??= []).push(...chunk[name]);
  }
  if (chunk.lyapunov) {
    (run.lyapunov ??= []).push(...chunk.lyapunov);
    run.lyapunovColumns ??= [];
    for (const spectrum of chunk.lyapunov) {
      spectrum.forEach((x, i) => (run.lyapunovColumns[i] ??= []).push(x));
    }
  }
}

/** The indicator columns of `run` for the downloadable document. */
export function indicatorColumns(run) {
  const out = {};
  if (run.lyapunov) out.lyapunov = run.lyapunov;
  for (const name of SCALARS) if (run[name]) out[name] = run[name];
  return out;
}

/** A column for a log axis: values that underflowed to 0 become gaps. */
function positive(column) {
  return (column || []).map((x) => (x > 0 ? x : null));
}

/**
 * The "Chaos indicators" section of the plots for a stream `header`, or null when the runs carry
 * none. `timePlot(key, title, yLabel, pick, options)` is the charts' time-plot definition.
 */
export function chaosSection(header, timePlot) {
  const asked = header.indicators ?? [];
  if (!asked.length) return null;
  const plots = [];
  if (asked.includes('megno')) {
    plots.push(timePlot('chaos:megno_mean', 'MEGNO ⟨Y⟩(t)', '⟨Y⟩', (r) => r.megno_mean || [],
      { caption: '2 on tori, 0 for isochronous motion, ≈ λt/2 in chaos' }));
  }
  if (asked.includes('lyapunov')) {
    plots.push(timePlot('chaos:lyapunov', 'Largest Lyapunov exponent λ₁(t)', 'λ₁',
      (r) => r.lyapunovColumns?.[0] || [], { caption: 'finite-time estimate from the method’s tangent map' }));
  }
  if (asked.includes('fli')) {
    plots.push(timePlot('chaos:fli', 'Fast Lyapunov indicator', 'FLI', (r) => r.fli || [],
      { caption: 'sup ln‖w‖: grows like ln t on tori, linearly in chaos' }));
  }
  if (asked.includes('sali')) {
    plots.push(timePlot('chaos:sali', 'SALI(t)', 'SALI', (r) => positive(r.sali),
      { log: true, caption: 'tends to 0 in chaos; log axis' }));
  }
  if (asked.includes('gali')) {
    plots.push(timePlot('chaos:gali', 'GALI(t)', 'GALI', (r) => positive(r.gali),
      { log: true, caption: 'log axis' }));
  }
  return { id: 'chaos', title: 'Chaos indicators', plots };
}

/** A sweep run's chaos maps (key → {label, values, log}), empty when it carries none. */
export function chaosMetrics(run) {
  const maps = [
    ['megno_mean', 'MEGNO ⟨Y⟩', false],
    ['megno', 'MEGNO Y', false],
    ['lyapunov_max', 'largest Lyapunov exponent', false],
    ['fli', 'fast Lyapunov indicator', false],
    ['sali', 'SALI', true],
    ['gali', 'GALI', true],
    ['stopped_at', 'time a threshold stopped the run', false],
  ];
  const out = {};
  for (const [key, label, log] of maps) {
    if (run[key]?.some((v) => v != null)) out[key] = { label, values: run[key], log };
  }
  return out;
}

/**
 * The colour scale a chaos map opens with, on the indicator's own meaning: MEGNO's ⟨Y⟩ (and Y)
 * from 0 to 8 with 2 — regular motion on a torus — marked, larger values (chaos, growing like
 * λt/2) clipped to the top colour; λ_max from 0 (regular orbits tend to 0 like ln t / t) to the
 * largest value; the FLI from its least to its largest value. `values` are a map's finite values;
 * null for a metric that is not an indicator (its scale comes from the data).
 */
export function chaosScale(metric, values) {
  const top = values.length ? Math.max(...values) : 1;
  const bottom = values.length ? Math.min(...values) : 0;
  switch (metric) {
    case 'megno_mean':
    case 'megno':
      return { lo: 0, hi: 8, marks: [[2, '2 regular']], clipped: true };
    case 'lyapunov_max':
      return { lo: 0, hi: top > 0 ? top : 1, marks: [], clipped: false };
    case 'fli':
      return { lo: bottom, hi: top > bottom ? top : bottom + 1, marks: [], clipped: false };
    default:
      return null;
  }
}

/** What an indicator's value says of the orbit, in words (empty for other metrics). */
export function chaosMeaning(metric, value) {
  if (value == null || !Number.isFinite(value)) return '';
  if (metric === 'megno_mean') {
    if (value < 1.5) return 'below 2: periodic or isochronous motion';
    if (value <= 2.5) return 'about 2: regular, on a torus';
    return 'above 2: chaotic';
  }
  return '';
}
