"""Basin maps: the damped double well's two basins (equal, and swapped by (x, p) → (−x, −p)),
Hénon–Heiles's three exits, the forced Duffing oscillator's periodic orbits, the client's arrays,
table and metrics against the server's document, dimensions named after the state components,
progress, and refusals naming the field."""

from __future__ import annotations

import json
from typing import Any, Dict

import httpx
import numpy as np
import pytest
from scipy.integrate import solve_ivp

import geomint
from geomint import _progress
from conftest import post_text
from test_simulate import assert_same_bits


@pytest.fixture(scope="module")
def presets(client: geomint.Client) -> Dict[str, Dict[str, Any]]:
    return {k: dict(p["request"]) for k, p in client.basin_presets().items()}


def coarse(request: Dict[str, Any], n: int) -> Dict[str, Any]:
    """A preset's request on an n × n grid over the same ranges."""
    return {**request, "axes": [dict(a, n=n) for a in request["axes"]]}


def test_the_double_well_has_two_equal_basins_swapped_by_the_reflection(
    client: geomint.Client, presets: Dict[str, Dict[str, Any]]
) -> None:
    assert set(presets) == {"double_well", "forced_duffing", "forced_pendulum", "henon_heiles_escapes",
                            "henon_heiles_escapes_damped"}
    # 10 × 10 over [−2, 2]²: no cell starts on the saddle at the origin.
    basins = client.basins(**coarse(presets["double_well"], 10), progress=False)
    assert basins.shape == (10, 10) and basins.exits == () and basins.stop == "finished"
    run = basins["csv2"]
    assert [a.kind for a in run.attractors] == ["equilibrium", "equilibrium"]
    assert all("minimum" in a.name for a in run.attractors)
    wells = sorted(run.attractors, key=lambda a: a.equilibrium.q[0] if a.equilibrium else 0)
    left, right = (a.equilibrium for a in wells)
    assert left is not None and right is not None
    assert left.q[0] == pytest.approx(-1, abs=1e-12) and right.q[0] == pytest.approx(1, abs=1e-12)
    assert left.energy == right.energy == pytest.approx(-0.25, abs=1e-15)
    assert (left.hessian_eigenvalues > 0).all() and (right.hessian_eigenvalues > 0).all()
    # Equal basins: 50 cells each, every cell decided by the energy argument, before t_end.
    assert [a.cells for a in run.attractors] == [50, 50]
    assert run.fractions.tolist() == [0.5, 0.5] and [a.fraction for a in run.attractors] == [0.5, 0.5]
    assert run.undecided_fraction == 0 and run.undecided == ()
    assert run.decided_by == {"energy": 100, "exit": 0, "recurrence": 0, "proximity": 0, "divergence": 0, "t_end": 0, "undecided": 0}
    assert np.isin(run.labels, [a.label for a in run.attractors]).all()
    assert np.isfinite(run.decided_at).all() and 0 < run.decided_at.max() < basins.request["t_end"]
    # The equation is odd in (x, x′): the reflection of a cell is in the other basin, decided
    # at the same time.
    assert np.array_equal(run.labels, (wells[0].label + wells[1].label) - run.labels[::-1, ::-1])
    assert np.array_equal(run.decided_at, run.decided_at[::-1, ::-1])
    # A start next to x = 1 at rest settles there.
    x, p = (a.values for a in basins.axes)
    assert x is not None and p is not None
    near = (int(np.abs(x - 1).argmin()), int(np.abs(p).argmin()))
    assert run.labels[near] == wells[1].label
    # The search found both minima and the saddle between them, at V = 0.
    assert basins.equilibria is not None and len(basins.equilibria) == 3
    assert basins.lowest_saddle_energy == pytest.approx(0, abs=1e-15)
    assert run.largest_energy_margin is not None and 0 < run.largest_energy_margin < 1e-5


