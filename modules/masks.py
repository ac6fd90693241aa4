"""The look-ahead masks of the agents (paper section 4 and 4b).

Each rule turns the env's `action_mask` (available actions), `lookahead_reward` (one-step reward of every action)
and `winning_actions` (the paper's set A when non-empty) into two masks:

- `explore_mask`: where epsilon-greedy picks uniformly;
- `greedy_mask`: where the greedy argmax over Q looks.

Neither mask is ever all False (TorchRL's EGreedyModule would crash on such a row), because each falls back to
the available actions, which the env guarantees non-empty.
"""
from __future__ import annotations

import torch
from tensordict import TensorDictBase
from tensordict.nn import TensorDictModuleBase

from ncbot.modules.deep_lookahead import MAX_PLIES, KStepLookahead
from ncbot.modules.mask_rules import (  # noqa: F401  (the keys and rules are used from here too)
    ALL_NEGATIVE_CHOICES, AVAILABLE_KEY, BOARD_KEY, EXPLORE_MASK_KEY, GREEDY_MASK_KEY, LOOKAHEAD_REWARD_KEY, WINNING_KEY,
    MaskRule, all_moves_negative, check_all_negative, no_lookahead, one_step_lookahead, untaken_actions,
    variant_lookahead,
)

#: Every mask rule a config, the CLI or a checkpoint can name: the paper's three, then the k-step searches
#: (``kN`` for free_move=anywhere, ``kN_open`` for open_subgrids).
LOOKAHEAD_RULES: dict[str, MaskRule] = {
    "none": no_lookahead,
    "variant": variant_lookahead,
    "one_step": one_step_lookahead,
    **{f"k{plies}": KStepLookahead(plies, "anywhere") for plies in range(1, MAX_PLIES + 1)},
    **{f"k{plies}_open": KStepLookahead(plies, "open_subgrids") for plies in range(1, MAX_PLIES + 1)},
}

# each agent's own mask rule; `uniform` (no learning, a uniform choice inside the greedy mask) takes Proposed's
AGENT_LOOKAHEAD: dict[str, str] = {"dqn_original": "none", "dqn_variant": "variant", "proposed": "one_step",
                                   "uniform": "one_step"}


def lookahead_rule(name: str) -> MaskRule:
    """The mask rule called `name`; ValueError naming the choices otherwise."""
    try:
        return LOOKAHEAD_RULES[name]
    except KeyError:
        raise ValueError(f"unknown look-ahead {name!r}; expected one of {sorted(LOOKAHEAD_RULES)}") from None


class LookaheadMasks(TensorDictModuleBase):
    """Writes `explore_mask` and `greedy_mask` from the env's look-ahead keys, using the rule called `lookahead`.

    `all_negative` (`agent.all_negative`): where the greedy mask falls back when every action of set A has a
    negative look-ahead reward: `available` (set A) or `untaken` (set A without the squares taken on the env's
    `board` key, which it then also reads); see `ncbot.modules.mask_rules`. The variant, one_step and k-step rules use it;
    `none` has no look-ahead and no fallback.
    """

    out_keys = [EXPLORE_MASK_KEY, GREEDY_MASK_KEY]

    def __init__(self, lookahead: str = "one_step", all_negative: str = "available") -> None:
        super().__init__()
        self.lookahead = lookahead
        self.rule = lookahead_rule(lookahead)
        self.all_negative = check_all_negative(all_negative)
        self.in_keys = [AVAILABLE_KEY, LOOKAHEAD_REWARD_KEY, WINNING_KEY] + ([BOARD_KEY] if all_negative == "untaken" else [])

    def forward(self, tensordict: TensorDictBase) -> TensorDictBase:
        available = tensordict.get(AVAILABLE_KEY)
        untaken = None
        if self.all_negative == "untaken":
            untaken = untaken_actions(tensordict.get(BOARD_KEY), available.shape[-1])
        if getattr(self.rule, "needs_tensordict", False):  # e.g. k-step look-ahead (modules.deep_lookahead)
            explore, greedy = self.rule.masks_from_tensordict(tensordict, untaken)
        else:
            explore, greedy = self.rule(
                available, tensordict.get(LOOKAHEAD_REWARD_KEY), tensordict.get(WINNING_KEY), untaken
            )
        tensordict.set(EXPLORE_MASK_KEY, explore)
        tensordict.set(GREEDY_MASK_KEY, greedy)
        return tensordict


class LookaheadOnlyPolicy:
    """No learning: an agent's look-ahead masks with a seeded uniform choice inside them (docs/reproduction.md: what learning adds).

    The decision maker of `ncbot play` and `ncbot robot play` without a checkpoint; `ncbot ladder --baseline`
    plays it beside the agent, since a learnt agent must clearly beat its own masks to have learnt anything.
    """

    name = "lookahead"

    def __init__(self, seed: int = 0, lookahead: str = "one_step", all_negative: str = "available") -> None:
        self.masks = LookaheadMasks(lookahead, all_negative)
        self.generator = torch.Generator().manual_seed(int(seed))

    def __call__(self, td: TensorDictBase) -> TensorDictBase:
        greedy = self.masks(td).get(GREEDY_MASK_KEY)
        td.set("action", (torch.rand(greedy.shape, generator=self.generator) + greedy.float()).argmax(-1))
        return td
