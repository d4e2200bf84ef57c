// The Your-system section: a form for a damped Hamiltonian system of the user's own — coordinates,
// momenta, a mass and a potential or a general H(q, p), damping (none, conformal γ, Rayleigh
// ε·D(q)), parameters, invariants, the bodies' positions, the initial state — filled from an
// example (examples.js) or a definition stored on the server. "Check" posts the definition to
// POST /api/v1/systems and shows the facts the service derives from it (dimension, separability,
// damping, the methods that apply). A refused definition's error appears at its field: the input
// is marked invalid, the message is beside it, and for an expression the character the error
// points at is marked in a copy of the expression and selected in the input. Run checks the
// definition if it changed, then runs it through POST /api/v1/simulate into the section's own
// results (simulation.js), with the bodies where the server places them (the samples' `bodies`).
// A link (#system=…, the definition and the run settings as base64url JSON) fills the section
// and runs.
//
// For tests the section carries `data-system-state`: idle, checking, checked, invalid (the check
// was refused or the text could not be read), running, done, cancelled, error.

import { storeSystem, ApiError } from './api.js';
import { askIndicators } from './chaos.js';
import { el, numberText, parseNumber, parseList } from './common.js';
import {
  DefinitionProblem, entryText, entryValue, linkedSystem, massText, nonBlankLines, rowsText, splitParts,
  systemLink, trimmed,
} from './definition-text.js';
import { MethodPicker } from './method-picker.js';
import { SimulationView } from './simulation.js';
import { EXAMPLES } from './examples.js';
import { definitionPlotOptions } from './plot-options.js';

/** The damping kinds of `facts.damping`, in words. */
const DAMPING_TEXT = {
  none: 'none',
  conformal: 'conformal, p′ = −∂H/∂q − 2γp',
  rayleigh_projector: 'Rayleigh, D(q) an orthogonal projector with M = m·I (exact damping sub-flow)',
  rayleigh: 'Rayleigh with a general D(q)',
};

/** The fields of a definition (the paths of errors about it start with one of these). */
const DEFINITION_FIELDS = new Set(['name', 'coordinates', 'momenta', 'mass', 'potential', 'hamiltonian',
  'damping', 'parameters', 'invariants', 'positions', 'q0', 'p0']);

export class SystemPanel {
  /**
   * @param {HTMLElement} root the section
   * @param {{systems: object[], methods: object[]}} catalogues the stored definitions among the
   *   systems fill the "Start from" list
   */
  constructor(root, catalogues) {
    const $ = (id) => root.querySelector(`#${id}`);
    this.root = root;
    this.form = $('sys-form');
    this.fields = Object.fromEntries(['example', 'name', 'coordinates', 'momenta', 'mass', 'potential',
      'hamiltonian', 'gamma', 'epsilon', 'matrix', 'parameters', 'invariants', 'positions', 'q0', 'p0',
      'h', 't_end', 'every', 'compare', 'chaos'].map((name) => [name, $(`sys-${name}`)]));
    this.ui = {
      alert: $('sys-alert'), examples: $('sys-examples'), stored: $('sys-stored'),
      separable: $('sys-separable'), general: $('sys-general'),
      conformal: $('sys-conformal'), rayleigh: $('sys-rayleigh'),
      check: $('sys-check'), checkStatus: $('sys-check-status'), facts: $('sys-facts'),
      methods: $('sys-methods'), methodsHelp: $('sys-methods-help'), run: $('sys-run'),
      definitionError: $('err-sys-definition'), formError: $('err-sys-form'),
      copyLink: $('sys-copy-link'), linkBox: $('sys-link-box'), link: $('sys-link'),
    };
    this.picker = new MethodPicker(this.ui.methods.querySelector('.method-groups'), catalogues.methods,
      { idPrefix: 'sys-m-', offered: [] });
    /** The last check that passed: {json: the definition as sent, entry: the stored entry}. */
    this.checked = null;
    /** Methods to choose once a check tells which apply (from an example or a link). */
    this.pendingMethods = null;
    /**
     * Path → {input, start, text, line?}: where each part of the last definition read came from
     * (`line`: the whole `name = …` line of a parameter or invariant).
     */
    this.sources = new Map();
    /** The definition of the run on show (its bodies are placed from it). */
    this.runDefinition = null;

    this.view = new SimulationView($('sys-results'), {
      chartOptions: (header, request) => definitionPlotOptions(this.runDefinition, header, request),
      showError: (error) => this.showError(error),
      setState: (state) => this.setState(state),
    }, $('sys-cancel'));

    this.ui.examples.replaceChildren(...EXAMPLES.map((x) => el('option', { value: `example:${x.id}`, text: x.label })));
    this.storedEntries = catalogues.systems.filter((s) => s.definition);
    this.listStored();
    this.fields.example.addEventListener('change', () => this.startFrom(this.fields.example.value));
    for (const radio of root.querySelectorAll('input[name="sys-energy"], input[name="sys-damping"]')) {
      radio.addEventListener('change', () => this.showChoices());
    }
    this.form.addEventListener('input', (event) => {
      if (event.target.closest('#sys-methods') || ['h', 't_end', 'every', 'compare'].some((f) => this.fields[f] === event.target)) return;
      this.markEdited();
    });
    this.fields.coordinates.addEventListener('input', () => this.showMomentumNames());
    this.ui.check.addEventListener('click', () => this.check());
    this.form.addEventListener('submit', (event) => {
      event.preventDefault();
      this.run();
    });
    this.ui.copyLink.addEventListener('click', () => this.copyLink());
    window.addEventListener('hashchange', () => this.followLink());
    this.ui.check.disabled = false;
    this.ui.run.disabled = false;
    this.setState('idle');
  }