def test_dimensions_are_named_after_the_state_components(
    client: geomint.Client, presets: Dict[str, Dict[str, Any]]
) -> None:
    request = coarse(presets["double_well"], 10)
    basins = client.basins(**request, progress=False)
    assert [a.dim for a in basins.axes] == ["x", "p_x"]
    ds = basins.to_xarray()
    assert ds["labels"].dims == ("run", "x", "p_x") and ds["decided_at"].dims == ("run", "x", "p_x")
    assert ds["x"].attrs["axis"] == "q0[0]" and ds["p0_0"].values.tolist() == basins.axes[1].values.tolist()
    run = basins[0]
    labels = run.to_xarray()["labels"]
    assert labels.dims == ("x", "p_x") and np.array_equal(labels.values, run.labels)
    # Selecting by coordinate value finds the cell; the table names it.
    table = run.to_xarray()
    x1, p1 = float(basins.axes[0].values[7]), float(basins.axes[1].values[2])
    label = int(table["labels"].sel(x=x1, p_x=p1))
    assert label == run.labels[7, 2]
    assert table["attractor"].sel(label=label).item() == run.names[label] == run.attractor(label).name
    assert table["cells"].sel(label=-1).item() == 0 and table["fraction"].sum().item() == 1
    # The axes may be given by the components' names: the same request, the same map.
    named = client.basins(request["system"], request["methods"], [("x", -2, 2, 10), ("p_x", -2, 2, 10)],
                          request["t_end"], h=request["h"], progress=False)
    assert named.digest == basins.digest and np.array_equal(named[0].labels, run.labels)
    frame = basins.to_pandas()
    assert list(frame.columns) == ["method", "chart", "x", "p_x", "label", "attractor", "decided_at"]
    assert len(frame) == 100 and frame["label"].tolist() == run.labels.ravel(order="F").tolist()
    # Cell order: the first axis runs fastest.
    assert frame["x"].iloc[1] == basins.axes[0].values[1] and frame["p_x"].iloc[1] == basins.axes[1].values[0]


def test_arrays_table_and_metrics_equal_the_document(
    client: geomint.Client, raw: httpx.Client, presets: Dict[str, Dict[str, Any]]
) -> None:
    """Hénon–Heiles's escapes on a 15 × 15 grid: exits, undecided cells off the energy surface,
    no energy margin; every number the client read from the stream is the plain JSON answer's."""
    request = coarse(presets["henon_heiles_escapes"], 15)
    doc = json.loads(post_text(raw, "/api/v1/studies/basins", request))
    basins = client.basins(**request, progress=False)
    assert basins.digest == doc["digest"] and basins.exits == ("up", "left", "right") == tuple(doc["exits"])
    assert basins.cells == 225 and basins.unfinished_cells.size == 0
    (expected,) = doc["runs"]
    run = basins[0]
    assert (run.method, run.chart) == (expected["label"]["method"], expected["label"]["chart"])
    for cell, (label, at) in enumerate(zip(expected["labels"], expected["decided_at"], strict=True)):
        i, j = cell % 15, cell // 15
        assert run.labels[i, j] == label
        assert_same_bits(run.decided_at[i, j : j + 1], [at])
    assert_same_bits(run.fractions, expected["fractions"])
    assert [(a.label, a.kind, a.name, a.cells, a.fraction) for a in run.attractors] == \
        [(a["label"], a["kind"], a["name"], a["cells"], f) for a, f in zip(expected["attractors"], expected["fractions"])]
    assert sorted(a.name for a in run.attractors) == ["left", "right", "up"]
    assert all(a.kind == "exit" and a.equilibrium is None and a.points is None for a in run.attractors)
    # The metrics are the document's, None where it has null.
    assert run.metrics == {name: expected[name] for name in geomint.basins.METRICS}
    assert run.largest_energy_margin is None and run.basin_entropy is not None and run.basin_entropy > 0
    assert run.uncertain_fractions == {u["epsilon_cells"]: u["fraction"] for u in expected["uncertain_fractions"]}
    assert run.wada == {w["label"]: w["share"] for w in expected["wada"]}
    assert run.not_started == expected["not_started"]
    assert run.decided_by == expected["decided_by"] and run.steps == expected["steps"]
    # Cells that cannot be on H = 0.25 are undecided and say why, at their place on the grid.
    assert [(u.cell, u.reason) for u in run.undecided] == [(u["cell"], u["reason"]) for u in expected["undecided"]]
    assert run.undecided and all("energy_surface.energy" in u.reason for u in run.undecided)
    assert all(run.labels[u.index] == -1 and np.isnan(run.decided_at[u.index]) for u in run.undecided)
    assert run.decided_by["undecided"] == len(run.undecided) == int((run.labels == -1).sum())
    # The equilibria: the minimum at the origin and the three saddles at V = 1/6.
    assert basins.equilibria is not None and len(basins.equilibria) == len(doc["equilibria"]) == 4
    for point, raw_point in zip(basins.equilibria, doc["equilibria"], strict=True):
        assert point.q.tolist() == raw_point["q"] and point.energy == raw_point["energy"]
        assert point.hessian_eigenvalues.tolist() == raw_point["hessian_eigenvalues"]
    assert basins.lowest_saddle_energy == doc["lowest_saddle_energy"] == pytest.approx(1 / 6, rel=1e-14)
    ds = basins.to_xarray()
    assert ds["labels"].dims == ("run", "y", "p_y")
    assert ds["basin_entropy"].item() == run.basin_entropy and np.isnan(ds["largest_energy_margin"].item())
    assert ds["attractor"].values.tolist()[0] == "undecided" and ds["cells"].sel(label=-1).item() == len(run.undecided)


