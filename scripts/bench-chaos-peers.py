"""The peers' side of `cargo bench --bench chaos`: the Hénon–Heiles map of the (y, p_y) section at
x = 0, p_x >= 0 from H = 1/8, T = 1000, on the same n x n grid, timed on all cores (two worker
processes), and compared cell by cell with geomint's map (target/chaos-map-<n>.tsv).

- heyoka: the adaptive Taylor integrator in batch mode (the recommended SIMD width), the equations
  of motion, their variational equations for one deviation vector (1, 1, 0, 0)/sqrt(2) and the
  MEGNO integrals A' = t (w.w')/(w.w), B' = 2A/t, so <Y> = B/T (started at t0 = 1e-6 with
  A = B = 0). The tolerance is an argument (default 1e-6, at which heyoka's <Y> is as close to a
  tolerance-1e-15 run as geomint's: see GEOMINT_CHAOS_ACCURACY below).
- pynamicalsys: it has no MEGNO; its largest Lyapunov exponent with the same fourth-order
  symplectic composition (Yoshida's, the triple jump of velocity Verlet), the same h = 0.05 and T,
  one deviation vector and QR every 10 steps, is the nearest computation with the same work per
  step (lambda_max t/2 is the chaotic <Y>).

Usage: bench-chaos-peers.py N [TOL] [PEERS]   (PEERS: heyoka,pynamicalsys by default; pynamicalsys
takes about 0.6 s per cell, so it runs on GEOMINT_PYNAMICALSYS_CELLS cells of the grid, 200 by
default, and its time for the whole grid is extrapolated). GEOMINT_CHAOS_ACCURACY=1 also measures
geomint's and heyoka's <Y> against heyoka's at tolerance 1e-15, to set heyoka's tolerance for the
same accuracy.
"""

import math
import multiprocessing as mp
import os
import sys
import time

import numpy as np

E, T, H = 0.125, 1000.0, 0.05


def grid(n):
    ys = [-0.45 + 1.1 * k / (n - 1) for k in range(n)]
    pys = [-0.5 + 1.0 * k / (n - 1) for k in range(n)]
    cells = []
    for j, py in enumerate(pys):
        for i, y in enumerate(ys):
            k2 = 2 * E - py * py - y * y + 2 * y ** 3 / 3
            cells.append((y, py, math.sqrt(k2) if k2 >= 0 else None))
    return cells


def heyoka_rows(args):
    cells, tol = args
    import heyoka as hy
    x, y, px, py, dx, dy, dpx, dpy, a, b = hy.make_vars("x", "y", "px", "py", "dx", "dy", "dpx", "dpy", "a", "b")
    t = hy.time
    fdx, fdy = dpx, dpy
    fdpx = -(1.0 + 2.0 * y) * dx - 2.0 * x * dy
    fdpy = -2.0 * x * dx - (1.0 - 2.0 * y) * dy
    r = (dx * fdx + dy * fdy + dpx * fdpx + dpy * fdpy) / (dx * dx + dy * dy + dpx * dpx + dpy * dpy)
    system = [(x, px), (y, py), (px, -x - 2.0 * x * y), (py, -y - x * x + y * y),
              (dx, fdx), (dy, fdy), (dpx, fdpx), (dpy, fdpy), (a, t * r), (b, 2.0 * a / t)]
    bs = hy.recommended_simd_size()
    ta = hy.taylor_adaptive_batch(system, np.zeros((10, bs)), time=np.full(bs, 1e-6), tol=tol)
    out = []
    live = [c for c in cells if c[2] is not None]
    w = 1.0 / math.sqrt(2.0)
    for start in range(0, len(live), bs):
        group = live[start:start + bs]
        state = np.zeros((10, bs))
        for k in range(bs):
            yv, pyv, pxv = group[min(k, len(group) - 1)]
            state[:, k] = [0.0, yv, pxv, pyv, w, w, 0.0, 0.0, 0.0, 0.0]
        ta.state[:] = state
        ta.set_time(np.full(bs, 1e-6))
        ta.propagate_until(T)
        for k in range(len(group)):
            out.append((group[k][0], group[k][1], ta.state[9, k] / T))
    return out


def pynamicalsys_rows(cells):
    """Its largest Lyapunov exponent on `cells` (those on the surface), after a first call that
    compiles its code; the rows, the compile time and the time of the rest."""
    from pynamicalsys import HamiltonianSystem
    ds = HamiltonianSystem(model="henon heiles")
    ds.integrator("svy4", time_step=H)
    live = [c for c in cells if c[2] is not None]
    out = []
    began = time.perf_counter()
    for k, (yv, pyv, pxv) in enumerate(live):
        if k == 1:
            compiled = time.perf_counter()
        lam = ds.lyapunov([0.0, yv], [pxv, pyv], T, num_exponents=1, qr_interval=10)
        out.append((yv, pyv, float(lam)))
    ended = time.perf_counter()
    if len(live) < 2:
        compiled = ended
    return [(out, compiled - began, ended - compiled, max(len(live) - 1, 0))]


