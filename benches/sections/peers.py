"""The peers of `cargo bench --bench sections`: the Hénon–Heiles section y = 0, p_y > 0 at
E = 1/8 from (x, y, p_x) = (-0.2, 0, 0.1), p_y from E, with heyoka.py (Taylor's method, its
events located on the Taylor polynomials, at its default tolerance, double precision, and at
1e-14, the loosest whose energy stays within the bound) and pynamicalsys
(fixed-step symplectic Yoshida 4, crossings interpolated linearly between steps). Each prints a
JSON line: its points, the seconds, and the largest |y| and |H - E| over the points (the bounds
geomint's run is held to: 1e-13 and 1e-12). Usage: peers.py POINTS.
"""

import json
import math
import sys
import time

import numpy as np

E = 0.125
CHAOTIC = (-0.2, 0.0, 0.1)


def start(x, y, px):
    v = (x * x + y * y) / 2 + x * x * y - y ** 3 / 3
    return [x, y, px, math.sqrt(2 * (E - v) - px * px)]


def energy(x, y, px, py):
    return (px * px + py * py) / 2 + (x * x + y * y) / 2 + x * x * y - y ** 3 / 3


def bounds(points):
    """Largest |y| and |H - E| over rows (t, x, y, px, py)."""
    p = np.asarray(points)
    h = energy(p[:, 1], p[:, 2], p[:, 3], p[:, 4])
    return float(np.max(np.abs(p[:, 2]))), float(np.max(np.abs(h - E)))


def heyoka(n, tol):
    import heyoka as hy

    x, y, px, py = hy.make_vars("x", "y", "px", "py")
    rhs = [(x, px), (y, py), (px, -(x + 2 * x * y)), (py, -(y + x * x - y * y))]
    points = np.empty((n, 5))
    count = 0

    def crossed(ta, t, d_sgn):
        nonlocal count
        if count < n:
            ta.update_d_output(t)
            points[count, 0] = t
            points[count, 1:] = ta.d_output
            count += 1

    event = hy.nt_event(y, crossed, direction=hy.event_direction.positive)
    # Compiled once, outside the timing.
    ta = hy.taylor_adaptive(rhs, start(*CHAOTIC), nt_events=[event], tol=tol)
    began = time.perf_counter()
    while count < n:
        ta.propagate_for(1000.0)
    seconds = time.perf_counter() - began
    max_y, max_dh = bounds(points)
    return {"peer": f"heyoka.py {hy.__version__} (Taylor, tol {tol:.1e})", "points": n,
            "seconds": seconds, "max_y": max_y, "max_dh": max_dh}


def pynamicalsys(n, h):
    import pynamicalsys as pds
    from pynamicalsys import HamiltonianSystem

    ds = HamiltonianSystem(model="henon heiles")
    ds.integrator("svy4", time_step=h)
    s = start(*CHAOTIC)
    # Compiled by numba once, outside the timing.
    ds.poincare_section(np.array(s[:2]), np.array(s[2:]), 10, section_index=1, crossing=1)
    began = time.perf_counter()
    section = ds.poincare_section(np.array(s[:2]), np.array(s[2:]), n, section_index=1, crossing=1)
    seconds = time.perf_counter() - began
    max_y, max_dh = bounds(section)
    return {"peer": f"pynamicalsys {pds.__version__} (Yoshida 4, h = {h}, linear interpolation)",
            "points": n, "seconds": seconds, "max_y": max_y, "max_dh": max_dh}


#: pynamicalsys's points per run: its fixed steps take minutes per 10⁴ points; its time for the
#: whole count is this run's scaled by the count (the section's cost is linear in its points).
PYNAMICALSYS_POINTS = 2_000


def main():
    n = int(sys.argv[1]) if len(sys.argv) > 1 else 1_000_000
    # Its default tolerance (double precision), and the loosest that keeps |H - E| within the
    # bound (at 1e-13 it reaches 3.2e-12 over 10^5 points).
    for tol in (2.0 ** -52, 1e-14):
        print(json.dumps(heyoka(n, tol)), flush=True)
    for h in (0.01, 0.001):
        m = min(n, PYNAMICALSYS_POINTS if h >= 0.01 else PYNAMICALSYS_POINTS // 10)
        row = pynamicalsys(m, h)
        row["seconds"] *= n / m
        row["peer"] += f" ({m} points, time scaled to {n})"
        row["points"] = n
        print(json.dumps(row), flush=True)


if __name__ == "__main__":
    main()
