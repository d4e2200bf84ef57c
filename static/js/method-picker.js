// The method checkboxes of a form: grouped as the catalogue groups them, each with its order,
// kind, citation, option input (inner method, base, processor, tolerance) and error slot. The
// simulation form (form.js) and the Your-system section (system.js) each have one.

import { el, parseNumber } from './common.js';

/** Display groups of the method catalogue, in order. */
const GROUPS = [
  { id: 'geometric', title: 'Geometric', note: 'Rayleigh-damped splittings (paper 000) and compositions' },
  { id: 'conformal', title: 'Conformal', note: 'conformal symplectic schemes (paper 003); linear damping only' },
  { id: 'baseline', title: 'Baselines', note: 'classical schemes and the adaptive reference' },
];

/** Inner methods `modin_rks` accepts (README, Methods; explicit Euler is not offered). */
const RKS_INNER = ['heun', 'rk3', 'rk4', 'implicit_midpoint'];

/** Processors `rowlands` accepts, the default first (paper 001 eqs. 32–37). */
const ROWLANDS_PROCESSORS = ['cheap', 'original', 'none'];

/** Chosen when nothing is: the first of these geometric methods that applies, beside rk4. */
const DEFAULT_GEOMETRIC = ['modin_3s', 'csv2', 'velocity_verlet', 'implicit_midpoint'];

/**
 * The method checkboxes, grouped as the catalogue groups them (geometric, conformal, baselines),
 * each with its order, kind, citation, option input (inner method, base, processor, tolerance)
 * and error slot. It keeps the chosen methods in the order they were ticked, which is the
 * request's order. The simulation form offers every method; the Your-system section only those
 * its system allows.
 */
export class MethodPicker {
  /**
   * @param {HTMLElement} box where the groups go
   * @param {object[]} methods the method catalogue (GET /api/v1/methods)
   * @param {object} [options]
   * @param {string} [options.idPrefix] of the inputs' ids: `m-` gives `m-rk4` and `m-rk4-tolerance`
   * @param {string[]|null} [options.offered] the ids of the methods offered (null: all)
   */
  constructor(box, methods, { idPrefix = 'm-', offered = null } = {}) {
    Object.assign(this, { box, methods, idPrefix });
    /** Chosen method ids in the order they were ticked. */
    this.order = [];
    this.offer(offered);
  }

  /**
   * Offers the methods whose ids are in `ids` (null: all), with only the bases among them for the
   * compositions. Methods still offered stay chosen.
   */
  offer(ids) {
    const offered = ids ? this.methods.filter((m) => ids.includes(m.id)) : this.methods;
    const keep = this.order.filter((id) => offered.some((m) => m.id === id));
    const specs = this.read().filter((spec) => keep.includes(spec.id ?? spec));
    this.bases = this.methods.filter((x) => x.symmetric && x.order === 2 && (!ids || ids.includes(x.id))).map((x) => x.id);
    // Each group folds away behind a summary that names the methods chosen in it, so that the
    // form stays short and Run is a few Tab presses from the top.
    const group = (title, note, members) => (members.length === 0 ? null
      : el('details', { class: 'method-group' },
        el('summary', {}, el('span', { class: 'group-title', text: title }), ' ',
          el('span', { class: 'group-chosen' }), note ? el('small', { class: 'group-note', text: note }) : null),
        members.map((m) => this.methodRow(m))));
    const groups = GROUPS.map((g) => group(g.title, g.note, offered.filter((m) => m.group === g.id)));
    groups.push(group('Other', null, offered.filter((m) => !GROUPS.some((g) => g.id === m.group))));
    this.box.replaceChildren(...groups.filter(Boolean));
    this.order = [];
    this.fill(specs);
  }

  /** Each group's summary: how many of its methods are chosen, and which. */
  showChosen() {
    for (const group of this.box.querySelectorAll('details.method-group')) {
      const boxes = [...group.querySelectorAll('input[type=checkbox]')];
      const chosen = boxes.filter((b) => b.checked).map((b) => b.value);
      group.querySelector('.group-chosen').textContent = chosen.length
        ? `— ${chosen.length} of ${boxes.length} chosen: ${chosen.join(', ')}`
        : `— none of ${boxes.length} chosen`;
      group.dataset.chosen = String(chosen.length);
    }
  }

  /**
   * When no method is chosen, chooses a geometric method that applies and rk4, so that a fresh
   * form runs as it is.
   */
  chooseDefaults() {
    if (this.order.length) return;
    const available = (id) => {
      const box = this.row(id)?.querySelector('input[type=checkbox]');
      return Boolean(box && !box.disabled);
    };
    this.fill([DEFAULT_GEOMETRIC.find(available), 'rk4'].filter((id) => id && available(id)));
  }

  /** Opens the group that holds `input` (to show an error there). */
  reveal(input) {
    const group = input?.closest('details.method-group');
    if (group) group.open = true;
  }

  /** Every method's row. */
  rows() {
    return this.box.querySelectorAll('.method');
  }

