#!/usr/bin/env python3
"""The peers of `cargo bench --bench basins`: pynamicalsys 1.7 (PyPI) on a sample of the same
cells as geomint's maps, in the same run, timed and compared label by label.

- forced_duffing (x'' + 0.5x' - x + x^3 = 0.1 cos t on (x0, p0) in [-1.8, 1.8] x [-1, 1]):
  pynamicalsys's `basin_of_attraction` on its built-in Duffing model, rk4 at h = T/64 (geomint
  runs csv1 at the same step), on the stroboscopic map: TRANSIENT periods discarded, then SAMPLES
  points per cell clustered by DBSCAN (eps 0.05). Every cell runs all TRANSIENT + SAMPLES periods;
  geomint stops each cell once its stroboscopic points repeat.
- henon_heiles_escapes (E = 0.25, exits two units out along the three channels): pynamicalsys has
  no exits, so its Hénon–Heiles model is integrated with svy4 (Yoshida's fourth-order
  composition of velocity Verlet, the triple jump geomint runs) at h = 0.01 to t_end = 200, and
  the exit crossed first is read off each trajectory: geomint's rule without its early stop.

pynamicalsys runs its cells in parallel itself (numba), so one process uses both cores. Its first
call compiles and is timed apart; the time per cell is then extrapolated to the whole grid.

Usage: bench-basins-peers.py N   (after `GEOMINT_BASINS_GRID=N cargo bench --bench basins`, which
writes target/basins-<preset>-N.tsv); GEOMINT_PYNAMICALSYS_CELLS cells are sampled (4000: with
400, its timed part lasted half a second on the Duffing map, and its extrapolation to the grid
varied from 1266 s to 2207 s between runs).
"""

import collections
import math
import os
import sys
import time

import numpy as np

PERIOD = 2 * math.pi
TRANSIENT, SAMPLES = 50, 20
SQRT3_2 = math.sqrt(3) / 2


def ours(preset, n):
    """geomint's map: (x, y, label name, decision time) per cell, in cell order."""
    path = f"target/basins-{preset}-{n}.tsv"
    with open(path) as f:
        rows = [line.rstrip("\n").split("\t") for line in f]
    return [(float(x), float(y), name, float(t)) for x, y, name, t in rows]


def sample(rows, count, keep=lambda r: True):
    """`count` of the cells `keep` admits, drawn at random (the same each run), in cell order."""
    on = [r for r in rows if keep(r)]
    picked = np.random.default_rng(20261130).choice(len(on), size=min(count, len(on)), replace=False)
    return [on[i] for i in sorted(picked)], len(on)


def timed(f, *args):
    wall, cpu = time.perf_counter(), time.process_time()
    out = f(*args)
    return out, time.perf_counter() - wall, time.process_time() - cpu


def duffing(rows, n, count):
    from pynamicalsys import ContinuousDynamicalSystem

    ds = ContinuousDynamicalSystem(model="duffing")
    ds.integrator("rk4", time_step=PERIOD / 64)
    params = [0.5, 1.0, 1.0, 0.1, 1.0]  # delta, alpha, beta, gamma, omega
    picked, live = sample(rows, count)
    u = np.array([[x, p] for x, p, _, _ in picked])
    run = lambda cells: ds.basin_of_attraction(cells, SAMPLES, parameters=params, transient_time=TRANSIENT * PERIOD,
                                               map_type="SM", sampling_time=PERIOD, eps=0.05)
    _, compile_s, _ = timed(run, u[:2])
    labels, wall, cpu = timed(run, u)
    report("forced_duffing", f"rk4, h T/64, {TRANSIENT} + {SAMPLES} periods, DBSCAN", picked, live, n,
           compile_s, wall, cpu, [str(k) for k in labels])


def exit_of(trajectory):
    """The exit a Hénon–Heiles trajectory (t, x, y, px, py rows) crosses first, upwards."""
    x, y = trajectory[:, 1], trajectory[:, 2]
    surfaces = {"up": y - 2, "left": -SQRT3_2 * x - y / 2 - 2, "right": SQRT3_2 * x - y / 2 - 2}
    first, name = math.inf, "stayed"
    for exit, s in surfaces.items():
        with np.errstate(invalid="ignore"):
            crossed = np.nonzero((s[:-1] < 0) & (s[1:] >= 0))[0]
        if crossed.size and crossed[0] < first:
            first, name = crossed[0], exit
    return name


def henon_heiles(rows, n, count):
    from pynamicalsys import HamiltonianSystem

    ds = HamiltonianSystem(model="henon heiles")
    ds.integrator("svy4", time_step=0.01)
    picked, live = sample(rows, count, lambda r: r[2] != "undecided")

    def run(cells):
        names = []
        for start in range(0, len(cells), 50):  # 50 trajectories of 20 001 states at a time
            chunk = cells[start:start + 50]
            y, py = np.array([c[0] for c in chunk]), np.array([c[1] for c in chunk])
            # x = 0 and p_x from H = E = 0.25, as geomint's energy surface solves it.
            px = np.sqrt(2 * 0.25 - py**2 - (y**2 - 2 * y**3 / 3))
            q, p = np.column_stack([np.zeros_like(y), y]), np.column_stack([px, py])
            with np.errstate(over="ignore", invalid="ignore"):
                trajectories = ds.trajectory(q, p, 200.0)
            names += [exit_of(t) for t in trajectories]
        return names

    _, compile_s, _ = timed(run, picked[:2])
    names, wall, cpu = timed(run, picked)
    report("henon_heiles_escapes", "svy4, h 0.01, to t_end 200, first exit read off", picked, live, n,
           compile_s, wall, cpu, names)


def report(preset, how, picked, live, n, compile_s, wall, cpu, theirs):
    """Time per cell, the grid extrapolated, and agreement: each of pynamicalsys's labels stands
    for the geomint label most of its cells have."""
    per_cell = wall / len(picked)
    votes = collections.defaultdict(collections.Counter)
    for row, label in zip(picked, theirs):
        votes[label][row[2]] += 1
    same = sum(c.most_common(1)[0][1] for c in votes.values())
    print(f"pynamicalsys {preset} ({how}): {len(picked)} of the {live} cells, {compile_s:.1f} s compiling, then "
          f"{wall:.2f} s wall ({cpu:.2f} s CPU): {per_cell * 1e6:.0f} µs per cell; the {n} x {n} grid would take "
          f"about {per_cell * live:.0f} s")
    print(f"  labels: the same outcome as geomint's in {same} of {len(picked)} sampled cells "
          f"({dict((k, dict(v)) for k, v in votes.items())})")


def main():
    n = int(sys.argv[1]) if len(sys.argv) > 1 else 1000
    count = int(os.environ.get("GEOMINT_PYNAMICALSYS_CELLS", "4000"))
    duffing(ours("forced_duffing", n), n, count)
    henon_heiles(ours("henon_heiles_escapes", n), n, count)


if __name__ == "__main__":
    main()
