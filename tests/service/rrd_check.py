"""Checks a geomint recording with Rerun's own Python reader (rerun-sdk 0.33).

Usage: python rrd_check.py RECORDING.rrd EXPECTED.json ANSWER.json

EXPECTED.json holds {"application_id": str, "rows": {entity: temporal row count},
"energy": {entity: index of its run in ANSWER.json}}; ANSWER.json is the JSON answer of
POST /api/v1/simulate for the same request (Python reads its numbers exactly). The script loads the recording with
rerun.experimental.RrdReader (the 0.33 reader; `store()` needs the file's footer and manifest),
compares entity paths, temporal row counts, timelines and energies (bit for bit), prints a
summary line per entity and exits 0 when everything matches, 1 otherwise.
"""

from __future__ import annotations

import json
import sys

import rerun as rr
from rerun.experimental import RrdReader


def main() -> int:
    path, expected_path, answer_path = sys.argv[1], sys.argv[2], sys.argv[3]
    with open(expected_path, encoding="utf-8") as f:
        expected = json.load(f)
    with open(answer_path, encoding="utf-8") as f:
        answer = json.load(f)
    problems: list[str] = []
    print(f"rerun-sdk {rr.__version__}")
    if not rr.__version__.startswith("0.33."):
        problems.append(f"expected rerun-sdk 0.33.x, got {rr.__version__}")

    reader = RrdReader(path)
    recordings = reader.recordings()
    blueprints = reader.blueprints()
    if len(recordings) != 1:
        problems.append(f"expected one recording store, got {len(recordings)}")
    if len(blueprints) != 1:
        problems.append(f"expected one blueprint store, got {len(blueprints)}")
    for store in recordings + blueprints:
        if store.application_id != expected["application_id"]:
            problems.append(f"application id {store.application_id!r}")

    rows: dict[str, int] = {}
    timelines: dict[str, set[str]] = {}
    energy: dict[str, list[tuple[int, float]]] = {}
    for chunk in reader.stream():
        entity = chunk.entity_path
        if chunk.is_static:
            rows.setdefault(entity, 0)
            continue
        rows[entity] = rows.get(entity, 0) + chunk.num_rows
        timelines.setdefault(entity, set()).update(chunk.timeline_names)
        if entity in expected["energy"]:
            batch = chunk.to_record_batch()
            steps = batch.column("step").to_pylist()
            values = [v[0] for v in batch.column("Scalars:scalars").to_pylist()]
            energy.setdefault(entity, []).extend(zip(steps, values))

    # The footer and manifest are there: the lazy store opens and knows every entity.
    store = reader.store()
    summary = store.summary()
    for entity in expected["rows"]:
        if entity not in summary:
            problems.append(f"{entity} missing from the store summary")

    for entity, count in sorted(expected["rows"].items()):
        got = rows.get(entity)
        print(f"{entity} rows={got} timelines={sorted(timelines.get(entity, []))}")
        if got != count:
            problems.append(f"{entity}: {got} rows, expected {count}")
        if count and timelines.get(entity) != {"step", "t"}:
            problems.append(f"{entity}: timelines {timelines.get(entity)}")
    extra = {e for e in rows if not e.startswith("/__")} - set(expected["rows"])
    if extra:
        problems.append(f"unexpected entities {sorted(extra)}")

    for entity, run in expected["energy"].items():
        values = answer["runs"][run]["energy"]
        got = [v for _, v in sorted(energy.get(entity, []))]
        if got != values:
            problems.append(f"{entity}: energies differ from the JSON answer")
        else:
            print(f"{entity} energies equal ({len(got)})")

    for p in problems:
        print(f"PROBLEM: {p}")
    print("ok" if not problems else "failed")
    return 0 if not problems else 1


if __name__ == "__main__":
    sys.exit(main())
