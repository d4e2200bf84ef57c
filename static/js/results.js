// The results of one simulation as they stream in: per-method sample columns assembled from the
// NDJSON `samples` chunks (with the Cartesian image of the state when the chart is not Cartesian,
// and the bodies' positions when the system places its bodies itself), each method's `summary`,
// the stats table, and the downloadable JSON document (the same shape as the JSON answer of
// POST /api/v1/simulate, plus the request).

import { el, fmt, saveBlob } from './common.js';
import { colour } from './charts.js';
import { collectIndicators, indicatorColumns } from './chaos.js';

/** One method's samples and summary. */
function emptyRun(label, invariants, energyError) {
  return {
    label,
    t: [],
    q: [],
    p: [],
    cartesian_q: null,
    cartesian_p: null,
    energy: [],
    energy_error: energyError ? [] : null,
    invariants: Object.fromEntries(invariants.map((name) => [name, []])),
    jacobian_defect: null,
    summary: null,
    dissipation_drift: null,
    // Columns for the plots, kept up to date as chunks arrive (no copying at redraw time):
    // positions and momenta per degree of freedom, Cartesian positions (null in the Cartesian
    // chart, where they are qColumns), the bodies' coordinates (null unless the store places
    // bodies), and |energy error| with zeros as gaps.
    qColumns: [],
    pColumns: [],
    xColumns: null,
    bodyColumns: null,
    errorMagnitude: [],
  };
}

/** Appends the components of `rows` (one list per sample) to per-component `columns`. */
function appendColumns(columns, rows) {
  for (const row of rows) {
    for (let i = 0; i < row.length; i++) (columns[i] ??= []).push(row[i]);
  }
}

/** The samples of a simulation, filled chunk by chunk. */
export class RunStore {
  /**
   * @param {object} request the request body that was sent
   * @param {object} header the stream's `header` line
   * @param {((q: number[]) => number[]) | null} [embed] the bodies' coordinates at the
   *   configuration q, body after body, for a system whose bodies are its first coordinates
   *   (samples that carry `bodies` are plotted from those)
   * @param {object} [options]
   * @param {boolean} [options.energyFromInitial] plot |H − H₀| as the energy error of samples
   *   that carry none (an undamped run, whose H₀ is an exact reference, from a server that does
   *   not send it)
   */
  constructor(request, header, embed = null, { energyFromInitial = false } = {}) {
    this.request = request;
    this.header = header;
    this.embed = embed;
    this.energyFromInitial = energyFromInitial;
    this.runs = header.methods.map((label) => emptyRun(label, header.invariants, header.energy_error));
    /** How the stream ended: running, done, cancelled or error. */
    this.outcome = 'running';
  }

  /** Samples expected when every method finishes. */
  get expected() {
    const per = this.header.schedule.samples_per_method;
    return this.runs.reduce((sum, run) => sum + (run.summary ? run.t.length : per), 0);
  }

  /** Samples received so far. */
  get received() {
    return this.runs.reduce((sum, run) => sum + run.t.length, 0);
  }

  /** Appends a `samples` chunk. */
  add(chunk) {
    const run = this.runs[chunk.method];
    if (!run) return;
    if (chunk.offset !== run.t.length) {
      throw new Error(`samples of ${run.label} arrived out of order (offset ${chunk.offset}, have ${run.t.length})`);
    }
    run.t.push(...chunk.t);
    run.q.push(...chunk.q);
    run.p.push(...chunk.p);
    appendColumns(run.qColumns, chunk.q);
    appendColumns(run.pColumns, chunk.p);
    if (chunk.bodies) appendColumns(run.bodyColumns ??= [], chunk.bodies);
    else if (this.embed) appendColumns(run.bodyColumns ??= [], chunk.q.map(this.embed));
    if (chunk.cartesian_q) {
      (run.cartesian_q ??= []).push(...chunk.cartesian_q);
      (run.cartesian_p ??= []).push(...(chunk.cartesian_p ?? []));
      appendColumns(run.xColumns ??= [], chunk.cartesian_q);
    }
    run.energy.push(...chunk.energy);
    const magnitude = (e) => (e == null || e === 0 || !Number.isFinite(e) ? null : Math.abs(e));
    if (chunk.energy_error) {
      (run.energy_error ??= []).push(...chunk.energy_error);
      for (const e of chunk.energy_error) run.errorMagnitude.push(magnitude(e));
    } else if (this.energyFromInitial) {
      // The same difference the server takes against H₀; the download keeps only what it sent.
      const initial = run.energy[0];
      for (const e of chunk.energy) run.errorMagnitude.push(magnitude(e - initial));
    }
    for (const [name, values] of Object.entries(chunk.invariants || {})) {
      (run.invariants[name] ??= []).push(...values);
    }
    if (chunk.jacobian_defect) (run.jacobian_defect ??= []).push(...chunk.jacobian_defect);
    collectIndicators(run, chunk);
  }

