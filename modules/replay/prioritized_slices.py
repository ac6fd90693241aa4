"""Prioritised replay of dialogue slices (agent.memory with buffer.prioritized), after R2D2 (Kapturowski et al. 2019).

Why our own: TorchRL's `PrioritizedSliceSampler` builds on its `PrioritizedSampler`, whose sum tree lives in the
compiled extension that does not load against the torch this project pins (see `prioritized_sampler.py`). This
sampler is TorchRL's `SliceSampler` (fragmented dialogues, padded slices: `modules.networks.recurrent.make_sequence_buffer`)
with the slice's start drawn by priority instead of uniformly, priorities kept in one tensor as in
`ProportionalSampler`.

- A sequence is a slice start: a storage row from which a slice of `slice_len` steps of its dialogue can begin (the
  first step of a dialogue shorter than the slice, any of the first len - L + 1 steps of a longer one). Its
  priority p sits on that row; on 3x3 each dialogue has one start (the whole dialogue), so it is the dialogue's.
- Starts are drawn with probability p ** alpha / sum; a new row gets the largest p seen so far, as TorchRL does.
- The loss gives each slice p = eta * max_t |delta_t| + (1 - eta) * mean_t |delta_t| over its loss steps
  (R2D2's mixture, eta = 0.9: the max keeps a rare surprising step from being averaged away over a long slice)
  and writes it on every step of the slice; `update_priority` keeps one per slice (its first step's row).
- Importance weight `priority_weight` = (p_i ** alpha / min over the starts) ** -beta, the same on every step of a
  slice, as the MLP path's `ProportionalSampler`.
"""
from __future__ import annotations

from typing import Any

import torch
from torchrl.data import SliceSampler
from torchrl.data.replay_buffers.samplers._trajectory import _FragmentedTrajectoryIndex

from ncbot.modules.replay.prioritized_sampler import WEIGHT_KEY

PRIORITY_ETA = 0.9  # R2D2's max/mean mixture of a sequence's |TD errors|


def sequence_priority(td_error: torch.Tensor, trained: torch.Tensor, eta: float = PRIORITY_ETA) -> torch.Tensor:
    """Per slice (rows of `td_error`, (B, L)): eta * max + (1 - eta) * mean of |TD error| over the `trained` steps."""
    error = td_error.abs() * trained
    count = trained.sum(-1).clamp(min=1)
    return eta * error.max(-1).values + (1.0 - eta) * error.sum(-1) / count


class PrioritizedSequenceSampler(SliceSampler):
    """TorchRL's fragmented, padded `SliceSampler` whose slice starts are drawn by priority (module doc)."""

    def __init__(self, capacity: int, slice_len: int, alpha: float, beta: float, *, traj_key: str, step_key: str,
                 eps: float = 1e-6) -> None:
        if capacity <= 0:
            raise ValueError(f"capacity must be positive, got {capacity}")
        super().__init__(slice_len=slice_len, traj_key=traj_key, step_key=step_key, fragmented=True,
                         strict_length=False, pad_output=True, truncated_key=None)
        self.alpha, self.beta, self.eps = float(alpha), float(beta), float(eps)
        self._priority = torch.zeros(capacity, dtype=torch.float64)  # p ** alpha per storage row
        self._max_priority = 1.0

    def extend(self, index: torch.Tensor) -> None:
        self._priority[torch.as_tensor(index).to("cpu").reshape(-1)] = self._max_priority ** self.alpha
        super().extend(index)

    def add(self, index: int | torch.Tensor) -> None:
        self.extend(torch.as_tensor(index))

    def _sample_fragmented(self, storage: Any, batch_size: int) -> tuple[tuple[torch.Tensor, ...], dict]:
        if len(storage) == 0:
            raise RuntimeError("cannot sample from an empty replay buffer")
        if self._fragmented_index is None:
            self._fragmented_index = _FragmentedTrajectoryIndex(self.traj_key, self.step_key)
        self._fragmented_index.refresh(storage)
        ordered_slots, run_offsets, lengths = self._fragmented_index.runs()
        seq_length, num_slices = self._adjusted_batch_size(batch_size)
        device = ordered_slots.device
        slots, offsets, run_lengths = ordered_slots.cpu(), run_offsets.cpu(), lengths.cpu()
        # packed position -> its dialogue run; a position may start a slice if the slice fits in the run after it
        run_of = torch.repeat_interleave(torch.arange(run_lengths.numel()), run_lengths)
        relative = torch.arange(slots.numel()) - offsets[run_of]
        starts_per_run = run_lengths - run_lengths.clamp_max(seq_length) + 1
        eligible = relative < starts_per_run[run_of]
        priority = self._priority[slots] * eligible
        packed_starts = torch.multinomial(priority, num_slices, replacement=True, generator=self._rng)
        weight = (priority[packed_starts] / priority[eligible].min()).pow(-self.beta).to(torch.float32)
        sampled_lengths = (run_lengths[run_of[packed_starts]] - relative[packed_starts]).clamp_max(seq_length)
        steps = torch.arange(seq_length)
        real = steps.unsqueeze(0) < sampled_lengths.unsqueeze(1)
        steps = torch.minimum(steps.unsqueeze(0), (sampled_lengths - 1).unsqueeze(1))  # padding repeats the last
        index = slots[packed_starts.unsqueeze(1) + steps].reshape(-1, 1).to(device)
        index, info = self._finalize_index(index=index, num_slices=num_slices, seq_length=sampled_lengths.to(device),
                                           target_seq_length=seq_length, mask_flat=real.reshape(-1).to(device),
                                           storage=storage)
        info[WEIGHT_KEY] = weight.repeat_interleave(seq_length).to(device)
        return index, info

    def update_priority(self, index: int | torch.Tensor, priority: float | torch.Tensor, *,
                        storage: Any = None) -> None:
        """`index` and `priority` per sampled step (slices of `slice_len` in order): each slice's first row takes
        its first step's priority (the loss writes the slice's on all its steps)."""
        rows = torch.as_tensor(index).to("cpu").reshape(-1, self.slice_len)[:, 0]
        raw = torch.as_tensor(priority).detach().to("cpu", torch.float64).reshape(-1, self.slice_len)[:, 0] + self.eps
        self._max_priority = max(self._max_priority, float(raw.max()))
        self._priority[rows] = raw.pow(self.alpha)

    def _empty(self) -> None:
        super()._empty()
        self._priority.zero_()
        self._max_priority = 1.0

    def state_dict(self) -> dict[str, Any]:
        return {"priority": self._priority.clone(), "max_priority": self._max_priority}

    def load_state_dict(self, state_dict: dict[str, Any]) -> None:
        super().load_state_dict(state_dict)
        self._priority.copy_(state_dict["priority"])
        self._max_priority = float(state_dict["max_priority"])

    def __repr__(self) -> str:
        return (f"{type(self).__name__}(capacity={self._priority.numel()}, slice_len={self.slice_len}, "
                f"alpha={self.alpha}, beta={self.beta})")