def timed(f, chunks):
    start = time.perf_counter()
    with mp.get_context("fork").Pool(2) as pool:
        rows = [r for part in pool.map(f, chunks) for r in part]
    return rows, time.perf_counter() - start


def main():
    n = int(sys.argv[1]) if len(sys.argv) > 1 else 101
    tol = float(sys.argv[2]) if len(sys.argv) > 2 else 1e-6
    peers = (sys.argv[3] if len(sys.argv) > 3 else "heyoka,pynamicalsys").split(",")
    cells = grid(n)
    halves = [cells[: len(cells) // 2], cells[len(cells) // 2:]]
    ours = {}
    try:
        with open(f"target/chaos-map-{n}.tsv") as f:
            for line in f:
                yv, pyv, m = line.split("\t")
                ours[(round(float(yv), 12), round(float(pyv), 12))] = float(m)
    except FileNotFoundError:
        print(f"no target/chaos-map-{n}.tsv: run GEOMINT_CHAOS_GRID={n} cargo bench --bench chaos first")
    live = sum(1 for c in cells if c[2] is not None)

    if "heyoka" in peers:
        rows, wall = timed(heyoka_rows, [(h, tol) for h in halves])
        print(f"heyoka (Taylor, batch, tol {tol:g}): {n} x {n}, {live} cells on the surface, {wall:.2f} s wall")
        compare("heyoka <Y>", rows, ours, lambda v: v > 4.0)
        if os.environ.get("GEOMINT_CHAOS_ACCURACY"):
            accuracy(halves, ours, rows)

    if "pynamicalsys" in peers:
        # About 0.6 s per cell: a sample of the grid's cells on the surface, spread evenly, timed
        # after each worker's first call (which compiles), and the time per cell extrapolated.
        sample = int(os.environ.get("GEOMINT_PYNAMICALSYS_CELLS", "200"))
        on = [c for c in cells if c[2] is not None]
        picked = on[:: max(1, len(on) // max(sample, 1))][:sample]
        parts, wall = timed(pynamicalsys_rows, [picked[0::2], picked[1::2]])
        rows = [r for part in parts for r in part[0]]
        compile_s = max(part[1] for part in parts)
        per_cell = sum(part[2] for part in parts) / max(sum(part[3] for part in parts), 1)
        print(f"pynamicalsys (svy4, h {H}, lambda_max): {len(picked)} of the {live} cells, "
              f"{wall:.2f} s wall: {compile_s:.1f} s compiling, then {per_cell:.3f} s per cell; "
              f"the {n} x {n} grid would take about {compile_s + per_cell * live / 2:.0f} s on two workers")
        compare("pynamicalsys lambda_max", rows, ours, lambda v: v > 8.0 / T)


def accuracy(halves, ours, rows):
    """Each map's <Y> against heyoka's at tolerance 1e-15 on the regular cells (<Y> < 4 there):
    the median and the 90th percentile of |<Y> - <Y>_ref|, so that heyoka's tolerance can be set
    for geomint's accuracy."""
    key = lambda yv, pyv: (round(yv, 12), round(pyv, 12))
    ref, wall = timed(heyoka_rows, [(h, 1e-15) for h in halves])
    ref = {key(yv, pyv): v for yv, pyv, v in ref}
    theirs = {key(yv, pyv): v for yv, pyv, v in rows}
    regular = [k for k, v in ref.items() if v < 4.0 and math.isfinite(ours.get(k, math.nan))]
    for label, m in (("geomint", ours), ("heyoka", theirs)):
        errors = [abs(m[k] - ref[k]) for k in regular]
        print(f"  {label} <Y> against heyoka at tol 1e-15 ({wall:.1f} s) on {len(regular)} regular cells: "
              f"median {np.median(errors):.2e}, 90th percentile {np.percentile(errors, 90):.2e}")


def compare(label, rows, ours, chaotic):
    """How often the peer's verdict (chaotic: value past its threshold) matches geomint's <Y> > 4,
    and for <Y> the median difference on the regular cells."""
    if not ours:
        return
    same, diffs, total = 0, [], 0
    for yv, pyv, v in rows:
        m = ours.get((round(yv, 12), round(pyv, 12)))
        if m is None or math.isnan(m) or not math.isfinite(v):
            continue
        total += 1
        same += (m > 4.0) == chaotic(v)
        if label.endswith("<Y>") and m < 4.0 and v < 4.0:
            diffs.append(abs(m - v))
    median = f", median |d<Y>| on regular cells {np.median(diffs):.2e}" if diffs else ""
    print(f"  {label}: same verdict as geomint's <Y> > 4 in {same} of {total} cells{median}")


if __name__ == "__main__":
    main()