  /** Records a method's `summary` line. */
  summarize(summary) {
    const run = this.runs[summary.method];
    if (!run) return;
    run.summary = summary;
    run.dissipation_drift = summary.dissipation_drift ?? null;
  }

  /** The simulation as a JSON document, like the API's JSON answer, with the request. */
  document() {
    return {
      request: this.request,
      system: this.header.system,
      schedule: this.header.schedule,
      invariants: this.header.invariants,
      runs: this.runs.map((run) => {
        const doc = {
          method: run.label,
          t: run.t,
          q: run.q,
          p: run.p,
        };
        if (run.cartesian_q) {
          doc.cartesian_q = run.cartesian_q;
          doc.cartesian_p = run.cartesian_p;
        }
        doc.energy = run.energy;
        if (run.energy_error) doc.energy_error = run.energy_error;
        doc.invariants = run.invariants;
        if (run.jacobian_defect) doc.jacobian_defect = run.jacobian_defect;
        if (run.dissipation_drift) doc.dissipation_drift = run.dissipation_drift;
        Object.assign(doc, indicatorColumns(run));
        if (run.summary?.indicators) doc.indicators = run.summary.indicators;
        doc.diverged_at = run.summary?.diverged_at ?? null;
        doc.stop = run.summary?.stop ?? { reason: 'incomplete' };
        doc.stats = run.summary?.stats ?? null;
        return doc;
      }),
    };
  }
}

const STOP_TEXT = {
  finished: 'finished',
  diverged: 'diverged',
  cancelled: 'cancelled',
  time_limit: 'time limit',
  failed: 'failed',
  indicator: 'threshold reached',
};

/** Fills the stats table body with one row per method. */
export function renderStats(tbody, store) {
  tbody.replaceChildren(...store.runs.map((run, i) => {
    const s = run.summary;
    const stop = s ? (STOP_TEXT[s.stop.reason] || s.stop.reason)
      : store.outcome === 'cancelled' ? 'cancelled' : store.outcome === 'error' ? 'no summary' : 'running…';
    const stopTitle = s?.stop.message || null;
    const diverged = s?.diverged_at ? `t = ${fmt(s.diverged_at.t)} (step ${s.diverged_at.step})` : '—';
    return el('tr', {},
      el('th', { scope: 'row' }, el('span', { class: 'swatch', style: `background:${colour(i)}`, 'aria-hidden': 'true' }), ' ', run.label),
      el('td', { text: s ? String(s.stats.steps) : '…' }),
      el('td', { text: s ? String(s.stats.force_evaluations) : '…' }),
      el('td', { text: s ? fmt(s.stats.wall_time_ms, 3) : '…' }),
      el('td', { text: String(run.t.length) }),
      el('td', { text: diverged }),
      el('td', { text: stop, title: stopTitle }));
  }));
}

/** Offers the store's document as a file download. */
export function downloadJson(store) {
  const blob = new Blob([JSON.stringify(store.document())], { type: 'application/json' });
  const stamp = new Date().toISOString().replace(/[:.]/g, '-').slice(0, 19);
  saveBlob(blob, `geomint-${store.header.system.id}-${stamp}.json`);
}
