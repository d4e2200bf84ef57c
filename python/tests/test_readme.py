"""python/README.md's examples run as written, one after the other in one namespace (against the
test server instead of the default URL), and say what their comments say."""

from __future__ import annotations

import re
from pathlib import Path
from typing import Any, Dict, List

import pytest

README = Path(__file__).resolve().parents[1] / "README.md"


def python_blocks() -> List[str]:
    return re.findall(r"```python\n(.*?)```", README.read_text(encoding="utf-8"), flags=re.S)


def test_the_readme_has_examples() -> None:
    assert len(python_blocks()) >= 4


def test_the_readmes_examples_run_as_written(url: str, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("GEOMINT_URL", url)
    namespace: Dict[str, Any] = {}
    for i, block in enumerate(python_blocks()):
        code = block.replace('"http://127.0.0.1:8080"', repr(url))
        exec(compile(code, f"{README.name}, example {i + 1}", "exec"), namespace)
    sim = namespace["sim"]
    # The last simulation's comments: the indicator stop and the spectrum per sample.
    assert sim["velocity_verlet"].stop.reason in ("indicator", "finished")
    assert namespace["ds"]["megno_mean"].dims == ("run", "y", "p_y")
