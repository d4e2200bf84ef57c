// One-click presets that reproduce the papers' experiments. Each preset group names its paper
// and figures; each variant is a complete simulation request (the form is filled with it and run).
// Paper 000 writes the damping as ε with D = M for the pendulum, so its ε = 0.01 is γ = 0.005 here.
// Runs sample about 1000 times per method unless a figure needs every step (h = 0.5 phase plots).
// Paper 001's presets choose a coordinate chart and give the initial state in Cartesian
// coordinates, so that the variants in different charts start from the same physical state.

const PENDULUM_Q0 = 0.9 * Math.PI;

/** The methods of paper 000's comparisons: Algorithms 3.1–3.3 (RKS with Heun inside) and Heun. */
const MODIN_VS_HEUN = ['modin_3s', 'modin_2s', { id: 'modin_rks', inner: 'heun' }, 'heun'];
/** The methods of paper 003's comparisons. */
const CONFORMAL_VS_RK3 = ['rk3', 'csv1', 'csv2', 'cimp'];

function pendulum000(h, methods = MODIN_VS_HEUN) {
  return {
    system: 'pendulum',
    params: { gamma: 0.005 },
    methods,
    h,
    t_end: 200,
    q0: [PENDULUM_Q0],
    p0: [0],
    compare_to_reference: true,
  };
}

function elastic000(epsilon, h = 0.1) {
  return {
    system: 'elastic_pendulum_3d',
    params: { epsilon },
    methods: MODIN_VS_HEUN,
    h,
    t_end: 200,
    compare_to_reference: true,
  };
}

function oscillator003(gamma, h, tEnd, every = undefined) {
  return {
    system: 'harmonic_oscillator',
    params: { omega: 1, gamma },
    methods: CONFORMAL_VS_RK3,
    h,
    t_end: tEnd,
    q0: [1],
    p0: [0],
    compare_to_reference: false,
    ...(every ? { output: { every } } : {}),
  };
}

function pendulum003(gamma, h = 0.025, tEnd = 100) {
  return {
    system: 'pendulum',
    params: { gamma },
    methods: CONFORMAL_VS_RK3,
    h,
    t_end: tEnd,
    q0: [PENDULUM_Q0],
    p0: [0],
    compare_to_reference: true,
  };
}

/** 001 Fig. 4: the planar elastic pendulum (l = m = k = 1, g = 0.2) to t = 4, Störmer–Verlet
 * against Rowlands' processed method, energy errors against the reference. */
function pendulum001(h) {
  return {
    system: 'elastic_pendulum_2d',
    chart: 'cartesian',
    initial_coordinates: 'cartesian',
    params: { m: 1, k: 1, l: 1, g: 0.2 },
    methods: ['velocity_verlet', { id: 'rowlands', processor: 'cheap' }],
    h,
    t_end: 4,
    q0: [0.6, 1.2],
    p0: [0, 0],
    compare_to_reference: true,
    output: { every: 1 },
  };
}

/** 001 Sec. 5.2: the free particle, symplectic Euler in `chart`. */
function particle001(chart) {
  return {
    system: 'free_particle_2d',
    chart,
    initial_coordinates: 'cartesian',
    params: { m: 1 },
    methods: ['symplectic_euler'],
    h: 0.1,
    t_end: 10,
    q0: [1, 0.5],
    p0: [0.2, 1],
    compare_to_reference: false,
    output: { every: 1 },
  };
}

/** 001 Fig. 8: 1000 steps of symplectic Euler at h = 0.3 on the undamped unit oscillator. */
function oscillator001(chart) {
  return {
    system: 'harmonic_oscillator',
    chart,
    initial_coordinates: 'cartesian',
    params: { omega: 1, gamma: 0, k: 2 },
    methods: ['symplectic_euler'],
    h: 0.3,
    t_end: 300,
    q0: [1],
    p0: [0],
    compare_to_reference: false,
    output: { every: 1 },
  };
}

/** 001 Figs. 2–3: explicit Euler on a first-order ODE in `chart`, beside the DOP853 reference
 * sampled at the same times (the exact solution, to the eye). */
function ode001(system, params, y0, h, tEnd, chart) {
  return {
    system,
    chart,
    initial_coordinates: 'cartesian',
    params,
    methods: ['explicit_euler', 'reference'],
    h,
    t_end: tEnd,
    q0: [y0],
    p0: [0],
    compare_to_reference: false,
    output: { every: 1 },
  };
}

/**
 * @typedef {{id: string, label: string, note?: string, request: object}} Variant
 * @typedef {{id: string, title: string, paper: string, text: string, variants: Variant[]}} PresetGroup
 * @type {PresetGroup[]}
 */
