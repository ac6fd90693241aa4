"""Hand-built env TensorDicts with the documented keys (docs/design.md), and the expected messages computed
from them independently of the logger, for the logs tests."""
from __future__ import annotations

import sys
from dataclasses import dataclass

import numpy as np
import pytest
import torch
from tensordict import TensorDict

N_ACTIONS, N_FEATURES, N_CELLS = 18, 73, 9


class NamedEnv:
    """Stands in for the env's name tables only (record_steps reads nothing else from `env`)."""

    action_names = [f"act_{i}" for i in range(N_ACTIONS)]
    templates = [f"utterance number {i}" for i in range(N_ACTIONS)]
    robot_commands = [f"who=rob, what=cmd{i}" for i in range(N_ACTIONS)]
    user_act_names = ["Provide(name)", "Reply(yes)", "GameMove", "Salutation(closing)"]
    feature_names = [f"f{i}" for i in range(N_FEATURES - 3)] + ["word[yes]", "word[no]", "word[name]"]

    class model:  # the env's dialogue model: texts of the simulated user's utterances
        utterance_texts = ("Yes, sure!", "No.", "My name is Sam", "bye")


def fake_batch(batch: int, steps: int, done_at: dict[int, list[int]], seed: int = 0,
               with_q: bool = True, cells: int = N_CELLS) -> TensorDict:
    """A (B, T) batch with every documented key; episode ends where `done_at[b]` says."""
    g = torch.Generator().manual_seed(seed)
    mask = torch.rand(batch, steps, N_ACTIONS, generator=g) > 0.4
    mask[..., 0] = True
    observation = (torch.rand(batch, steps, N_FEATURES, generator=g) > 0.8).float()
    observation[..., 5] = torch.rand(batch, steps, generator=g)  # a continuous (temporal-like) feature
    next_observation = (torch.rand(batch, steps, N_FEATURES, generator=g) > 0.8).float()
    next_observation[..., -3:] = torch.rand(batch, steps, 3, generator=g)  # ASR confidences of user words
    done = torch.zeros(batch, steps, 1, dtype=torch.bool)
    truncated = torch.zeros(batch, steps, 1, dtype=torch.bool)
    turn = torch.zeros(batch, steps, 1, dtype=torch.int64)
    for b in range(batch):
        count = 0
        for t in range(steps):
            turn[b, t] = count
            count += 1
            if t in done_at.get(b, []):
                done[b, t] = True
                count = 0
    truncated[0, :, 0] = done[0, :, 0] & (torch.arange(steps) % 2 == 1)  # a few truncations on row 0
    td = TensorDict({
        "observation": observation,
        "action_mask": mask,
        "lookahead_reward": torch.randint(-1, 2, (batch, steps, N_ACTIONS), generator=g).float() * 5,
        "winning_actions": torch.rand(batch, steps, N_ACTIONS, generator=g) > 0.85,
        "board": torch.randint(0, 3, (batch, steps, cells), generator=g).to(torch.int8),
        "robot_first": (torch.arange(batch) % 2 == 0).view(batch, 1, 1).expand(batch, steps, 1).clone(),
        "turn": turn,
        "action": torch.randint(0, N_ACTIONS, (batch, steps), generator=g),
        "next": {
            "observation": next_observation,
            "reward": torch.randint(-5, 6, (batch, steps, 1), generator=g).float(),
            "done": done, "terminated": done & ~truncated, "truncated": truncated,
            "board": torch.randint(0, 3, (batch, steps, cells), generator=g).to(torch.int8),
            "outcome": torch.randint(0, 4, (batch, steps, 1), generator=g).to(torch.int8),
            "user_act": torch.randint(-1, 4, (batch, steps, 1), generator=g),
            "user_move": torch.randint(-1, cells, (batch, steps, 1), generator=g),
            "user_utterance": torch.randint(0, 4, (batch, steps, 1), generator=g),
        },
    }, batch_size=(batch, steps))
    if with_q:
        td["action_value"] = torch.randn(batch, steps, N_ACTIONS, generator=g) * 3
    return td


@dataclass
class ExpectedEpisode:
    batch_index: int
    steps: list[dict]
    outcome: str
    seat: str
    total: float
    truncated: bool


def expected_episodes(td: TensorDict) -> list[ExpectedEpisode]:
    """The finished episodes in a batch, in the order they end (time, then batch index)."""
    arrays = {key: value.numpy() for key, value in td.flatten_keys(".").items()}
    batch, steps = td.batch_size
    pending: dict[int, list[dict]] = {b: [] for b in range(batch)}
    finished = []
    for t in range(steps):
        for b in range(batch):
            mask = arrays["action_mask"][b, t]
            available = [int(a) for a in np.flatnonzero(mask)]
            winning = [int(a) for a in np.flatnonzero(arrays["winning_actions"][b, t] & mask)]
            step = {
                "act": int(arrays["action"][b, t]), "step": int(arrays["turn"][b, t, 0]), "mask": available,
                "A": winning or available,
                "A_hat": [int(a) for a in np.flatnonzero(mask & (arrays["lookahead_reward"][b, t] < 0))],
                "reward": float(arrays["next.reward"][b, t, 0]),
                "cells": "".join(str(int(v)) for v in arrays["next.board"][b, t]),
                "user_act": int(arrays["next.user_act"][b, t, 0]),
                "features": arrays["observation"][b, t].copy(),
                "next_features": arrays["next.observation"][b, t].copy(),
                "utterance": int(arrays["next.user_utterance"][b, t, 0]),
            }
            if "action_value" in arrays:
                step["q"] = [float(arrays["action_value"][b, t, a]) for a in available]
            pending[b].append(step)
            if arrays["next.done"][b, t, 0]:
                outcome = ("none", "win", "loss", "draw")[int(arrays["next.outcome"][b, t, 0])]
                finished.append(ExpectedEpisode(
                    b, pending[b], outcome, "first" if arrays["robot_first"][b, t, 0] else "second",
                    sum(s["reward"] for s in pending[b]), bool(arrays["next.truncated"][b, t, 0])))
                pending[b] = []
    return finished


def run_cli(*args: str, capsys: pytest.CaptureFixture) -> tuple[int, str, str]:
    """Run `ncbot` in-process through the real entry point (`ncbot.pipelines.cli.app.main`)."""
    from ncbot.pipelines.cli.app import main

    old_argv = sys.argv
    sys.argv = ["ncbot", *map(str, args)]
    try:
        main()
        code = 0
    except SystemExit as stop:
        code = stop.code if isinstance(stop.code, int) else (0 if stop.code is None else 1)
    finally:
        sys.argv = old_argv
    captured = capsys.readouterr()
    return code, captured.out, captured.err
