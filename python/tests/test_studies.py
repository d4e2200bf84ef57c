"""Studies: grids rebuilt from the server's row-major cells, axes as coordinates, and what the
papers measure (csv1's stability bound, the Fig. 6 counts, orders of convergence)."""

from __future__ import annotations

import json
from typing import Any, Dict

import httpx
import numpy as np
import pytest

import geomint
from geomint import _progress
from conftest import post_text
from test_simulate import assert_same_bits, literal_floats

SWEEP: Dict[str, Any] = {
    "system": "harmonic_oscillator", "methods": ["csv1", "cimp"], "t_end": 200, "every": 100,
    "params": {"omega": 1},
    "axes": [{"name": "params.gamma", "min": 0, "max": 1, "n": 3}, {"name": "h", "min": 0.5, "max": 3, "n": 6}],
}


def sweep_result(raw: httpx.Client, body: Dict[str, Any], literal: bool = True) -> Any:
    """The sweep's document as its stream's result line (numbers as literals, unless not)."""
    response = raw.post("/api/v1/studies/sweep", json=body, headers={"accept": "application/x-ndjson"})
    assert response.status_code == 200
    parse = literal_floats if literal else json.loads
    lines = [parse(line) for line in response.text.splitlines() if line.strip()]
    return next(line for line in lines if line["type"] == "result")


