"""A sweep's ``results/`` folder: one JSON document per design, named by its key."""
from __future__ import annotations

import json
from pathlib import Path

from .designs import Design, Sweep


def result_path(out, key: str) -> Path:
    return Path(out) / "results" / f"{key}.json"


def read_design_result(out, key: str) -> dict | None:
    """The stored document of a design, or None if absent or unreadable (then it is recomputed)."""
    try:
        doc = json.loads(result_path(out, key).read_text())
    except (OSError, ValueError):
        return None
    return doc if isinstance(doc, dict) and isinstance(doc.get("sweep"), dict) else None


def pending(sweep: Sweep, out, retry_failed: bool = False) -> list[Design]:
    """Designs without a stored result (or with a stored failure, if ``retry_failed``)."""
    todo = []
    for d in sweep.designs:
        doc = read_design_result(out, d.key)
        if doc is None or (retry_failed and doc["sweep"].get("status") != "ok"):
            todo.append(d)
    return todo
