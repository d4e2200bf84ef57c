// The Phase-space section: the Poincaré section of a two-degree-of-freedom system (built-in or
// typed-in) at a chosen energy, or the stroboscopic section of a driven one, drawn orbit by orbit.
// A click on the plane (or Enter on the keyboard cursor) launches an orbit from that point: the
// plane's two names are set to the point's coordinates, the remaining momentum is solved from the
// energy by the server (`energy` of the request), and the orbit's crossings (`section` of the
// request, located by Hénon's trick) arrive over the NDJSON stream as `crossings` lines and are
// drawn as they come, one colour per orbit. A readout gives the coordinates under the pointer and
// the crossing nearest to it; the orbits download as JSON, the last one as a Rerun recording; a
// link (`#orbits=…`) reproduces the picture. The state is `data-ps-state` (idle, running, done,
// error), for tests; `window.geomint.phaseSpace.orbits` holds each orbit's request and points.

import { ApiError, simulateRrd, simulateStream } from './api.js';
import { downloadRecording, el, fmt, parseCount, parseNumber, plural, saveBlob } from './common.js';
import { colour } from './charts.js';
import { PhasePlot, wrap } from './phase-plot.js';

const HENON_HEILES = {
  name: 'Hénon–Heiles', coordinates: ['x', 'y'], mass: 1,
  potential: '(x^2 + y^2)/2 + x^2*y - y^3/3',
};
const DUFFING = {
  name: 'Driven damped Duffing oscillator', coordinates: ['x'], mass: 1,
  potential: '-x^2/2 + x^4/4 - A*x*cos(omega*t)', damping: { gamma: 'delta/2' },
  parameters: { delta: 0.3, A: 0.5, omega: 1.2 },
};
const PENDULUM = {
  name: 'Driven damped pendulum', coordinates: ['q'], mass: 1,
  potential: '1 - cos(q) - A*q*cos(omega*t)', damping: { gamma: 'b/2' },
  parameters: { b: 0.5, A: 1.5, omega: 0.6666666666666666 },
};
const EIGHTH = { id: 'kahan_li_8', base: 'velocity_verlet' };
const SIXTH = { id: 'kahan_li_6', base: 'modin_3s' };

/** The examples: a system and the settings that show it. */
export const EXAMPLES = [
  {
    id: 'henon_heiles', label: 'Hénon–Heiles at E = 1/8 (section y = 0, p_y > 0)', system: HENON_HEILES,
    kind: 'energy', where: 'y', direction: 'up', energy: 0.125, solve: 'p_y',
    x: { name: 'x', min: -0.45, max: 0.6 }, y: { name: 'p_x', min: -0.5, max: 0.5 },
    method: EIGHTH, h: 0.08, t_end: 2000, points: 250,
  },
  {
    id: 'elastic_pendulum', label: 'Planar elastic pendulum (built-in) at E = −0.1 (x = 0, p_x > 0)',
    system: 'elastic_pendulum_2d', kind: 'energy', where: 'x', direction: 'up', energy: -0.1, solve: 'p_x',
    x: { name: 'y', min: 0.6, max: 1.8 }, y: { name: 'p_y', min: -0.6, max: 0.6 },
    method: EIGHTH, h: 0.05, t_end: 2000, points: 250,
  },
  {
    id: 'duffing', label: 'Driven Duffing x″ + δx′ − x + x³ = A cos ωt, stroboscopic', system: DUFFING,
    kind: 'stroboscopic', period: (2 * Math.PI) / 1.2, phase: 0,
    x: { name: 'x', min: -1.8, max: 1.8 }, y: { name: 'p_x', min: -1.2, max: 1.2 },
    method: SIXTH, h: (2 * Math.PI) / 1.2 / 64, t_end: 10000, points: 2000,
  },
  {
    id: 'pendulum', label: 'Driven damped pendulum q″ + bq′ + sin q = A cos ωt, stroboscopic', system: PENDULUM,
    kind: 'stroboscopic', period: 3 * Math.PI, phase: 0,
    x: { name: 'q', min: -Math.PI, max: Math.PI, period: 2 * Math.PI }, y: { name: 'p_q', min: -3, max: 3 },
    method: SIXTH, h: (3 * Math.PI) / 64, t_end: 10000, points: 1000,
  },
];

