"""Rerun recordings (.rrd) from the server: saved to a file or shown in a notebook."""

from __future__ import annotations

import os
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Optional, Tuple, Union

from . import _optional
from ._wire import RecordingEntry

# Every Rerun recording file starts with these four bytes.
RRD_MAGIC = b"RRF2"


@dataclass(frozen=True, eq=False)
class Recording:
    """A Rerun recording: the .rrd bytes the server wrote (Rerun 0.33), and the id under which
    the server stores it, if it does."""

    data: bytes = field(repr=False)
    id: Optional[str] = None

    def __len__(self) -> int:
        return len(self.data)

    def __repr__(self) -> str:
        stored = f", id={self.id!r}" if self.id else ""
        return f"Recording({len(self.data)} bytes{stored})"

    def save(self, path: Union[str, "os.PathLike[str]"]) -> Path:
        """Writes the recording to ``path`` (open it with ``rerun path``); returns the path."""
        target = Path(path)
        target.write_bytes(self.data)
        return target

    def show(self, width: Union[int, str] = "auto", height: Union[int, str] = "auto") -> "Shown":
        """Shows the recording in Rerun's viewer inside the notebook, once, and returns a
        :class:`Shown` handle on the viewer (``.viewer``), which displays nothing more when it is
        a cell's last value.

        Needs ``pip install 'geomint[rerun]'`` (rerun-sdk 0.33 with its notebook viewer); the
        recording is sent to the viewer from memory, so the notebook's browser need not reach
        the server.
        """
        notebook = _optional.require("rerun_notebook", "rerun", "Recording.show()")
        display = _optional.require("IPython.display", "rerun", "Recording.show()")
        viewer = notebook.Viewer(width=width, height=height)
        display.display(viewer)
        viewer.send_rrd(self.data)
        return Shown(viewer, len(self.data))


class Shown:
    """Rerun's notebook viewer that :meth:`Recording.show` displayed: ``viewer`` is the viewer
    itself (its other attributes are reached through this handle too). IPython's display of it
    is a no-op (:meth:`_ipython_display_`), so ``recording.show()`` as a cell's last line shows
    the viewer once, not a second time as the cell's value."""

    def __init__(self, viewer: Any, size: int) -> None:
        self.viewer = viewer
        self._size = size

    def __getattr__(self, name: str) -> Any:
        return getattr(self.viewer, name)

    def __repr__(self) -> str:
        return f"<Rerun viewer showing a recording of {self._size} bytes>"

    def _ipython_display_(self) -> None:
        """Nothing: the viewer was displayed where :meth:`Recording.show` was called."""


@dataclass(frozen=True)
class RecordingInfo:
    """A stored recording's entry: id, size, creation time, origin and, for a simulation, what it
    holds (system, methods, h, t_end); for a job's result (origin ``job``), the job's id."""

    id: str
    bytes: int
    created: str
    origin: Optional[str]
    application_id: Optional[str]
    system: Optional[str]
    methods: Tuple[str, ...]
    h: Optional[float]
    t_end: Optional[float]
    job: Optional[str] = None

    @classmethod
    def from_json(cls, doc: RecordingEntry) -> "RecordingInfo":
        spec, job = doc.get("spec"), doc.get("job")
        return cls(
            id=doc["id"],
            bytes=doc["bytes"],
            created=doc["created"],
            origin=doc.get("origin"),
            application_id=doc.get("application_id"),
            system=None if spec is None else spec["system"],
            methods=() if spec is None else tuple(spec["methods"]),
            h=None if spec is None else spec["h"],
            t_end=None if spec is None else spec["t_end"],
            job=None if job is None else job["id"],
        )
