"""Jobs: a study submitted to run in the background, its status, events and result."""

from __future__ import annotations

from typing import Any, Dict, Literal, Optional, TypedDict, Union

from .answers import ErrorDetail
from .basins import BasinsRequest
from .requests import ConvergenceRequest, EnergyMapRequest, SweepRequest, WorkPrecisionRequest

JobState = Literal["queued", "running", "done", "failed", "cancelled"]


class _Priority(TypedDict, total=False):
    priority: int


class SweepJob(_Priority):
    """A sweep (or chaos map) as a job."""

    study: Literal["sweep"]
    request: SweepRequest


class BasinsJob(_Priority):
    """A basin map as a job."""

    study: Literal["basins"]
    request: BasinsRequest


class EnergyMapJob(_Priority):
    """An energy-error map as a job."""

    study: Literal["energy-map"]
    request: EnergyMapRequest


class ConvergenceJob(_Priority):
    """A convergence study as a job."""

    study: Literal["convergence"]
    request: ConvergenceRequest


class WorkPrecisionJob(_Priority):
    """A work–precision study as a job."""

    study: Literal["work-precision"]
    request: WorkPrecisionRequest


# ``POST /api/v1/jobs``: a study's kind (named as its route), the body its route takes, and a
# priority among the owner's jobs (stability maps are not submitted by this client).
JobRequest = Union[SweepJob, BasinsJob, EnergyMapJob, ConvergenceJob, WorkPrecisionJob]


class _JobStatusRequired(TypedDict):
    id: str
    study: str
    owner: str
    priority: int
    state: JobState
    submitted: str
    cells: int
    cells_done: int
    parts: int
    parts_done: int


class JobStatus(_JobStatusRequired, total=False):
    """A job's status."""

    started: Optional[str]
    ended: Optional[str]
    error: Optional[ErrorDetail]
    recording: Optional[str]


EventKind = Literal["submitted", "started", "part", "stopped", "resumed", "done", "failed", "cancelled"]


class _JobEventRequired(TypedDict):
    seq: int
    event: EventKind
    at: str
    state: JobState
    parts_done: int
    parts: int
    cells_done: int
    cells: int


class JobEvent(_JobEventRequired, total=False):
    """A line of a job's event stream."""

    error: Optional[ErrorDetail]


class JobSubmission(TypedDict):
    """A job as it was submitted: its study, the request its route takes, its priority."""

    study: str
    request: Dict[str, Any]
    priority: int
