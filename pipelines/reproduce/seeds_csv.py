"""A table's per-seed CSV (`<table>_seeds.csv`, written by `ncbot table`) read back as the runs it was written from.

Why: run folders are large and not shipped; the CSV beside every published table holds each run's numbers, so
`ncbot table results/paper_table_seeds.csv ...` re-makes the table and its verdicts from what ships. A run read
back has the eval.json keys the table reads (frames, run id, wall time, each seat's outcome shares); it has no
learning curve and no config.yaml, so its row is labelled by its key ("Ultimate (100)") and no curve is drawn.
Numbers are read back exactly (Python writes floats as their shortest exact form), so writing the CSV again gives
the same bytes.
"""
from __future__ import annotations

import csv
import re
from collections import defaultdict
from pathlib import Path
from typing import Any

KEY_COLUMNS = ("suite", "game", "agent")
INTEGER = re.compile(r"-?\d+")
EXPECTED = ("expected the <table>_seeds.csv `ncbot table` writes: a header with suite, game, agent, seed, run_id, "
            "frames, first.task_success, ... and one row per run")


def _number(text: str, where: str) -> int | float | None:
    if text == "":
        return None
    try:
        return int(text) if INTEGER.fullmatch(text) else float(text)
    except ValueError:
        raise ValueError(f"{where}: {text!r} is not a number; {EXPECTED}") from None


def is_seeds_csv(source: str | Path) -> bool:
    """A table source given as a CSV file rather than a runs folder."""
    return Path(source).suffix.lower() == ".csv"


def read_seeds_csv(path: str | Path) -> dict[tuple[str, str, str], list[dict[str, Any]]]:
    """(suite, game row, agent cell) -> the runs of that cell as eval.json-like dicts, in the file's order; a bad
    file is one ValueError naming it and what was expected."""
    path = Path(path)
    try:
        with path.open(newline="", encoding="utf-8") as handle:
            rows = list(csv.DictReader(handle))
            header = rows and list(rows[0])
    except OSError as error:
        raise FileNotFoundError(f"seeds CSV {str(path)!r} cannot be read ({error.strerror}); {EXPECTED}") from None
    required = (*KEY_COLUMNS, "seed", "run_id", "frames", "first.task_success", "second.task_success")
    if not rows or any(column not in header for column in required):
        raise ValueError(f"{path} has no runs or lacks a column of {', '.join(required)}; {EXPECTED}")
    groups: dict[tuple[str, str, str], list[dict[str, Any]]] = defaultdict(list)
    for line, row in enumerate(rows, 2):
        run: dict[str, Any] = {"history": []}
        for column, text in row.items():
            if column in KEY_COLUMNS or column is None:
                continue
            if column == "run_id":
                run["run_id"] = text or None
                continue
            value = _number(text or "", f"{path} line {line}, column {column}")
            if value is None:
                continue
            seat, _, key = column.partition(".")
            if key:
                run.setdefault(seat, {})[key] = value
            else:
                run[column] = value
        if not isinstance(run.get("seed"), int):
            raise ValueError(f"{path} line {line}: seed {row.get('seed')!r} is not a whole number; {EXPECTED}")
        groups[tuple(row[column] for column in KEY_COLUMNS)].append(run)
    return dict(groups)