  setState(state) {
    this.root.dataset.systemState = state;
  }

  /** Shows an error in the section's alert (empty text hides it). */
  alert(text) {
    if (text) this.forgetCopied();
    this.ui.alert.textContent = text || '';
    this.ui.alert.hidden = !text;
  }

  /** Cancels the section's running simulation, if any. */
  cancel() {
    this.view.cancel();
  }

  /** Point counts of the section's plots (for tests), as window.geomint.pointCounts gives them. */
  pointCounts() {
    return this.view.charts.pointCounts();
  }

  /** The "Stored on this server" options. */
  listStored() {
    this.ui.stored.replaceChildren(...this.storedEntries.map((s) =>
      el('option', { value: `stored:${s.id}`, text: `${s.name} (${s.id})` })));
    this.ui.stored.hidden = this.storedEntries.length === 0;
  }

  /** Fills the section from the "Start from" choice: `example:<id>` or `stored:<id>`. */
  startFrom(value) {
    const [kind, id] = value.split(/:(.*)/);
    if (kind === 'example') {
      const example = EXAMPLES.find((x) => x.id === id);
      if (example) this.fill(structuredClone(example.definition), example.run);
    } else if (kind === 'stored') {
      const entry = this.storedEntries.find((s) => s.id === id);
      if (entry) this.fill(structuredClone(entry.definition));
    }
  }

  /** The chosen radio of group `name`. */
  choice(name) {
    return this.root.querySelector(`input[name="sys-${name}"]:checked`)?.value;
  }

  choose(name, value) {
    const radio = this.root.querySelector(`input[name="sys-${name}"][value="${value}"]`);
    if (radio) radio.checked = true;
    this.showChoices();
  }

  /** Shows the inputs of the chosen energy form and damping kind only. */
  showChoices() {
    const general = this.choice('energy') === 'general';
    this.ui.separable.hidden = general;
    this.ui.general.hidden = !general;
    const damping = this.choice('damping');
    this.ui.conformal.hidden = damping !== 'conformal';
    this.ui.rayleigh.hidden = damping !== 'rayleigh';
  }

