"""Turn env TensorDicts (one step (B,) or a collector batch (B, T)) into finished episodes, fast.

Speed matters: a training step costs well under 100 us and logging may add 10 %. So the assembler never
loops over steps in Python: each batch becomes fixed-width rows with one numpy call per field
(`logs.packed.batch_rows`), the assembler notes where each episode lies in them ((rows, b, t0, t1)
slices), and a finished episode is its rows concatenated. Written as is, that is the packed
`/episode/steps` message; expanded (`expand_episode`, also used by the reader) it becomes the per-action
`/step`, `/dialogue` and `/board` messages. Steps wait per batch index until their episode ends, so an
episode is written in one piece and never split across files.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

from logs.names import NameTables
from logs.packed import batch_rows, unpack_steps
from logs.schemas import OUTCOMES

REQUIRED_KEYS = ("action", "action_mask", ("next", "reward"), ("next", "done"), ("next", "board"))
OPTIONAL_KEYS = ("observation", ("next", "observation"), "lookahead_reward", "winning_actions", "robot_first", "turn",
                 "action_value", ("next", "terminated"), ("next", "truncated"), ("next", "outcome"),
                 ("next", "user_act"), ("next", "user_move"), ("next", "user_utterance"))


@dataclass
class PendingEpisode:
    """Where one batch index's current episode lies in the batches seen so far, and its running totals."""

    parts: list[bytes] = field(default_factory=list)  # the bytes of its step rows, batch by batch
    robot_first: bool = True
    length: int = 0
    total_reward: float = 0.0


@dataclass
class FinishedEpisode:
    """An episode ready to write: its step rows (None when not kept) and its summary fields."""

    rows: bytes | None
    row_dtype: np.dtype | None
    present: list[str]
    batch_index: int
    end_t: int  # time index of its last step in the batch it ended in
    length: int
    seat: str
    outcome: str
    total_reward: float
    truncated: bool

    def step_rows(self) -> np.ndarray:
        return np.frombuffer(self.rows, self.row_dtype)


def _key_name(key: str | tuple[str, ...]) -> str:
    return ".".join(key) if isinstance(key, tuple) else key


def step_arrays(td: Any) -> dict[str, np.ndarray]:
    """The keys the logger uses as numpy arrays shaped (B, T, ...); checks the required ones are there."""
    keys = set(td.keys(include_nested=True, leaves_only=True))
    missing = [_key_name(key) for key in REQUIRED_KEYS if key not in keys]
    if missing:
        raise ValueError(f"record_steps needs the env keys {', '.join(missing)} in the TensorDict; "
                         "pass the env's step output (root keys plus ('next', ...))")
    if td.batch_dims > 2:
        raise ValueError(f"record_steps expects a TensorDict with batch size (B,) or (B, T), got {tuple(td.batch_size)}")
    arrays = {}
    for key in REQUIRED_KEYS + OPTIONAL_KEYS:
        if key in keys:
            value = td.get(key).detach().cpu().numpy()
            if td.batch_dims == 0:
                value = value[None, None]
            elif td.batch_dims == 1:
                value = value[:, None]
            arrays[_key_name(key)] = value
    return arrays


