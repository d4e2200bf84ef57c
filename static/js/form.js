// The simulation form: builds the system, coordinate-chart, parameter, initial-state and method
// inputs from the catalogues (GET /api/v1/systems, /api/v1/methods), reads them into a request
// body for POST /api/v1/simulate, fills them from a preset, and shows API errors beside the input
// named by the error's `field` path (`h`, `params.gamma`, `q0[1]`, `methods[1].inner`,
// `output.every`, `chart`). The initial state is entered in Cartesian coordinates (the server
// transforms it into the chart, so every chart starts from the same physical state) or, on
// request, in the chart's own coordinates; switching converts the values on the server. The
// method checkboxes are a MethodPicker (method-picker.js), which the Your-system section
// (system.js) uses too.

import { simulateJson } from './api.js';
import { el, numberText, parseNumber, parseList } from './common.js';
import { askIndicators, asksIndicators } from './chaos.js';
import { MethodPicker } from './method-picker.js';

/** Up to this many degrees of freedom the initial state gets one input per component. */
const MAX_COMPONENT_INPUTS = 6;

const REQUIREMENT_TEXT = {
  separable_constant_mass: 'a separable H with constant mass',
  conformal_damping: 'conformal damping (p′ = −∇V − 2γp)',
  conservative: 'no damping (γ = 0, ε = 0)',
};

/** Text with `backtick` spans as <code> elements, for catalogue descriptions. */
function richText(text) {
  return String(text).split('`').map((part, i) => (i % 2 ? el('code', { text: part }) : part));
}

/** A chart's name in text: `Cartesian` for the Cartesian chart, else its id. */
export function chartName(id) {
  return id === 'cartesian' ? 'Cartesian' : id;
}

/** Names of the coordinates of a state with `dof` degrees of freedom (`names` if they fit). */
function coordinateNames(dof, names = null) {
  if (names?.length === dof) return names;
  if (dof === 2) return ['x', 'y'];
  if (dof === 3) return ['x', 'y', 'z'];
  return Array.from({ length: dof }, (_, i) => String(i + 1));
}

/** The form: inputs, request reading and error display. */
export class SimForm {
  /**
   * @param {HTMLFormElement} form
   * @param {{systems: object[], methods: object[]}} catalogues
   */
  constructor(form, catalogues) {
    this.form = form;
    this.systems = catalogues.systems;
    this.methods = catalogues.methods;
    this.systemSelect = form.querySelector('#system');
    this.systemDescription = form.querySelector('#system-description');
    this.chartField = form.querySelector('#chart-field');
    this.chartSelect = form.querySelector('#chart');
    this.chartDescription = form.querySelector('#chart-description');
    this.coordinateSwitch = form.querySelector('#state-coordinates');
    /** The coordinates the initial-state inputs hold: `cartesian` or `chart`. */
    this.stateMode = 'cartesian';
    /** The chart the inputs belong to (the select's value once a change is through). */
    this.chartId = null;
    /** Bumped by every conversion and system change, so that a superseded conversion is dropped. */
    this.conversion = 0;
    this.paramsBox = form.querySelector('#params');
    this.stateBox = form.querySelector('#state');
    this.methodsBox = form.querySelector('#methods');
    this.generalError = form.querySelector('#form-error');
    /** Field path → {input, error} for error display. */
    this.fields = new Map();
    this.registerStatic('h');
    this.registerStatic('t_end');
    this.registerStatic('output.every', 'every');
    this.registerStatic('compare_to_reference', 'compare');
    this.registerStatic('indicators', 'chaos');
    this.registerStatic('system');
    this.registerStatic('chart');
    this.registerStatic('methods', null, this.methodsBox.querySelector('#err-methods'));

    this.systemSelect.replaceChildren(
      ...this.systems.map((s) => el('option', { value: s.id, text: `${s.name}` })),
    );
    this.picker = new MethodPicker(this.methodsBox.querySelector('.method-groups'), this.methods);
    this.systemSelect.addEventListener('change', () => this.setSystem(this.systemSelect.value));
    this.chartSelect.addEventListener('change', () => this.changeChart(this.chartSelect.value));
    for (const radio of this.coordinateSwitch.querySelectorAll('input[type=radio]')) {
      radio.addEventListener('change', () => this.switchStateCoordinates(radio.value));
    }
    form.querySelector('#defaults').addEventListener('click', () =>
      this.setSystem(this.system.id, { chart: this.chartSelect.value }));
    this.setSystem(this.systems[0].id);
  }

