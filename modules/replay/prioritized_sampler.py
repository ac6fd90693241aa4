"""Proportional prioritised replay (Schaul et al. 2016) as a TorchRL `Sampler`, in plain torch.

Why not TorchRL's own `PrioritizedSampler`: its sum and min trees live in TorchRL's compiled extension, which does
not load against the torch this project pins (`torchrl._torchrl` fails on an undefined symbol), so the sampler
raises "SumSegmentTreeFp32 is not available". This one keeps the priorities of the whole storage in one tensor
and draws with `torch.multinomial`: O(capacity) per draw instead of O(log capacity), which is cheap here because
the learner draws all the updates of a collected batch at once (`Learner.update_many`).

Same contract as TorchRL's: new rows get the largest priority seen so far; a draw returns the rows and their
importance weights `priority_weight` = (p_i / p_min) ** -beta (p = (|TD error| + eps) ** alpha), which the loss
multiplies into each row's error; the learner sends the rows' new |TD error| back with `update_priority`.
"""
from __future__ import annotations

from typing import Any

import torch
from torchrl.data.replay_buffers.samplers import Sampler

WEIGHT_KEY = "priority_weight"  # the name TorchRL's PrioritizedSampler and DQNLoss use


class ProportionalSampler(Sampler):
    """Rows drawn with probability p_i / sum(p), p_i = (|TD error_i| + eps) ** alpha (module doc)."""

    def __init__(self, capacity: int, alpha: float, beta: float, eps: float = 1e-6) -> None:
        if capacity <= 0:
            raise ValueError(f"capacity must be positive, got {capacity}")
        self.alpha, self.beta, self.eps = float(alpha), float(beta), float(eps)
        self._priority = torch.zeros(capacity, dtype=torch.float64)  # p_i ** alpha per storage slot
        self._max_priority = 1.0  # the largest |TD error| + eps seen: what a new row starts with

    def _set_new(self, index: int | torch.Tensor) -> None:
        self._priority[index] = self._max_priority ** self.alpha

    def add(self, index: int) -> None:
        self._set_new(index)

    def extend(self, index: torch.Tensor) -> None:
        self._set_new(torch.as_tensor(index).to("cpu").reshape(-1))

    def sample(self, storage: Any, batch_size: int) -> tuple[torch.Tensor, dict]:
        size = len(storage)
        if size == 0:
            raise RuntimeError("cannot sample from an empty replay buffer")
        priority = self._priority[:size]
        index = torch.multinomial(priority, batch_size, replacement=True, generator=self._rng)
        chosen = priority[index]
        weight = (chosen / priority.min()).pow(-self.beta).to(torch.float32)  # <= 1, the rarest row's is 1
        return index, {WEIGHT_KEY: weight}

    def update_priority(self, index: int | torch.Tensor, priority: float | torch.Tensor, *,
                        storage: Any = None) -> None:
        # priorities live on the CPU whatever the storage's device (a GPU run's |TD errors| and indices come back)
        raw = torch.as_tensor(priority).detach().to("cpu", torch.float64).reshape(-1) + self.eps
        self._max_priority = max(self._max_priority, float(raw.max()))
        self._priority[torch.as_tensor(index).to("cpu").reshape(-1)] = raw.pow(self.alpha)

    def _empty(self) -> None:
        self._priority.zero_()
        self._max_priority = 1.0

    def state_dict(self) -> dict[str, Any]:
        return {"priority": self._priority.clone(), "max_priority": self._max_priority}

    def load_state_dict(self, state_dict: dict[str, Any]) -> None:
        self._priority.copy_(state_dict["priority"])
        self._max_priority = float(state_dict["max_priority"])

    def dumps(self, path: Any) -> None:
        raise NotImplementedError("ProportionalSampler is saved through state_dict (the run's checkpoint)")

    def loads(self, path: Any) -> None:
        raise NotImplementedError("ProportionalSampler is loaded through load_state_dict (the run's checkpoint)")

    def __repr__(self) -> str:
        return f"{type(self).__name__}(capacity={self._priority.numel()}, alpha={self.alpha}, beta={self.beta})"