/** The coordinates and momenta of `system` (an id of `catalogue` or a definition). */
export function stateNames(system, catalogue) {
  if (typeof system === 'string') {
    const entry = catalogue.find((s) => s.id === system);
    const coordinates = entry?.definition?.coordinates ?? entry?.charts?.[0]?.coordinates ?? [];
    const momenta = entry?.definition?.momenta ?? coordinates.map((c) => `p_${c}`);
    return { coordinates, momenta };
  }
  const coordinates = system?.coordinates ?? [];
  return { coordinates, momenta: system?.momenta ?? coordinates.map((c) => `p_${c}`) };
}

export class PhaseSpacePanel {
  /**
   * @param {HTMLElement} root the section
   * @param {object[]} systems the system catalogue (built-in and stored)
   */
  constructor(root, systems) {
    this.root = root;
    this.systems = systems;
    const $ = (id) => root.querySelector(`#ps-${id}`);
    this.$ = $;
    this.canvas = $('canvas');
    this.readout = $('readout');
    this.status = $('status');
    this.list = $('orbits');
    this.generalError = root.querySelector('#err-ps-form');
    /** Each orbit: {start: [a, b], request, points: {t, q, p, energy}, state, error}. */
    this.orbits = [];
    /** The settings the orbits on show were launched with. */
    this.settings = null;
    this.controllers = new Set();
    this.plot = new PhasePlot(this.canvas, this.read());
    $('example').replaceChildren(...EXAMPLES.map((e) => el('option', { value: e.id, text: e.label })));
    $('example').addEventListener('change', () => this.useExample($('example').value));
    $('kind').addEventListener('change', () => this.showKind());
    $('form').addEventListener('submit', (event) => {
      event.preventDefault();
      this.clear();
    });
    $('cancel').addEventListener('click', () => this.cancel());
    $('download-json').addEventListener('click', () => this.downloadJson());
    $('download-rrd').addEventListener('click', () => this.downloadRrd());
    this.canvas.addEventListener('click', (event) => {
      const at = this.plot.value(...this.pointer(event));
      if (at) this.launch(...at);
    });
    this.canvas.addEventListener('pointermove', (event) => this.readAt(...this.pointer(event)));
    this.canvas.addEventListener('keydown', (event) => this.key(event));
    new ResizeObserver(() => this.plot.resize()).observe($('figure'));
    this.useExample(EXAMPLES[0].id);
    this.setState('idle');
  }

  setState(state) {
    this.root.dataset.psState = state;
  }

  /** The pointer's position relative to the canvas, in CSS pixels. */
  pointer(event) {
    const box = this.canvas.getBoundingClientRect();
    return [event.clientX - box.left, event.clientY - box.top];
  }

  /** Fills the form with example `id` and starts a fresh picture. */
  useExample(id, overrides = {}) {
    const e = { ...EXAMPLES.find((x) => x.id === id), ...overrides };
    const set = (name, value) => {
      this.$(name).value = value ?? '';
    };
    set('example', e.id);
    set('system', JSON.stringify(e.system, null, 1));
    set('kind', e.kind);
    for (const name of ['where', 'direction', 'energy', 'solve', 'period', 'phase', 'h', 'points']) set(name, e[name]);
    set('t-end', e.t_end);
    set('method', JSON.stringify(e.method));
    for (const axis of ['x', 'y']) {
      set(`${axis}-name`, e[axis].name);
      set(`${axis}-min`, e[axis].min);
      set(`${axis}-max`, e[axis].max);
      this.$(`${axis}-name`).dataset.period = e[axis].period ?? '';
    }
    this.showKind();
    this.clear();
  }

  /** Shows the fields of the chosen kind of section. */
  showKind() {
    const energy = this.$('kind').value === 'energy';
    this.$('energy-fields').hidden = !energy;
    this.$('strobe-fields').hidden = energy;
  }

  /** The settings the form describes (bad numbers as null: the API names them). */
  read() {
    const value = (id) => this.$(id).value;
    const json = (id) => {
      try {
        return JSON.parse(value(id));
      } catch {
        return value(id).trim();
      }
    };
    const axis = (a) => ({
      name: value(`${a}-name`).trim(),
      min: parseNumber(value(`${a}-min`)) ?? 0,
      max: parseNumber(value(`${a}-max`)) ?? 1,
      period: parseNumber(this.$(`${a}-name`).dataset.period ?? '') ?? undefined,
    });
    return {
      example: value('example'),
      system: json('system'),
      kind: value('kind'),
      where: value('where'),
      direction: value('direction'),
      energy: parseNumber(value('energy')),
      solve: value('solve').trim(),
      period: parseNumber(value('period')),
      phase: parseNumber(value('phase')),
      x: axis('x'),
      y: axis('y'),
      method: json('method'),
      h: parseNumber(value('h')),
      t_end: parseNumber(value('t-end')),
      points: parseCount(value('points')),
    };
  }

