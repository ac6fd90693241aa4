"""Learning rewards: the paper's shaped rewards as the env gives them, or game-outcome rewards.

Why an alternative: the paper's reward pays +5 for "about to win" (making a threat) as much as for winning, so a
return-maximising agent learns to keep making threats instead of closing the game, and against a random user
some of those games end in draws. `outcome` rewards pay only for how the game ends (+5 win, +1 draw, -5 loss)
and keep the -5 for an act outside the action mask; the env, the look-ahead masks and all reported metrics still
use the paper's rewards. The learner's reward goes under its own key, ("next", "learning_reward"), so
("next", "reward") keeps the env's meaning; the loss reads it through `set_keys(reward="learning_reward")`.
"""
from __future__ import annotations

import torch
from tensordict import TensorDictBase

from ncbot.envs.core import OUTCOME_DRAW, OUTCOME_HUMAN_WON, OUTCOME_NONE, OUTCOME_ROBOT_WON, REWARD_DRAW, REWARD_WIN

REWARD_MODES = ("paper", "outcome")
LEARNING_REWARD_KEY = ("next", "learning_reward")


def outcome_rewards(transitions: TensorDictBase, loss_reward: float = -5.0) -> torch.Tensor:
    """Reward of each transition from the game outcome it caused (shape like ("next", "reward")).

    `loss_reward` prices a lost game: at -5 (the paper's scale) a return-maximiser accepts a small risk of losing
    for a likelier win; a heavier price (e.g. -20) makes losing nothing part of the optimum."""
    before = transitions.get("outcome").long()
    after = transitions.get(("next", "outcome")).long()
    ended = (before == OUTCOME_NONE) & (after != OUTCOME_NONE)
    reward = torch.zeros(after.shape, dtype=torch.float32, device=after.device)
    reward = torch.where(ended & (after == OUTCOME_ROBOT_WON), REWARD_WIN, reward)
    reward = torch.where(ended & (after == OUTCOME_DRAW), REWARD_DRAW, reward)
    reward = torch.where(ended & (after == OUTCOME_HUMAN_WON), float(loss_reward), reward)
    action = transitions.get("action").unsqueeze(-1)
    refused = ~torch.gather(transitions.get("action_mask"), -1, action)
    return torch.where(refused, -5.0, reward).reshape(transitions.get(("next", "reward")).shape)


def learning_rewards(transitions: TensorDictBase, mode: str, loss_reward: float = -5.0) -> TensorDictBase:
    """Write ("next", "learning_reward"), the reward the learner trains on: the env's ("next", "reward") under
    `paper`, the game-outcome reward under `outcome` (`loss_reward` applies to `outcome` only). The env's reward
    itself is left as it is."""
    if mode == "paper":
        reward = transitions.get(("next", "reward"))
    elif mode == "outcome":
        reward = outcome_rewards(transitions, loss_reward)
    else:
        raise ValueError(f"unknown reward mode {mode!r}; expected one of {', '.join(REWARD_MODES)}")
    transitions.set(LEARNING_REWARD_KEY, reward)
    return transitions
