"""Turn env TensorDicts (one step (B,) or a collector batch (B, T)) into finished episodes, fast.

Speed matters: a training step costs well under 100 us and logging may add 10 %. So the assembler never
loops over steps in Python: each batch becomes fixed-width rows with one numpy call per field
(`ncbot.logs.packed.batch_rows`), the assembler notes where each episode lies in them ((rows, b, t0, t1)
slices), and a finished episode is its rows concatenated. Written as is, that is the packed
`/episode/steps` message; expanded (`expand_episode`, also used by the reader) it becomes the per-action
`/step`, `/dialogue` and `/board` messages. Steps wait per batch index until their episode ends, so an
episode is written in one piece and never split across files.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from ncbot.logs.names import NameTables
from ncbot.logs.packed import batch_rows, unpack_steps
from ncbot.logs.schemas import OUTCOMES

REQUIRED_KEYS = ("action", "action_mask", ("next", "reward"), ("next", "done"), ("next", "board"))
OPTIONAL_KEYS = ("observation", ("next", "observation"), "lookahead_reward", "winning_actions", "robot_first", "turn",
                 "action_value", ("next", "terminated"), ("next", "truncated"), ("next", "outcome"),
                 ("next", "user_act"), ("next", "user_move"), ("next", "user_utterance"))


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
    """Follows the running episode of every batch row across calls and hands back the episodes that ended.

    The state of the running episodes is kept in arrays (length, return so far, seat, where it started), so
    a call costs a few numpy operations over the batch plus Python work per *ending episode* only, never
    per step or per row. The rows of each call are kept until no running episode needs them."""

    def __init__(self) -> None:
        self._resize(0)
        self.calls: dict[int, np.ndarray] = {}  # call number -> its rows as raw bytes, (B, T * row width)
        self.call_count = 0
        self.abandoned = 0  # unfinished episodes dropped (a new one began at their row, or the row went idle)

    def _resize(self, batch: int) -> None:
        self.length = np.zeros(batch, np.int64)  # steps of the running episode so far (0: none running)
        self.total = np.zeros(batch)  # its return so far
        self.robot_first = np.ones(batch, bool)
        self.start_call = np.zeros(batch, np.int64)  # call and time index of its first step
        self.start_t = np.zeros(batch, np.int64)

    @property
    def pending(self) -> int:
        """How many rows have an unfinished episode waiting."""
        return int((self.length > 0).sum())

    def add(self, arrays: dict[str, np.ndarray], names: NameTables, detail: bool = True,
            active: np.ndarray | None = None) -> list[FinishedEpisode]:
        """Add every (b, t) step of a batch; return the episodes whose last step was in it, in time order.
        With `detail` False only the summary (return, length, outcome, seat) is kept; rows b with
        `active[b]` False are skipped (and any episode waiting there dropped)."""
        batch, steps = arrays["action"].shape[:2]
        if batch != len(self.length):  # another env stream: whatever was running there is abandoned
            self.abandoned += self.pending
            self._resize(batch)
            self.calls.clear()
        call = self.call_count
        self.call_count += 1
        dtype, present, width = None, [], 0
        if detail:
            rows, present = batch_rows(arrays, names)
            dtype, width = rows.dtype, rows.dtype.itemsize
            self.calls[call] = rows.view(np.uint8).reshape(batch, steps * width)
        cumulative = np.cumsum(arrays["next.reward"].reshape(batch, steps).astype(np.float64), axis=1)
        first = arrays["robot_first"].reshape(batch, steps).astype(bool) if "robot_first" in arrays \
            else np.ones((batch, steps), bool)
        done = arrays["next.done"].reshape(batch, steps).astype(bool)
        restart = arrays["turn"].reshape(batch, steps)[:, 0] == 0 if "turn" in arrays else np.zeros(batch, bool)
        if active is not None:
            done = done & active[:, None]
            restart = restart | ~active
        # an unfinished episode where a new one starts (turn 0) was abandoned, e.g. an eval env closed mid-game
        self.abandoned += int((restart & (self.length > 0)).sum())
        self.length[restart] = 0
        fresh = self.length == 0
        self.total[fresh] = 0.0
        self.robot_first[fresh] = first[fresh, 0]
        self.start_call[fresh] = call
        self.start_t[fresh] = 0

        end_rows, end_times = np.nonzero(done)
        outcomes, cuts = _ending_flags(arrays, end_rows, end_times)
        finished: list[tuple[int, int, FinishedEpisode]] = []
        previous_row, previous_t = -1, -1
        for b, t, outcome, cut in zip(end_rows.tolist(), end_times.tolist(), outcomes, cuts):
            if b != previous_row:  # the episode that was running at this row when the call began
                length, total = int(self.length[b]), float(self.total[b])
                start_call, start_t, robot_first = int(self.start_call[b]), int(self.start_t[b]), bool(self.robot_first[b])
                t0 = 0 if start_call < call else start_t
            else:  # a later episode of the same row, begun in this call
                length, total, start_call, start_t = 0, 0.0, call, previous_t + 1
                robot_first, t0 = bool(first[b, start_t]), start_t
            length += t + 1 - t0
            total += float(cumulative[b, t] - (cumulative[b, t0 - 1] if t0 > 0 else 0.0))
            data = self._bytes(b, start_call, start_t, call, t, width) if detail else None
            finished.append((t, b, FinishedEpisode(data, dtype, present, b, t, length,
                                                   "first" if robot_first else "second", outcome, total, cut)))
            previous_row, previous_t = b, t
            # what follows this end in the call is the row's running episode from now on
            self.length[b], self.start_call[b], self.start_t[b] = 0, call, t + 1
            self.total[b] = 0.0
            if t + 1 < steps:
                self.robot_first[b] = first[b, t + 1]
        # rows now hold steps from start_t (this call) or from the start of the call onwards
        began_here = self.start_call == call
        tail = np.where(began_here, steps - self.start_t, steps)
        offset = np.where(began_here, self.start_t, 0)
        before = np.where(offset > 0, cumulative[np.arange(batch), np.maximum(offset - 1, 0)], 0.0)
        self.total += cumulative[:, -1] - before
        self.length += tail
        if active is not None:
            self.length[~active] = 0
        running = self.length > 0
        oldest = int(self.start_call[running].min()) if running.any() else call + 1
        for number in [number for number in self.calls if number < oldest]:
            del self.calls[number]
        return [item[2] for item in sorted(finished, key=lambda item: (item[0], item[1]))]

    def _bytes(self, b: int, start_call: int, start_t: int, end_call: int, end_t: int, width: int) -> bytes:
        """The raw rows of row b from (start_call, start_t) to (end_call, end_t) inclusive."""
        parts = []
        for number in range(start_call, end_call + 1):
            raw = self.calls[number]
            t0 = start_t if number == start_call else 0
            t1 = end_t + 1 if number == end_call else raw.shape[1] // width
            parts.append(raw[b, t0 * width:t1 * width].tobytes())
        return parts[0] if len(parts) == 1 else b"".join(parts)


def _ending_flags(arrays: dict[str, np.ndarray], rows: np.ndarray, times: np.ndarray) -> tuple[list[str], list[bool]]:
    """Outcome names and truncation flags at the given (b, t) episode ends."""
    def at_ends(key: str) -> np.ndarray:
        if key not in arrays:
            return np.zeros(len(rows), np.int64)
        values = arrays[key]
        return values.reshape(values.shape[0], values.shape[1])[rows, times]

    outcomes = [OUTCOMES[code] for code in (at_ends("next.outcome").astype(np.int64) % len(OUTCOMES)).tolist()]
    truncated = (at_ends("next.truncated").astype(bool) & ~at_ends("next.terminated").astype(bool)).tolist()
    return outcomes, truncated


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