  /** Registers one of the inputs written in the HTML (error slot `err-<id>`). */
  registerStatic(path, id = path, error = null) {
    const input = id ? this.form.querySelector('#' + id) : null;
    this.fields.set(path, { input, error: error || this.form.querySelector('#err-' + (id || path)) });
  }

  /** The catalogue entry of the chosen system. */
  get system() {
    return this.systems.find((s) => s.id === this.systemSelect.value);
  }

  /**
   * Switches to system `id` in `chart` (default: its first): its parameters and initial state with
   * defaults (Cartesian), methods it allows. `initialCoordinates` says what `q0` and `p0` are in.
   */
  setSystem(id, { params = {}, q0 = null, p0 = null, chart = null, initialCoordinates = null } = {}) {
    this.conversion += 1;
    this.lockState(false);
    this.systemSelect.value = id;
    const system = this.system;
    this.systemDescription.replaceChildren(...richText(system.description));
    for (const key of [...this.fields.keys()]) {
      if (key.startsWith('params.') || key.startsWith('q0') || key.startsWith('p0')) this.fields.delete(key);
    }
    this.paramsBox.replaceChildren(...system.params.map((p) => this.paramRow(p, params[p.name])));
    this.chartSelect.replaceChildren(...system.charts.map((c) => el('option', {
      value: c.id, text: `${chartName(c.id)} (${c.coordinates.join(', ')})`,
    })));
    this.chartId = system.charts.some((c) => c.id === chart) ? chart : system.charts[0].id;
    this.chartSelect.value = this.chartId;
    this.chartField.hidden = system.charts.length < 2;
    this.stateMode = initialCoordinates === 'chart' && q0 && p0 ? 'chart' : 'cartesian';
    this.showChart();
    this.buildState(system, q0 ?? system.q0, p0 ?? system.p0);
    this.updateMethodAvailability();
    this.clearErrors();
  }

  /** The catalogue entry of the chart the inputs belong to. */
  get chart() {
    return this.system.charts.find((c) => c.id === this.chartId) ?? this.system.charts[0];
  }

  /** Whether the chart is the system's first (Cartesian) one, where both coordinates agree. */
  get defaultChart() {
    return this.chartId === this.system.charts[0].id;
  }

  /** The chart's description, and the coordinate switch (only for a non-Cartesian chart). */
  showChart() {
    const [first] = this.system.charts;
    const chart = this.chart;
    this.chartDescription.replaceChildren(...richText(chart.description));
    this.coordinateSwitch.hidden = this.defaultChart;
    const label = (value, c) => {
      const radio = this.coordinateSwitch.querySelector(`input[value="${value}"]`);
      radio.checked = this.stateMode === value;
      radio.labels[0].textContent = `${chartName(c.id)} (${c.coordinates.join(', ')})`;
    };
    label('cartesian', first);
    label('chart', chart);
  }

  /** Names of the coordinates the initial-state inputs hold. */
  stateNames() {
    return (this.stateMode === 'chart' ? this.chart : this.system.charts[0]).coordinates;
  }

  /** Rebuilds the initial-state inputs with `q0` and `p0` (in the current state coordinates). */
  setState(q0, p0) {
    for (const key of [...this.fields.keys()]) {
      if (key.startsWith('q0') || key.startsWith('p0')) this.fields.delete(key);
    }
    this.buildState(this.system, q0, p0);
  }

  /** Disables the chart select and the coordinate switch while a conversion runs. */
  lockState(locked) {
    this.chartSelect.disabled = locked;
    for (const radio of this.coordinateSwitch.querySelectorAll('input')) radio.disabled = locked;
    this.form.dataset.converting = locked ? 'true' : 'false';
  }

