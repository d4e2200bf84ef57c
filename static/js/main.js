// The page's entry point: fills the page's templates, shows one section at a time
// (sections.js), loads the catalogues, builds the form and the preset buttons, and runs
// simulations into the results beside the form (simulation.js: streamed NDJSON in the plots with
// a progress bar, cancellable with the Cancel button or Esc, the finished run as JSON or a Rerun
// recording); sets up the Your-system section (system.js), the stability section (stability.js),
// the work–precision section (workprecision.js), the convergence section (convergence.js), the
// energy-error map section (energymap.js), the sweeps (sweep.js), the basin maps (basins.js), the
// Poincaré sections (phasespace.js), the recordings library (library.js), which plots
// recordings with the same charts, and the jobs (jobs.js), whose results the study sections show. For tests it exposes `window.geomint` (the uPlot instances and
// their point counts, and the sections) and the run's state as `data-run-state` on <body>
// (loading, idle, running, done, cancelled, error).

import { catalogues } from './api.js';
import { setupTokenField } from './token.js';
import { el, expandTemplates } from './common.js';
import { Sections } from './sections.js';
import { SimForm } from './form.js';
import { builtInPlotOptions } from './plot-options.js';
import { PRESETS, presetRequest } from './presets.js';
import { SimulationView } from './simulation.js';
import { SystemPanel } from './system.js';
import { StabilityPanel } from './stability.js';
import { WorkPrecisionPanel } from './workprecision.js';
import { ConvergencePanel } from './convergence.js';
import { EnergyMapPanel } from './energymap.js';
import { SweepPanel } from './sweep.js';
import { BasinsPanel } from './basins.js';
import { RecordingsPanel } from './library.js';
import { PhaseSpacePanel } from './phasespace.js';
import { JobsPanel } from './jobs.js';

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

/** Starts a simulation from the form, cancelling one that still runs. */
function start() {
  form.clearErrors();
  return view.start(form.read());
}

async function init() {
  document.querySelector('#boot')?.remove();
  expandTemplates();
  // The token first: a server that needs one refuses the catalogues without it.
  let library = null;
  setupTokenField($('#api-token'), $('#token-status'), () => library?.refresh());
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
    chartOptions: (header, request) =>
      builtInPlotOptions(form.systems.find((s) => s.id === header.system.id), header, request),
    showError: (error) => form.showError(error),
    setState,
  }, $('#cancel'));
  const system = new SystemPanel($('#your-system'), cats);
  const stability = new StabilityPanel($('#stability'), cats.methods);
  const workPrecision = new WorkPrecisionPanel($('#work-precision'));
  const convergence = new ConvergencePanel($('#convergence'));
  const energyMap = new EnergyMapPanel($('#energy-map'), cats.methods);
  const sweep = new SweepPanel($('#sweep'), cats.systems);
  const basins = new BasinsPanel($('#basins'), cats.systems);
  library = new RecordingsPanel($('#recordings'), cats.systems);
  const phaseSpace = new PhaseSpacePanel($('#phase-space'), cats.systems);
  // The sections a done job's document is shown in, by study.
  const shownIn = (section, panel) => ({ section, show: (body, doc) => panel.show(body, doc) });
  const jobs = new JobsPanel($('#jobs'), {
    sweep: shownIn('sweep', sweep),
    basins: shownIn('basins', basins),
    'energy-map': shownIn('energy-map', energyMap),
    'work-precision': shownIn('work-precision', workPrecision),
    convergence: shownIn('convergence', convergence),
  });
  // The chaos map of a section's plane runs in Sweeps; a click on one of its cells launches that
  // orbit on the section.
  phaseSpace.onChaosMap = (body) => {
    window.location.hash = '#sweep';
    sweep.runFromPlane(body, (x, y) => {
      window.location.hash = '#phase-space';
      phaseSpace.launch(x, y);
    });
  };
  for (const button of ui.presets.querySelectorAll('button')) button.disabled = false;
  ui.run.disabled = false;
  // "Skip to Run" (the page's second Tab stop) puts the focus on Run, so Enter runs.
  document.querySelector('a.skip[href="#run"]')?.addEventListener('click', () => {
    requestAnimationFrame(() => ui.run.focus());
  });
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
    basins,
    library,
    phaseSpace,
    jobs,
  };
  setState('idle');
  await Promise.all([system.followLink(), phaseSpace.followLink(), sweep.init(), basins.init(), workPrecision.init(), jobs.refresh(), (async () => {
    await library.refresh();
    await library.followLink();
  })()]);
}

init();
