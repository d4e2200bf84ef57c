"""The client on a server with a tokens file: ``Client(url, token=...)`` sends the token, and
the server's refusals come back as ``GeomintError`` with their status and code. The server is a
second one the test starts (``GEOMINT_BIN``, set by scripts/test-python) with two tokens made by
``geomint token``."""

from __future__ import annotations

import os
import socket
import subprocess
import time
from pathlib import Path
from typing import Iterator

import httpx
import pytest

import geomint

RUN = {"system": "pendulum", "methods": ["modin_3s"], "h": 0.1, "t_end": 2.0}


@pytest.fixture(scope="module")
def tokened(tmp_path_factory: pytest.TempPathFactory) -> Iterator[tuple[str, dict[str, str]]]:
    binary = os.environ.get("GEOMINT_BIN")
    if not binary:
        pytest.skip("GEOMINT_BIN is not set (scripts/test-python sets it)")
    data = tmp_path_factory.mktemp("tokened")
    tokens = data / "tokens"
    secrets = {
        name: subprocess.run(
            [binary, "token", name, "--scopes", scopes, "--append", str(tokens)],
            check=True, capture_output=True, text=True,
        ).stdout.strip()
        for name, scopes in [("alice", "read,run,store"), ("reader", "read")]
    }
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    env = {**os.environ, "GEOMINT_LOG": "warn"}
    server = subprocess.Popen(
        [binary, "serve", "--addr", f"127.0.0.1:{port}", "--tokens", str(tokens),
         "--data-dir", str(data / "recordings"), "--systems-dir", str(data / "systems")],
        env=env,
    )
    url = f"http://127.0.0.1:{port}"
    try:
        for _ in range(300):
            try:
                if httpx.get(f"{url}/healthz").status_code == 200:
                    break
            except httpx.TransportError:
                time.sleep(0.1)
        yield url, secrets
    finally:
        server.terminate()
        server.wait(timeout=30)


def test_a_token_runs_and_stores_and_its_absence_is_refused(tokened: tuple[str, dict[str, str]]) -> None:
    url, secrets = tokened
    with geomint.Client(url, token=secrets["alice"]) as alice:
        sim = alice.simulate("pendulum", ["modin_3s"], h=0.1, t_end=2.0)
        assert len(sim["modin_3s"].t) == 21
        stored = alice.store(sim)
        assert any(r.id == stored.id for r in alice.recordings())
    with geomint.Client(url) as anonymous:
        with pytest.raises(geomint.GeomintError) as refused:
            anonymous.simulate("pendulum", ["modin_3s"], h=0.1, t_end=2.0)
        assert (refused.value.status, refused.value.code, refused.value.field) == (401, "unauthorized", "Authorization")
    with geomint.Client(url, token=secrets["reader"]) as reader:
        assert any(r.id == stored.id for r in reader.recordings())
        with pytest.raises(geomint.GeomintError) as refused:
            reader.delete_recording(stored.id)
        assert (refused.value.status, refused.value.code) == (403, "forbidden")
