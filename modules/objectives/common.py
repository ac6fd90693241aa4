"""What the objectives share: the keys of a replayed transition, the error functions and the target updater.

Every objective reads the same replayed rows (`ncbot.modules.replay.transitions`): the loss's `set_keys` wires its
reward to ("next", "learning_reward") and its bootstrap mask to ("next", "bootstrap_mask") (`TRANSITION_LOSS_KEYS`).
"""
from __future__ import annotations

from dataclasses import dataclass

from torchrl.objectives import HardUpdate, LossModule, SoftUpdate

from ncbot.modules.networks.qnet import ACTION_VALUE_KEY
from ncbot.modules.policies.mask_rules import AVAILABLE_KEY

BOOTSTRAP_VALUE_KEY = "bootstrap_value"  # max of Q over the bootstrap mask, written by the value network
PRIORITY_KEY = "td_error"  # |Q(s, a) - y| per row, written by the loss for a prioritised replay buffer
PRIORITY_WEIGHT_KEY = "priority_weight"  # a prioritised sampler's importance weight per row
LOSS_FUNCTIONS = {"l2": "l2", "mse": "l2", "huber": "smooth_l1", "smooth_l1": "smooth_l1"}


@dataclass
class TransitionKeys:
    """The keys a DQN objective reads from a replayed batch (reward, done, terminated and bootstrap_mask under
    "next") and writes into it (priority); TorchRL's `_AcceptedKeys`, set with `set_keys`."""

    action: str = "action"
    reward: str = "reward"
    done: str = "done"
    terminated: str = "terminated"
    bootstrap_mask: str = AVAILABLE_KEY
    steps_to_next_obs: str = "steps_to_next_obs"
    value: str = BOOTSTRAP_VALUE_KEY
    action_value: str = ACTION_VALUE_KEY
    priority: str = PRIORITY_KEY
    priority_weight: str = PRIORITY_WEIGHT_KEY


def check_loss_function(name: str) -> str:
    """The `distance_loss` name of `loss.loss_function` (l2 | huber, and their TorchRL spellings)."""
    if name not in LOSS_FUNCTIONS:
        raise ValueError(f"unknown loss_function {name!r}; expected one of {sorted(LOSS_FUNCTIONS)}")
    return LOSS_FUNCTIONS[name]


def make_target_updater(loss: LossModule, kind: str = "hard", period: int = 100, tau: float = 0.005):
    """TorchRL target updater: `hard` copies the online weights every `period` calls of `.step()`, `soft` uses tau.

    TorchRL's `HardUpdate(value_network_update_interval=k)` copies on every (k+1)-th call, hence `period - 1`.
    """
    if kind == "hard":
        if period < 1:
            raise ValueError(f"loss.target_period must be >= 1, got {period}")
        return HardUpdate(loss, value_network_update_interval=period - 1)
    if kind == "soft":
        if not 0.0 < tau <= 1.0:
            raise ValueError(f"loss.tau must be in (0, 1], got {tau}")
        return SoftUpdate(loss, tau=tau)
    raise ValueError(f"unknown target update {kind!r}; expected 'hard' or 'soft'")
