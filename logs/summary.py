"""What `ncbot logs inspect` reports: channels, counts, time span, episodes by phase, truncation."""
from __future__ import annotations

from collections import Counter, defaultdict
from datetime import datetime, timezone
from pathlib import Path
from typing import Any

import ncbot.logs.schemas as schemas
from ncbot.logs.reader import LogReader


def summarize(path: str | Path, reader: LogReader | None = None) -> dict[str, Any]:
    """One JSON-ready dict describing a log file or run directory (keys: episodes, by_phase, channels,
    truncated, files, time_span, messages, agents, bytes_per_episode)."""
    reader = reader or LogReader(path)
    episodes = [message.data for message in reader.messages([schemas.EPISODE_TOPIC])]
    reader.require_ncbot()
    scans = [reader.scans[file] for file in reader.files]

    channels: dict[str, dict[str, Any]] = {}
    for scan in scans:
        for topic, (schema_name, encoding) in scan.channels.items():
            entry = channels.setdefault(topic, {"schema": schema_name, "encoding": encoding, "messages": 0})
            entry["messages"] += scan.counts.get(topic, 0)
    starts = [scan.start_ns for scan in scans if scan.start_ns is not None]
    ends = [scan.end_ns for scan in scans if scan.end_ns is not None]
    time_span = None
    if starts:
        start, end = min(starts), max(ends)
        time_span = {"start": _iso(start), "end": _iso(end), "seconds": round((end - start) / 1e9, 3)}
    total_bytes = sum(scan.size for scan in scans)
    return {
        "path": str(reader.path),
        "files": [{"path": str(scan.path), "bytes": scan.size, "complete": scan.complete,
                   "truncated": scan.truncated, "cut_bytes": scan.cut_bytes, "error": scan.error} for scan in scans],
        "truncated": any(scan.truncated for scan in scans),
        "channels": channels,
        "messages": sum(entry["messages"] for entry in channels.values()),
        "time_span": time_span,
        "episodes": len(episodes),
        "agents": sorted({str(e.get("agent")) for e in episodes}),
        "by_phase": by_phase(episodes),
        "bytes_per_episode": round(total_bytes / len(episodes), 1) if episodes else None,
    }


def by_phase(episodes: list[dict[str, Any]]) -> dict[str, dict[str, Any]]:
    """Per phase: episode count, outcome counts, task success, mean length/return/reward per step."""
    groups: dict[str, list[dict[str, Any]]] = defaultdict(list)
    for episode in episodes:
        groups[str(episode.get("phase"))].append(episode)
    result = {}
    for phase in sorted(groups, key=lambda p: (schemas.PHASES + (p,)).index(p)):
        group = groups[phase]
        lengths = [int(e.get("length", 0)) for e in group]
        returns = [float(e.get("return", 0.0)) for e in group]
        outcomes = Counter(str(e.get("outcome")) for e in group)
        result[phase] = {
            "episodes": len(group),
            "outcomes": {name: outcomes.get(name, 0) for name in schemas.OUTCOMES},
            "task_success": round(sum(bool(e.get("task_success")) for e in group) / len(group), 4),
            "mean_length": round(sum(lengths) / len(group), 3),
            "mean_return": round(sum(returns) / len(group), 4),
            "reward_per_step": round(sum(returns) / max(1, sum(lengths)), 4),
            "truncated": sum(bool(e.get("truncated")) for e in group),
        }
    return result


def _iso(ns: int) -> str:
    return datetime.fromtimestamp(ns / 1e9, tz=timezone.utc).isoformat(timespec="milliseconds")


def format_summary(summary: dict[str, Any]) -> str:
    """The human-readable form of `summarize` for the terminal."""
    lines = [f"log: {summary['path']}"]
    for file in summary["files"]:
        state = "complete" if file["complete"] else (f"TRUNCATED (no summary section): last {file['cut_bytes']} bytes "
                                                     f"unreadable, everything before recovered ({file['error']})")
        lines.append(f"  {file['path']}  {file['bytes']} bytes  {state}")
    lines.append("channels:")
    for topic, entry in sorted(summary["channels"].items()):
        lines.append(f"  {topic:<28} {entry['schema']:<26} {entry['encoding']:<9} {entry['messages']:>9} messages")
    span = summary["time_span"]
    if span:
        lines.append(f"time span: {span['start']} .. {span['end']} ({span['seconds']} s)")
    per_episode = summary["bytes_per_episode"]
    lines.append(f"episodes: {summary['episodes']}" + (f"  ({per_episode} bytes per episode on disk)" if per_episode else "")
                 + (f"  agents: {', '.join(summary['agents'])}" if summary["agents"] else ""))
    for phase, stats in summary["by_phase"].items():
        outcomes = " ".join(f"{name}={count}" for name, count in stats["outcomes"].items())
        lines.append(f"  {phase:<6} {stats['episodes']:>7} episodes  {outcomes}  task success {stats['task_success']:.4f}"
                     f"  mean length {stats['mean_length']:.2f}  reward/step {stats['reward_per_step']:.4f}"
                     f"  truncated {stats['truncated']}")
    lines.append("truncated: " + ("yes (recovered everything up to the cut)" if summary["truncated"] else "no"))
    return "\n".join(lines)


