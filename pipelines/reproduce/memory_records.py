"""The memory report's runs as two CSV files, written beside the report and read back as if they were run folders.

Why: a run folder holds checkpoints and MCAP logs (tens of MB a run), so it stays on the machine that trained it,
while the report is shared. `table_seeds.csv` (one row per run: what it was trained with, its evaluation, its cost)
and `table_curves.csv` (its periodic evaluations) hold everything the report reads, so a later report can add new
runs to arms measured elsewhere: `ncbot reproduce memory results/memory/table_seeds.csv runs/new_grid`.
"""
from __future__ import annotations

import csv
import io
from pathlib import Path
from typing import Any, Iterable

SEEDS_CSV = "table_seeds.csv"
CURVES_CSV = "table_curves.csv"
THRESHOLDS = (0.95, 0.99)  # training games until the periodic task success first reached these
#: what identifies a run's arm and seed (the first columns of both files)
KEY_COLUMNS = ("game", "reward", "memory", "temporal", "batch_size", "seed", "run_id")
SEAT_COLUMNS = ("first.task_success", "first.win", "first.draw", "first.loss", "first.truncated", "first.avg_length",
                "second.task_success", "second.win", "second.loss")
SEEDS_COLUMNS = (*KEY_COLUMNS, "frames", "train_wall_time_s", "params", *(f"games_to_{t}" for t in THRESHOLDS),
                 *SEAT_COLUMNS)
CURVES_COLUMNS = (*KEY_COLUMNS, "episodes", "frames", "task_success")
ArmKey = tuple[str, str, str, bool, int]  # game, recipe (reward), memory, temporal features, batch size


def games_to(run: dict[str, Any], threshold: float) -> float | None:
    """Training games at the first periodic evaluation with task success >= threshold (None: never reached). A run
    read from a seeds CSV without its curve keeps the figure the CSV holds."""
    if run.get("history"):
        return next((float(point["episodes"]) for point in run["history"]
                     if point.get("task_success", 0.0) >= threshold), None)
    return run.get("games_to", {}).get(threshold)


def _key(game: str, reward: str, memory: str, temporal: bool, batch_size: int, run: dict[str, Any]) -> list[Any]:
    return [game, reward, memory, str(temporal).lower(), batch_size, run["seed"], run.get("run_id", "")]


def seeds_csv(runs: Iterable[tuple[ArmKey, dict[str, Any]]]) -> str:
    """One row per (arm key, run): the rows `read_records` reads back."""
    rows = [",".join(SEEDS_COLUMNS)]
    for key, run in runs:
        reached = [games_to(run, threshold) for threshold in THRESHOLDS]
        values = [*_key(*key, run), run["frames"], run["train_wall_time_s"], run.get("params") or "",
                  *("" if games is None else int(games) for games in reached),
                  *(run[seat].get(name, "") for seat, name in (column.split(".") for column in SEAT_COLUMNS))]
        rows.append(",".join(str(value) for value in values))
    return "\n".join(rows) + "\n"


def curves_csv(runs: Iterable[tuple[ArmKey, dict[str, Any]]]) -> str:
    """One row per periodic evaluation of every run that has them."""
    rows = [",".join(CURVES_COLUMNS)]
    for key, run in runs:
        for point in run.get("history", []):
            rows.append(",".join(str(value) for value in
                                 [*_key(*key, run), point["episodes"], point.get("frames", ""), point["task_success"]]))
    return "\n".join(rows) + "\n"


def _rows(path: Path, columns: tuple[str, ...]) -> list[dict[str, str]]:
    try:
        reader = csv.DictReader(io.StringIO(path.read_text(encoding="utf-8")))
        rows = list(reader)
    except (OSError, UnicodeDecodeError, csv.Error) as error:
        raise ValueError(f"{path} cannot be read as CSV ({error}); expected a {path.name} the memory report wrote") from None
    missing = [column for column in columns if column not in (reader.fieldnames or [])]
    if missing:
        expected = CURVES_CSV if columns == CURVES_COLUMNS else SEEDS_CSV
        raise ValueError(f"{path} lacks the columns {', '.join(missing)}; expected a {expected} the memory report "
                         "wrote (ncbot reproduce memory ... --out FOLDER)")
    return rows


def _number(row: dict[str, str], column: str, path: Path, line: int, kind: type = float) -> Any:
    text = row[column].strip()
    if text == "":
        return None
    try:
        return kind(float(text)) if kind is int else kind(text)
    except ValueError:
        raise ValueError(f"{path} line {line}: {column} is {text!r}, expected a number") from None


def read_records(path: str | Path) -> list[tuple[ArmKey, dict[str, Any]]]:
    """(arm key, run) for every row of a seeds CSV, each run shaped like a run folder's eval.json with its settings,
    the periodic evaluations attached from the `table_curves.csv` beside it when that file holds them."""
    path = Path(path)
    records = []
    for line, row in enumerate(_rows(path, SEEDS_COLUMNS), start=2):
        if row["temporal"] not in ("true", "false"):
            raise ValueError(f"{path} line {line}: temporal is {row['temporal']!r}, expected true or false")
        key = (row["game"], row["reward"], row["memory"], row["temporal"] == "true",
               _number(row, "batch_size", path, line, int))
        run: dict[str, Any] = {
            "seed": _number(row, "seed", path, line, int), "run_id": row["run_id"],
            "frames": _number(row, "frames", path, line, int),
            "train_wall_time_s": _number(row, "train_wall_time_s", path, line),
            "params": _number(row, "params", path, line, int),
            "games_to": {t: _number(row, f"games_to_{t}", path, line) for t in THRESHOLDS},
            "first": {}, "second": {}}
        for column in SEAT_COLUMNS:
            seat, name = column.split(".")
            if (value := _number(row, column, path, line)) is not None:
                run[seat][name] = value
        if None in (key[4], run["seed"], run["frames"], run["train_wall_time_s"]) or "task_success" not in run["first"]:
            raise ValueError(f"{path} line {line}: batch_size, seed, frames, train_wall_time_s and "
                             "first.task_success must each hold a number")
        records.append((key, run))
    curves = path.parent / CURVES_CSV
    if curves.is_file():
        histories: dict[tuple[Any, ...], list[dict[str, float]]] = {}
        for line, row in enumerate(_rows(curves, CURVES_COLUMNS), start=2):
            point = {"episodes": _number(row, "episodes", curves, line, int),
                     "frames": _number(row, "frames", curves, line, int),
                     "task_success": _number(row, "task_success", curves, line)}
            histories.setdefault(tuple(row[column] for column in KEY_COLUMNS), []).append(point)
        for key, run in records:
            run["history"] = histories.get(tuple(str(value) for value in _key(*key, run)), [])
    return records
