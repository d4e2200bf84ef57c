// The page's entry point: loads the catalogues, builds the form and the preset buttons, and runs
// simulations — streaming NDJSON into the plots with a progress bar, cancellable with the Cancel
// button or Esc; offers the finished run as JSON or a Rerun recording (rerun.js) and sets up the
// stability section (stability.js), the work–precision section (studies.js), the convergence
// section (convergence.js), the energy-error map section (energymap.js) and the recordings library
// (library.js), whose recordings it plots with the same charts. For tests it exposes
// `window.geomint` (the uPlot instances and their point counts) and the run's state as
// `data-run-state` on <body> (loading, idle, running, done, cancelled, error); `data-source` on
// the results says what they show (`run`, or `recording:<id>`).

import { catalogues, simulateStream, ApiError } from './api.js';
import { SimForm, el, chartName } from './form.js';
import { Charts, colour } from './charts.js';
import { RunStore, renderStats, downloadJson } from './results.js';
import { PRESETS, presetRequest } from './presets.js';
import { RerunPanel } from './rerun.js';
import { StabilityPanel } from './stability.js';
import { WorkPrecisionPanel } from './studies.js';
import { ConvergencePanel } from './convergence.js';
import { EnergyMapPanel } from './energymap.js';
import { RecordingsPanel, streamLines, describe, when } from './library.js';

/** Shortest time between two redraws while samples stream in, in milliseconds. Redraws of long
 * runs take longer; the pause after one is at least REDRAW_SHARE times its duration, so drawing
 * never takes more than a fraction of the main thread while lines keep arriving. */
const REDRAW_INTERVAL = 120;
const REDRAW_SHARE = 4;

const $ = (selector) => document.querySelector(selector);

const ui = {
  form: $('#sim-form'),
  run: $('#run'),
  cancel: $('#cancel'),
  progress: $('#progress'),
  status: $('#status'),
  legend: $('#legend'),
  plots: $('#plots'),
  stats: $('#stats-body'),
  download: $('#download-json'),
  results: $('#results'),
  loadError: $('#load-error'),
  presets: $('#preset-list'),
};

/** The .rrd download and the Rerun viewer; set up once the form exists. */
let rerun = null;

const charts = new Charts(ui.plots);
/** The current or last simulation. */
let current = null;
/** The simulation whose results are on the page (a refused request leaves the last one). */
let shown = null;
let form = null;

function setState(state) {
  document.body.dataset.runState = state;
}

function setStatus(text) {
  ui.status.textContent = text;
}

/** Builds the preset cards: a title, the paper, a description and one button per variant. */
function buildPresets() {
  ui.presets.replaceChildren(...PRESETS.map((group) => {
    const titleId = `preset-${group.id}`;
    return el('article', { class: 'preset', 'aria-labelledby': titleId },
      el('h3', { id: titleId }, group.title, ' ', el('small', { text: group.paper })),
      el('p', { text: group.text }),
      el('div', { class: 'preset-buttons', role: 'group', 'aria-label': `${group.title} (${group.paper})` },
        group.variants.map((v) => el('button', {
          type: 'button', class: 'preset-button', 'data-preset': `${group.id}/${v.id}`,
          onclick: () => runPreset(group.id, v.id),
        }, v.label, v.note ? el('small', { text: v.note }) : null))));
  }));
}

/** Fills the form from a preset and runs it. */
function runPreset(groupId, variantId) {
  const request = presetRequest(groupId, variantId);
  if (!request || !form) return;
  form.fill(structuredClone(request));
  if (window.matchMedia('(max-width: 959px)').matches) {
    ui.results.scrollIntoView({ behavior: 'smooth', block: 'start' });
  }
  start();
}

/** Systems whose y axis points down, along gravity. */
const Y_DOWN = new Set(['elastic_pendulum_2d']);

/** The plots' coordinate names and captions for a run of `system` in chart `chartId`. */
function chartOptions(system, chartId) {
  const charts = system?.charts ?? [];
  const [first] = charts;
  const chart = charts.find((c) => c.id === chartId) ?? first;
  const other = chart && first && chart.id !== first.id;
  return {
    chartNames: chart?.coordinates,
    cartesianNames: first?.coordinates,
    chartNote: other ? `${chartName(chart.id)} chart coordinates (${chart.coordinates.join(', ')})` : null,
    cartesianNote: other ? `${chartName(first.id)} coordinates (${first.coordinates.join(', ')}) of the run in the ${chartName(chart.id)} chart` : null,
    yDown: Y_DOWN.has(system?.id),
  };
}

