"""The agent's policies as TensorDict modules: one greedy (test time) and one epsilon-greedy (for the Collector).

Both run the same chain, so the masks used while learning are the masks used at test time (paper, Algorithm 2):
Q-network (`ncbot.modules.networks.qnet.QValues`, on the Q-network's own module) -> look-ahead masks -> masked argmax [-> TorchRL
`EGreedyModule`].
The raw Q-values stay under `action_value` for the logger; the greedy argmax reads `greedy_mask`, exploration
samples uniformly inside `explore_mask`.
"""
from __future__ import annotations

from dataclasses import dataclass

import torch
from tensordict.nn import TensorDictModule, TensorDictSequential
from torchrl.data import TensorSpec
from torchrl.modules import EGreedyModule

from ncbot.modules.networks.argmax import MaskedArgmax
from ncbot.modules.policies.masks import EXPLORE_MASK_KEY, GREEDY_MASK_KEY, LookaheadMasks
from ncbot.modules.networks.qnet import ACTION_VALUE_KEY, QValues

CHOSEN_ACTION_VALUE_KEY = "chosen_action_value"


@dataclass
class AgentPolicies:
    """The two views of one agent: `greedy` for evaluation, `explore` (with its `egreedy` schedule) for training."""

    greedy: TensorDictSequential
    explore: TensorDictSequential
    egreedy: EGreedyModule


def make_policies(
    qnet: TensorDictModule | QValues,
    action_spec: TensorSpec,
    lookahead: str = "one_step",
    *,
    eps_init: float = 1.0,
    eps_end: float = 0.005,
    annealing_frames: int = 10_000,
    all_negative: str = "available",
    device: torch.device | str | None = None,
) -> AgentPolicies:
    """Chain the Q-network with the look-ahead masks, a masked argmax and an epsilon-greedy layer.

    `action_spec` is the env's unbatched categorical action spec (`env.action_spec_unbatched`). `device`: where
    the Q-network lives when it is not the CPU (the epsilon-greedy layer's schedule and spec go there too).
    """
    greedy = TensorDictSequential(
        # the same network and parameters, without TensorDictModule's per-call overhead; a recurrent network
        # (modules/networks/recurrent.py, a TensorDictSequential) runs as it is
        qnet if isinstance(qnet, TensorDictSequential) else QValues(qnet),
        LookaheadMasks(lookahead, all_negative),
        MaskedArgmax(ACTION_VALUE_KEY, GREEDY_MASK_KEY, "action", CHOSEN_ACTION_VALUE_KEY),
    )
    egreedy = EGreedyModule(
        spec=action_spec.clone(),
        eps_init=eps_init,
        eps_end=eps_end,
        annealing_num_steps=max(1, int(annealing_frames)),
        action_mask_key=EXPLORE_MASK_KEY,
        device=None if device is None or torch.device(device).type == "cpu" else device,  # None: today's CPU call
    )
    return AgentPolicies(greedy=greedy, explore=TensorDictSequential(greedy, egreedy), egreedy=egreedy)
