"""Jobs: a study submitted to run on the server in the background, in parts it stores as they
finish, so that neither a closed notebook nor a restart of the server loses it.

>>> job = client.submit(client.sweep, "henon_heiles", "rk4", axes, 1000, h=0.01)  # doctest: +SKIP
>>> sweep = job.wait()        # a progress bar; the same Sweep that client.sweep(...) returns

:meth:`JobCalls.submit` takes any study method of the client (``sweep``, ``basins``,
``energy_map``, ``convergence``, ``work_precision``) with its arguments, reads them exactly as
the method does (the same errors, naming the same arguments), and sends the request to the server
as a job; :meth:`Job.wait` follows the job's events (reconnecting from the last one seen when the
connection drops) and returns the method's own result type, built from the job's document.
"""

from __future__ import annotations

import json
import threading
import time
from typing import Any, Callable, Dict, Generic, Iterator, List, Optional, TypeVar, cast

import httpx

from ._progress import Progress
from ._transport import Transport
from ._wire import NDJSON, ROUTES, RRD, JobEvent, JobRequest, JobStatus, JobSubmission
from .errors import GeomintError, RefusedError, UnreachableError, ValidationError
from .recording import Recording

T = TypeVar("T")

# The client's study streams by the name of the job's study.
_STUDIES = {
    "sweep": "sweep",
    "basins": "basins",
    "energy_map": "energy-map",
    "convergence": "convergence",
    "work_precision": "work-precision",
}


class _Captured(Exception):
    """Raised in place of a study's stream while a study method is read for :meth:`submit`."""

    def __init__(self, name: str, body: Any) -> None:
        super().__init__(name)
        self.name = name
        self.body = body


class Job(Generic[T]):
    """A job on the server: its :meth:`status`, :meth:`wait` for its result, :meth:`cancel`.

    A job from :meth:`JobCalls.submit` gives the result type of the study method it was
    submitted with; one found again by id (:meth:`JobCalls.job`) gives the study's document as
    a dict."""

    def __init__(self, client: "JobCalls", status: JobStatus, build: Optional[Callable[[Any], T]] = None) -> None:
        self._client = client
        self._build = build
        self.id: str = status["id"]
        self.study: str = status["study"]
        self._status = status

    def __repr__(self) -> str:
        s = self._status
        return (
            f"<Job {self.id} {self.study}: {s['state']}, {s['parts_done']}/{s['parts']} parts, "
            f"{s['cells_done']}/{s['cells']} cells>"
        )

    def status(self) -> JobStatus:
        """The job's status now (state, cells and parts done, why it failed)."""
        self._status = cast(JobStatus, self._client._json("get_job", ids={"id": self.id}))
        return self._status

    @property
    def state(self) -> str:
        """``queued``, ``running``, ``done``, ``failed`` or ``cancelled``, as last read."""
        return self._status["state"]

    def cancel(self) -> JobStatus:
        """Cancels the job (a running one stops between steps, keeping its finished parts; one
        that has ended is left as it is)."""
        self._status = cast(JobStatus, self._client._json("cancel_job", ids={"id": self.id}))
        return self._status

    def remove(self) -> None:
        """Removes a job that has ended, with its result (else ``job_not_done``)."""
        self._client._send("remove_job", ids={"id": self.id})

    def events(self, after: int = 0, patience: float = 300.0) -> Iterator[JobEvent]:
        """The job's events after the one whose ``seq`` is ``after``, as they happen, to its
        last. A stream that drops or ends early (the server restarting) is resumed from the last
        event seen, for up to ``patience`` seconds without an answer."""
        seen = after
        waited = 0.0
        while True:
            try:
                for event in self._client._job_events(self.id, seen):
                    seen = int(event["seq"])
                    waited = 0.0
                    yield event
                    if event["event"] in ("done", "failed", "cancelled"):
                        return
            except (httpx.TransportError, UnreachableError):
                if waited >= patience:
                    raise
            time.sleep(1.0)
            waited += 1.0

    def wait(self, progress: bool = True) -> T:
        """Follows the job to its end with a progress bar over its cells and returns its result
        (the study method's result type). A failed job raises its error; a cancelled one raises
        :class:`~geomint.RefusedError` with code ``cancelled``."""
        with Progress(progress, "cells") as bar:
            for event in self.events():
                bar.total(int(event["cells"]))
                bar.to(int(event["cells_done"]))
                error = event.get("error")
                if event["event"] == "failed" and error is not None:
                    raise GeomintError.from_detail(error)
                if event["event"] == "cancelled":
                    raise RefusedError("cancelled", f"job {self.id} was cancelled")
        return self.result()

    def result(self) -> T:
        """The result of a job that is done (else :class:`~geomint.RefusedError`
        ``job_not_done``)."""
        document = self._client._json("job_result", ids={"id": self.id})
        self._status["state"] = "done"
        if self._build is None:
            return cast(T, document)
        return self._build({"type": "result", **document})

    def request(self) -> JobSubmission:
        """The job as it was submitted: ``{"study", "request", "priority"}``, the request being
        the body its study's route takes, as it was sent."""
        submitted: JobSubmission = self._client._json("job_request", ids={"id": self.id})
        return submitted

    def recording(self) -> Recording:
        """The Rerun recording of a done job's study (every study but a convergence study)."""
        response = self._client._send("job_result", ids={"id": self.id}, query={"format": "rrd"}, accept=RRD)
        return Recording(response.content)


