"""Question (b) of "The remaining gaps": a logged evaluation's average reward per act split by what paid it.

Every robot act earns its one-step reward; over a set of games the average reward per act is the sum of those rewards
over the sum of the dialogue lengths (the evaluation's `avg_reward`), so the sum splits exactly into sources:
  win            +5 on the game move that wins (the last accepted move of a won game)
  about to win   every other +5 (a threat standing after the move)
  draw           +1 on a move that draws or leaves the position dead (about to draw)
  about to lose  -5 on an accepted move after which the user can win at once (the losing move among them)
  refused        -5 on an act the game did not accept (a square really taken: the robot's marks did not grow)
Read from the MCAP log `ncbot eval --out` writes (steps with act and reward, boards, each game's outcome).
"""
from __future__ import annotations

from collections import Counter
from pathlib import Path
from typing import Any

from ncbot.envs.core import ROBOT
from ncbot.logs.names import NameTables
from ncbot.logs.reader import LogReader, read_episode_records

SOURCES = ("win", "about to win", "draw", "about to lose", "refused")


def _episode_sources(record: Any, names: NameTables) -> tuple[Counter, int]:
    """(reward per source, robot acts) of one logged game."""
    boards = {board["step"]: str(board["cells"]).count(str(ROBOT)) for board in record.boards}
    robot = [step for step in record.steps if step.get("who", "robot") == "robot"]
    marks, accepted_moves = 0, []
    sources: Counter = Counter()
    for step in robot:
        act, reward = int(step["act"]), float(step["reward"])
        is_move = names.action_names[act].startswith("GameMove(") if 0 <= act < len(names.action_names) else False
        now = boards.get(step["step"], marks)
        accepted = (now > marks) if is_move else reward != -5.0
        marks = now
        if is_move and accepted:
            accepted_moves.append(step)
        if reward == 0.0:
            continue
        if not accepted:
            sources["refused"] += reward
        elif reward < 0:
            sources["about to lose"] += reward
        elif reward == 1.0:
            sources["draw"] += reward
        else:
            sources["about to win"] += reward
    outcome = (record.summary or {}).get("outcome")
    if outcome == "win" and accepted_moves and float(accepted_moves[-1]["reward"]) == 5.0:
        sources["about to win"] -= 5.0
        sources["win"] += 5.0
    return sources, len(robot)


def reward_sources(logs: str | Path) -> dict[str, Any]:
    """{"games", "acts", "avg_reward", "per_act": {source: reward per act}} over the finished robot-first test games
    logged under ``logs``; the parts add up to ``avg_reward``."""
    reader = LogReader(logs)
    records = read_episode_records(logs, reader=reader)
    names = NameTables.from_metadata(reader.names())
    total: Counter = Counter()
    acts = games = 0
    for record in records.values():
        if record.summary is None or record.summary.get("phase") != "eval" or not record.steps:
            continue
        found, length = _episode_sources(record, names)
        total.update(found)
        acts += length
        games += 1
    if not acts:
        raise ValueError(f"no finished test game with logged steps under {logs}")
    per_act = {source: total[source] / acts for source in SOURCES}
    return {"games": games, "acts": acts, "avg_reward": sum(per_act.values()), "per_act": per_act}
