// The Phase-space section: the Poincaré section of a two-degree-of-freedom system (built-in or
// typed-in) at a chosen energy, or the stroboscopic section of a driven one, drawn orbit by orbit.
// A click on the plane (or Enter on the keyboard cursor) launches an orbit from that point: the
// plane's two names are set to the point's coordinates, the remaining momentum is solved from the
// energy by the server (`energy` of the request), and the orbit's crossings (`section` of the
// request, located by Hénon's trick) arrive over the NDJSON stream as `crossings` lines and are
// drawn as they come, one colour per orbit. A readout gives the coordinates under the pointer and
// the crossing nearest to it; the orbits download as JSON, the last one as a Rerun recording; a
// link (`#orbits=…`) reproduces the picture. The picture never disagrees with the form unsaid:
// the plane's ranges apply at once, other edits apply while nothing is drawn, and otherwise a note
// names the settings the orbits on show were drawn with until the next click starts afresh. The
// part of the plane outside the energy surface (POST /api/v1/simulate/allowed-region) is grey, and
// a click there says why no orbit starts. The state is `data-ps-state` (idle, running, done,
// error), for tests; `window.geomint.phaseSpace.orbits` holds each orbit's request and points.

import { ApiError, allowedRegion, simulateRrd, simulateStream } from './api.js';
import { downloadRecording, el, fmt, parseCount, parseNumber, plural, saveBlob } from './common.js';
import { colour } from './charts.js';
import { PhasePlot, wrap } from './phase-plot.js';
import { chaosMeaning } from './chaos.js';
import { rampColour } from './sweep.js';

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
    x: { name: 'x', min: -0.55, max: 0.55 }, y: { name: 'p_x', min: -0.55, max: 0.55 },
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
    this.plot.colourOf = (k) => this.orbitColour(k);
    $('example').replaceChildren(...EXAMPLES.map((e) => el('option', { value: e.id, text: e.label })));
    $('example').addEventListener('change', () => this.useExample($('example').value));
    $('kind').addEventListener('change', () => this.showKind());
    // Edits take effect at once: the plane's ranges redraw the orbits on show, other settings
    // apply while nothing is drawn, and otherwise the picture says it was drawn with others.
    $('form').addEventListener('input', (event) => {
      if (event.target !== $('example')) this.formChanged();
    });
    $('form').addEventListener('change', (event) => {
      if (event.target !== $('example')) this.formChanged();
    });
    $('form').addEventListener('submit', (event) => {
      event.preventDefault();
      this.clear();
    });
    $('cancel').addEventListener('click', () => this.cancel());
    $('colour-by').addEventListener('change', () => this.recolour());
    /** Called with a sweep request: the chaos map of the plane (main.js runs it in Sweeps). */
    this.onChaosMap = null;
    $('chaos-map').addEventListener('click', () => {
      if (this.stale) this.clear();
      const body = this.chaosMapRequest();
      if (body) this.onChaosMap?.(body);
    });
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
    if ('chaos' in e) this.$('chaos').checked = Boolean(e.chaos);
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
      chaos: this.$('chaos').checked,
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
    // At one energy only: the tangent maps of a driven system's clock are not offered here.
    if (s.chaos && s.kind === 'energy') request.indicators = ['megno', 'lyapunov'];
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
    this.plot.region = null;
    this.plot.clear();
    this.list.replaceChildren();
    this.generalError.textContent = '';
    this.status.textContent = 'Click on the plane (or move the cursor with the arrow keys and press Enter) to launch an orbit.';
    this.$('download-json').disabled = true;
    this.$('download-rrd').disabled = true;
    this.showDrawn();
    this.showStale([]);
    this.refreshRegion();
    this.updateLink();
    this.setState('idle');
  }

  /** The settings that change what an orbit is (all but the plane's ranges), in words. */
  static described(s) {
    const system = typeof s.system === 'string' ? s.system : s.system?.name ?? 'the system typed in';
    const method = typeof s.method === 'string' ? s.method : s.method?.id ?? JSON.stringify(s.method);
    const entries = [
      ['system', 'the system', JSON.stringify(s.system), system],
      ['kind', 'the kind of section', s.kind, s.kind],
    ];
    if (s.kind === 'energy') {
      entries.push(['where', 'the surface', s.where, `${s.where} = 0`], ['direction', 'the crossing', s.direction, s.direction],
        ['energy', 'E', s.energy, fmt(s.energy, 6)], ['solve', 'the momentum solved', s.solve, s.solve]);
    } else {
      entries.push(['period', 'T', s.period, fmt(s.period, 6)], ['phase', 'φ', s.phase, fmt(s.phase, 6)]);
    }
    entries.push(['x-name', 'across', s.x.name, s.x.name], ['y-name', 'up', s.y.name, s.y.name],
      ['method', 'the method', JSON.stringify(s.method), method], ['h', 'h', s.h, fmt(s.h, 6)],
      ['t-end', 't_end', s.t_end, fmt(s.t_end, 6)], ['points', 'points per orbit', s.points, String(s.points)],
      ['chaos', 'chaos indicators', Boolean(s.chaos), s.chaos ? 'on' : 'off']);
    return entries.map(([id, label, key, text]) => ({ id, label, key: String(key), text }));
  }

  /** What differs between the drawn settings and the form's, but the plane's ranges. */
  static differences(drawn, form) {
    const now = PhaseSpacePanel.described(form);
    const before = PhaseSpacePanel.described(drawn);
    if (drawn.kind !== form.kind) return [now[1]].map((n) => ({ ...n, drawn: before[1].text }));
    return now.flatMap((n, k) => (n.key === before[k].key ? [] : [{ ...n, drawn: before[k].text }]));
  }

  /**
   * The form was edited: with nothing drawn yet the edit applies; the plane's ranges apply at
   * once (the orbits on show are redrawn); other edits mark the picture as drawn with other
   * settings until the next click, which starts a new picture.
   */
  formChanged() {
    if (!this.settings) return;
    const form = this.read();
    const changes = PhaseSpacePanel.differences(this.settings, form);
    if (changes.length > 0 && this.orbits.length === 0) {
      this.clear();
      return;
    }
    const { x, y } = this.settings;
    const range = (a, b) => a.min !== b.min || a.max !== b.max;
    if ((range(x, form.x) || range(y, form.y)) && form.x.max > form.x.min && form.y.max > form.y.min) {
      for (const axis of ['x', 'y']) Object.assign(this.settings[axis], { min: form[axis].min, max: form[axis].max });
      this.plot.plane = { x: this.settings.x, y: this.settings.y };
      this.plot.draw();
      this.updateLink();
      this.refreshRegion();
    }
    this.showStale(changes);
  }

  /** The caption of the picture: the settings it is drawn with. */
  showDrawn() {
    const s = this.settings;
    const d = Object.fromEntries(PhaseSpacePanel.described(s).map((e) => [e.id, e.text]));
    const surface = s.kind === 'energy'
      ? `at E = ${d.energy} on the surface ${d.where} (crossing ${d.direction}), ${d.solve} solved from the energy`
      : `stroboscopic, every T = ${d.period} from φ = ${d.phase}`;
    this.$('drawn').textContent = `Drawn: ${d.system}, ${surface}; ${d.method} with h = ${d.h} to t = ${d['t-end']}, ` +
      `at most ${d.points} points per orbit.`;
  }

  /** Says which settings the picture was drawn with, where the form now says otherwise. */
  showStale(changes) {
    this.stale = changes.length > 0;
    const note = this.$('stale');
    note.hidden = !this.stale;
    this.root.dataset.psStale = String(this.stale);
    if (!this.stale) {
      note.textContent = '';
      return;
    }
    const list = (f) => changes.map(f).join(', ');
    note.textContent = `The orbits on show were drawn with ${list((c) => `${c.label} = ${c.drawn}`)}; the form now ` +
      `says ${list((c) => `${c.label} = ${c.text}`)}. The next click clears the picture and uses the form's ` +
      'settings (as does “Clear and use these settings”).';
  }

  /**
   * Asks the server which points of the plane can start an orbit at the energy (in a moment:
   * edits come keystroke by keystroke), and shades the others.
   */
  refreshRegion() {
    clearTimeout(this.regionTimer);
    this.regionController?.abort();
    const s = this.settings;
    const legend = this.$('region');
    if (s.kind !== 'energy') {
      this.plot.region = null;
      this.plot.draw();
      legend.textContent = '';
      delete this.root.dataset.psRegion;
      return;
    }
    this.root.dataset.psRegion = 'loading';
    this.regionTimer = setTimeout(async () => {
      const controller = new AbortController();
      this.regionController = controller;
      const axis = (a, points) => ({ name: a.name, min: a.min, max: a.max, points });
      const body = { ...this.request(s, s.x.min, s.y.min), plane: { x: axis(s.x, 121), y: axis(s.y, 91) } };
      try {
        const region = await allowedRegion(body, controller.signal);
        if (controller.signal.aborted) return;
        this.plot.region = region;
        this.plot.draw();
        const total = region.x.length * region.y.length;
        const least = Math.min(...region.lowest.flat().filter((v) => v !== null));
        legend.textContent = region.allowed_points === 0
          ? `No point of this plane lies on the energy surface at E = ${fmt(s.energy, 6)}: even with ${s.solve} = 0 ` +
            `the least energy on it is ${fmt(least, 6)}. Raise E or move the plane.`
          : `Grey: outside the energy surface at E = ${fmt(s.energy, 6)}. There the energy with ${s.solve} = 0 is ` +
            `already above E, so no value of ${s.solve} puts the point on the surface and a click starts nothing ` +
            `(${plural(region.allowed_points, 'point')} of a ${region.x.length} × ${region.y.length} grid can start an orbit).`;
        legend.dataset.allowed = String(region.allowed_points);
        legend.dataset.total = String(total);
        this.root.dataset.psRegion = 'ready';
      } catch (error) {
        if (controller.signal.aborted) return;
        this.plot.region = null;
        this.plot.draw();
        legend.textContent = `Which points can start an orbit is not known: ${error.message}`;
        this.root.dataset.psRegion = 'error';
      }
    }, 250);
  }

  /** Why no orbit starts at (a, b), in words, when the point is outside the energy surface; else null. */
  forbiddenAt(a, b) {
    const at = this.plot.regionAt(a, b);
    if (!at?.forbidden || !this.settings) return null;
    const s = this.settings;
    const least = this.plot.region.lowest[at.j][at.i];
    return `(${fmt(a, 3)}, ${fmt(b, 3)}) lies outside the energy surface (grey): with ${s.solve} = 0 its energy is ` +
      `already ${least === null ? 'unbounded' : `about ${fmt(least, 4)}`}, above E = ${fmt(s.energy, 6)}, so no orbit starts there.`;
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
    if (!this.settings || this.stale) this.clear();
    const why = this.forbiddenAt(a, b);
    if (why) {
      this.status.textContent = `No orbit: ${why}`;
      this.root.dataset.psRefused = `${a},${b}`;
      return;
    }
    delete this.root.dataset.psRefused;
    const s = this.settings;
    const k = this.orbits.length;
    const orbit = { start: [a, b], request: this.request(s, a, b), points: { t: [], q: [], p: [], energy: [] }, state: 'running' };
    this.orbits.push(orbit);
    const item = el('li', { class: 'orbit', style: `--orbit-colour:${this.orbitColour(k)}` },
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
        if (line.type === 'summary') {
          orbit.summary = line.section_summary;
          orbit.indicators = line.indicators ?? null;
        }
        if (line.type === 'error') throw new ApiError(line.error, 0, line.method);
      }, controller.signal);
      orbit.state = 'done';
      const n = orbit.points.t.length;
      item.textContent = `orbit ${k + 1} from (${fmt(a, 3)}, ${fmt(b, 3)}): ${plural(n, 'point')}` +
        (orbit.summary?.note ? ` (${orbit.summary.note})` : '') + PhaseSpacePanel.fewer(s, n, orbit.summary) +
        PhaseSpacePanel.chaosText(orbit.indicators);
      item.dataset.megno = orbit.indicators?.megno_mean ?? '';
      if (this.$('colour-by').value === 'megno') this.recolour();
    } catch (error) {
      orbit.state = controller.signal.aborted ? 'cancelled' : 'error';
      orbit.error = error;
      const outside = error.field === 'energy.value';
      const words = outside
        ? `no orbit from (${fmt(a, 3)}, ${fmt(b, 3)}): the point lies outside the energy surface at E = ` +
          `${fmt(s.energy, 6)} (no ${s.solve} ≥ 0 gives that energy there)`
        : error.message;
      item.textContent = `orbit ${k + 1}: ${orbit.state === 'cancelled' ? 'cancelled' : words}`;
      if (orbit.state === 'error' && !outside) {
        this.generalError.textContent = error.message;
      }
    } finally {
      this.controllers.delete(controller);
    }
    this.settle();
  }

  /**
   * Why an orbit has fewer points than asked, in words (empty when it has them all): the run
   * reached t_end first — after so many drive periods, or with so many crossings of the surface
   * in that time — or some crossings could not be located.
   */
  static fewer(s, n, summary) {
    if (!Number.isInteger(s.points) || n >= s.points || n === 0) return '';
    const why = s.kind === 'stroboscopic'
      ? `t_end = ${fmt(s.t_end, 6)} holds ${Math.floor(s.t_end / s.period)} drive periods`
      : `the orbit crossed the surface ${n} times before t_end = ${fmt(s.t_end, 6)}`;
    const unlocated = summary?.unlocated ? `; ${plural(summary.unlocated, 'crossing')} could not be located` : '';
    return ` — fewer than the ${s.points} asked: ${why}${unlocated}; raise t_end for more`;
  }

  /** An orbit's indicators in words: `; ⟨Y⟩ = 2.01 (about 2: regular, on a torus), λ_max = 0.0012`. */
  static chaosText(indicators) {
    const y = indicators?.megno_mean;
    const lambda = indicators?.lyapunov?.[0];
    if (y == null && lambda == null) return '';
    const parts = [];
    if (y != null) parts.push(`⟨Y⟩ = ${fmt(y, 3)} (${chaosMeaning('megno_mean', y)})`);
    if (lambda != null) parts.push(`λ_max = ${fmt(lambda, 3)}`);
    return `; ${parts.join(', ')}`;
  }

  /** The colour of orbit `k` as the choice above the list says: its own, or by its ⟨Y⟩. */
  orbitColour(k) {
    if (this.$('colour-by').value !== 'megno') return colour(k);
    const y = this.orbits[k]?.indicators?.megno_mean;
    return y == null ? '#9a9a9a' : `rgb(${rampColour(y / 8).join(',')})`;
  }

  /** Redraws the orbits and their list markers in the chosen colours. */
  recolour() {
    this.orbits.forEach((_, k) => this.list.children[k]?.style.setProperty('--orbit-colour', this.orbitColour(k)));
    this.plot.draw();
  }

  /**
   * The sweep whose cells are the orbits a click on this plane launches: the same system, method,
   * step and energy, the plane's two names as the axes (the initial state's other components 0,
   * the energy's momentum solved per cell), MEGNO's ⟨Y⟩ per cell; at most 1000 time units and a
   * 41-column grid, so that the map comes in seconds. Null (with the reason shown) when the
   * section is not at one energy or its names are not the state's.
   */
  chaosMapRequest() {
    const s = this.settings;
    const { coordinates, momenta } = stateNames(s.system, this.systems);
    const slot = (name) => {
      const i = coordinates.indexOf(name);
      if (i >= 0) return `q0[${i}]`;
      const j = momenta.indexOf(name);
      return j >= 0 ? `p0[${j}]` : null;
    };
    const [x, y, solve] = [slot(s.x.name), slot(s.y.name), slot(s.solve)];
    if (s.kind !== 'energy' || !x || !y || !solve?.startsWith('p0')) {
      this.status.textContent = 'A chaos map needs a section at one energy whose plane and solved momentum are the system’s names.';
      return null;
    }
    const tEnd = Math.min(s.t_end ?? 1000, 1000);
    const columns = 41;
    const rows = Math.max(5, Math.min(81, Math.round((columns * (s.y.max - s.y.min)) / (s.x.max - s.x.min))));
    return {
      system: s.system,
      methods: [s.method],
      h: s.h,
      t_end: tEnd,
      every: Math.max(1, Math.ceil(tEnd / (s.h || 1))),
      q0: coordinates.map(() => 0),
      p0: momenta.map(() => 0),
      indicators: ['megno'],
      energy_surface: { energy: s.energy, solve_for: solve },
      axes: [
        { name: x, min: s.x.min, max: s.x.max, n: columns },
        { name: y, min: s.y.min, max: s.y.max, n: rows },
      ],
    };
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
    const why = this.forbiddenAt(...at);
    if (why) text += `: outside the energy surface, no orbit starts here`;
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