/** The legend: one colour per method. */
function renderLegend(labels) {
  ui.legend.replaceChildren(...labels.map((label, i) => el('li', {},
    el('span', { class: 'swatch', style: `background:${colour(i)}`, 'aria-hidden': 'true' }), label)));
}

/** Creates the plots and the legend for a stream `header`. */
function buildCharts(header) {
  const system = form.systems.find((s) => s.id === header.system.id);
  const source = system?.exact_solution ? 'exact' : header.energy_error ? 'ref' : null;
  charts.build(header, {
    energyErrorSource: header.energy_error ? source || 'ref' : null,
    drift: Boolean(system?.conformal_damping) && header.system.q0.length === 1,
    ...chartOptions(system, header.system.chart),
  });
  renderLegend(header.methods);
}

/**
 * Draws a stored recording's samples (read back from its .rrd by the server) with the page's
 * charts, in place of the results; a running simulation is cancelled first.
 */
async function showRecording(doc, entry) {
  if (current?.state === 'running') {
    current.controller.abort();
    await current.finished;
  }
  current = null;
  form.clearErrors();
  rerun.close();
  rerun.clearMessages();
  const { header, samples, summaries } = streamLines(doc);
  const store = new RunStore(doc.request, header);
  for (const chunk of samples) store.add(chunk);
  for (const summary of summaries) store.summarize(summary);
  store.outcome = 'done';
  shown = { store };
  buildCharts(header);
  charts.update(store);
  renderStats(ui.stats, store);
  ui.progress.max = Math.max(1, store.received);
  ui.progress.value = store.received;
  ui.download.disabled = store.received === 0;
  // The .rrd buttons of the results would run the request again: the library row has the file.
  rerun.setRun(null);
  ui.results.dataset.source = `recording:${entry.id}`;
  setStatus(`Recording ${describe(entry)}, stored ${when(entry.created)}: ${store.received} samples read back ` +
    'from the .rrd file (positions and momenta as recorded, in single precision).');
  setState('done');
  ui.results.scrollIntoView({ behavior: 'smooth', block: 'start' });
  ui.results.focus({ preventScroll: true });
}

/** Updates the plots, the stats table and the progress bar (at most every REDRAW_INTERVAL ms). */
function scheduleRedraw(run) {
  if (run.redrawPending) return;
  run.redrawPending = true;
  const pause = Math.max(REDRAW_INTERVAL, REDRAW_SHARE * (run.redrawCost || 0));
  const wait = Math.max(0, pause - (performance.now() - (run.lastRedraw || 0)));
  setTimeout(() => requestAnimationFrame(() => {
    run.redrawPending = false;
    if (run !== current || !run.store) return;
    redraw(run);
  }), wait);
}

function redraw(run) {
  const started = performance.now();
  charts.update(run.store);
  renderStats(ui.stats, run.store);
  const { received, expected } = run.store;
  ui.progress.max = Math.max(1, expected);
  ui.progress.value = received;
  if (run.state === 'running' && received > 0) {
    setStatus(`Running: ${received} of ${expected} samples (${Math.floor((100 * received) / Math.max(1, expected))} %).`);
  }
  // uPlot draws in a microtask after setData; this one runs after those.
  queueMicrotask(() => {
    run.lastRedraw = performance.now();
    run.redrawCost = run.lastRedraw - started;
  });
}

/** Handles one line of the stream. */
function onLine(run, line) {
  switch (line.type) {
    case 'header': {
      // The previous results stay until the new run has started.
      run.store = new RunStore(run.request, line);
      shown = run;
      ui.download.disabled = true;
      rerun.setRun(null);
      ui.results.dataset.source = 'run';
      buildCharts(line);
      renderStats(ui.stats, run.store);
      ui.progress.max = Math.max(1, run.store.expected);
      ui.progress.value = 0;
      setStatus(run.request.compare_to_reference
        ? 'Computing the reference solution…'
        : `Running ${line.methods.length} method${line.methods.length > 1 ? 's' : ''}…`);
      break;
    }
    case 'samples':
      run.store.add(line);
      scheduleRedraw(run);
      break;
    case 'summary':
      run.store.summarize(line);
      scheduleRedraw(run);
      break;
    case 'error':
      run.streamErrors.push(new ApiError(line.error, 0, line.method));
      break;
    default:
      break;
  }
}

/** Shows an error of the API beside its field; focuses that field. */
function showApiError(error) {
  const input = form.showError(error);
  const where = error.field && !error.message.startsWith(error.field) ? ` (field ${error.field})` : '';
  setStatus(`The server refused the request: ${error.message}${where}`);
  if (input) input.focus({ preventScroll: false });
}