  /** The simulation request of an orbit launched at (a, b) of the plane. */
  request(s, a, b) {
    const { coordinates, momenta } = stateNames(s.system, this.systems);
    const q0 = coordinates.map(() => 0);
    const p0 = momenta.map(() => 0);
    for (const [name, v] of [[s.x.name, a], [s.y.name, b]]) {
      const i = coordinates.indexOf(name);
      const j = momenta.indexOf(name);
      if (i >= 0) q0[i] = v;
      if (j >= 0) p0[j] = v;
    }
    const request = { system: s.system, method: s.method, h: s.h, t_end: s.t_end, q0, p0 };
    if (s.kind === 'energy') {
      request.section = { where: s.where, direction: s.direction, max_points: s.points };
      request.energy = { value: s.energy, momentum: s.solve };
    } else {
      request.section = { period: s.period, phase: s.phase, max_points: s.points };
    }
    // Samples are not drawn here: as few as the server allows.
    request.output = { every: Math.max(1, Math.ceil((s.t_end ?? 0) / (s.h || 1))) };
    return request;
  }

  /** Starts a fresh picture with the form's settings. */
  clear() {
    this.cancel();
    this.settings = this.read();
    this.orbits = [];
    this.plot.plane = { x: this.settings.x, y: this.settings.y };
    this.plot.clear();
    this.list.replaceChildren();
    this.generalError.textContent = '';
    this.status.textContent = 'Click on the plane (or move the cursor with the arrow keys and press Enter) to launch an orbit.';
    this.$('download-json').disabled = true;
    this.$('download-rrd').disabled = true;
    this.updateLink();
    this.setState('idle');
  }

  /** The plane point of a section point: the values of the plane's two names. */
  planePoint(names, q, p) {
    const { x, y } = this.settings;
    const valueOf = (name) => {
      const i = names.coordinates.indexOf(name);
      return i >= 0 ? q[i] : p[names.momenta.indexOf(name)];
    };
    return [wrap(valueOf(x.name), x.period), valueOf(y.name)];
  }

  /** Launches an orbit from plane point (a, b) and draws its crossings as they stream in. */
  async launch(a, b) {
    if (!this.settings) this.clear();
    const s = this.settings;
    const k = this.orbits.length;
    const orbit = { start: [a, b], request: this.request(s, a, b), points: { t: [], q: [], p: [], energy: [] }, state: 'running' };
    this.orbits.push(orbit);
    const item = el('li', { class: 'orbit', style: `--orbit-colour:${colour(k)}` },
      `orbit ${k + 1} from (${fmt(a, 3)}, ${fmt(b, 3)}): starting…`);
    this.list.append(item);
    this.setState('running');
    this.updateLink();
    const controller = new AbortController();
    this.controllers.add(controller);
    let names = stateNames(s.system, this.systems);
    try {
      await simulateStream(orbit.request, (line) => {
        if (line.type === 'header' && line.section) names = line.section;
        if (line.type === 'header') orbit.p0 = line.system.p0;
        if (line.type === 'crossings' && line.surface === 'section') {
          const c = orbit.points;
          c.t.push(...line.t);
          c.q.push(...line.q);
          c.p.push(...line.p);
          c.energy.push(...line.energy);
          this.plot.add(k, line.q.map((q, i) => this.planePoint(names, q, line.p[i])));
          item.textContent = `orbit ${k + 1} from (${fmt(a, 3)}, ${fmt(b, 3)}): ${plural(c.t.length, 'point')}…`;
        }
        if (line.type === 'summary') orbit.summary = line.section_summary;
        if (line.type === 'error') throw new ApiError(line.error, 0, line.method);
      }, controller.signal);
      orbit.state = 'done';
      const n = orbit.points.t.length;
      item.textContent = `orbit ${k + 1} from (${fmt(a, 3)}, ${fmt(b, 3)}): ${plural(n, 'point')}` +
        (orbit.summary?.note ? ` (${orbit.summary.note})` : '');
    } catch (error) {
      orbit.state = controller.signal.aborted ? 'cancelled' : 'error';
      orbit.error = error;
      item.textContent = `orbit ${k + 1}: ${orbit.state === 'cancelled' ? 'cancelled' : error.message}`;
      if (orbit.state === 'error') {
        this.generalError.textContent = error.message;
      }
    } finally {
      this.controllers.delete(controller);
    }
    this.settle();
  }

