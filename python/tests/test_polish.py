"""The answers' manners: every study has a table (``to_pandas``), a simulation's repr is a short
summary, ``Recording.show()`` displays the viewer once, and progress bars appear only where
someone watches (a notebook or a terminal)."""

from __future__ import annotations

import io
import sys
import types
from typing import Any, List

import numpy as np
import pytest

import geomint
from geomint import _progress


def test_a_sweep_is_a_table_one_row_per_run_and_cell(client: geomint.Client) -> None:
    sweep = client.sweep("pendulum", ["csv1", "rk4"], [("params.gamma", 0, 0.2, 3), ("h", 0.05, 0.1, 2)], 2,
                         progress=False)
    frame = sweep.to_pandas()
    assert len(frame) == 2 * 3 * 2
    assert list(frame.columns[:4]) == ["method", "chart", "gamma", "h"]
    for run in sweep:
        rows = frame[frame["method"] == run.method]
        for i, gamma in enumerate(sweep.axes[0].values):
            for j, h in enumerate(sweep.axes[1].values):
                row = rows[(rows["gamma"] == gamma) & (rows["h"] == h)]
                assert len(row) == 1
                assert row["steps"].item() == run.steps[i, j]
                assert np.array_equal(row["energy_error_max"].to_numpy(), [run.energy_error_max[i, j]],
                                      equal_nan=True)


def test_a_simulations_repr_is_a_short_summary(client: geomint.Client) -> None:
    sim = client.simulate("pendulum", ["modin_3s", "heun"], h=0.01, t_end=200)
    text = repr(sim)
    assert len(text.splitlines()) == 3, text
    assert "pendulum" in text and "h=0.01" in text and "1001 samples" in text and "heun" in text
    assert len(repr(sim["heun"])) < 200
    sweep = client.sweep("pendulum", "csv1", [("h", 0.05, 0.1, 2)], 1, progress=False)
    assert len(repr(sweep).splitlines()) == 1


class FakeViewer:
    """Stands for rerun_notebook.Viewer: counts what is sent to it."""

    def __init__(self, width: Any, height: Any) -> None:
        self.sent: List[bytes] = []

    def send_rrd(self, data: bytes) -> None:
        self.sent.append(data)


def test_show_displays_the_viewer_once(monkeypatch: pytest.MonkeyPatch) -> None:
    ipython_display = pytest.importorskip("IPython.display")
    formatters = pytest.importorskip("IPython.core.formatters")
    shown: List[Any] = []
    monkeypatch.setitem(sys.modules, "rerun_notebook", types.SimpleNamespace(Viewer=FakeViewer))
    monkeypatch.setattr(ipython_display, "display", lambda obj, **kw: shown.append(obj))
    recording = geomint.Recording(b"RRF2" + bytes(12))
    handle = recording.show()
    assert len(shown) == 1 and shown[0] is handle.viewer and handle.viewer.sent == [recording.data]
    assert handle.send_rrd == handle.viewer.send_rrd  # the viewer's own methods through the handle
    # The handle as a cell's last value: IPython's formatter hands it to its display method,
    # which shows nothing more.
    handle._ipython_display_()
    assert formatters.DisplayFormatter().format(handle) == ({}, {})
    assert len(shown) == 1 and "Rerun viewer" in repr(handle)


def test_progress_bars_only_where_someone_watches(monkeypatch: pytest.MonkeyPatch) -> None:
    pytest.importorskip("tqdm")

    class Terminal(io.StringIO):
        def isatty(self) -> bool:
            return True

    monkeypatch.setattr(sys, "stderr", io.StringIO())
    assert not _progress.interactive()
    with _progress.Progress(True, "cells") as bar:
        bar.total(10)
        bar.to(10)
    assert bar._bar is None and sys.stderr.getvalue() == ""
    monkeypatch.setattr(sys, "stderr", Terminal())
    assert _progress.interactive()
    with _progress.Progress(True, "cells") as bar:
        bar.total(10)
        bar.to(10)
    assert bar._bar is not None and "10/10" in sys.stderr.getvalue()
    with _progress.Progress(False, "cells") as bar:
        assert bar._bar is None


def test_the_maps_are_tables_too(client: geomint.Client) -> None:
    maps = client.stability(["csv1", "rk4"], omega=1, gamma=(0, 1, 4), h=(0.1, 2, 5))
    frame = maps.to_pandas()
    assert len(frame) == 2 * 5 * 4
    row = frame[(frame["method"] == "rk4") & (frame["h"] == maps.h[3]) & (frame["gamma"] == maps.gamma[2])]
    assert np.array_equal(row["spectral_radius"].to_numpy(), [maps["rk4"].spectral_radius[3, 2]], equal_nan=True)
    emap = client.energy_map(nx=3, ny=4, t_max=10, progress=False)
    cells = emap.to_pandas()
    assert len(cells) == 12 and cells["x"].iloc[4] == emap.x[1] and cells["y"].iloc[4] == emap.y[0]
    assert np.array_equal(cells["epsilon_polar"].to_numpy(), emap.epsilon_polar.ravel(), equal_nan=True)


def test_a_notebook_kernel_counts_as_watched(monkeypatch: pytest.MonkeyPatch) -> None:
    ipython = pytest.importorskip("IPython")
    monkeypatch.setattr(sys, "stderr", io.StringIO())
    monkeypatch.setattr(ipython, "get_ipython", lambda: types.SimpleNamespace(kernel=object()))
    assert _progress.in_notebook() and _progress.interactive()
    monkeypatch.setattr(ipython, "get_ipython", lambda: types.SimpleNamespace())  # IPython in a terminal
    assert not _progress.in_notebook() and not _progress.interactive()
