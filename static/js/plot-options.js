// What a run's plots are given (the options of Charts.build), from what is known of its system:
// the catalogue entry of a built-in system, or the definition of a system typed in (on the
// Your-system section, or read back with a stored recording). The coordinates' and momenta's
// names, the bodies, the chart's captions, and what the energy error is measured against:
//
// - `exact`: the system's exact solution;
// - `ref`: the adaptive DOP853 reference ("Compare to the reference");
// - `initial`: the initial energy H₀, an exact reference where nothing damps the motion. The
//   server sends it for an undamped system without exact solution; where an older server sends
//   none, the page takes the same difference of the sampled energies itself (`deriveEnergyError`).
//
// Only a damped system without exact solution, run without the reference, has no energy error.

import { chartName } from './form.js';
import { positionsOf } from './expression.js';

/** Built-in systems whose y axis points down, along gravity. */
const Y_DOWN = new Set(['elastic_pendulum_2d']);

/** The parameters that damp the built-in systems. */
const DAMPING_PARAMS = ['gamma', 'epsilon'];

/**
 * What the energy error of a run is measured against: `exact`, `ref`, `initial` or null (none).
 * @param {object} facts
 * @param {boolean} facts.sent whether the answer carries `energy_error`
 * @param {boolean} facts.exact whether the system has an exact solution
 * @param {boolean} facts.compared whether the run was compared to the reference
 * @param {boolean} facts.undamped whether nothing damps the run (H is then conserved)
 */
export function energyErrorSource({ sent, exact, compared, undamped }) {
  if (sent) return exact ? 'exact' : compared ? 'ref' : 'initial';
  return undamped ? 'initial' : null;
}

/** The energy-error options: the source, and whether the page derives the error itself. */
function energyError(header, request, exact, undamped) {
  // The server says what it measured against; recordings made before it did are inferred.
  const served = { exact: 'exact', reference: 'ref', initial: 'initial' }[header.energy_reference];
  const source = served ?? energyErrorSource({
    sent: Boolean(header.energy_error), exact, compared: Boolean(request?.compare_to_reference), undamped,
  });
  return { energyErrorSource: source, deriveEnergyError: source === 'initial' && !header.energy_error };
}

/** The names and captions of the plots of a run of built-in `system` in chart `chartId`. */
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

/**
 * The plot options of a run of built-in `system` (its catalogue entry) from its stream `header`
 * and its `request`. It is undamped when every damping parameter it has is 0.
 */
export function builtInPlotOptions(system, header, request) {
  const params = header.system.params ?? {};
  const damping = DAMPING_PARAMS.filter((name) => name in params);
  const undamped = damping.length > 0 && damping.every((name) => params[name] === 0);
  return {
    ...energyError(header, request, Boolean(system?.exact_solution), undamped),
    drift: Boolean(system?.conformal_damping) && header.system.q0.length === 1,
    ...chartOptions(system, header.system.chart),
  };
}

/**
 * How the bodies of `definition` are plotted: {dims, count, names, embed}, or null where there is
 * nothing to place beyond the one coordinate. Without `positions` the body is the first two or
 * three coordinates, as the server draws it. With them, a run's samples carry each body's place
 * (`bodies`) and `embed` is null — unless `evaluate`, for samples that do not (a recording read
 * back), where the page computes them from the definition's expressions at `params`.
 */
export function placeBodies(definition, { evaluate = false, params = {} } = {}) {
  const { coordinates, positions } = definition;
  if (!positions?.length) {
    if (coordinates.length < 2) return null;
    const dims = Math.min(3, coordinates.length);
    return { dims, count: 1, names: coordinates.slice(0, dims), embed: (q) => q.slice(0, dims) };
  }
  return {
    dims: positions[0].length, count: positions.length, names: ['x', 'y', 'z'],
    embed: evaluate ? positionsOf(definition, params) : null,
  };
}

/** Whether `definition` damps nothing: no damping, or a rate that is 0 at `params`. */
export function undampedDefinition(definition, params = {}) {
  const damping = definition.damping;
  if (!damping) return true;
  const rate = damping.gamma ?? damping.epsilon;
  const value = typeof rate === 'string' ? ({ ...definition.parameters, ...params })[rate.trim()] : rate;
  return value === 0;
}

/**
 * The plot options of a run of a system typed in, `definition`, from its stream `header` and its
 * `request`; `evaluate` places the bodies from the definition (see placeBodies).
 */
export function definitionPlotOptions(definition, header, request, { evaluate = false } = {}) {
  const { coordinates, momenta } = definition;
  const params = request?.params ?? header.system.params ?? {};
  return {
    ...energyError(header, request, false, undampedDefinition(definition, params)),
    drift: false,
    chartNames: coordinates,
    cartesianNames: coordinates,
    momentumNames: momenta ?? coordinates.map((c) => `p_${c}`),
    bodies: placeBodies(definition, { evaluate, params }),
  };
}