# ---------------------------------------------------------------------- a browser study (`ncbot robot serve`)
PERSON_SIDE = {"win": "loss", "loss": "win", "draw": "draw"}


def study_sessions(path: str | Path) -> list[Path]:
    """The session folders of a study directory (sub-folders holding .mcap files); [] if `path` is a plain run."""
    path = Path(path)
    if not path.is_dir() or any(p.suffix == ".mcap" for p in path.iterdir()):
        return []
    return sorted(d for d in path.iterdir() if d.is_dir() and any(p.suffix == ".mcap" for p in d.iterdir()))


def summarize_study(path: str | Path) -> dict[str, Any]:
    """People, sessions, games, outcomes (the person's side), misrecognised moves, dialogue lengths and time per
    turn of a study written by `ncbot robot serve --out DIR` (one session-<id>/ log per browser tab)."""
    import statistics

    folders = study_sessions(path)
    if not folders:
        raise ValueError(f"{path} holds no session folders with .mcap logs; expected the --out of `ncbot robot serve`")
    people: set[str] = set()
    outcomes: Counter = Counter()
    games, lengths, person_acts, human_turns, robot_turns = [], [], [], [], []
    misrecognised = unseen = truncated = 0
    for folder in folders:
        reader = LogReader(folder)
        messages = list(reader.messages([schemas.EPISODE_TOPIC, "/dialogue"]))
        truncated += any(reader.scans[file].truncated for file in reader.files)
        episodes = [m.data for m in messages if m.topic == schemas.EPISODE_TOPIC and m.data.get("phase") == "robot"]
        person_acts.append(sum(1 for m in messages if m.topic == "/dialogue" and m.data.get("source") == "browser"))
        for episode in episodes:
            extra = episode.get("extra") or {}
            people.add(str(extra.get("participant") or extra.get("session") or folder.name))
            outcomes[PERSON_SIDE.get(str(extra.get("true_outcome")), "unfinished")] += 1
            misrecognised += int(extra.get("misrecognised_moves", 0))
            unseen += int(extra.get("unseen_moves", 0))
            lengths.append(int(episode.get("length", 0)))
            human_turns += [float(s) for s in extra.get("human_turn_seconds", [])]
            robot_turns += [float(s) for s in extra.get("robot_move_seconds", [])]
        games.append(len(episodes))

    def stats(values: list[float]) -> dict[str, float] | None:
        if not values:
            return None
        ordered = sorted(values)
        return {"median": round(statistics.median(ordered), 3), "mean": round(statistics.fmean(ordered), 3),
                "p95": round(ordered[min(len(ordered) - 1, int(0.95 * len(ordered)))], 3), "max": round(ordered[-1], 3)}

    return {"path": str(path), "sessions": len(folders), "people": len(people), "games": sum(games),
            "games_per_session": stats([float(g) for g in games]),
            "outcomes": {name: outcomes.get(name, 0) for name in ("win", "loss", "draw", "unfinished")},
            "misrecognised_moves": misrecognised, "unseen_moves": unseen,
            "dialogue_length": stats([float(n) for n in lengths]),
            "person_dialogue_acts_per_session": stats([float(n) for n in person_acts]),
            "seconds_per_person_turn": stats(human_turns), "seconds_per_robot_move": stats(robot_turns),
            "truncated_sessions": truncated}


def format_study(summary: dict[str, Any]) -> str:
    """The terminal form of `summarize_study`."""
    def line(name: str, value: dict[str, float] | None) -> str:
        if value is None:
            return f"  {name}: -"
        return f"  {name}: median {value['median']}  mean {value['mean']}  p95 {value['p95']}  max {value['max']}"

    outcomes = " ".join(f"{name}={count}" for name, count in summary["outcomes"].items())
    return "\n".join([
        f"study: {summary['path']}",
        f"  people {summary['people']}  sessions {summary['sessions']}  games {summary['games']}"
        f"  (logs cut off: {summary['truncated_sessions']})",
        f"  outcomes (the person's side): {outcomes}",
        f"  misrecognised moves {summary['misrecognised_moves']}  unseen moves {summary['unseen_moves']}",
        line("robot actions per game (dialogue length)", summary["dialogue_length"]),
        line("person's dialogue buttons per session", summary["person_dialogue_acts_per_session"]),
        line("seconds per person turn (thinking + drawing + recognition)", summary["seconds_per_person_turn"]),
        line("seconds per robot move", summary["seconds_per_robot_move"]),
    ])
