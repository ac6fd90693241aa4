"""The look-ahead masks of the agents (paper section 4 and 4b).

Each rule turns the env's `action_mask` (available actions), `lookahead_reward` (one-step reward of every action)
and `winning_actions` (the paper's set A when non-empty) into two masks:

- `explore_mask`: where epsilon-greedy picks uniformly;
- `greedy_mask`: where the greedy argmax over Q looks.

Neither mask is ever all False (TorchRL's EGreedyModule would crash on such a row), because each falls back to
the available actions, which the env guarantees non-empty.
"""
from __future__ import annotations

from collections.abc import Callable

import torch
from tensordict import TensorDictBase
from tensordict.nn import TensorDictModuleBase

AVAILABLE_KEY = "action_mask"
LOOKAHEAD_REWARD_KEY = "lookahead_reward"
WINNING_KEY = "winning_actions"
EXPLORE_MASK_KEY = "explore_mask"
GREEDY_MASK_KEY = "greedy_mask"

MaskRule = Callable[[torch.Tensor, torch.Tensor, torch.Tensor], tuple[torch.Tensor, torch.Tensor]]


def _nonempty_or(mask: torch.Tensor, fallback: torch.Tensor) -> torch.Tensor:
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
    return available, _nonempty_or(available & ~worst, available)


def one_step_lookahead(
    available: torch.Tensor, reward: torch.Tensor, winning: torch.Tensor
) -> tuple[torch.Tensor, torch.Tensor]:
    """Proposed (Algorithm 2): A = winning actions if any else available; greedy over A minus A_hat (negative reward).

    Epsilon picks uniformly in A; the greedy argmax falls back to A when every action of A has a negative reward.
    """
    set_a = _nonempty_or(winning & available, available)
    a_hat = reward < 0
    return set_a, _nonempty_or(set_a & ~a_hat, set_a)


LOOKAHEAD_RULES: dict[str, MaskRule] = {
    "none": no_lookahead,
    "variant": variant_lookahead,
    "one_step": one_step_lookahead,
}

AGENT_LOOKAHEAD: dict[str, str] = {"dqn_original": "none", "dqn_variant": "variant", "proposed": "one_step"}


def register_lookahead(name: str, rule: MaskRule) -> None:
    """Add a mask rule (e.g. a k-step look-ahead) so configs can select it by name."""
    LOOKAHEAD_RULES[name] = rule


def lookahead_rule(name: str) -> MaskRule:
    """The mask rule called `name`; ValueError naming the choices otherwise."""
    try:
        return LOOKAHEAD_RULES[name]
    except KeyError:
        raise ValueError(f"unknown look-ahead {name!r}; expected one of {sorted(LOOKAHEAD_RULES)}") from None


class LookaheadMasks(TensorDictModuleBase):
    """Writes `explore_mask` and `greedy_mask` from the env's look-ahead keys, using the rule called `lookahead`."""

    in_keys = [AVAILABLE_KEY, LOOKAHEAD_REWARD_KEY, WINNING_KEY]
    out_keys = [EXPLORE_MASK_KEY, GREEDY_MASK_KEY]

    def __init__(self, lookahead: str = "one_step") -> None:
        super().__init__()
        self.lookahead = lookahead
        self.rule = lookahead_rule(lookahead)

    def forward(self, tensordict: TensorDictBase) -> TensorDictBase:
        if getattr(self.rule, "needs_tensordict", False):  # e.g. k-step look-ahead (modules.deep_lookahead)
            explore, greedy = self.rule.masks_from_tensordict(tensordict)
        else:
            explore, greedy = self.rule(
                tensordict.get(AVAILABLE_KEY), tensordict.get(LOOKAHEAD_REWARD_KEY), tensordict.get(WINNING_KEY)
            )
        tensordict.set(EXPLORE_MASK_KEY, explore)
        tensordict.set(GREEDY_MASK_KEY, greedy)
        return tensordict


import modules.deep_lookahead  # noqa: E402,F401  (registers the k-step rules k1..k5, k1_open..k5_open)
