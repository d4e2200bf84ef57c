"""Chaos indicators: Hénon–Heiles at E = 1/8 has MEGNO ⟨Y⟩ → 2 on a torus and ⟨Y⟩ growing on a
chaotic orbit, a threshold stops a run with the reason ``indicator``, the Lyapunov spectrum of a
symplectic method comes in ± pairs, the stream gives the document's bits, and a sweep's chaos
maps land on its grid."""

from __future__ import annotations

import json
from typing import Any, Dict

import httpx
import numpy as np
import pytest

import geomint
from conftest import post_text
from test_simulate import assert_same_bits, literal_floats

ENERGY = 0.125
# x = 0, p_y = 0, p_x ≥ 0 solved so that H = 1/8; y = 0.1 starts on a torus, y = −0.25 in the
# chaotic sea (measured: at t = 4000 ⟨Y⟩ = 1.937 for the first; at t = 2000 ⟨Y⟩ ≈ 59 for the second).
REGULAR: Dict[str, Any] = {"q0": [0.0, 0.1], "p0": [0.0, 0.0], "energy": (ENERGY, "p_x"), "h": 0.05}
CHAOTIC: Dict[str, Any] = {**REGULAR, "q0": [0.0, -0.25]}


def test_megno_tends_to_two_on_a_torus_and_grows_on_a_chaotic_orbit(client: geomint.Client) -> None:
    regular = client.simulate("henon_heiles", "velocity_verlet", t_end=4000, every=1000,
                              indicators=["megno", "lyapunov"], **REGULAR)
    run = regular["velocity_verlet"]
    assert regular.system.p0[0] == pytest.approx(np.sqrt(2 * ENERGY - 0.1**2 + 2 * 0.1**3 / 3), rel=1e-15)
    assert regular.indicators == ("lyapunov", "megno") and regular.deviations == 4
    assert run.indicators == ("lyapunov", "megno")
    assert run.stop == geomint.Stop("finished")
    assert run.final is not None and run.final.megno_mean is not None
    # ⟨Y⟩ → 2 on a torus, from below (1.822 at t = 1000, 1.893 at 2000, 1.937 at 4000).
    assert abs(run.final.megno_mean - 2) < 0.1
    assert run.megno_mean is not None and run.megno is not None
    assert run.megno_mean[-1] == run.final.megno_mean and run.megno[-1] == run.final.megno
    assert run.megno_mean.shape == run.t.shape == (81,) and run.megno_mean[0] == 0
    # The finite-time spectrum: 2n = 4 exponents per sample, largest first, 0 at t = 0, in
    # ± pairs (the method is symplectic), the largest small and falling like log(t)/t.
    assert run.lyapunov is not None and run.lyapunov.shape == (81, 4)
    assert np.all(run.lyapunov[0] == 0)
    assert np.all(np.diff(run.lyapunov[1:], axis=1) <= 0)
    assert np.abs(run.lyapunov + run.lyapunov[:, ::-1]).max() < 1e-12
    assert run.final.lyapunov is not None and run.final.lyapunov.tobytes() == run.lyapunov[-1].tobytes()
    assert run.final.lyapunov_max == run.lyapunov[-1, 0] and 0 < run.lyapunov[-1, 0] < 0.01

    chaotic = client.simulate("henon_heiles", "velocity_verlet", t_end=2000, every=1000,
                              indicators="megno", **CHAOTIC)["velocity_verlet"]
    assert chaotic.final is not None and chaotic.final.megno_mean is not None
    assert chaotic.final.megno_mean > 20
    assert chaotic.lyapunov is None and chaotic.final.lyapunov is None and chaotic.fli is None


def test_a_megno_threshold_stops_a_chaotic_run(client: geomint.Client) -> None:
    sim = client.simulate("henon_heiles", "velocity_verlet", t_end=2000, every=1, indicators=["megno"],
                          stop_when={"megno_mean": 4}, **CHAOTIC)
    run = sim["velocity_verlet"]
    stop = run.stop
    assert stop is not None and stop.reason == "indicator"
    assert stop.indicator == "megno_mean" and stop.threshold == 4
    assert stop.value is not None and stop.value >= 4
    assert stop.step is not None and stop.t is not None and 0 < stop.t < 2000
    # The last sample is the step the threshold was seen at (measured: step 2320, t = 116).
    assert run.t[-1] == stop.t and run.samples == stop.step + 1
    assert run.megno_mean is not None and run.megno_mean[-1] == stop.value
    # The indicators are updated (and the thresholds checked) every qr_every = 10 steps: below
    # 4 at every such step before the last (between them, the samples may pass it).
    assert stop.step % 10 == 0 and np.all(run.megno_mean[: stop.step : 10] < 4)
    # Thresholds alone have no surface, so the simulation reports no stop_when surface.
    assert sim.stop_when is None and run.events is None
    # The regular orbit never gets there.
    regular = client.simulate("henon_heiles", "velocity_verlet", t_end=2000, every=1000, indicators=["megno"],
                              stop_when={"megno_mean": 4}, **REGULAR)
    assert regular["velocity_verlet"].stop == geomint.Stop("finished")


