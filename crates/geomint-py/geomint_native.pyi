"""geomint's integrator core in the Python process; ``geomint.local`` is its interface."""

from typing import Tuple

def simulate(request: str) -> Tuple[bool, str]:
    """Runs the simulation ``request`` (JSON, the body of ``POST /api/v1/simulate``): ``(True,
    document)`` or ``(False, error)``, both JSON text."""