class _Mode(threading.local):
    """What this thread's study calls do instead of streaming: raise their request
    (``capturing``, for :meth:`JobCalls.submit`) or return a job's result line (``answer``)."""

    capturing: bool = False
    answer: Optional[Any] = None


class JobCalls(Transport):
    """The client's job calls: submit a study method's request as a job, find jobs again.

    A study method is called twice: at :meth:`submit`, to read its arguments into the request,
    and when the job's result is read, to build its result type from the job's document. The
    arguments should be values (lists rather than generators, which the first call would use up).
    """

    def submit(self, study: Callable[..., T], *args: Any, priority: int = 0, **kwargs: Any) -> Job[T]:
        """Submits what ``study(*args, **kwargs)`` would run as a job and returns it at once.

        ``study`` is one of this client's study methods (``client.sweep``, ``client.basins``,
        ``client.energy_map``, ``client.convergence``, ``client.work_precision``), given its own
        arguments; ``priority`` (-1000 to 1000) orders this owner's jobs. The arguments are read
        as the method reads them, so a mistake raises here, naming the argument."""
        owner = getattr(study, "__self__", None)
        if owner is not self or getattr(study, "__name__", None) not in _STUDIES:
            raise ValidationError(
                "study",
                f"give one of this client's study methods ({', '.join('client.' + n for n in _STUDIES)})",
            )
        kwargs.setdefault("progress", False)
        mode = self._mode()
        mode.capturing = True
        try:
            study(*args, **kwargs)
            raise ValidationError("study", "the study method sent no request")
        except _Captured as captured:
            body = cast(JobRequest, {"study": _STUDIES[captured.name], "request": captured.body, "priority": priority})
        finally:
            mode.capturing = False
        status = cast(JobStatus, self._json("submit_job", body=body))

        def build(line: Any) -> T:
            mode = self._mode()
            mode.answer = line
            try:
                return study(*args, **kwargs)
            finally:
                mode.answer = None

        return Job(self, status, build)

    def job(self, id: str) -> Job[Dict[str, Any]]:
        """The job ``id`` (one of the caller's); its result is the study's document as a dict."""
        return Job(self, cast(JobStatus, self._json("get_job", ids={"id": id})))

    def jobs(self) -> List[JobStatus]:
        """The caller's jobs, oldest first."""
        return cast(List[JobStatus], self._json("list_jobs"))

    def _mode(self) -> _Mode:
        mode = self.__dict__.get("_job_mode")
        if mode is None:
            mode = self.__dict__.setdefault("_job_mode", _Mode())
        return cast(_Mode, mode)

    def _study(self, name: str, body: Any, progress: bool, label: str) -> Any:
        mode = self._mode()
        if mode.capturing:
            raise _Captured(name, body)
        if mode.answer is not None:
            return mode.answer
        return super()._study(name, body, progress, label)

    def _job_events(self, id: str, after: int) -> Iterator[JobEvent]:
        route = ROUTES["job_events"]
        request = self._request(route, accept=NDJSON, query={"after": str(after)}, ids={"id": id})
        try:
            response = self._http.send(request, stream=True)
        except (httpx.ConnectError, httpx.ConnectTimeout) as e:
            raise self._unreachable(e) from e
        try:
            if response.status_code >= 400:
                response.read()
                raise self._error(response)
            for text in response.iter_lines():
                if text.strip():
                    yield cast(JobEvent, json.loads(text))
        finally:
            response.close()