  /**
   * Fills the definition's inputs from `definition` and, if given, the run settings from `run`
   * ({methods, h, t_end, every, compare, chaos}); the methods are chosen once a check says which
   * apply.
   */
  fill(definition, run = null) {
    const f = this.fields;
    f.name.value = definition.name ?? '';
    f.coordinates.value = (definition.coordinates ?? []).join(', ');
    f.momenta.value = (definition.momenta ?? []).join(', ');
    this.showMomentumNames();
    this.choose('energy', definition.hamiltonian !== undefined ? 'general' : 'separable');
    f.mass.value = massText(definition.mass);
    f.potential.value = definition.potential ?? '';
    f.hamiltonian.value = definition.hamiltonian ?? '';
    const damping = definition.damping ?? {};
    this.choose('damping', damping.gamma !== undefined ? 'conformal' : damping.epsilon !== undefined ? 'rayleigh' : 'none');
    f.gamma.value = entryText(damping.gamma);
    f.epsilon.value = entryText(damping.epsilon);
    f.matrix.value = rowsText(damping.matrix);
    f.parameters.value = Object.entries(definition.parameters ?? {}).map(([k, v]) => `${k} = ${numberText(v)}`).join('\n');
    f.invariants.value = Object.entries(definition.invariants ?? {}).map(([k, v]) => `${k} = ${v}`).join('\n');
    f.positions.value = rowsText(definition.positions);
    f.q0.value = (definition.q0 ?? []).map(numberText).join(', ');
    f.p0.value = (definition.p0 ?? []).map(numberText).join(', ');
    // Text areas grow to show every line they were filled with (up to a point).
    for (const area of this.form.querySelectorAll('textarea')) {
      area.dataset.rows ??= String(area.rows);
      area.rows = Math.min(8, Math.max(Number(area.dataset.rows), area.value.split('\n').length));
    }
    if (run) {
      this.pendingMethods = run.methods ?? null;
      f.h.value = numberText(run.h);
      f.t_end.value = numberText(run.t_end);
      f.every.value = run.every ? String(run.every) : '';
      f.compare.checked = Boolean(run.compare);
      f.chaos.checked = Boolean(run.chaos);
    }
    this.checked = null;
    this.ui.linkBox.hidden = true;
    this.picker.offer([]);
    this.ui.facts.hidden = true;
    this.ui.methodsHelp.textContent = 'Check the definition to see which methods apply to it.';
    this.ui.checkStatus.textContent = 'Not checked yet.';
    this.clearErrors();
    this.alert('');
    this.setState('idle');
  }

  /** The default momenta's names as the momenta's placeholder. */
  showMomentumNames() {
    const names = splitParts(this.fields.coordinates.value, ',').map((part) => part.text).filter(Boolean);
    this.fields.momenta.placeholder = (names.length ? names : ['x', 'y']).map((n) => `p_${n}`).join(', ');
  }

  /** After an edit of the definition: the facts on show are of an older one. */
  markEdited() {
    if (!this.checked || this.ui.facts.classList.contains('stale')) return;
    this.ui.facts.classList.add('stale');
    this.ui.checkStatus.textContent = 'The definition changed since its check: Check it again (Run does).';
  }

  /**
   * The definition the inputs describe, and where each part of it came from. Throws a
   * DefinitionProblem for text that is not a definition's shape (a parameter line without `=`).
   * @returns {{definition: object, sources: Map<string, object>}}
   */
  readDefinition() {
    const f = this.fields;
    const sources = new Map();
    const note = (path, input, part, line = null) => sources.set(path, { input, start: part.start, text: part.text, line });
    const whole = (path, input) => note(path, input, trimmed(input.value, 0));
    // A comma-separated list of entries (names, numbers or expressions), as the API path `path`.
    const list = (path, input, text = input.value, from = 0) => splitParts(text, ',', from).map((part, i) => {
      note(`${path}[${i}]`, input, part);
      return part.text;
    });
    // One row of entries per line.
    const rows = (path, input) => nonBlankLines(input.value).map((line, i) => {
      note(`${path}[${i}]`, input, line);
      return list(`${path}[${i}]`, input, line.text, line.start).map(entryValue);
    });
    // `name = value` lines, as {name: value(text)}.
    const assignments = (path, input, value, what) => Object.fromEntries(nonBlankLines(input.value).map((line) => {
      const eq = line.text.indexOf('=');
      if (eq < 0) throw new DefinitionProblem(path, `${path}: “${line.text}” is not of the form name = ${what}`);
      const name = line.text.slice(0, eq).trim();
      const part = trimmed(line.text.slice(eq + 1), line.start + eq + 1);
      note(`${path}.${name}`, input, part, line);
      return [name, value(part.text)];
    }));

    const definition = {};
    const name = f.name.value.trim();
    if (name) definition.name = name;
    whole('coordinates', f.coordinates);
    definition.coordinates = f.coordinates.value.trim() ? list('coordinates', f.coordinates) : [];
    if (f.momenta.value.trim()) {
      whole('momenta', f.momenta);
      definition.momenta = list('momenta', f.momenta);
    }
    if (this.choice('energy') === 'general') {
      whole('hamiltonian', f.hamiltonian);
      definition.hamiltonian = f.hamiltonian.value.trim();
    } else {
      const mass = f.mass.value;
      if (mass.trim()) {
        whole('mass', f.mass);
        const massRows = splitParts(mass, ';');
        if (massRows.length > 1) {
          definition.mass = massRows.map((row, i) => {
            note(`mass[${i}]`, f.mass, row);
            return list(`mass[${i}]`, f.mass, row.text, row.start).map(entryValue);
          });
        } else if (splitParts(mass, ',').length > 1) {
          definition.mass = list('mass', f.mass).map(entryValue);
        } else {
          definition.mass = entryValue(mass.trim());
        }
      }
      whole('potential', f.potential);
      if (f.potential.value.trim()) definition.potential = f.potential.value.trim();
    }
    const damping = this.choice('damping');
    if (damping === 'conformal') {
      whole('damping.gamma', f.gamma);
      definition.damping = { gamma: entryValue(f.gamma.value.trim()) };
    } else if (damping === 'rayleigh') {
      whole('damping.epsilon', f.epsilon);
      whole('damping.matrix', f.matrix);
      definition.damping = { epsilon: entryValue(f.epsilon.value.trim()), matrix: rows('damping.matrix', f.matrix) };
    }
    whole('parameters', f.parameters);
    const parameters = assignments('parameters', f.parameters, entryValue, 'number');
    if (Object.keys(parameters).length) definition.parameters = parameters;
    whole('invariants', f.invariants);
    const invariants = assignments('invariants', f.invariants, (text) => text, 'expression');
    if (Object.keys(invariants).length) definition.invariants = invariants;
    if (f.positions.value.trim()) {
      whole('positions', f.positions);
      definition.positions = rows('positions', f.positions);
    }
    for (const key of ['q0', 'p0']) {
      if (!f[key].value.trim()) continue;
      whole(key, f[key]);
      definition[key] = parseList(f[key].value);
    }
    return { definition, sources };
  }

