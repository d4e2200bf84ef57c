// The page's entry point: loads the catalogues, builds the form and the preset buttons, and runs
// simulations into the results beside the form (simulation.js: streamed NDJSON in the plots with
// a progress bar, cancellable with the Cancel button or Esc, the finished run as JSON or a Rerun
// recording); sets up the Your-system section (system.js), the stability section (stability.js),
// the work–precision section (workprecision.js), the convergence section (convergence.js), the
// energy-error map section (energymap.js) and the recordings library (library.js), whose
// recordings it plots with the same charts. For tests it exposes `window.geomint` (the uPlot
// instances and their point counts, and the sections) and the run's state as `data-run-state` on
// <body> (loading, idle, running, done, cancelled, error); `data-source` on the results says what
// they show (`run`, or `recording:<id>`).

import { catalogues } from './api.js';
import { el, expandTemplates } from './common.js';
import { Sections } from './sections.js';
import { SimForm, chartName } from './form.js';
import { RunStore } from './results.js';
import { PRESETS, presetRequest } from './presets.js';
import { SimulationView } from './simulation.js';
import { SystemPanel } from './system.js';
import { StabilityPanel } from './stability.js';
import { WorkPrecisionPanel } from './workprecision.js';
import { ConvergencePanel } from './convergence.js';
import { EnergyMapPanel } from './energymap.js';
import { SweepPanel } from './sweep.js';
import { RecordingsPanel, streamLines, describe, when } from './library.js';

const $ = (selector) => document.querySelector(selector);

const ui = {
  form: $('#sim-form'),
  run: $('#run'),
  results: $('#results'),
  loadError: $('#load-error'),
  presets: $('#preset-list'),
};

/** The simulation form and the results beside it; set up once the catalogues are in. */
let form = null;
let view = null;
/** Which section of the page is on show. */
let sections = null;

function setState(state) {
  document.body.dataset.runState = state;
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

/** The options of the plots for a stream `header` of a built-in system. */
function plotOptions(header) {
  const system = form.systems.find((s) => s.id === header.system.id);
  const source = system?.exact_solution ? 'exact' : header.energy_error ? 'ref' : null;
  return {
    energyErrorSource: header.energy_error ? source || 'ref' : null,
    drift: Boolean(system?.conformal_damping) && header.system.q0.length === 1,
    ...chartOptions(system, header.system.chart),
  };
}

/**
 * Draws a stored recording's samples (read back from its .rrd by the server) with the page's
 * charts, in place of the results; a running simulation is cancelled first.
 */
async function showRecording(doc, entry) {
  form.clearErrors();
  const { header, samples, summaries } = streamLines(doc);
  const store = new RunStore(doc.request, header);
  for (const chunk of samples) store.add(chunk);
  for (const summary of summaries) store.summarize(summary);
  store.outcome = 'done';
  await view.present(store, `recording:${entry.id}`,
    `Recording ${describe(entry)}, stored ${when(entry.created)}: ${store.received} samples read back ` +
    'from the .rrd file (positions and momenta as recorded, in single precision).');
  ui.results.scrollIntoView({ behavior: 'smooth', block: 'start' });
  ui.results.focus({ preventScroll: true });
}

/** Starts a simulation from the form, cancelling one that still runs. */
function start() {
  form.clearErrors();
  return view.start(form.read());
}

async function init() {
  document.querySelector('#boot')?.remove();
  expandTemplates();
  sections = new Sections($('nav.sections'), 'simulation');
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
  // Stored definitions are the Your-system section's; the form offers the built-in systems.
  const builtIn = cats.systems.filter((s) => !s.definition);
  form = new SimForm(ui.form, { systems: builtIn, methods: cats.methods });
  view = new SimulationView(ui.results, {
    chartOptions: plotOptions,
    showError: (error) => form.showError(error),
    setState,
  }, $('#cancel'));
  const system = new SystemPanel($('#your-system'), cats);
  const stability = new StabilityPanel($('#stability'), cats.methods);
  const workPrecision = new WorkPrecisionPanel($('#work-precision'));
  const convergence = new ConvergencePanel($('#convergence'));
  const energyMap = new EnergyMapPanel($('#energy-map'), cats.methods);
  const sweep = new SweepPanel($('#sweep'));
  const library = new RecordingsPanel($('#recordings'), showRecording);
  for (const button of ui.presets.querySelectorAll('button')) button.disabled = false;
  ui.run.disabled = false;
  ui.form.addEventListener('submit', (event) => {
    event.preventDefault();
    start();
  });
  document.addEventListener('keydown', (event) => {
    if (event.key !== 'Escape') return;
    view.cancel();
    system.cancel();
  });
  window.geomint = {
    sections,
    charts: view.charts.plots,
    pointCounts: () => view.charts.pointCounts(),
    runPreset,
    system,
    stability,
    workPrecision,
    convergence,
    energyMap,
    sweep,
    library,
  };
  setState('idle');
  await Promise.all([system.followLink(), sweep.init(), (async () => {
    await library.refresh();
    await library.followLink();
  })()]);
}

init();
