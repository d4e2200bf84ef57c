"""Rerun recordings: saved, read back with Rerun's own reader (rerun-sdk 0.33), stored on the
server, uploaded, shown in a notebook viewer."""

from __future__ import annotations

from pathlib import Path
from typing import Any, Dict, List

import numpy as np
import pytest

import geomint

rr = pytest.importorskip("rerun")
from rerun.experimental import RrdReader  # noqa: E402


def energies(path: Path) -> Dict[str, np.ndarray]:
    """Each ``/{method}/energy`` series of a recording, in step order."""
    series: Dict[str, List[tuple]] = {}
    for chunk in RrdReader(str(path)).stream():
        entity = chunk.entity_path
        if chunk.is_static or not entity.endswith("/energy"):
            continue
        batch = chunk.to_record_batch()
        steps = batch.column("step").to_pylist()
        values = [v[0] for v in batch.column("Scalars:scalars").to_pylist()]
        series.setdefault(entity, []).extend(zip(steps, values, strict=True))
    return {k: np.array([v for _, v in sorted(pairs)]) for k, pairs in series.items()}


def test_rerun_sdk_is_the_servers_version() -> None:
    assert rr.__version__.startswith("0.33.")


def test_a_simulations_recording_holds_its_energies_bit_for_bit(client: geomint.Client, tmp_path: Path) -> None:
    sim = client.simulate("elastic_pendulum_3d", ["modin_3s", {"id": "modin_rks", "inner": "rk4"}],
                          h=0.01, t_end=10, every=4, params={"epsilon": 0.1})
    recording = client.recording(sim)
    assert recording.data[:4] == b"RRF2" and recording.id is None
    path = recording.save(tmp_path / "run.rrd")
    assert path.stat().st_size == len(recording)
    reader = RrdReader(str(path))
    assert [s.application_id for s in reader.recordings()] == ["geomint"]
    got = energies(path)
    assert set(got) == {"/modin_3s/energy", "/modin_rks_rk4/energy"}
    assert got["/modin_3s/energy"].tobytes() == sim["modin_3s"].energy.tobytes()
    assert got["/modin_rks_rk4/energy"].tobytes() == sim["modin_rks(rk4)"].energy.tobytes()


def test_stored_recordings_list_read_back_and_delete(client: geomint.Client) -> None:
    sim = client.simulate("pendulum", ["modin_3s", "heun"], h=0.1, t_end=50, every=5, compare_to_reference=True)
    stored = client.store(sim)
    assert stored.id is not None and stored.data[:4] == b"RRF2"
    info = next(r for r in client.recordings() if r.id == stored.id)
    assert info.bytes == len(stored) and info.system == "pendulum" and info.methods == ("modin_3s", "heun")
    assert info.origin == "simulation" and info.h == 0.1
    back = client.samples(stored.id)
    for run in sim:
        again = back[run.method]
        # Energies and errors are exact; q and p are kept in single precision.
        assert again.energy.tobytes() == run.energy.tobytes()
        assert again.energy_error is not None and run.energy_error is not None
        assert again.energy_error.tobytes() == run.energy_error.tobytes()
        assert np.array_equal(again.q, run.q.astype(np.float32).astype(np.float64))
        assert again.stats is not None and again.stats.steps == 500 and again.stop is None
    client.delete_recording(stored.id)
    with pytest.raises(geomint.GeomintError) as caught:
        client.download(stored.id)
    assert (caught.value.code, caught.value.status) == ("not_found", 404)


def test_upload_and_download_give_back_the_same_bytes(client: geomint.Client, tmp_path: Path) -> None:
    recording = client.recording(client.simulate("pendulum", "csv1", h=0.1, t_end=20))
    path = recording.save(tmp_path / "csv1.rrd")
    uploaded = client.upload(path)
    assert uploaded.id is not None and uploaded.data == recording.data
    assert client.download(uploaded.id).data == recording.data
    entry = next(r for r in client.recordings() if r.id == uploaded.id)
    assert entry.origin == "upload"
    with pytest.raises(geomint.ValidationError) as caught:
        client.upload(b"not a recording")
    assert caught.value.field == "body"
    with pytest.raises(geomint.GeomintError) as caught:
        client.upload(recording.data[: len(recording.data) // 2])
    assert (caught.value.code, caught.value.field) == ("invalid_recording", "body")
    client.delete_recording(uploaded.id)


def test_studies_record_too(client: geomint.Client, tmp_path: Path) -> None:
    results: List[Any] = [
        client.sweep("harmonic_oscillator", "csv1", [("params.gamma", 0, 1, 3), ("h", 0.5, 3, 4)], t_end=50,
                     every=10, progress=False),
        client.stability(["csv1", "cimp"], omega=3.51, gamma=(0, 3.5, 8), h=(0, 1, 6)),
        client.energy_map(nx=5, ny=5, t_max=100, progress=False),
        client.work_precision("harmonic_oscillator", [("csv1", [0.1, 0.05])], t_end=10, samples=10, progress=False),
    ]
    for result in results:
        recording = client.recording(result)
        path = recording.save(tmp_path / f"{type(result).__name__}.rrd")
        stores = RrdReader(str(path)).recordings()
        assert len(stores) == 1 and stores[0].application_id == "geomint", type(result).__name__
    with pytest.raises(ValueError):
        client.recording(client.samples(client.store(client.simulate("pendulum", "csv1", h=0.1, t_end=1)).id))


def test_show_sends_the_recording_to_the_notebook_viewer(
    client: geomint.Client, monkeypatch: pytest.MonkeyPatch
) -> None:
    notebook = pytest.importorskip("rerun_notebook")
    sent: List[bytes] = []
    original = notebook.Viewer.send_rrd

    def send_rrd(self: Any, data: bytes) -> None:
        sent.append(data)
        original(self, data)

    monkeypatch.setattr(notebook.Viewer, "send_rrd", send_rrd)
    recording = client.recording(client.simulate("pendulum", ["modin_3s", "heun"], h=0.1, t_end=20))
    shown = recording.show(width=640, height=360)
    assert isinstance(shown.viewer, notebook.Viewer)
    assert sent == [recording.data]