def test_sweep_cells_land_on_their_axes(client: geomint.Client, raw: httpx.Client) -> None:
    literal = sweep_result(raw, SWEEP)
    sweep = client.sweep(**SWEEP, progress=False)
    assert sweep.shape == (3, 6)
    gamma, h = (a.values for a in sweep.axes)
    assert_same_bits(gamma, literal["axes"][0]["values"])
    assert_same_bits(h, literal["axes"][1]["values"])
    n0 = 3
    for run, doc in zip(sweep, literal["runs"], strict=True):
        for name in ("energy_error_final", "energy_error_max", "energy_error_l2", "diverged_at"):
            grid = getattr(run, name)
            for cell, text in enumerate(doc[name]):
                i, j = cell % n0, cell // n0
                assert_same_bits(grid[i, j : j + 1], [text])
        assert [int(s) for s in doc["steps"]] == [int(run.steps[c % n0, c // n0]) for c in range(18)]
    ds = sweep.to_xarray()
    assert ds["energy_error_max"].dims == ("run", "gamma", "h")
    assert ds["h"].attrs["axis"] == "h" and ds["gamma"].attrs["axis"] == "params.gamma"
    # Selecting by coordinate value finds the cell the server computed there.
    for cell in (0, 4, 11, 17):
        i, j = cell % n0, cell // n0
        value = ds["energy_error_l2"].sel(run="csv1", gamma=gamma[i], h=h[j]).item()
        expected = literal["runs"][0]["energy_error_l2"][cell]
        assert (np.isnan(value) and expected is None) or value == float(expected)


def test_csv1_diverges_exactly_where_h_omega_exceeds_two(client: geomint.Client) -> None:
    """Paper 003's corrected relation: csv1 is stable iff hω ≤ 2, whatever γ; cimp always."""
    sweep = client.sweep(**SWEEP, progress=False)
    h = sweep.axes[1].values
    csv1, cimp = sweep["csv1"], sweep["cimp"]
    diverged = ~np.isnan(csv1.diverged_at)
    assert np.array_equal(diverged, np.broadcast_to(h > 2, diverged.shape))
    assert np.isnan(cimp.diverged_at).all()
    # A diverged run reports no error figures.
    assert np.isnan(csv1.energy_error_max[diverged]).all()
    assert np.isfinite(csv1.energy_error_max[~diverged]).all()


def test_a_one_axis_sweep_with_invariants_and_charts(client: geomint.Client) -> None:
    sweep = client.sweep("elastic_pendulum_3d", ["implicit_midpoint", "heun"], ("params.epsilon", 0, 0.2, 5),
                         t_end=20, h=0.1, charts=["cartesian", "cylindrical"], progress=False)
    assert sweep.shape == (5,) and len(sweep.runs) == 4
    ds = sweep.to_xarray()
    assert list(ds["run"].values) == ["implicit_midpoint [cartesian]", "implicit_midpoint [cylindrical]",
                                      "heun [cartesian]", "heun [cylindrical]"]
    assert ds["final_q"].shape == (4, 5, 3) and ds["epsilon"].attrs["axis"] == "params.epsilon"
    drift = ds["invariant_drift"].sel(invariant="J3")
    # J₃ is quadratic, so the implicit midpoint rule keeps it for every ε; in the cylindrical
    # chart it is a momentum that no method moves at all (paper 001 Sec. 4).
    assert float(drift.sel(run="implicit_midpoint [cartesian]").max()) < 1e-13
    assert float(drift.sel(run="heun [cartesian]").min()) > 1e-3
    assert float(drift.sel(run="heun [cylindrical]").max()) == 0.0
    # Both charts start from the same physical state; the discretisations end apart.
    q_cart = sweep[("implicit_midpoint", "cartesian")].final_q
    q_cyl = sweep[("implicit_midpoint", "cylindrical")].final_q
    gap = np.abs(q_cart - q_cyl).max()
    assert 1e-6 < gap < 0.05


def test_a_preset_runs_as_given(client: geomint.Client) -> None:
    presets = client.sweep_presets()
    assert {"fig6_energy_map", "csv1_stability"} <= set(presets)
    request = dict(presets["csv1_stability"]["request"])
    request["axes"] = [dict(a, n=5) for a in request["axes"]]  # a coarser grid, same axes
    sweep = client.sweep(**request, progress=False)
    assert sweep.shape == (5, 5)
    # Divergence only where h·ω > 2 (ω = 1 by default).
    h = sweep.axes[1].values
    diverged = ~np.isnan(sweep["csv1"].diverged_at)
    assert np.array_equal(diverged.any(axis=0), h > 2)


def test_sweep_refusals_name_the_axis(client: geomint.Client) -> None:
    with pytest.raises(geomint.GeomintError) as caught:
        client.sweep("harmonic_oscillator", "csv1", [("params.gamma", -1, 2, 3)], t_end=20, h=0.1, progress=False)
    assert (caught.value.code, caught.value.field) == ("invalid_value", "axes[0].min")
    with pytest.raises(geomint.ValidationError) as caught:
        client.sweep("harmonic_oscillator", "csv1", [("params.gamma", 0, 2, 3)], t_end=20, progress=False)
    assert caught.value.field == "h"
    with pytest.raises(geomint.ValidationError) as caught:
        client.sweep("harmonic_oscillator", "csv1", [("h", 0.1, 2, 3)] * 3, t_end=20, progress=False)
    assert caught.value.field == "axes"


def test_stability_maps_on_the_servers_grid(client: geomint.Client, raw: httpx.Client) -> None:
    body = {"omega": 3.51, "gamma": {"min": 0, "max": 3.5, "n": 15}, "h": {"min": 0, "max": 1, "n": 11},
            "methods": ["cimp", "csv1", "rk4"]}
    literal = literal_floats(post_text(raw, "/api/v1/stability", body))
    maps = client.stability(["cimp", "csv1", "rk4"], omega=3.51, gamma=(0, 3.5, 15), h=(0, 1, 11))
    for m, doc in zip(maps, literal["maps"], strict=True):
        assert m.spectral_radius.shape == (11, 15)
        assert_same_bits(m.spectral_radius, doc["spectral_radius"])
        assert m.stable.tolist() == doc["stable"]
    # The grid's points are the server's: the point analysis there gives the map's numbers.
    for i, j in ((3, 7), (10, 14), (6, 1)):
        point = client.stability_point("csv1", omega=3.51, gamma=float(maps.gamma[j]), h=float(maps.h[i]))
        assert point.spectrum.spectral_radius == maps["csv1"].spectral_radius[i, j]
        assert point.gamma == maps.gamma[j] and point.h == maps.h[i]
    # cimp is stable on the whole grid; csv1 iff hω ≤ 2 (away from the boundary cell).
    assert maps["cimp"].stable.all()
    hw = maps.h[:, None] * 3.51 * np.ones((1, 15))
    assert maps["csv1"].stable[hw < 1.9].all() and not maps["csv1"].stable[hw > 2.1].any()
    assert maps["csv1"].analytic is not None and maps["rk4"].analytic is None
    ds = maps.to_xarray()
    assert ds["spectral_radius"].dims == ("run", "h", "gamma")
    assert bool(ds["has_analytic"].sel(run="csv1")) and not bool(ds["has_analytic"].sel(run="rk4"))
    assert ds["spectral_radius"].sel(run="rk4", h=maps.h[5], gamma=maps.gamma[2]).item() == \
        maps["rk4"].spectral_radius[5, 2]


def test_energy_map_fig6_coarse(client: geomint.Client, raw: httpx.Client) -> None:
    """Paper 001 Fig. 6 on a coarse 21 × 21 grid (g = 0.02, h = 0.2, t_max = 2000)."""
    body = {"nx": 21, "ny": 17, "t_max": 2000}
    response = raw.post("/api/v1/studies/energy-map", json=body)
    literal = literal_floats(response.text)
    emap = client.energy_map(nx=21, ny=17, t_max=2000, progress=False)
    assert emap.epsilon_cartesian.shape == (21, 17)
    for name in ("energy", "epsilon_cartesian", "epsilon_polar", "difference", "polar_diverged_at"):
        grid = getattr(emap, name)
        for cell in (0, 5, 20, 21, 200, 356):
            i, j = cell % 21, cell // 21
            assert_same_bits(grid[i, j : j + 1], [literal[name][cell]])
    # The counts the server reports are the arrays' own.
    summary = emap.summary
    assert summary["polar_diverged"] == int(np.isfinite(emap.polar_diverged_at).sum())
    assert summary["cartesian_diverged"] == int(np.isfinite(emap.cartesian_diverged_at).sum())
    assert summary["predicted_divergent"] == int(emap.predicted_divergent.sum())
    # Every predicted cell diverges in polar coordinates; Cartesian coordinates win most cells.
    assert np.isfinite(emap.polar_diverged_at[emap.predicted_divergent]).all()
    assert summary["cartesian_better"] > 4 * summary["polar_better"]
    # Released at rest, H₀ = V(x, y): the energy grid is the potential at the grid's points.
    x, y = np.meshgrid(emap.x, emap.y, indexing="ij")
    r = np.hypot(x, y)
    assert np.allclose(emap.energy, 0.5 * (r - 1) ** 2 - 0.02 * y, rtol=0, atol=1e-15)
    ds = emap.to_xarray()
    assert ds["epsilon_polar"].dims == ("x", "y")
    assert ds.attrs["polar_diverged"] == summary["polar_diverged"]


def test_convergence_orders_of_paper_001_fig_9(client: geomint.Client) -> None:
    """Symplectic Euler's largest energy error: order 1 in the original coordinate, 2 in the
    compensating chart of eq. (82)."""
    h = [0.04, 0.02, 0.01, 0.005, 0.0025, 0.00125]
    study = client.convergence("harmonic_oscillator", "symplectic_euler", h, 10, params={"omega": 1, "gamma": 0},
                               charts=["cartesian", "compensating"], q0=[1], p0=[0], progress=False)
    assert study.reference == "exact solution"
    cart, comp = study["symplectic_euler [cartesian]"], study["symplectic_euler [compensating]"]
    assert np.array_equal(cart.h, h) and list(cart.steps) == [250, 500, 1000, 2000, 4000, 8000]
    assert cart.max_energy.order == pytest.approx(1.0, abs=0.05)
    assert comp.max_energy.order == pytest.approx(2.0, abs=0.1)
    # The fitted order is the least-squares slope of the arrays the client holds.
    for series in (cart, comp):
        slope = np.polyfit(np.log10(series.h), np.log10(series.max_energy_error), 1)[0]
        assert series.max_energy.order == pytest.approx(slope, rel=1e-9)
    frame = study.to_pandas()
    assert len(frame) == 12 and set(frame["chart"]) == {"cartesian", "compensating"}
    ds = study.to_xarray()
    assert ds["max_energy_error"].sel(h=0.01).values.tolist() == [cart.max_energy_error[2], comp.max_energy_error[2]]


def test_work_precision_energy_error_falls_four_times_per_halving(client: geomint.Client) -> None:
    study = client.work_precision("harmonic_oscillator", [("csv1", [0.2, 0.1, 0.05]),
                                                          {"method": "reference", "tolerance": [1e-6, 1e-9]}],
                                  t_end=10, samples=10, progress=False)
    csv1, reference = study["csv1"], study["reference"]
    assert np.array_equal(csv1.h, [0.2, 0.1, 0.05]) and np.isnan(csv1.tolerance).all()
    assert np.array_equal(reference.tolerance, [1e-6, 1e-9]) and np.isnan(reference.h).all()
    ratios = csv1.max_energy_error[:-1] / csv1.max_energy_error[1:]
    assert np.all((ratios > 3.8) & (ratios < 4.2)), ratios
    assert list(csv1.steps) == [50, 100, 200]
    assert reference.max_energy_error[1] < reference.max_energy_error[0]
    frame = study.to_pandas()
    assert len(frame) == 5 and list(frame["method"]) == ["csv1"] * 3 + ["reference"] * 2
    with pytest.raises(geomint.GeomintError) as caught:
        client.work_precision("harmonic_oscillator", [("csv1", [0.2, 0.3])], t_end=10, samples=10, progress=False)
    assert caught.value.field == "runs[0].h[1]"


def test_study_results_match_the_plain_json_answer(client: geomint.Client, raw: httpx.Client) -> None:
    """The client reads a study from its stream's result line; the plain JSON answer is the same
    document (its wall time aside)."""
    plain = json.loads(post_text(raw, "/api/v1/studies/sweep", SWEEP))
    streamed = sweep_result(raw, SWEEP, literal=False)
    for key in ("axes", "runs", "digest", "cells", "steps", "unfinished_cells"):
        assert plain[key] == streamed[key], key


def test_progress_of_a_study(
    client: geomint.Client, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setattr(_progress, "interactive", lambda: True)  # as on a terminal
    client.energy_map(nx=9, ny=9, t_max=200, progress=True)
    err = capsys.readouterr().err
    assert "81/81" in err