def test_the_forced_duffing_oscillator_locks_onto_a_periodic_orbit_in_each_well(
    client: geomint.Client, presets: Dict[str, Dict[str, Any]]
) -> None:
    basins = client.basins(**coarse(presets["forced_duffing"], 9), progress=False)
    run = basins[0]
    assert basins.equilibria is None and basins.lowest_saddle_energy is None
    assert [(a.kind, a.period) for a in run.attractors] == [("periodic", 1), ("periodic", 1)]
    # Two orbits of period 1, each with its own name.
    assert sorted(a.name for a in run.attractors) == ["period-1 orbit 1", "period-1 orbit 2"]
    assert run.attractor("period-1 orbit 2").label in (0, 1)
    points = [a.points for a in run.attractors]
    assert all(p is not None and p.shape == (1, 2) for p in points)
    assert sorted(np.sign(p[0, 0]) for p in points if p is not None) == [-1, 1]
    assert run.decided_by["recurrence"] == 81 and run.undecided_fraction == 0
    assert sum(a.cells for a in run.attractors) == 81


def test_the_forced_pendulum_turns_once_a_period_each_way_as_scipy_confirms(
    client: geomint.Client, presets: Dict[str, Dict[str, Any]]
) -> None:
    request = coarse(presets["forced_pendulum"], 12)
    assert request["recognition"]["angles"] == ["theta"]
    run = client.basins(**request, progress=False)[0]
    assert [(a.kind, a.period) for a in run.attractors] == [("periodic", 1), ("periodic", 1)]
    assert run.decided_by["recurrence"] == 144 and run.undecided_fraction == 0
    # Each orbit's stroboscopic point, integrated over one period by DOP853 at 1e-12, comes back
    # to itself on the circle (to csv1's first-order error at T/64) having turned once: the two
    # orbits turn opposite ways.
    params = request["system"]["parameters"]
    nu, force, period = params["nu"], params["F"], request["recognition"]["period"]

    def pendulum(t: float, y: np.ndarray) -> list:
        return [y[1], -nu * y[1] - np.sin(y[0]) + force * np.cos(t)]

    turns = []
    for attractor in run.attractors:
        assert attractor.points is not None and -np.pi < attractor.points[0, 0] <= np.pi
        start = attractor.points[0]
        end = solve_ivp(pendulum, (0, period), start, method="DOP853", rtol=1e-12, atol=1e-12).y[:, -1]
        turned = (end[0] - start[0]) / (2 * np.pi)
        turns.append(round(turned))
        assert abs(turned - round(turned)) < 2e-3 and abs(end[1] - start[1]) < 1e-2
    assert sorted(turns) == [-1, 1]


def test_given_attractors_name_the_labels_and_decide_by_proximity(
    client: geomint.Client, presets: Dict[str, Dict[str, Any]]
) -> None:
    request = coarse(presets["forced_pendulum"], 8)
    found = client.basins(**request, progress=False)[0]
    given = [(f"turn {a.label}", a.points, 0.05) for a in found.attractors]
    run = client.basins(**request, attractors=given, progress=False)[0]
    assert [(a.kind, a.name, a.radius) for a in run.attractors] == [("given", "turn 0", 0.05), ("given", "turn 1", 0.05)]
    assert np.array_equal(run.labels, found.labels)
    assert run.decided_by["proximity"] + run.decided_by["recurrence"] == 64 and run.decided_by["proximity"] > 32
    assert np.nanmean(run.decided_at) < np.nanmean(found.decided_at)
    with pytest.raises(geomint.ValidationError) as radius:
        client.basins(**request, attractors=[("turn", [[0, 0]], 0)], progress=False)
    assert radius.value.field == "attractors[0].radius"
    for points in ([[0, 0], [1]], [[0, float("nan")]]):
        with pytest.raises(geomint.ValidationError) as ragged:
            client.basins(**request, attractors=[("turn", points, 0.1)], progress=False)
        assert ragged.value.field == "attractors[0].points"
    with pytest.raises(geomint.RefusedError) as momentum:
        client.basins(**{**request, "recognition": {**request["recognition"], "angles": ["p_theta"]}}, progress=False)
    assert momentum.value.field == "recognition.angles[0]"