  /** Reads the definition, showing a problem at its field; null when there is one. */
  read() {
    this.clearErrors();
    try {
      const read = this.readDefinition();
      this.sources = read.sources;
      return read;
    } catch (problem) {
      if (!(problem instanceof DefinitionProblem)) throw problem;
      this.showError(problem)?.focus();
      this.ui.checkStatus.textContent = `The definition cannot be read: ${problem.message}`;
      this.setState('invalid');
      return null;
    }
  }

  /**
   * Checks the definition the inputs describe (POST /api/v1/systems) and shows its facts and the
   * methods that apply. Resolves to the definition, or null when it was refused.
   */
  async check(read = this.read()) {
    if (!read) return null;
    this.setState('checking');
    this.ui.checkStatus.textContent = 'Checking…';
    this.ui.check.disabled = true;
    this.ui.run.disabled = true;
    try {
      const entry = await storeSystem(read.definition);
      this.checked = { json: JSON.stringify(read.definition), entry };
      this.showFacts(entry);
      if (!this.storedEntries.some((s) => s.id === entry.id)) {
        this.storedEntries.push(entry);
        this.listStored();
      }
      this.ui.checkStatus.textContent = `Checked: stored as ${entry.id}` +
        `${entry.created ? '' : ' (it was stored already)'}; see what it is below.`;
      this.setState('checked');
      return read.definition;
    } catch (error) {
      this.checked = null;
      if (error instanceof ApiError && error.field) {
        this.showError(error)?.focus();
        this.ui.checkStatus.textContent = 'The server refused the definition (see the message at its field).';
        this.setState('invalid');
      } else {
        this.ui.definitionError.textContent = `The check failed: ${error.message}`;
        this.ui.checkStatus.textContent = '';
        this.setState('error');
      }
      return null;
    } finally {
      this.ui.check.disabled = false;
      this.ui.run.disabled = false;
    }
  }