  /**
   * The initial state of the inputs in `to` coordinates (`cartesian` or `chart`) of chart
   * `chartId`, converted by the server: a one-step run of explicit Euler reports the start both in
   * the chart (the header's q0, p0) and in Cartesian coordinates (the first sample's cartesian_q,
   * cartesian_p). Returns null and shows the error (beside its field) when the server refuses.
   */
  async convertState(to, chartId) {
    const request = this.read();
    const body = {
      system: request.system,
      params: request.params,
      chart: chartId,
      initial_coordinates: to === 'chart' ? 'cartesian' : 'chart',
      methods: ['explicit_euler'],
      h: request.h,
      t_end: request.h,
      q0: request.q0,
      p0: request.p0,
      output: { every: 1 },
    };
    const generation = ++this.conversion;
    this.clearErrors();
    this.lockState(true);
    try {
      const doc = await simulateJson(body);
      if (generation !== this.conversion) return null;
      const run = doc.runs[0];
      const state = to === 'chart'
        ? { q0: doc.system.q0, p0: doc.system.p0 }
        : { q0: (run.cartesian_q ?? run.q)[0], p0: (run.cartesian_p ?? run.p)[0] };
      if (![...state.q0, ...state.p0].every(Number.isFinite)) {
        // A state given in the chart's coordinates is not checked against its range; outside it
        // the Cartesian image is undefined.
        this.showError({
          field: 'q0',
          message: `this state has no ${to === 'chart' ? `${chartName(chartId)} chart` : 'Cartesian'} coordinates: ` +
            `it lies outside the ${chartName(chartId)} chart`,
        });
        return null;
      }
      return state;
    } catch (error) {
      if (generation !== this.conversion) return null;
      this.showError(error);
      return null;
    } finally {
      if (generation === this.conversion) this.lockState(false);
    }
  }

  /** Enters the initial state in `mode` coordinates (`cartesian` or `chart`), converting it. */
  async switchStateCoordinates(mode) {
    if (mode === this.stateMode) return;
    const state = await this.convertState(mode, this.chartId);
    if (state) {
      this.stateMode = mode;
      this.setState(state.q0, state.p0);
    }
    this.showChart();
  }

  /**
   * Moves to chart `id`. The inputs keep the physical start: values in the old chart's own
   * coordinates are converted to Cartesian ones first (the new chart then takes them as such).
   */
  async changeChart(id) {
    if (this.stateMode === 'chart' && !this.defaultChart) {
      const state = await this.convertState('cartesian', this.chartId);
      if (!state) {
        this.chartSelect.value = this.chartId;
        return;
      }
      this.stateMode = 'cartesian';
      this.chartId = id;
      this.setState(state.q0, state.p0);
    } else {
      this.stateMode = 'cartesian';
      this.chartId = id;
      this.setState(...this.stateValues());
    }
    this.clearErrors();
    this.showChart();
    this.updateMethodAvailability();
  }

  /** The initial-state inputs' values as [q0, p0] (as read for a request). */
  stateValues() {
    const request = this.read();
    return [request.q0, request.p0];
  }

  /** One parameter's label, input, description with range and default, and error slot. */
  paramRow(param, value) {
    const id = 'param-' + param.name;
    const errorId = 'err-' + id;
    const helpId = 'help-' + id;
    let input;
    let help = '';
    if (param.kind === 'number') {
      const low = param.min_exclusive ? '(' : '[';
      help = ` Range ${low}${param.min}, ${param.max}], default ${param.default}.`;
      input = el('input', {
        id, name: id, type: 'number', step: 'any', inputmode: 'decimal',
        min: param.min, max: param.max,
        value: numberText(value ?? param.default),
      });
    } else if (param.kind === 'choice') {
      help = ` Default ${param.default}.`;
      input = el('select', { id, name: id },
        param.options.map((o) => el('option', { value: o, text: o })));
      input.value = value ?? param.default;
    } else {
      help = ` Comma-separated, each in (${param.min}, ${param.max}], at most ${param.max_len}; default ${param.default.join(', ')}.`;
      input = el('input', { id, name: id, type: 'text', inputmode: 'decimal', value: (value ?? param.default).join(', ') });
    }
    input.dataset.param = param.name;
    input.dataset.kind = param.kind;
    input.setAttribute('aria-describedby', `${helpId} ${errorId}`);
    const error = el('p', { class: 'field-error', id: errorId, 'aria-live': 'polite' });
    this.fields.set('params.' + param.name, { input, error });
    return el('div', { class: 'field' },
      el('label', { for: id }, el('span', { class: 'param-name', text: param.name })),
      input,
      el('p', { class: 'help', id: helpId }, ...richText(param.description), help),
      error);
  }

