// Definitions to start from in the Your-system section (system.js): each is the body of
// POST /api/v1/systems with the run it is meant for (methods, step size, final time). They cover
// the three kinds of damping (conformal γ, Rayleigh ε·D(q), none), separable and general
// Hamiltonians, invariants the damped flow keeps, and bodies placed by `positions`.

/**
 * @typedef {{methods: (string|object)[], h: number, t_end: number}} ExampleRun
 * @typedef {{id: string, label: string, definition: object, run: ExampleRun}} Example
 * @type {Example[]}
 */
export const EXAMPLES = [
  {
    id: 'duffing',
    label: 'Damped Duffing oscillator (double well, conformal γ)',
    definition: {
      name: 'Damped Duffing oscillator',
      coordinates: ['x'],
      mass: 1,
      // α < 0 < β: two wells at x = ±√(−α/β); released above the barrier, the damped motion
      // crosses it a few times and settles into one well.
      potential: 'alpha*x^2/2 + beta*x^4/4',
      damping: { gamma: 'gamma' },
      parameters: { alpha: -1, beta: 1, gamma: 0.05 },
      q0: [1.5],
      p0: [0],
    },
    run: { methods: ['csv2', 'rk4'], h: 0.05, t_end: 100 },
  },
  {
    id: 'henon-heiles',
    label: 'Hénon–Heiles with Rayleigh damping',
    definition: {
      name: 'Hénon–Heiles with Rayleigh damping',
      coordinates: ['x', 'y'],
      mass: 1,
      potential: '(x^2 + y^2)/2 + x^2*y - y^3/3',
      // D = I: the friction −ε q̇ slows both directions alike.
      damping: { epsilon: 'eps', matrix: [[1, 0], [0, 1]] },
      parameters: { eps: 0.002 },
      // Energy 0.125, below the escape energy 1/6, in the chaotic band.
      q0: [0, 0.1],
      p0: [0.49, 0],
    },
    run: { methods: ['modin_3s', 'rk4'], h: 0.05, t_end: 500 },
  },
  {
    id: 'double-pendulum',
    label: 'Double pendulum (general H(q, p), no damping)',
    definition: {
      name: 'Double pendulum',
      // The angles of the two rods from the downward vertical; unit masses and lengths.
      coordinates: ['a', 'b'],
      momenta: ['p1', 'p2'],
      hamiltonian: '(p1^2 + 2*p2^2 - 2*p1*p2*cos(a-b)) / (2*(1 + sin(a-b)^2)) - 2*g*cos(a) - g*cos(b)',
      parameters: { g: 9.81 },
      // The bobs in the vertical plane, the second coordinate up.
      positions: [['sin(a)', '-cos(a)'], ['sin(a)+sin(b)', '-cos(a)-cos(b)']],
      q0: [1.8, 2.4],
      p0: [0, 0],
    },
    run: { methods: ['implicit_midpoint', 'rk4'], h: 0.005, t_end: 20 },
  },
  {
    id: 'kepler',
    label: 'Kepler problem with radial Rayleigh damping',
    definition: {
      name: 'Kepler problem with radial damping',
      coordinates: ['x', 'y'],
      mass: 1,
      potential: '-k/sqrt(x^2 + y^2)',
      // D(q) = r̂r̂ᵀ damps the radial velocity only: the force stays central, so the angular
      // momentum L is kept while the orbit circularizes (towards r = L²/k).
      damping: {
        epsilon: 'eps',
        matrix: [['x^2/(x^2 + y^2)', 'x*y/(x^2 + y^2)'], ['x*y/(x^2 + y^2)', 'y^2/(x^2 + y^2)']],
      },
      parameters: { k: 1, eps: 0.05 },
      invariants: { L: 'x*p_y - y*p_x' },
      q0: [1, 0],
      p0: [0, 1.2],
    },
    run: { methods: ['modin_3s', 'rk4'], h: 0.01, t_end: 100 },
  },
  {
    id: 'spring-chain',
    label: 'Chain of three masses and four springs, fixed ends',
    definition: {
      name: 'Spring chain with a damped middle mass',
      // Displacements of three masses from their rest positions 1, 2, 3 between walls at 0 and 4.
      coordinates: ['x1', 'x2', 'x3'],
      mass: 'm',
      potential: 'k/2*(x1^2 + (x2 - x1)^2 + (x3 - x2)^2 + x3^2)',
      // A dashpot on the middle mass only. The antisymmetric mode x1 = −x3, x2 = 0 does not move
      // it, so that mode's energy E_anti is kept while the rest decays.
      damping: { epsilon: 'c', matrix: [[0, 0, 0], [0, 1, 0], [0, 0, 0]] },
      parameters: { m: 1, k: 1, c: 0.2 },
      invariants: { E_anti: '(p_x1 - p_x3)^2/(4*m) + k*(x1 - x3)^2/2' },
      positions: [['1 + x1', '0'], ['2 + x2', '0'], ['3 + x3', '0']],
      q0: [0.3, 0, 0],
      p0: [0, 0, 0],
    },
    run: { methods: ['modin_3s', 'rk4'], h: 0.05, t_end: 200 },
  },
];
