"""`ncbot logs show`: an episode replayed as text — utterances, boards, and each robot decision."""
from __future__ import annotations

from collections.abc import Callable
from typing import Any

from pathlib import Path

from ncbot.logs.board_image import board_text
from ncbot.logs.names import NameTables
from ncbot.logs.reader import EpisodeRecord, LogReader, read_episode_records


def load_episode(path: str | Path, episode_id: int,
                 progress: Callable[..., Any] | None = None) -> tuple[EpisodeRecord, NameTables]:
    """The logged record of one episode and the name tables stored with it; ValueError if absent."""
    reader = LogReader(path, progress=progress)
    records = read_episode_records(path, [episode_id], reader=reader)
    reader.require_ncbot()
    if episode_id not in records:
        raise ValueError(f"episode {episode_id} is not in {path}; list ids with `ncbot logs episodes {path}`")
    return records[episode_id], NameTables.from_metadata(reader.names())


def format_episode(record: EpisodeRecord, names: NameTables, max_q: int = 8) -> str:
    """Text replay: per step the robot's decision (Q-values, mask, look-ahead sets), its utterance,
    the user's answer and the board after the step."""
    lines = []
    summary = record.summary
    if summary:
        lines.append(f"episode {record.episode}: {summary.get('phase')} {summary.get('game')} agent={summary.get('agent')} "
                     f"seed={summary.get('seed')} robot moves {summary.get('seat')}  outcome={summary.get('outcome')} "
                     f"return={summary.get('return')} length={summary.get('length')}"
                     + (" (truncated)" if summary.get("truncated") else ""))
    else:
        lines.append(f"episode {record.episode}: no /episode summary (the run stopped before it ended)")
    if not record.steps:
        lines.append("  (no per-step messages were logged for this episode's phase)")
    turns_by_step: dict[int, list[dict]] = {}
    for turn in record.dialogue:
        turns_by_step.setdefault(int(turn["step"]), []).append(turn)
    boards = {int(board["step"]): board for board in record.boards}
    for step in record.steps:
        index = int(step["step"])
        act = int(step["act"])
        lines.append("")
        lines.append(f"[step {index}] robot chose {names.action_name(act)} (act {act}), reward {step.get('reward')}")
        lines.append("  " + _decision_text(step, names, max_q))
        for turn in turns_by_step.get(index, []):
            who = "ROBOT" if turn["speaker"] == "robot" else "USER "
            text = turn.get("text") or ""
            detail = names.readable(turn.get("act_name", ""))
            if turn.get("command"):
                detail += f" [{turn['command']}]"
            if turn.get("move", -1) is not None and int(turn.get("move", -1)) >= 0:
                detail += f" move={names.cell_name(int(turn['move']))}"
            if turn.get("words"):
                detail += " words=" + ", ".join(f"{word}:{conf:.2f}" for word, conf in turn["words"])
            lines.append(f"  {who}: {text}  ({detail.strip()})" if text else f"  {who}: ({detail.strip()})")
        board = boards.get(index)
        if board is not None:
            lines.extend("    " + line for line in board_text(board["cells"], names.cols).splitlines())
    return "\n".join(lines)


def _decision_text(step: dict, names: NameTables, max_q: int) -> str:
    mask = [int(a) for a in step.get("mask", [])]
    excluded = set(int(a) for a in step.get("A_hat", []))
    candidates = set(int(a) for a in step.get("A", mask))
    parts = [f"mask={mask}", f"A={sorted(candidates) if candidates != set(mask) else 'all available'}",
             f"A_hat={sorted(excluded)}"]
    q_values = step.get("q")
    if q_values:
        ranked = sorted(zip(mask, q_values), key=lambda pair: -pair[1])
        shown = []
        for act, value in ranked[:max_q]:
            flag = "*" if act == int(step["act"]) else ("x" if act in excluded else "")
            shown.append(f"{names.action_name(act)}{flag}={value:+.3f}")
        more = f" (+{len(ranked) - max_q} more)" if len(ranked) > max_q else ""
        parts.append("Q: " + " ".join(shown) + more)
    else:
        parts.append("Q: not logged")
    return "  ".join(parts)
