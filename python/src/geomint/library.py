"""The client's calls on the server's recordings library: store a simulation as a recording,
upload a .rrd file, list, download, read back and delete stored recordings."""

from __future__ import annotations

import os
from pathlib import Path
from typing import List, Union

from ._transport import Transport
from ._wire import RRD, RecordingCreated
from .errors import ValidationError
from .recording import RRD_MAGIC, Recording, RecordingInfo
from .simulation import Simulation


class RecordingCalls(Transport):
    """The recordings library's calls of :class:`~geomint.Client`."""

    def store(self, of: Simulation) -> Recording:
        """Runs a simulation's request again as a stored recording on the server; returns the
        recording with its id (listed by :meth:`recordings`, read back by :meth:`samples`)."""
        if of.request is None:
            raise ValueError("this simulation carries no request (it was read back from a recording)")
        created: RecordingCreated = self._json("create_recording", body=of.request)
        return self.download(created["id"])

    def upload(self, recording: Union[Recording, bytes, str, "os.PathLike[str]"]) -> Recording:
        """Stores a .rrd file (a :class:`Recording`, bytes, or a path) on the server, which checks
        it first; returns it with its id."""
        if isinstance(recording, Recording):
            data = recording.data
        elif isinstance(recording, bytes):
            data = recording
        else:
            data = Path(recording).read_bytes()
        if not data.startswith(RRD_MAGIC):
            raise ValidationError("body", f"not a Rerun recording (.rrd): it starts with {data[:8]!r}",
                                  code="invalid_recording")
        created: RecordingCreated = self._json("upload_recording", content=data)
        return Recording(data, created["id"])

    def recordings(self) -> List[RecordingInfo]:
        """The stored recordings, newest first."""
        return [RecordingInfo.from_json(e) for e in self._json("list_recordings")]

    def download(self, id: str) -> Recording:
        """A stored recording's file."""
        response = self._send("get_recording", accept=RRD, ids={"id": f"{id}.rrd"})
        return Recording(response.content, id)

    def samples(self, id: str) -> Simulation:
        """A stored simulation recording's runs, read back from the file by the server: energies
        and invariants exact, ``q`` and ``p`` in single precision, no stop reasons or wall times."""
        return Simulation.from_recorded(self._json("recording_samples", ids={"id": id}))

    def delete_recording(self, id: str) -> None:
        """Deletes a stored recording."""
        self._send("delete_recording", ids={"id": id})
