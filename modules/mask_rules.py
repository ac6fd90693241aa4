"""The one-step look-ahead rules of the paper (section 4 and 4b) and the TensorDict keys every mask rule reads.

A rule maps the env's `action_mask` (available actions), `lookahead_reward` (one-step reward of every action) and
`winning_actions` (the paper's set A when non-empty) to (explore mask, greedy mask). The deeper rules of
`modules.deep_lookahead` build on these keys; `modules.masks` names every rule in one table.
"""
from __future__ import annotations

from collections.abc import Callable

import torch

AVAILABLE_KEY = "action_mask"
LOOKAHEAD_REWARD_KEY = "lookahead_reward"
WINNING_KEY = "winning_actions"
EXPLORE_MASK_KEY = "explore_mask"
GREEDY_MASK_KEY = "greedy_mask"

MaskRule = Callable[[torch.Tensor, torch.Tensor, torch.Tensor], tuple[torch.Tensor, torch.Tensor]]


def nonempty_or(mask: torch.Tensor, fallback: torch.Tensor) -> torch.Tensor:
    """Rows of `mask` with no True entry are replaced by the same row of `fallback`."""
    return torch.where(mask.any(-1, keepdim=True), mask, fallback)


def no_lookahead(available: torch.Tensor, reward: torch.Tensor, winning: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
    """DQN-Original: plain masked DQN; repeated or losing moves are only discouraged by their -5 reward."""
    return available, available


def variant_lookahead(
    available: torch.Tensor, reward: torch.Tensor, winning: torch.Tensor
) -> tuple[torch.Tensor, torch.Tensor]:
    """DQN-Variant: the greedy choice skips the available actions tied for the lowest reward when it is negative.

    Exploration is unchanged (uniform over available actions); there is no win-forcing.
    """
    masked_reward = torch.where(available, reward, torch.full_like(reward, float("inf")))
    lowest = masked_reward.min(-1, keepdim=True).values
    worst = available & (reward == lowest) & (lowest < 0)
    return available, nonempty_or(available & ~worst, available)


def one_step_lookahead(
    available: torch.Tensor, reward: torch.Tensor, winning: torch.Tensor
) -> tuple[torch.Tensor, torch.Tensor]:
    """Proposed (Algorithm 2): A = winning actions if any else available; greedy over A minus A_hat (negative reward).

    Epsilon picks uniformly in A; the greedy argmax falls back to A when every action of A has a negative reward.
    """
    set_a = nonempty_or(winning & available, available)
    a_hat = reward < 0
    return set_a, nonempty_or(set_a & ~a_hat, set_a)