  /** The q₀ and p₀ inputs: one per component for small systems, else comma-separated lists. */
  buildState(system, q0, p0) {
    const dof = q0.length;
    const chartNames = this.stateNames();
    const rows = [];
    for (const [vec, values, title] of [['q0', q0, 'positions'], ['p0', p0, 'momenta']]) {
      const errorId = 'err-' + vec;
      const error = el('p', { class: 'field-error', id: errorId, 'aria-live': 'polite' });
      const symbol = vec[0];
      if (dof === 1) {
        const id = `${vec}-0`;
        const input = el('input', {
          id, name: id, type: 'number', step: 'any', inputmode: 'decimal',
          value: numberText(values[0]), 'aria-describedby': errorId,
        });
        input.dataset.vector = vec;
        this.fields.set(`${vec}[0]`, { input, error });
        this.fields.set(vec, { input, error });
        const [name] = chartNames;
        const coordinate = name && name !== 'q' ? (symbol === 'q' ? `, ${name}` : `, p_${name}`) : '';
        rows.push(el('div', { class: 'field' },
          el('label', { for: id, text: `${symbol}₀ (${title === 'positions' ? 'position' : 'momentum'}${coordinate})` }),
          input, error));
      } else if (dof <= MAX_COMPONENT_INPUTS) {
        const names = coordinateNames(dof, chartNames);
        this.fields.set(vec, { input: null, error });
        const inputs = values.map((v, i) => {
          const id = `${vec}-${i}`;
          const input = el('input', {
            id, name: id, type: 'number', step: 'any', inputmode: 'decimal',
            value: numberText(v), 'aria-describedby': errorId,
          });
          input.dataset.vector = vec;
          this.fields.set(`${vec}[${i}]`, { input, error });
          const sub = `${symbol}₀,${names[i]}`;
          return el('div', { class: 'component' }, el('label', { for: id, text: sub }), input);
        });
        this.fields.get(vec).input = inputs[0].querySelector('input');
        rows.push(el('fieldset', { class: 'vector' },
          el('legend', { text: `${symbol}₀ (${title})` }),
          el('div', { class: 'components' }, inputs),
          error));
      } else {
        const id = vec + '-list';
        const input = el('input', {
          id, name: id, type: 'text', inputmode: 'decimal', class: 'wide',
          value: values.join(', '), 'aria-describedby': `help-${id} ${errorId}`,
        });
        input.dataset.vector = vec;
        this.fields.set(vec, { input, error });
        rows.push(el('div', { class: 'field' },
          el('label', { for: id, text: `${symbol}₀ (${title}, ${dof} values)` }),
          input,
          el('p', { class: 'help', id: `help-${id}`, text: 'Comma-separated; 3 per body (x, y, z).' }),
          error));
      }
    }
    this.stateBox.replaceChildren(...rows);
  }

  /**
   * Disables methods whose requirements the chosen system does not meet, and marks those that
   * need a separable Hamiltonian when the chart is not separable (the server refuses them there,
   * naming the method).
   */
  updateMethodAvailability() {
    const system = this.system;
    const chart = this.chart;
    for (const row of this.picker.rows()) {
      const separable = row.requirements.includes('separable_constant_mass') && !chart.separable;
      let soft = row.querySelector('.unmet-chart');
      if (separable && !soft) {
        soft = el('span', { class: 'unmet-chart' });
        row.querySelector('.method-note').append(soft);
      }
      if (separable) soft.textContent = ` — needs a separable H: not in the ${chartName(chart.id)} chart`;
      else soft?.remove();
      const unmet = row.requirements.filter((r) => r === 'conformal_damping' && !system.conformal_damping);
      const box = row.querySelector('input[type=checkbox]');
      box.disabled = unmet.length > 0;
      row.classList.toggle('unavailable', unmet.length > 0);
      let why = row.querySelector('.unmet');
      if (unmet.length) {
        if (!why) {
          why = el('span', { class: 'unmet' });
          row.querySelector('.method-note').append(why);
        }
        why.textContent = ` — not for this system: needs ${unmet.map((r) => REQUIREMENT_TEXT[r] || r).join(', ')}`;
        if (box.checked) this.picker.untick(row.dataset.method);
      } else if (why) {
        why.remove();
      }
    }
    this.picker.chooseDefaults();
  }

