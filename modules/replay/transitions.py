"""Collector batch -> replay-buffer transitions: the learning reward, the bootstrap mask and n-step returns, in one
call (`prepare_transitions`), so the training loop has one line between the Collector and the buffer.

Keys written (nothing the env wrote changes meaning; the loss reads the new keys through its `set_keys`,
`LOSS_KEYS`, wired by `ncbot.pipelines.train.build.make_objective`):
- ("next", "learning_reward"): the reward the learner trains on (modules/replay/rewards.py, `loss.reward`);
- ("next", "bootstrap_mask"): the next actions the TD target maximises over (modules/replay/bootstrap.py,
  `loss.bootstrap`);
- with `loss.n_step` > 1, TorchRL's `MultiStepTransform`: "next" then holds the state the window ended in,
  ("next", "learning_reward") the discounted sum of the window's learning rewards and `steps_to_next_obs` its
  length k, so the loss's TD(0) estimator bootstraps with gamma^k (exact, also for windows cut by a truncation).

The buffer keeps only what the loss reads (`BUFFER_KEYS`): the env's masks, outcomes and shaped reward were only
needed to build the keys above.
"""
from __future__ import annotations

import torch
from tensordict import TensorDictBase
from torchrl.envs.transforms import MultiStepTransform

from ncbot.modules.replay.bootstrap import BOOTSTRAP_MASK_KEY, bootstrap_keys, set_bootstrap_mask
from ncbot.modules.replay.rewards import LEARNING_REWARD_KEY, learning_rewards

# what the learning reward and the bootstrap mask are computed from (plus the look-ahead keys `greedy` reads)
TRANSITION_KEYS = (
    "observation", "action_mask", "action", "outcome", ("next", "outcome"),
    ("next", "observation"), ("next", "action_mask"), ("next", "reward"),
    ("next", "done"), ("next", "terminated"), ("next", "truncated"),
)
STEPS_KEY = "steps_to_next_obs"  # TorchRL's name: written by MultiStepTransform, read by the TD(0) estimator
BUFFER_KEYS = ("observation", "action", ("next", "observation"), LEARNING_REWARD_KEY, BOOTSTRAP_MASK_KEY,
               ("next", "done"), ("next", "terminated"), ("next", "truncated"))
# the loss's `set_keys` for these transitions (keys under "next" are given by their leaf name)
LOSS_KEYS = {"reward": LEARNING_REWARD_KEY[1], "bootstrap_mask": BOOTSTRAP_MASK_KEY[1]}


def stored_keys(n_step: int) -> tuple:
    """The keys of a stored transition, which an objective may read (`steps_to_next_obs` with n-step returns)."""
    return (*BUFFER_KEYS, STEPS_KEY) if n_step > 1 else BUFFER_KEYS


def make_multistep(n_step: int, gamma: float) -> MultiStepTransform | None:
    """TorchRL's n-step transform over the learning reward (None for the one-step target, n_step = 1).

    It keeps the last n steps of every env row until the next batch completes their windows, so every step becomes
    exactly one n-step transition, n steps late; a resumed run starts with an empty wait list."""
    if int(n_step) < 1:
        raise ValueError(f"loss.n_step must be >= 1, got {n_step}")
    if not 0.0 <= float(gamma) <= 1.0:
        raise ValueError(f"n-step returns need 0 <= gamma <= 1, got {gamma}")
    if n_step == 1:
        return None
    # done_keys=[]: the done flags are gathered from the window's end like the next observation (TorchRL's default
    # keeps step t's flags, so a window that ends the game at t + k > t would bootstrap from the terminal state)
    return MultiStepTransform(int(n_step), float(gamma), reward_keys=[LEARNING_REWARD_KEY[1]], done_keys=[])


def prepare_transitions(batch: TensorDictBase, *, reward: str, loss_reward: float, bootstrap: str, lookahead: str,
                        multistep: MultiStepTransform | None = None) -> TensorDictBase:
    """(env rows, T) collector batch -> flat transitions with `BUFFER_KEYS` (+ `steps_to_next_obs` with n-step).

    `reward`, `loss_reward`: the learning reward (modules/replay/rewards.py); `bootstrap`, `lookahead`: the bootstrap mask
    (modules/replay/bootstrap.py); `multistep` is `make_multistep(...)` of the run (it holds the rows' unfinished windows)."""
    if batch.batch_dims != 2:
        raise ValueError(f"prepare_transitions needs collector batches shaped (env rows, time), "
                         f"got {tuple(batch.shape)}")
    transitions = batch.select(*TRANSITION_KEYS, *bootstrap_keys(bootstrap))
    transitions = learning_rewards(transitions, reward, loss_reward=loss_reward)
    transitions = set_bootstrap_mask(transitions, bootstrap, lookahead).select(*BUFFER_KEYS)
    if multistep is None:
        return transitions.reshape(-1)
    windows = multistep.inv(transitions)
    if windows is None:  # the rows are still shorter than one window: nothing to emit yet
        rows = transitions.shape[0]
        windows = transitions[:, :0].set(STEPS_KEY, torch.ones(rows, 0, dtype=torch.long, device=transitions.device))
    return windows.select(*BUFFER_KEYS, STEPS_KEY).reshape(-1)
