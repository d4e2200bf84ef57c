// A results area that runs simulations: streams POST /api/v1/simulate (NDJSON) into a run store
// and draws it — plots, legend, stats table, progress bar and status line, redrawn at most every
// REDRAW_INTERVAL ms while lines arrive — cancellable, and offers the finished run as JSON and as a
// Rerun recording (rerun.js). Its elements are a copy of the page's results template (index.html),
// their ids prefixed with the results section's `data-prefix`: the Simulation section and the
// Your-system section each have one. What differs between them (which
// plots a run gets, where a refused request's error goes, where the state is shown) comes in as
// hooks.

import { simulateStream, ApiError } from './api.js';
import { el } from './common.js';
import { Charts, colour } from './charts.js';
import { RunStore, renderStats, downloadJson } from './results.js';
import { RerunPanel } from './rerun.js';

/** Shortest time between two redraws while samples stream in, in milliseconds. Redraws of long
 * runs take longer; the pause after one is at least REDRAW_SHARE times its duration, so drawing
 * never takes more than a fraction of the main thread while lines keep arriving. */
const REDRAW_INTERVAL = 120;
const REDRAW_SHARE = 4;

export class SimulationView {
  /**
   * @param {HTMLElement} results the results section (`data-source` says what it shows), filled
   *   from the results template (expandTemplates); its `data-status` is the first status line
   * @param {object} hooks
   * @param {(header: object, request: object) => object} hooks.chartOptions the options of
   *   Charts.build for a stream header and the request; their `bodies.embed`, if any, places the
   *   bodies for the run store, and `deriveEnergyError` has it take the energy error from H₀
   * @param {(error: ApiError) => HTMLElement|null} hooks.showError shows an error of the API beside
   *   the field it names; returns the input to focus, if any
   * @param {(state: string) => void} hooks.setState running, done, cancelled or error
   * @param {HTMLButtonElement} [cancel] "Cancel" (the form's)
   */
  constructor(results, { chartOptions, showError, setState }, cancel = null) {
    const prefix = results.dataset.prefix ?? '';
    const $ = (name) => results.querySelector(`#${CSS.escape(prefix + name)}`);
    this.ui = {
      results, plots: $('plots'), legend: $('legend'), stats: $('stats-body'), progress: $('progress'),
      status: $('status'), download: $('download-json'), cancel,
    };
    Object.assign(this, { chartOptions, showFieldError: showError, setState });
    this.rerun = new RerunPanel({
      download: $('download-rrd'), view: $('view-rerun'), status: $('rrd-status'),
      error: results.querySelector(`#err-${CSS.escape(prefix)}rrd`), section: $('rerun'), box: $('rerun-viewer'),
      fallback: $('rerun-fallback'), close: $('rerun-close'),
    }, (error) => {
      const input = showError(error);
      input?.focus({ preventScroll: false });
      return Boolean(input);
    });
    this.ui.status.textContent = results.dataset.status ?? '';
    this.charts = new Charts(this.ui.plots);
    /** The current or last simulation. */
    this.current = null;
    /** The simulation whose results are on show (a refused request leaves the last one). */
    this.shown = null;
    cancel?.addEventListener('click', () => this.cancel());
    this.ui.download.addEventListener('click', () => {
      if (this.shown?.store) downloadJson(this.shown.store);
    });
  }

  /** Whether a simulation is running. */
  get running() {
    return this.current?.state === 'running';
  }

  setStatus(text) {
    this.ui.status.textContent = text;
  }

  /** Cancels the running simulation, if any. */
  cancel() {
    if (this.running) this.current.controller.abort();
  }

  /** Cancels the running simulation and waits until it has stopped. */
  async stop() {
    if (!this.running) return;
    this.current.controller.abort();
    await this.current.finished;
  }

  /** The legend: one colour per method. */
  renderLegend(labels) {
    this.ui.legend.replaceChildren(...labels.map((label, i) => el('li', {},
      el('span', { class: 'swatch', style: `background:${colour(i)}`, 'aria-hidden': 'true' }), label)));
  }

  /** Creates the plots and the legend for a stream `header` with `options` of Charts.build. */
  buildCharts(header, options) {
    this.charts.build(header, options);
    this.renderLegend(header.methods);
  }

  /** A run store for `request` and its stream `header`, with the plots' `options`. */
  newStore(request, header, options) {
    return new RunStore(request, header, options.bodies?.embed ?? null, { energyFromInitial: options.deriveEnergyError });
  }

  /**
   * Shows the lines of a whole stream ({header, samples, summaries}: a recording read back, say)
   * of `request` in place of the results, as `source` (`data-source` of the results), with
   * `status` as the status line. A running simulation is cancelled first. The .rrd buttons stay
   * off: they would run the request again.
   */
  async present({ header, samples, summaries }, request, source, status) {
    await this.stop();
    this.current = null;
    this.rerun.close();
    this.rerun.clearMessages();
    const options = this.chartOptions(header, request);
    const store = this.newStore(request, header, options);
    for (const chunk of samples) store.add(chunk);
    for (const summary of summaries) store.summarize(summary);
    store.outcome = 'done';
    this.shown = { store };
    this.buildCharts(header, options);
    this.charts.update(store);
    renderStats(this.ui.stats, store);
    this.ui.progress.max = Math.max(1, store.received);
    this.ui.progress.value = store.received;
    this.ui.download.disabled = store.received === 0;
    this.rerun.setRun(null);
    this.ui.results.dataset.source = source;
    this.setStatus(status);
    this.setState('done');
    return store;
  }