  /** Fills the form with a request (a preset). */
  fill(request) {
    this.setSystem(request.system, {
      params: request.params || {}, q0: request.q0, p0: request.p0,
      chart: request.chart, initialCoordinates: request.initial_coordinates,
    });
    this.picker.fill(request.methods || [request.method]);
    this.form.querySelector('#h').value = numberText(request.h);
    this.form.querySelector('#t_end').value = numberText(request.t_end);
    this.form.querySelector('#every').value = request.output?.every ? String(request.output.every) : '';
    this.form.querySelector('#compare').checked = Boolean(request.compare_to_reference);
    this.form.querySelector('#chaos').checked = asksIndicators(request);
  }

  /** The request body the form describes. Bad numbers are sent as null so the API names them. */
  read() {
    const system = this.system;
    const params = {};
    for (const input of this.paramsBox.querySelectorAll('[data-param]')) {
      const text = input.value.trim();
      if (text === '') continue;
      const kind = input.dataset.kind;
      params[input.dataset.param] = kind === 'number' ? parseNumber(text)
        : kind === 'number_list' ? parseList(text) : text;
    }
    const vector = (name) => {
      const list = this.stateBox.querySelector(`#${name}-list`);
      if (list) return parseList(list.value);
      return [...this.stateBox.querySelectorAll(`input[data-vector="${name}"]`)].map((i) => parseNumber(i.value));
    };
    const request = {
      system: system.id,
      params,
      methods: this.picker.read(),
      h: parseNumber(this.form.querySelector('#h').value),
      t_end: parseNumber(this.form.querySelector('#t_end').value),
      q0: vector('q0'),
      p0: vector('p0'),
      compare_to_reference: this.form.querySelector('#compare').checked,
    };
    if (system.charts.length > 1) {
      request.chart = this.chartId;
      request.initial_coordinates = this.defaultChart ? 'cartesian' : this.stateMode;
    }
    const every = this.form.querySelector('#every').value.trim();
    if (every !== '') {
      const n = Number(every);
      request.output = { every: Number.isInteger(n) ? n : every };
    }
    return askIndicators(request, this.form.querySelector('#chaos').checked);
  }

  /** Removes every error message. */
  clearErrors() {
    for (const node of this.form.querySelectorAll('.field-error')) node.textContent = '';
    for (const node of this.form.querySelectorAll('[aria-invalid]')) node.removeAttribute('aria-invalid');
    for (const node of this.form.querySelectorAll('.has-error')) node.classList.remove('has-error');
  }

  /**
   * Shows an API error beside the input its `field` names (or above the Run button when it names
   * none the form has); returns the input to focus, if any.
   * @param {{message: string, field: string|null}} error
   */
  showError(error) {
    const target = this.locate(error.field);
    const slot = target?.error || this.generalError;
    slot.textContent = error.message;
    if (target?.input) target.input.setAttribute('aria-invalid', 'true');
    slot.closest('.field, .method, fieldset')?.classList.add('has-error');
    this.picker.reveal(slot);
    return target?.input || null;
  }

  /** The input and error slot of an API field path. */
  locate(field) {
    if (!field) return null;
    if (/^methods?\b/.test(field)) return this.picker.locate(field) ?? this.fields.get('methods');
    // Exact path, then the path without its trailing index (`params.masses[2]` → `params.masses`).
    let path = field;
    for (;;) {
      if (this.fields.has(path)) return this.fields.get(path);
      const shorter = path.replace(/(\[\d+\]|\.[^.[\]]+)$/, '');
      if (shorter === path || shorter === '') break;
      path = shorter;
    }
    if (field === 'params.epsilon' && this.fields.has('params.gamma')) return this.fields.get('params.gamma');
    return null;
  }
}
