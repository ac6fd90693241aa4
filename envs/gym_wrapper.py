"""Gymnasium view of one dialogue game, registered as ``ncbot/NoughtsCrosses-v0``.

Why a wrapper and not a second env: the dynamics live once, in the batched TorchRL env; this runs it with
batch size 1 and converts to NumPy, so Gymnasium users (SB3's MaskablePPO, CleanRL scripts) get the same
game. The action mask is in ``info["action_mask"]`` and from ``action_masks()`` (the MaskablePPO hook).

>>> import gymnasium, envs
>>> env = gymnasium.make("ncbot/NoughtsCrosses-v0", game="ultimate", temporal=False)
"""
from __future__ import annotations

from typing import Any

import gymnasium as gym
import numpy as np
import torch
from tensordict import TensorDict

from ncbot.envs.dialogue_env import DialogueGameEnv


class NoughtsCrossesGymEnv(gym.Env):
    """One dialogue game (3x3 or Ultimate) with Discrete actions and a Box observation in [0, 1]."""

    metadata = {"render_modes": ["ansi"], "render_fps": 1}

    def __init__(self, game: str = "standard", temporal: bool = True, free_move: str = "anywhere", render_mode: str | None = None, **options: Any) -> None:
        if render_mode not in (None, "ansi"):
            raise ValueError(f"render_mode must be None or 'ansi', got {render_mode!r}")
        self.render_mode = render_mode
        self.env = DialogueGameEnv(game=game, batch_size=(1,), temporal=temporal, free_move=free_move, **options)
        self.observation_space = gym.spaces.Box(0.0, 1.0, shape=(self.env.n_features,), dtype=np.float32)
        self.action_space = gym.spaces.Discrete(self.env.n_actions)
        self._last: TensorDict | None = None
        self._last_action: int | None = None

    def _info(self, td: TensorDict) -> dict[str, Any]:
        return {
            "action_mask": td["action_mask"][0].numpy().copy(),
            "lookahead_reward": td["lookahead_reward"][0].numpy().copy(),
            "winning_actions": td["winning_actions"][0].numpy().copy(),
            "board": td["board"][0].numpy().copy(),
            "outcome": int(td["outcome"][0, 0]),
            "user_act": int(td["user_act"][0, 0]),
            "user_move": int(td["user_move"][0, 0]),
            "user_says": self.env.user_utterance(int(td["user_utterance"][0, 0])),
        }

    def reset(self, *, seed: int | None = None, options: dict | None = None):
        super().reset(seed=seed)
        if seed is not None:
            self.env.set_seed(int(seed))
        td = self.env.reset()
        self._last, self._last_action = td, None
        return td["observation"][0].numpy().copy(), self._info(td)

    def step(self, action):
        if self._last is None:
            raise ValueError("call reset() before step()")
        action = int(action)
        td = TensorDict({"action": torch.tensor([action])}, batch_size=[1])
        out = self.env.step(td)["next"]
        self._last, self._last_action = out, action
        return (
            out["observation"][0].numpy().copy(),
            float(out["reward"][0, 0]),
            bool(out["terminated"][0, 0]),
            bool(out["truncated"][0, 0]),
            self._info(out),
        )

    def action_masks(self) -> np.ndarray:
        """The current action mask (bool, one entry per dialogue act)."""
        if self._last is None:
            raise ValueError("call reset() before action_masks()")
        return self._last["action_mask"][0].numpy().copy()

    def render(self) -> str | None:
        if self.render_mode != "ansi" or self._last is None:
            return None
        rules = self.env.rules
        board = self._last["board"][0].tolist()
        symbol = {0: ".", 1: "R", 2: "H"}
        rows = [" ".join(symbol[board[r * rules.cols + c]] for c in range(rules.cols)) for r in range(rules.rows)]
        said = "" if self._last_action is None else f"robot: {self.env.describe_action(self._last_action)}\n"
        heard = self.env.user_utterance(int(self._last["user_utterance"][0, 0]))
        return said + (f"user: {heard}\n" if heard else "") + "\n".join(rows)