  /** Updates the plots, the stats table and the progress bar (at most every REDRAW_INTERVAL ms). */
  scheduleRedraw(run) {
    if (run.redrawPending) return;
    run.redrawPending = true;
    const pause = Math.max(REDRAW_INTERVAL, REDRAW_SHARE * (run.redrawCost || 0));
    const wait = Math.max(0, pause - (performance.now() - (run.lastRedraw || 0)));
    setTimeout(() => requestAnimationFrame(() => {
      run.redrawPending = false;
      if (run !== this.current || !run.store) return;
      this.redraw(run);
    }), wait);
  }

  redraw(run) {
    const started = performance.now();
    this.charts.update(run.store);
    renderStats(this.ui.stats, run.store);
    const { received, expected } = run.store;
    this.ui.progress.max = Math.max(1, expected);
    this.ui.progress.value = received;
    if (run.state === 'running' && received > 0) {
      this.setStatus(`Running: ${received} of ${expected} samples (${Math.floor((100 * received) / Math.max(1, expected))} %).`);
    }
    // uPlot draws in a microtask after setData; this one runs after those.
    queueMicrotask(() => {
      run.lastRedraw = performance.now();
      run.redrawCost = run.lastRedraw - started;
    });
  }

  /** Handles one line of the stream. */
  onLine(run, line) {
    switch (line.type) {
      case 'header': {
        // The previous results stay until the new run has started.
        const options = this.chartOptions(line, run.request);
        run.store = this.newStore(run.request, line, options);
        this.shown = run;
        this.ui.download.disabled = true;
        this.rerun.setRun(null);
        this.ui.results.dataset.source = 'run';
        this.buildCharts(line, options);
        renderStats(this.ui.stats, run.store);
        this.ui.progress.max = Math.max(1, run.store.expected);
        this.ui.progress.value = 0;
        this.setStatus(run.request.compare_to_reference
          ? 'Computing the reference solution…'
          : `Running ${line.methods.length} method${line.methods.length > 1 ? 's' : ''}…`);
        break;
      }
      case 'samples':
        run.store.add(line);
        this.scheduleRedraw(run);
        break;
      case 'summary':
        run.store.summarize(line);
        this.scheduleRedraw(run);
        break;
      case 'error':
        run.streamErrors.push(new ApiError(line.error, 0, line.method));
        break;
      default:
        break;
    }
  }

  /** Shows an error of the API beside its field and in the status line; focuses that field. */
  showApiError(error) {
    const input = this.showFieldError(error);
    const where = error.field && !error.message.startsWith(error.field) ? ` (field ${error.field})` : '';
    this.setStatus(`The server refused the request: ${error.message}${where}`);
    if (input) input.focus({ preventScroll: false });
  }

  /**
   * Runs `request` (the body of POST /api/v1/simulate), cancelling a simulation that still runs.
   * Resolves once it has ended; its outcome is in the state.
   */
  async start(request) {
    await this.stop();
    this.rerun.close();
    this.rerun.clearMessages();
    const run = {
      request,
      controller: new AbortController(),
      store: null,
      state: 'running',
      streamErrors: [],
    };
    this.current = run;
    this.ui.progress.removeAttribute('value');
    if (this.ui.cancel) this.ui.cancel.disabled = false;
    this.setState('running');
    this.setStatus('Starting…');

    run.finished = (async () => {
      let outcome = 'done';
      try {
        await simulateStream(request, (line) => this.onLine(run, line), run.controller.signal);
      } catch (error) {
        if (error?.name === 'AbortError') {
          outcome = 'cancelled';
        } else if (error instanceof ApiError) {
          outcome = 'error';
          this.showApiError(error);
        } else {
          outcome = 'error';
          this.setStatus(`The run failed: ${error?.message || error}`);
        }
      }
      run.state = outcome;
      if (run.store) {
        run.store.outcome = outcome;
        this.redraw(run);
      }
      if (outcome === 'done' && run.streamErrors.length) {
        outcome = 'error';
        run.streamErrors.forEach((e) => this.showFieldError(e));
        this.setStatus(`The run reported an error: ${run.streamErrors[0].message}`);
      } else if (outcome === 'done') {
        const stops = run.store.runs.map((r) => r.summary?.stop.reason);
        const odd = stops.filter((s) => s && s !== 'finished').length;
        this.setStatus(`Done: ${run.store.received} samples from ${run.store.runs.length} method${run.store.runs.length > 1 ? 's' : ''}` +
          (odd ? `; ${odd} stopped early (see the table).` : '.'));
      } else if (outcome === 'cancelled') {
        this.setStatus(run.store ? `Cancelled after ${run.store.received} samples; what arrived is shown.` : 'Cancelled.');
      }
      if (this.current === run) {
        const { store } = this.shown ?? {};
        if (this.ui.cancel) this.ui.cancel.disabled = true;
        this.ui.download.disabled = !(store && store.received > 0);
        this.rerun.setRun(store ?? null);
        if (run.store) this.ui.progress.value = outcome === 'done' ? this.ui.progress.max : this.ui.progress.value || 0;
        else this.ui.progress.value = 0;
        this.setState(outcome);
      }
      run.state = outcome;
    })();
    return run.finished;
  }
}