def test_indicators_stream_with_the_documents_bits(client: geomint.Client, raw: httpx.Client) -> None:
    options: Dict[str, Any] = dict(t_end=300, every=50, indicators=["lyapunov", "megno", "fli", "sali", "gali"],
                                   stop_when={"where": "y", "count": 1000, "fli": 1e6}, **CHAOTIC)
    document = client.simulate("henon_heiles", ["velocity_verlet", "modin_3s"], **options)
    header: Dict[str, Any] = {}

    def on_line(line: Any) -> None:
        if line["type"] == "header":
            header.update(line)

    streamed = client.stream("henon_heiles", ["velocity_verlet", "modin_3s"], progress=False, on_line=on_line,
                             **options)
    assert header["indicators"] == ["lyapunov", "megno", "fli", "sali", "gali"] and header["deviations"] == 4
    assert streamed.indicators == document.indicators == tuple(header["indicators"])
    assert streamed.deviations == document.deviations == 4
    for a, b in zip(document, streamed, strict=True):
        assert a.stop == b.stop and a.final == b.final
        for name in ("lyapunov", "megno", "megno_mean", "fli", "sali", "gali"):
            u, v = getattr(a, name), getattr(b, name)
            assert u is not None and v is not None and u.shape == v.shape and u.tobytes() == v.tobytes(), name
    # The client's arrays are the server's numbers.
    assert document.request is not None
    literal = literal_floats(post_text(raw, "/api/v1/simulate", document.request))
    for run, doc in zip(document, literal["runs"], strict=True):
        assert run.lyapunov is not None
        assert_same_bits(run.lyapunov, doc["lyapunov"])
        for name in ("megno", "megno_mean", "fli", "sali", "gali"):
            assert_same_bits(getattr(run, name), doc[name])
    # With k = 4 = 2n vectors, GALI_4 and SALI fall on this chaotic orbit.
    run = document["velocity_verlet"]
    assert run.gali is not None and run.sali is not None and run.gali[-1] < run.gali[1] and run.sali[-1] < 1
    frame = run.to_pandas()
    assert {"lyapunov0", "lyapunov3", "megno", "megno_mean", "fli", "sali", "gali"} <= set(frame.columns)
    ds = document.to_xarray()
    assert ds["lyapunov"].dims == ("run", "t", "exponent") and ds["lyapunov"].shape == (2, run.samples, 4)
    assert ds["megno_mean"].dims == ("run", "t")


def test_deviations_and_qr_every_reach_the_server(client: geomint.Client) -> None:
    sim = client.simulate("henon_heiles", "velocity_verlet", t_end=50, every=100, indicators=["lyapunov"],
                          deviations=2, qr_every=5, **REGULAR)
    run = sim["velocity_verlet"]
    assert sim.deviations == 2 and run.lyapunov is not None and run.lyapunov.shape == (run.samples, 2)
    assert sim.request is not None and sim.request["qr_every"] == 5 and sim.request["deviations"] == 2


def test_stop_when_and_indicators_are_checked_before_sending(client: geomint.Client) -> None:
    with pytest.raises(geomint.ValidationError) as caught:
        client.simulate("henon_heiles", "velocity_verlet", h=0.05, t_end=1, stop_when={})  # type: ignore[arg-type]
    assert caught.value.field == "stop_when"
    with pytest.raises(geomint.ValidationError) as caught:
        client.simulate("henon_heiles", "velocity_verlet", h=0.05, t_end=1, stop_when={"megno": 3, "count": 2})
    assert caught.value.field == "stop_when.where"
    with pytest.raises(geomint.ValidationError) as caught:
        client.simulate("henon_heiles", "velocity_verlet", h=0.05, t_end=1, stop_when={"megno": "3"})
    assert caught.value.field == "stop_when.megno"
    with pytest.raises(geomint.ValidationError) as caught:
        client.simulate("henon_heiles", "velocity_verlet", h=0.05, t_end=1,
                        indicators=["megno", "chaos"])  # type: ignore[list-item]
    assert caught.value.field == "indicators[1]"
    with pytest.raises(geomint.ValidationError) as caught:
        client.sweep("henon_heiles", "velocity_verlet", [("q0[1]", 0, 0.1, 2)], 1, h=0.05, indicators="megno",
                     stop_when={"where": "y"})  # type: ignore[dict-item]
    assert caught.value.field == "stop_when.where"
    # A threshold on an indicator not asked for: the server refuses it, naming the field.
    with pytest.raises(geomint.GeomintError) as refused:
        client.simulate("henon_heiles", "velocity_verlet", h=0.05, t_end=1, stop_when={"fli": 3},
                        indicators=["megno"])
    assert refused.value.status == 422 and refused.value.field is not None
    assert refused.value.field.startswith("stop_when")