  /** Shows the facts of a stored entry and offers the methods that apply. */
  showFacts(entry) {
    const { facts } = entry;
    const item = (term, key, ...value) => [el('dt', { text: term }), el('dd', { 'data-fact': key }, ...value)];
    this.ui.facts.replaceChildren(
      ...item('Stored as', 'id', el('code', { text: entry.id })),
      ...item('Degrees of freedom', 'dimension', String(facts.dimension)),
      ...item('Hamiltonian', 'separable', facts.separable
        ? 'separable: H = ½pᵀM⁻¹p + V(q), constant M' : 'general H(q, p), not separable'),
      ...item('Damping', 'damping', DAMPING_TEXT[facts.damping] ?? facts.damping),
      ...item('Methods that apply', 'methods', `${facts.methods.length}: `,
        ...facts.methods.flatMap((id, i) => [i ? ', ' : '', el('code', { text: id })])));
    Object.assign(this.ui.facts.dataset, {
      separable: String(facts.separable), damping: facts.damping, dimension: String(facts.dimension),
    });
    this.ui.facts.classList.remove('stale');
    this.ui.facts.hidden = false;

    this.picker.offer(facts.methods);
    if (this.pendingMethods) {
      this.picker.fill(this.pendingMethods);
      this.pendingMethods = null;
    }
    this.picker.chooseDefaults();
    this.ui.methodsHelp.textContent = facts.methods.length
      ? `The ${facts.methods.length} methods that apply to this system; each is drawn in its own colour.`
      : 'No method applies to this system.';
  }

  /** The body of POST /api/v1/simulate for `definition` and the run settings. */
  request(definition) {
    const f = this.fields;
    const request = {
      system: definition,
      params: definition.parameters ?? {},
      methods: this.picker.read(),
      h: parseNumber(f.h.value),
      t_end: parseNumber(f.t_end.value),
      compare_to_reference: f.compare.checked,
    };
    const every = f.every.value.trim();
    if (every !== '') {
      const n = Number(every);
      request.output = { every: Number.isInteger(n) ? n : every };
    }
    return askIndicators(request, f.chaos.checked);
  }

  /** Runs the definition (checked first, when it changed since its last check). */
  async run() {
    this.forgetCopied();
    const read = this.read();
    if (!read) return;
    const definition = this.checked?.json === JSON.stringify(read.definition)
      ? read.definition : await this.check(read);
    if (!definition) return;
    this.runDefinition = definition;
    await this.view.start(this.request(definition));
  }

  /** The definition and run settings as a link's state. */
  linkState() {
    const f = this.fields;
    const run = { methods: this.picker.read(), h: parseNumber(f.h.value), t_end: parseNumber(f.t_end.value) };
    const every = parseNumber(f.every.value);
    if (every) run.every = every;
    if (f.compare.checked) run.compare = true;
    if (f.chaos.checked) run.chaos = true;
    return { definition: this.readDefinition().definition, run };
  }

  /** Takes back the status that a link was copied, once anything else has happened since. */
  forgetCopied() {
    if (this.copiedStatus && this.view.ui.status.textContent === this.copiedStatus) this.view.setStatus('');
    this.copiedStatus = null;
  }

  /**
   * Copies the link to the definition and run (and shows it, for browsers that do not copy). A
   * definition without coordinates or without its energy (a potential, or a Hamiltonian) makes no
   * link: the link would open on the server's refusal.
   */
  async copyLink() {
    let link;
    try {
      const state = this.linkState();
      const d = state.definition;
      if (!d.coordinates?.length) throw new DefinitionProblem('coordinates', 'coordinates: give the coordinates\' names, e.g. x, y');
      if (!d.potential && !d.hamiltonian) {
        const general = this.choice('energy') === 'general';
        throw new DefinitionProblem(general ? 'hamiltonian' : 'potential',
          general ? 'hamiltonian: give H(q, p), e.g. p_x^2/2 + x^2/2' : 'potential: give V(q), e.g. x^2/2');
      }
      link = systemLink(state);
    } catch (problem) {
      if (!(problem instanceof DefinitionProblem)) throw problem;
      this.clearErrors();
      this.forgetCopied();
      this.showError(problem)?.focus();
      this.ui.linkBox.hidden = true;
      this.view.setStatus(`No link: the definition is not complete (${problem.message}).`);
      return;
    }
    this.ui.link.value = link;
    this.ui.linkBox.hidden = false;
    try {
      await navigator.clipboard.writeText(link);
      this.copiedStatus = 'Copied the link to this system and run.';
      this.view.setStatus(this.copiedStatus);
    } catch {
      this.ui.link.focus();
      this.ui.link.select();
      this.view.setStatus('This browser did not let the page copy: the link is selected below, copy it from there.');
    }
  }