  /** The section's state once no orbit runs any more. */
  settle() {
    if (this.orbits.some((o) => o.state === 'running')) return;
    const failed = this.orbits.some((o) => o.state === 'error');
    const total = this.orbits.reduce((sum, o) => sum + o.points.t.length, 0);
    this.status.textContent = `${plural(this.orbits.length, 'orbit')}, ${plural(total, 'point')} in all.`;
    this.$('download-json').disabled = this.orbits.length === 0;
    this.$('download-rrd').disabled = this.orbits.length === 0;
    this.setState(failed ? 'error' : 'done');
  }

  cancel() {
    for (const controller of this.controllers) controller.abort();
  }

  /** The readout at pointer (cx, cy): the plane's coordinates, and the crossing nearest. */
  readAt(cx, cy) {
    const at = this.plot.value(cx, cy);
    if (!at || !this.settings) return;
    const { x, y } = this.settings;
    let text = `${x.name} = ${fmt(at[0])}, ${y.name} = ${fmt(at[1])}`;
    const hit = this.plot.nearest(cx, cy);
    if (hit) {
      const c = this.orbits[hit.orbit].points;
      text += `; orbit ${hit.orbit + 1}, crossing ${hit.index + 1}: t = ${fmt(c.t[hit.index], 6)}, H = ${fmt(c.energy[hit.index], 12)}`;
      this.readout.dataset.orbit = String(hit.orbit);
      this.readout.dataset.index = String(hit.index);
    } else {
      delete this.readout.dataset.orbit;
      delete this.readout.dataset.index;
    }
    this.readout.textContent = `${text}.`;
  }

  /** Arrow keys move the cursor by a fiftieth of the plane; Enter launches an orbit there. */
  key(event) {
    if (!this.settings) return;
    const { x, y } = this.settings;
    const cursor = this.plot.cursor ?? [(x.min + x.max) / 2, (y.min + y.max) / 2];
    const dx = (x.max - x.min) / 50;
    const dy = (y.max - y.min) / 50;
    const moves = { ArrowLeft: [-dx, 0], ArrowRight: [dx, 0], ArrowUp: [0, dy], ArrowDown: [0, -dy] };
    if (event.key in moves) {
      event.preventDefault();
      const [mx, my] = moves[event.key];
      this.plot.cursor = [cursor[0] + mx, cursor[1] + my];
      this.plot.draw();
      this.readAt(...this.plot.px(...this.plot.cursor));
    } else if (event.key === 'Enter') {
      event.preventDefault();
      this.plot.cursor = cursor;
      this.launch(...cursor);
    }
  }

  /** The link that reproduces the picture: its settings and its orbits' starting points. */
  updateLink() {
    const state = { settings: this.settings, orbits: this.orbits.map((o) => o.start) };
    this.$('link').href = `#orbits=${encodeURIComponent(JSON.stringify(state))}`;
  }

  /** Follows an `#orbits=…` link: the settings, then each orbit launched again. */
  async followLink() {
    const match = /^#orbits=(.*)$/.exec(window.location.hash);
    if (!match) return;
    let state;
    try {
      state = JSON.parse(decodeURIComponent(match[1]));
    } catch {
      this.generalError.textContent = 'The link does not hold a picture.';
      return;
    }
    const s = state.settings;
    this.useExample(s.example ?? EXAMPLES[0].id, { ...s, method: s.method, t_end: s.t_end });
    // One after the other: the server's simulation slots are shared.
    for (const [a, b] of state.orbits ?? []) await this.launch(a, b);
  }

  downloadJson() {
    const doc = { settings: this.settings, orbits: this.orbits.map(({ start, request, points, summary }) => ({ start, request, section: points, summary })) };
    saveBlob(new Blob([JSON.stringify(doc)], { type: 'application/json' }), 'geomint-phase-space.json');
  }

  downloadRrd() {
    const last = this.orbits[this.orbits.length - 1];
    if (!last) return;
    downloadRecording({
      button: this.$('download-rrd'), status: this.status, error: this.root.querySelector('#err-ps-rrd'),
      name: 'geomint-orbit.rrd', fetchBlob: () => simulateRrd(last.request),
    });
  }
}
