"""Every route the client calls (:data:`ROUTES`), with the types it sends and reads."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Dict, List, Literal, Optional

from .requests import (
    ConvergenceRequest,
    EnergyMapRequest,
    PointRequest,
    SimulateRequest,
    StabilityRequest,
    SweepRequest,
    SystemDefinition,
    WorkPrecisionRequest,
)
from .answers import (
    Health,
    MethodEntry,
    RecordedDocument,
    RecordingCreated,
    RecordingEntry,
    SimulationDocument,
    StoredSystem,
    StreamLine,
    SystemEntry,
)
from .studies import (
    ConvergenceLine,
    MapLine,
    PointDocument,
    Preset,
    StabilityDocument,
    StudyLine,
    SweepLine,
)
from .basins import BasinsLine, BasinsRequest
from .jobs import JobEvent, JobRequest, JobStatus, JobSubmission


JSON = "application/json"
NDJSON = "application/x-ndjson"
RRD = "application/octet-stream"


@dataclass(frozen=True)
class Route:
    """One operation the client performs.

    ``answers`` maps each media type the client asks for to the type it reads (``bytes`` for a
    recording); ``query`` lists the query values it sends; ``request`` is the body's type.
    """

    method: Literal["GET", "POST", "DELETE"]
    path: str
    answers: Dict[str, object] = field(default_factory=dict)
    request: Optional[object] = None
    request_media: str = JSON
    query: Dict[str, List[str]] = field(default_factory=dict)
    status: int = 200

    def url(self, **params: str) -> str:
        """The path with its ``{name}`` segments filled in (the values quoted by the caller)."""
        return self.path.format(**params)


ROUTES: Dict[str, Route] = {
    "health": Route("GET", "/healthz", {JSON: Health}),
    "list_systems": Route("GET", "/api/v1/systems", {JSON: List[SystemEntry]}),
    "get_system": Route("GET", "/api/v1/systems/{id}", {JSON: SystemEntry}),
    "create_system": Route("POST", "/api/v1/systems", {JSON: StoredSystem}, SystemDefinition),
    "delete_system": Route("DELETE", "/api/v1/systems/{id}", status=204),
    "list_methods": Route("GET", "/api/v1/methods", {JSON: List[MethodEntry]}),
    "simulate": Route(
        "POST",
        "/api/v1/simulate",
        {JSON: SimulationDocument, NDJSON: StreamLine, RRD: bytes},
        SimulateRequest,
        query={"format": ["rrd"]},
    ),
    "create_recording": Route(
        "POST", "/api/v1/recordings", {JSON: RecordingCreated}, SimulateRequest, status=201
    ),
    "upload_recording": Route(
        "POST", "/api/v1/recordings", {JSON: RecordingCreated}, bytes, request_media=RRD, status=201
    ),
    "list_recordings": Route("GET", "/api/v1/recordings", {JSON: List[RecordingEntry]}),
    "get_recording": Route("GET", "/api/v1/recordings/{id}", {RRD: bytes}),
    "recording_samples": Route("GET", "/api/v1/recordings/{id}/samples", {JSON: RecordedDocument}),
    "delete_recording": Route("DELETE", "/api/v1/recordings/{id}", status=204),
    "stability_map": Route(
        "POST",
        "/api/v1/stability",
        {JSON: StabilityDocument, RRD: bytes},
        StabilityRequest,
        query={"format": ["rrd"]},
    ),
    "stability_point": Route("POST", "/api/v1/stability/point", {JSON: PointDocument}, PointRequest),
    "sweep": Route(
        "POST",
        "/api/v1/studies/sweep",
        {NDJSON: SweepLine, RRD: bytes},
        SweepRequest,
        query={"format": ["rrd"]},
    ),
    "sweep_presets": Route("GET", "/api/v1/studies/sweep/presets", {JSON: List[Preset]}),
    "basins": Route("POST", "/api/v1/studies/basins", {NDJSON: BasinsLine}, BasinsRequest),
    "basins_presets": Route("GET", "/api/v1/studies/basins/presets", {JSON: List[Preset]}),
    "energy_map": Route(
        "POST",
        "/api/v1/studies/energy-map",
        {NDJSON: MapLine, RRD: bytes},
        EnergyMapRequest,
        query={"format": ["rrd"]},
    ),
    "convergence": Route(
        "POST", "/api/v1/studies/convergence", {NDJSON: ConvergenceLine}, ConvergenceRequest
    ),
    "work_precision": Route(
        "POST",
        "/api/v1/studies/work-precision",
        {NDJSON: StudyLine, RRD: bytes},
        WorkPrecisionRequest,
        query={"format": ["rrd"]},
    ),
    "submit_job": Route("POST", "/api/v1/jobs", {JSON: JobStatus}, JobRequest, status=202),
    "list_jobs": Route("GET", "/api/v1/jobs", {JSON: List[JobStatus]}),
    "get_job": Route("GET", "/api/v1/jobs/{id}", {JSON: JobStatus}),
    "cancel_job": Route("POST", "/api/v1/jobs/{id}/cancel", {JSON: JobStatus}),
    "remove_job": Route("DELETE", "/api/v1/jobs/{id}", status=204),
    "job_events": Route("GET", "/api/v1/jobs/{id}/events", {NDJSON: JobEvent}),
    "job_request": Route("GET", "/api/v1/jobs/{id}/request", {JSON: JobSubmission}),
    "job_result": Route(
        "GET", "/api/v1/jobs/{id}/result", {JSON: Dict[str, Any], RRD: bytes}, query={"format": ["rrd"]}
    ),
}