def test_two_methods_share_the_labels(client: geomint.Client, presets: Dict[str, Dict[str, Any]]) -> None:
    request = {**coarse(presets["henon_heiles_escapes"], 9), "methods": ["yoshida_6", "rk4"], "h": 0.05}
    basins = client.basins(**request, progress=False)
    first, second = basins["yoshida_6"], basins["rk4"]
    assert first.names == second.names
    # The same outcome has the same label in both runs: the cells agree nearly everywhere.
    assert (first.labels == second.labels).mean() > 0.9
    ds = basins.to_xarray()
    assert list(ds["run"].values) == [first.method, "rk4"] and first.method == "yoshida_6(modin_3s)" and ds["labels"].shape == (2, 9, 9)
    assert ds["cells"].sel(run="rk4").values.tolist() == \
        [int((second.labels == k).sum()) for k in ds["label"].values]


def test_progress_of_a_basin_map(
    client: geomint.Client, presets: Dict[str, Dict[str, Any]], capsys: pytest.CaptureFixture[str],
    monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setattr(_progress, "interactive", lambda: True)  # as on a terminal
    client.basins(**coarse(presets["double_well"], 8), progress=True)
    assert "64/64" in capsys.readouterr().err


def test_refusals_name_the_field(client: geomint.Client, presets: Dict[str, Dict[str, Any]]) -> None:
    request = coarse(presets["double_well"], 4)
    # An axis over a parameter: the server's refusal, by the request's name or the bare one.
    for axis in ("params.delta", "delta"):
        with pytest.raises(geomint.RefusedError) as caught:
            client.basins(**{**request, "axes": [(axis, 0, 1, 3)]}, progress=False)
        assert (caught.value.code, caught.value.field, caught.value.status) == ("invalid_value", "axes[0].name", 422)
    with pytest.raises(geomint.RefusedError) as caught:
        client.basins(**request, exits=[("out", "x - 3", "up"), ("back", "x +* 3")], progress=False)
    assert (caught.value.field, caught.value.position) == ("exits[1].where", 3)
    with pytest.raises(geomint.RefusedError) as caught:
        client.basins(**request, recognition={"period": 1.0}, progress=False)
    assert caught.value.field == "recognition.period"
    # The client's own checks, before anything is sent.
    with pytest.raises(geomint.ValidationError) as caught:
        client.basins(**request, exits=[{"name": "out", "where": "x - 3", "direction": "outwards"}], progress=False)
    assert caught.value.field == "exits[0].direction"
    with pytest.raises(geomint.ValidationError) as caught:
        client.basins(**request, exits=[{"where": "x - 3"}], progress=False)
    assert caught.value.field == "exits[0].name"
    with pytest.raises(geomint.ValidationError) as caught:
        client.basins(**{**request, "h": 0}, progress=False)
    assert caught.value.field == "h"
    with pytest.raises(geomint.ValidationError) as caught:
        client.basins(**{**request, "axes": [("x", -1, 1, 3)] * 3}, progress=False)
    assert caught.value.field == "axes"
    with pytest.raises(geomint.ValidationError) as caught:
        client.basins(**request, recognition={"max_period": 0}, progress=False)
    assert caught.value.field == "recognition.max_period"
    with pytest.raises(TypeError, match="did you mean 'exits'"):
        client.basins(**request, exit=[("out", "x - 3")], progress=False)


# The reference: scipy's DOP853 at rtol = atol = 1e-12, independent of geomint's integrators.
REFERENCE = dict(method="DOP853", rtol=1e-12, atol=1e-12)


def whole_neighbourhoods(labels: np.ndarray) -> list[tuple[int, int]]:
    """The decided cells whose eight neighbours all have their label."""
    n0, n1 = labels.shape
    return [
        (i, j)
        for i in range(1, n0 - 1)
        for j in range(1, n1 - 1)
        if labels[i, j] >= 0 and (labels[i - 1 : i + 2, j - 1 : j + 2] == labels[i, j]).all()
    ]


def box_entropies(labels: np.ndarray, box: int = 5) -> tuple[float, float]:
    """S_b and S_bb of a map whose cells all start an orbit (Daza et al., Sci. Rep. 6 (2016)
    31416): the mean Gibbs entropy of the whole box × box boxes, and of those on a boundary."""
    entropies = []
    for bj in range(labels.shape[1] // box):
        for bi in range(labels.shape[0] // box):
            block = labels[bi * box : (bi + 1) * box, bj * box : (bj + 1) * box]
            _, counts = np.unique(block, return_counts=True)
            p = counts / block.size
            entropies.append(float(-(p * np.log(p)).sum()))
    boundary = [s for s in entropies if s > 0]
    return sum(entropies) / len(entropies), sum(boundary) / len(boundary)


def test_labels_agree_with_scipys_dop853_and_the_entropies_with_their_formula(
    client: geomint.Client, presets: Dict[str, Dict[str, Any]]
) -> None:
    """Every cell whose whole neighbourhood shares its label gets the same outcome from scipy's
    DOP853 at 1e-12: the well the damped double well settles in (once H < 0, below the saddle,
    the energy cannot rise back), the exit a Hénon–Heiles orbit leaves through first."""
    # x″ + δx′ − x + x³ = 0, δ = 0.25: H = p²/2 − x²/2 + x⁴/4.
    request = coarse(presets["double_well"], 30)
    delta = request["system"]["parameters"]["delta"]
    run = client.basins(**request, progress=False)[0]
    (x_axis, p_axis) = (a.values for a in client.basins(**request, progress=False).axes)
    well_of = {a.label: np.sign(a.equilibrium.q[0]) for a in run.attractors if a.equilibrium is not None}

    def settled(t: float, z: np.ndarray) -> float:
        return z[1] ** 2 / 2 - z[0] ** 2 / 2 + z[0] ** 4 / 4 + 1e-3

    settled.terminal = True  # type: ignore[attr-defined]
    cells = whole_neighbourhoods(run.labels)
    agree = 0
    for i, j in cells:
        start = np.array([x_axis[i], p_axis[j]])
        if settled(0, start) < 0:
            # Below the saddle already: in the well it starts in.
            agree += int(np.sign(start[0]) == well_of[int(run.labels[i, j])])
            continue
        orbit = solve_ivp(
            lambda t, z: [z[1], z[0] - z[0] ** 3 - delta * z[1]],
            (0, request["t_end"]), start, events=settled, **REFERENCE,
        )
        assert orbit.t_events[0].size == 1, f"cell {i, j} did not settle by t_end"
        agree += int(np.sign(orbit.y_events[0][0][0]) == well_of[int(run.labels[i, j])])
    print(f"double well, 30 × 30: {agree} of {len(cells)} cells agree with DOP853")
    assert len(cells) >= 100 and agree / len(cells) >= 0.999, f"{agree} of {len(cells)}"
    # The entropies the document reports are the formula's on its labels.
    s_b, s_bb = box_entropies(np.asarray(run.labels))
    assert run.basin_entropy == pytest.approx(s_b, rel=1e-12)
    assert run.boundary_basin_entropy == pytest.approx(s_bb, rel=1e-12)

    # Hénon–Heiles at E = 0.25 on x = 0, p_x ≥ 0 solved from the energy: the first exit crossed
    # upwards, each surface as the preset writes it.
    request = coarse(presets["henon_heiles_escapes"], 24)
    basins = client.basins(**request, progress=False)
    run = basins[0]
    y_axis, py_axis = (a.values for a in basins.axes)
    exits = {a.label: a.name for a in run.attractors}
    s3 = np.sqrt(3) / 2
    surfaces = {
        "up": lambda t, z: z[1] - 2,
        "left": lambda t, z: -s3 * z[0] - z[1] / 2 - 2,
        "right": lambda t, z: s3 * z[0] - z[1] / 2 - 2,
    }
    for event in surfaces.values():
        event.terminal = True  # type: ignore[attr-defined]
        event.direction = 1  # type: ignore[attr-defined]

    def field(t: float, z: np.ndarray) -> list[float]:
        x, y, px, py = z
        return [px, py, -x - 2 * x * y, -y - x * x + y * y]

    cells = whole_neighbourhoods(run.labels)
    agree = 0
    for i, j in cells:
        y, py = y_axis[i], py_axis[j]
        px = np.sqrt(2 * (request["energy_surface"]["energy"] - (y * y / 2 - y**3 / 3)) - py * py)
        orbit = solve_ivp(field, (0, request["t_end"]), [0, y, px, py], events=list(surfaces.values()), **REFERENCE)
        crossed = [name for name, at in zip(surfaces, orbit.t_events) if at.size]
        agree += int(crossed == [exits[int(run.labels[i, j])]])
    print(f"Hénon–Heiles, 24 × 24: {agree} of {len(cells)} cells agree with DOP853")
    assert len(cells) >= 60 and agree / len(cells) >= 0.999, f"{agree} of {len(cells)}"