  /** Fills the section from the definition and run the location hash holds, and runs. */
  async followLink() {
    const state = linkedSystem(window.location.hash);
    if (!state) return;
    if (state.invalid) {
      this.alert(`The link does not open a system: ${state.invalid}.`);
      this.root.scrollIntoView({ block: 'start' });
      return;
    }
    this.fields.example.value = '';
    this.fill(state.definition, state.run ?? null);
    this.root.scrollIntoView({ block: 'start' });
    await this.run();
  }

  /** Removes every error message and mark. */
  clearErrors() {
    for (const node of this.form.querySelectorAll('.field-error')) node.textContent = '';
    for (const node of this.form.querySelectorAll('.expr-where')) node.remove();
    for (const node of this.form.querySelectorAll('[aria-invalid]')) node.removeAttribute('aria-invalid');
    for (const node of this.form.querySelectorAll('.has-error')) node.classList.remove('has-error');
  }

  /**
   * The input, error slot and source of an error's field path: a part of the definition (paths as
   * POST /api/v1/systems names them, or with the `system.` prefix of a simulate request), a
   * parameter value (`params.k`), a method, or a run setting. A path the page does not hold as
   * such is placed at its nearest parent (`damping.matrix[1]` for `damping.matrix[1][5]`).
   */
  locate(field) {
    if (!field) return null;
    if (/^methods?\b/.test(field)) {
      return this.picker.locate(field) ?? { input: null, error: this.root.querySelector('#err-sys-methods') };
    }
    const runFields = { h: 'h', t_end: 't_end', 'output.every': 'every', compare_to_reference: 'compare', indicators: 'chaos' };
    if (runFields[field]) {
      const input = this.fields[runFields[field]];
      return { input, error: this.root.querySelector(`#err-${input.id}`) };
    }
    let path = field.replace(/^system\./, '').replace(/^params\./, 'parameters.');
    for (;;) {
      const source = this.sources.get(path);
      if (source) return { input: source.input, error: this.root.querySelector(`#err-${source.input.id}`), source };
      if (path === 'damping') {
        return { input: this.root.querySelector('input[name="sys-damping"]:checked'), error: this.root.querySelector('#err-sys-damping') };
      }
      const shorter = path.replace(/(\[\d+\]|\.[^.[\]]+)$/, '');
      if (shorter === path || shorter === '') return null;
      path = shorter;
    }
  }

  /**
   * Shows an error ({field, message, position?}) beside the input its field names, or above the
   * Check button (a definition's) or the Run button (anything else). For an expression's error it
   * marks the character at `position` in a copy of the expression and selects it in the input.
   * Returns the input to focus, if any.
   */
  showError(error) {
    this.forgetCopied();
    const target = this.locate(error.field);
    const top = (error.field ?? '').replace(/^system\./, '').split(/[.[]/)[0];
    const slot = target?.error ?? (DEFINITION_FIELDS.has(top) ? this.ui.definitionError : this.ui.formError);
    slot.textContent = error.message;
    slot.closest('.field, .method, fieldset')?.classList.add('has-error');
    this.picker.reveal(slot);
    const input = target?.input ?? null;
    if (input) input.setAttribute('aria-invalid', 'true');
    const source = target?.source;
    if (source && Number.isInteger(error.position)) {
      this.markPosition(slot, source, error.position);
    } else if (source) {
      const { start, end } = source.line ?? { start: source.start, end: source.start + source.text.length };
      source.input.setSelectionRange(start, end);
    }
    return input;
  }

  /**
   * Marks character `position` (counted in Unicode characters, as the server counts) of the
   * source's text after the error `slot`, and selects it in the input.
   */
  markPosition(slot, { input, start, text }, position) {
    const chars = [...text];
    const before = chars.slice(0, position).join('');
    const at = chars[position] ?? '';
    const after = chars.slice(position + 1).join('');
    const from = start + before.length;
    input.setSelectionRange(from, from + at.length);
    // People count characters from 1: the server's 0-based position, said so.
    slot.textContent = slot.textContent.replace(/\bat character (\d+)/, (_, n) => `at character ${Number(n) + 1}`);
    slot.after(el('p', { class: 'expr-where', 'data-position': position },
      el('code', {}, before,
        el('mark', { class: at ? null : 'end', title: at ? `character ${position + 1}` : 'the end' }, at || '\u00a0'),
        after),
      el('code', { class: 'caret', 'aria-hidden': 'true' }, `${'\u00a0'.repeat(chars.slice(0, position).length)}^`),
      ` character ${position + 1}${at ? ` (“${at}”)` : ', the end'}`));
  }
}