  /** The row of method `id`, if offered. */
  row(id) {
    return this.box.querySelector(`.method[data-method="${id}"]`);
  }

  /** One method: checkbox, name, id, order and kind, citation, option input, error slot. */
  methodRow(m) {
    const id = this.idPrefix + m.id;
    const errorId = 'err-' + id;
    const box = el('input', { type: 'checkbox', id, name: 'method', value: m.id, 'aria-describedby': `note-${id} ${errorId}` });
    box.addEventListener('change', () => {
      this.order = this.order.filter((x) => x !== m.id);
      if (box.checked) this.order.push(m.id);
      this.showChosen();
    });
    const kind = m.kind.replace('_', ' ');
    const label = el('label', { for: id },
      el('span', { class: 'method-name', text: m.name }), ' ',
      el('code', { text: m.id }));
    const note = el('p', { class: 'method-note', id: `note-${id}` },
      el('span', { class: 'tag', text: `order ${m.order}` }),
      el('span', { class: `tag kind-${m.kind}`, text: kind }),
      m.conformal_symplectic ? el('span', { class: 'tag', text: 'conformal symplectic' })
        : m.symplectic ? el('span', { class: 'tag', text: 'symplectic' }) : null,
      m.requirements.includes('conservative') ? el('span', { class: 'tag', text: 'undamped only' }) : null,
      el('span', { class: 'cite', text: `${m.reference.paper}, ${m.reference.equation}` }));
    let option = null;
    if (m.options.includes('inner')) {
      option = this.optionSelect(m, 'inner', 'inner method', RKS_INNER, 'heun');
    } else if (m.options.includes('base')) {
      const bases = this.bases;
      option = this.optionSelect(m, 'base', 'base method', bases, bases.includes('modin_3s') ? 'modin_3s' : bases[0]);
    } else if (m.options.includes('processor')) {
      option = this.optionSelect(m, 'processor', 'processor', ROWLANDS_PROCESSORS, ROWLANDS_PROCESSORS[0]);
    } else if (m.options.includes('tolerance')) {
      const tid = `${id}-tolerance`;
      option = el('span', { class: 'method-option' },
        el('label', { for: tid, text: 'tolerance' }),
        el('input', { id: tid, type: 'number', step: 'any', placeholder: '1e-12', 'data-option': 'tolerance' }));
    }
    const error = el('p', { class: 'field-error', id: errorId, 'aria-live': 'polite' });
    const row = el('div', { class: 'method', 'data-method': m.id },
      el('div', { class: 'method-head' }, box, label), note, option, error);
    row.requirements = m.requirements;
    return row;
  }

  optionSelect(m, option, text, values, fallback) {
    const id = `${this.idPrefix}${m.id}-${option}`;
    const select = el('select', { id, 'data-option': option },
      values.map((v) => el('option', { value: v, text: v })));
    select.value = fallback;
    return el('span', { class: 'method-option' }, el('label', { for: id, text }), select);
  }

  /** Unticks method `id`. */
  untick(id) {
    const box = this.row(id)?.querySelector('input[type=checkbox]');
    if (box) box.checked = false;
    this.order = this.order.filter((x) => x !== id);
    this.showChosen();
  }

  /** Chooses the methods of `specs` (ids, or objects with `id` and options), in that order. */
  fill(specs) {
    this.order = [];
    for (const box of this.box.querySelectorAll('input[type=checkbox]')) box.checked = false;
    for (const spec of specs) {
      const id = typeof spec === 'string' ? spec : spec.id;
      const row = this.row(id);
      if (!row) continue;
      row.querySelector('input[type=checkbox]').checked = true;
      this.order.push(id);
      if (typeof spec === 'object') {
        for (const input of row.querySelectorAll('[data-option]')) {
          const v = spec[input.dataset.option];
          if (v !== undefined) input.value = String(v);
        }
      }
    }
    this.showChosen();
  }

  /** The chosen methods as the request lists them: an id, or {id, option} where one is set. */
  read() {
    return this.order.map((id) => {
      const row = this.row(id);
      const spec = { id };
      for (const input of row.querySelectorAll('[data-option]')) {
        const v = input.value.trim();
        if (v === '') continue;
        spec[input.dataset.option] = input.type === 'number' ? parseNumber(v) : v;
      }
      return Object.keys(spec).length === 1 ? id : spec;
    });
  }

  /**
   * The input and error slot an API field path names: `methods[1]` (the second chosen method),
   * `methods[1].inner` (its option), `method` (the first). Null for paths it does not place.
   */
  locate(field) {
    const match = /^methods?(?:\[(\d+)\])?(?:\.(\w+))?/.exec(field ?? '');
    if (!match) return null;
    const index = match[1] === undefined ? (field === 'method' ? 0 : null) : Number(match[1]);
    const id = index === null ? null : this.order[index];
    const row = id && this.row(id);
    if (!row) return null;
    const option = match[2] && row.querySelector(`[data-option="${match[2]}"]`);
    return { input: option || row.querySelector('input[type=checkbox]'), error: row.querySelector('.field-error') };
  }
}
