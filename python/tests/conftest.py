"""The tests run against a real geomint server: ``GEOMINT_URL`` names it (scripts/test-python
starts one on a free loopback port with a temporary data directory and sets it)."""

from __future__ import annotations

import os
from typing import Any, Iterator

import httpx
import pytest

import geomint


@pytest.fixture(scope="session")
def url() -> str:
    value = os.environ.get("GEOMINT_URL")
    if not value:
        pytest.exit("GEOMINT_URL is not set: start a geomint server and set it (scripts/test-python does both)", 2)
    return value.rstrip("/")


@pytest.fixture(scope="session")
def client(url: str) -> Iterator[geomint.Client]:
    with geomint.Client(url) as c:
        yield c


@pytest.fixture(scope="session")
def raw(url: str) -> Iterator[httpx.Client]:
    """A plain HTTP client, for the server's answers as text beside the client's arrays."""
    with httpx.Client(base_url=url, timeout=300) as c:
        yield c


def post_text(raw: httpx.Client, path: str, body: Any) -> str:
    """The server's JSON answer to ``body`` as text."""
    response = raw.post(path, json=body)
    assert response.status_code == 200, response.text
    return response.text