/** Starts a simulation from the form, cancelling one that still runs. */
async function start() {
  if (current?.state === 'running') {
    current.controller.abort();
    await current.finished;
  }
  form.clearErrors();
  rerun.close();
  rerun.clearMessages();
  const request = form.read();
  const run = {
    request,
    controller: new AbortController(),
    store: null,
    state: 'running',
    streamErrors: [],
  };
  current = run;
  ui.progress.removeAttribute('value');
  ui.run.disabled = false;
  ui.cancel.disabled = false;
  setState('running');
  setStatus('Starting…');

  run.finished = (async () => {
    let outcome = 'done';
    try {
      await simulateStream(request, (line) => onLine(run, line), run.controller.signal);
    } catch (error) {
      if (error?.name === 'AbortError') {
        outcome = 'cancelled';
      } else if (error instanceof ApiError) {
        outcome = 'error';
        showApiError(error);
      } else {
        outcome = 'error';
        setStatus(`The run failed: ${error?.message || error}`);
      }
    }
    run.state = outcome;
    if (run.store) {
      run.store.outcome = outcome;
      redraw(run);
    }
    if (outcome === 'done' && run.streamErrors.length) {
      outcome = 'error';
      run.streamErrors.forEach((e) => form.showError(e));
      setStatus(`The run reported an error: ${run.streamErrors[0].message}`);
    } else if (outcome === 'done') {
      const stops = run.store.runs.map((r) => r.summary?.stop.reason);
      const odd = stops.filter((s) => s && s !== 'finished').length;
      setStatus(`Done: ${run.store.received} samples from ${run.store.runs.length} method${run.store.runs.length > 1 ? 's' : ''}` +
        (odd ? `; ${odd} stopped early (see the table).` : '.'));
    } else if (outcome === 'cancelled') {
      setStatus(run.store ? `Cancelled after ${run.store.received} samples; what arrived is shown.` : 'Cancelled.');
    }
    if (current === run) {
      ui.cancel.disabled = true;
      ui.download.disabled = !(shown?.store && shown.store.received > 0);
      rerun.setRun(shown?.store ?? null);
      if (run.store) ui.progress.value = outcome === 'done' ? ui.progress.max : ui.progress.value || 0;
      else ui.progress.value = 0;
      setState(outcome);
    }
    run.state = outcome;
  })();
  return run.finished;
}

function cancel() {
  if (current?.state === 'running') current.controller.abort();
}

async function init() {
  document.querySelector('#boot')?.remove();
  buildPresets();
  for (const button of ui.presets.querySelectorAll('button')) button.disabled = true;
  let cats;
  try {
    cats = await catalogues();
  } catch (error) {
    ui.loadError.hidden = false;
    ui.loadError.textContent = `Could not load the catalogues from the API: ${error.message}`;
    setState('error');
    return;
  }
  form = new SimForm(ui.form, cats);
  rerun = new RerunPanel({
    download: $('#download-rrd'),
    view: $('#view-rerun'),
    status: $('#rrd-status'),
    error: $('#err-rrd'),
    section: $('#rerun'),
    box: $('#rerun-viewer'),
    fallback: $('#rerun-fallback'),
    close: $('#rerun-close'),
  }, (error) => {
    const input = form.showError(error);
    if (input) input.focus({ preventScroll: false });
    return Boolean(input);
  });
  const stability = new StabilityPanel($('#stability'), cats.methods);
  const workPrecision = new WorkPrecisionPanel($('#work-precision'));
  const convergence = new ConvergencePanel($('#convergence'));
  const energyMap = new EnergyMapPanel($('#energy-map'), cats.methods);
  const library = new RecordingsPanel($('#recordings'), showRecording);
  for (const button of ui.presets.querySelectorAll('button')) button.disabled = false;
  ui.run.disabled = false;
  ui.form.addEventListener('submit', (event) => {
    event.preventDefault();
    start();
  });
  ui.cancel.addEventListener('click', cancel);
  document.addEventListener('keydown', (event) => {
    if (event.key === 'Escape') cancel();
  });
  ui.download.addEventListener('click', () => {
    if (shown?.store) downloadJson(shown.store);
  });
  window.geomint = {
    charts: charts.plots,
    pointCounts: () => charts.pointCounts(),
    runPreset,
    stability,
    workPrecision,
    convergence,
    energyMap,
    library,
  };
  setState('idle');
  await library.refresh();
  await library.followLink();
}

init();