class EpisodeAssembler:
    """Collects the steps of each batch index and hands back the episodes that finished.

    Work per batch is a few numpy calls plus a Python loop over batch rows and episode ends, never over
    steps. Rows are copies, so callers may reuse their buffers."""

    def __init__(self) -> None:
        self.pending: dict[int, PendingEpisode] = {}
        self.abandoned = 0  # unfinished episodes dropped because a new one began at their batch index

    def add(self, arrays: dict[str, np.ndarray], names: NameTables, detail: bool = True,
            active: np.ndarray | None = None) -> list[FinishedEpisode]:
        """Add every (b, t) step of a batch; return the episodes whose last step was in it, in time order.
        With `detail` False only the summary (return, length, outcome, seat) is kept; rows b with
        `active[b]` False are skipped (and any episode waiting there dropped)."""
        batch, steps = arrays["action"].shape[:2]
        if detail:
            rows, present = batch_rows(arrays, names)
            dtype, raw = rows.dtype, rows.view(np.uint8).reshape(batch, steps * rows.dtype.itemsize)
        else:
            dtype, raw, present = None, None, []
        width = dtype.itemsize if dtype is not None else 0
        rewards = np.zeros((batch, steps + 1))
        np.cumsum(arrays["next.reward"].reshape(batch, steps), axis=1, out=rewards[:, 1:])
        cumulative = rewards.tolist()  # a segment's return is a difference of two of these
        done = arrays["next.done"].reshape(batch, steps)
        starts = (arrays["turn"].reshape(batch, steps)[:, 0] == 0).tolist() if "turn" in arrays else [False] * batch
        first = arrays["robot_first"].reshape(batch, steps).tolist() if "robot_first" in arrays else None
        ends_by_row: dict[int, list[int]] = {}
        for b, t in zip(*(index.tolist() for index in np.nonzero(done))):
            ends_by_row.setdefault(b, []).append(t)
        ending = _ending_flags(arrays, batch, steps) if ends_by_row else None
        finished: list[tuple[int, int, FinishedEpisode]] = []
        for b in range(batch):
            if active is not None and not active[b]:
                self.pending.pop(b, None)
                continue
            episode = self.pending.get(b)
            if episode is not None and starts[b]:
                # a new episode starts where an unfinished one was waiting: its stream was abandoned
                # (e.g. an evaluation env closed mid-game); drop it rather than glue two games together
                self.abandoned += 1
                episode = None
            ends = ends_by_row.get(b, [])
            t0 = 0
            for t_end in ends + [steps - 1]:
                if t0 > t_end:
                    break
                if episode is None:
                    episode = PendingEpisode(robot_first=True if first is None else bool(first[b][t0]))
                if raw is not None:
                    episode.parts.append(raw[b, t0 * width:(t_end + 1) * width].tobytes())
                episode.length += t_end + 1 - t0
                episode.total_reward += cumulative[b][t_end + 1] - cumulative[b][t0]
                if t_end in ends:
                    outcome, truncated = ending[b][t_end]
                    finished.append((t_end, b, FinishedEpisode(
                        b"".join(episode.parts) if raw is not None else None, dtype, present, b, t_end, episode.length,
                        "first" if episode.robot_first else "second", outcome, episode.total_reward, truncated)))
                    episode = None
                t0 = t_end + 1
            if episode is None:
                self.pending.pop(b, None)
            else:
                self.pending[b] = episode
        return [item[2] for item in sorted(finished, key=lambda item: (item[0], item[1]))]


def _ending_flags(arrays: dict[str, np.ndarray], batch: int, steps: int) -> list[list[tuple[str, bool]]]:
    """(outcome name, truncated) of every (b, t), in case an episode ends there."""
    def grid(key: str) -> np.ndarray:
        return arrays[key].reshape(batch, steps) if key in arrays else np.zeros((batch, steps), np.int64)

    outcome = (grid("next.outcome").astype(np.int64) % len(OUTCOMES)).tolist()
    truncated = (grid("next.truncated").astype(bool) & ~grid("next.terminated").astype(bool)).tolist()
    return [[(OUTCOMES[o], c) for o, c in zip(row_outcome, row_cut)] for row_outcome, row_cut in zip(outcome, truncated)]


def expand_episode(episode_id: int, rows: np.ndarray, present: set[str] | list[str],
                   names: NameTables) -> tuple[list, list, list]:
    """An episode's rows as per-action `/step`, `/dialogue` and `/board` message dicts.

    The writer uses this for phases logged per action, the reader for packed `/episode/steps` messages, so
    both give the same dicts (dialogue text comes from the name tables stored in the file)."""
    steps, dialogue, boards = [], [], []
    for row in unpack_steps(rows, set(present), names):
        index, act = row["step"], row["act"]
        step = {"episode": episode_id, "step": index, "who": "robot", "act": act, "mask": row["mask"],
                "reward": row["reward"]}
        for optional in ("A", "A_hat", "q", "on"):
            if optional in row:
                step[optional] = row[optional]
        if row.get("val"):
            step["val"] = row["val"]
        steps.append(step)
        robot_turn = {"episode": episode_id, "step": index, "speaker": "robot", "act": act,
                      "act_name": names.action_name(act), "text": names.template(act)}
        command = names.robot_command(act)
        if command:
            robot_turn["command"] = command
        dialogue.append(robot_turn)
        if row["user_act"] >= 0:
            user_turn = {"episode": episode_id, "step": index, "speaker": "user", "act": row["user_act"],
                         "act_name": names.user_act_name(row["user_act"])}
            text = names.user_utterance(row["user_utterance"])
            if text:
                user_turn["text"] = text
            user_turn["move"] = row["user_move"]
            if row["words"]:
                user_turn["words"] = row["words"]
            dialogue.append(user_turn)
        boards.append({"episode": episode_id, "step": index, "cells": row["cells"],
                       "size": 3 if len(row["cells"]) == 9 else 9})
    return steps, dialogue, boards
