"""What `ncbot logs acts` reports: where a dialogue's length goes, counted from the log alone.

A dialogue's length is its number of robot acts, so the mean count per game of every act adds up to the mean
dialogue length. Game moves are one row (which square does not matter here), and the moves the game refused (the
square was taken: the robot's mark count did not grow) are counted beside them, so a reader can tell a long
dialogue that plays many moves from one that repeats refused ones or talks more between moves. Rows are split by
the robot's outcome, since draws run to the last square and lost games differ again.
"""
from __future__ import annotations

from collections import Counter
from pathlib import Path
from typing import Any, Callable

from ncbot.envs.core import ROBOT
import ncbot.logs.schemas as schemas
from ncbot.logs.names import NameTables
from ncbot.logs.reader import EpisodeRecord, LogReader, read_episode_records

GAME_MOVES = "game moves"
REFUSED = "refused (square taken)"
SEATS = ("first", "second")


def count_acts(record: EpisodeRecord, names: NameTables) -> Counter:
    """Robot acts of one episode by name (game moves pooled as GAME_MOVES), and REFUSED: its game moves after
    which the robot had no more marks on the logged board than before."""
    counts: Counter = Counter()
    robot_mark = str(ROBOT)
    before = 0
    boards = {board["step"]: board["cells"] for board in record.boards}
    for step in record.steps:
        if step.get("who", "robot") != "robot":
            continue
        act = int(step["act"])
        raw = names.action_names[act] if 0 <= act < len(names.action_names) else ""
        cells = boards.get(step["step"])
        marks = before if cells is None else str(cells).count(robot_mark)
        if raw.startswith("GameMove("):
            counts[GAME_MOVES] += 1
            if cells is not None and marks <= before:
                counts[REFUSED] += 1
        else:
            counts[names.action_name(act)] += 1
        before = marks
    return counts


def act_table(path: str | Path, phase: str | None = "eval", seat: str | None = None,
              progress: Callable[..., Any] | None = None) -> dict[str, Any]:
    """Mean robot acts per game by act, over the finished episodes of ``phase`` (None: all) and ``seat`` (None:
    both), for all games and per outcome: {"path", "phase", "seat", "groups": {label: {"games", "mean_length",
    "acts": {name: mean per game}}}} with labels "all" then the outcomes that occur."""
    if phase is not None and phase not in schemas.PHASES:
        raise ValueError(f"--phase must be one of {', '.join(schemas.PHASES)}, got {phase!r}")
    if seat is not None and seat not in SEATS:
        raise ValueError(f"--seat must be first or second (the robot's seat), got {seat!r}")
    reader = LogReader(path, progress=progress)
    records = read_episode_records(path, reader=reader)
    reader.require_ncbot()
    names = NameTables.from_metadata(reader.names())
    chosen = [record for record in records.values() if record.summary is not None and record.steps
              and (phase is None or record.summary.get("phase") == phase)
              and (seat is None or record.summary.get("seat") == seat)]
    if not chosen:
        where = " ".join(part for part in (phase and f"phase {phase}", seat and f"seat {seat}") if part)
        raise ValueError(f"no finished episode with logged steps{' for ' + where if where else ''} in {path}; "
                         f"list them with `ncbot logs episodes {path}`")
    groups: dict[str, list[tuple[int, Counter]]] = {"all": []}
    for record in chosen:
        entry = (int(record.summary.get("length", len(record.steps))), count_acts(record, names))
        groups["all"].append(entry)
        groups.setdefault(str(record.summary.get("outcome")), []).append(entry)
    order = ["all", *[name for name in schemas.OUTCOMES if name in groups]]
    return {"path": str(path), "phase": phase, "seat": seat,
            "groups": {label: _means(groups[label]) for label in order}}


def _means(entries: list[tuple[int, Counter]]) -> dict[str, Any]:
    total: Counter = Counter()
    for _, counts in entries:
        total.update(counts)
    games = len(entries)
    acts = {GAME_MOVES: total.pop(GAME_MOVES, 0) / games, REFUSED: total.pop(REFUSED, 0) / games}
    acts.update({name: count / games for name, count in total.most_common()})
    return {"games": games, "mean_length": sum(length for length, _ in entries) / games, "acts": acts}


def format_act_table(table: dict[str, Any]) -> str:
    """The Markdown table of `act_table`: one row per act, one column per group."""
    groups = table["groups"]
    labels = list(groups)
    names = list(dict.fromkeys(name for label in labels for name in groups[label]["acts"]))
    who = ", ".join(part for part in (f"phase {table['phase']}" if table["phase"] else "every phase",
                                      f"robot {table['seat']}" if table["seat"] else "both seats"))
    lines = [f"robot acts per game ({who}; {table['path']})", "",
             "| act | " + " | ".join(labels) + " |", "|---|" + "---|" * len(labels),
             "| games | " + " | ".join(str(groups[label]["games"]) for label in labels) + " |",
             "| dialogue length | " + " | ".join(f"{groups[label]['mean_length']:.2f}" for label in labels) + " |"]
    for name in names:
        shown = f"  of which {name}" if name == REFUSED else name
        lines.append(f"| {shown} | " + " | ".join(f"{groups[label]['acts'].get(name, 0.0):.2f}" for label in labels)
                     + " |")
    return "\n".join(lines)