export const PRESETS = [
  {
    id: 'p000-pendulum',
    title: 'Damped pendulum',
    paper: 'Paper 000, Figs. 1–3',
    text: 'q₀ = 0.9π, p₀ = 0, ε = 0.01 (γ = 0.005), t ≤ 200: splittings 3S, 2S, RKS against Heun.',
    variants: [
      { id: 'h0.1', label: 'h = 0.1', request: pendulum000(0.1) },
      { id: 'h0.2', label: 'h = 0.2', request: pendulum000(0.2) },
      { id: 'h0.4', label: 'h = 0.4', request: pendulum000(0.4) },
      { id: 'h0.5', label: 'h = 0.5', request: pendulum000(0.5) },
      { id: 'h0.8', label: 'h = 0.8', request: pendulum000(0.8) },
      { id: 'h1', label: 'h = 1', request: pendulum000(1) },
      { id: '3s-heun', label: '3S vs Heun', note: 'h = 0.2', request: pendulum000(0.2, ['modin_3s', 'heun']) },
    ],
  },
  {
    id: 'p000-elastic',
    title: 'Elastic 3-D pendulum',
    paper: 'Paper 000, Figs. 4–5',
    text: 'Paper’s initial state, h = 0.1, t ≤ 200: 3S, 2S, RKS against Heun; J₃ and the x–y limit cycle.',
    variants: [
      { id: 'eps0.1', label: 'ε = 0.1', request: elastic000(0.1) },
      { id: 'eps0.01', label: 'ε = 0.01', request: elastic000(0.01) },
      { id: 'eps0.01-h0.4', label: 'ε = 0.01', note: 'h = 0.4', request: elastic000(0.01, 0.4) },
    ],
  },
  {
    id: 'p003-oscillator',
    title: 'Damped oscillator',
    paper: 'Paper 003, Figs. 4.1–4.7',
    text: 'ω = 1, q₀ = 1, p₀ = 0: RK3 against CSV1, CSV2, CIMP; errors against the exact solution.',
    variants: [
      { id: 'g0.005-h0.5', label: 'γ = 0.005, h = 0.5', note: 'Figs. 4.6–4.7, t ≤ 2000', request: oscillator003(0.005, 0.5, 2000, 1) },
      { id: 'g0.025-h0.0125', label: 'γ = 0.025, h = 0.0125', note: 'Fig. 4.1, t ≤ 50', request: oscillator003(0.025, 0.0125, 50) },
      { id: 'g0.0001-h0.0125', label: 'γ = 0.0001, h = 0.0125', note: 'Figs. 4.3, 4.5, t ≤ 100', request: oscillator003(0.0001, 0.0125, 100) },
    ],
  },
  {
    id: 'p003-pendulum',
    title: 'Damped pendulum (conformal)',
    paper: 'Paper 003, Figs. 4.8–4.13',
    text: 'q₀ = 0.9π, h = 0.025, t ≤ 100: RK3 against CSV1, CSV2, CIMP; errors against the reference.',
    variants: [
      { id: 'g0.02', label: 'γ = 0.02', note: 'Figs. 4.12–4.13', request: pendulum003(0.02) },
      { id: 'g0.05', label: 'γ = 0.05', note: 'Figs. 4.9–4.10', request: pendulum003(0.05) },
      { id: 'g0.0025', label: 'γ = 0.0025', note: 'Fig. 4.11', request: pendulum003(0.0025) },
    ],
  },
  {
    id: 'p001-fig4',
    title: 'Planar elastic pendulum',
    paper: 'Paper 001, Fig. 4',
    text: 'l = m = k = 1, g = 0.2, t ≤ 4, Cartesian chart: Störmer–Verlet (order 2) against Rowlands’ processed method (order 4); energy errors against the reference.',
    variants: [
      { id: 'h0.1', label: 'h = 0.1', request: pendulum001(0.1) },
      { id: 'h0.05', label: 'h = 0.05', request: pendulum001(0.05) },
    ],
  },
  {
    id: 'p001-sec52',
    title: 'Free particle in polar coordinates',
    paper: 'Paper 001, Sec. 5.2',
    text: 'Symplectic Euler, h = 0.1, t ≤ 10: in the polar chart it keeps p_θ = −L but not p_x, p_y; in the Cartesian chart it keeps all three.',
    variants: [
      { id: 'polar', label: 'polar chart', request: particle001('polar') },
      { id: 'cartesian', label: 'Cartesian chart', request: particle001('cartesian') },
    ],
  },
  {
    id: 'p001-fig8',
    title: 'Compensating coordinate',
    paper: 'Paper 001, Fig. 8',
    text: 'Undamped oscillator ω = 1, q₀ = 1, p₀ = 0, 1000 steps of symplectic Euler at h = 0.3: the energy error in the eq. (82) coordinate (k = 2) against the plain one.',
    variants: [
      { id: 'compensating', label: 'compensating chart', request: oscillator001('compensating') },
      { id: 'cartesian', label: 'Cartesian chart', request: oscillator001('cartesian') },
    ],
  },
  {
    id: 'p001-fig23',
    title: 'Exact explicit Euler',
    paper: 'Paper 001, Figs. 2–3',
    text: 'Explicit Euler beside the reference: in the transformed variable (eqs. 15, 18) it is exact; in y it is not. y′ = −y (y₀ = 1, h = 0.3), Gompertz (y₀ = 3, a = 2, b = 0.5, h = 0.9).',
    variants: [
      { id: 'decay-transformed', label: 'decay, transformed', note: 'Fig. 2', request: ode001('exponential_decay', { alpha: 1 }, 1, 0.3, 6, 'transformed') },
      { id: 'decay-original', label: 'decay, original', request: ode001('exponential_decay', { alpha: 1 }, 1, 0.3, 6, 'original') },
      { id: 'gompertz-transformed', label: 'Gompertz, transformed', note: 'Fig. 3', request: ode001('gompertz', { a: 2, b: 0.5 }, 3, 0.9, 9, 'transformed') },
      { id: 'gompertz-original', label: 'Gompertz, original', request: ode001('gompertz', { a: 2, b: 0.5 }, 3, 0.9, 9, 'original') },
    ],
  },
];

/** The request of preset `groupId`/`variantId`, or undefined. */
export function presetRequest(groupId, variantId) {
  const group = PRESETS.find((g) => g.id === groupId);
  return group?.variants.find((v) => v.id === variantId)?.request;
}
