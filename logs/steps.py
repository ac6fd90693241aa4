"""Turn env TensorDicts (one step (B,) or a collector batch (B, T)) into per-episode message dicts.

Steps are buffered per batch index until their episode ends, so each episode is written in one piece
(contiguous in the file, one id, never split across files) and an unfinished episode costs nothing on disk.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

from logs.names import NameTables
from logs.schemas import OUTCOMES

REQUIRED_KEYS = ("action", "action_mask", ("next", "reward"), ("next", "done"), ("next", "board"))
OPTIONAL_KEYS = ("observation", ("next", "observation"), "lookahead_reward", "winning_actions", "robot_first", "turn", "action_value",
                 ("next", "terminated"), ("next", "truncated"), ("next", "outcome"), ("next", "user_act"),
                 ("next", "user_move"), ("next", "user_utterance"))


@dataclass
class PendingEpisode:
    """What has been seen of one batch index's current episode."""

    steps: list[dict] = field(default_factory=list)
    dialogue: list[dict] = field(default_factory=list)
    boards: list[dict] = field(default_factory=list)
    robot_first: bool = True
    total_reward: float = 0.0
    length: int = 0


@dataclass
class FinishedEpisode:
    """An episode ready to write: its messages (episode id still unset) and its summary fields."""

    steps: list[dict]
    dialogue: list[dict]
    boards: list[dict]
    batch_index: int
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
    """Builds step/dialogue/board dicts per batch index and hands back the episodes that finished."""

    def __init__(self) -> None:
        self.pending: dict[int, PendingEpisode] = {}
        self.abandoned = 0  # unfinished episodes dropped because a new one began at their batch index

    def add(self, arrays: dict[str, np.ndarray], names: NameTables, detail: bool = True) -> list[FinishedEpisode]:
        """Add every (b, t) step of a batch; return the episodes whose last step was in it, in time order.
        With `detail` False only the summary (return, length, outcome, seat) is kept."""
        batch, steps = arrays["action"].shape[:2]
        finished: list[FinishedEpisode] = []
        word_columns = names.word_columns() if detail else {}
        for t in range(steps):
            for b in range(batch):
                episode = self.pending.get(b)
                if episode is not None and episode.length and "turn" in arrays and int(arrays["turn"][b, t].reshape(-1)[0]) == 0:
                    # a new episode starts where an unfinished one was waiting: its stream was abandoned
                    # (e.g. an evaluation env closed mid-game); drop it rather than glue two games together
                    del self.pending[b]
                    self.abandoned += 1
                    episode = None
                if episode is None:
                    episode = self.pending[b] = PendingEpisode()
                    if "robot_first" in arrays:
                        episode.robot_first = bool(arrays["robot_first"][b, t].reshape(-1)[0])
                episode.length += 1
                episode.total_reward += float(arrays["next.reward"][b, t].reshape(-1)[0])
                if detail:
                    self._add_step(episode, arrays, b, t, names, word_columns)
                if bool(arrays["next.done"][b, t].reshape(-1)[0]):
                    finished.append(self._finish(b, arrays, t))
        return finished

    def _add_step(self, episode: PendingEpisode, arrays: dict[str, np.ndarray], b: int, t: int,
                  names: NameTables, word_columns: dict[str, int]) -> None:
        act = int(arrays["action"][b, t].reshape(-1)[0]) if arrays["action"][b, t].size == 1 \
            else int(np.argmax(arrays["action"][b, t]))  # one-hot actions from some TorchRL specs
        index = int(arrays["turn"][b, t].reshape(-1)[0]) if "turn" in arrays else len(episode.steps)
        mask = arrays["action_mask"][b, t]
        available = np.flatnonzero(mask)
        reward = float(arrays["next.reward"][b, t].reshape(-1)[0])
        step: dict[str, Any] = {"episode": -1, "step": index, "who": "robot", "act": act,
                                "mask": available.tolist(), "reward": round(reward, 4)}
        if "winning_actions" in arrays:
            winning = np.flatnonzero(arrays["winning_actions"][b, t] & mask)
            step["A"] = winning.tolist() if winning.size else step["mask"]
        if "lookahead_reward" in arrays:
            step["A_hat"] = np.flatnonzero(mask & (arrays["lookahead_reward"][b, t] < 0)).tolist()
        if "action_value" in arrays:
            step["q"] = np.round(arrays["action_value"][b, t][available].astype(np.float64), 3).tolist()
        if "observation" in arrays:
            features = arrays["observation"][b, t]
            nonzero = np.flatnonzero(features)
            values = features[nonzero]
            ones = values == 1.0
            step["on"] = nonzero[ones].tolist()
            others = ~ones
            if others.any():
                step["val"] = [[int(i), round(float(v), 3)] for i, v in zip(nonzero[others], values[others])]
        episode.steps.append(step)

        robot_turn: dict[str, Any] = {"episode": -1, "step": index, "speaker": "robot", "act": act,
                                      "act_name": names.action_name(act), "text": names.template(act)}
        command = names.robot_command(act)
        if command:
            robot_turn["command"] = command
        episode.dialogue.append(robot_turn)
        user_act = int(arrays["next.user_act"][b, t].reshape(-1)[0]) if "next.user_act" in arrays else -1
        if user_act >= 0:
            user_turn: dict[str, Any] = {"episode": -1, "step": index, "speaker": "user", "act": user_act,
                                         "act_name": names.user_act_name(user_act)}
            utterance = int(arrays["next.user_utterance"][b, t].reshape(-1)[0]) if "next.user_utterance" in arrays else -1
            text = names.user_utterance(utterance)
            if text:
                user_turn["text"] = text
            if "next.user_move" in arrays:
                user_turn["move"] = int(arrays["next.user_move"][b, t].reshape(-1)[0])
            next_obs = arrays.get("next.observation")
            if text and word_columns and next_obs is not None:
                # the user's words hold their ASR confidence in the observation after the user spoke
                said = [word for word in dict.fromkeys(_tokenize(text)) if word in word_columns]
                user_turn["words"] = [[word, round(float(next_obs[b, t][word_columns[word]]), 3)] for word in said]
            episode.dialogue.append(user_turn)

        cells = arrays["next.board"][b, t].astype(np.uint8).ravel()
        board: dict[str, Any] = {"episode": -1, "step": index, "cells": (cells + 48).tobytes().decode(),
                                 "size": 3 if cells.size == 9 else 9}
        if "next.outcome" in arrays:
            board["outcome"] = OUTCOMES[int(arrays["next.outcome"][b, t].reshape(-1)[0]) % len(OUTCOMES)]
        episode.boards.append(board)

    def _finish(self, b: int, arrays: dict[str, np.ndarray], t: int) -> FinishedEpisode:
        episode = self.pending.pop(b)
        outcome_code = int(arrays["next.outcome"][b, t].reshape(-1)[0]) if "next.outcome" in arrays else 0
        truncated = bool(arrays["next.truncated"][b, t].reshape(-1)[0]) if "next.truncated" in arrays else False
        if "next.terminated" in arrays and bool(arrays["next.terminated"][b, t].reshape(-1)[0]):
            truncated = False
        return FinishedEpisode(episode.steps, episode.dialogue, episode.boards, b, episode.length,
                               "first" if episode.robot_first else "second",
                               OUTCOMES[outcome_code % len(OUTCOMES)], episode.total_reward, truncated)


def _tokenize(text: str) -> list[str]:
    """Words of an utterance exactly as the env turns them into word features."""
    from envs.dialogue import tokenize

    return tokenize(text)
