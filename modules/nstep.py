"""n-step returns for the competitive DQN: collector batches of one-step transitions -> n-step transitions.

Why: on Ultimate a game lasts ~16 robot decisions and the outcome rewards pay only at the end, so a one-step
target moves the value of a win back by one decision per target-network refresh. An n-step target
y = r_t + g r_{t+1} + ... + g^(n-1) r_{t+n-1} + g^n max_a' Q_target(s_{t+n}, a') moves it n decisions at once.

How it fits the one-step loss unchanged: each emitted transition keeps (s_t, a_t) and carries in its ``next``
entries the state where its window ended (s_{t+n}, or the terminal state when the game ended earlier) with the
discounted reward sum. Windows that reach s_{t+n} bootstrap with exactly g^n, windows that end at a terminal
state do not bootstrap at all, so the loss's TD(0) estimator with gamma = g^n (``bootstrap_gamma``) gives the
exact n-step target. A window cut by truncation (100 actions) bootstraps with g^n instead of g^(k+1): a small
bias on a rare event (Ultimate games last ~32 actions).

The collector hands batches shaped (env rows, T) whose rows continue from one batch to the next, so the last
n - 1 steps of each row wait here for the next batch: every step becomes exactly one n-step transition, one
batch late. A resumed run starts with an empty wait list.
"""
from __future__ import annotations

import torch
from tensordict import TensorDictBase


class NStepTransitions:
    """Stateful converter: call it on every collector batch (after the learning rewards are set); it returns the
    flat n-step transitions ready for the replay buffer."""

    def __init__(self, n_steps: int, gamma: float) -> None:
        if int(n_steps) < 1:
            raise ValueError(f"n-step returns need n_steps >= 1, got {n_steps}")
        if not 0.0 <= float(gamma) <= 1.0:
            raise ValueError(f"n-step returns need 0 <= gamma <= 1, got {gamma}")
        self.n_steps, self.gamma = int(n_steps), float(gamma)
        self.pending: TensorDictBase | None = None  # the last n - 1 steps of every env row, still waiting

    @property
    def bootstrap_gamma(self) -> float:
        """The discount the one-step loss must use on these transitions: gamma ** n."""
        return self.gamma ** self.n_steps

    def __call__(self, batch: TensorDictBase) -> TensorDictBase:
        """(rows, T) one-step transitions -> (N,) n-step transitions; N = rows * T once the wait list is full."""
        if batch.batch_dims != 2:
            raise ValueError(f"n-step returns need collector batches shaped (env rows, time), got {tuple(batch.shape)}")
        if self.n_steps == 1:
            return batch.reshape(-1)
        steps = batch if self.pending is None else torch.cat([self.pending, batch], dim=1)
        emit = steps.shape[1] - (self.n_steps - 1)  # windows that lie fully inside `steps`
        if emit <= 0:
            self.pending = steps
            return steps[:, :0].reshape(-1)
        self.pending = steps[:, emit:].clone()
        return self._windows(steps, emit).reshape(-1)

    def _windows(self, steps: TensorDictBase, emit: int) -> TensorDictBase:
        """The n-step transition starting at each of the first `emit` time steps of `steps`."""
        rows = steps.shape[0]
        reward = torch.zeros_like(steps.get(("next", "reward"))[:, :emit])
        alive = torch.ones(reward.shape, dtype=torch.bool)
        last = torch.full((rows, emit), self.n_steps - 1, dtype=torch.long)  # where each window ends
        for k in range(self.n_steps):
            window = slice(k, k + emit)
            reward = reward + torch.where(alive, self.gamma ** k * steps.get(("next", "reward"))[:, window], 0.0)
            done = steps.get(("next", "done"))[:, window]
            last = torch.where(alive.squeeze(-1) & done.squeeze(-1), k, last)
            alive = alive & ~done
        row_index = torch.arange(rows).unsqueeze(1).expand(rows, emit)
        time_index = torch.arange(emit).unsqueeze(0) + last
        out = steps[:, :emit].clone()
        out.set("next", steps.get("next")[row_index, time_index])
        out.set(("next", "reward"), reward)
        return out