SECTION: Dict[str, Any] = {
    "system": "henon_heiles", "methods": ["velocity_verlet"], "t_end": 500, "h": 0.05,
    "q0": [0.0, 0.0], "p0": [0.0, 0.0], "indicators": ["megno"],
    "axes": [{"name": "q0[1]", "min": -0.3, "max": 0.9, "n": 4}, {"name": "p0[1]", "min": -0.2, "max": 0.2, "n": 3}],
    "energy_surface": {"energy": ENERGY, "solve_for": "p0[0]"}, "stop_when": {"megno_mean": 6},
}


def test_a_chaos_map_sweep_gives_the_columns_on_its_grid(client: geomint.Client, raw: httpx.Client) -> None:
    sweep = client.sweep(**SECTION, progress=False)
    assert sweep.shape == (4, 3)
    run = sweep["velocity_verlet"]
    for name in ("lyapunov_max", "megno", "megno_mean", "fli", "sali", "gali", "stopped_at"):
        column = getattr(run, name)
        assert column is not None and column.shape == (4, 3), name
    # Only MEGNO was asked for: the others are NaN everywhere.
    for name in ("lyapunov_max", "fli", "sali", "gali"):
        assert np.all(np.isnan(getattr(run, name))), name
    assert run.megno_mean is not None and run.stopped_at is not None
    # y = 0.9 lies outside the energy surface (H > 1/8 whatever p_x): no run, an error, NaN.
    # y = −0.3, 0.1, 0.5, 0.9 by p_y = −0.2, 0, 0.2.
    outside = run.errors[3, :]
    assert all(e is not None and "energy_surface" in e for e in outside)
    assert all(e is None for e in run.errors[:3, :].ravel())
    assert np.all(np.isnan(run.megno_mean[3, :])) and np.all(run.steps[3, :] == 0)
    inside = run.megno_mean[:3, :]
    assert not np.isnan(inside).any()
    # A cell stopped by the threshold has ⟨Y⟩ ≥ 6 and fewer steps; the others ran all 10⁴ steps
    # with ⟨Y⟩ < 6. The grid has both (measured: 2 of the 9 cells on the surface stop).
    stopped = ~np.isnan(run.stopped_at[:3, :])
    assert stopped.any() and (~stopped).any()
    assert np.all(inside[stopped] >= 6) and np.all(inside[~stopped] < 6)
    assert np.all(run.steps[:3, :][stopped] < 10_000) and np.all(run.steps[:3, :][~stopped] == 10_000)
    assert np.all(run.stopped_at[:3, :][stopped] == 0.05 * run.steps[:3, :][stopped])
    # The server's numbers on the grid, cell i0 + n0·i1 at [i0, i1].
    response = raw.post("/api/v1/studies/sweep", json=sweep.request, headers={"accept": "application/x-ndjson"})
    result = next(line for line in map(literal_floats, response.text.splitlines()) if line["type"] == "result")
    assert_same_bits(run.megno_mean.ravel(order="F"), result["runs"][0]["megno_mean"])
    assert_same_bits(run.stopped_at.ravel(order="F"), result["runs"][0]["stopped_at"])
    ds = sweep.to_xarray()
    # The axes q0[1], p0[1] are Hénon–Heiles's y and p_y; the request's spelling stays a coordinate.
    assert ds["megno_mean"].dims == ("run", "y", "p_y") and ds["megno_mean"].shape == (1, 4, 3)
    assert ds["q0_1"].dims == ("y",) and ds["p0_1"].dims == ("p_y",)
    assert {"lyapunov_max", "megno", "fli", "sali", "gali", "stopped_at"} <= set(ds.data_vars)
    assert ds["megno_mean"].sel(run="velocity_verlet").values.tobytes() == run.megno_mean.tobytes()


def test_a_sweep_without_indicators_has_no_chaos_columns(client: geomint.Client) -> None:
    sweep = client.sweep("henon_heiles", "velocity_verlet", [("q0[1]", 0, 0.1, 2)], 1, h=0.05, progress=False)
    assert sweep["velocity_verlet"].megno is None and sweep["velocity_verlet"].stopped_at is None
    assert "megno" not in sweep.to_xarray().data_vars


def test_the_chaos_presets_run(client: geomint.Client) -> None:
    presets = client.sweep_presets()
    assert {"henon_heiles_megno", "elastic_pendulum_chaos"} <= set(presets)
    request = json.loads(json.dumps(presets["henon_heiles_megno"]["request"]))
    assert request["indicators"] == ["megno"] and request["energy_surface"]["solve_for"] == "p0[0]"
    # A coarse copy of the preset: the same section, fewer cells, a shorter time.
    request["axes"] = [dict(a, n=3) for a in request["axes"]]
    request["t_end"] = 50
    sweep = client.sweep(**request, progress=False)
    assert sweep.shape == (3, 3)
    assert sweep.runs[0].megno_mean is not None and sweep.runs[0].megno_mean.shape == (3, 3)
