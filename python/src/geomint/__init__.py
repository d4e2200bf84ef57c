"""geomint's Python client: geometric numerical integration of damped Hamiltonian systems, run by
a geomint server, with the answers as numpy arrays (and xarray or pandas objects on request).

>>> import geomint                                                   # doctest: +SKIP
>>> client = geomint.Client("http://127.0.0.1:8080")                 # doctest: +SKIP
>>> sim = client.simulate("pendulum", ["modin_3s", "heun"], h=0.1, t_end=200)  # doctest: +SKIP
>>> sim["modin_3s"].energy                                           # doctest: +SKIP

Without a server, :func:`geomint.local.simulate` runs the same request in this process.
"""

from ._version import __version__
from .catalog import Chart, Definition, Facts, Method, Parameter, System
from ._transport import DEFAULT_URL
from .basins import Attractor, BasinMap, BasinRun, CriticalPoint, Undecided
from .client import Client
from .jobs import Job
from .errors import (
    GeomintError,
    MissingError,
    OverloadedError,
    RefusedError,
    ServerError,
    UnreachableError,
    ValidationError,
)
from .recording import Recording, RecordingInfo, Shown
from .sections import (
    Crossings,
    SectionSummary,
    Surface,
)
from .simulation import (
    DivergedAt,
    Indicators,
    Run,
    Schedule,
    Simulation,
    Stats,
    Stop,
    SystemState,
)
from .maps import (
    EnergyMap,
    Spectrum,
    StabilityMap,
    StabilityMaps,
    StabilityPoint,
)
from .studies import (
    Axis,
    Convergence,
    ConvergenceSeries,
    OrderFit,
    Sweep,
    SweepRun,
    WorkPrecision,
    WorkPrecisionRun,
)

__all__ = [
    "DEFAULT_URL",
    "Job",
    "Attractor",
    "Axis",
    "BasinMap",
    "BasinRun",
    "Chart",
    "Client",
    "Convergence",
    "ConvergenceSeries",
    "CriticalPoint",
    "Crossings",
    "Definition",
    "DivergedAt",
    "EnergyMap",
    "Facts",
    "GeomintError",
    "Indicators",
    "MissingError",
    "Method",
    "OrderFit",
    "OverloadedError",
    "Parameter",
    "Recording",
    "RecordingInfo",
    "RefusedError",
    "Run",
    "Schedule",
    "Shown",
    "SectionSummary",
    "ServerError",
    "Simulation",
    "Spectrum",
    "StabilityMap",
    "StabilityMaps",
    "StabilityPoint",
    "Stats",
    "Stop",
    "Surface",
    "Sweep",
    "SweepRun",
    "SystemState",
    "System",
    "Undecided",
    "UnreachableError",
    "ValidationError",
    "WorkPrecision",
    "WorkPrecisionRun",
    "__version__",
]
