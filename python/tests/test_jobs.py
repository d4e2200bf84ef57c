"""Jobs from Python: a study method submitted as a job returns at once, and ``wait()`` gives the
same result type with the same numbers as the synchronous call; a job found again by id gives
the document; a mistake in the arguments raises at ``submit`` naming the argument; a cancelled
job raises on ``wait()``."""

from __future__ import annotations

from typing import Any, Dict

import numpy as np
import pytest

import geomint

SWEEP: Dict[str, Any] = {
    "system": "harmonic_oscillator",
    "methods": ["csv1", "rk4"],
    "t_end": 20,
    "h": 0.1,
    "axes": [("params.gamma", 0, 1, 3), ("q0[0]", 0.5, 2, 17)],
}


def test_a_submitted_sweep_waits_to_the_same_sweep(client: geomint.Client) -> None:
    job = client.submit(client.sweep, **SWEEP)
    assert isinstance(job, geomint.Job) and job.study == "sweep"
    assert job.state in ("queued", "running", "done")
    from_job = job.wait(progress=False)
    direct = client.sweep(**SWEEP, progress=False)
    assert type(from_job) is type(direct) and from_job.shape == direct.shape == (3, 17)
    for name in ("csv1", "rk4"):
        for metric in ("energy_error_final", "energy_error_max"):
            a, b = getattr(from_job[name], metric), getattr(direct[name], metric)
            assert np.array_equal(a, b, equal_nan=True), (name, metric)
    status = job.status()
    assert status["state"] == "done" and status["cells_done"] == status["cells"] == 51
    assert status["parts_done"] == status["parts"]
    assert job.id in [j["id"] for j in client.jobs()]
    submitted = client.job(job.id).request()
    assert submitted["study"] == "sweep" and submitted["priority"] == 0
    assert submitted["request"]["axes"][1]["n"] == 17
    again = client.job(job.id).result()
    assert again["axes"][1]["n"] == 17 and len(again["runs"]) == 2
    recording = job.recording()
    assert recording.data.startswith(b"RRF2")
    # The same recording in the recordings library, said to be the job's.
    kept = [r for r in client.recordings() if r.id == status["recording"]]
    assert len(kept) == 1 and kept[0].origin == "job" and kept[0].job == job.id
    assert client.download(kept[0].id).data == recording.data


def test_a_submitted_basin_map_waits_to_the_same_map(client: geomint.Client) -> None:
    presets = {k: dict(p["request"]) for k, p in client.basin_presets().items()}
    request = {**presets["double_well"], "axes": [dict(a, n=9) for a in presets["double_well"]["axes"]]}
    from_job = client.submit(client.basins, **request).wait(progress=False)
    direct = client.basins(**request, progress=False)
    assert len(from_job.runs) == len(direct.runs) == 1
    for a, b in zip(from_job.runs, direct.runs):
        assert np.array_equal(a.labels, b.labels)
        assert np.array_equal(a.decided_at, b.decided_at, equal_nan=True)
        assert [x.name for x in a.attractors] == [x.name for x in b.attractors]


def test_mistakes_raise_at_submit_naming_the_argument(client: geomint.Client) -> None:
    with pytest.raises(TypeError, match="tend"):
        client.submit(client.sweep, **SWEEP, tend=10)
    with pytest.raises(geomint.ValidationError) as caught:
        client.submit(client.sweep, **{**SWEEP, "t_end": -1})
    assert caught.value.field == "t_end"
    with pytest.raises(geomint.RefusedError) as refused:
        client.submit(client.sweep, **{**SWEEP, "axes": [("params.gamma", -1, 1, 3)]})
    assert (refused.value.code, refused.value.field) == ("invalid_value", "request.axes[0].min")
    with pytest.raises(geomint.ValidationError) as caught:
        client.submit(len, [1, 2])  # type: ignore[arg-type]
    assert caught.value.field == "study"


def test_a_cancelled_job_raises_on_wait(client: geomint.Client) -> None:
    long = {**SWEEP, "methods": ["rk4"], "h": 0.0005, "t_end": 5000, "every": 1000,
            "axes": [("q0[0]", 0.1, 3, 64)]}
    job = client.submit(client.sweep, **long)
    status = job.cancel()
    assert status["state"] in ("cancelled", "running", "queued")
    with pytest.raises(geomint.RefusedError) as caught:
        job.wait(progress=False)
    assert caught.value.code == "cancelled"
    assert job.status()["state"] == "cancelled"
    with pytest.raises(geomint.RefusedError) as not_done:
        job.result()
    assert not_done.value.code == "job_not_done"
    job.remove()
    with pytest.raises(geomint.RefusedError) as gone:
        job.status()
    assert gone.value.code == "not_found"
